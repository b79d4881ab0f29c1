"""DPsim as the host of the DER FMU: the FMU is the outer controller of a grid-forming converter.

The FMU (fmpy's FMU2Slave) imposes E∠θ; DPsim realizes it as a controlled voltage source behind
R_f + jX_f (on the unit's rating) and solves the network one step at a time; the host measures
p, q, v and the voltage angle at the terminal bus in the frame rotating at f_nom and feeds them
back at the next step. Two DPsim domains:

- ``dp``: single-phase dynamic phasors (the envelope in the f_nom frame), 1 ms steps;
- ``emt``: three-phase instantaneous values, 50 µs steps; the host turns E∠θ into three
  sinusoids and the instantaneous node voltages back into a phasor with the space vector at f_nom.

Per unit: voltages on V_NOM (line-to-line RMS), powers on S_BASE; the DPsim circuit is in volts,
ohms and henries. DPsim's single-phase DP circuits carry line-to-line RMS voltages and per-phase
impedances, so V·conj(I) of a branch is the three-phase power.

Run as a script to print the figures of docs/emt.md and write the figure's SVG:
``python tests/python/dpsim_host.py [--svg PATH]``.
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
V_NOM = 20e3  # line-to-line RMS, V
S_BASE = 100e6  # VA
Z_BASE = V_NOM**2 / S_BASE
PEAK = math.sqrt(2.0 / 3.0)  # line-to-line RMS to phase peak (DPsim's RMS3PH_TO_PEAK1PH)
A120 = cmath.exp(2j * math.pi / 3)
# Instantaneous phase values (a, b, c) to the line-to-line RMS phasor at the angle 0 of f_nom.
SPACE_VECTOR = (2.0 / 3.0) * np.array([1.0, A120, A120**2]) / PEAK
R_OPEN = 1e12  # ohm, an open switch (its leakage, 4e-12 pu, is left out of the initial point)

# The unit: the generic DER (60 MVA, grid-forming, static ADPFs with mu_p = mu_q = 1, R_f + jX_f =
# 0.01 + j0.1 on its rating) with a small virtual inertia: the droop's time constant H/D is 6 ms
# (5.55 s / 33.33 = 0.17 s in the case study), so a run settles within 0.1-0.2 s.
UNIT = {"Tdes.H": 0.2}


def der_path():
    from conftest import DIST

    return str(DIST / "dvpp_der.fmu")


class Der(Slave):
    """One DER FMU instance through fmpy's FMU2Slave, driven step by step (inputs held over each
    step), with its log collected."""

    INPUTS = ("p", "q", "v", "v_angle")
    OUTPUTS = ("E", "theta", "df", "p_set", "q_ref", "i_ac", "i_limit", "p_min", "p_max")
    FLAGS = ("limit.current", "limit.dc", "limit.source", "limit.modulation", "synchronized")

    def __init__(self, params, start, name="der"):
        super().__init__(der_path(), name, {**params, **start})
        self.vr_in = [self.vars[n].valueReference for n in self.INPUTS]
        self.vr_out = [self.vars[n].valueReference for n in self.OUTPUTS]
        self.vr_flags = [self.vars[n].valueReference for n in self.FLAGS]

    def flags(self):
        return dict(zip(self.FLAGS, self.fmu.getBoolean(self.vr_flags)))

    def step(self, t, h, measured):
        self.fmu.setReal(self.vr_in, measured)
        self.fmu.doStep(t, h)
        return self.fmu.getReal(self.vr_out)

    def warnings(self):
        return [m for status, m in self.messages if status >= 1]


class Network:
    """The converter's slot and a small network in DPsim, stepped from Python.

    Nodes: ``src`` (the imposed voltage) -R_f- ``mid`` -L_f- ``bus`` (the terminal). At the bus a
    load, a series R-L branch drawing ``load`` = P + jQ (pu on S_BASE) at 1 pu voltage, and a load
    step of the same kind, ``step``, behind a switch. ``case`` = ``island``: nothing else;
    ``stiff``: the bus is also tied through the series R-L ``z_line`` (pu on S_BASE) to a stiff
    source; ``startup``: the stiff case started dead (every node at 0 V, the stiff source off
    until ``energize()``), the converter behind a breaker that is open until
    ``close_breaker()``. The initial point is the bus at 1∠0 with the converter injecting
    ``s0``; the stiff source is placed where the line carries the difference, and every node
    starts at its steady-state voltage, so a run starts flat.
    """

    def __init__(self, domain, case, z, h, s0, load, step, z_line=complex(0.01, 0.1)):
        # DPsim's components and solver open their logs under ./logs (empty with logging off):
        # build the circuit in a directory of its own, out of the working tree.
        self._tmp = tempfile.TemporaryDirectory(prefix="dpsim-")
        cwd = os.getcwd()
        os.chdir(self._tmp.name)
        try:
            self._build(domain, case, z, h, s0, load, step, z_line)
        finally:
            os.chdir(cwd)

    def _build(self, domain, case, z, h, s0, load, step, z_line):
        import dpsimpy

        self.domain, self.case, self.h = domain, case, h
        emt = domain == "emt"
        mod = dpsimpy.emt if emt else dpsimpy.dp
        ph = mod.ph3 if emt else mod.ph1
        log = dpsimpy.LogLevel.off
        self.z = z
        self.e0 = 1.0 + z * s0.conjugate()  # the bus at 1∠0
        nodes, comps = [], []

        def node(name, v_pu):
            v = v_pu * V_NOM
            if emt:
                n = mod.SimNode(name, dpsimpy.PhaseType.ABC, [v, v * A120**2, v * A120])
            else:
                n = mod.SimNode(name, dpsimpy.PhaseType.Single, [v])
            nodes.append(n)
            return n

        def mat(x):
            return x * np.eye(3) if emt else x

        def add(comp, a, b, value):
            comp.set_parameters(mat(value))
            comp.connect([a, b])
            comps.append(comp)
            return comp

        def branch(name, a, b, z_pu, v_a, i_pu):
            """Series R-L (z_pu on S_BASE) from a to b; v_a the voltage at a, i_pu the current."""
            n = node(f"{name}_rl", v_a - z_pu.real * i_pu)
            add(ph.Resistor(f"r_{name}", log), a, n, z_pu.real * Z_BASE)
            add(ph.Inductor(f"l_{name}", log), n, b, z_pu.imag * Z_BASE / W_NOM)
            return n

        gnd = mod.SimNode.gnd
        # A start from zero voltage: every node at 0 V, the stiff source off until energize(),
        # the converter behind an open breaker until the unit has synchronized.
        dead = case == "startup"
        live = 0.0 if dead else 1.0
        n_src = node("src", live * self.e0)
        n_bus = node("bus", live)
        self.vs = ph.VoltageSource("vs", log)
        self._set_phasor_params(self.vs, live * self.e0, emt)
        self.vs.connect([gnd, n_src])
        comps.append(self.vs)
        if dead:
            n_conv = node("conv", 0.0)
            n_mid = branch("f", n_src, n_conv, z, 0.0, 0.0)
            self.breaker = ph.Switch("breaker", log)
            self.breaker.set_parameters(mat(R_OPEN), mat(1e-6 * Z_BASE), False)
            self.breaker.connect([n_conv, n_bus])
            comps.append(self.breaker)
        else:
            n_mid = branch("f", n_src, n_bus, z, self.e0, s0.conjugate())
        branch("load", n_bus, gnd, 1.0 / load.conjugate(), live, live * load.conjugate())
        n_sw = node("sw", 0.0)
        self.sw = ph.Switch("sw", log)
        self.sw.set_parameters(mat(R_OPEN), mat(1e-3 * Z_BASE), False)
        self.sw.connect([n_bus, n_sw])
        comps.append(self.sw)
        branch("step", n_sw, gnd, 1.0 / step.conjugate(), 0.0, 0.0)
        if case in ("stiff", "startup"):
            i_line = (s0 - load).conjugate()  # from the bus into the line
            self.v_grid = v_grid = 1.0 - z_line * i_line
            n_grid = node("grid", live * v_grid)
            branch("line", n_bus, n_grid, z_line, live, live * i_line)
            self.grid = ph.VoltageSource("grid", log)
            self._set_phasor_params(self.grid, live * v_grid, emt)
            self.grid.connect([gnd, n_grid])
            comps.append(self.grid)

        system = dpsimpy.SystemTopology(F_NOM, nodes, comps)
        sim = dpsimpy.Simulation(f"dvpp_{domain}_{case}", log)
        sim.set_system(system)
        sim.set_domain(dpsimpy.Domain.EMT if emt else dpsimpy.Domain.DP)
        sim.set_time_step(h)
        sim.set_final_time(1e6)
        sim.do_init_from_nodes_and_terminals(True)
        sim.start()
        self.sim = sim
        # Attribute handles: reading and writing through them takes ~1 µs, the properties ~40 µs.
        self.v_ref = self.vs.attr("V_ref")
        self.v_src, self.v_mid, self.v_bus = (n.attr("v") for n in (n_src, n_mid, n_bus))
        self.dv_per_pu = z.real * Z_BASE * S_BASE / V_NOM  # volts across R_f per pu of current
        self.t_solve = h  # DPsim solves its first step at t = h (start() advances its clock)
        self.angle = 0.0

    @staticmethod
    def _set_phasor_params(source, v_pu, emt):
        v = v_pu * V_NOM
        if emt:
            source.set_parameters(np.array([[v], [v * A120**2], [v * A120]]), F_NOM)
        else:
            source.set_parameters(complex(v), 0.0)  # f_src = 0: a phasor fixed in the f_nom frame

    def set_source(self, e, theta):
        v = cmath.rect(e * V_NOM, theta)
        if self.domain == "emt":
            # RMS line-to-line per phase: DPsim imposes v_a(t) = sqrt(2/3)|V| cos(w t + theta).
            self.v_ref.set(np.array([[v], [v * A120**2], [v * A120]]))
        else:
            self.v_ref.set(v)

    def phasors(self, t):
        """The phasors (pu) of the bus voltage and of the current out of the slot at DPsim's
        solution for time t, in the frame rotating at f_nom."""
        v_bus = self.v_bus.get()
        dv = self.v_src.get() - self.v_mid.get()
        if self.domain == "emt":
            # The space vector of the three instantaneous values turned into the frame rotating
            # at f_nom and scaled to line-to-line RMS: a balanced set gives the phasor the DP
            # domain would give, at any frequency.
            turn = SPACE_VECTOR * cmath.exp(-1j * W_NOM * t)
            return complex(turn @ v_bus[:, 0]) / V_NOM, complex(turn @ dv[:, 0]) / self.dv_per_pu
        return complex(v_bus[0, 0]) / V_NOM, complex(dv[0, 0]) / self.dv_per_pu

    def next(self):
        """One DPsim step; returns (t, p, q, v, angle) at the terminal bus, pu on S_BASE, the
        angle unwrapped."""
        t = self.t_solve
        # Simulation.next() solves at its clock's time and then advances the clock by h.
        self.t_solve = self.sim.next()
        v, i = self.phasors(t)
        s = v * i.conjugate()
        a = cmath.phase(v)
        self.angle += (a - self.angle + math.pi) % (2 * math.pi) - math.pi
        return t, s.real, s.imag, abs(v), self.angle

    def close_switch(self):
        self.sw.close()

    def jump_grid(self, radians):
        attr = self.grid.attr("V_ref")
        attr.set(attr.get() * cmath.exp(1j * radians))

    def energize(self):
        v = self.v_grid * V_NOM
        attr = self.grid.attr("V_ref")
        attr.set(np.array([[v], [v * A120**2], [v * A120]]) if self.domain == "emt" else v)

    def close_breaker(self):
        self.breaker.close()

    def stop(self):
        self.sim.stop()
        self._tmp.cleanup()


STEP = {"dp": 1e-3, "emt": 50e-6}
SIGNALS = ("t", "p", "q", "v", "angle") + Der.OUTPUTS


def run(domain, case, t_end, events, params=None, s0=complex(0.3, 0.1), load=None,
        step=complex(0.1, 0.03), h=None, comm=None):
    """The FMU and DPsim coupled step by step: the measurement at t_k, the FMU's step to t_{k+1},
    its E∠θ at t_{k+1} into the source, DPsim's solution at t_{k+1}, the measurement at t_{k+1}.

    ``comm``: the FMU's communication step, a multiple of DPsim's step ``h`` (default: ``h``).
    When it is longer, the FMU steps from t_k to t_k + comm on the measurement at t_k, and the
    source follows E and θ interpolated linearly from their values at t_k to those at
    t_k + comm over DPsim's steps in between (θ moves on at the FMU's frequency instead of
    jumping once per communication step).

    ``events``: (time, what) with what = "load" (the load step's switch closes), ("jump", deg)
    (the stiff source's angle jumps) or "energize" (case "startup": the stiff source, off until
    then, comes on; the unit, initialized at zero voltage, waits, and the host closes the
    converter's breaker when the unit reports ``synchronized``). Returns the signals as arrays, the unit's parameters, its
    warnings, its limit flags at the end and the wall time of the coupled loop."""
    params = {**UNIT, **(params or {})}
    h = h or STEP[domain]
    if load is None:
        load = s0 if case == "island" else complex(0.2, 0.05)
    dead = case == "startup"
    start = {"p": s0.real, "q": 0.0 if dead else s0.imag, "v": 0.0 if dead else 1.0, "v_angle": 0.0}
    der = Der(params, start, name=f"{domain}-{case}")
    unit = dict(zip(("S_rated", "S_base", "S_dvpp", "f_nom", "Tdes.H", "Tdes.D", "R_f", "X_f"),
                    der.get("S_rated", "S_base", "S_dvpp", "f_nom", "Tdes.H", "Tdes.D", "R_f", "X_f")))
    assert unit["S_base"] * 1e6 == S_BASE and unit["f_nom"] == F_NOM, unit
    z = complex(unit["R_f"], unit["X_f"]) * unit["S_base"] / unit["S_rated"]  # on S_BASE
    net = Network(domain, case, z, h, s0, load, step)
    n = round(t_end / h)
    m = round((comm or h) / h)
    assert abs(m * h - (comm or h)) < 1e-12 * m and n % m == 0, (comm, h, t_end)
    at = {round(t / h): what for t, what in events}
    rec = {k: np.empty(n + 1) for k in SIGNALS}
    e, theta = der.get("E", "theta")
    if dead:
        meas = (0.0, 0.0, 0.0, 0.0)
        assert e == 0.0 and not der.flags()["synchronized"]
    else:
        meas = (s0.real, s0.imag, 1.0, 0.0)
        assert abs(e - abs(net.e0)) < 1e-9 and abs(theta - cmath.phase(net.e0)) < 1e-9, (e, theta, net.e0)
    closed = None
    for key, x in zip(SIGNALS, (0.0, *meas, *der.get(*Der.OUTPUTS))):
        rec[key][0] = x
    columns = [rec[key] for key in SIGNALS]
    started = time.perf_counter()
    out = der.get(*Der.OUTPUTS)
    for k in range(n):
        j = k % m
        if j == 0:
            e0, theta0 = out[0], out[1]
            out = der.step(k * h, m * h, meas)
            if dead and closed is None and der.flags()["synchronized"]:
                closed = (k + 1) * h  # the first solution with the breaker closed
                net.close_breaker()
        what = at.get(k + 1)
        if what == "load":
            net.close_switch()
        elif what == "energize":
            net.energize()
        elif what is not None:
            net.jump_grid(math.radians(what[1]))
        x = (j + 1) / m
        net.set_source(e0 + x * (out[0] - e0), theta0 + x * (out[1] - theta0))
        t, p, q, v, angle = net.next()
        meas = (p, q, v, angle)
        for column, value in zip(columns, (t, p, q, v, angle, *out)):
            column[k + 1] = value
    wall = time.perf_counter() - started
    flags = der.flags()
    warnings = der.warnings()
    der.free()
    net.stop()
    return {**rec, "wall": wall, "h": h, "comm": m * h, "unit": unit, "flags": flags,
            "warnings": warnings, "domain": domain, "case": case, "t_closed": closed,
            "events": [msg for status, msg in der.messages if status == 0]}


def droop_check(rec, window=0.1):
    """Steady-state frequency deviation from the node voltage's angle progression over the last
    ``window`` seconds, against the droop law Δf = -Δp (S_base/S_dvpp)/D with Δp = p - p_set
    (the generic unit's static ADPF with mu_p = 1: T_i^pf = 1/(H s + D))."""
    unit = rec["unit"]
    h = rec["h"]
    m = round(window / h)
    t, angle = rec["t"][-m:], rec["angle"][-m:]
    slope = np.polyfit(t - t[0], angle, 1)[0]
    df_angle = slope / (2 * math.pi * F_NOM)
    dp = rec["p"][-1] - rec["p_set"][-1]
    df_law = -dp * (unit["S_base"] / unit["S_dvpp"]) / unit["Tdes.D"]
    return {"dp": dp, "df_law": df_law, "df_angle": df_angle, "df_fmu": rec["df"][-1],
            "err_angle": abs(df_angle / df_law - 1), "err_fmu": abs(rec["df"][-1] / df_law - 1)}


def settling_time(t, x, final, band):
    """The first time after which |x - final| stays within band (inf if it never does)."""
    outside = np.nonzero(np.abs(x - final) > band)[0]
    if not len(outside):
        return t[0]
    return t[outside[-1] + 1] if outside[-1] + 1 < len(t) else math.inf


def svg_figure(panels, title, width=960, panel_height=230):
    """A small SVG of stacked panels; each panel: (title, xlabel, ylabel, series) with series
    (t, y, colour, dashed, label)."""
    left, right, top, gap = 78, 20, 44, 74
    w = width - left - right
    height = top + len(panels) * (panel_height + gap)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
           f'viewBox="0 0 {width} {height}" font-family="DejaVu Sans, Arial, sans-serif">',
           f'<rect x="0" y="0" width="{width}" height="{height}" fill="#ffffff"/>',
           f'<text x="{width / 2}" y="26" text-anchor="middle" font-size="16" font-weight="bold" '
           f'fill="#222222">{title}</text>']

    def ticks(lo, hi):
        raw = (hi - lo) / 5
        mag = 10 ** math.floor(math.log10(raw))
        step = min((m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw), default=10 * mag)
        first = math.ceil(lo / step - 1e-9) * step
        return [first + i * step for i in range(int((hi - first) / step + 1e-9) + 1)]

    for n, (ptitle, xlabel, ylabel, series) in enumerate(panels):
        y0 = top + 22 + n * (panel_height + gap)
        xs = np.concatenate([s[0] for s in series])
        ys = np.concatenate([s[1] for s in series])
        xlo, xhi = float(xs.min()), float(xs.max())
        ylo, yhi = float(ys.min()), float(ys.max())
        pad = 0.08 * (yhi - ylo or abs(yhi) or 1.0)
        ylo, yhi = ylo - pad, yhi + pad

        def px(x):
            return left + (x - xlo) / (xhi - xlo) * w

        def py(y):
            return y0 + panel_height - (y - ylo) / (yhi - ylo) * panel_height

        out.append(f'<text x="{left}" y="{y0 - 8}" font-size="13" font-weight="bold" fill="#222222">{ptitle}</text>')
        grid = []
        for x in ticks(xlo, xhi):
            grid.append(f"M{px(x):.1f} {y0}V{y0 + panel_height}")
            out.append(f'<text x="{px(x):.1f}" y="{y0 + panel_height + 16}" text-anchor="middle" '
                       f'font-size="11" fill="#444444">{x:g}</text>')
        for y in ticks(ylo, yhi):
            grid.append(f"M{left} {py(y):.1f}H{left + w}")
            out.append(f'<text x="{left - 6}" y="{py(y) + 4:.1f}" text-anchor="end" font-size="11" '
                       f'fill="#444444">{y:.6g}</text>')
        out.append(f'<path d="{"".join(grid)}" stroke="#dddddd" stroke-width="0.8" fill="none"/>')
        out.append(f'<rect x="{left}" y="{y0}" width="{w}" height="{panel_height}" stroke="#888888" fill="none"/>')
        out.append(f'<text x="{left + w / 2}" y="{y0 + panel_height + 34}" text-anchor="middle" '
                   f'font-size="12" fill="#222222">{xlabel}</text>')
        out.append(f'<text transform="translate({left - 58},{y0 + panel_height / 2}) rotate(-90)" '
                   f'text-anchor="middle" font-size="12" fill="#222222">{ylabel}</text>')
        for i, (t, y, colour, dashed, label) in enumerate(series):
            stride = max(1, len(t) // 2000)
            points = " ".join(f"{px(a):.1f},{py(b):.2f}" for a, b in zip(t[::stride], y[::stride]))
            dash = ' stroke-dasharray="6 4"' if dashed else ""
            out.append(f'<polyline stroke="{colour}" stroke-width="1.5" fill="none"{dash} points="{points}"/>')
            lx, ly = left + w - 250, y0 + 16 + 16 * i
            out.append(f'<path d="M{lx} {ly - 4}h24" stroke="{colour}" stroke-width="2"{dash}/>')
            out.append(f'<text x="{lx + 30}" y="{ly}" font-size="11" fill="#222222">{label}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    import argparse
    import sys

    sys.path.insert(0, os.path.dirname(__file__))
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--svg", help="write the figure here")
    args = parser.parse_args()
    print("| run | h | FMU step | Δp (pu) | Δf law (pu) | rel. error, bus angle | rel. error, FMU df | wall | wall / simulated s |")
    print("|---|---|---|---|---|---|---|---|---|")
    island = {}
    for name, domain, comm, params, end in (("dp", "dp", None, {}, 0.5), ("emt", "emt", None, {}, 0.5),
                                            ("emt-fmu1ms", "emt", 1e-3, {}, 0.5),
                                            ("dp-H5.55", "dp", None, {"Tdes.H": 5.55}, 3.1)):
        rec = island[name] = run(domain, "island", end, [(0.1, "load")], params=params, comm=comm)
        c = droop_check(rec)
        print(f"| island {name} | {rec['h'] * 1e3:g} ms | {rec['comm'] * 1e3:g} ms | {c['dp']:.6f} | "
              f"{c['df_law']:.6e} | {c['err_angle']:.1e} | {c['err_fmu']:.1e} | {rec['wall']:.2f} s | "
              f"{rec['wall'] / end:.2f} s |")
    print()
    print("| run | event | peak abs(p - p_set) | settled (p, q within 1e-3 pu) | p - p_set, q - q_ref at the end | wall / simulated s |")
    print("|---|---|---|---|---|---|")
    stiff = {}
    for name, domain, comm in (("dp", "dp", None), ("emt", "emt", None), ("emt-fmu1ms", "emt", 1e-3)):
        rec = stiff[name] = run(domain, "stiff", 1.5, [(0.1, "load"), (0.7, ("jump", -2.0))], comm=comm)
        t, h = rec["t"], rec["h"]
        ep, eq = rec["p"] - rec["p_set"], rec["q"] - rec["q_ref"]
        for event, start, end in (("load step", 0.1, 0.7), ("-2° jump", 0.7, 1.5 + h)):
            span = slice(round(start / h), round(end / h))
            k1 = span.stop - 1
            sp = settling_time(t[span], ep[span], 0.0, 1e-3) - start
            sq = settling_time(t[span], eq[span], 0.0, 1e-3) - start
            print(f"| stiff {name} | {event} | {np.max(np.abs(ep[span])):.4f} | {sp * 1e3:.0f} ms, {sq * 1e3:.0f} ms | "
                  f"{ep[k1]:.0e}, {eq[k1]:.0e} | {rec['wall'] / 1.5:.2f} s |")
    print()
    print("| run | breaker closed (source on at 0.05 s) | largest current in the 5 ms after | p - p_set, q - q_ref at 1 s | wall / simulated s |")
    print("|---|---|---|---|---|")
    for name, domain, comm in (("dp", "dp", None), ("emt-fmu1ms", "emt", 1e-3)):
        rec = run(domain, "startup", 1.0, [(0.05, "energize")], params={"startup.ramp": 0.3}, comm=comm)
        k = round(rec["t_closed"] / rec["h"])
        inrush = np.max(rec["i_ac"][k:k + round(5e-3 / rec["h"])])
        print(f"| startup {name} | {rec['t_closed']:.4f} s | {inrush:.1e} pu | {rec['p'][-1] - rec['p_set'][-1]:.0e}, "
              f"{rec['q'][-1] - rec['q_ref'][-1]:.0e} | {rec['wall']:.2f} s |")
    if args.svg:
        f_nom = F_NOM
        law = droop_check(island["emt"])["df_law"] * f_nom * 1e3
        cut = [(r["t"] >= 0.05) & (r["t"] <= 0.35) for r in (island["dp"], island["emt"])]
        panels = [
            ("Island: the converter alone feeds its load; +0.1 pu load at t = 0.1 s", "t (s)",
             "frequency deviation (mHz)",
             [(island["dp"]["t"][cut[0]], island["dp"]["df"][cut[0]] * f_nom * 1e3, "#1f77b4", False,
               "dynamic phasors, 1 ms"),
              (island["emt"]["t"][cut[1]], island["emt"]["df"][cut[1]] * f_nom * 1e3, "#d62728", False,
               "EMT, 50 µs"),
              (np.array([0.05, 0.35]), np.array([law, law]), "#555555", True,
               "droop law -Δp (S_base/S_dvpp)/D")]),
            ("Stiff source behind a line: +0.1 pu load at 0.1 s, source angle -2° at 0.7 s", "t (s)",
             "p (pu on 100 MVA)",
             [(stiff["dp"]["t"], stiff["dp"]["p"], "#1f77b4", False, "dynamic phasors, 1 ms"),
              (stiff["emt"]["t"], stiff["emt"]["p"], "#d62728", False, "EMT, 50 µs"),
              (stiff["emt-fmu1ms"]["t"], stiff["emt-fmu1ms"]["p"], "#2ca02c", False, "EMT, 50 µs, FMU at 1 ms"),
              (stiff["dp"]["t"], stiff["dp"]["p_set"], "#555555", True, "p_set")]),
            ("Stiff source: reactive power", "t (s)", "q (pu on 100 MVA)",
             [(stiff["dp"]["t"], stiff["dp"]["q"], "#1f77b4", False, "dynamic phasors, 1 ms"),
              (stiff["emt"]["t"], stiff["emt"]["q"], "#d62728", False, "EMT, 50 µs"),
              (stiff["emt-fmu1ms"]["t"], stiff["emt-fmu1ms"]["q"], "#2ca02c", False, "EMT, 50 µs, FMU at 1 ms"),
              (stiff["dp"]["t"], stiff["dp"]["q_ref"], "#555555", True, "q_ref (dynamic phasors)")]),
        ]
        os.makedirs(os.path.dirname(os.path.abspath(args.svg)), exist_ok=True)
        with open(args.svg, "w") as f:
            f.write(svg_figure(panels, "The DER FMU as the outer controller of a grid-forming converter in DPsim"))
        print(f"wrote {args.svg}")
