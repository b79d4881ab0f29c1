"""Case study I's nine-bus system in DPsim EMT with the DVPP's three EMT-level converters (dvpp_der_emt FMUs + operator) at bus 2.

Built from fmu-grid/cases/ieee9_dvpp.toml: SG1 and SG3, the network and the loads exactly as
tests/python/dpsim_ieee9.py builds them (its functions, imported), and at bus 2, in place of SG2,
the case's [[der]] slots as the bundled emt_thevenin system's units (wind, PV, BESS: its
wind/pv/bess.fmu, operator.fmu) hosted as tests/python/dpsim_emt_thevenin.py hosts them: each
unit's averaged converter, RLC filter and transformer (``dpsim_emt_host.Converter``, per unit on
its rating) into bus 2, the FMUs closing the loops every 50 µs, the PCC meter (SRF-PLL + lag of
the plant's pcc.f_filter_t) giving the operator's pcc.f.

- Bus 2's base voltage is taken as the host's 20 kV (``dpsim_emt_host.V_LL``) instead of 18 kV:
  its only branch is the transformer T2-8, whose ideal ratio follows the base, so nothing
  changes in per unit.
- Power flow: DPsim's NRP (dpsim_ieee9.power_flow) with a stand-in PV generator at bus 2 holding
  the slots' summed p_mw at v_set; the units then start at their slot's p_mw and a share of bus
  2's reactive power in proportion to their ratings (as the case file says).
- EMT: all nodes from the power flow, the converters' own nodes and currents from their per-unit
  steady state at bus 2's power-flow voltage; the machines (with exciter, PSS, governor) as in
  dpsim_ieee9.run; the operator's inputs start at that initial point.
- Case I's event: the case's load step (dp_mw at bus 2, constant resistance drawing dp_mw at
  bus 2's power-flow voltage) behind a switch closing at its time.

Measured (50 µs; DVPP_DIST pointing at the bundles): with no event, 2 s, max |Δf| SG1 3.4e-7, SG3
4.7e-7, PCC meter 4.1e-6 Hz, max |p - p0| wind 5.0e-5, PV 7.5e-5, BESS 3.4e-5 pu, 6 s of wall
time. The units start at our master's phasor case1_load operating point (q 0.00072, 0.00114,
0.00094 pu). With the event, 5 s (16-19 s of wall time): PCC Δf nadir -0.1352 Hz at 2.30 s (our
master's phasor case1_load run: -0.1353 Hz at 2.22 s; NRMSE of the two PCC Δf traces 3.9 % of its
peak); PCC Δf against the operator's ref.df: NRMSE 8.6 % of the peak |ref.df| (our master's
run: 8.4 %); no converter limit, no warnings.

    python tests/python/dpsim_ieee9_dvpp.py [--end 2] [--event]
"""
import argparse
import cmath
import math
import os
import pathlib
import time

import numpy as np

import dpsim_emt_host as host
import dpsim_ieee9 as ieee9
from dpsim_emt_host import SPACE_VECTOR, V_LL, V_R, DerEmt, Network
from dpsim_emt_thevenin import DER_TO_OPERATOR, OPERATOR_OUT, UNITS, PccMeter, Plant, nrmse
from fmu_slave import Slave

ROOT = pathlib.Path(__file__).resolve().parents[2]
CASE = ROOT / "fmu-grid" / "cases" / "ieee9_dvpp.toml"
H_STEP = host.H_STEP


def bundle():
    """The bundled emt_thevenin system (its unit and operator FMUs), beside dist/default."""
    from conftest import DIST

    return DIST.parent / "emt_thevenin"


def load_case(path=CASE):
    """The case, bus 2 (the DVPP's bus) at the host's voltage level (see the docstring)."""
    case = ieee9.load_case(path)
    pcc = case["pcc"]["bus"]
    for b in case["bus"]:
        if b["id"] == pcc:
            b["base_kv"] = V_LL / 1e3
    return case


def pf_case(case):
    """The case for the power flow: a stand-in PV generator at the PCC for the DVPP's slots."""
    ders = [d for d in case["der"] if d["bus"] == case["pcc"]["bus"]]
    stand_in = {"name": "DVPP", "bus": case["pcc"]["bus"], "model": "sub_transient", "base": "machine",
                "rating_mva": sum(d["rating_mva"] for d in ders), "p_mw": sum(d["p_mw"] for d in ders)}
    return {**case, "machine": case["machine"] + [stand_in]}


class Grid:
    """The nine-bus system with the DVPP's converters at the PCC bus, started from the power
    flow (DPsim simulation at step h, no solution yet)."""

    def __init__(self, case, dpsimpy, units, h=H_STEP, event=False):
        """``units``: (name, S_rated in MVA, the filter data as the FMU has it) per unit."""
        self.h, self.case = h, case
        s_base = case["base_mva"]
        pcc_bus = case["pcc"]["bus"]
        net = self.net = Network()  # now in a temporary directory (DPsim's logs)
        system_pf, v_pf, s_pf = ieee9.power_flow(pf_case(case), dpsimpy)
        self.v_pf, self.s_pf = v_pf, s_pf
        nodes, comps, gens = ieee9.build(case, dpsimpy, "emt", {b: abs(x) for b, x in v_pf.items()},
                                          ieee9.warp(case, h))
        self.gens = gens
        v = v_pf[pcc_bus] / V_LL  # pu phasor (line-to-line RMS volts / base)
        self.v0 = v
        s_dvpp = s_pf["DVPP"] / (s_base * 1e6)
        ders = {d["name"]: d for d in case["der"]}
        rating = sum(ders[name]["rating_mva"] for name, _, _ in units)
        self.s0 = {name: complex(ders[name]["p_mw"] / s_base, s_dvpp.imag * ders[name]["rating_mva"] / rating)
                   for name, _, _ in units}
        n_pcc = nodes[pcc_bus]
        self.converters, self.scale = [], []
        for name, s_rated, f in units:
            i_g = (self.s0[name] / v).conjugate() * s_base / s_rated  # pu of the unit's rating
            self.converters.append(host.Converter(net, name, s_rated * 1e6, f, n_pcc, v, i_g))
            self.scale.append(s_rated / s_base)
        self.switches = []
        if event:
            ev = next(e for e in case["event"] if e["type"] == "load_step")
            if ev.get("dq_mvar", 0.0):
                raise NotImplementedError("a reactive load step")
            r = (abs(v_pf[ev["bus"]]) ** 2) / (ev["dp_mw"] * 1e6)  # ohm: dp_mw at the power-flow voltage
            sw = net.ph3.Switch("sw_step", net.log)
            sw.set_parameters(host.R_OPEN * np.eye(3), r * np.eye(3), False)
            net.add(sw, nodes[ev["bus"]], net.gnd)
            self.switches.append((ev["time"], sw))
        system = dpsimpy.SystemTopology(case["f_nom"], list(nodes.values()) + net.nodes, comps + net.comps)
        # The nodes' start from the power flow, set here (as Network.node does: line-to-line RMS
        # phasors per phase): DPsim's init_with_powerflow crashes on the stand-in generator,
        # which has no counterpart in the EMT system.
        for b, node in nodes.items():
            x = v_pf[b]
            node.set_initial_voltage(np.array([[x], [x * host.A120**2], [x * host.A120]]))
        for m in case["machine"]:
            s = s_pf[m["name"]]
            gens[m["name"]].set_initial_values(s, s.real, v_pf[m["bus"]])
            ieee9.add_controls(gens[m["name"]], m, dpsimpy, h)
        sim = self.sim = dpsimpy.Simulation("ieee9_dvpp_emt", dpsimpy.LogLevel.off)
        sim.set_system(system)
        sim.set_domain(dpsimpy.Domain.EMT)
        sim.set_time_step(h)
        sim.set_final_time(1e6)
        sim.do_init_from_nodes_and_terminals(True)
        try:
            sim.start()
        finally:
            os.chdir(net._cwd)
        for c in self.converters:
            c.bind()
        self.v_pcc = n_pcc.attr("v")
        self.w = {name: g.attr("w_r") for name, g in gens.items()}
        self.t_solve = h

    def pcc(self):
        """The PCC voltage's space vector (pu) and each unit's p + jq into it (pu on S_base)."""
        v = complex(SPACE_VECTOR @ self.v_pcc.get()[:, 0]) / V_R
        s = [v * complex(SPACE_VECTOR @ c.i_g.get()[:, 0]).conjugate() / -c.i_r * k
             for c, k in zip(self.converters, self.scale)]
        return v, s

    def next(self):
        t = self.t_solve
        self.t_solve = self.sim.next()
        return t

    def stop(self):
        self.sim.stop()
        self.net.cleanup()


def run(t_end, event=False, h=H_STEP, root=None, case=None):
    """One coupled run; returns the recorded signals: ``t``, ``f`` (the PCC meter's pcc.f, pu),
    ``w`` (machine speeds, pu, by name), ``p``/``q`` (units x steps, pu on S_base), ``ref_df``
    (the operator's ref.df), the units' flags and warnings, the wall time of the coupled loop."""
    import dpsimpy
    import fmpy.fmi2  # noqa: F401

    root = root or bundle()
    case = case or load_case()
    plant = Plant(root / "plant.fmu")  # only its pcc.f_filter_t (the meter's lag)
    units = []
    for name in UNITS:
        probe = Slave(root / f"{name}.fmu", f"probe-{name}")
        info = dict(zip(host.UNIT_INFO, probe.get(*host.UNIT_INFO)))
        probe.free()
        units.append((name, info["S_rated"], {k: info[k] for k in host.FILTER}))
    grid = Grid(case, dpsimpy, units, h, event)
    v, s = grid.pcc()
    # The operator at this initial point (its other start values the bundle's).
    op_start = {"pcc.f": 1.0, "pcc.v": abs(v), "pcc.p": sum(x.real for x in s), "pcc.q": sum(x.imag for x in s)}
    for k, name in enumerate(UNITS):
        s0 = grid.s0[name]
        op_start.update({f"der[{k + 1}].p": s0.real, f"der[{k + 1}].q": s0.imag, f"der[{k + 1}].p_set": s0.real})
    operator = Slave(root / "operator.fmu", "operator", op_start)
    mu_names = [OPERATOR_OUT[name] for name in UNITS]
    mu_vr = [operator.vr(f"der[{k + 1}].{n}") for k, names in enumerate(mu_names) for n in names]
    mu_split = np.cumsum([len(names) for names in mu_names])[:-1]
    vr_ref_df = operator.vr("ref.df")
    mu = np.split(np.array(operator.fmu.getReal(mu_vr)), mu_split)
    ders = []
    for k, (name, _, _) in enumerate(units):
        der = DerEmt(dict(zip(mu_names[k], mu[k])), grid.converters[k].measure(), name=name,
                     path=root / f"{name}.fmu")
        der.vr_in = der.vr_in + [der.vr(n) for n in mu_names[k]]
        der.vr_out = der.vr_out + [der.vr(n) for n in DER_TO_OPERATOR]
        ders.append(der)
    op_in = [operator.vr(f"der[{k + 1}].{n}") for k in range(len(UNITS)) for n in ("P_avail", "p_set", "p", "q")]
    op_in += [operator.vr(f"pcc.{n}") for n in ("p", "q", "f", "v")]
    volts_per_m = []
    for der, c in zip(ders, grid.converters):
        vpm = der.get("vdc_ratio")[0] / 2.0
        volts_per_m.append(vpm)
        c.last = np.array(der.fmu.getReal(der.vr_out[:3])) * vpm
    meter = PccMeter(cmath.phase(v), plant.f_filter_t, h)
    switches = sorted(((round(t_on / h), sw) for t_on, sw in grid.switches), key=lambda x: x[0])
    n = round(t_end / h)
    rec = {k: np.empty(n + 1) for k in ("t", "f", "v", "ref_df")}
    rec["w"] = {name: np.empty(n + 1) for name in grid.w}
    rec["p"], rec["q"] = np.empty((len(UNITS), n + 1)), np.empty((len(UNITS), n + 1))
    f = 1.0
    rec["t"][0], rec["f"][0], rec["v"][0] = 0.0, f, abs(v)
    rec["ref_df"][0] = operator.fmu.getReal([vr_ref_df])[0]
    for name, a in grid.w.items():
        rec["w"][name][0] = a.get()
    rec["p"][:, 0], rec["q"][:, 0] = [x.real for x in s], [x.imag for x in s]
    to_operator = [der.fmu.getReal(der.vr_out[-2:]) for der in ders]
    started = time.perf_counter()
    for k in range(n):
        t = k * h
        outs = [der.step(t, h, [*c.measure(), *m]) for der, c, m in zip(ders, grid.converters, mu)]
        values = []
        for (p_avail, p_set), x in zip(to_operator, s):
            values += [p_avail, p_set, x.real, x.imag]
        p_sum = sum(s)
        operator.fmu.setReal(op_in, values + [p_sum.real, p_sum.imag, f, abs(v)])
        operator.fmu.doStep(t, h)
        out_op = operator.fmu.getReal(mu_vr + [vr_ref_df])
        mu = np.split(np.array(out_op[:-1]), mu_split)
        to_operator = [out[-2:] for out in outs]
        while switches and switches[0][0] == k + 1:
            switches.pop(0)[1].close()
        for c, out, vpm in zip(grid.converters, outs, volts_per_m):
            c.apply([x * vpm for x in out[:3]])
        t = grid.next()
        v, s = grid.pcc()
        f = meter.step(v)
        rec["t"][k + 1], rec["f"][k + 1], rec["v"][k + 1], rec["ref_df"][k + 1] = t, f, abs(v), out_op[-1]
        for name, a in grid.w.items():
            rec["w"][name][k + 1] = a.get()
        rec["p"][:, k + 1], rec["q"][:, k + 1] = [x.real for x in s], [x.imag for x in s]
    wall = time.perf_counter() - started
    flags = {name: der.flags() for der, name in zip(ders, UNITS)}
    warnings = [w for der in ders for w in der.warnings()] + [m for st, m in operator.messages if st >= 1]
    for der in ders:
        der.free()
    operator.free()
    grid.stop()
    f_nom = case["f_nom"]
    return {**rec, "wall": wall, "h": h, "t_end": t_end, "flags": flags, "warnings": warnings,
            "v0": grid.v0, "s0": grid.s0, "f_nom": f_nom,
            "t_step": min((t_on for t_on, _ in grid.switches), default=None)}


def flat_figures(rec, k_end=None):
    """The largest |Δf| (Hz) of each machine and the PCC meter, and each unit's largest |p - p0|
    (pu on S_base), over the samples before k_end (all by default)."""
    f_nom = rec["f_nom"]
    sl = slice(0, k_end)
    df = {name: float(np.max(np.abs(w[sl] - 1.0))) * f_nom for name, w in rec["w"].items()}
    df["PCC"] = float(np.max(np.abs(rec["f"][sl] - 1.0))) * f_nom
    dp = {name: float(np.max(np.abs(rec["p"][j][sl] - rec["p"][j][0]))) for j, name in enumerate(UNITS)}
    return df, dp


def event_figures(rec):
    """The PCC Δf nadir (Hz, s) and the NRMSE of the PCC Δf (pu) against the operator's ref.df
    (by the peak |ref.df|)."""
    df = rec["f"] - 1.0
    k = int(np.argmin(df))
    return {"nadir": (df[k] * rec["f_nom"], rec["t"][k]), "nrmse": nrmse(df, rec["ref_df"]),
            "ref_nadir": (float(np.min(rec["ref_df"])) * rec["f_nom"], rec["t"][int(np.argmin(rec["ref_df"]))])}


OWN_SIGNALS = ("time", "grid.pcc.f", "operator.ref.df")


def own_case1(out_dir, t_end):
    """Our master's run of the bundled case1_load system (the phasor grid FMU of the same case,
    1 ms steps) for ``t_end``: the signals of OWN_SIGNALS as arrays, or None when the cosim
    binary or the bundle is missing."""
    import subprocess

    from conftest import DIST

    ssp = DIST.parent / "case1_load" / "case1_load.ssp"
    cosim = DIST.parents[1] / "target" / "release" / "cosim"
    if not (ssp.exists() and cosim.exists()):
        return None
    csv = os.path.join(out_dir, "case1_load.csv")
    subprocess.run([str(cosim), str(ssp), "--out", csv, "--stop", str(t_end), "--record",
                    ",".join(OWN_SIGNALS[1:])], check=True, capture_output=True)
    with open(csv) as f:
        names = f.readline().strip().split(",")
    data = np.loadtxt(csv, delimiter=",", skiprows=1, usecols=[names.index(n) for n in OWN_SIGNALS])
    return dict(zip(OWN_SIGNALS, data.T))


def compare_own(rec, own):
    """The PCC Δf against our master's phasor run: NRMSE by its peak |Δf|, its nadir (Hz, s),
    and its own PCC Δf against its ref.df (NRMSE by the peak |ref.df|)."""
    df_own = own["grid.pcc.f"] - 1.0
    k = int(np.argmin(df_own))
    return {"nrmse": nrmse(rec["f"] - 1.0, np.interp(rec["t"], own["time"], df_own)),
            "nadir_own": (df_own[k] * rec["f_nom"], own["time"][k]),
            "nrmse_own_ref": nrmse(df_own, own["operator.ref.df"])}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--end", type=float, default=None, help="simulated time, s (2 flat, 5 with --event)")
    parser.add_argument("--event", action="store_true", help="the case's 28 MW load step at bus 2")
    args = parser.parse_args()
    end = args.end or (5.0 if args.event else 2.0)
    rec = run(end, event=args.event)
    print(f"DPsim EMT, {end:g} s at {rec['h'] * 1e6:g} µs, event {'on' if args.event else 'off'}: "
          f"wall {rec['wall']:.1f} s; PCC at t = 0 {abs(rec['v0']):.6f} pu at {math.degrees(cmath.phase(rec['v0'])):.4f} deg")
    print("units' start (pu on S_base): " + ", ".join(f"{n} {s.real:.4f}{s.imag:+.4f}j" for n, s in rec["s0"].items()))
    k_end = round(rec["t_step"] / rec["h"]) if rec["t_step"] is not None else None
    df, dp = flat_figures(rec, k_end)
    print("max |Δf| (Hz)" + (" before the event" if k_end else "") + ": "
          + ", ".join(f"{n} {x:.2e}" for n, x in df.items()))
    print("max |p - p0| (pu on S_base): " + ", ".join(f"{n} {x:.2e}" for n, x in dp.items()))
    if args.event:
        e = event_figures(rec)
        print(f"PCC Δf nadir {e['nadir'][0]:.5f} Hz at {e['nadir'][1]:.4f} s; operator ref.df min "
              f"{e['ref_nadir'][0]:.5f} Hz at {e['ref_nadir'][1]:.4f} s; NRMSE (PCC Δf vs ref.df, by peak) {e['nrmse']:.3e}")
        import tempfile

        with tempfile.TemporaryDirectory(prefix="case1-load-") as tmp:
            own = own_case1(tmp, end)
        if own is None:
            print("(our master's cosim binary or the case1_load bundle is missing: no comparison)")
        else:
            c = compare_own(rec, own)
            print(f"our master's phasor case1_load: PCC Δf nadir {c['nadir_own'][0]:.5f} Hz at {c['nadir_own'][1]:.4f} s; "
                  f"NRMSE of DPsim's PCC Δf against it (by its peak) {c['nrmse']:.3e}; its own PCC Δf vs its "
                  f"ref.df NRMSE {c['nrmse_own_ref']:.3e}")
        print(f"at {end:g} s: PCC Δf {(rec['f'][-1] - 1) * rec['f_nom']:.5f} Hz, ref.df {rec['ref_df'][-1] * rec['f_nom']:.5f} Hz")
    print(f"flags {rec['flags']}; warnings {rec['warnings']}")


if __name__ == "__main__":
    main()
