"""The DER FMU as the outer controller of a grid-forming converter in DPsim, a third-party
dynamic-phasor / EMT simulator (issue 17): DPsim realizes the FMU's E∠θ as a voltage source behind
R_f + jX_f and feeds back p, q, v and the angle it measures at the terminal bus
(tests/python/dpsim_host.py; docs/emt.md). In the dynamic-phasor domain at 1 ms and in the
three-phase EMT domain at 50 µs:

1. an island (the converter alone feeds its load) meets the droop law exactly after a load step:
   the frequency the island runs at, read from the angle progression of the bus voltage, is
   Δf = -Δp (S_base/S_dvpp)/D;
2. against a stiff source behind a line, after a load step and a 2° jump of the source's angle,
   the converter's powers settle to their set points (p to p_set, q to q_ref);
3. started from zero voltage, the unit waits, synchronizes when the source comes on, and the
   host closes the converter's breaker without inrush.

The EMT runs also go with the FMU at 1 ms over the network at 50 µs ("emt-fmu1ms"). The unit is
the generic DER with Tdes.H = 0.2 s (dpsim_host.UNIT), so that its droop settles within 0.1 s and
a run lasts 0.5-1.5 s; one dynamic-phasor island run keeps the case study's H = 5.55 s.
"""

import numpy as np
import pytest

from conftest import require_dpsim  # noqa: E402

require_dpsim("test_dpsim.py")

import dpsim_host as host  # noqa: E402

# Load step and angle jump times, run lengths (s).
T_LOAD = 0.1
T_JUMP = 0.7
ISLAND_END = 0.5
STIFF_END = 1.5
# |p - p_set| and |q - q_ref| within this band count as settled (pu on S_base: 0.1 MW, 0.1 Mvar).
SETTLE_BAND = 1e-3


def check_flat_start_and_limits(rec, until):
    """Nothing moves before the first event; no converter limit acts (the example host applies
    none, so none may be needed)."""
    k = round(until / rec["h"])
    drift = np.max(np.abs(rec["p"][:k] - rec["p"][0])) + np.max(np.abs(rec["q"][:k] - rec["q"][0]))
    print(f"  flat start: largest |Δp| + |Δq| before t = {until} s: {drift:.1e} pu, "
          f"largest |df| {np.max(np.abs(rec['df'][:k])):.1e}")
    # The dynamic-phasor circuit starts exactly at its steady state. The EMT one starts at the
    # continuous-time steady state, which the trapezoidal rule at 50 µs misses by ~1e-5 (its
    # inductors' reactance is off by (ωh)²/12 = 2e-5): a small transient.
    if rec["domain"] == "dp":
        assert drift < 1e-10 and np.max(np.abs(rec["df"][:k])) < 1e-12
    else:
        assert drift < 1e-4 and np.max(np.abs(rec["df"][:k])) < 1e-6
    assert not any(on for name, on in rec["flags"].items() if name.startswith("limit.")), rec["flags"]
    assert rec["flags"]["synchronized"]
    assert rec["warnings"] == [], rec["warnings"]
    assert np.max(rec["i_ac"]) < rec["i_limit"][-1]


# (domain, FMU communication step or None for DPsim's step, unit parameters, run length)
RUNS = {
    "dp": ("dp", None, {}, ISLAND_END),
    "emt": ("emt", None, {}, ISLAND_END),
    # The FMU at 1 ms over EMT at 50 µs, E∠θ interpolated in between.
    "emt-fmu1ms": ("emt", 1e-3, {}, ISLAND_END),
    # The case study's inertia: the droop settles with H/D = 0.17 s, so the run lasts 3.1 s.
    "dp-H5.55": ("dp", None, {"Tdes.H": 5.55}, 3.1),
}


def describe(rec, end):
    comm = f", FMU step {rec['comm'] * 1e6:.0f} µs" if rec["comm"] != rec["h"] else ""
    return (f"\n{rec['domain']} {rec['case']}, Tdes.H = {rec['unit']['Tdes.H']} s, h = {rec['h'] * 1e6:.0f} µs"
            f"{comm}: wall {rec['wall']:.2f} s for {end} s ({rec['wall'] / end:.2f} s per simulated s)")


@pytest.mark.parametrize("run", RUNS.values(), ids=RUNS.keys())
def test_island_steady_state_meets_the_droop_law(run):
    domain, comm, params, end = run
    rec = host.run(domain, "island", end, [(T_LOAD, "load")], params=params, comm=comm)
    c = host.droop_check(rec)
    print(describe(rec, end))
    print(f"  Δp = {c['dp']:.6f} pu on S_base; Δf: law {c['df_law']:.10e}, bus angle {c['df_angle']:.10e} "
          f"(rel. error {c['err_angle']:.1e}), FMU df {c['df_fmu']:.10e} (rel. error {c['err_fmu']:.1e})")
    check_flat_start_and_limits(rec, T_LOAD)
    assert 0.09 < c["dp"] < 0.11  # the 0.1 pu load step, at the settled voltage and frequency
    assert c["err_angle"] < 1e-6
    assert c["err_fmu"] < 1e-6


@pytest.mark.parametrize("domain, comm", [("dp", None), ("emt", None), ("emt", 1e-3)],
                         ids=["dp", "emt", "emt-fmu1ms"])
def test_stiff_grid_run_settles_to_the_set_points(domain, comm):
    rec = host.run(domain, "stiff", STIFF_END, [(T_LOAD, "load"), (T_JUMP, ("jump", -2.0))], comm=comm)
    t, h = rec["t"], rec["h"]
    print(describe(rec, STIFF_END))
    check_flat_start_and_limits(rec, T_LOAD)
    ep, eq = rec["p"] - rec["p_set"], rec["q"] - rec["q_ref"]
    for name, start, end in (("load step", T_LOAD, T_JUMP), ("angle jump", T_JUMP, STIFF_END + h)):
        # The event acts from sample k0 on; k1 is the last sample before the next one.
        k0, k1 = round(start / h), round(end / h) - 1
        span = slice(k0, k1 + 1)
        settle_p = host.settling_time(t[span], ep[span], 0.0, SETTLE_BAND) - start
        settle_q = host.settling_time(t[span], eq[span], 0.0, SETTLE_BAND) - start
        peak = np.max(np.abs(ep[span]))
        print(f"  {name} at {start} s: peak |p - p_set| {peak:.4f} pu, within {SETTLE_BAND} pu after "
              f"{settle_p * 1e3:.0f} ms (p), {settle_q * 1e3:.0f} ms (q); at {t[k1]:.3f} s: p - p_set = "
              f"{ep[k1]:.1e}, q - q_ref = {eq[k1]:.1e}, df = {rec['df'][k1]:.1e}")
        assert peak > 0.01  # the disturbance moved the converter
        assert settle_p < 0.4 and settle_q < 0.4
        assert abs(ep[k1]) < 1e-6 and abs(eq[k1]) < 1e-6
        assert abs(rec["df"][k1]) < 1e-8


@pytest.mark.parametrize("domain, comm", [("dp", None), ("emt", 1e-3)], ids=["dp", "emt-fmu1ms"])
def test_start_from_zero_voltage_waits_synchronizes_and_ramps(domain, comm):
    """Every node starts at 0 V; the stiff source comes on at 50 ms. The unit, initialized with
    v = 0 (and p = its dispatch), waits with zero current; the host keeps the converter's breaker
    open until the unit reports `synchronized` (startup.t_hold = 50 ms after the voltage is up and
    steady), then closes it: no inrush, and the set point ramps to the dispatch over
    startup.ramp (0.3 s here, to keep the run short)."""
    t_on, ramp, end = 0.05, 0.3, 1.0
    rec = host.run(domain, "startup", end, [(t_on, "energize")], params={"startup.ramp": ramp}, comm=comm)
    t, h, closed = rec["t"], rec["h"], rec["t_closed"]
    print(describe(rec, end))
    assert closed is not None
    k = round(closed / h)
    print(f"  breaker closed at {closed:.4f} s (source on at {t_on} s); largest current in the 5 ms after: "
          f"{np.max(rec['i_ac'][k:k + round(5e-3 / h)]):.1e} pu of rated; at {end} s: p = {rec['p'][-1]:.9f}, "
          f"p - p_set = {rec['p'][-1] - rec['p_set'][-1]:.1e}, q - q_ref = {rec['q'][-1] - rec['q_ref'][-1]:.1e}")
    assert t_on + 0.05 <= closed < t_on + 0.08
    assert np.max(np.abs(rec["p"][:k])) < 1e-9 and np.max(np.abs(rec["q"][:k])) < 1e-9  # waited at zero current
    assert np.max(rec["i_ac"][k:k + round(5e-3 / h)]) < 1e-3  # closed without inrush
    mid = round((closed + ramp / 2) / h)
    assert abs(rec["p_set"][mid] - 0.3 / 2) < 0.01  # ramping
    assert rec["p_set"][-1] == pytest.approx(0.3)  # the dispatch, the start value of p
    assert abs(rec["p"][-1] - 0.3) < 1e-6 and abs(rec["q"][-1] - rec["q_ref"][-1]) < 1e-6
    assert rec["flags"]["synchronized"] and rec["warnings"] == [], rec["warnings"]
    assert not any(on for name, on in rec["flags"].items() if name.startswith("limit."))
