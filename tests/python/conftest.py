"""Where the bundled FMUs are for the fmpy tests (cargo xtask test sets DVPP_DIST)."""
import os
import pathlib

import pytest

DIST = pathlib.Path(os.environ.get("DVPP_DIST", pathlib.Path(__file__).parents[2] / "dist" / "default"))
# Every FMU the bundler wrote: the defaults and their variants (dist/variants beside dist/default).
FMUS = sorted(DIST.glob("*.fmu")) + sorted((DIST.parent / "variants").glob("*.fmu"))


@pytest.fixture(params=FMUS, ids=lambda p: p.stem)
def fmu(request):
    return str(request.param)

