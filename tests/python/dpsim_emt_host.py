"""DPsim as the EMT host of the EMT-level DER controller FMU (dvpp_der_emt).

DPsim computes the converter's three-phase circuit in the EMT domain (``dpsimpy.emt.ph3``, 50 µs
steps): the averaged converter as a controlled voltage source, the RLC filter (R_f, L_f, C_f in
star to ground), the LV/MV transformer as a series R_t-L_t, and a network at the PCC (an R-L load
and a switched load step; in the grid cases a line to a stiff three-phase source). The FMU
(fmpy's FMU2Slave) only controls: each step it reads the instantaneous filter-capacitor voltage,
converter-side current and grid-side current from DPsim's solution and returns the modulation.

Per unit (the FMU's convention, on the converter rating S_rated): voltages in pu of the rated
phase-to-neutral peak v_r, currents in pu of the rated peak current i_r = (2/3) S_rated / v_r,
so that v·conj(i) of the amplitude-invariant space vectors is the power in pu of S_rated. A
balanced set X cos(ωt + φ) is the phasor X e^{jφ}. The converter's phase voltage is
m · v_dc · vdc_ratio / 2 pu of v_r; DPsim's circuit has no dc link, so v_dc = 1 (the FMU's
input, and in the source). The FMU's powers p, q are on S_base (100 MVA).

The whole circuit is at one voltage level, V_LL = 20 kV line-to-line RMS: the transformer is its
series R_t + jX_t (pu on S_rated) with an ideal ratio, which in per unit is no transformer at all.
DPsim's node voltages at initialization are line-to-line RMS phasors (volts): a node at the
per-unit phasor x starts at x·V_LL, its phase a at sqrt(2/3)·V_LL·Re(x) = v_r·Re(x).

Coupling, every 50 µs: the measurements at DPsim's solution for t_k go into the FMU, doStep(t_k,
h), and the modulation it returns drives the source for DPsim's solution at t_{k+1}. The FMU
meant its output held over [t_{k+1}, t_{k+2}] (its angle is advanced by 1.5 steps); DPsim's
trapezoidal rule takes a source as a sample at the solution's time, interpolated linearly in
between. ``timing="mid"`` (the default) therefore imposes the mean of the last two outputs at
t_{k+1} (the sample at the boundary of their two hold intervals); ``timing="direct"`` imposes the
last output as it is (half a step ahead in phase).

Run as a script to print the measured figures (and ``--svg PATH`` for a figure):
``python tests/python/dpsim_emt_host.py [--svg PATH]``.
"""
import cmath
import math
import os
import tempfile
import time

import numpy as np

from fmu_slave import Slave

F_NOM = 50.0
W_NOM = 2 * math.pi * F_NOM
V_LL = 20e3  # line-to-line RMS, V: the one voltage level of the circuit
PEAK = math.sqrt(2.0 / 3.0)  # line-to-line RMS to phase peak
V_R = V_LL * PEAK  # the rated phase-to-neutral peak voltage, V
A120 = cmath.exp(2j * math.pi / 3)
ABC = np.array([1.0, A120**2, A120])  # the phasor of phase a, b, c of a positive sequence set
# Instantaneous phase values (a, b, c) to the amplitude-invariant space vector.
SPACE_VECTOR = (2.0 / 3.0) * np.array([1.0, A120, A120**2])
R_OPEN = 1e12  # ohm, an open switch
R_CLOSED = 1e-3  # a closed switch, of its load's resistance
H_STEP = 50e-6

INPUTS = ("v_a", "v_b", "v_c", "i_a", "i_b", "i_c", "ig_a", "ig_b", "ig_c", "v_dc")
OUTPUTS = ("m_a", "m_b", "m_c", "df", "theta", "p", "q", "v", "p_set", "q_ref", "E", "i_ac")
FLAGS = ("limit.current", "limit.modulation", "limit.source")


def der_emt_path():
    from conftest import DIST

    return str(DIST / "dvpp_der_emt.fmu")


def grid_line(scr, r_over_x=0.1):
    """The line's impedance (pu on S_rated) for a short-circuit ratio ``scr`` at the PCC."""
    x = 1.0 / scr / math.hypot(1.0, r_over_x)
    return complex(r_over_x * x, x)


class Network:
    """DPsim's three-phase EMT nodes and components under construction, at the one voltage level
    V_LL; impedances in per unit of a base impedance given with them (a unit's rating or the
    network's S_base). DPsim's components and solver open their logs under ./logs (empty with
    logging off): the circuit is built and started in a directory of its own, out of the working
    tree."""

    def __init__(self):
        import dpsimpy

        self.dpsimpy, self.log = dpsimpy, dpsimpy.LogLevel.off
        self.ph3, self.gnd = dpsimpy.emt.ph3, dpsimpy.emt.SimNode.gnd
        self.nodes, self.comps = [], []
        self._tmp = tempfile.TemporaryDirectory(prefix="dpsim-emt-")
        self._cwd = os.getcwd()
        os.chdir(self._tmp.name)

    def node(self, name, x):
        """A node starting at the per-unit phasor x (DPsim takes line-to-line RMS volts)."""
        v = x * V_LL
        n = self.dpsimpy.emt.SimNode(name, self.dpsimpy.PhaseType.ABC, [v, v * A120**2, v * A120])
        self.nodes.append(n)
        return n

    def add(self, comp, a, b, value=None):
        """Connects comp from a to b; ``value``: its parameter, a number (the same in each phase)
        or a 3x3 matrix."""
        if value is not None:
            comp.set_parameters(value if np.ndim(value) == 2 else value * np.eye(3))
        comp.connect([a, b])
        self.comps.append(comp)
        return comp

    def rl(self, name, a, b, z, z_b, v_a, i, three_wire=False):
        """Series R-L (z pu of z_b) from a to b; v_a the voltage at a, i the current (a to b).
        ``three_wire``: its zero sequence blocked (``three_wire_inductance``). Returns the
        inductor: its i_intf is the current from b to a."""
        n = self.node(f"{name}_rl", v_a - z.real * i)
        self.add(self.ph3.Resistor(f"r_{name}", self.log), a, n, z.real * z_b)
        l = z.imag * z_b / W_NOM
        return self.add(self.ph3.Inductor(f"l_{name}", self.log), n, b,
                        three_wire_inductance(l) if three_wire else l)

    def controlled_source(self, name, n, x):
        """A controlled voltage source from ground to n, starting at the phasor x (pu)."""
        source = self.ph3.ControlledVoltageSource(name, self.log)
        source.set_parameters(instantaneous(x, 0.0))
        return self.add(source, self.gnd, n)

    def switched_load(self, name, n, z, z_b):
        """A series R-L load (z pu of z_b) behind an open switch at n; returns the switch. The
        closed switch's resistance is taken from the load's, so that the closed branch is z."""
        n_sw = self.node(f"{name}_sw", 0.0)
        switch = self.ph3.Switch(f"sw_{name}", self.log)
        switch.set_parameters(R_OPEN * np.eye(3), R_CLOSED * z.real * z_b * np.eye(3), False)
        self.add(switch, n, n_sw)
        self.rl(name, n_sw, self.gnd, z - R_CLOSED * z.real, z_b, 0.0, 0.0)
        return switch

    def start(self, name, h):
        """The simulation of this circuit at step h, initialized from the nodes' voltages and
        started (no solution yet: the first next() solves at t = h)."""
        dpsimpy = self.dpsimpy
        sim = dpsimpy.Simulation(name, self.log)
        sim.set_system(dpsimpy.SystemTopology(F_NOM, self.nodes, self.comps))
        sim.set_domain(dpsimpy.Domain.EMT)
        sim.set_time_step(h)
        sim.set_final_time(1e6)
        sim.do_init_from_nodes_and_terminals(True)
        try:
            sim.start()
        finally:
            os.chdir(self._cwd)
        return sim

    def cleanup(self):
        self._tmp.cleanup()


# The zero-sequence inductance of a three-wire branch, per unit of its phase inductance.
ZERO_SEQUENCE_BLOCK = 1e6


def three_wire_inductance(l):
    """The 3x3 inductance matrix (H) that is l for the positive and negative sequence and
    ZERO_SEQUENCE_BLOCK l for the zero sequence: a branch with no zero-sequence current to speak
    of (an ungrounded star, a three-wire unit), as DPsim's ph3 components all return through
    ground. Balanced, it carries what the scalar l carries (DPsim's initialization included)."""
    j = np.full((3, 3), 1.0 / 3.0)
    return l * (np.eye(3) - j) + ZERO_SEQUENCE_BLOCK * l * j


def instantaneous(x, t):
    """The three instantaneous phase voltages (V, 3x1) of the phasor x (pu) at time t."""
    return (V_R * (x * cmath.exp(1j * W_NOM * t) * ABC).real).reshape(3, 1)


class Converter:
    """One averaged converter (a controlled voltage source), its RLC filter (R_f, L_f; C_f in
    star to ground) and its transformer (series R_t-L_t) into the node ``n_pcc``, per unit on
    ``s_rated`` (VA) in the FMU's convention. ``f``: the filter and transformer data as the FMU
    has them (pu on S_rated, the L and C as their reactance and susceptance at f_nom). Starts at
    its steady state with the PCC at the phasor ``v_pcc`` and the grid-side current ``i_g``
    (pu of the rated peak current, toward the PCC). ``three_wire``: the transformer blocks the
    zero sequence (a three-wire unit, as our plant's default ``der[k].grounding`` = 0); else the
    unit is a grounded star (the source and C_f return through ground)."""

    def __init__(self, net, name, s_rated, f, n_pcc, v_pcc, i_g, three_wire=False):
        self.z_b = V_LL**2 / s_rated  # ohm
        self.i_r = (2.0 / 3.0) * s_rated / V_R  # A, the rated peak current
        z_f, z_t = complex(f["R_f"], f["L_f"]), complex(f["R_t"], f["L_t"])
        v_cap = v_pcc + z_t * i_g
        i_f = i_g + 1j * f["C_f"] * v_cap
        self.v_conv0 = v_cap + z_f * i_f
        n_conv = net.node(f"{name}_conv", self.v_conv0)
        self.source = net.controlled_source(f"{name}_conv", n_conv, self.v_conv0)
        n_cap = net.node(f"{name}_cap", v_cap)
        self.l_f = net.rl(f"{name}_f", n_conv, n_cap, z_f, self.z_b, self.v_conv0, i_f)
        net.add(net.ph3.Capacitor(f"{name}_c_f", net.log), n_cap, net.gnd, f["C_f"] / (self.z_b * W_NOM))
        self.l_t = net.rl(f"{name}_t", n_cap, n_pcc, z_t, self.z_b, v_cap, i_g, three_wire)
        self.n_cap = n_cap

    def bind(self):
        """The attribute handles, once the simulation started (~1 µs a read or write, the
        properties ~40 µs). The controlled source's V_ref is a 3x1 real vector of instantaneous
        volts (its property raises)."""
        self.v_ref = self.source.attr("V_ref")
        self.v_cap = self.n_cap.attr("v")
        self.i_f, self.i_g = self.l_f.attr("i_intf"), self.l_t.attr("i_intf")
        self.last = self.v_ref.get()[:, 0] / V_R  # the converter's voltage (pu) at t = 0

    def measure(self):
        """The FMU's inputs from DPsim's latest solution: v_a..c, i_a..c, ig_a..c (pu), v_dc = 1.
        The inductors' i_intf runs from their second terminal to their first, against the
        converter-to-grid direction."""
        v = self.v_cap.get()[:, 0] / V_R
        i = -self.i_f.get()[:, 0] / self.i_r
        ig = -self.i_g.get()[:, 0] / self.i_r
        return [*v, *i, *ig, 1.0]

    def apply(self, v_conv, timing="mid"):
        """The converter's phase voltages (pu of v_r, as the FMU meant them held over the next
        step) into the source for DPsim's next solution (see the module's docstring)."""
        v_conv = np.asarray(v_conv)
        x = 0.5 * (self.last + v_conv) if timing == "mid" else v_conv
        self.last = v_conv
        self.v_ref.set((V_R * x).reshape(3, 1))


class Circuit:
    """One converter (``Converter``) and its network in DPsim's three-phase EMT domain, per unit
    on ``s_rated`` (VA) in the FMU's convention, in volts, ohms, henries and farads inside.

    ``load`` and ``step``: series R-L loads (pu of S_rated at 1 pu voltage), the step behind an
    open switch. ``z_line``: None (an island) or the series R-L line (pu on S_rated) from the PCC
    to a stiff source. The initial point: the PCC at v0∠0, the converter feeding ``s0`` (pu on
    S_rated) into the PCC (in an island the load, whatever s0 is); every node and inductor current
    starts at its steady state (DPsim's initialization from node voltages), so a run starts flat.
    """

    def __init__(self, s_rated, f, load, step, z_line=None, s0=None, v0=1.0, h=H_STEP, timing="mid"):
        self.h, self.timing = h, timing
        net = self.net = Network()
        z_b = V_LL**2 / s_rated
        # The steady state in per unit (phasors), from the PCC at v0∠0.
        z_load = 1.0 / load.conjugate()
        v_pcc = complex(v0)
        i_load = v_pcc / z_load
        i_g = i_load if z_line is None else s0.conjugate() / v_pcc.conjugate()
        n_pcc = net.node("pcc", v_pcc)
        self.converter = Converter(net, "unit", s_rated, f, n_pcc, v_pcc, i_g)
        net.rl("load", n_pcc, net.gnd, z_load, z_b, v_pcc, i_load)
        self.switch = net.switched_load("step", n_pcc, 1.0 / step.conjugate(), z_b)
        if z_line is not None:
            i_line = i_g - i_load
            v_grid = v_pcc - z_line * i_line
            n_grid = net.node("grid", v_grid)
            net.rl("line", n_pcc, n_grid, z_line, z_b, v_pcc, i_line)
            grid = net.ph3.VoltageSource("grid", net.log)
            v = v_grid * V_LL
            grid.set_parameters(np.array([[v], [v * A120**2], [v * A120]]), F_NOM)
            net.add(grid, net.gnd, n_grid)
            self.v_grid0 = v_grid
        self.sim = net.start("dvpp_der_emt", h)
        self.converter.bind()
        self.v_pcc = n_pcc.attr("v")
        self.t_solve = self.h

    @property
    def last(self):
        return self.converter.last

    @last.setter
    def last(self, v_conv):
        self.converter.last = v_conv

    def measure(self):
        return self.converter.measure()

    def pcc(self):
        """The PCC voltage's space vector (pu) at the latest solution, in the stationary frame."""
        return complex(SPACE_VECTOR @ self.v_pcc.get()[:, 0]) / V_R

    def apply(self, v_conv):
        self.converter.apply(v_conv, self.timing)

    def next(self):
        """One DPsim step; returns the time of its solution."""
        t = self.t_solve
        self.t_solve = self.sim.next()  # solves at its clock's time, then advances the clock
        return t

    def close_switch(self):
        self.switch.close()

    def stop(self):
        self.sim.stop()
        self.net.cleanup()


class DerEmt(Slave):
    """The dvpp_der_emt FMU, its inputs set to the circuit's state at t = 0 before
    initialization (it initializes from them as a sinusoidal steady state)."""

    def __init__(self, params, measured, name="der_emt", path=None):
        super().__init__(path or der_emt_path(), name, {**params, **dict(zip(INPUTS, measured))})
        self.vr_in = [self.vr(n) for n in INPUTS]
        self.vr_out = [self.vr(n) for n in OUTPUTS]
        self.vr_flags = [self.vr(n) for n in FLAGS]

    def step(self, t, h, measured):
        self.fmu.setReal(self.vr_in, measured)
        self.fmu.doStep(t, h)
        return self.fmu.getReal(self.vr_out)

    def flags(self):
        return dict(zip(FLAGS, self.fmu.getBoolean(self.vr_flags)))

    def warnings(self):
        return [m for status, m in self.messages if status >= 1]


FILTER = ("R_f", "L_f", "C_f", "R_t", "L_t")
UNIT_INFO = ("S_rated", "S_base", "S_dvpp", "Tdes.H", "Tdes.D", "vdc_ratio", "vi.r", *FILTER)
# The experiments' loads, pu of S_rated at 1 pu voltage.
ISLAND_LOAD = complex(0.5, 0.1)
LOAD_STEP = complex(0.1, 0.02)
GRID_LOAD = complex(0.3, 0.05)  # the local load in the grid cases
GRID_S0 = complex(0.5, 0.1)  # the converter's initial output there (the line exports the rest)
T_STEP = 1.0
SIGNALS = ("t", "angle", *OUTPUTS)


def run(case, t_end, params=None, t_step=T_STEP, v0=1.0, timing="mid", h=H_STEP):
    """One coupled run: ``case`` = "island" or a short-circuit ratio (a number: the PCC tied to a
    stiff source through a line of R/X = 0.1). The PCC starts at ``v0`` pu, the load step closes
    at ``t_step``; ``timing``: how the held modulation becomes the source's samples (the module's
    docstring). Returns the recorded signals (arrays; ``angle``: the unwrapped PCC voltage angle
    beyond ω_nom t), the unit's parameters, its flags at the end, its warnings and the wall time
    of the coupled loop."""
    import fmpy.fmi2  # noqa: F401 (loaded before the clock starts)

    params = {"t_s": h, **(params or {})}
    # The unit's data first (its defaults, with params), to build the circuit with.
    probe = Slave(der_emt_path(), "probe", params)
    unit = dict(zip(UNIT_INFO, probe.get(*UNIT_INFO)))
    probe.free()
    f = {k: unit[k] for k in FILTER}
    if case == "island":
        circuit = Circuit(unit["S_rated"] * 1e6, f, ISLAND_LOAD, LOAD_STEP, v0=v0, h=h, timing=timing)
    else:
        circuit = Circuit(unit["S_rated"] * 1e6, f, GRID_LOAD, LOAD_STEP, z_line=grid_line(case),
                          s0=GRID_S0, v0=v0, h=h, timing=timing)
    # The converter's phase voltage (pu of v_r) per unit of modulation, at v_dc = 1.
    volts_per_m = unit["vdc_ratio"] / 2.0
    der = DerEmt(params, circuit.measure(), name=f"emt-{case}")
    n = round(t_end / h)
    k_step = round(t_step / h)
    rec = {k: np.empty(n + 1) for k in SIGNALS}
    out = der.fmu.getReal(der.vr_out)
    rec["t"][0], rec["angle"][0] = 0.0, cmath.phase(circuit.pcc())
    for j, name in enumerate(OUTPUTS):
        rec[name][0] = out[j]
    columns = [rec[name] for name in OUTPUTS]
    angle = rec["angle"][0]
    # The output at initialization is the modulation held over the first step [0, h].
    circuit.last = np.array(out[:3]) * volts_per_m
    started = time.perf_counter()
    meas = circuit.measure()
    for k in range(n):
        out = der.step(k * h, h, meas)
        if k + 1 == k_step:
            circuit.close_switch()
        circuit.apply([m * volts_per_m for m in out[:3]])
        t = circuit.next()
        meas = circuit.measure()
        a = cmath.phase(circuit.pcc() * cmath.exp(-1j * W_NOM * t))
        angle += (a - angle + math.pi) % (2 * math.pi) - math.pi
        rec["t"][k + 1], rec["angle"][k + 1] = t, angle
        for column, x in zip(columns, out):
            column[k + 1] = x
    wall = time.perf_counter() - started
    flags, warnings = der.flags(), der.warnings()
    der.free()
    circuit.stop()
    return {**rec, "wall": wall, "h": h, "unit": unit, "flags": flags, "warnings": warnings,
            "case": case, "t_step": t_step, "t_end": t_end}


def droop_check(rec, window=0.1):
    """The frequency at the end, from the PCC voltage's angle progression over the last
    ``window`` seconds and from the FMU's df, against the droop law Δf = -(p - p_set)
    (S_base/S_dvpp)/D with the FMU's p and p_set."""
    unit, h = rec["unit"], rec["h"]
    m = round(window / h)
    t, angle = rec["t"][-m:], rec["angle"][-m:]
    df_angle = np.polyfit(t - t[0], angle, 1)[0] / W_NOM
    dp = rec["p"][-1] - rec["p_set"][-1]
    df_law = -dp * (unit["S_base"] / unit["S_dvpp"]) / unit["Tdes.D"]
    return {"dp": dp, "df_law": df_law, "df_angle": df_angle, "df_fmu": rec["df"][-1],
            "err_angle": abs(df_angle / df_law - 1), "err_fmu": abs(rec["df"][-1] / df_law - 1)}


def settling_time(t, x, band):
    """The first time after which |x| stays within band (inf if it never does)."""
    outside = np.nonzero(np.abs(x) > band)[0]
    if not len(outside):
        return t[0]
    return t[outside[-1] + 1] if outside[-1] + 1 < len(t) else math.inf


# Our own master's run of the same island (scenario emt_island: the plant FMU's averaged
# converter and circuit, the unit with S_dvpp = 60 and P_avail0 = 1), for comparison.
OWN_ISLAND = {"S_dvpp": 60.0, "P_avail0": 1.0}


def own_island(out_dir):
    """Runs the bundled emt_island scenario with our master (the cosim binary beside the bundled
    FMUs) and returns its time, unit.df and unit.v as arrays, or None when either is missing."""
    import subprocess

    from conftest import DIST

    ssp = DIST.parent / "emt_island" / "emt_island.ssp"
    cosim = DIST.parents[1] / "target" / "release" / "cosim"
    if not (ssp.exists() and cosim.exists()):
        return None
    csv = os.path.join(out_dir, "emt_island.csv")
    subprocess.run([str(cosim), str(ssp), "--out", csv, "--record", "all"], check=True,
                   capture_output=True)
    with open(csv) as f:
        names = f.readline().strip().split(",")
    data = np.loadtxt(csv, delimiter=",", skiprows=1, usecols=[names.index(n) for n in
                                                                ("time", "unit.df", "unit.v")])
    return {"t": data[:, 0], "df": data[:, 1], "v": data[:, 2]}


def compare_with_own(rec, own):
    """Δf at the end and the traces' NRMSE (normalized by the peak |Δf| of our master's run)."""
    df_own = np.interp(rec["t"], own["t"], own["df"])
    nrmse = math.sqrt(np.mean((rec["df"] - df_own) ** 2)) / np.max(np.abs(own["df"]))
    return {"df_dpsim": rec["df"][-1], "df_own": own["df"][-1],
            "rel": abs(rec["df"][-1] / own["df"][-1] - 1), "nrmse": nrmse}


def grid_figures(rec, band=1e-3):
    """The grid case's figures: flatness before the step, the peak of |p - p_set| after it and
    when it settles within ``band``, p - p_set and df at the end, the range of q."""
    t, h = rec["t"], rec["h"]
    k = round(rec["t_step"] / h)
    ep = rec["p"] - rec["p_set"]
    return {"df_before": np.max(np.abs(rec["df"][:k])), "ep_before": np.max(np.abs(ep[:k])),
            "peak": np.max(np.abs(ep[k:])), "settle": settling_time(t[k:], ep[k:], band) - rec["t_step"],
            "ep_end": ep[-1], "df_end": rec["df"][-1], "q_min": np.min(rec["q"]), "q_max": np.max(rec["q"]),
            "q_end": rec["q"][-1], "q_ref_end": rec["q_ref"][-1]}


if __name__ == "__main__":
    import argparse
    import sys

    sys.path.insert(0, os.path.dirname(__file__))
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--svg", help="write the figure here")
    args = parser.parse_args()

    print("Island: 0.5 + j0.1 pu load (of 60 MVA), +0.1 + j0.02 pu at 1 s, 3 s at 50 µs")
    print("| run | Tdes.H | S_dvpp | max abs(df) before 1 s | Δp (S_base) | Δf law | Δf FMU (rel. err) "
          "| Δf PCC angle (rel. err) | wall / simulated s |")
    print("|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="emt-island-") as tmp:
        own = own_island(tmp)
    v0 = own["v"][0] if own else 1.0
    island = {}
    for name, params, start in (("default", {}, 1.0), ("own-master point", OWN_ISLAND, v0)):
        rec = island[name] = run("island", 3.0, params=params, v0=start)
        c = droop_check(rec)
        k = round(T_STEP / rec["h"])
        print(f"| {name} (PCC at {start:.6f} pu) | {rec['unit']['Tdes.H']:g} s | {rec['unit']['S_dvpp']:g} | "
              f"{np.max(np.abs(rec['df'][:k])):.1e} | {c['dp']:.6f} | {c['df_law']:.6e} | "
              f"{c['df_fmu']:.6e} ({c['err_fmu']:.1e}) | {c['df_angle']:.6e} ({c['err_angle']:.1e}) | "
              f"{rec['wall'] / 3.0:.2f} s |")
    if own:
        c = compare_with_own(island["own-master point"], own)
        print(f"\nOur master's emt_island (S_dvpp = 60): Δf at 3 s {c['df_own']:.6e}; DPsim {c['df_dpsim']:.6e}; "
              f"rel. difference {c['rel']:.2e}; NRMSE of the Δf traces (by peak abs(Δf)) {c['nrmse']:.2e}")
    else:
        print("\n(our master's cosim binary or the emt_island bundle is missing: no comparison)")

    print("\nStiff source behind a line (R/X = 0.1), local load 0.3 + j0.05 pu, the unit at 0.5 + j0.1 pu "
          "(of 60 MVA), +0.1 + j0.02 pu load at 1 s")
    print("| SCR | Tdes.H | max abs(df), abs(p - p_set) before 1 s | peak abs(p - p_set) | within 1e-3 pu after "
          "| p - p_set, df at the end | q range (q, q_ref at the end) | flags | wall / simulated s |")
    print("|---|---|---|---|---|---|---|---|---|")
    grid = {}
    for scr, hh, end in ((20, 1.0, 2.0), (3, 1.0, 2.0), (20, 5.55, 3.0), (3, 5.55, 3.0)):
        rec = grid[scr, hh] = run(scr, end, params={"Tdes.H": hh})
        g = grid_figures(rec)
        limits = [n for n, on in rec["flags"].items() if on] or "none"
        settle = f"{g['settle'] * 1e3:.0f} ms" if g["settle"] < math.inf else f"not within {end - T_STEP:g} s"
        print(f"| {scr} | {hh:g} s | {g['df_before']:.1e}, {g['ep_before']:.1e} | {g['peak']:.4f} | "
              f"{settle} | {g['ep_end']:.1e}, {g['df_end']:.1e} | {g['q_min']:.4f} .. {g['q_max']:.4f} "
              f"({g['q_end']:.4f}, {g['q_ref_end']:.4f}) | {limits} | {rec['wall'] / end:.2f} s |")

    if args.svg:
        from dpsim_host import svg_figure

        mhz = F_NOM * 1e3
        series = [(island["default"]["t"], island["default"]["df"] * mhz, "#1f77b4", False,
                   "DPsim, S_dvpp = 96"),
                  (island["own-master point"]["t"], island["own-master point"]["df"] * mhz, "#d62728", False,
                   "DPsim, S_dvpp = 60")]
        if own:
            series.append((own["t"], own["df"] * mhz, "#2ca02c", True, "our master (emt_island), S_dvpp = 60"))
        for name, colour in (("default", "#1f77b4"), ("own-master point", "#d62728")):
            law = droop_check(island[name])["df_law"] * mhz
            series.append((np.array([2.0, 3.0]), np.array([law, law]), "#555555", True, f"droop law ({name})"))
        panels = [
            ("Island: +0.1 pu load at 1 s (Tdes.H = 5.55 s)", "t (s)", "frequency deviation (mHz)", series),
            ("Stiff source behind a line: +0.1 pu load at 1 s (Tdes.H = 1 s)", "t (s)", "p - p_set (pu on 100 MVA)",
             [(grid[20, 1.0]["t"], grid[20, 1.0]["p"] - grid[20, 1.0]["p_set"], "#1f77b4", False, "SCR 20"),
              (grid[3, 1.0]["t"], grid[3, 1.0]["p"] - grid[3, 1.0]["p_set"], "#d62728", False, "SCR 3")]),
            ("Stiff source behind a line: reactive power", "t (s)", "q (pu on 100 MVA)",
             [(grid[20, 1.0]["t"], grid[20, 1.0]["q"], "#1f77b4", False, "SCR 20"),
              (grid[3, 1.0]["t"], grid[3, 1.0]["q"], "#d62728", False, "SCR 3"),
              (grid[20, 1.0]["t"], grid[20, 1.0]["q_ref"], "#555555", True, "q_ref, SCR 20")]),
        ]
        os.makedirs(os.path.dirname(os.path.abspath(args.svg)), exist_ok=True)
        with open(args.svg, "w") as f:
            f.write(svg_figure(panels, "The EMT-level DER controller FMU over DPsim's three-phase EMT circuit"))
        print(f"wrote {args.svg}")
