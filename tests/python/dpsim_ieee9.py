"""The case file's IEEE nine-bus system in DPsim's three-phase EMT domain: power flow, EMT start, flat-start check.

Built from fmu-grid/cases/ieee9.toml (read with tomllib, nothing typed twice), in SI units at each
bus's base_kv: lines as PiLines (r, x, b on base_mva), transformers as an ideal ratio (HV side end
1) with the series impedance referred to the HV side, constant-impedance loads (as in our grid
model: P + jQ in the power flow, then an R || L RXLoad of that power at the power-flow voltage), the
machines as 6th-order VBR synchronous generators (SynchronGenerator6bOrderVBR) with their data on
the machine rating. DPsim's 6th-order VBR model takes no stator resistance (ra is not modelled)
and L0 = x_l here. Controls (add_controls; all by default): the ST1A exciter as DPsim's
ExciterStatic, the PSS1A on the speed, the reheat steam governor and turbine.

Power flow: DPsim's NRP solver on an sp.ph1 copy (slack at the slack bus, PV at the others with the
machines' p_mw). EMT: every node and component initialized from the power flow, the generators
(and their controls) from their power-flow power and terminal voltage; 50 µs steps, no event.
Two DPsim details would break the flat start and are undone in build: the transformers' terminal
snubbers (0.1 % of the rated power as load on each side: the transformers get a tiny rated
power) and the PiLine's default 1e-6 S shunt conductance for G = 0. The trapezoidal rule's
reactances, off by (ωh)²/12 at f_nom, load the machines slightly more than the power flow
does: without governors they drift together by 1.0e-4 Hz over 2 s at 50 µs (2.5e-5 at 25 µs,
4.0e-4 at 100 µs), with them by 5e-6 Hz; the network's L and C are pre-warped (warp) to remove
that (1e-7 Hz left, either way).

    python tests/python/dpsim_ieee9.py [--end 2.0] [--controls exciter,pss,governor|none]
"""
import argparse
import math
import os
import pathlib
import tempfile
import time
import tomllib

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
CASE = ROOT / "fmu-grid" / "cases" / "ieee9.toml"
H_STEP = 50e-6
S_SNUB = 1e3  # VA, the transformers' 'rated power' (see build): ~1 W of snubber load each
CONTROLS = ("exciter", "pss", "governor")
G_TINY = 1e-12  # S, a line's shunt conductance (0.05 W at 230 kV)
R_OPEN = 1e12  # ohm, an open switch


def load_case(path=CASE):
    with open(path, "rb") as f:
        return tomllib.load(f)


def _z_base(case, kv):
    return (kv * 1e3) ** 2 / (case["base_mva"] * 1e6)


def warp(case, h):
    """The factor k = (ωh/2) / tan(ωh/2) (1 - (ωh)²/12 to first order): the trapezoidal rule at
    step h gives an inductance L the reactance ωL/k at f_nom and a capacitance C the susceptance
    ωC/k; with L·k and C·k the discrete network has the power flow's reactances at f_nom."""
    x = math.pi * case["f_nom"] * h
    return x / math.tan(x)


def build(case, dpsimpy, domain, v_load=None, k=1.0):
    """The nodes and components of the case in one domain ("sp": the power flow, "emt"). In the
    power flow a load is P + jQ (a PQ load); in EMT an R || L of that power at the bus's
    power-flow voltage v_load[bus] (volts, line-to-line RMS; base_kv when not given). The
    network's inductances and capacitances are scaled by k (see warp; not the machines')."""
    log = dpsimpy.LogLevel.off
    w = 2 * math.pi * case["f_nom"]
    kv = {b["id"]: b["base_kv"] for b in case["bus"]}
    kind = {b["id"]: b.get("kind", "pq") for b in case["bus"]}
    vset = {b["id"]: b.get("v_set", 1.0) for b in case["bus"]}
    if domain == "sp":
        mod, node = dpsimpy.sp.ph1, lambda n: dpsimpy.sp.SimNode(n, dpsimpy.PhaseType.Single)
        mat = lambda x: x  # noqa: E731
    else:
        mod, node = dpsimpy.emt.ph3, lambda n: dpsimpy.emt.SimNode(n, dpsimpy.PhaseType.ABC)
        mat = lambda x: x * np.eye(3)  # noqa: E731
    nodes = {b: node(f"bus{b}") for b in kv}
    comps, gens = [], {}
    for ln in case["line"]:
        f, t = ln["from"], ln["to"]
        zb = _z_base(case, kv[f])
        c = mod.PiLine(f"line{f}-{t}", log)
        # DPsim's PiLine replaces a zero shunt conductance by 1e-6 S (0.3 MW over the six lines
        # at 230 kV): G_TINY instead, no conductance in effect.
        c.set_parameters(mat(ln.get("r", 0.0) * zb), mat(k * ln["x"] * zb / w), mat(k * ln.get("b", 0.0) / zb / w),
                         mat(G_TINY))
        if domain == "sp":
            c.set_base_voltage(kv[f] * 1e3)
        c.connect([nodes[f], nodes[t]])
        comps.append(c)
    for tr in case["transformer"]:
        a, b = tr["from"], tr["to"]
        hv, lv = (a, b) if kv[a] >= kv[b] else (b, a)
        zb = _z_base(case, kv[hv])
        if (tr.get("tap") or 1.0) != 1.0:
            raise NotImplementedError("off-nominal taps")
        c = mod.Transformer(tr["name"], log)
        ratio = kv[hv] / kv[lv]
        r, l = tr.get("r", 0.0) * zb, k * tr["x"] * zb / w
        # DPsim's transformer uses its rated power only to size its terminal snubbers (0.1 % of
        # it as a resistive load on each side and a small capacitor, not in the power flow; with
        # 100 MVA they took 0.6 MW in all): S_SNUB makes them vanish.
        c.set_parameters(kv[hv] * 1e3, kv[lv] * 1e3, S_SNUB, ratio, 0.0, mat(r), mat(l))
        if domain == "sp":
            c.set_base_voltage(kv[hv] * 1e3)
        c.connect([nodes[hv], nodes[lv]])
        comps.append(c)
    for ld in case["load"]:
        if ld.get("model", "constant_impedance") != "constant_impedance":
            raise NotImplementedError("constant-impedance loads only")
        bus, v = ld["bus"], kv[ld["bus"]] * 1e3
        p, q = ld["p_mw"] * 1e6, ld.get("q_mvar", 0.0) * 1e6
        if domain == "sp":
            c = mod.Load(f"load{bus}", log)
            c.set_parameters(p, q, v)
            c.modify_power_flow_bus_type(dpsimpy.PowerflowBusType.PQ)
        else:
            c = mod.RXLoad(f"load{bus}", log)
            q = q / k if q > 0 else q * k  # an inductance (Q = V²/X) or a capacitance (Q = -V²B)
            c.set_parameters(mat(p / 3), mat(q / 3), (v_load or {}).get(bus, v))
        c.connect([nodes[bus]])
        comps.append(c)
    for m in case["machine"]:
        if m.get("base", "machine") != "machine" or m["model"] != "sub_transient":
            raise NotImplementedError("sub-transient machines on their own rating only")
        bus, v, s = m["bus"], kv[m["bus"]] * 1e3, m["rating_mva"] * 1e6
        if kind[bus] not in ("slack", "pv"):
            raise NotImplementedError(f"{m['name']} on a PQ bus")
        if domain == "sp":
            g = mod.SynchronGenerator(m["name"], log)
            bt = dpsimpy.PowerflowBusType.VD if kind[bus] == "slack" else dpsimpy.PowerflowBusType.PV
            g.set_parameters(s, v, m.get("p_mw", 0.0) * 1e6, vset[bus] * v, bt)
            g.set_base_voltage(v)
            g.modify_power_flow_bus_type(bt)
        else:
            g = mod.SynchronGenerator6bOrderVBR(m["name"], log)
            g.set_operational_parameters_per_unit(
                s, v, case["f_nom"], m["h"], m["xd"], m["xq"], m["xl"], m["xd_p"], m["xq_p"],
                m["td0_p"], m["tq0_p"], m["xd_pp"], m["xq_pp"], m["td0_pp"], m["tq0_pp"])
        g.connect([nodes[bus]])
        comps.append(g)
        gens[m["name"]] = g
    return nodes, comps, gens


def add_controls(g, m, dpsimpy, h, parts=CONTROLS):
    """DPsim's signal components for the machine's [machine.exciter] (st1a: ExciterStatic, see
    below; the limits vr_min, vr_max taken as constants, not times V_t; DPsim's ExciterST1Simp
    is not used: its output K_a (V_r - V_ref) feeds the voltage back with the wrong sign and
    the machines run away within 2 s), [machine.pss] (pss1a:
    PSS1A on the speed, Kw = ks) and [machine.governor] (tgov_reheat: SteamTurbineGovernor
    1/R into a first-order lag T3 = t_g, limits 0..p_max; SteamTurbine with F_hp = f_hp after
    T_ch and F_ip = 1 - f_hp after T_rh, no LP stage)."""
    sig, log = dpsimpy.signal, dpsimpy.LogLevel.off
    exc = m.get("exciter")
    if "exciter" in parts and exc is not None:
        if exc["type"] != "st1a" or exc.get("kf", 0.0) or exc.get("ta", 0.0) or exc.get("tc", 0.0) != exc.get("tb", 0.0):
            raise NotImplementedError(f"exciter {exc}")
        # ExciterStatic: T_r, then a lead-lag (1 + sT_a)/(1 + sT_b), then K_a/(1 + sT_e) within
        # MinEfd..MaxEfd. T_a = T_b (T_C = T_B: no transient gain reduction); T_e = h, which in
        # its forward-Euler step is the gain K_a delayed by one step (ST1A's T_A = 0).
        ep = sig.ExciterStaticParameters()
        ep.Tr, ep.Ka, ep.Ta, ep.Tb, ep.Te, ep.Kbc = exc["tr"], exc["ka"], 1.0, 1.0, h, 0.0
        ep.MaxEfd, ep.MinEfd = exc.get("vr_max", 1e3), exc.get("vr_min", -1e3)
        g.add_exciter(sig.ExciterStatic(f"{m['name']}_exc", log), ep)
        pss = m.get("pss")
        if "pss" in parts and pss is not None:
            if pss["type"] != "pss1a":
                raise NotImplementedError(f"stabilizer {pss['type']!r}")
            pp = sig.PSS1AParameters()
            pp.Kp, pp.Kv, pp.Kw = 0.0, 0.0, pss["ks"]
            pp.T1, pp.T2, pp.T3, pp.T4, pp.Tw = pss["t1"], pss["t2"], pss["t3"], pss["t4"], pss["tw"]
            pp.Vs_max, pp.Vs_min = pss.get("vs_max", 1e3), pss.get("vs_min", -1e3)
            g.add_pss(sig.PSS1A(f"{m['name']}_pss", log), pp)
    gov = m.get("governor")
    if "governor" in parts and gov is not None:
        if gov["type"] != "tgov_reheat":
            raise NotImplementedError(f"governor {gov['type']!r}")
        gp = sig.SteamGovernorParameters()
        gp.R, gp.T1, gp.T2, gp.T3 = gov["r"], 0.0, 0.0, gov["t_g"]
        gp.dPmax, gp.dPmin, gp.Pmax, gp.Pmin = 1e3, -1e3, gov.get("p_max", 1.0), gov.get("p_min", 0.0)
        gp.OmRef, gp.Kbc = 1.0, 0.0
        tp = sig.SteamTurbineParameters()
        tp.Fhp, tp.Fip, tp.Flp = gov["f_hp"], 1.0 - gov["f_hp"], 0.0
        tp.Tch, tp.Trh, tp.Tco = gov["t_ch"], gov["t_rh"], 0.5  # Tco: the absent LP stage's lag
        g.add_governor_and_turbine(sig.SteamTurbineGovernor(f"{m['name']}_gov", log), gp,
                                   sig.SteamTurbine(f"{m['name']}_turb", log), tp)


def power_flow(case, dpsimpy):
    """DPsim's NRP power flow of the case: (system, {bus: complex voltage V}, {machine: S in VA}).
    As in our grid model, the power flow takes the loads as P + jQ; the dynamic model then holds
    each load's admittance fixed at its power-flow voltage."""
    system, v = _power_flow_once(case, dpsimpy)
    s = {m["name"]: complex(system.node(f"bus{m['bus']}").attr("s").get()[0, 0]) for m in case["machine"]}
    return system, v, s


def _power_flow_once(case, dpsimpy):
    nodes, comps, gens = build(case, dpsimpy, "sp")
    system = dpsimpy.SystemTopology(case["f_nom"], list(nodes.values()), comps)
    sim = dpsimpy.Simulation("ieee9_pf", dpsimpy.LogLevel.off)
    sim.set_system(system)
    sim.set_domain(dpsimpy.Domain.SP)
    sim.set_solver(dpsimpy.Solver.NRP)
    sim.set_solver_component_behaviour(dpsimpy.SolverBehaviour.Initialization)
    sim.set_time_step(0.1)
    sim.set_final_time(0.1)
    sim.do_init_from_nodes_and_terminals(False)
    sim.run()
    return system, {b: complex(n.attr("v").get()[0, 0]) for b, n in nodes.items()}


def run(case=None, end=2.0, h=H_STEP, prewarp=True, controls=CONTROLS, load_step=None):
    """Power flow, EMT start from it, `end` seconds at step h. ``load_step``: None (no event) or
    a load step as a case file gives one (bus, dp_mw, time): a resistance drawing dp_mw at the
    bus's power-flow voltage behind a switch that closes at that time. Returns a dict: the
    power-flow machine powers (pu on base_mva), bus voltages (pu), and per machine the speed trace
    (pu) and the largest |Δf| (Hz) over the run, the centre-of-inertia speed (H on the system
    base), and the wall time."""
    import dpsimpy

    case = case or load_case()
    sb = case["base_mva"] * 1e6
    kv = {b["id"]: b["base_kv"] * 1e3 for b in case["bus"]}
    cwd = os.getcwd()
    with tempfile.TemporaryDirectory(prefix="dpsim-ieee9-") as tmp:
        os.chdir(tmp)  # DPsim opens its logs under ./logs
        try:
            system_pf, v_pf, s_pf = power_flow(case, dpsimpy)
            nodes, comps, gens = build(case, dpsimpy, "emt", {b: abs(x) for b, x in v_pf.items()},
                                        warp(case, h) if prewarp else 1.0)
            switch = None
            if load_step is not None:
                r = abs(v_pf[load_step["bus"]]) ** 2 / (load_step["dp_mw"] * 1e6)
                switch = dpsimpy.emt.ph3.Switch("sw_step", dpsimpy.LogLevel.off)
                switch.set_parameters(R_OPEN * np.eye(3), r * np.eye(3), False)
                switch.connect([nodes[load_step["bus"]], dpsimpy.emt.SimNode.gnd])
                comps = comps + [switch]
            system = dpsimpy.SystemTopology(case["f_nom"], list(nodes.values()), comps)
            system.init_with_powerflow(system_pf, dpsimpy.Domain.EMT)
            for m in case["machine"]:
                s = s_pf[m["name"]]
                gens[m["name"]].set_initial_values(s, s.real, v_pf[m["bus"]])
                add_controls(gens[m["name"]], m, dpsimpy, h, controls)
            sim = dpsimpy.Simulation("ieee9_emt", dpsimpy.LogLevel.off)
            sim.set_system(system)
            sim.set_domain(dpsimpy.Domain.EMT)
            sim.set_time_step(h)
            sim.set_final_time(end + h)
            sim.do_init_from_nodes_and_terminals(True)
            n = round(end / h)
            w = {name: np.empty(n + 1) for name in gens}
            t0 = time.perf_counter()
            sim.start()
            for name, g in gens.items():
                w[name][0] = g.attr("w_r").get()
            k_step = round(load_step["time"] / h) if switch is not None else None
            for k in range(1, n + 1):
                if k == k_step:
                    switch.close()
                sim.next()
                for name, g in gens.items():
                    w[name][k] = g.attr("w_r").get()
            wall = time.perf_counter() - t0
            sim.stop()
        finally:
            os.chdir(cwd)
    f = case["f_nom"]
    weight = {m["name"]: m["h"] * (m["rating_mva"] if m.get("base", "machine") == "machine" else case["base_mva"])
              for m in case["machine"]}
    coi = sum(weight[k] * x for k, x in w.items()) / sum(weight.values())
    return {
        "coi": coi,
        "h": h,
        "p_pf": {k: s.real / sb for k, s in s_pf.items()},
        "q_pf": {k: s.imag / sb for k, s in s_pf.items()},
        "v_pf": {b: abs(x) / kv[b] for b, x in v_pf.items()},
        "a_pf": {b: math.degrees(np.angle(x)) for b, x in v_pf.items()},
        "w": w,
        "df_max": {k: float(np.max(np.abs(x - 1.0))) * f for k, x in w.items()},
        "wall": wall,
        "end": end,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--end", type=float, default=2.0)
    parser.add_argument("--controls", default=",".join(CONTROLS),
                        help="comma-separated subset of exciter,pss,governor, or none")
    args = parser.parse_args()
    controls = tuple(c for c in args.controls.split(",") if c and c != "none")
    rec = run(end=args.end, controls=controls)
    print(f"controls: {', '.join(controls) or 'none'}")
    print("power flow (DPsim NRP), bus voltages:")
    for b in sorted(rec["v_pf"]):
        print(f"  bus {b}: {rec['v_pf'][b]:.5f} pu at {rec['a_pf'][b]:8.4f} deg")
    print("power flow, machine powers (pu on 100 MVA):")
    for k in rec["p_pf"]:
        print(f"  {k}: P {rec['p_pf'][k]:.5f}, Q {rec['q_pf'][k]:.5f}")
    print(f"EMT, {rec['end']} s at {H_STEP * 1e6:.0f} us, no event (wall {rec['wall']:.1f} s):")
    for k, df in rec["df_max"].items():
        print(f"  {k}: max |df| {df:.3e} Hz, speed at end {rec['w'][k][-1]:.9f} pu")


if __name__ == "__main__":
    main()
