"""The DER FMU as fmpy loads it: the case-I units aggregate to T_pf, step responses match the
analytic reference models, ramped dc gains keep the participation condition, limits warn."""
import math

import numpy as np
import pytest
from conftest import DIST
from fmu_slave import Slave

VARIANTS = DIST.parent / "variants"
H, D, S_BASE, S_DVPP = 5.55, 33.33, 100.0, 96.0
TO_DVPP = S_BASE / S_DVPP


def path_of(unit):
    return str(DIST / "dvpp_der.fmu") if unit == "default" else str(VARIANTS / f"dvpp_der-{unit}.fmu")


# Limits lifted for a unit driven open loop (the bus does not answer its angle).
# Open loop: limits lifted, and no delay compensation (the bus does not answer the angle).
OPEN_LOOP = {"I_max": 1e9, "dc.t_budget": 1e-9, "E_max": 1e9, "delay.c": 0.0}


class Unit(Slave):
    """One DER instance through fmpy's FMU2Slave, with its log collected."""

    def __init__(self, unit, params=None, name="der"):
        super().__init__(path_of(unit), name, params)
        self.t = 0.0

    def step(self, h):
        self.fmu.doStep(self.t, h)
        self.t += h

    def warnings(self):
        return [m for status, m in self.messages if status == 1]


def t_pf(w):
    return 1.0 / (H * 1j * w + D)


# --- 1. Sine sweep: the case-I grid-forming units aggregate to T_pf -------------------------------

def measured_t_pf(unit, f, amplitude=0.01, settle=12.0):
    """T_i^pf(j 2π f) of one grid-forming unit driven with a sine on p (held over each step).

    The fundamental of Δf is fitted over whole periods after the transients decayed; the input's
    fundamental is that of the zero-order-hold staircase the FMU sees, A sinc(ωh/2) e^{-jωh/2}."""
    w = 2 * math.pi * f
    period = 1.0 / f
    h = min(1e-3, period / 400)
    n_periods = max(1, math.ceil(2.0 / period))
    start = math.ceil(settle / period) * period
    n_settle, n_fit = round(start / h), round(n_periods * period / h)
    u = Unit(unit, OPEN_LOOP, name=f"{unit}-{f}")
    p0 = u.get("p")[0]
    vp, vdf = [u.vr("p")], [u.vr("df")]
    times, df = np.empty(n_fit), np.empty(n_fit)
    for k in range(n_settle + n_fit):
        u.fmu.setReal(vp, [p0 + amplitude * math.sin(w * k * h)])
        u.fmu.doStep(k * h, h)
        if k >= n_settle:
            times[k - n_settle] = (k + 1) * h
            df[k - n_settle] = u.fmu.getReal(vdf)[0]
    u.free()
    basis = np.column_stack([np.sin(w * times), np.cos(w * times), np.ones_like(times)])
    a, b, _ = np.linalg.lstsq(basis, df, rcond=None)[0]
    x = w * h / 2
    u_phasor = amplitude * TO_DVPP * (math.sin(x) / x) * np.exp(-1j * x)
    return -(a + 1j * b) / u_phasor


FREQUENCIES = [0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0]


def test_case_i_grid_forming_units_aggregate_to_t_pf():
    """Each unit is also compared with its own reference model T_pf/m_i. The strictly proper BESS
    reference matches to ~1e-5; the biproper low-pass references show up to 0.3 % and ωh/2 in
    phase (0.45° at 5 Hz, h = 0.5 ms): their direct feedthrough is seen at the communication
    points half a step late (sampling a held input; it shrinks with h). The aggregate stays within
    0.13 % / 0.04°."""
    mu_w, mu_pv = Unit("wind").get("mu_p")[0], Unit("pv").get("mu_p")[0]

    def reference(unit, s):
        m = {"wind": mu_w / (1.5 * s + 1), "pv": mu_pv / (0.6 * s + 1),
             "bess": 1 - mu_w / (1.5 * s + 1) - mu_pv / (0.6 * s + 1)}[unit]
        return 1.0 / ((H * s + D) * m)

    worst_mag, worst_phase = 0.0, 0.0
    for f in FREQUENCIES:
        w = 2 * math.pi * f
        units = [measured_t_pf(u, f) for u in ("wind", "pv", "bess")]
        for name, t in zip(("wind", "pv", "bess"), units):
            ratio = t / reference(name, 1j * w)
            print(f"  {name:4s} {f:5.2f} Hz: |T_i|/|ref| - 1 = {abs(ratio) - 1:+.1e}, "
                  f"phase {math.degrees(np.angle(ratio)):+.1e} deg")
            assert abs(abs(ratio) - 1) < 0.01 and abs(math.degrees(np.angle(ratio))) < 1.0, (name, f)
        aggregate = 1.0 / sum(1.0 / t for t in units)
        target = t_pf(w)
        mag = abs(abs(aggregate) / abs(target) - 1.0)
        phase = abs(math.degrees(np.angle(aggregate / target)))
        worst_mag, worst_phase = max(worst_mag, mag), max(worst_phase, phase)
        print(f"f = {f:5.2f} Hz: |agg|/|T_pf| - 1 = {mag:.2e}, phase error = {phase:.2e} deg")
        assert mag < 0.01, f"{f} Hz: magnitude off by {mag:.3%}"
        assert phase < 1.0, f"{f} Hz: phase off by {phase:.3f} deg"
    print(f"sweep: worst magnitude error {worst_mag:.2e}, worst phase error {worst_phase:.2e} deg")


# --- 2. Step responses against the analytic reference models -------------------------------------

def lpf_step(mu, tau, t, dp):
    """Δf(t) of T_i^pf = (τ s + 1)/(μ (H s + D)) for a step Δp (DVPP base)."""
    return -(dp / mu) * (1.0 / D + (tau / H - 1.0 / D) * np.exp(-D * t / H))


def complement_step(mus, taus, t, dp):
    """Δf(t) of T_i^pf = T_pf/m with m = 1 - Σ μ_j/(τ_j s + 1) for a step Δp: partial fractions of
    N(s)/(s² Q(s)) (m has a zero at the origin, the step adds the second pole there)."""
    lags = [np.poly1d([tau, 1.0]) for tau in taus]
    prod = np.poly1d([1.0])
    for lag in lags:
        prod = prod * lag
    num_m = prod
    for j, mu in enumerate(mus):
        rest = np.poly1d([1.0])
        for i, lag in enumerate(lags):
            if i != j:
                rest = rest * lag
        num_m = num_m - mu * rest
    # num_m = s · r(s); T_pf/m/s = prod / (s² r(s) (H s + D))
    r = np.poly1d(num_m.coeffs[:-1])
    assert abs(num_m.coeffs[-1]) < 1e-12
    q = r * np.poly1d([H, D])
    n = prod
    a1 = n(0) / q(0)
    a0 = (n.deriv()(0) * q(0) - n(0) * q.deriv()(0)) / q(0) ** 2
    y = a1 * t + a0
    for root in q.roots:
        y = y + (n(root) / (root**2 * q.deriv()(root))) * np.exp(root * t)
    return -dp * np.real(y)


@pytest.mark.parametrize("h", [1e-4, 1e-3, 1e-2])
@pytest.mark.parametrize("unit", ["wind", "pv", "bess", "default"])
def test_step_response_matches_the_reference_model(unit, h):
    u = Unit(unit, OPEN_LOOP, name=f"step-{unit}-{h}")
    p0, mu, lpf1, lpf2, tau = u.get("p", "mu_p", "mu_p_lpf[1]", "mu_p_lpf[2]", "adpf.p.tau")
    dp = 0.02
    u.set("p", p0 + dp)
    n = round(2.0 / h)
    t = np.arange(1, n + 1) * h
    df = np.empty(n)
    for k in range(n):
        u.fmu.doStep(k * h, h)
        df[k] = u.get("df")[0]
    u.free()
    if unit == "bess":
        expected = complement_step([lpf1, lpf2], [1.5, 0.6], t, dp * TO_DVPP)
    elif unit == "default":  # static ADPF m = μ
        expected = -(dp * TO_DVPP / (mu * D)) * (1.0 - np.exp(-D * t / H))
    else:
        expected = lpf_step(mu, tau, t, dp * TO_DVPP)
    err = np.max(np.abs(df - expected))
    print(f"{unit} h = {h}: max |Δf - analytic| = {err:.2e} pu")
    assert err < 1e-4
    assert np.max(np.abs(expected)) > 1e-4  # the response is not trivially small


# --- 3. Ramped dc gains keep the participation condition ----------------------------------------

def test_ramped_dc_gains_keep_the_participation_condition():
    """Grid-following wind, PV (low-pass) and BESS (complement) units share one PLL input; the
    operator ramps their dc gains. Their power changes must sum to that of one unit with m = 1
    at every step (Σ m_i ≡ 1 while the gains move), and a stale complement must break it."""
    h, n = 1e-3, 5000
    names = ["wind", "pv", "bess", "default", "stale"]
    units = {k: Unit("default" if k == "default" else ("bess" if k == "stale" else k), {"mode": 2}, name=k)
             for k in names}
    p0 = {k: u.get("p_ref")[0] for k, u in units.items()}
    worst, stale_worst, moved = 0.0, 0.0, 0.0
    for k in range(n):
        t = k * h
        mu_w = 0.2 + 0.6 * t / (n * h)  # 0.2 → 0.8
        mu_pv = 1.0 - mu_w
        angle = 0.05 * math.sin(2 * math.pi * 0.7 * t) - 2 * math.pi * 50 * 0.002 * t
        for u in units.values():
            u.set("v_angle", angle)
        units["wind"].set("mu_p", mu_w)
        units["pv"].set("mu_p", mu_pv)
        units["bess"].fmu.setReal([units["bess"].vr("mu_p_lpf[1]"), units["bess"].vr("mu_p_lpf[2]")], [mu_w, mu_pv])
        for u in units.values():
            u.fmu.doStep(t, h)
        d = {k: u.get("p_ref")[0] - p0[k] for k, u in units.items()}
        total = d["wind"] + d["pv"] + d["bess"]
        worst = max(worst, abs(total - d["default"]))
        stale_worst = max(stale_worst, abs(d["wind"] + d["pv"] + d["stale"] - d["default"]))
        moved = max(moved, abs(d["wind"]))
    for u in units.values():
        assert not u.warnings(), u.warnings()
        u.free()
    print(f"participation: max |Σ Δp_i - Δp(m = 1)| = {worst:.2e} pu (stale complement: {stale_worst:.2e})")
    assert moved > 1e-3
    assert worst < 1e-9
    assert stale_worst > 1e-4


# --- 4. Primary source, dc side and limits --------------------------------------------------------

def test_availability_step_limits_the_dc_source_and_warns_once():
    u = Unit("wind", {"avail.t_step": 0.5, "avail.dP": -0.3}, name="cloud")
    p = u.get("p")[0]
    h = 1e-3
    avail, vdc = [], []
    for k in range(1000):
        u.fmu.doStep(k * h, h)
        a, v = u.get("P_avail", "v_dc")
        avail.append(a)
        vdc.append(v)
    assert avail[0] == pytest.approx(0.4) and avail[-1] == pytest.approx(0.1)
    assert vdc[400] == pytest.approx(1.0, abs=1e-6)  # before the step the dc link holds 1 pu
    # The source cannot cover p after the step: the link sags (driven open loop, nothing holds
    # p to the link's budget here; in a system the grid's slot does).
    assert min(vdc) < 0.9, min(vdc)
    # One warning per limit episode, not one per step: the source at its availability, then
    # (open loop, the unit's angle drifting from the fixed bus) the link's budget, the current
    # and the modulation limits, each once.
    warnings = u.warnings()
    kinds = ["primary source at its limit", "dc-link power budget", "current limit", "modulation limit"]
    assert sum(kinds[0] in w for w in warnings) == 1, warnings
    assert all(sum(k in w for w in warnings) <= 1 for k in kinds), warnings
    assert len(warnings) <= len(kinds), warnings
    u.free()


def test_grid_following_references_stop_at_the_current_limit():
    # The dc budget lifted: this is about the current limit (I_max = 1.2 at v = 1 pu).
    u = Unit("default", {"mode": 2, "dc.t_budget": 1e-9, "v_dc_min": 0.0}, name="rating")
    h = 1e-3
    s_max = 1.2 * 60.0 / 100.0
    for k in range(2000):
        u.set("v_angle", -2 * math.pi * 50 * 0.02 * k * h)  # a 2 % frequency drop: a large Δp
        u.fmu.doStep(k * h, h)
        p_ref, q_ref = u.get("p_ref", "q_ref")
        assert math.hypot(p_ref, q_ref) <= s_max * (1 + 1e-12)
    assert p_ref == pytest.approx(s_max)  # active current first (limit.priority = 0)
    warnings = [w for w in u.warnings() if "current limit" in w]
    assert len(warnings) == 1, u.warnings()
    u.free()


# --- 5. Coupled to an infinite bus: flat start, q tracks its reference through E -----------------

def injection(e, theta, v, phi, r, x):
    """p + jq that E∠θ injects through r + jx into a bus at V∠φ (per unit)."""
    i = (e * np.exp(1j * theta) - v * np.exp(1j * phi)) / (r + 1j * x)
    s = v * np.exp(1j * phi) * np.conj(i)
    return s.real, s.imag


@pytest.mark.parametrize("unit", ["default", "wind", "bess"])
def test_grid_forming_unit_on_an_infinite_bus_starts_flat_and_tracks_q(unit):
    # The bus answers E∠θ within the step (no exchange delay): no delay compensation (delay.c).
    u = Unit(unit, {"delay.c": 0.0}, name=f"bus-{unit}")
    p0, q0, s_rated, r_f, x_f, mu_q = u.get("p", "q", "S_rated", "R_f", "X_f", "mu_q")
    r, x = r_f * S_BASE / s_rated, x_f * S_BASE / s_rated
    h, v_bus = 1e-3, 1.0
    ps, qs, qrefs = [], [], []
    for k in range(4000):
        if k == 500:
            v_bus = 0.999  # a 0.1 % voltage dip at t = 0.5 s
        e, theta = u.get("E", "theta")
        p, q = injection(e, theta, v_bus, 0.0, r, x)
        u.fmu.setReal([u.vr("p"), u.vr("q"), u.vr("v")], [p, q, v_bus])
        u.fmu.doStep(k * h, h)
        ps.append(p)
        qs.append(q)
        qrefs.append(u.get("q_ref")[0])
    u.free()
    # Initialized behind the impedance at the measured operating point: nothing moves before the dip.
    assert max(abs(p - p0) for p in ps[:500]) < 1e-12
    assert max(abs(q - q0) for q in qs[:500]) < 1e-12
    # q_ref = q0 - T_i^vq Δv: in steady state μ_q/Dq Δv on S_dvpp, here on S_base.
    expected = q0 + mu_q / 0.01 * 0.001 / TO_DVPP
    assert qrefs[-1] == pytest.approx(expected, rel=1e-9)
    assert abs(qs[-1] - qrefs[-1]) < 1e-4 * abs(expected - q0), (qs[-1], qrefs[-1])
