"""Where the bundled FMUs are for the fmpy tests (cargo xtask test sets DVPP_DIST)."""
import os
import pathlib

import pytest

DIST = pathlib.Path(os.environ.get("DVPP_DIST", pathlib.Path(__file__).parents[2] / "dist" / "default"))
IDS = ["dvpp_der", "dvpp_operator", "dvpp_grid"]


@pytest.fixture(params=IDS)
def fmu(request):
    path = DIST / f"{request.param}.fmu"
    assert path.is_file(), f"{path} is missing: run `cargo xtask bundle`"
    return str(path)
