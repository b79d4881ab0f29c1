"""Where the bundled FMUs are for the fmpy tests (cargo xtask test sets DVPP_DIST)."""
import os
import pathlib
import platform
import sys
import warnings

import pytest

DIST = pathlib.Path(os.environ.get("DVPP_DIST", pathlib.Path(__file__).parents[2] / "dist" / "default"))
# Every FMU the bundler wrote: the defaults and their variants (dist/variants beside dist/default).
FMUS = sorted(DIST.glob("*.fmu")) + sorted((DIST.parent / "variants").glob("*.fmu"))


@pytest.fixture(params=FMUS, ids=lambda p: p.stem)
def fmu(request):
    return str(request.param)



def require_dpsim(test_file):
    """Skip the calling test module, saying why, when DPsim's Python module does not import."""
    try:
        import dpsimpy  # noqa: F401
    except (ImportError, OSError) as error:
        reason = (
            f"dpsim cannot be imported ({error.__class__.__name__}: {error}) on CPython "
            f"{platform.python_version()}, {sys.platform} {platform.machine()}. PyPI has dpsim 1.4.0 "
            "wheels for CPython 3.10-3.13 on x86_64 Linux (manylinux_2_28) and on win_amd64 only; "
            "cargo xtask test installs it where such a wheel exists (xtask/src/main.rs, PYTHON_PACKAGES)"
        )
        print(f"{test_file} skipped: {reason}")
        warnings.warn(reason)
        pytest.skip(reason, allow_module_level=True)


def require_andes(test_file):
    """Skip the calling test module, saying why, when ANDES does not import."""
    try:
        import andes  # noqa: F401
    except ImportError as error:
        reason = (f"andes cannot be imported ({error}) on CPython {platform.python_version()}; "
                  "cargo xtask test installs it (xtask/src/main.rs, PYTHON_PACKAGES)")
        print(f"{test_file} skipped: {reason}")
        warnings.warn(reason)
        pytest.skip(reason, allow_module_level=True)
