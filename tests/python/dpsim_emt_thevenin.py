"""DPsim as the EMT host of case study I's DVPP on a swinging Thevenin source (scenario emt_thevenin).

The bundled system dist/emt_thevenin: three grid-forming ``dvpp_der_emt`` units (wind 46 MVA,
PV 73 MVA, BESS 60 MVA: the bundle's wind.fmu, pv.fmu, bess.fmu, which carry the scenario's
start values) and the DVPP operator (operator.fmu), on the plant of plant.fmu. Here DPsim's
three-phase EMT domain (50 µs) computes the plant instead: each unit's converter, filter and
transformer (``dpsim_emt_host.Converter``, per unit on its rating, the whole circuit at 20 kV)
into one PCC, the constant-impedance loads (series R-L of the plant's "at 1 pu" powers), the load
step behind a switch closing at its t_on, and the Thevenin source behind R + jX. The host does
what the plant FMU does beyond the circuit:

- the swing of the Thevenin source, ``2H dΔω/dt = p_m - p_e - D Δω`` on S_base, ``p_m`` its
  electrical power at t = 0: each step ``p_e`` (its EMF times its current) at DPsim's solution
  advances Δω over the step exactly for that power (as the plant does with the step's mean power:
  one step behind the circuit), the angle by the trapezoidal rule, and the source, a
  ControlledVoltageSource, takes the EMF's instantaneous values at the next solution's time;
- the PCC meter: an SRF-PLL (kp 60, ki 240) on the PCC voltage, ``1 + Δω/ω_b`` through a first
  order lag of ``pcc.f_filter_t`` gives ``pcc.f``;
- the operator's network inputs: each unit's p, q into the PCC (the PCC voltage times its
  transformer current, on S_base), their sums ``pcc.p``, ``pcc.q``, and ``pcc.v``, ``pcc.f``.

Coupling, every 50 µs, as our master's Jacobi steps do between the controllers: the units step
from DPsim's solution at t_k and the operator's gains of t_k, the operator from the units'
outputs and the network's measurements at t_k. DPsim has no dc link: v_dc = 1 (the plant's dc
links stay within 1 % of 1; the FMU divides its modulation by the v_dc it reads, so the
converter's voltage does not depend on it: fed the plant's v_dc traces, this host's figures
did not change in their printed digits).

The run starts flat from the plant's steady state (solved here as a phasor circuit, the units
injecting the plant's p0 + j q0 at the PCC). One difference remains at the load step: the plant
connects the load with zero current at t_on and steps exactly, DPsim's trapezoidal rule has the
closed switch's inductive branch carry (h/2L) v at the solution at t_on, about half a step
early; the units' p, which jumps by 0.02-0.04 pu in that sample (their instantaneous share of
the step through the network), differs there, and that millisecond carries most of the units'
Δp difference. ``python tests/python/dpsim_emt_thevenin.py
[--end T]`` prints the comparison with our master's run of the bundle.
"""
import cmath
import math
import os
import subprocess
import time
import tomllib
import zipfile

import numpy as np

import dpsim_emt_host as host
from dpsim_emt_host import SPACE_VECTOR, V_LL, V_R, W_NOM, DerEmt, Network, instantaneous
from fmu_slave import Slave

UNITS = ("wind", "pv", "bess")
PLL_GAINS = (60.0, 240.0)  # the plant's pll.kp, pll.ki (its defaults)
H_STEP = host.H_STEP


def bundle():
    """The bundled emt_thevenin system's directory (beside dist/default)."""
    from conftest import DIST

    return DIST.parent / "emt_thevenin"


def fmu_config(path):
    """The resources/config.toml an FMU of the bundle carries (its model and start values)."""
    with zipfile.ZipFile(path) as z:
        return tomllib.loads(z.read("resources/config.toml").decode())


class Plant:
    """The plant's data from plant.fmu's config.toml: the Thevenin source (R, X, E, angle, H, D
    on S_base), the loads (p, q at 1 pu, t_on), the units' start powers (p0, q0 on S_base, by
    name), S_base (MVA) and the PCC frequency's lag."""

    def __init__(self, path):
        config = fmu_config(path)
        start = config["start"]
        self.s_base = start["S_base"]
        self.th = {k: start[f"thevenin.{k}"] for k in ("R", "X", "E", "angle", "H", "D")}
        self.f_filter_t = start["pcc.f_filter_t"]
        self.loads = [(load["name"], complex(load["p"], load["q"]), load["t_on"])
                      for load in config["model"]["loads"]]
        self.s0 = {u["name"]: complex(u["p0"], u["q0"]) for u in config["model"]["units"]}

    def steady_state(self):
        """The PCC voltage (phasor, pu) with the Thevenin source as slack, the loads on at t = 0
        connected and each unit injecting its s0: a fixed point of the PCC's nodal equation."""
        z_th = complex(self.th["R"], self.th["X"])
        e = self.th["E"] * cmath.exp(1j * self.th["angle"])
        y = 1.0 / z_th + sum(s.conjugate() for _, s, t_on in self.loads if t_on <= 0.0)
        s_units = sum(self.s0.values())
        v = complex(1.0)
        for _ in range(200):
            v_new = (e / z_th + (s_units / v).conjugate()) / y
            if abs(v_new - v) < 1e-15:
                break
            v = v_new
        return v_new


class PccMeter:
    """The plant's PCC frequency meter: an SRF-PLL on the PCC voltage's space vector (the phase
    error atan2(v_q, v_d) drives Δω = kp ε + ki ∫ε, the angle advances by ω_b + Δω), and 1 + Δω/ω_b
    through a first-order lag of ``t_filter``. Locked on the angle ``theta`` at t = 0."""

    def __init__(self, theta, t_filter, h, gains=PLL_GAINS):
        self.theta, self.dw, self.xi, self.df = theta, 0.0, 0.0, 0.0
        self.kp, self.ki = gains
        self.h = h
        self.lag = -math.expm1(-h / t_filter) if t_filter > 0.0 else 1.0

    def step(self, v):
        """Advance over one step and take the PCC voltage's space vector v at its end; returns
        pcc.f (pu)."""
        self.theta += (W_NOM + self.dw) * self.h
        e = cmath.phase(v * cmath.exp(-1j * self.theta)) if abs(v) > 1e-9 else 0.0
        self.xi += self.ki * e * self.h
        self.dw = self.kp * e + self.xi
        self.df += self.lag * (self.dw / W_NOM - self.df)
        return 1.0 + self.df


class Swing:
    """The Thevenin source's angle: ``2H dΔω/dt = p_m - p_e - D Δω`` (pu on S_base), Δω over a
    step exact for the power held, the angle δ (beyond its start) by the trapezoidal rule."""

    def __init__(self, h_inertia, d, p_m, h):
        self.h, self.p_m, self.d = h, p_m, d
        self.k = math.exp(-h * d / (2.0 * h_inertia))
        self.dw, self.delta = 0.0, 0.0

    def step(self, p_e):
        dw0 = self.dw
        self.dw = dw0 * self.k + (self.p_m - p_e) / self.d * (1.0 - self.k)
        self.delta += W_NOM * self.h * 0.5 * (dw0 + self.dw)
        return self.delta


class TheveninCircuit:
    """The plant in DPsim's three-phase EMT domain: the units' converters into the PCC, the loads
    (those with t_on > 0 behind open switches), the Thevenin source (a ControlledVoltageSource
    behind R + jX), all starting at the plant's steady state."""

    def __init__(self, plant, units, h=H_STEP):
        """``units``: (name, S_rated in MVA, the filter data as the FMU has it) per unit."""
        self.plant, self.h = plant, h
        net = self.net = Network()
        s_base = plant.s_base * 1e6
        z_b = V_LL**2 / s_base
        self.i_b = (2.0 / 3.0) * s_base / V_R  # A, the network's base peak current
        v = plant.steady_state()
        self.v0 = v
        n_pcc = net.node("pcc", v)
        self.converters, self.scale = [], []
        for name, s_rated, f in units:
            i_g = (plant.s0[name] / v).conjugate() * plant.s_base / s_rated  # pu of the unit's rating
            self.converters.append(host.Converter(net, name, s_rated * 1e6, f, n_pcc, v, i_g))
            self.scale.append(s_rated / plant.s_base)
        self.switches = []
        for name, s, t_on in plant.loads:
            z = 1.0 / s.conjugate()
            if t_on <= 0.0:
                net.rl(name, n_pcc, net.gnd, z, z_b, v, v / z)
            else:
                self.switches.append((t_on, net.switched_load(name, n_pcc, z, z_b)))
        th = plant.th
        z_th = complex(th["R"], th["X"])
        self.e0 = th["E"] * cmath.exp(1j * th["angle"])
        i_th = (self.e0 - v) / z_th
        n_th = net.node("thevenin", self.e0)
        self.source = net.controlled_source("thevenin", n_th, self.e0)
        self.l_th = net.rl("thevenin", n_th, n_pcc, z_th, z_b, self.e0, i_th)
        self.p_m = (self.e0 * i_th.conjugate()).real  # its electrical power at t = 0, pu on S_base
        self.sim = net.start("dvpp_emt_thevenin", h)
        for c in self.converters:
            c.bind()
        self.v_pcc, self.e_ref, self.i_th = n_pcc.attr("v"), self.source.attr("V_ref"), self.l_th.attr("i_intf")
        self.t_solve = h

    def pcc(self):
        """The PCC voltage's space vector (pu) and each unit's p + jq into it (pu on S_base) at
        the latest solution."""
        v = complex(SPACE_VECTOR @ self.v_pcc.get()[:, 0]) / V_R
        s = [v * complex(SPACE_VECTOR @ c.i_g.get()[:, 0]).conjugate() / -c.i_r * k
             for c, k in zip(self.converters, self.scale)]
        return v, s

    def p_e(self):
        """The Thevenin EMF's electrical power (pu on S_base) at the latest solution: the sum of
        its phase voltages times the currents it drives toward the PCC (i_intf runs back)."""
        return float(self.e_ref.get()[:, 0] @ -self.i_th.get()[:, 0]) / (1.5 * V_R * self.i_b)

    def set_angle(self, delta, t):
        """The EMF at the angle δ beyond its start, for DPsim's solution at t."""
        self.e_ref.set(instantaneous(self.e0 * cmath.exp(1j * delta), t))

    def next(self):
        """One DPsim step; returns the time of its solution."""
        t = self.t_solve
        self.t_solve = self.sim.next()
        return t

    def stop(self):
        self.sim.stop()
        self.net.cleanup()


# The operator's gains each unit reads and the outputs the operator reads, as the SSD wires them.
OPERATOR_OUT = {"wind": ("mu_p", "mu_q"), "pv": ("mu_p", "mu_q"), "bess": ("mu_q", "mu_p_lpf[1]", "mu_p_lpf[2]")}
DER_TO_OPERATOR = ("P_avail", "p_set")
SIGNALS = ("t", "f", "dw_th", "v")


def run(t_end, h=H_STEP, root=None):
    """One coupled run of ``t_end`` seconds; returns the recorded signals (arrays: ``f`` the PCC
    meter's pcc.f, ``dw_th`` the source's speed deviation, ``v`` pcc.v, ``p``/``q`` (units x
    steps) the units' powers into the PCC), the units' flags and warnings at the end and the
    wall time of the coupled loop."""
    import fmpy.fmi2  # noqa: F401 (loaded before the clock starts)

    root = root or bundle()
    plant = Plant(root / "plant.fmu")
    # The units' data from their FMUs (the bundle's start values), to build the circuit with.
    units = []
    for name in UNITS:
        probe = Slave(root / f"{name}.fmu", f"probe-{name}")
        info = dict(zip(host.UNIT_INFO, probe.get(*host.UNIT_INFO)))
        probe.free()
        units.append((name, info["S_rated"], {k: info[k] for k in host.FILTER}))
    circuit = TheveninCircuit(plant, units, h)
    # The operator at the scenario's initial point (its bundled start values), its gains the
    # units' start values.
    operator = Slave(root / "operator.fmu", "operator")
    mu_names = [OPERATOR_OUT[name] for name in UNITS]
    mu_vr = [operator.vr(f"der[{k + 1}].{n}") for k, names in enumerate(mu_names) for n in names]
    mu_split = np.cumsum([len(names) for names in mu_names])[:-1]
    mu = np.split(np.array(operator.fmu.getReal(mu_vr)), mu_split)
    ders = []
    for k, (name, _, _) in enumerate(units):
        der = DerEmt(dict(zip(mu_names[k], mu[k])), circuit.converters[k].measure(), name=name,
                     path=root / f"{name}.fmu")
        # One setReal and one getReal a step: the gains after the measurements, P_avail and
        # p_set after the outputs.
        der.vr_in = der.vr_in + [der.vr(n) for n in mu_names[k]]
        der.vr_out = der.vr_out + [der.vr(n) for n in DER_TO_OPERATOR]
        ders.append(der)
    op_in = [operator.vr(f"der[{k + 1}].{n}") for k in range(len(UNITS)) for n in ("P_avail", "p_set", "p", "q")]
    op_in += [operator.vr(f"pcc.{n}") for n in ("p", "q", "f", "v")]
    volts_per_m = []
    for der, c in zip(ders, circuit.converters):
        vpm = der.get("vdc_ratio")[0] / 2.0
        volts_per_m.append(vpm)
        c.last = np.array(der.fmu.getReal(der.vr_out[:3])) * vpm  # held over the first step
    v, s = circuit.pcc()
    meter = PccMeter(cmath.phase(v), plant.f_filter_t, h)
    swing = Swing(plant.th["H"], plant.th["D"], circuit.p_m, h)
    switches = sorted(((round(t_on / h), sw) for t_on, sw in circuit.switches), key=lambda x: x[0])
    n = round(t_end / h)
    rec = {k: np.empty(n + 1) for k in SIGNALS}
    rec["p"], rec["q"] = np.empty((len(UNITS), n + 1)), np.empty((len(UNITS), n + 1))
    f = 1.0
    rec["t"][0], rec["f"][0], rec["dw_th"][0], rec["v"][0] = 0.0, f, 0.0, abs(v)
    rec["p"][:, 0], rec["q"][:, 0] = [x.real for x in s], [x.imag for x in s]
    to_operator = [der.fmu.getReal(der.vr_out[-2:]) for der in ders]
    started = time.perf_counter()
    for k in range(n):
        t = k * h
        # The units from the solution at t and the operator's gains of t.
        outs = [der.step(t, h, [*c.measure(), *m]) for der, c, m in zip(ders, circuit.converters, mu)]
        # The operator from the units' outputs and the network's measurements at t.
        values = []
        for (p_avail, p_set), x in zip(to_operator, s):
            values += [p_avail, p_set, x.real, x.imag]
        p_sum = sum(s)
        operator.fmu.setReal(op_in, values + [p_sum.real, p_sum.imag, f, abs(v)])
        operator.fmu.doStep(t, h)
        mu = np.split(np.array(operator.fmu.getReal(mu_vr)), mu_split)
        to_operator = [out[-2:] for out in outs]
        # The sources for the solution at t + h.
        while switches and switches[0][0] == k + 1:
            switches.pop(0)[1].close()
        for c, out, vpm in zip(circuit.converters, outs, volts_per_m):
            c.apply([x * vpm for x in out[:3]])
        circuit.set_angle(swing.step(circuit.p_e()), t + h)
        t = circuit.next()
        v, s = circuit.pcc()
        f = meter.step(v)
        rec["t"][k + 1], rec["f"][k + 1], rec["dw_th"][k + 1], rec["v"][k + 1] = t, f, swing.dw, abs(v)
        rec["p"][:, k + 1], rec["q"][:, k + 1] = [x.real for x in s], [x.imag for x in s]
    wall = time.perf_counter() - started
    flags = {name: der.flags() for der, name in zip(ders, UNITS)}
    warnings = [w for der in ders for w in der.warnings()] + [m for st, m in operator.messages if st >= 1]
    for der in ders:
        der.free()
    operator.free()
    circuit.stop()
    return {**rec, "wall": wall, "h": h, "t_end": t_end, "flags": flags, "warnings": warnings,
            "t_step": min(t_on for _, _, t_on in plant.loads if t_on > 0.0), "v0": circuit.v0}


OWN_SIGNALS = ("time", "plant.pcc.f", "plant.pcc.v", "plant.thevenin.df",
               *(f"plant.der[{k + 1}].p" for k in range(len(UNITS))))


def own_thevenin(out_dir, t_end=None):
    """Runs the bundled emt_thevenin system with our master (the cosim binary beside the bundle)
    for ``t_end`` (its default experiment: 10 s) and returns the signals of OWN_SIGNALS as arrays,
    or None when either is missing."""
    from conftest import DIST

    ssp = bundle() / "emt_thevenin.ssp"
    cosim = DIST.parents[1] / "target" / "release" / "cosim"
    fmus = [bundle() / f"{name}.fmu" for name in (*UNITS, "operator", "plant")]
    if not all(p.exists() for p in (ssp, cosim, *fmus)):
        return None
    csv = os.path.join(out_dir, "emt_thevenin.csv")
    args = [str(cosim), str(ssp), "--out", csv, "--record", ",".join(OWN_SIGNALS[1:])]
    if t_end is not None:
        args += ["--stop", str(t_end)]
    subprocess.run(args, check=True, capture_output=True)
    with open(csv) as f:
        names = f.readline().strip().split(",")
    data = np.loadtxt(csv, delimiter=",", skiprows=1, usecols=[names.index(n) for n in OWN_SIGNALS])
    return dict(zip(OWN_SIGNALS, data.T))


def nrmse(x, ref):
    """RMS of x - ref over the peak |ref|."""
    return math.sqrt(np.mean((x - ref) ** 2)) / np.max(np.abs(ref))


def compare(rec, own, f_nom=host.F_NOM):
    """The PCC frequency deviations (pu) against our master's: NRMSE by its peak |Δf|, the nadirs
    (Hz, s); each unit's Δp (p minus its initial) NRMSE by its peak |Δp|, over the run and from
    1 ms after the load step on (the step's first sample differs: see the module's docstring);
    flatness before the step."""
    t = rec["t"]
    df = rec["f"] - 1.0
    df_own = np.interp(t, own["time"], own["plant.pcc.f"] - 1.0)
    k_own, k = np.argmin(own["plant.pcc.f"]), np.argmin(df)
    k_step = round(rec["t_step"] / rec["h"])
    k_late = k_step + round(1e-3 / rec["h"])
    dp, dp_late = {}, {}
    for j, name in enumerate(UNITS):
        p_own = own[f"plant.der[{j + 1}].p"]
        x, ref = rec["p"][j] - rec["p"][j][0], np.interp(t, own["time"], p_own - p_own[0])
        dp[name] = nrmse(x, ref)
        dp_late[name] = math.sqrt(np.mean((x[k_late:] - ref[k_late:]) ** 2)) / np.max(np.abs(ref))
    return {"nrmse": nrmse(df, df_own),
            "nadir": (df[k] * f_nom, t[k]),
            "nadir_own": ((own["plant.pcc.f"][k_own] - 1.0) * f_nom, own["time"][k_own]),
            "end": (df[-1] * f_nom, df_own[-1] * f_nom),
            "dp": dp,
            "dp_late": dp_late,
            "df_before": np.max(np.abs(df[:k_step])),
            "dp_before": np.max(np.abs(rec["p"][:, :k_step] - rec["p"][:, :1])),
            "v0": (abs(rec["v0"]), own["plant.pcc.v"][0])}


def report(rec, c):
    print(f"DPsim EMT, {rec['t_end']:g} s at {rec['h'] * 1e6:g} µs: wall {rec['wall']:.1f} s "
          f"({rec['wall'] / rec['t_end']:.2f} s per simulated s)")
    print(f"PCC at t = 0: {c['v0'][0]:.9f} pu (our master {c['v0'][1]:.9f}); before the step: "
          f"max |Δf| {c['df_before']:.1e} pu, max |Δp| {c['dp_before']:.1e} pu")
    print(f"PCC Δf NRMSE {c['nrmse']:.1e} of the peak; nadir {c['nadir'][0]:.6f} Hz at "
          f"{c['nadir'][1]:.4f} s (our master {c['nadir_own'][0]:.6f} Hz at {c['nadir_own'][1]:.4f} s); "
          f"at {rec['t_end']:g} s {c['end'][0]:.6f} Hz (ours {c['end'][1]:.6f})")
    print("units' Δp NRMSE (by the peak of our master's): " + ", ".join(f"{n} {x:.1e}" for n, x in c["dp"].items())
          + f"; from {rec['t_step'] * 1e3 + 1:g} ms on: "
          + ", ".join(f"{n} {x:.1e}" for n, x in c["dp_late"].items()))
    print(f"flags {rec['flags']}; warnings {rec['warnings']}")


if __name__ == "__main__":
    import argparse
    import sys
    import tempfile

    sys.path.insert(0, os.path.dirname(__file__))
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--end", type=float, default=10.0, help="simulated time, s")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="emt-thevenin-") as tmp:
        own = own_thevenin(tmp, args.end)
    rec = run(args.end)
    if own is None:
        print("(our master's cosim binary or the emt_thevenin bundle is missing: no comparison)")
    else:
        report(rec, compare(rec, own))
