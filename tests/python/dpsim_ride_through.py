"""Grid-code events in DPsim EMT: one dvpp_der_emt unit against a host-driven Thevenin grid.

The events of our master's ``cargo xtask ride-through`` (studies/src/ride_through.rs), with
DPsim's three-phase EMT domain (50 µs) as the plant: the generic 60 MVA unit of
``dpsim_emt_host`` (the default ``dvpp_der_emt.fmu``; its converter, RLC filter and transformer
the host's ``Converter``), the host's local load at the PCC (0.3 + j0.05 pu of the unit's
rating) and a Thevenin grid: a ControlledVoltageSource behind R + jX (|Z| = 1/SCR pu on the
unit's rating, X/R 10), the unit starting at 0.5 + j0.1 pu with the PCC at 1 pu. Per control
(grid-forming option A; option B, ``inner.kind`` = 1; grid-following, ``mode`` = 2 and
``vq.tau`` = 2 s, as the study sets them) and SCR (10, 3, 1.5), one event at 1 s, runs to 3.5 s:

- dips of the source to 0.5 and 0.1 pu for 150 ms, ±25° phase jumps of the source, ±5 Hz/s
  frequency ramps for 0.4 s (then held): the host drives the source. Its phasor over each step
  is what our plant holds there (the dip from the first step boundary at or after its start to
  the first at or after its end, the jump from the first at or after its time, the ramp's angle
  at the step's middle). DPsim's trapezoidal rule takes the source as samples at the solution
  times, joined linearly, so the host imposes at t_k the mean of the instantaneous values at t_k
  of the phasors held over the two steps that meet there (the converter's timing="mid" rule): a
  step of amplitude or angle at t_k enters as half of it at t_k;
- faults at the PCC through 0.01 + j0.01 pu per faulted branch on S_base (100 MVA) for 150 ms:
  three-phase (a, b and c each to ground), phase a to ground, phase b to phase c (one branch
  between them, as our plant's ``fault.type`` = 3). DPsim's ``emt.ph3.Switch`` is a 3x3
  resistance matrix, stamped as its inverse (a conductance matrix, not only diagonal): each
  branch is a switch from a fault node to ground, closed at the branch's conductance
  a aᵀ/R_f (a its phase incidence: (1, 0, 0) phase a to ground, (0, 1, -1) b to c) plus 1 MΩ
  per phase (so that the matrix inverts), open 1e12 Ω; the fault's inductance per phase sits
  between the PCC and the fault node (X_f on a phase to ground, X_f/2 on b and c for b-c). The
  switches close for the solution at 1 s (DPsim's inductive branch then carries (h/2L) v at
  1 s: half a step early, as the host's load step); each opens, as our plant's breaker poles
  (``fault.clearing`` = 0), at the first step boundary after its current crossed zero from
  1.15 s on.

The unit is three-wire and the local load an ungrounded star, as our plant's defaults (its
``der[k].grounding`` = 0, loads in α and β only): their inductances block the zero sequence
(``dpsim_emt_host.three_wire_inductance``); the Thevenin source is grounded with Z0 = Z1, as our
plant's.

Measured per run, as the study measures: *rides through* (the FMU's doStep returns OK
throughout and the unit's frequency, 1 + df, is within 0.05 Hz of the grid's over the last
0.5 s); the largest phase current of the converter (its converter-side current) over I_max =
1.2; during dips and faults the mean of p/v and q/v from 50 ms after the event to its clearing
(p + jq the unit's power into the PCC, v the PCC voltage's space-vector magnitude; pu of the
unit's rating); recovery (from the event's end, until the unit's p stays within 5 % of its
rating of its mean over the last 0.2 s). A unit that stops with fmi2Error is "no: tripped at
t = …" with its message.

``python tests/python/dpsim_ride_through.py [--only TEXT] [--docs docs/emt.md]``: every run (or
those whose name, "event, control, SCR x", contains TEXT), the Markdown table; all runs write
results/dpsim_ride_through.csv (and with --docs the table between the page's markers), --only
writes each run's traces to results/dpsim_ride_through/.
"""
import cmath
import csv
import math
import os
import re
import sys
import time
from dataclasses import dataclass

import numpy as np

import dpsim_emt_host as host
from dpsim_emt_host import (FILTER, GRID_LOAD, GRID_S0, H_STEP, R_OPEN, SPACE_VECTOR, UNIT_INFO, V_LL, V_R,
                            W_NOM, Converter, DerEmt, Network, der_emt_path, grid_line, instantaneous)
from fmu_slave import Slave

F_NOM = host.F_NOM
T_EVENT = 1.0
T_END = 3.5
DURATION = 0.15  # dips and faults
RAMP = 0.4  # frequency ramps
SYNC_HZ = 0.05
TAIL = 0.5
RECOVERY_BAND = 0.05
I_MAX = 1.2
SCRS = (10.0, 3.0, 1.5)
FAULT_Z = complex(0.01, 0.01)  # per faulted branch, pu on S_base
S_BASE = 100e6
DAMPING_R = 1e3  # pu on S_rated: the PCC's damping resistor (a part of the local load)
R_LEAK = 1e6  # ohm per phase to ground of a closed fault switch, so that its matrix inverts
# The fault's branches: phase incidence (+1 where the current leaves the PCC, -1 where it returns).
FAULT_BRANCHES = {1: ((1, 0, 0), (0, 1, 0), (0, 0, 1)), 2: ((1, 0, 0),), 3: ((0, 1, -1),)}
FAULT_NAMES = {1: "three-phase", 2: "phase-a-to-ground", 3: "phase-b-to-c"}

# The controls, as the study sets them on the generic unit.
CONTROLS = {
    "grid-forming, option A": {},
    "grid-forming, option B": {"inner.kind": 1},
    "grid-following": {"mode": 2, "vq.tau": 2.0},
}


@dataclass(frozen=True)
class Event:
    """One event of the grid codes' tests: ``kind`` "dip" (value: the retained voltage, pu),
    "fault" (value: 1 three-phase, 2 phase a to ground, 3 phase b to c), "jump" (degrees) or
    "rocof" (Hz/s); at ``t`` (s)."""

    kind: str
    value: float
    t: float = T_EVENT

    def name(self):
        if self.kind == "dip":
            return f"dip to {self.value:g} pu, 150 ms"
        if self.kind == "fault":
            return f"{FAULT_NAMES[int(self.value)]} fault at the PCC, 150 ms"
        if self.kind == "jump":
            return f"phase jump {self.value:+g}°"
        return f"{self.value:+g} Hz/s for {RAMP:g} s"

    def end(self):
        """When it is over: a dip or fault cleared, a jump at once, a ramp at its end."""
        return self.t + {"dip": DURATION, "fault": DURATION, "jump": 0.0, "rocof": RAMP}[self.kind]

    def holds_voltage_down(self):
        return self.kind in ("dip", "fault")

    def phasor(self, t, h):
        """The source's phasor over the step [t, t + h), per unit of its initial one."""
        tol = 1e-9 * max(abs(t), 1.0)
        x = complex(1.0)
        if self.kind == "dip" and self.t - tol <= t < self.t + DURATION - tol:
            x = complex(self.value)
        elif self.kind == "jump" and t >= self.t - tol:
            x = cmath.exp(1j * math.radians(self.value))
        elif self.kind == "rocof":
            tau = max(t + 0.5 * h - self.t, 0.0)
            ramped = min(tau, RAMP)
            x = cmath.exp(2j * math.pi * self.value * (0.5 * ramped * ramped + RAMP * max(tau - ramped, 0.0)))
        return x

    def sample(self, t, h):
        """The source's phasor sampled at the solution time t (the mean of the two held ones)."""
        return 0.5 * (self.phasor(t - h, h) + self.phasor(t, h))

    def f_grid(self, t):
        """The grid's frequency (Hz) at t (arrays too)."""
        if self.kind != "rocof":
            return np.full_like(np.asarray(t, dtype=float), F_NOM)
        return F_NOM + self.value * np.clip(np.asarray(t) - self.t, 0.0, RAMP)


EVENTS = (Event("dip", 0.5), Event("dip", 0.1), Event("fault", 1), Event("fault", 2), Event("fault", 3),
          Event("jump", 25.0), Event("jump", -25.0), Event("rocof", 5.0), Event("rocof", -5.0))


def run_name(event, control, scr):
    return f"{event.name()}, {control}, SCR {scr:g}"


class Fault:
    """The fault at node n (at the phasor v, pu): its inductance from n to a fault node, and
    per branch a switch from the fault node to ground (the module's docstring). ``z`` pu of
    ``z_b``."""

    def __init__(self, net, n, v, kind, z, z_b):
        if not z.real > 0.0 or not z.imag > 0.0:
            raise ValueError(f"FAULT_Z = {z}: the fault's resistance and reactance must be positive")
        self.branches = [np.array(a, dtype=float) for a in FAULT_BRANCHES[kind]]
        r, l = z.real * z_b, z.imag * z_b / W_NOM
        l_phase = np.full(3, l)
        for a in self.branches:
            if np.sum(np.abs(a)) == 2:  # between two phases: half of it in each
                l_phase[a != 0] = 0.5 * l
        n_f = net.node("fault", v)
        self.l_f = net.add(net.ph3.Inductor("l_fault", net.log), n, n_f, np.diag(l_phase))
        self.switches = []
        for k, a in enumerate(self.branches):
            closed = np.linalg.inv(np.outer(a, a) / r + np.eye(3) / R_LEAK)
            switch = net.ph3.Switch(f"sw_fault{k}", net.log)
            switch.set_parameters(R_OPEN * np.eye(3), closed, False)
            self.switches.append(net.add(switch, n_f, net.gnd))
        self.closed = [False] * len(self.branches)
        self.last = None

    def bind(self):
        self.i_f = self.l_f.attr("i_intf")

    def currents(self):
        """Each branch's current at the latest solution (its sign only matters here)."""
        i = self.i_f.get()[:, 0]
        return [float(a @ i) / float(a @ a) for a in self.branches]

    def close(self):
        for s in self.switches:
            s.close()
        self.closed = [True] * len(self.switches)
        self.last = None

    def open_at_zero(self):
        """Opens (for the next solution) each closed branch whose current crossed zero over the
        last step; returns whether any is still closed."""
        now = self.currents()
        if self.last is not None:
            for k, (a, b) in enumerate(zip(self.last, now)):
                if self.closed[k] and a * b <= 0.0:
                    self.switches[k].open()
                    self.closed[k] = False
        self.last = now
        return any(self.closed)


class GridCircuit:
    """The unit (three-wire), the local load (ungrounded), the fault (if any) at the PCC and the
    Thevenin source (a ControlledVoltageSource behind z_th, pu on S_rated) in DPsim's EMT
    domain, at the steady state of the PCC at 1 pu with the unit feeding GRID_S0."""

    def __init__(self, s_rated, f, z_th, event, h=H_STEP):
        self.h, self.event = h, event
        net = self.net = Network()
        z_b = V_LL**2 / s_rated
        v = complex(1.0)
        i_load = v * GRID_LOAD.conjugate()
        i_g = GRID_S0.conjugate() / v.conjugate()
        n_pcc = net.node("pcc", v)
        self.converter = Converter(net, "unit", s_rated, f, n_pcc, v, i_g, three_wire=True)
        # The local load: a damping resistor from the PCC to ground and a series R-L of the rest.
        net.add(net.ph3.Resistor("r_damping", net.log), n_pcc, net.gnd, DAMPING_R * z_b)
        z_load = 1.0 / (GRID_LOAD.conjugate() - 1.0 / DAMPING_R)
        net.rl("load", n_pcc, net.gnd, z_load, z_b, v, v / z_load, three_wire=True)
        i_th = i_load - i_g  # from the source into the PCC
        self.e0 = v + z_th * i_th
        n_th = net.node("thevenin", self.e0)
        self.source = net.controlled_source("thevenin", n_th, self.e0)
        net.rl("thevenin", n_th, n_pcc, z_th, z_b, self.e0, i_th)
        self.fault = None
        if event.kind == "fault":
            self.fault = Fault(net, n_pcc, v, int(event.value), FAULT_Z * s_rated / S_BASE, z_b)
        self.sim = net.start("dvpp_ride_through", h)
        self.converter.bind()
        if self.fault:
            self.fault.bind()
        self.v_pcc, self.v_th, self.e_ref = n_pcc.attr("v"), n_th.attr("v"), self.source.attr("V_ref")
        self.t_solve = h

    def set_source(self, t):
        """The source's sample for DPsim's solution at t."""
        self.e_ref.set(instantaneous(self.e0 * self.event.sample(t, self.h), t))

    def pcc(self):
        """The PCC voltage's space vector and the unit's p + jq into the PCC (pu on S_rated) at
        the latest solution."""
        c = self.converter
        v = complex(SPACE_VECTOR @ self.v_pcc.get()[:, 0]) / V_R
        i = complex(SPACE_VECTOR @ c.i_g.get()[:, 0]) / -c.i_r
        return v, v * i.conjugate()

    def source_angle(self, t):
        """The source node's voltage angle (rad) beyond ω_nom t, from DPsim's solution."""
        return cmath.phase(complex(SPACE_VECTOR @ self.v_th.get()[:, 0]) * cmath.exp(-1j * W_NOM * t))

    def next(self):
        t = self.t_solve
        self.t_solve = self.sim.next()
        return t

    def stop(self):
        self.sim.stop()
        self.net.cleanup()


SIGNALS = ("t", "v", "v_a", "p", "q", "i_max", "df", "f_grid", "grid_angle")


def unit_data(params):
    probe = Slave(der_emt_path(), "probe", params)
    unit = dict(zip(UNIT_INFO, probe.get(*UNIT_INFO)))
    probe.free()
    return unit


def run(event, control, scr, t_end=T_END, h=H_STEP):
    """One run; returns its signals (arrays up to the last solution before a trip: ``v`` the
    PCC voltage's space-vector magnitude, ``v_a`` its phase a (pu of v_r), ``p``, ``q`` the
    unit's power into the PCC on its rating, ``i_max`` the largest magnitude of the converter's
    phase currents (pu of the rated peak current), ``df`` the FMU's, ``f_grid`` the grid's
    frequency (Hz), ``grid_angle`` the source node's angle beyond ω_nom t from DPsim's solution),
    the trip (t, message) or None, and the wall time."""
    import fmpy.fmi2  # noqa: F401
    from fmpy.fmi1 import FMICallException

    params = {"t_s": h, **CONTROLS[control]}
    unit = unit_data(params)
    circuit = GridCircuit(unit["S_rated"] * 1e6, {k: unit[k] for k in FILTER}, grid_line(scr), event, h)
    volts_per_m = unit["vdc_ratio"] / 2.0
    der = DerEmt(params, circuit.converter.measure(), name=run_name(event, control, scr))
    i_df = host.OUTPUTS.index("df")
    n = round(t_end / h)
    k_event = round(event.t / h)
    k_clear = round(event.end() / h)
    rec = {k: np.empty(n + 1) for k in SIGNALS}

    def record(j, t, meas, df):
        v, s = circuit.pcc()
        rec["t"][j], rec["v"][j], rec["p"][j], rec["q"][j] = t, abs(v), s.real, s.imag
        rec["v_a"][j] = circuit.v_pcc.get()[0, 0] / V_R
        rec["i_max"][j] = max(abs(x) for x in meas[3:6])
        rec["df"][j] = df
        rec["grid_angle"][j] = circuit.source_angle(t)

    out = der.fmu.getReal(der.vr_out)
    circuit.converter.last = np.array(out[:3]) * volts_per_m
    meas = circuit.converter.measure()
    record(0, 0.0, meas, out[i_df])
    trip, last = None, n
    fault_on = False
    started = time.perf_counter()
    for k in range(n):
        try:
            out = der.step(k * h, h, meas)
        except FMICallException as error:
            errors = [m for status, m in der.messages if status >= 3]
            trip, last = (k * h, errors[-1] if errors else str(error)), k
            break
        if circuit.fault:
            if k + 1 == k_event:
                circuit.fault.close()
                fault_on = True
            elif fault_on and k >= k_clear:
                fault_on = circuit.fault.open_at_zero()
        circuit.converter.apply([m * volts_per_m for m in out[:3]])
        circuit.set_source((k + 1) * h)
        t = circuit.next()
        meas = circuit.converter.measure()
        record(k + 1, t, meas, out[i_df])
    wall = time.perf_counter() - started
    try:
        der.free()
    except FMICallException:
        pass
    circuit.stop()
    rec = {k: x[: last + 1] for k, x in rec.items()}
    rec["f_grid"] = event.f_grid(rec["t"])
    rec["grid_angle"] = np.unwrap(rec["grid_angle"])
    return {**rec, "trip": trip, "wall": wall, "h": h, "event": event, "control": control, "scr": scr,
            "t_end": t_end, "unit": unit}


def at(t, time_):
    return min(int(np.searchsorted(t, time_ - 1e-9)), len(t) - 1)


def measure(rec):
    """The table's figures of one run (the study's)."""
    t, event = rec["t"], rec["event"]
    f_unit = (1.0 + rec["df"]) * F_NOM
    out = {"name": run_name(event, rec["control"], rec["scr"]), "trip": rec["trip"],
           "i_peak": np.max(rec["i_max"]) / I_MAX, "i_active": math.nan, "i_reactive": math.nan,
           "sync_hz": math.nan, "recovery": math.nan, "wall": rec["wall"]}
    if rec["trip"] is None:
        tail = at(t, rec["t_end"] - TAIL)
        out["sync_hz"] = float(np.max(np.abs(f_unit[tail:] - rec["f_grid"][tail:])))
        last = at(t, rec["t_end"] - 0.2)
        p_end = np.mean(rec["p"][last:])
        start = at(t, event.end())
        outside = np.nonzero(np.abs(rec["p"][start:] - p_end) > RECOVERY_BAND)[0]
        out["recovery"] = t[start + outside[-1]] - event.end() if len(outside) else 0.0
    if event.holds_voltage_down() and rec["trip"] is None:
        a, b = at(t, event.t + 0.05), at(t, event.end())
        v = np.maximum(rec["v"][a:b], 1e-3)
        out["i_active"] = float(np.mean(rec["p"][a:b] / v))
        out["i_reactive"] = float(np.mean(rec["q"][a:b] / v))
    out["rides_through"] = rec["trip"] is None and out["sync_hz"] <= SYNC_HZ
    return out


def stopped(message):
    """The FMU's message up to its first ';', without its "fmi2DoStep at t = …: " (the verdict
    says when) and table separators."""
    message = re.sub(r"^fmi2DoStep at t = [^:]*: ", "", message)
    return message.split(";")[0].strip().replace("|", "/")


def verdict(m):
    if m["trip"] is not None:
        return f"no: tripped at t = {m['trip'][0]:.6g} s: {stopped(m['trip'][1])}"
    return "yes" if m["rides_through"] else f"no: {m['sync_hz']:.2f} Hz from the grid at the end"


def number(x, digits=2):
    return f"{x:.{digits}f}" if math.isfinite(x) else "-"


def table(rows):
    lines = ["| event | control | SCR | rides through | largest phase current / I_max | active, reactive current "
             "in the event (pu of S_rated) | recovery (s) |", "|---|---|---|---|---|---|---|"]
    for (event, control, scr), m in rows:
        currents = f"{number(m['i_active'])}, {number(m['i_reactive'])}" if math.isfinite(m["i_active"]) else ""
        i_peak = number(m["i_peak"]) if m["trip"] is None else "-"
        lines.append(f"| {event.name()} | {control} | {scr:g} | {verdict(m)} | {i_peak} | {currents} | "
                     f"{number(m['recovery'])} |")
    return "\n".join(lines)


def write_csv(path, rows):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.writer(f, quoting=csv.QUOTE_MINIMAL)
        w.writerow(["event", "control", "scr", "rides_through", "sync_Hz", "i_peak_over_i_max", "i_active_pu",
                    "i_reactive_pu", "recovery_s", "trip_t", "error"])
        for (event, control, scr), m in rows:
            trip_t, error = m["trip"] if m["trip"] else ("", "")
            w.writerow([event.name(), control, scr, m["rides_through"], m["sync_hz"], m["i_peak"], m["i_active"],
                        m["i_reactive"], m["recovery"], trip_t, error])


def write_traces(path, rec):
    np.savetxt(path, np.column_stack([rec[k] for k in SIGNALS]), delimiter=",", header=",".join(SIGNALS),
               comments="")


DOCS_BEGIN = "<!-- dpsim-ride-through: begin (python tests/python/dpsim_ride_through.py --docs docs/emt.md) -->"
DOCS_END = "<!-- dpsim-ride-through: end -->"


def write_docs(path, text):
    """The table between the markers in the page at ``path``."""
    with open(path) as f:
        page = f.read()
    if DOCS_BEGIN not in page or DOCS_END not in page:
        sys.exit(f"{path}: the markers {DOCS_BEGIN!r} and {DOCS_END!r} are missing")
    head, rest = page.split(DOCS_BEGIN, 1)
    tail = rest.split(DOCS_END, 1)[1]
    with open(path, "w") as f:
        f.write(f"{head}{DOCS_BEGIN}\n{text}\n{DOCS_END}{tail}")


def file_name(name):
    return re.sub(r"[^A-Za-z0-9.+-]", "_", name)


def jobs():
    return [(event, control, scr) for control in CONTROLS for scr in SCRS for event in EVENTS]


if __name__ == "__main__":
    import argparse

    sys.path.insert(0, os.path.dirname(__file__))
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", help="the runs whose name (event, control, SCR x) contains this")
    parser.add_argument("--docs", help="write the table (all runs) between the markers in this page")
    args = parser.parse_args()
    if args.docs and args.only:
        sys.exit("--docs takes the table of all runs: not with --only")
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
    todo = jobs()
    if args.only:
        todo = [j for j in todo if args.only in run_name(*j)]
        if not todo:
            sys.exit(f"no run's name contains '{args.only}' (names are like '{run_name(*jobs()[0])}')")
    trace_dir = os.path.join(root, "results", "dpsim_ride_through")
    if args.only:
        os.makedirs(trace_dir, exist_ok=True)
    print(f"DPsim EMT ride-through: {len(todo)} runs of {T_END:g} s at {H_STEP * 1e6:g} µs", flush=True)
    rows = []
    started = time.perf_counter()
    for j, job in enumerate(todo):
        rec = run(*job)
        m = measure(rec)
        rows.append((job, m))
        print(f"  {j + 1}/{len(todo)} {m['name']}: {verdict(m)} ({rec['wall']:.0f} s)", flush=True)
        if args.only:
            write_traces(os.path.join(trace_dir, file_name(m["name"]) + ".csv"), rec)
    print(table(rows))
    if args.only:
        print(f"each run's traces in {os.path.normpath(trace_dir)}")
    else:
        path = os.path.join(root, "results", "dpsim_ride_through.csv")
        write_csv(path, rows)
        print(f"wrote {os.path.normpath(path)} ({time.perf_counter() - started:.0f} s)")
        if args.docs:
            write_docs(args.docs, table(rows))
            print(f"wrote the table in {args.docs}")
