"""Case study I's nine-bus system in DPsim EMT with the DVPP's three EMT-level converters (dvpp_der_emt FMUs + operator) at bus 2.

Built from fmu-grid/cases/ieee9_dvpp.toml: SG1 and SG3, the network and the loads exactly as
tests/python/dpsim_ieee9.py builds them (its functions, imported), and at bus 2, in place of SG2,
the case's [[der]] slots as the bundled emt_thevenin system's units (wind, PV, BESS: its
wind/pv/bess.fmu, operator.fmu) hosted as tests/python/dpsim_emt_thevenin.py hosts them: each
unit's averaged converter, RLC filter and transformer (``dpsim_emt_host.Converter``, per unit on
its rating) into bus 2, the unit FMUs closing the loops every 50 µs and the operator FMU exchanging
every 1 ms (H_OPERATOR), the PCC meter (SRF-PLL + lag of
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
- The dc links: DPsim's circuits end at the converters' ac side, so each unit's dc side is
  stepped here (DcLink) as our EMT plant FMU steps it: the primary source's lag toward the FMU's
  i_dc_ref within the range it outputs (p_src_min, p_src_max: its availability), the link as an
  energy store drawn on by the converter's ac energy; the FMU measures its v_dc and the
  converter's voltage is the modulation times that v_dc.
- The units' settings: with an event, the start values of the phasor twin's scenario file
  (studies/scenarios/phasor_case1_<event>.toml: the virtual resistance and q integral gain the
  EMT controllers share with it, the dispatch, the cloud) over the bundle's (unit_start).
- Case I's events (``event``): "load", the case's load step (dp_mw at bus 2, a constant
  resistance drawing dp_mw at bus 2's power-flow voltage behind a switch closing at its time);
  "cloud", the PV unit's availability step (its avail.* start values).

Measured (50 µs; DVPP_DIST pointing at the bundles): with no event, 2 s, max |Δf| SG1 3.4e-7, SG3
4.7e-7, PCC meter 4.1e-6 Hz, max |p - p0| wind 5.0e-5, PV 7.5e-5, BESS 3.4e-5 pu. The units start
at our master's phasor case1_load operating point (q 0.00072, 0.00114, 0.00094 pu). The events'
figures against the operator's desired response and our master's phasor runs:
tests/python/emt_case1.py (`cargo xtask emt-case1`) and docs/emt.md §12.

    python tests/python/dpsim_ieee9_dvpp.py [--end 2] [--event load|cloud]
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
        if event == "load":
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


class DcLink:
    """A unit's dc side as our EMT plant FMU steps it (fmu-emt-plant/src/dc.rs): the primary
    source's current through its lag ``tau`` toward the controller's command (exact for a held
    command), its power within the range the controller outputs (p_src_min, p_src_max: cut at
    once to a range that fell, held from the instant the lag reaches a bound), the link as the
    energy store ``W = C_dc v_dc²/2`` (pu·s on S_rated) balanced each step against the source's
    energy, the conductance's loss and the converter's ac energy ``e_ac``. Starts at
    ``v_dc = 1`` with the source covering ``p_conv`` and the loss."""

    V_FLOOR = 0.05  # pu: below it the source's current range is taken at it

    def __init__(self, c, g, tau, p_conv):
        self.c, self.g, self.tau = c, g, tau
        self.i_src, self.w = p_conv + g, 0.5 * c
        self.source = self.loss = self.ac = 0.0  # the account since t = 0, pu·s

    @property
    def v(self):
        return math.sqrt(2.0 * max(self.w, 0.0) / self.c)

    def _charge(self, i0, i_ref, t):
        return i_ref * t - (i0 - i_ref) * self.tau * math.expm1(-t / self.tau)

    def step(self, i_ref, e_ac, h, p_min, p_max):
        v_range = max(self.v, self.V_FLOOR)
        lo, hi = p_min / v_range, max(p_min, p_max) / v_range
        i0 = min(max(self.i_src, lo), hi)
        bound = hi if i_ref > hi else lo if i_ref < lo else None
        t_b = self.tau * math.log((i0 - i_ref) / (bound - i_ref)) if bound is not None else math.inf
        if t_b < h:
            charge, i1 = self._charge(i0, i_ref, t_b) + bound * (h - t_b), bound
        else:
            charge, i1 = self._charge(i0, i_ref, h), i_ref + (i0 - i_ref) * math.exp(-h / self.tau)
        v0 = self.v
        v1 = math.sqrt(2.0 * max(self.w + v0 * charge - self.g * v0 * v0 * h - e_ac, 0.0) / self.c)
        source, loss = 0.5 * (v0 + v1) * charge, self.g * h * 0.5 * (v0 * v0 + v1 * v1)
        self.w += source - loss - e_ac
        self.i_src = i1
        self.source, self.loss, self.ac = self.source + source, self.loss + loss, self.ac + e_ac


EVENTS = ("load", "cloud")
# The operator's communication step: the DVPP's own rate (the phasor case's step), not the
# converters'.
H_OPERATOR = 1e-3
SCENARIOS = ROOT / "studies" / "scenarios"


def unit_start(event, twin=True):
    """The units' start values of case I's ``event`` as our phasor scenario sets them (by unit
    name): phasor_case1_<event>.toml (the twin: the outer-loop settings the EMT controllers
    share with it) or case1_<event>.toml. Case I in DPsim applies the twin's to the EMT
    controller FMUs, so both settings run one configuration from one file (the cloud is its
    PV's avail.* values)."""
    import tomllib

    with open(SCENARIOS / f"{'phasor_' if twin else ''}case1_{event}.toml", "rb") as f:
        sc = tomllib.load(f)
    return {d["name"]: dict(d.get("start", {})) for d in sc["der"]}


def run(t_end, event=None, h=H_STEP, root=None, case=None, start=None, h_operator=H_OPERATOR):
    """One coupled run; ``event``: None, "load" (the case's load step) or "cloud" (the PV's
    availability step, its avail.* values from ``start``); ``start``: the units' start values by
    name over the bundle's (by default, with an event, unit_start(event)); ``h_operator``: the
    operator FMU's communication step (a multiple of h). Returns the recorded signals: ``t``, ``f`` (the PCC meter's pcc.f, pu),
    ``v`` (|v_pcc|), ``w`` (machine speeds, pu, by name), ``coi`` (their centre of inertia, H on
    the system base), ``p``/``q`` (units x steps, pu on S_base), ``v_dc`` (units x steps),
    ``mu`` (the operator's dc gains by name), ``ref_df`` (the operator's ref.df), the units' flags
    and warnings, the dc links' energy accounts, the wall time of the coupled loop and where it
    went (``timing``: DPsim's solve, the unit FMUs' calls, the operator FMU's, the rest)."""
    import dpsimpy
    import fmpy.fmi2  # noqa: F401

    if event not in (None, *EVENTS):
        raise ValueError(f"event {event!r}: one of {EVENTS} or None")
    root = root or bundle()
    case = case or load_case()
    plant = Plant(root / "plant.fmu")  # only its pcc.f_filter_t (the meter's lag)
    extra = start if start is not None else unit_start(event) if event else {}
    if event == "cloud" and not any(x.get("avail.dP", 0.0) for x in extra.values()):
        raise ValueError("a cloud needs a unit's avail.dP (and avail.t_step) in the start values")
    units, dc_data = [], []
    for name in UNITS:
        probe = Slave(root / f"{name}.fmu", f"probe-{name}")
        names = (*host.UNIT_INFO, "C_dc", "G_dc", "tau_dc")
        info = dict(zip(names, probe.get(*names)))
        probe.free()
        units.append((name, info["S_rated"], {k: info[k] for k in host.FILTER}))
        dc_data.append((info["C_dc"], info["G_dc"], info["tau_dc"]))
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
    ders, links = [], []
    for k, (name, _, _) in enumerate(units):
        c = grid.converters[k]
        der = DerEmt({**dict(zip(mu_names[k], mu[k])), **extra.get(name, {})}, c.measure(), name=name,
                     path=root / f"{name}.fmu")
        der.vr_in = der.vr_in + [der.vr(n) for n in mu_names[k]]
        der.vr_out = der.vr_out + [der.vr(n) for n in ("i_dc_ref", "p_src_min", "p_src_max", *DER_TO_OPERATOR)]
        ders.append(der)
        # The converter's power at t = 0 from the circuit's state (pu on S_rated).
        i_f = c.measure()[3:6]
        p_conv = (2.0 / 3.0) * float(np.dot(c.last, i_f))
        links.append(DcLink(*dc_data[k], p_conv))
    op_in = [operator.vr(f"der[{k + 1}].{n}") for k in range(len(UNITS)) for n in ("P_avail", "p_set", "p", "q")]
    op_in += [operator.vr(f"pcc.{n}") for n in ("p", "q", "f", "v")]
    volts_per_m = []
    for der, c in zip(ders, grid.converters):
        vpm = der.get("vdc_ratio")[0] / 2.0
        volts_per_m.append(vpm)
        c.last = np.array(der.fmu.getReal(der.vr_out[:3])) * vpm
    meter = PccMeter(cmath.phase(v), plant.f_filter_t, h)
    switches = sorted(((round(t_on / h), sw) for t_on, sw in grid.switches), key=lambda x: x[0])
    weights = {m["name"]: m["h"] * (m["rating_mva"] if m.get("base", "machine") == "machine" else case["base_mva"])
               for m in case["machine"]}
    n = round(t_end / h)
    rec = {k: np.empty(n + 1) for k in ("t", "f", "v", "ref_df", "coi")}
    rec["w"] = {name: np.empty(n + 1) for name in grid.w}
    rec["p"], rec["q"], rec["v_dc"] = (np.empty((len(UNITS), n + 1)) for _ in range(3))
    rec["mu"] = {f"{u}.{m}": np.empty(n + 1) for u, names in zip(UNITS, mu_names) for m in names}
    mu_keys = list(rec["mu"])

    def sample(k, t, f, v, s, ref_df, mu_flat):
        rec["t"][k], rec["f"][k], rec["v"][k], rec["ref_df"][k] = t, f, abs(v), ref_df
        for name, a in grid.w.items():
            rec["w"][name][k] = a.get()
        rec["coi"][k] = sum(weights[x] * rec["w"][x][k] for x in grid.w) / sum(weights[x] for x in grid.w)
        rec["p"][:, k], rec["q"][:, k] = [x.real for x in s], [x.imag for x in s]
        rec["v_dc"][:, k] = [link.v for link in links]
        for key, x in zip(mu_keys, mu_flat):
            rec["mu"][key][k] = x

    f = 1.0
    sample(0, 0.0, f, v, s, operator.fmu.getReal([vr_ref_df])[0], np.concatenate(mu))
    to_operator = [der.fmu.getReal(der.vr_out[-2:]) for der in ders]
    clock = time.perf_counter
    timing = dict.fromkeys(("dpsim", "units", "operator"), 0.0)
    started = clock()
    measured = [c.measure() for c in grid.converters]
    # The operator at its own rate, exchanging as our master's Jacobi step does: at each of its
    # communication points the units take the outputs it had there, and it steps over the next
    # interval from the inputs measured there.
    op_every = max(1, round(h_operator / h))
    out_op = operator.fmu.getReal(mu_vr + [vr_ref_df])
    for k in range(n):
        t = k * h
        t0 = clock()
        if k % op_every == 0:
            mu = np.split(np.array(out_op[:-1]), mu_split)
            held = out_op
            values = []
            for (p_avail, p_set), x in zip(to_operator, s):
                values += [p_avail, p_set, x.real, x.imag]
            p_sum = sum(s)
            operator.fmu.setReal(op_in, values + [p_sum.real, p_sum.imag, f, abs(v)])
            operator.fmu.doStep(t, op_every * h)
            out_op = operator.fmu.getReal(mu_vr + [vr_ref_df])
        t1 = clock()
        outs = [der.step(t, h, [*x[:-1], link.v, *m]) for der, x, link, m in zip(ders, measured, links, mu)]
        t2 = clock()
        to_operator = [out[-2:] for out in outs]
        while switches and switches[0][0] == k + 1:
            switches.pop(0)[1].close()
        # The converter voltage from the modulation and the link's voltage at the step's start.
        for c, out, vpm, link in zip(grid.converters, outs, volts_per_m, links):
            c.apply([x * vpm * link.v for x in out[:3]])
        t3 = clock()
        t = grid.next()
        t4 = clock()
        # The ac energy the converter drew over the step: the applied (mid-step) voltage times
        # the mean filter current (pu on S_rated).
        before, measured = measured, [c.measure() for c in grid.converters]
        for c, link, out, x0, x1 in zip(grid.converters, links, outs, before, measured):
            applied = c.v_ref.get()[:, 0] / V_R
            i_mean = 0.5 * (np.asarray(x0[3:6]) + np.asarray(x1[3:6]))
            link.step(out[-5], (2.0 / 3.0) * float(np.dot(applied, i_mean)) * h, h, out[-4], out[-3])
        v, s = grid.pcc()
        f = meter.step(v)
        sample(k + 1, t, f, v, s, held[-1], held[:-1])
        timing["operator"] += t1 - t0
        timing["units"] += t2 - t1
        timing["dpsim"] += t4 - t3
    wall = clock() - started
    timing["rest"] = wall - sum(timing.values())
    flags = {name: der.flags() for der, name in zip(ders, UNITS)}
    warnings = [w for der in ders for w in der.warnings()] + [m for st, m in operator.messages if st >= 1]
    for der in ders:
        der.free()
    operator.free()
    grid.stop()
    f_nom = case["f_nom"]
    dc = {name: {"source": link.source, "loss": link.loss, "ac": link.ac, "stored": link.w - 0.5 * link.c}
          for name, link in zip(UNITS, links)}
    t_event = min((t_on for t_on, _ in grid.switches), default=None)
    if event == "cloud":
        t_event = min(x["avail.t_step"] for x in extra.values() if x.get("avail.dP", 0.0))
    return {**rec, "wall": wall, "timing": timing, "h": h, "t_end": t_end, "flags": flags, "warnings": warnings,
            "v0": grid.v0, "s0": grid.s0, "f_nom": f_nom, "dc": dc, "event": event, "t_step": t_event}


def flat_figures(rec, k_end=None):
    """The largest |Δf| (Hz) of each machine and the PCC meter, and each unit's largest |p - p0|
    (pu on S_base), over the samples before k_end (all by default)."""
    f_nom = rec["f_nom"]
    sl = slice(0, k_end)
    df = {name: float(np.max(np.abs(w[sl] - 1.0))) * f_nom for name, w in rec["w"].items()}
    df["PCC"] = float(np.max(np.abs(rec["f"][sl] - 1.0))) * f_nom
    dp = {name: float(np.max(np.abs(rec["p"][j][sl] - rec["p"][j][0]))) for j, name in enumerate(UNITS)}
    return df, dp


def window(rec, seconds=None):
    """The samples from the event on (all after t = 0 without one), ``seconds`` long or to the end."""
    t0 = rec["t_step"] or 0.0
    t1 = rec["t"][-1] if seconds is None else t0 + seconds
    return (rec["t"] >= t0 - 1e-12) & (rec["t"] <= t1 + 1e-12)


def event_figures(rec, seconds=None):
    """The PCC Δf nadir (Hz, s) and the NRMSE of the PCC Δf (pu) against the operator's ref.df
    (by the peak |ref.df|), from the event on, ``seconds`` long (to the end by default)."""
    sel = window(rec, seconds)
    df = rec["f"][sel] - 1.0
    t, ref = rec["t"][sel], rec["ref_df"][sel]
    k = int(np.argmin(df))
    return {"nadir": (df[k] * rec["f_nom"], t[k]), "nrmse": nrmse(df, ref),
            "ref_nadir": (float(np.min(ref)) * rec["f_nom"], t[int(np.argmin(ref))])}


OWN_SIGNALS = ("time", "grid.pcc.f", "grid.coi.f", "operator.ref.df", "grid.der[1].p", "grid.der[2].p",
               "grid.der[3].p", "wind.v_dc", "pv.v_dc", "bess.v_dc")


def own_case1(out_dir, t_end, event="load", twin=False):
    """Our master's run of case I's ``event`` in the phasor setting (the grid FMU of the same case,
    1 ms steps) for ``t_end``: the bundled case1_<event>, or with ``twin`` phasor_case1_<event>
    (the same with the units' outer loops set as the EMT controllers'); the signals of
    OWN_SIGNALS as arrays, or None when the cosim binary or the bundle is missing."""
    import subprocess

    from conftest import DIST

    name = f"{'phasor_' if twin else ''}case1_{event}"
    ssp = DIST.parent / name / f"{name}.ssp"
    cosim = pathlib.Path(os.environ.get("DVPP_COSIM", DIST.parents[1] / "target" / "release" / "cosim"))
    if not (ssp.exists() and cosim.exists()):
        return None
    csv = os.path.join(out_dir, f"{name}.csv")
    subprocess.run([str(cosim), str(ssp), "--out", csv, "--stop", str(t_end), "--record",
                    ",".join(OWN_SIGNALS[1:])], check=True, capture_output=True)
    with open(csv) as f:
        names = f.readline().strip().split(",")
    data = np.loadtxt(csv, delimiter=",", skiprows=1, usecols=[names.index(n) for n in OWN_SIGNALS])
    return dict(zip(OWN_SIGNALS, data.T))


def compare_own(rec, own, seconds=None):
    """DPsim's run against our master's phasor run, from the event on (``seconds`` long, to the
    end by default): the NRMSE of the PCC Δf and of the COI Δf, each by the peak of ours; both
    nadirs (Hz, s) of each; our own PCC Δf against its ref.df (NRMSE by the peak |ref.df|)."""
    sel = window(rec, seconds)
    t = rec["t"][sel]
    sel_own = (own["time"] >= t[0] - 1e-9) & (own["time"] <= t[-1] + 1e-9)
    out = {}
    for key, mine in (("pcc", rec["f"]), ("coi", rec["coi"])):
        theirs = own["grid.pcc.f" if key == "pcc" else "grid.coi.f"] - 1.0
        k, j = int(np.argmin(theirs[sel_own])), int(np.argmin(mine[sel] - 1.0))
        out[key] = {"nrmse": nrmse(mine[sel] - 1.0, np.interp(t, own["time"], theirs)),
                    "nadir": ((mine[sel][j] - 1.0) * rec["f_nom"], t[j]),
                    "nadir_own": (theirs[sel_own][k] * rec["f_nom"], own["time"][sel_own][k])}
    out["nrmse_own_ref"] = nrmse(own["grid.pcc.f"][sel_own] - 1.0, own["operator.ref.df"][sel_own])
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--end", type=float, default=None, help="simulated time, s (2 flat, 5 with --event)")
    parser.add_argument("--event", choices=EVENTS, default=None,
                        help="load: the case's 28 MW load step at bus 2; cloud: case1_cloud's PV availability step")
    args = parser.parse_args()
    end = args.end or (5.0 if args.event else 2.0)
    rec = run(end, event=args.event)
    print(f"DPsim EMT, {end:g} s at {rec['h'] * 1e6:g} µs, event {args.event}: "
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

        for twin, label in ((True, f"phasor_case1_{args.event}"), (False, f"case1_{args.event}")):
            with tempfile.TemporaryDirectory(prefix="case1-") as tmp:
                own = own_case1(tmp, end, args.event, twin)
            if own is None:
                print(f"(our master's cosim binary or the {label} bundle is missing: no comparison)")
                continue
            c = compare_own(rec, own)
            for key in ("pcc", "coi"):
                x = c[key]
                print(f"{key.upper()} Δf: nadir {x['nadir'][0]:.5f} Hz at {x['nadir'][1]:.4f} s, {label} "
                      f"{x['nadir_own'][0]:.5f} Hz at {x['nadir_own'][1]:.4f} s; NRMSE against it {x['nrmse']:.3e}")
            print(f"{label}: its PCC Δf vs its ref.df NRMSE {c['nrmse_own_ref']:.3e}")
        print(f"at {end:g} s: PCC Δf {(rec['f'][-1] - 1) * rec['f_nom']:.5f} Hz, ref.df {rec['ref_df'][-1] * rec['f_nom']:.5f} Hz")
    print("wall time: " + ", ".join(f"{k} {x:.1f} s" for k, x in rec["timing"].items()))
    print(f"flags {rec['flags']}; warnings {rec['warnings']}")


if __name__ == "__main__":
    main()
