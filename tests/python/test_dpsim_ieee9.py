"""The case file's IEEE nine-bus system in DPsim's three-phase EMT domain (tests/python/dpsim_ieee9.py):

1. DPsim's power flow of fmu-grid/cases/ieee9.toml gives the machines' powers of our own power
   flow (docs/validation.md: 1.88419 / 0.81500 / 0.48000 pu on 100 MVA) within 1e-3 pu;
2. the EMT system (6th-order VBR machines, with and without the exciters, stabilizers and
   governors), initialized from that power flow, starts flat: no machine's speed leaves f_nom by
   1e-4 Hz over 2 s at 50 µs with no event (the network's reactances pre-warped to the
   trapezoidal rule's at f_nom; without the pre-warp and the governors the common drift is
   1.0e-4 Hz and grows as h²). Measured: ~1.2e-7 Hz in both cases, ~2 s of wall time each.
"""
import pytest

from conftest import require_dpsim  # noqa: E402

require_dpsim("test_dpsim_ieee9.py")

import dpsim_ieee9  # noqa: E402

OUR_P = {"SG1": 1.88419, "SG2": 0.81500, "SG3": 0.48000}  # pu on 100 MVA, docs/validation.md
END = 2.0


@pytest.fixture(scope="module", params=[dpsim_ieee9.CONTROLS, ()], ids=["controls", "no-controls"])
def rec(request):
    return dpsim_ieee9.run(end=END, controls=request.param)


def test_power_flow_matches_our_case(rec):
    print("\n" + ", ".join(f"{k}: P {p:.5f} (ours {OUR_P[k]:.5f})" for k, p in rec["p_pf"].items()))
    for k, p in OUR_P.items():
        assert abs(rec["p_pf"][k] - p) < 1e-3


def test_emt_starts_flat(rec):
    print(f"\n{END} s at {dpsim_ieee9.H_STEP * 1e6:.0f} us, wall {rec['wall']:.1f} s: "
          + ", ".join(f"{k} max |df| {df:.2e} Hz" for k, df in rec["df_max"].items()))
    assert set(rec["df_max"]) == set(OUR_P)
    for df in rec["df_max"].values():
        assert df < 1e-4


def test_load_step_matches_our_grid_model():
    """The machines alone, DPsim EMT against our phasor grid FMU (the bundled ieee9 scenario: 28 MW
    at bus 5 at 1 s), 5 s: the centre-of-inertia Δf (H on the system base in both) within 2 %
    NRMSE of ours and its nadir within 2 % and 50 ms. This is the ground the DVPP comparison of
    emt_case1.py stands on: without the converters the two settings agree. Measured: NRMSE
    0.48 %, nadir -0.12157 Hz at 2.267 s (ours -0.12249 Hz at 2.259 s), ~10 s of wall time."""
    import os
    import subprocess
    import tempfile

    import numpy as np

    from conftest import DIST

    ssp = DIST.parent / "ieee9" / "ieee9.ssp"
    cosim = os.environ.get("DVPP_COSIM", str(DIST.parents[1] / "target" / "release" / "cosim"))
    if not (ssp.exists() and os.path.exists(cosim)):
        pytest.skip("our master's cosim binary or the ieee9 bundle is missing")
    import tomllib

    with open(dpsim_ieee9.ROOT / "studies" / "scenarios" / "ieee9.toml", "rb") as fh:
        step = tomllib.load(fh)["grid"]["event"][0]
    assert step["type"] == "load_step"
    end = 5.0
    rec = dpsim_ieee9.run(end=end, load_step=step)
    t = np.arange(len(rec["coi"])) * rec["h"]
    with tempfile.TemporaryDirectory(prefix="ieee9-") as tmp:
        csv = os.path.join(tmp, "ieee9.csv")
        subprocess.run([cosim, str(ssp), "--out", csv, "--stop", str(end), "--record", "grid.coi.f"],
                       check=True, capture_output=True)
        own_t, own_f = np.loadtxt(csv, delimiter=",", skiprows=1, unpack=True)
    theirs = np.interp(t, own_t, own_f - 1.0)
    mine = rec["coi"] - 1.0
    nrmse = float(np.sqrt(np.mean((mine - theirs) ** 2)) / np.max(np.abs(theirs)))
    k, j = int(np.argmin(mine)), int(np.argmin(own_f))
    f = dpsim_ieee9.load_case()["f_nom"]
    print(f"\nCOI Δf NRMSE {nrmse:.2%}; nadir {mine[k] * f:.5f} Hz at {t[k]:.3f} s, ours "
          f"{(own_f[j] - 1) * f:.5f} Hz at {own_t[j]:.3f} s; wall {rec['wall']:.1f} s")
    assert nrmse < 0.02
    assert abs(mine[k] / (own_f[j] - 1.0) - 1.0) < 0.02
    assert abs(t[k] - own_t[j]) < 0.05
