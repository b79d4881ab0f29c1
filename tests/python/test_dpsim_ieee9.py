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
