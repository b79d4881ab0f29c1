"""The short variant of `cargo xtask emt-case1`: case study I's two events in DPsim EMT (the nine-bus system with the DVPP's EMT controller FMUs) for 3 s each, against our master's phasor twin.

tests/python/emt_case1.py runs each event (the 28 MW load step at bus 2 and the cloud on the PV
plant, both at t = 1 s) in DPsim EMT at 50 µs and our master's phasor runs of the same case
(phasor_case1_<event>: the units' outer loops as the EMT controllers'; case1_<event>). Over the
3 s the figures the full 20 s runs are judged by hold where a 3 s window can show them: the
machines' COI Δf within 5 % NRMSE of the phasor twin's and its nadir within 5 %, the PCC Δf
against the operator's ref.df no worse than the twin's own by more than a point (the ≤ 5 %
over the run is the 20 s figure: the first 2 s after an event are the transient, 13-15 %), a
flat start, the dc links' energy accounts closed and their voltages near 1 pu, no converter
limit, no warning, and the CSV and the figure written. Measured (3 s): load COI 0.93 %, nadir
-0.13298 vs -0.13453 Hz (1.2 %), PCC vs ref.df 12.6 % (twin 13.0 %); cloud COI 0.95 %, nadir
1.1 %, 14.3 % (twin 14.6 %); lowest v_dc 0.990 (PV, load) and 0.977 (PV, cloud); about 12 s of
wall time per event.
"""
import pytest

from conftest import require_dpsim  # noqa: E402

require_dpsim("test_emt_case1.py")

import dpsim_ieee9_dvpp as dvpp  # noqa: E402
import emt_case1  # noqa: E402

END = 3.0


@pytest.fixture(scope="module")
def studies():
    root = dvpp.bundle()
    if not all((root / f"{n}.fmu").exists() for n in (*dvpp.UNITS, "operator", "plant")):
        pytest.skip(f"the bundled emt_thevenin system is missing ({root})")
    return {event: emt_case1.study(event, END) for event in dvpp.EVENTS}


@pytest.mark.parametrize("event", dvpp.EVENTS)
def test_case_one_in_dpsim_emt_meets_its_phasor_twin(studies, event, tmp_path):
    rec, twin, _, fig = studies[event]
    coi = fig["twin"]["coi"]
    print(f"\n{event}: COI vs twin {coi['nrmse']:.2%}, nadir {coi['nadir'][0]:.5f} vs {coi['nadir_own'][0]:.5f} Hz; "
          f"PCC vs ref.df {fig['match_run']:.2%} (twin {fig['twin_match_run']:.2%}); lowest v_dc "
          + ", ".join(f"{u} {d['v_min']:.4f}" for u, d in fig["dc"].items()) + f"; wall {fig['wall']:.1f} s")
    assert max(fig["flat"].values()) < 1e-4
    assert coi["nrmse"] < 0.05
    assert abs(coi["nadir"][0] / coi["nadir_own"][0] - 1) < 0.05
    assert fig["match_run"] < fig["twin_match_run"] + 0.01
    for unit, d in fig["dc"].items():
        assert abs(d["residual"]) < 1e-9, unit
        assert 0.95 < d["v_min"] and d["v_max"] < 1.05, (unit, d)
    assert fig["limits"] == [], fig["limits"]
    assert fig["warnings"] == [], fig["warnings"]
    csv, svg = tmp_path / f"{event}.csv", tmp_path / f"{event}.svg"
    emt_case1.write_csv(rec, csv)
    emt_case1.write_figure(rec, twin, svg)
    header = csv.read_text().splitlines()[0].split(",")
    rows = csv.read_text().count("\n") - 1
    assert header[:4] == ["time", "pcc.f", "pcc.v", "coi.f"] and rows == round(END * 1e3) + 1
    assert svg.read_text().count("<polyline") >= 10
