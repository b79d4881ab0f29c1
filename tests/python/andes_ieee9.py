"""Our phasor grid model against ANDES on the same case file: converter, events, metrics, modes.

The case TOML of fmu-grid (one data source) is converted into an ANDES system built in code:
buses, lines with their charging, transformers, constant-impedance loads, PV/slack generators,
GENROU machines (no saturation), ESST1A exciters, IEEEST stabilizers and IEEEG1 governors for
our `tgov_reheat`. The same events then run in ANDES's time-domain simulation and in our grid
FMU (bundled from a scenario file by `cargo xtask bundle --scenario`, run by `cosim`), and the
responses are compared: nadir, RoCoF, the centre-of-inertia frequency and per-machine speed and
power NRMSE. The electromechanical modes come from ANDES's eigenvalue analysis and, for both
simulators alike, from a matrix-pencil fit of the machines' relative speeds after a small load
step, with and without the stabilizers.

    python tests/python/andes_ieee9.py [--case fmu-grid/cases/ieee9.toml] [--out target/andes]

prints the Markdown tables of docs/validation.md (needs `andes` in the Python environment, the
`cosim` binary: $DVPP_COSIM or target/release/cosim, and cargo for the bundles).
"""
import argparse
import copy
import io
import logging
import math
import os
import pathlib
import subprocess
import sys
import time
import tomllib

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
COSIM = pathlib.Path(os.environ.get("DVPP_COSIM", ROOT / "target" / "release" / "cosim"))
DEFAULT_CASE = ROOT / "fmu-grid" / "cases" / "ieee9.toml"

# The events compared (case-file event tables; time in s). The load step acts as our
# `load_step` with its default model: an admittance fixed at the pre-event bus voltage.
EVENT_TIME = 1.0
EVENTS = {
    "load_step": {"type": "load_step", "time": EVENT_TIME, "bus": 5, "dp_mw": 28.0},
    "generator_trip": {"type": "generator_trip", "time": EVENT_TIME, "machine": 3},
    "line_trip": {"type": "line_trip", "time": EVENT_TIME, "branch": "L5-6"},
}
# The small disturbance whose ring-down the modes are fitted on.
SMALL_STEP = {"type": "load_step", "time": EVENT_TIME, "bus": 5, "dp_mw": 2.0}
# ANDES's fixed step (implicit trapezoidal rule), s; the comparisons are made on its time points,
# which our runs (RK4 at 1 ms, every 1 ms step within) are recorded at.
ANDES_STEP = 0.02
DT = ANDES_STEP
# IEEEST's input-filter time constant in the eigenvalue analysis only (s; see build_andes): a
# lag of 0.7 degrees at 2 Hz.
EIG_PSS_FILTER = 1e-3
# Electromechanical band of the modes (Hz); an eigenvalue counts as electromechanical when this
# share of its participation lies in the rotor angles and speeds.
MECH_SHARE = 0.3
# Order of the matrix-pencil fit (poles; enough for the slow governor and voltage modes besides
# the two inter-machine swings).
FIT_ORDER = 10
BAND = (0.1, 3.0)


# ---------------------------------------------------------------------------------------------
# Case file handling
# ---------------------------------------------------------------------------------------------

def load_case(path):
    with open(path, "rb") as f:
        return tomllib.load(f)


def without_pss(case):
    """The case with every machine's `[machine.pss]` table deleted."""
    c = copy.deepcopy(case)
    for m in c.get("machine", []):
        m.pop("pss", None)
    return c


def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {v!r} as TOML")


def to_toml(d, prefix=""):
    """A TOML document of nested tables and arrays of tables (what the case format uses)."""
    out = io.StringIO()
    scalars = {k: v for k, v in d.items()
               if not isinstance(v, dict) and not (isinstance(v, list) and v and isinstance(v[0], dict))}
    for k, v in scalars.items():
        out.write(f"{k} = {_toml_value(v)}\n")
    for k, v in d.items():
        if k in scalars:
            continue
        name = f"{prefix}{k}"
        if isinstance(v, dict):
            out.write(f"\n[{name}]\n")
            out.write(to_toml(v, name + "."))
        else:
            for item in v:
                out.write(f"\n[[{name}]]\n")
                out.write(to_toml(item, name + "."))
    return out.getvalue()


def branch_names(case):
    """Line and transformer names as the grid model names them (lines: `L<from>-<to>` unless
    named)."""
    names = {}
    for ln in case.get("line", []):
        names[ln.get("name") or f"L{ln['from']}-{ln['to']}"] = ("line", ln)
    for tr in case.get("transformer", []):
        names[tr.get("name") or f"T{tr['from']}-{tr['to']}"] = ("transformer", tr)
    return names


def machine_names(case):
    return [m.get("name") or f"SG{j + 1}" for j, m in enumerate(case["machine"])]


# ---------------------------------------------------------------------------------------------
# ANDES side
# ---------------------------------------------------------------------------------------------

def _andes():
    import andes
    andes.config_logger(stream_level=logging.ERROR)
    return andes


def _on_machine_base(case, m):
    """(z factor, power factor) that bring the machine's data to its own rating."""
    if m.get("base", "system") == "machine":
        return 1.0, 1.0
    k = m["rating_mva"] / case["base_mva"]  # z_machine = z_system * S_rating / S_base
    return k, 1.0 / k


def build_andes(case, events=(), *, pss_filter=0.0):
    """An ANDES System of the case with the event tables `events`, set up and ready for its
    power flow. Returns (system, names) where names maps our element names to ANDES idx.
    `pss_filter` > 0 replaces IEEEST's absent input filter (A1..A6 = 0) by a first-order lag of
    that time constant (A1) and a second-order lead-lag that cancels itself (A3 = A5): ANDES's
    eigenvalue analysis, which folds the states of zero time constant into the algebraic part,
    loses the stabilizer's path with the all-zero filter (the in-band modes come out identical
    to those without stabilizers) and misplaces them with A1 = 0 alone; the time-domain
    simulation is not affected and keeps A1..A6 = 0."""
    andes = _andes()
    ss = andes.System(no_output=True, default_config=True)
    sb, fn = case["base_mva"], case["f_nom"]
    vn = {b["id"]: b.get("base_kv") or 100.0 for b in case["bus"]}
    machines_at = {}
    for j, m in enumerate(case.get("machine", [])):
        machines_at.setdefault(m["bus"], []).append(j)
    for b in case["bus"]:
        ss.add("Bus", {"idx": b["id"], "name": b.get("name") or f"Bus{b['id']}", "Vn": vn[b["id"]],
                       "v0": b.get("v_set", 1.0), "a0": math.radians(b.get("angle_deg", 0.0))})
    for name, (kind, br) in branch_names(case).items():
        f, t = br["from"], br["to"]
        r, x = br.get("r", 0.0), br["x"]
        if kind == "line" and br.get("rx") is not None:
            z = math.hypot(r, x)
            x = z / math.hypot(br["rx"], 1.0)
            r = br["rx"] * x
        data = {"idx": name, "name": name, "bus1": f, "bus2": t, "Sn": sb, "fn": fn,
                "Vn1": vn[f], "Vn2": vn[t], "r": r, "x": x, "u": 1 if br.get("in_service", True) else 0}
        if kind == "line":
            data["b"] = br.get("b", 0.0)
        else:
            data.update(trans=1, tap=br.get("tap") or 1.0)
        ss.add("Line", data)
    for k, sh in enumerate(case.get("shunt", [])):
        ss.add("Shunt", {"idx": f"SH{k + 1}", "bus": sh["bus"], "Sn": sb, "Vn": vn[sh["bus"]], "fn": fn,
                         "g": sh.get("g", 0.0), "b": sh.get("b", 0.0)})
    for k, ld in enumerate(case.get("load", [])):
        if ld.get("model", "constant_impedance") != "constant_impedance":
            raise NotImplementedError("ANDES PQ loads are converted to constant impedance for all loads")
        ss.add("PQ", {"idx": f"PQ{k + 1}", "bus": ld["bus"], "Vn": vn[ld["bus"]],
                      "p0": ld["p_mw"] / sb, "q0": ld.get("q_mvar", 0.0) / sb})
    if case.get("der"):
        raise NotImplementedError("DER slots have no ANDES counterpart here")
    names = {"machine": [], "exciter": [], "pss": [], "governor": []}
    for j, m in enumerate(case.get("machine", [])):
        bus = next(b for b in case["bus"] if b["id"] == m["bus"])
        gen = f"G{j + 1}"
        static = {"idx": gen, "bus": m["bus"], "Sn": m["rating_mva"], "Vn": vn[m["bus"]],
                  "v0": bus.get("v_set", 1.0)}
        if bus.get("kind") == "slack":
            static["a0"] = math.radians(bus.get("angle_deg", 0.0))
            ss.add("Slack", static)
        elif bus.get("kind") == "pv":
            static["p0"] = m.get("p_mw", 0.0) / sb
            ss.add("PV", static)
        else:
            raise NotImplementedError(f"machine {j + 1} on a PQ bus")
        if len(machines_at[m["bus"]]) > 1:
            raise NotImplementedError("several machines on one bus")
        zk, pk = _on_machine_base(case, m)
        model = m["model"]
        if model != "sub_transient":
            raise NotImplementedError(f"machine model {model!r}: GENROU is the sub-transient model")
        if abs(m["xd_pp"] - m["xq_pp"]) > 1e-12:
            raise NotImplementedError("GENROU needs xd_pp = xq_pp")
        syn = f"GENROU{j + 1}"
        ss.add("GENROU", {
            "idx": syn, "bus": m["bus"], "gen": gen, "Sn": m["rating_mva"], "Vn": vn[m["bus"]], "fn": fn,
            "M": 2.0 * m["h"] * pk, "D": m.get("d", 0.0) * pk, "ra": m.get("ra", 0.0) * zk,
            "xl": m["xl"] * zk, "xd": m["xd"] * zk, "xq": m["xq"] * zk, "xd1": m["xd_p"] * zk,
            "xq1": m["xq_p"] * zk, "xd2": m["xd_pp"] * zk, "xq2": m["xq_pp"] * zk,
            "Td10": m["td0_p"], "Tq10": m["tq0_p"], "Td20": m["td0_pp"], "Tq20": m["tq0_pp"],
            "S10": 0.0, "S12": 0.0})
        names["machine"].append(syn)
        exc = m.get("exciter")
        avr = None
        if exc is not None:
            if exc["type"] != "st1a":
                raise NotImplementedError(f"exciter {exc['type']!r}")
            avr = f"ESST1A{j + 1}"
            ss.add("ESST1A", {
                "idx": avr, "syn": syn, "TR": exc.get("tr", 0.0), "TC": exc.get("tc", 0.0),
                "TB": exc.get("tb", 0.0), "TC1": exc.get("tc1", 0.0), "TB1": exc.get("tb1", 0.0),
                "KA": exc["ka"], "TA": exc.get("ta", 0.0), "KF": exc.get("kf", 0.0), "TF": exc.get("tf", 1.0),
                "VIMIN": exc.get("vi_min", -999.0), "VIMAX": exc.get("vi_max", 999.0),
                "VAMIN": exc.get("va_min", -999.0), "VAMAX": exc.get("va_max", 999.0),
                "VRMIN": exc.get("vr_min", -999.0), "VRMAX": exc.get("vr_max", 999.0),
                # no commutation reactance, no field-current limiter, no UEL/OEL input
                "KC": 0.0, "KLR": 0.0, "ILR": 999.0, "UELc": 0, "VOSc": 0})
        names["exciter"].append(avr)
        pss = m.get("pss")
        if pss is not None:
            if pss["type"] != "pss1a" or avr is None:
                raise NotImplementedError(f"stabilizer {pss['type']!r} (needs an exciter)")
            ss.add("IEEEST", {
                "idx": f"IEEEST{j + 1}", "avr": avr, "MODE": 1,
                "A1": pss_filter, "A2": 0.0, "A3": pss_filter, "A4": 0.0, "A5": pss_filter, "A6": 0.0,
                "T1": pss["t1"], "T2": pss["t2"], "T3": pss["t3"], "T4": pss["t4"],
                "T5": pss["tw"], "T6": pss["tw"], "KS": pss["ks"],
                "LSMAX": pss.get("vs_max", 999.0), "LSMIN": pss.get("vs_min", -999.0)})
            names["pss"].append(f"IEEEST{j + 1}")
        else:
            names["pss"].append(None)
        gov = m.get("governor")
        if gov is not None:
            if gov["type"] != "tgov_reheat":
                raise NotImplementedError(f"governor {gov['type']!r}")
            ss.add("IEEEG1", {
                "idx": f"IEEEG1{j + 1}", "syn": syn, "K": 1.0 / gov["r"], "T1": 0.0, "T2": 0.0,
                "T3": gov["t_g"], "UO": 100.0, "UC": -100.0,
                "PMAX": gov.get("p_max", 999.0), "PMIN": gov.get("p_min", 0.0),
                "T4": gov["t_ch"], "K1": gov["f_hp"], "T5": gov["t_rh"], "K3": 1.0 - gov["f_hp"],
                "K2": 0.0, "K4": 0.0, "K5": 0.0, "K6": 0.0, "K7": 0.0, "K8": 0.0})
            names["governor"].append(f"IEEEG1{j + 1}")
        else:
            names["governor"].append(None)
    branches = branch_names(case)
    for k, ev in enumerate(events):
        kind = ev["type"]
        if kind == "load_step":
            if ev.get("model", "constant_impedance") != "constant_impedance":
                raise NotImplementedError("constant-power load steps")
            # Our load step adds the admittance conj(S)/|V|^2 at the pre-event voltage: the same
            # admittance as an ANDES Shunt, switched on by a Toggle. |V| is that of the power flow
            # (the run is flat until the event); set in run_andes once the power flow is solved.
            idx = f"STEP{k + 1}"
            b = ev["bus"]
            ss.add("Shunt", {"idx": idx, "bus": b, "Sn": sb, "Vn": vn[b], "fn": fn, "u": 0,
                             "g": ev["dp_mw"] / sb, "b": -ev.get("dq_mvar", 0.0) / sb})
            ss.add("Toggle", {"model": "Shunt", "dev": idx, "t": ev["time"]})
        elif kind == "generator_trip":
            ss.add("Toggle", {"model": "GENROU", "dev": names["machine"][ev["machine"] - 1], "t": ev["time"]})
        elif kind == "line_trip":
            if ev["branch"] not in branches:
                raise KeyError(f"unknown branch {ev['branch']}")
            ss.add("Toggle", {"model": "Line", "dev": ev["branch"], "t": ev["time"]})
        else:
            raise NotImplementedError(kind)
    # Loads: constant impedance in the time-domain simulation (ANDES's default weights, stated).
    ss.PQ.config.p2p, ss.PQ.config.p2i, ss.PQ.config.p2z = 0.0, 0.0, 1.0
    ss.PQ.config.q2q, ss.PQ.config.q2i, ss.PQ.config.q2z = 0.0, 0.0, 1.0
    ss.PQ.config.pq2z = 0
    ss.setup()
    ss.PFlow.config.tol = 1e-11
    return ss, names


def _scale_step_shunts(ss, events):
    """g, b of the load-step shunts from S at the power-flow voltage (|V| of the flat run)."""
    for k, ev in enumerate(events):
        if ev["type"] != "load_step":
            continue
        i = ss.Shunt.idx.v.index(f"STEP{k + 1}")
        bus = ss.Bus.idx.v.index(ev["bus"])
        v2 = ss.Bus.v.v[bus] ** 2
        ss.Shunt.g.v[i] /= v2
        ss.Shunt.b.v[i] /= v2


def andes_power_flow(case):
    ss, _ = build_andes(case)
    ss.PFlow.run()
    if not ss.PFlow.converged:
        raise RuntimeError("ANDES power flow did not converge")
    return {b: (ss.Bus.v.v[i], math.degrees(ss.Bus.a.v[i])) for i, b in enumerate(ss.Bus.idx.v)}


def run_andes(case, events, tf):
    """ANDES TDS of the case with the events: time, COI frequency (pu), per-machine speed (pu)
    and electrical power (pu on the system base), in-service flags."""
    ss, names = build_andes(case, events)
    ss.PFlow.run()
    if not ss.PFlow.converged:
        raise RuntimeError("ANDES power flow did not converge")
    # The shunt's |V|^2 scaling uses the power-flow voltage; the shunt is off until the event,
    # so its parameter only matters from then on. The converted (system-base) y parameters are
    # changed in place before TDS initialization.
    _scale_step_shunts(ss, events)
    ss.TDS.config.tf = tf
    ss.TDS.config.tstep = ANDES_STEP
    ss.TDS.config.fixt = 1
    ss.TDS.config.shrinkt = 0
    ss.TDS.config.no_tqdm = 1
    ss.TDS.config.tol = 1e-6
    # no angle-separation stop: a tripped machine's frozen angle drifts from the others'
    ss.TDS.config.criteria = 0
    started = time.time()
    ss.TDS.run()
    wall = time.time() - started
    if ss.exit_code != 0:
        raise RuntimeError(f"ANDES TDS failed (exit code {ss.exit_code})")
    ts = ss.dae.ts
    t = np.asarray(ts.t)
    omega = np.asarray(ts.x)[:, ss.GENROU.omega.a]
    pe = np.asarray(ts.y)[:, ss.GENROU.Pe.a]  # terminal power, as our sg[j].p
    return {"t": t, "omega": omega, "p": pe, "wall": wall, "system": ss, "names": names}


def andes_modes(case):
    """ANDES's small-signal eigenvalues in the electromechanical band: (Hz, damping ratio,
    eigenvalue) of the modes with at least MECH_SHARE of their participation in the rotor
    angles and speeds, sorted by frequency."""
    ss, _ = build_andes(case, pss_filter=EIG_PSS_FILTER)
    ss.PFlow.run()
    ss.EIG.run()
    mu = np.asarray(ss.EIG.mu)
    pf = np.abs(np.asarray(ss.EIG.pfactors))
    names = list(ss.EIG.x_name)
    mech = [i for i, n in enumerate(names) if n.startswith(("delta ", "omega "))]
    out = []
    for k, lam in enumerate(mu):
        f = lam.imag / (2 * math.pi)
        if f <= 0 or not (BAND[0] <= f <= BAND[1]):
            continue
        if pf[k, mech].sum() / pf[k].sum() < MECH_SHARE:
            continue
        out.append((f, -lam.real / abs(lam), lam))
    return sorted(out)


# ---------------------------------------------------------------------------------------------
# Our side: a scenario bundled by cargo xtask, run by cosim
# ---------------------------------------------------------------------------------------------

def bundle_ours(case, event, name, work):
    """Writes the case file and a grid-only scenario with `event`, bundles it with `cargo xtask
    bundle --scenario` (dist/<name>/); returns the .ssp path."""
    work = pathlib.Path(work)
    work.mkdir(parents=True, exist_ok=True)
    case_file = work / f"{name}-case.toml"
    c = copy.deepcopy(case)
    c["event"] = []
    case_file.write_text(f"# {name}: written by tests/python/andes_ieee9.py\n" + to_toml(c))
    scenario = {
        "description": f"{name}: our grid model against ANDES (tests/python/andes_ieee9.py)",
        "experiment": {"stop": 10.0, "step": 1e-3},
        "grid": {"case_file": case_file.name, "event": [event]},
    }
    path = work / f"{name}.toml"
    path.write_text(to_toml(scenario))
    done = subprocess.run(["cargo", "xtask", "bundle", "--scenario", str(path)], cwd=ROOT,
                          capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"cargo xtask bundle --scenario {path} failed:\n{done.stdout}{done.stderr}")
    return ROOT / "dist" / name / f"{name}.ssp"


def run_ours(ssp, n_machines, tf, work):
    """Runs the bundled scenario in cosim: time, COI frequency (pu), per-machine speed and power."""
    csv = pathlib.Path(work) / (pathlib.Path(ssp).stem + ".csv")
    sg = [f"grid.sg[{j + 1}].{v}" for j in range(n_machines) for v in ("omega", "p", "in_service")]
    cols = ["time", "grid.coi.f", *sg]
    started = time.time()
    done = subprocess.run([str(COSIM), str(ssp), "--stop", str(tf), "--out", str(csv),
                           "--record", ",".join(cols[1:]), "--output-interval", str(DT)],
                          capture_output=True, text=True)
    wall = time.time() - started
    if done.returncode != 0:
        raise RuntimeError(f"cosim failed: {done.stderr.strip()}")
    with open(csv) as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    col = {n: data[:, header.index(n)] for n in cols}
    omega = np.column_stack([col[f"grid.sg[{j + 1}].omega"] for j in range(n_machines)])
    p = np.column_stack([col[f"grid.sg[{j + 1}].p"] for j in range(n_machines)])
    on = np.column_stack([col[f"grid.sg[{j + 1}].in_service"] for j in range(n_machines)])
    return {"t": col["time"], "coi": col["grid.coi.f"], "omega": omega, "p": p, "on": on, "wall": wall}


# ---------------------------------------------------------------------------------------------
# Metrics
# ---------------------------------------------------------------------------------------------

def machine_h_system(case):
    """Each machine's H on the system base (the COI weights)."""
    out = []
    for m in case["machine"]:
        _, pk = _on_machine_base(case, m)
        out.append(m["h"] * pk * m["rating_mva"] / case["base_mva"])
    return np.array(out)


def coi(omega, h, on):
    w = h[None, :] * on
    return np.sum(w * omega, axis=1) / np.sum(w, axis=1)


def resample(t, y, grid):
    y = np.asarray(y)
    if y.ndim == 1:
        return np.interp(grid, t, y)
    return np.column_stack([np.interp(grid, t, y[:, k]) for k in range(y.shape[1])])


def at(t, y, when):
    return float(np.interp(when, t, y))


def rocof(t, f_hz, t0, window):
    """Mean RoCoF (Hz/s) over `window` s after t0."""
    return (at(t, f_hz, t0 + window) - at(t, f_hz, t0)) / window


def nrmse(x, ref, base):
    """RMS of x - ref over the peak |ref - base| (peak-normalised)."""
    peak = np.max(np.abs(ref - base))
    return math.sqrt(np.mean((x - ref) ** 2)) / peak if peak > 0 else float("nan")


def compare(case, event, tf, work, name):
    """Both simulators on one event: metrics and the traces on a common time grid."""
    fn = case["f_nom"]
    h = machine_h_system(case)
    n = len(case["machine"])
    a = run_andes(case, [event], tf)
    ours = run_ours(bundle_ours(case, event, name, work), n, tf, work)
    grid = np.round(np.arange(0.0, tf + DT / 2, DT), 9)
    t0 = event["time"]
    on = np.ones((len(grid), n))
    if event["type"] == "generator_trip":
        on[grid >= t0, event["machine"] - 1] = 0.0
    wa, pa = resample(a["t"], a["omega"], grid), resample(a["t"], a["p"], grid)
    wo, po = resample(ours["t"], ours["omega"], grid), resample(ours["t"], ours["p"], grid)
    fa = coi(wa, h, on) * fn
    fo = resample(ours["t"], ours["coi"], grid) * fn
    after = grid >= t0
    res = {"grid": grid, "f_andes": fa, "f_ours": fo, "andes_wall": a["wall"], "ours_wall": ours["wall"],
           "coi_check": float(np.max(np.abs(coi(wo, h, on) * fn - fo)))}
    for tag, f in (("andes", fa), ("ours", fo)):
        res[f"nadir_{tag}"] = float(np.min(f[after])) if event["type"] != "line_trip" else float(
            f[after][np.argmax(np.abs(f[after] - fn))])
        res[f"rocof100_{tag}"] = rocof(grid, f, t0, 0.1)
        res[f"rocof500_{tag}"] = rocof(grid, f, t0, 0.5)
    # The sample at the event instant is left out of the NRMSEs: the powers jump there, and a
    # sampled output holds either side of the jump (ANDES's the value after, cosim's before).
    k = np.abs(grid - t0) > DT / 2
    res["f_nrmse"] = nrmse(fo[k], fa[k], fn)
    res["f_steady_andes"], res["f_steady_ours"] = float(fa[-1]), float(fo[-1])
    names = machine_names(case)
    res["machines"] = []
    for j in range(n):
        tripped = not on[-1, j]
        res["machines"].append({
            "name": names[j],
            "in_service": not tripped,
            # a tripped machine is flat before its trip and frozen after it in both: not compared
            "omega_nrmse": float("nan") if tripped else nrmse(wo[k, j], wa[k, j], 1.0),
            "p_nrmse": float("nan") if tripped else nrmse(po[k, j], pa[k, j], pa[0, j]),
            "p0_andes": float(pa[0, j]), "p0_ours": float(po[0, j]),
        })
    return res


# ---------------------------------------------------------------------------------------------
# Mode fit (matrix pencil) on the machines' relative speeds
# ---------------------------------------------------------------------------------------------

def matrix_pencil(y, dt, order=None, pencil=None, tol=1e-7):
    """Damped exponentials of the sampled signals y (samples × channels, fitted jointly):
    continuous-time poles (1/s) and the relative size of each mode in the fit."""
    y = np.atleast_2d(np.asarray(y, dtype=float).T).T
    n = y.shape[0]
    L = pencil or n // 3
    hank = np.vstack([np.column_stack([y[i:i + L + 1, c] for i in range(n - L)]).T for c in range(y.shape[1])])
    _, s, vh = np.linalg.svd(hank, full_matrices=False)
    m = order or int(np.sum(s > tol * s[0]))
    v = vh[:m].conj().T
    v1, v2 = v[:-1], v[1:]
    z = np.linalg.eigvals(np.linalg.pinv(v1) @ v2)
    z = z[np.abs(z) > 1e-12]
    lam = np.log(z.astype(complex)) / dt
    # residues by least squares on each channel, for the modes' weights
    k = np.arange(n)[:, None]
    basis = z[None, :] ** k
    amp, *_ = np.linalg.lstsq(basis, y.astype(complex), rcond=None)
    weight = np.sqrt(np.sum(np.abs(amp) ** 2, axis=1))
    return lam, weight


def fitted_modes(t, omega, h, t0, *, window=8.0, dt=0.02, order=FIT_ORDER):
    """Electromechanical modes of the machines' speeds relative to the COI after t0 (the first
    100 ms skipped): [(Hz, damping ratio, weight)], sorted by frequency, each mode in the band
    once (conjugate pairs merged)."""
    grid = np.arange(t0 + 0.1, t0 + 0.1 + window, dt)
    w = resample(t, omega, grid)
    rel = w - coi(w, h, np.ones_like(w))[:, None]
    rel = rel - rel.mean(axis=0)
    lam, weight = matrix_pencil(rel, dt, order=order)
    out = []
    for l_, wt in zip(lam, weight):
        f = l_.imag / (2 * math.pi)
        if f <= 0 or not (BAND[0] <= f <= BAND[1]):
            continue
        out.append((f, -l_.real / abs(l_), wt))
    out.sort()
    total = sum(o[2] for o in out) or 1.0
    return [(f, z, wt / total) for f, z, wt in out]


def nearest(modes, f, rel=0.25):
    """The fitted mode nearest in frequency to f Hz (within `rel` of it), or None."""
    near = [m for m in modes if abs(m[0] - f) <= rel * f]
    return min(near, key=lambda m: abs(m[0] - f)) if near else None


def damping_study(case, work, tf=10.0):
    """The 0.1-3 Hz modes with and without the stabilizers: ANDES's eigenvalues and both
    simulators' fits after a small load step."""
    h = machine_h_system(case)
    n = len(case["machine"])
    out = {}
    for label, c in (("with PSS", case), ("without PSS", without_pss(case))):
        eig = andes_modes(c)
        a = run_andes(c, [SMALL_STEP], tf)
        tag = "pss" if c is case else "nopss"
        ours = run_ours(bundle_ours(c, SMALL_STEP, f"andes_small_{tag}", work), n, tf, work)
        out[label] = {
            "eig": [(f, z) for f, z, _ in eig],
            "fit_andes": fitted_modes(a["t"], a["omega"], h, SMALL_STEP["time"]),
            "fit_ours": fitted_modes(ours["t"], ours["omega"], h, SMALL_STEP["time"]),
        }
    return out


# ---------------------------------------------------------------------------------------------
# Tables
# ---------------------------------------------------------------------------------------------

def event_table(name, r):
    lines = [f"**{name}**", "",
             "| quantity | ANDES | ours | agreement |", "|---|---|---|---|",
             f"| nadir / extreme of f_COI (Hz) | {r['nadir_andes']:.5f} | {r['nadir_ours']:.5f} | "
             f"{1e3 * (r['nadir_ours'] - r['nadir_andes']):+.2f} mHz |",
             f"| RoCoF over 100 ms (Hz/s) | {r['rocof100_andes']:.4f} | {r['rocof100_ours']:.4f} | "
             f"{_rel(r['rocof100_ours'], r['rocof100_andes'])} |",
             f"| RoCoF over 500 ms (Hz/s) | {r['rocof500_andes']:.4f} | {r['rocof500_ours']:.4f} | "
             f"{_rel(r['rocof500_ours'], r['rocof500_andes'])} |",
             f"| f_COI at the end (Hz) | {r['f_steady_andes']:.5f} | {r['f_steady_ours']:.5f} | "
             f"{1e3 * (r['f_steady_ours'] - r['f_steady_andes']):+.2f} mHz |",
             f"| Δf_COI NRMSE (of the peak) | | | {100 * r['f_nrmse']:.3f} % |"]
    for m in r["machines"]:
        if not m["in_service"]:
            lines.append(f"| {m['name']} | tripped | tripped | not compared |")
            continue
        lines.append(f"| {m['name']} speed NRMSE | | | {100 * m['omega_nrmse']:.3f} % |")
        lines.append(f"| {m['name']} electrical power NRMSE (P at t = 0: {m['p0_andes']:.5f} / "
                     f"{m['p0_ours']:.5f} pu) | | | {100 * m['p_nrmse']:.3f} % |")
    return "\n".join(lines)


def _rel(x, ref):
    return f"{100 * (x - ref) / abs(ref):+.2f} %" if ref != 0 else "n/a"


def modes_table(study):
    """One row per ANDES eigenvalue in the band, with the fitted modes nearest to it."""
    lines = ["| case | ANDES eigenvalue: Hz, ζ | ANDES TDS fit: Hz, ζ | ours fit: Hz, ζ |",
             "|---|---|---|---|"]
    for label, s in study.items():
        for f, z in s["eig"]:
            cells = []
            for fit in (s["fit_andes"], s["fit_ours"]):
                m = nearest(fit, f)
                cells.append(f"{m[0]:.3f}, {100 * m[1]:.2f} %" if m else "not seen")
            lines.append(f"| {label} | {f:.3f}, {100 * z:.2f} % | {cells[0]} | {cells[1]} |")
    return "\n".join(lines)


def study(case, out, tf=10.0):
    """Every comparison of docs/validation.md: the three events and the damping study."""
    events = {key: compare(case, ev, tf, out, f"andes_{key}") for key, ev in EVENTS.items()}
    return {"events": events, "modes": damping_study(case, out, tf)}


def report(case_path, results):
    path = pathlib.Path(case_path).resolve()
    parts = [f"case `{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}`", ""]
    for key, r in results["events"].items():
        ev = {k: v for k, v in EVENTS[key].items() if k != "type"}
        parts.append(event_table(f"{key} {ev}", r))
        parts.append(f"\n(wall time: ANDES {r['andes_wall']:.1f} s, ours {r['ours_wall']:.2f} s; our COI "
                     f"from the sg[] outputs against coi.f: {r['coi_check']:.1e} Hz)\n")
    parts.append(modes_table(results["modes"]))
    return "\n".join(parts)


def main(argv=None):
    global ANDES_STEP, DT
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default=str(DEFAULT_CASE))
    ap.add_argument("--out", default=str(ROOT / "target" / "andes"))
    ap.add_argument("--tf", type=float, default=10.0)
    ap.add_argument("--andes-step", type=float, default=ANDES_STEP,
                    help="ANDES's fixed step, s, also the comparisons' sampling interval")
    args = ap.parse_args(argv)
    ANDES_STEP = DT = args.andes_step
    print(report(args.case, study(load_case(args.case), args.out, args.tf)))


if __name__ == "__main__":
    sys.exit(main())
