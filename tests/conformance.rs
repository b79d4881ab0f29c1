//! The EMT unit's host-conformance trajectories (controllers/tests/conformance/) as FMU calls: replayed through `dvpp_der_emt` in process, or written as an `fmi2-trace` for the wine master's replay.

use dvpp_controllers::emt::trajectory::INPUTS;
use dvpp_controllers::emt::trajectory::{Trajectory, N_OUT, OUTPUTS};
use dvpp_controllers::emt::ParamValue;
use dvpp_cosim::{Instance, Status};
use model_description::ModelDescription;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Every committed trajectory, by file name order.
pub fn trajectories() -> Vec<(PathBuf, Trajectory)> {
    let dir = super::root()
        .join("controllers")
        .join("tests")
        .join("conformance");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("a directory entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "txt"))
        .collect();
    files.sort();
    assert!(!files.is_empty(), "{}: no trajectories", dir.display());
    files
        .into_iter()
        .map(|p| {
            let text =
                std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            let t = Trajectory::parse(&text).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            (p, t)
        })
        .collect()
}

/// The value reference of the variable `name`.
pub fn vr(md: &ModelDescription, name: &str) -> u32 {
    md.variable(name)
        .unwrap_or_else(|| panic!("{}: no variable {name}", md.model_name))
        .value_reference
}

/// The FMU's references of a trajectory's signals: inputs, gains (`mu_p`, `mu_q`,
/// `mu_p_lpf[1..8]`), the Real outputs and the flags (the last three outputs).
pub struct Refs {
    pub inputs: Vec<u32>,
    pub gains: Vec<u32>,
    pub reals: Vec<u32>,
    pub flags: Vec<u32>,
}

impl Refs {
    pub fn of(md: &ModelDescription) -> Refs {
        let mut gains = vec![vr(md, "mu_p"), vr(md, "mu_q")];
        gains.extend((1..=8).map(|k| vr(md, &format!("mu_p_lpf[{k}]"))));
        Refs {
            inputs: INPUTS.iter().map(|n| vr(md, n)).collect(),
            gains,
            reals: OUTPUTS[..N_OUT - 3].iter().map(|n| vr(md, n)).collect(),
            flags: OUTPUTS[N_OUT - 3..].iter().map(|n| vr(md, n)).collect(),
        }
    }
}

fn gains(t: &Trajectory) -> Vec<f64> {
    let mut g = vec![t.gains.mu_p, t.gains.mu_q];
    g.extend(t.gains.mu_p_lpf);
    g
}

/// The trajectory's commands from an instance of `dvpp_der_emt` (freshly instantiated): its
/// parameters set, initialized on the first measurement, stepped on the others.
pub fn replay(
    i: &mut Instance,
    md: &ModelDescription,
    t: &Trajectory,
) -> ([f64; N_OUT], Vec<[f64; N_OUT]>) {
    let refs = Refs::of(md);
    let ok = |s: Status, what: &str, i: &Instance| {
        assert_eq!(s, Status::Ok, "{}: {what}: {:?}", t.case, i.last_message());
    };
    for (name, v) in &t.params {
        let r = vr(md, name);
        let s = match v {
            ParamValue::Real(x) => i.set_real(&[r], &[*x]),
            ParamValue::Integer(k) => i.set_integer(&[r], &[*k]),
            ParamValue::Boolean(b) => i.set_boolean(&[r], &[*b]),
        };
        ok(s, &format!("set {name}"), i);
    }
    ok(i.setup_experiment(t.init_t, None), "setup_experiment", i);
    ok(
        i.enter_initialization_mode(),
        "enter_initialization_mode",
        i,
    );
    ok(
        i.set_real(&refs.inputs, &t.init_inputs),
        "set the inputs",
        i,
    );
    ok(i.set_real(&refs.gains, &gains(t)), "set the gains", i);
    ok(i.exit_initialization_mode(), "exit_initialization_mode", i);
    let read = |i: &mut Instance| {
        let mut out = [0.0; N_OUT];
        let (reals, flags) = out.split_at_mut(N_OUT - 3);
        ok(i.get_real(&refs.reals, reals), "get_real", i);
        let mut b = [false; 3];
        ok(i.get_boolean(&refs.flags, &mut b), "get_boolean", i);
        for (o, b) in flags.iter_mut().zip(b) {
            *o = if b { 1.0 } else { 0.0 };
        }
        out
    };
    let init = read(i);
    let steps = t
        .steps
        .iter()
        .map(|s| {
            ok(i.set_real(&refs.inputs, &s.inputs), "set the inputs", i);
            ok(i.do_step(s.t, s.h), &format!("do_step at {}", s.t), i);
            read(i)
        })
        .collect();
    (init, steps)
}

fn hex(x: f64) -> String {
    format!("{:016x}", x.to_bits())
}

/// The trajectory as the calls of an `fmi2-trace` (cosim/src/fmu/trace.rs) to an instance of
/// the FMU of `md`, with a `sample` after initialization and after each step; and the wine
/// master's OUTPUTS argument for the trajectory's outputs, in their order.
pub fn trace(md: &ModelDescription, t: &Trajectory) -> (String, String) {
    let refs = Refs::of(md);
    let mut s = String::from("fmi2-trace 1\n");
    let _ = writeln!(s, "# the conformance trajectory {}", t.case);
    let _ = writeln!(s, "instantiate conformance 1 {} -", md.guid);
    for (name, v) in &t.params {
        let r = vr(md, name);
        let _ = match v {
            ParamValue::Real(x) => writeln!(s, "set_real 1 {r} {}", hex(*x)),
            ParamValue::Integer(k) => writeln!(s, "set_integer 1 {r} {k}"),
            ParamValue::Boolean(b) => writeln!(s, "set_boolean 1 {r} {}", u8::from(*b)),
        };
    }
    let zero = hex(0.0);
    let _ = writeln!(s, "setup_experiment 0 {zero} {} 0 {zero}", hex(t.init_t));
    s.push_str("enter_initialization_mode\n");
    let set = |s: &mut String, vrs: &[u32], xs: &[f64]| {
        let _ = write!(s, "set_real {}", vrs.len());
        for (r, x) in vrs.iter().zip(xs) {
            let _ = write!(s, " {r} {}", hex(*x));
        }
        s.push('\n');
    };
    let get = |s: &mut String, t: f64| {
        let list = |vrs: &[u32]| {
            vrs.iter()
                .map(|r| r.to_string())
                .collect::<Vec<_>>()
                .join(" ")
        };
        let _ = writeln!(s, "get_real {} {}", refs.reals.len(), list(&refs.reals));
        let _ = writeln!(s, "get_boolean {} {}", refs.flags.len(), list(&refs.flags));
        let _ = writeln!(s, "sample {}", hex(t));
    };
    set(&mut s, &refs.inputs, &t.init_inputs);
    set(&mut s, &refs.gains, &gains(t));
    s.push_str("exit_initialization_mode\n");
    get(&mut s, t.init_t);
    for st in &t.steps {
        set(&mut s, &refs.inputs, &st.inputs);
        let _ = writeln!(s, "do_step {} {} 1", hex(st.t), hex(st.h));
        get(&mut s, st.t + st.h);
    }
    s.push_str("terminate\n");
    let mut outputs: Vec<String> = refs.reals.iter().map(|r| r.to_string()).collect();
    outputs.extend(refs.flags.iter().map(|r| format!("b:{r}")));
    (s, outputs.join(","))
}

/// A replay's rows (the samples' outputs, as the wine master prints them) as the commands of
/// initialization and of each step.
pub fn commands(rows: &[(f64, Vec<f64>)]) -> ([f64; N_OUT], Vec<[f64; N_OUT]>) {
    let row = |v: &Vec<f64>| -> [f64; N_OUT] { v.as_slice().try_into().expect("19 outputs") };
    let init = row(&rows[0].1);
    (init, rows[1..].iter().map(|r| row(&r.1)).collect())
}
