"""The grid FMU and its variants through fmpy: initial point, flat start, the 28 MW load step."""
import fmpy
import numpy as np
import pytest
from fmpy.model_description import read_model_description
from fmpy.validation import validate_fmu

from conftest import DIST

VARIANTS = DIST.parent / "variants"
GRIDS = [DIST / "dvpp_grid.fmu"] + sorted(VARIANTS.glob("dvpp_grid-*.fmu"))


def names(md, prefix, suffix=""):
    return [v.name for v in md.modelVariables if v.name.startswith(prefix) and v.name.endswith(suffix)]


def test_the_grid_variants_are_bundled():
    stems = {p.stem for p in GRIDS}
    assert {"dvpp_grid", "dvpp_grid-ieee9", "dvpp_grid-ieee9_hybrid", "dvpp_grid-ieee9_dvpp_file"} <= stems


@pytest.mark.parametrize("path", GRIDS, ids=lambda p: p.stem)
def test_grid_validates_and_declares_the_interface(path):
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    variables = {v.name: v for v in md.modelVariables}
    for name in ["pcc.p", "pcc.q", "pcc.v", "pcc.f", "coi.f", "sys.p_gen", "sys.p_load", "sys.p_loss", "sys.p_mismatch"]:
        assert variables[name].causality == "output", name
    for k in range(1, len(names(md, "der[", ".p")) + 1):
        gfm = f"der[{k}].theta" in variables
        inputs = ["theta", "E"] if gfm else ["p_ref", "q_ref"]
        for s in inputs:
            assert variables[f"der[{k}].{s}"].causality == "input"
        for s in ["p", "q", "v", "v_angle"]:
            assert variables[f"der[{k}].{s}"].causality == "output"
    # No output depends directly on an input (inputs act through the next step only).
    for unknown in md.outputs:
        assert unknown.dependencies == [], unknown.variable.name


@pytest.mark.parametrize("path", GRIDS, ids=lambda p: p.stem)
def test_flat_start_through_fmpy(path):
    md = read_model_description(str(path))
    off = {n: False for n in names(md, "event[", ".enabled")}
    freqs = ["coi.f", "pcc.f"] + names(md, "sg[", ".omega")
    powers = names(md, "der[", ".p")
    result = fmpy.simulate_fmu(
        str(path),
        fmi_type="CoSimulation",
        start_values=off,
        stop_time=10.0,
        step_size=1e-3,
        output_interval=0.01,
        output=freqs + powers + ["sys.p_mismatch"],
    )
    assert abs(result["time"][-1] - 10.0) < 1e-9
    for f in freqs:
        assert np.max(np.abs(result[f] - 1.0)) < 1e-6, f
    assert np.max(np.abs(result["sys.p_mismatch"])) < 1e-6
    for p in powers:
        assert np.ptp(result[p]) < 1e-9, p


def test_default_grid_starts_at_the_power_flow_point():
    result = fmpy.simulate_fmu(
        str(DIST / "dvpp_grid.fmu"),
        fmi_type="CoSimulation",
        stop_time=0.5,
        output=["der[1].p", "der[2].p", "der[3].p", "pcc.p", "pcc.v"],
    )
    first = result[0]
    assert np.allclose([first["der[1].p"], first["der[2].p"], first["der[3].p"]], [0.315, 0.5, 0.0], atol=1e-9)
    assert abs(first["pcc.p"] - 0.815) < 1e-9
    assert abs(first["pcc.v"] - 1.025) < 1e-9


def test_load_step_on_ieee9_through_fmpy():
    """28 MW at bus 5, t = 1 s: the first 30 s agree with the standalone model's figures."""
    path = str(VARIANTS / "dvpp_grid-ieee9.fmu")
    result = fmpy.simulate_fmu(
        path,
        fmi_type="CoSimulation",
        start_values={"event[1].enabled": True},
        stop_time=30.0,
        step_size=0.01,
        output_interval=0.01,
        output=["coi.f", "sys.p_mismatch", "sg[1].p", "sg[2].p", "sg[3].p"],
    )
    t, f = result["time"], result["coi.f"]
    assert np.all(f[t < 1.0 - 1e-9] == 1.0)
    i = int(np.argmin(f))
    # the paper's machines: 0.99755 in the library (grid-model's load_step example)
    assert abs(f[i] - 0.99755) < 2e-4, f[i]
    assert 2.0 < t[i] < 3.0, t[i]  # measured 2.26 s
    after = (t > 1.0 + 1e-9) & (t < 1.1 + 1e-9)
    rocof = (f[after][-1] - 1.0) / 0.1 * 50.0  # Hz/s over the first 100 ms
    # -ΔP f/(2 ΣH S) = -0.209 Hz/s at the step; measured -0.218 over the first 100 ms
    assert -0.23 < rocof < -0.205, rocof
    assert np.max(np.abs(result["sys.p_mismatch"])) < 1e-6
    picked_up = sum(result[f"sg[{j}].p"][-1] - result[f"sg[{j}].p"][0] for j in (1, 2, 3))
    assert 0.2 < picked_up < 0.3


def test_a_bad_case_file_is_refused_with_the_problem_named():
    """A case file with a line of zero impedance: fmi2Instantiate fails and the log says why."""
    import pathlib
    import shutil

    from fmpy import extract
    from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

    src = str(VARIANTS / "dvpp_grid-ieee9_dvpp_file.fmu")
    md = read_model_description(src)
    unzipdir = extract(src)
    case_file = pathlib.Path(unzipdir) / "resources" / "ieee9_dvpp.toml"
    case = case_file.read_text()
    bad = case.replace("r = 0.017\nx = 0.092", "r = 0.0\nx = 0.0", 1)
    assert bad != case
    case_file.write_text(bad)
    messages = []
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(lambda env, name, status, cat, msg: messages.append(msg.decode()))
    callbacks.allocateMemory = defaultCallbacks.allocateMemory
    callbacks.freeMemory = defaultCallbacks.freeMemory
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.coSimulation.modelIdentifier)
    with pytest.raises(Exception):
        fmu.instantiate(loggingOn=True, callbacks=callbacks)
    assert any("line 1 (4-5)" in m and "non-positive series impedance" in m for m in messages), messages
    shutil.rmtree(unzipdir, ignore_errors=True)
