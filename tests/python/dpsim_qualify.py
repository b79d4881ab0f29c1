"""The qualification suite's tests in DPsim EMT: each preset unit alone against a host-driven Thevenin grid, judged as `cargo xtask qualify` judges them, and the two hosts' agreement.

The subjects, tests, parameters and criteria of studies/src/qualify.rs (docs/qualification.md):
each preset unit (wind 46, PV 73, BESS 60 MVA) with grid-forming option A (``inner.kind`` 0),
option B (1) and grid-following (``mode`` 2, ``vq.tau`` 2 s) where the test applies, the unit
FMU and its start values exactly as the master's bundled system ``dist/qualify_<unit>/``
(its SSP's parameter bindings), the unit at its plant dispatch ``der[1].p0`` (pu on S_base,
``q0`` 0) with the source at the plant's default E = 1.02 pu (the master's initialization), the Thevenin source at
SCR 3 on the unit's rating (X/R 10), every event at 1 s, every run to 3.5 s at 50 µs:

- the phase jump (+10°: largest |Δp| in the first 100 ms ≥ 0.2 pu; ±25°: rides through),
  -1 Hz/s for 0.5 s (the inertia from the energy), ±5 Hz/s for 0.4 s (rides through): the host
  drives the source (dpsim_ride_through's sampling rule);
- dips of the source to 0.5 and 0.1 pu for 150 ms (rides through with the fast fault current
  min(2 (Δv - 0.1), 1) - 0.1 pu), faults at the PCC for 150 ms, phase a to ground and phases b-c,
  R = X = 0.0096 pu of the rating per branch (rides through, each phase's converter current
  ≤ 1.05 I_max): dpsim_ride_through's fault, its poles opening at current zero from 1.15 s;
- the SCR step: a three-phase fault for 150 ms with the source's impedance at SCR 2 in parallel
  with a line of SCR 8 (together SCR 10), which leaves service when the fault clears (its poles
  at their currents' zeros from 1.15 s; our plant removes it at the step boundary at 1.15 s):
  rides through;
- loss of the grid (the source's breaker opens at 1 s, its poles at current zero): the local
  load of 0.4 + j0.04 pu on, the unit at 0.6 pu (BESS 0.8; charging: -0.8) with the PCC at 1 pu
  before; the PCC voltage within 0.9-1.1 pu over the last 0.5 s, the PCC frequency (an SRF-PLL
  on the PCC voltage, the plant's meter: kp 60, ki 240) within the tunnel around T_pf's response
  to the measured power change.

The unit's dc link and primary source are the plant's (``DcLink``: fmu-emt-plant/src/dc.rs in
Python, C_dc 0.096 s, G_dc 0.05 pu, the scenario's tau_dc, the source within the unit's
[p_src_min, p_src_max]) beside DPsim's circuit: the host feeds the FMU its v_dc, scales the
converter's voltage by it and charges the link with the converter's power over each step (the
trapezoidal mean of the imposed samples times the converter current, as DPsim integrates).
Without it (v_dc = 1, an unlimited source) a unit can deliver beyond its available power.

Host cost: the loop makes one call per FMI function per step on preallocated ctypes arrays
(fmpy's raw functions, no per-call list conversion), writes the inputs through a numpy view of
those arrays, precomputes the source's samples, and records the raw solution (converter and grid
currents, capacitor and PCC voltages) into preallocated arrays: the figures are computed after
the run, vectorized. ``--profile`` prints where a run's time goes.

``python tests/python/dpsim_qualify.py [--only TEXT] [--jobs N] [--docs docs/qualification.md]
[--master results/qualification.csv]``: the runs (or those whose name contains TEXT) in N
processes (default 2), the table of verdicts and figures beside the master's (from
``--master``, default the matrix in docs/qualification.md), results/dpsim_qualification.csv;
with --docs the table between the page's dpsim-qualify markers.
"""
import ctypes
import math
import os
import re
import sys
import time
import zipfile
from dataclasses import dataclass

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import dpsim_emt_host as host  # noqa: E402
from dpsim_emt_host import FILTER, SPACE_VECTOR, V_LL, V_R, W_NOM, ABC, Converter, DerEmt, Network  # noqa: E402
from dpsim_ride_through import R_LEAK, Fault  # noqa: E402
from fmu_slave import Slave  # noqa: E402

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
# The bundled systems: beside DVPP_DIST (dist/default) as cargo xtask test sets it, else dist/.
DIST = os.path.dirname(os.path.normpath(os.environ["DVPP_DIST"])) if "DVPP_DIST" in os.environ else \
    os.path.join(ROOT, "dist")
F_NOM = host.F_NOM
H = 50e-6
T_EVENT, T_END = 1.0, 3.5
SCR, SCR_STEP = 3.0, (10.0, 2.0)
SYNC_HZ, TAIL = 0.05, 0.5
I_TOLERANCE, JUMP_POWER, H_MIN = 0.05, 0.2, 2.5
K_FFC, FFC_TOLERANCE = 2.0, 0.1
ISLAND_V = (0.9, 1.1)
I_MAX = 1.2
S_BASE = 100.0
TDES_H, TDES_D = 5.55, 33.33
DURATION, RAMP = 0.15, 0.4
ENERGY_AFTER = 1.0
UNSTEADY = 0.02
ROCOF1 = (-1.0, 0.5)
Z_FAULT = 0.0096
ISLAND_LOAD = complex(0.4, 0.04)
ISLAND_DISPATCH = {(False, "BESS"): 0.8, (False, "wind"): 0.6, (False, "PV"): 0.6, (True, "BESS"): -0.8}
TUNNEL_F = (0.002, 0.1, 0.5, 0.3)  # abs, rel, widen, tau
ISLAND_GRACE = 0.05
PLL = (60.0, 240.0)
E_SOURCE = 1.02  # the plant's default thevenin.E (pu)
DAMPING_R = 1e3  # pu of the rating: the PCC's damping resistor (dpsim_ride_through's)
R_ON = 1e-4  # a closed breaker pole, pu of the rating's impedance

SUBJECTS = {"wind": ("qualify_wind", "wind", 46.0), "PV": ("qualify_pv", "pv", 73.0),
            "BESS": ("qualify_bess", "bess", 60.0)}
CONTROLS = {"grid-forming, option A": ("A", {}), "grid-forming, option B": ("B", {"inner.kind": 1}),
            "grid-following": ("GFL", {"mode": 2, "vq.tau": 2.0})}


@dataclass(frozen=True)
class Test:
    """One test of the suite: ``kind`` jump (value: degrees), rocof (Hz/s, ``duration``), dip
    (retained pu), fault (2 phase a to ground, 3 phases b-c), scrstep, island (value 1:
    charging); ``name`` the master's."""

    name: str
    kind: str
    value: float = 0.0
    duration: float = RAMP

    def forming_only(self):
        return self.kind == "island" or self.name.startswith(("1. phase jump +10", "2. -1 Hz/s"))

    def applies(self, subject, control):
        if self.forming_only() and control == "grid-following":
            return False
        return not (self.kind == "island" and self.value == 1.0 and subject != "BESS")

    def end(self):
        if self.kind in ("dip", "fault", "scrstep"):
            return T_EVENT + DURATION
        return T_EVENT + (self.duration if self.kind == "rocof" else 0.0)

    def phasor(self, t, h):
        """The source's phasor over [t, t + h), per unit of its initial one (dpsim_ride_through)."""
        tol = 1e-9 * max(abs(t), 1.0)
        if self.kind == "dip" and T_EVENT - tol <= t < T_EVENT + DURATION - tol:
            return complex(self.value)
        if self.kind == "jump" and t >= T_EVENT - tol:
            return complex(math.cos(math.radians(self.value)), math.sin(math.radians(self.value)))
        if self.kind == "rocof":
            tau = max(t + 0.5 * h - T_EVENT, 0.0)
            r = min(tau, self.duration)
            a = 2 * math.pi * self.value * (0.5 * r * r + self.duration * max(tau - r, 0.0))
            return complex(math.cos(a), math.sin(a))
        return complex(1.0)

    def f_grid(self, t):
        if self.kind != "rocof":
            return np.full_like(t, F_NOM)
        return F_NOM + self.value * np.clip(t - T_EVENT, 0.0, self.duration)


TESTS = (
    Test("1. phase jump +10°, SCR 3", "jump", 10.0),
    Test("1. phase jump +25°, SCR 3", "jump", 25.0),
    Test("1. phase jump -25°, SCR 3", "jump", -25.0),
    Test("2. -1 Hz/s for 0.5 s (inertia)", "rocof", ROCOF1[0], ROCOF1[1]),
    Test("2. +5 Hz/s for 0.4 s", "rocof", 5.0),
    Test("2. -5 Hz/s for 0.4 s", "rocof", -5.0),
    Test("4. dip to 0.5 pu, 150 ms", "dip", 0.5),
    Test("4. dip to 0.1 pu, 150 ms", "dip", 0.1),
    Test("4. phase a to ground, 150 ms", "fault", 2),
    Test("4. phases b-c, 150 ms", "fault", 3),
    Test("5. SCR 10 → 2 with a fault", "scrstep"),
    Test("6. loss of the grid, discharging", "island", 0.0),
    Test("6. loss of the grid, charging", "island", 1.0),
)


def jobs():
    return [(t, s, c) for t in TESTS for s in SUBJECTS for c in CONTROLS if t.applies(s, c)]


def job_name(test, subject, control):
    return f"{test.name}, {subject}, {control}"


def impedance(scr):
    """The source's impedance (pu on the rating) for ``scr``, X/R 10."""
    z = 1.0 / scr / math.sqrt(101.0)
    return complex(z, 10.0 * z)


def bindings(system, unit):
    """The unit's start values in the master's bundled system (its SSP's parameter bindings)."""
    ssp = os.path.join(DIST, system, f"{system}.ssp")
    with zipfile.ZipFile(ssp) as z:
        ssd = z.read("SystemStructure.ssd").decode()
    comp = ssd.split(f'<ssd:Component name="{unit}"', 1)[1].split("</ssd:Component>", 1)[0]
    out = {}
    for name, kind, value in re.findall(r'<ssv:Parameter name="([^"]+)">\s*<ssv:(\w+) value="([^"]*)"', comp):
        out[name] = {"Real": float, "Integer": int, "Boolean": lambda x: x == "true"}[kind](value)
    return out


class Breaker:
    """A three-pole breaker from ``a`` to ``b`` in series with the inductor ``l`` (whose current
    it carries): one ph3.Switch per pole in parallel, each closed on its own phase only; each
    pole opens at the first step boundary after its current crossed zero (``open_at_zero``)."""

    def __init__(self, net, name, a, b, z_b):
        self.poles = []
        for k in range(3):
            closed = np.full(3, R_LEAK * 1e6)
            closed[k] = R_ON * z_b
            sw = net.ph3.Switch(f"sw_{name}{k}", net.log)
            sw.set_parameters(host.R_OPEN * np.eye(3), np.diag(closed), True)
            self.poles.append(net.add(sw, a, b))
        self.closed = [True] * 3
        self.last = None

    def bind(self, inductor):
        self.i = inductor.attr("i_intf")

    def open_at_zero(self):
        now = self.i.get()[:, 0].copy()
        if self.last is not None:
            for k in range(3):
                if self.closed[k] and self.last[k] * now[k] <= 0.0:
                    self.poles[k].open()
                    self.closed[k] = False
        self.last = now
        return any(self.closed)


class Circuit:
    """The unit (three-wire), the PCC's damping resistor (and for the island the local load),
    the fault (if any), and the Thevenin source behind its impedance (and for the SCR step the
    parallel line behind a breaker; for the island the source's breaker)."""

    def __init__(self, test, subject, s_rated, f, p0):
        net = self.net = Network()
        z_b = V_LL**2 / (s_rated * 1e6)
        island = test.kind == "island"
        z_th = impedance(SCR_STEP[1] if test.kind == "scrstep" else SCR)
        z_par = impedance(SCR_STEP[0] - SCR_STEP[1]) if test.kind == "scrstep" else None
        z_grid = z_th if z_par is None else z_th * z_par / (z_th + z_par)
        load = ISLAND_LOAD if island else 0.0
        s0 = complex(ISLAND_DISPATCH[(test.value == 1.0, subject)] if island else p0)
        y = load.conjugate() + 1.0 / DAMPING_R  # the PCC's shunt admittance
        # The PCC at v∠0: at 1 pu for the island (the master sets E so), else with |E| the plant's.
        v = complex(1.0)
        for _ in range(0 if island else 50):
            e = v + z_grid * (v * y - (s0 / v).conjugate())
            v = v * E_SOURCE / abs(e)
        i_g = (s0 / v).conjugate()
        n_pcc = net.node("pcc", v)
        self.converter = Converter(net, "unit", s_rated * 1e6, f, n_pcc, v, i_g, three_wire=True)
        net.add(net.ph3.Resistor("r_damping", net.log), n_pcc, net.gnd, DAMPING_R * z_b)
        if island:
            z_load = 1.0 / (ISLAND_LOAD.conjugate())
            net.rl("load", n_pcc, net.gnd, z_load, z_b, v, v / z_load, three_wire=True)
        i_grid = v * y - i_g  # from the source into the PCC
        self.e0 = v + z_grid * i_grid
        n_th = net.node("thevenin", self.e0)
        self.source = net.controlled_source("thevenin", n_th, self.e0)
        i_th = (self.e0 - v) / z_th
        self.breaker = self.fault = None
        if island:
            n_b = net.node("breaker", v)
            self.l_th = net.rl("thevenin", n_th, n_b, z_th, z_b, self.e0, i_th)
            self.breaker = Breaker(net, "breaker", n_b, n_pcc, z_b)
        else:
            self.l_th = net.rl("thevenin", n_th, n_pcc, z_th, z_b, self.e0, i_th)
        if z_par is not None:
            n_b = net.node("parallel", v)
            self.l_par = net.rl("parallel", n_th, n_b, z_par, z_b, self.e0, (self.e0 - v) / z_par)
            self.breaker = Breaker(net, "parallel", n_b, n_pcc, z_b)
        if test.kind in ("fault", "scrstep"):
            kind = 1 if test.kind == "scrstep" else int(test.value)
            self.fault = Fault(net, n_pcc, v, kind, complex(Z_FAULT, Z_FAULT), z_b)
        self.sim = net.start("dvpp_qualify", H)
        self.converter.bind()
        if self.fault:
            self.fault.bind()
        if self.breaker:
            self.breaker.bind(self.l_par if z_par is not None else self.l_th)
        self.v_pcc, self.e_ref = n_pcc.attr("v"), self.source.attr("V_ref")

    def stop(self):
        self.sim.stop()
        self.net.cleanup()


def source_samples(e0, test, n):
    """The source's instantaneous voltages (V) for DPsim's solutions at t_k, k = 0..n (shape
    (n + 1, 3, 1)): the mean at t_k of the phasors held over the two steps meeting there."""
    x = np.array([e0 * 0.5 * (test.phasor((k - 1) * H, H) + test.phasor(k * H, H)) for k in range(n + 1)])
    t = np.arange(n + 1) * H
    return np.ascontiguousarray((V_R * (x[:, None] * np.exp(1j * W_NOM * t)[:, None] * ABC).real)[:, :, None])


class DcLink:
    """The plant's dc link and primary source (fmu-emt-plant/src/dc.rs, its defaults C_dc 0.096 s,
    G_dc 0.05 pu and the scenario's tau_dc): stored energy ``w`` = C_dc v_dc²/2 and the source
    current ``i_src`` lagging the unit's command i_dc_ref by tau_dc within its power range
    [p_src_min, p_src_max]; the converter draws ``e_ac`` over each step (pu·s on the rating)."""

    V_FLOOR = 0.05

    def __init__(self, tau, p_conv, c=0.096, g=0.05):
        self.c, self.g, self.tau = c, g, tau
        self.i_src, self.w = p_conv + g, 0.5 * c

    def v(self):
        return math.sqrt(2.0 * max(self.w, 0.0) / self.c)

    def _charge(self, i0, i_ref, t):
        return i_ref * t - (i0 - i_ref) * self.tau * math.expm1(-t / self.tau)

    def step(self, i_ref, e_ac, h, lo_p, hi_p):
        v_range = max(self.v(), self.V_FLOOR)
        lo, hi = lo_p / v_range, max(lo_p, hi_p) / v_range
        i0 = min(max(self.i_src, lo), hi)
        bound = hi if i_ref > hi else lo if i_ref < lo else None
        t_b = self.tau * math.log((i0 - i_ref) / (bound - i_ref)) if bound is not None else math.inf
        if t_b < h:
            charge, i1 = self._charge(i0, i_ref, t_b) + bound * (h - t_b), bound
        else:
            charge, i1 = self._charge(i0, i_ref, h), i_ref + (i0 - i_ref) * math.exp(-h / self.tau)
        v0 = self.v()
        v1 = math.sqrt(2.0 * max(self.w + v0 * charge - self.g * v0 * v0 * h - e_ac, 0.0) / self.c)
        self.w += 0.5 * (v0 + v1) * charge - self.g * h * 0.5 * (v0 * v0 + v1 * v1) - e_ac
        self.i_src = i1
        return self.w > 0.0


class Stepper:
    """The FMU's three calls per step (fmi2SetReal, fmi2DoStep, fmi2GetReal) through fmpy's raw
    ctypes functions on preallocated arrays: ``u`` (numpy view) the inputs, ``y`` the outputs
    m_a, m_b, m_c, df."""

    OUT = ("m_a", "m_b", "m_c", "df", "i_dc_ref", "p_src_min", "p_src_max")

    def __init__(self, der):
        f = der.fmu._functions
        self.set_real, self.do_step, self.get_real = f["fmi2SetReal"], f["fmi2DoStep"], f["fmi2GetReal"]
        self.c = der.fmu.component
        self.vr_in = (ctypes.c_uint * 10)(*der.vr_in)
        self.x_in = (ctypes.c_double * 10)()
        self.u = np.ctypeslib.as_array(self.x_in)
        self.vr_out = (ctypes.c_uint * len(self.OUT))(*[der.vr(n) for n in self.OUT])
        self.x_out = (ctypes.c_double * len(self.OUT))()
        self.y = np.ctypeslib.as_array(self.x_out)
        self.get()

    def get(self):
        return self.get_real(self.c, self.vr_out, len(self.OUT), self.x_out)

    def step(self, t):
        """One step from t; the FMI status (0 OK, 1 warning, above: stopped)."""
        self.set_real(self.c, self.vr_in, 10, self.x_in)
        status = self.do_step(self.c, t, H, 1)
        if status > 1:
            return status
        return max(status, self.get())


def run(test, subject, control, t_end=T_END, profile=False):
    """One run: the raw solution per step (``u``: the FMU's inputs, ``vpcc`` the PCC's phase
    voltages in V, ``df``), the trip (t, message) or None, the wall time of the loop and, with
    ``profile``, the time per part of the step."""
    system, unit, rating = SUBJECTS[subject]
    path = os.path.join(DIST, system, f"{unit}.fmu")
    params = {**bindings(system, unit), **CONTROLS[control][1]}
    probe = Slave(path, "probe", params)
    info = dict(zip(host.UNIT_INFO, probe.get(*host.UNIT_INFO)))
    probe.free()
    if abs(info["S_rated"] - rating) > 1e-9:
        raise ValueError(f"{path}: S_rated = {info['S_rated']}, the study's {subject} is {rating} MVA")
    p0 = _plant_p0(system) * S_BASE / rating
    circuit = Circuit(test, subject, rating, {k: info[k] for k in FILTER}, p0)
    conv = circuit.converter
    n = round(t_end / H)
    e = source_samples(circuit.e0, test, n)
    der = DerEmt(params, conv.measure(), name=job_name(test, subject, control), path=path)
    st = Stepper(der)
    volts = info["vdc_ratio"] / 2.0 * V_R
    scale = np.array([1.0 / V_R] * 3 + [-1.0 / conv.i_r] * 6)
    u, y, x_out = st.u, st.y, st.x_out
    u[9] = 1.0
    with open(os.path.join(ROOT, "studies", "scenarios", f"{system}.toml"), "rb") as fh:
        import tomllib

        tau_dc = tomllib.load(fh)["emt"]["plant"]["units"][0]["tau_dc"]
    rec_u, rec_v, rec_df = np.empty((n + 1, 10)), np.empty((n + 1, 3)), np.empty(n + 1)
    v_cap, i_f, i_g, v_pcc, e_ref, v_ref = conv.v_cap, conv.i_f, conv.i_g, circuit.v_pcc, circuit.e_ref, conv.v_ref
    sim = circuit.sim

    def measure():
        u[0:3] = v_cap.get()[:, 0]
        u[3:6] = i_f.get()[:, 0]
        u[6:9] = i_g.get()[:, 0]
        u[:9] *= scale

    measure()
    rec_u[0], rec_v[0], rec_df[0] = u, v_pcc.get()[:, 0], y[3]
    last = y[:3] * volts
    # The converter's power (pu on the rating) at the solution: its imposed sample times i_f.
    p_last = float(conv.v_ref.get()[:, 0] @ u[3:6]) / V_R * (2.0 / 3.0)
    dc = DcLink(tau_dc, p_last)
    k_event, k_clear = round(T_EVENT / H), round(test.end() / H)
    fault, breaker = circuit.fault, circuit.breaker
    fault_on, breaker_on = False, breaker is not None
    k_open = k_event if test.kind == "island" else k_clear
    trip, end = None, n
    parts = np.zeros(4)
    clock = time.perf_counter
    started = clock()
    for k in range(n):
        if profile:
            t0 = clock()
        status = st.step(k * H)
        if status > 1:
            errors = [m for s, m in der.messages if s >= 3]
            trip, end = (k * H, errors[-1] if errors else f"fmi2DoStep returned {status}"), k
            break
        if profile:
            t1 = clock()
        if fault and k + 1 == k_event:
            fault.close()
            fault_on = True
        elif fault_on and k >= k_clear:
            fault_on = fault.open_at_zero()
        if breaker_on and k + 1 >= k_open:
            breaker_on = breaker.open_at_zero()
        now = y[:3] * (volts * u[9])
        sample = 0.5 * (last + now)
        v_ref.set(sample.reshape(3, 1))
        last = now
        e_ref.set(e[k + 1])
        if profile:
            t2 = clock()
        sim.next()
        if profile:
            t3 = clock()
        measure()
        p_now = float(sample @ u[3:6]) * (2.0 / 3.0) / V_R
        if not dc.step(x_out[4], 0.5 * (p_last + p_now) * H, H, x_out[5], x_out[6]):
            trip, end = ((k + 1) * H, "the dc link is discharged (DPsim host)"), k
            break
        p_last = p_now
        u[9] = dc.v()
        rec_u[k + 1] = u
        rec_v[k + 1] = v_pcc.get()[:, 0]
        rec_df[k + 1] = y[3]
        if profile:
            parts += (t1 - t0, t2 - t1, t3 - t2, clock() - t3)
    wall = clock() - started
    if trip is None:
        der.fmu.terminate()
    der.fmu.freeInstance()
    circuit.stop()
    s = end + 1
    return {"u": rec_u[:s], "vpcc": rec_v[:s], "df": rec_df[:s], "t": np.arange(s) * H, "trip": trip,
            "wall": wall, "steps": end, "parts": parts, "test": test, "subject": subject, "control": control,
            "t_end": t_end}


def _plant_p0(system):
    """The unit's dispatch der[1].p0 (pu on S_base) from the study's scenario."""
    import tomllib

    with open(os.path.join(ROOT, "studies", "scenarios", f"{system}.toml"), "rb") as f:
        return tomllib.load(f)["emt"]["plant"]["units"][0]["p0"]


def at(t, x):
    return min(int(np.searchsorted(t, x - 1e-9)), len(t) - 1)


def pll(v_ab):
    """The plant's SRF-PLL (fmu-emt-plant/src/meter.rs) on the PCC's space vectors: frequency, Hz."""
    kp, ki = PLL
    theta, dw, xi = math.atan2(v_ab[0].imag, v_ab[0].real), 0.0, 0.0
    out = np.empty(len(v_ab))
    out[0] = F_NOM
    for k in range(1, len(v_ab)):
        theta += (W_NOM + dw) * H
        x = v_ab[k] * complex(math.cos(theta), -math.sin(theta))
        err = 0.0 if abs(x) < 1e-9 else math.atan2(x.imag, x.real)
        xi += ki * err * H
        dw = kp * err + xi
        out[k] = F_NOM + dw / (2 * math.pi)
    return out


def measure(rec):
    """The master's measurements (studies/src/qualify.rs, ``measure``) from one run."""
    test = rec["test"]
    m = {"trip": rec["trip"], "sync_hz": math.nan, "i_peak": [math.nan] * 3, "dp_100ms": math.nan,
         "energy": math.nan, "energy_event": math.nan, "i_reactive": math.nan, "dv": math.nan,
         "v_tail": (math.nan, math.nan), "unsteady": math.nan, "excursion": math.nan, "wall": rec["wall"],
         "steps": rec["steps"]}
    if rec["trip"] is not None:
        return m
    t, u = rec["t"], rec["u"]
    v_sv = (rec["vpcc"] @ SPACE_VECTOR) / V_R
    i_sv = u[:, 6:9] @ SPACE_VECTOR
    s = v_sv * i_sv.conjugate()
    p, q, v = s.real, s.imag, np.abs(v_sv)
    i_abs = np.abs(u[:, 3:6]) / I_MAX
    m["i_peak"] = [float(x) for x in np.max(i_abs, axis=0)]
    f_unit = (1.0 + rec["df"]) * F_NOM
    f_grid = test.f_grid(t)
    pre, ev = at(t, T_EVENT - 0.1), at(t, T_EVENT)
    p0, v0 = np.mean(p[pre:ev]), np.mean(v[pre:ev])
    m["p0"], m["q0"], m["v0"] = float(p0), float(np.mean(q[pre:ev])), float(v0)
    m["dp_100ms"] = float(np.max(np.abs(p[ev:at(t, T_EVENT + 0.1)] - p0)))
    end = at(t, test.end())
    m["energy_event"] = float(np.sum(p[ev:max(end, ev + 1)] - p0) * H)
    m["energy"] = float(np.sum(p[ev:max(at(t, test.end() + ENERGY_AFTER), ev + 1)] - p0) * H)
    m["unsteady"] = float(np.max(np.abs(p[at(t, 0.2):ev] - p0)))
    if test.kind in ("dip", "fault", "scrstep"):
        a = at(t, T_EVENT + 0.05)
        m["i_reactive"] = float(np.sum(q[a:end] / np.maximum(v[a:end], 1e-3)) / max(end - a, 1))
        m["dv"] = float(v0 - np.sum(v[a:end]) / max(end - a, 1))
    tail = at(t, T_END - TAIL)
    m["v_tail"] = (float(np.min(v[tail:])), float(np.max(v[tail:])))
    m["sync_hz"] = float(np.max(np.abs(f_unit[tail:] - f_grid[tail:])))
    if test.kind == "island":
        # The master's envelope on 1 ms traces: Δf_ref from H dΔf/dt + D Δf = -Δp.
        every = at(t, 1e-3)
        tr_t, tr_p, tr_f = t[::every], p[::every], pll(v_sv)[::every]
        dt = tr_t[1] - tr_t[0]
        e = at(tr_t, T_EVENT)
        f0 = np.mean(tr_f[at(tr_t, T_EVENT - 0.1):e])
        df, expected = 0.0, np.empty(len(tr_t))
        for k in range(len(tr_t)):
            expected[k] = df
            if k >= e:
                df += dt / TDES_H * (-(tr_p[k] - p0) - TDES_D * df)
        measured = (tr_f - f0) / F_NOM
        a_abs, rel, widen, tau = TUNNEL_F
        amp = np.max(np.abs(expected[e:]))
        w = a_abs + rel * np.abs(expected[e:]) + widen * amp * np.exp(-(tr_t[e:] - T_EVENT) / tau)
        judged = tr_t[e:] >= T_EVENT + ISLAND_GRACE - 1e-9
        m["excursion"] = float(np.max((np.abs(measured[e:] - expected[e:]) / w)[judged]))
    return m


def inertia(m, over_ramp=False):
    a, t = -ROCOF1[0] / F_NOM, ROCOF1[1]
    if over_ramp:
        return (m["energy_event"] - TDES_D * a * t * t / 2.0) / (2.0 * a * t)
    return (m["energy"] - TDES_D * a * (t * t / 2.0 + t * ENERGY_AFTER)) / (2.0 * a * t)


def judge(test, m):
    """The master's verdict (``judge``): (pass, figure)."""
    if m["trip"] is not None:
        return False, "(stopped)"
    synced = test.kind == "island" or m["sync_hz"] <= SYNC_HZ
    if test.kind == "jump" and test.value == 10.0:
        return m["dp_100ms"] >= JUMP_POWER and synced, f"{m['dp_100ms']:.2f} pu"
    if test.kind in ("jump", "scrstep") or (test.kind == "rocof" and test.duration == RAMP):
        return synced, f"{m['sync_hz']:.3f} Hz"
    if test.kind == "rocof":
        h = inertia(m)
        return h >= H_MIN and synced, f"H {h:.2f} s ({inertia(m, True):.2f} over the ramp)"
    if test.kind == "dip":
        need = min(max(K_FFC * (m["dv"] - 0.1), 0.0), 1.0) - FFC_TOLERANCE
        return m["i_reactive"] >= need and synced, f"i_q {m['i_reactive']:.2f} pu"
    if test.kind == "fault":
        a, b, c = m["i_peak"]
        return max(a, b, c) <= 1.0 + I_TOLERANCE and synced, f"{a:.2f}/{b:.2f}/{c:.2f} I_max"
    v_ok = ISLAND_V[0] <= m["v_tail"][0] and m["v_tail"][1] <= ISLAND_V[1]
    return m["excursion"] <= 1.0 and v_ok, f"{m['excursion']:.2f} of the tunnel"


def stopped(message):
    message = re.sub(r"^fmi2DoStep at t = [^:]*: ", "", message)
    return message.split(";")[0].strip().replace("|", "/")


def cell(test, m):
    if "cell" in m:  # read back from the CSV
        return m["cell"]
    ok, figure = judge(test, m)
    return f"{'pass' if ok else 'fail'} {figure}"


# The master's matrix: docs/qualification.md between its markers (or its CSV).
MATRIX_BEGIN, MATRIX_END = "<!-- qualify:begin -->", "<!-- qualify:end -->"


def master_cells(path=None):
    """{(test name, subject, control short): cell text} of the master's suite: from its CSV
    (``cargo xtask qualify``'s results/qualification.csv) if ``path`` is one, else from the
    matrix in docs/qualification.md."""
    import csv

    path = path or os.path.join(ROOT, "docs", "qualification.md")
    out = {}
    if path.endswith(".csv"):
        with open(path, newline="") as f:
            for r in csv.DictReader(f):
                short = CONTROLS[r["control"]][0]
                out[(r["test"], r["subject"], short)] = f"{r['verdict']} {r['figure']}"
        return out
    with open(path) as f:
        text = f.read().split(MATRIX_BEGIN, 1)[1].split(MATRIX_END, 1)[0]
    lines = [x for x in text.strip().splitlines() if x.startswith("|")]
    head = [h.strip() for h in lines[0].strip("|").split("|")]
    for line in lines[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        for h, c in zip(head[1:], cells[1:]):
            subject, short = h.rsplit(" ", 1)
            out[(cells[0], subject, short)] = c
    return out


def numbers(text):
    return [float(x) for x in re.findall(r"-?\d+\.\d+", text)]


def agreement(test, ours, theirs):
    """Verdicts equal, and the figures' largest absolute difference (in the figure's unit)."""
    same = ours.split(" ", 1)[0] == theirs.split(" ", 1)[0]
    a, b = numbers(ours), numbers(theirs)
    diff = max((abs(x - y) for x, y in zip(a, b)), default=math.nan) if len(a) == len(b) and a else math.nan
    return same, diff


def unit_of(test):
    if test.kind == "jump" and test.value == 10.0:
        return "pu"
    if test.kind == "rocof" and test.duration != RAMP:
        return "s"
    return {"dip": "pu", "fault": "I_max", "island": "of the tunnel"}.get(test.kind, "Hz")


def table(rows, master):
    """Markdown: per run the master's cell, DPsim's, whether the verdicts agree and the figures'
    difference."""
    lines = ["| test | unit | control | master | DPsim | verdicts | figure difference |", "|---|---|---|---|---|---|---|"]
    for (test, subject, control), m in rows:
        ours = cell(test, m)
        if m["trip"] is not None:
            ours += f": {stopped(m['trip'][1])}"
        theirs = master.get((test.name, subject, CONTROLS[control][0]), "-")
        same, diff = agreement(test, ours, theirs)
        d = f"{diff:.3f} {unit_of(test)}" if math.isfinite(diff) else "-"
        lines.append(f"| {test.name} | {subject} | {CONTROLS[control][0]} | {theirs} | {ours} | "
                     f"{'agree' if same else 'DIFFER'} | {d} |")
    return "\n".join(lines)


def summary(rows, master):
    """Per test: runs, verdicts agreeing, the largest figure difference where both hosts pass and
    where both fail (a unit that lost synchronism or stopped: its figure is not a response)."""
    by = {}
    for (test, subject, control), m in rows:
        theirs = master.get((test.name, subject, CONTROLS[control][0]))
        if theirs is None:
            continue
        ours = cell(test, m)
        same, diff = agreement(test, ours, theirs)
        n, agree, worst = by.get(test.name, (0, 0, {"pass": math.nan, "fail": math.nan}))
        if same and math.isfinite(diff):
            key = ours.split(" ", 1)[0]
            worst[key] = diff if not math.isfinite(worst[key]) else max(worst[key], diff)
        by[test.name] = (n + 1, agree + same, worst)
    lines = ["| test | runs | verdicts agree | largest figure difference, both pass | both fail |",
             "|---|---|---|---|---|"]

    def fmt(x, test):
        return f"{x:.3f} {unit_of(test)}" if math.isfinite(x) else "-"

    for test in TESTS:
        if test.name in by:
            n, agree, worst = by[test.name]
            lines.append(f"| {test.name} | {n} | {agree} | {fmt(worst['pass'], test)} | {fmt(worst['fail'], test)} |")
    return "\n".join(lines)


def write_csv(path, rows):
    import csv

    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["test", "subject", "control", "verdict", "figure", "sync_Hz", "i_peak_a", "i_peak_b", "i_peak_c",
                    "dp_100ms", "energy", "energy_event", "i_reactive", "dv", "excursion", "unsteady", "wall_s",
                    "steps", "error"])
        for (test, subject, control), m in rows:
            ok, figure = judge(test, m)
            w.writerow([test.name, subject, control, "pass" if ok else "fail", figure, m["sync_hz"], *m["i_peak"],
                        m["dp_100ms"], m["energy"], m["energy_event"], m["i_reactive"], m["dv"], m["excursion"],
                        m["unsteady"], m["wall"], m["steps"], m["trip"][1] if m["trip"] else ""])


def read_csv(path):
    """The rows of a previous run from its CSV (``--from-csv``): the verdicts, figures and times."""
    import csv

    by_name = {job_name(*j): j for j in jobs()}
    rows = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            job = by_name[job_name(next(t for t in TESTS if t.name == r["test"]), r["subject"], r["control"])]
            rows.append((job, {"cell": f"{r['verdict']} {r['figure']}", "trip": (math.nan, r["error"]) if r["error"]
                               else None, "wall": float(r["wall_s"]), "steps": int(r.get("steps") or 0)}))
    return rows


DOCS_BEGIN = "<!-- dpsim-qualify: begin (python tests/python/dpsim_qualify.py --docs docs/qualification.md) -->"
DOCS_END = "<!-- dpsim-qualify: end -->"


def write_docs(path, text):
    with open(path) as f:
        page = f.read()
    if DOCS_BEGIN not in page or DOCS_END not in page:
        sys.exit(f"{path}: the markers {DOCS_BEGIN!r} and {DOCS_END!r} are missing")
    head, rest = page.split(DOCS_BEGIN, 1)
    with open(path, "w") as f:
        f.write(f"{head}{DOCS_BEGIN}\n{text}\n{DOCS_END}{rest.split(DOCS_END, 1)[1]}")


def one(job):
    """A worker's run: (job index, measurements)."""
    k, (ti, subject, control) = job
    rec = run(TESTS[ti], subject, control)
    return k, measure(rec)


def run_all(todo, workers):
    """The runs of ``todo`` in ``workers`` processes (each run its own DPsim simulation), in order."""
    import multiprocessing as mp

    args = [(k, (TESTS.index(t), s, c)) for k, (t, s, c) in enumerate(todo)]
    out = [None] * len(todo)
    ctx = mp.get_context("spawn")
    with ctx.Pool(workers, maxtasksperchild=8) if workers > 1 else _Serial() as pool:
        for done, (k, m) in enumerate(pool.imap_unordered(one, args), 1):
            out[k] = m
            t, s, c = todo[k]
            print(f"  {done}/{len(todo)} {job_name(t, s, c)}: {cell(t, m)} ({m['wall']:.1f} s)", flush=True)
    return list(zip(todo, out))


class _Serial:
    def __enter__(self):
        return self

    def __exit__(self, *a):
        return False

    def imap_unordered(self, f, args):
        return map(f, args)


def profile_report(rec):
    n = rec["steps"]
    parts = rec["parts"] / n * 1e6
    return (f"{n} steps, {rec['wall'] / n * 1e6:.1f} µs a step (profiled): FMU set/doStep/get {parts[0]:.1f} µs, "
            f"host events and source inputs {parts[1]:.1f} µs, DPsim's next() {parts[2]:.1f} µs, "
            f"measurements, dc link and record {parts[3]:.1f} µs")


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", help="the runs whose name (test, unit, control) contains this")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    parser.add_argument("--docs", help="write the agreement table (all runs) between the markers in this page")
    parser.add_argument("--master", help="the master's results/qualification.csv (default: the matrix in "
                        "docs/qualification.md)")
    parser.add_argument("--from-csv", help="the tables from a previous run's results/dpsim_qualification.csv "
                        "(no runs)")
    parser.add_argument("--profile", action="store_true", help="one short run with the step's parts timed")
    args = parser.parse_args()
    if args.profile:
        import dpsim_ride_through as rt

        before = rt.run(rt.Event("dip", 0.5), "grid-forming, option A", 3.0, t_end=1.0)
        print(f"before (dpsim_ride_through's loop, the generic unit, dip to 0.5 pu, 1 s): "
              f"{before['wall'] / round(1.0 / H) * 1e6:.1f} µs a step")
        for t in (TESTS[6], TESTS[8]):
            rec = run(t, "wind", "grid-forming, option A", t_end=1.0)
            print(f"after ({t.name}, wind, option A, 1 s): {rec['wall'] / rec['steps'] * 1e6:.1f} µs a step")
            rec = run(t, "wind", "grid-forming, option A", t_end=1.0, profile=True)
            print(f"  {profile_report(rec)}")
        sys.exit(0)
    if args.docs and args.only:
        sys.exit("--docs takes the table of all runs: not with --only")
    todo = jobs()
    if args.only:
        todo = [j for j in todo if args.only in job_name(*j)]
        if not todo:
            sys.exit(f"no run's name contains '{args.only}' (names are like '{job_name(*jobs()[0])}')")
    if not args.from_csv:
        print(f"DPsim EMT qualification: {len(todo)} runs of {T_END:g} s at {H * 1e6:g} µs in {args.jobs} "
              "processes", flush=True)
    started = time.perf_counter()
    if args.from_csv:
        rows = [r for r in read_csv(args.from_csv) if r[0] in todo]
        wall = math.nan
    else:
        rows = run_all(todo, args.jobs)
        wall = time.perf_counter() - started
    master = master_cells(args.master)
    steps = sum(m["steps"] for _, m in rows) or len(rows) * round(T_END / H)
    loop = sum(m["wall"] for _, m in rows)
    timing = (f"{len(rows)} runs" + (f" in {wall:.0f} s wall time ({args.jobs} processes)" if math.isfinite(wall)
                                     else "") + f"; the stepping loops {loop:.0f} s, {loop / steps * 1e6:.1f} µs a "
              "50 µs step")
    text = f"{summary(rows, master)}\n\n{table(rows, master)}\n\n{timing}"
    print(text)
    if not args.from_csv:
        path = os.path.join(ROOT, "results", "dpsim_qualification.csv")
        write_csv(path, rows)
        print(f"wrote {os.path.relpath(path, ROOT)}")
    if args.docs:
        write_docs(args.docs, text)
        print(f"wrote the table in {args.docs}")
