//! The real-code DLLs as an EMT tool's import uses them (`dvpp_realcode::loader`: dlopen, the model info read, the arrays allocated from it, parameters checked, initialized, stepped): the library's host-conformance trajectories through the DER DLL bit for bit with many instances in one process, three instances in closed loop with the EMT plant beside the operator DLL and its FMU twin, a snapshot of the arrays restored, and parameters refused by name.

#[path = "../../../controllers/tests/support/mod.rs"]
#[allow(dead_code)]
mod support;

use dvpp_controllers::emt::trajectory::{Trajectory, INPUTS, N_OUT, OUTPUTS};
use dvpp_controllers::emt::{EmtCommand, InnerKind, ParamValue};
use dvpp_controllers::Mode;
use dvpp_realcode::ffi;
use dvpp_realcode::info::c_name;
use dvpp_realcode::loader::{Inst, Library, SYMBOLS};
use fmi_export::harness::Harness;
use fmi_export::Status;
use std::path::PathBuf;
use std::sync::OnceLock;
use support::{command, measure, plant_for, unit_params};

/// The DER DLL's step.
const H: f64 = 50e-6;
/// The operator DLL's step, in DER steps.
const OPERATOR_EVERY: usize = 20;

/// The directory the test's cdylibs are built into (`target/<profile>/deps`).
fn deps() -> PathBuf {
    std::env::current_exe()
        .expect("the test's path")
        .parent()
        .expect("its directory")
        .to_path_buf()
}

fn so(name: &str) -> PathBuf {
    let p = deps().join(format!("lib{name}.so"));
    assert!(
        p.exists(),
        "{}: not built (cargo test -p realcode-der-emt builds it with its dev-dependency realcode-operator)",
        p.display()
    );
    p
}

fn der() -> &'static Library {
    static L: OnceLock<Library> = OnceLock::new();
    L.get_or_init(|| Library::open(&so("dvpp_der_emt_dll")).unwrap_or_else(|e| panic!("{e}")))
}

fn operator() -> &'static Library {
    static L: OnceLock<Library> = OnceLock::new();
    L.get_or_init(|| Library::open(&so("dvpp_operator_dll")).unwrap_or_else(|e| panic!("{e}")))
}

/// Every committed trajectory of the library, by case name.
fn trajectories() -> Vec<Trajectory> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../controllers/tests/conformance");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("an entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "txt"))
        .collect();
    files.sort();
    assert_eq!(files.len(), 8, "{}: the eight cases", dir.display());
    files
        .iter()
        .map(|p| {
            let text = std::fs::read_to_string(p).expect("a trajectory");
            Trajectory::parse(&text).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
        })
        .collect()
}

fn gains(t: &Trajectory) -> Vec<f64> {
    let mut g = vec![t.gains.mu_p, t.gains.mu_q];
    g.extend(t.gains.mu_p_lpf);
    g
}

const GAIN_NAMES: [&str; 10] = [
    "mu_p",
    "mu_q",
    "mu_p_lpf_1",
    "mu_p_lpf_2",
    "mu_p_lpf_3",
    "mu_p_lpf_4",
    "mu_p_lpf_5",
    "mu_p_lpf_6",
    "mu_p_lpf_7",
    "mu_p_lpf_8",
];

/// A DER instance with a trajectory's parameters, checked.
fn der_instance(t: &Trajectory) -> Inst<'static> {
    let mut i = der().instance().unwrap_or_else(|e| panic!("{e}"));
    for (name, v) in &t.params {
        let x = match v {
            ParamValue::Real(x) => *x,
            ParamValue::Integer(k) => f64::from(*k),
            ParamValue::Boolean(b) => f64::from(u8::from(*b)),
        };
        i.set_parameter(&c_name(name), x)
            .unwrap_or_else(|e| panic!("{}: {e}", t.case));
    }
    i.check_parameters()
        .unwrap_or_else(|e| panic!("{}: {e}", t.case));
    i
}

/// The slots of the trajectory's inputs, gains and outputs in a DER instance.
struct Slots {
    inputs: Vec<(ffi::DataType, usize)>,
    gains: Vec<(ffi::DataType, usize)>,
    outputs: Vec<(ffi::DataType, usize)>,
}

fn slots(i: &Inst<'_>) -> Slots {
    let outs: Vec<String> = OUTPUTS.iter().map(|n| c_name(n)).collect();
    let outs: Vec<&str> = outs.iter().map(|s| s.as_str()).collect();
    Slots {
        inputs: i.slots(&INPUTS, false).expect("the inputs"),
        gains: i.slots(&GAIN_NAMES, false).expect("the gains"),
        outputs: i.slots(&outs, true).expect("the outputs"),
    }
}

fn read(i: &mut Inst<'_>, s: &Slots) -> [f64; N_OUT] {
    let mut out = [0.0; N_OUT];
    i.get_outputs(&s.outputs, &mut out);
    out
}

#[test]
fn the_dll_exports_the_eight_functions_and_describes_every_variable() {
    let info = &der().info;
    assert_eq!(info.version, ffi::INTERFACE_VERSION);
    assert_eq!(info.name, "dvpp_der_emt");
    assert_eq!(info.step, H);
    assert_eq!((info.float_states, info.double_states), (0, 0));
    // Every input, output and parameter of the FMU, with its unit, range and default.
    let md = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fmu-der/emt/modelDescription.xml"),
    )
    .expect("the FMU's model description");
    let count = |c: &str| md.matches(&format!("causality=\"{c}\"")).count();
    assert_eq!(info.inputs.len(), count("input"));
    assert_eq!(info.outputs.len(), count("output"));
    assert_eq!(info.parameters.len(), count("parameter"));
    let tdes_h = info
        .parameters
        .iter()
        .find(|p| p.name == "Tdes_H")
        .expect("Tdes_H");
    assert_eq!((tdes_h.min, tdes_h.max, tdes_h.default), (0.0, 1e12, 5.55));
    assert_eq!((tdes_h.unit.as_str(), tdes_h.fixed), ("s", true));
    let mode = info
        .parameters
        .iter()
        .find(|p| p.name == "mode")
        .expect("mode");
    assert_eq!((mode.data_type, mode.min, mode.max), (ffi::INT32, 1.0, 2.0));
    for n in ["v_a", "v_dc", "mu_p"] {
        assert!(
            info.inputs.iter().any(|d| d.name == n && d.width == 1),
            "{n}"
        );
    }
    assert_eq!(operator().info.step, 1e-3);
    // Exactly the eight symbols, and the C runtime only.
    for lib in ["dvpp_der_emt_dll", "dvpp_operator_dll"] {
        let path = so(lib);
        let nm = std::process::Command::new("nm")
            .args(["-D", "--defined-only"])
            .arg(&path)
            .output()
            .expect("nm");
        let text = String::from_utf8_lossy(&nm.stdout);
        let mut exported: Vec<&str> = text
            .lines()
            .filter_map(|l| l.split_whitespace().nth(2))
            .collect();
        exported.sort();
        let mut eight = SYMBOLS.to_vec();
        eight.sort();
        assert_eq!(exported, eight, "{}", path.display());
        let elf = std::process::Command::new("readelf")
            .arg("-d")
            .arg(&path)
            .output()
            .expect("readelf");
        let text = String::from_utf8_lossy(&elf.stdout);
        for l in text.lines().filter(|l| l.contains("(NEEDED)")) {
            assert!(
                [
                    "libc.so.6",
                    "libgcc_s.so.1",
                    "ld-linux-x86-64.so.2",
                    "libm.so.6"
                ]
                .iter()
                .any(|n| l.contains(n)),
                "{}: {l}",
                path.display()
            );
        }
    }
    assert_eq!(der().print_info(), 0);
}

#[test]
fn every_trajectory_replays_through_the_dll_bit_for_bit_with_all_instances_in_one_process() {
    let ts = trajectories();
    // One instance per case, all alive together, stepped in turn.
    let mut insts: Vec<(Inst<'static>, Slots)> = ts
        .iter()
        .map(|t| {
            let mut i = der_instance(t);
            let s = slots(&i);
            i.set_inputs(&s.inputs, &t.init_inputs);
            i.set_inputs(&s.gains, &gains(t));
            i.initialize(t.init_t)
                .unwrap_or_else(|e| panic!("{}: {e}", t.case));
            (i, s)
        })
        .collect();
    let mut outs: Vec<([f64; N_OUT], Vec<[f64; N_OUT]>)> = insts
        .iter_mut()
        .map(|(i, s)| (read(i, s), Vec::new()))
        .collect();
    let n = ts.iter().map(|t| t.steps.len()).max().unwrap_or(0);
    let mut largest = 0;
    for k in 0..n {
        for ((t, (i, s)), out) in ts.iter().zip(&mut insts).zip(&mut outs) {
            let Some(step) = t.steps.get(k) else { continue };
            assert_eq!(step.h, H, "{}: the DLL's fixed step", t.case);
            i.set_inputs(&s.inputs, &step.inputs);
            i.outputs(step.t)
                .unwrap_or_else(|e| panic!("{}: step {k}: {e}", t.case));
            out.1.push(read(i, s));
            if k + 1 == t.steps.len() {
                largest = largest.max(i.snapshot().ints[1]);
            }
        }
    }
    for (t, (init, steps)) in ts.iter().zip(&outs) {
        if let Err(m) = t.compare(init, steps) {
            panic!("{} through the DLL: {m}", t.case);
        }
        eprintln!(
            "{}: {} steps through the DLL bit for bit",
            t.case,
            steps.len()
        );
    }
    let cap = 4 * (der().info.int_states - dvpp_realcode::dll::HEADER);
    eprintln!("largest state blob {largest} bytes of {cap}");
    assert!(
        (largest as usize) * 2 < cap,
        "the state blob ({largest} bytes) must leave half of NumIntStates' {cap} bytes free"
    );
}

#[test]
fn a_snapshot_of_the_arrays_restored_continues_exactly_here_and_in_a_fresh_instance() {
    let ts = trajectories();
    for case in ["weak_gfm_b", "weak_gfl", "island_gfm_a"] {
        let t = ts.iter().find(|t| t.case == case).expect("the case");
        let run = |i: &mut Inst<'_>, s: &Slots, from: usize| -> Vec<[f64; N_OUT]> {
            t.steps[from..]
                .iter()
                .map(|st| {
                    i.set_inputs(&s.inputs, &st.inputs);
                    i.outputs(st.t).unwrap_or_else(|e| panic!("{case}: {e}"));
                    read(i, s)
                })
                .collect()
        };
        let mid = t.steps.len() / 2;
        // The snapshot at step `mid` of a run from the start.
        let mut a = der_instance(t);
        let s = slots(&a);
        a.set_inputs(&s.inputs, &t.init_inputs);
        a.set_inputs(&s.gains, &gains(t));
        a.initialize(t.init_t).expect("initialize");
        for st in &t.steps[..mid] {
            a.set_inputs(&s.inputs, &st.inputs);
            a.outputs(st.t).expect("a step");
        }
        let snap = a.snapshot();
        let rest = run(&mut a, &s, mid);
        // The same instance, its arrays restored: the rest again, bit for bit.
        a.restore(&snap);
        assert_eq!(run(&mut a, &s, mid), rest, "{case}: restored in place");
        // A fresh instance (as a host restoring a saved snapshot in another process: no
        // Model_Initialize, the arrays and the parameters given).
        let mut b = der().instance().expect("an instance");
        a.copy_parameters_to(&mut b);
        b.set_inputs(&s.gains, &gains(t));
        b.restore(&snap);
        assert_eq!(
            run(&mut b, &s, mid),
            rest,
            "{case}: restored into a fresh instance"
        );
        // And against the library's own run.
        let mut all: Vec<[f64; N_OUT]> = Vec::new();
        let mut c = der_instance(t);
        c.set_inputs(&s.inputs, &t.init_inputs);
        c.set_inputs(&s.gains, &gains(t));
        c.initialize(t.init_t).expect("initialize");
        let init = read(&mut c, &s);
        all.extend(run(&mut c, &s, 0));
        t.compare(&init, &all)
            .unwrap_or_else(|m| panic!("{case}: {m}"));
        eprintln!(
            "{case}: snapshot at step {mid} restored twice, {} steps bit for bit",
            rest.len()
        );
    }
}

#[test]
fn parameters_out_of_range_are_refused_by_name() {
    let ts = trajectories();
    let t = &ts[0];
    let refused = |name: &str, x: f64, needle: &str| {
        let mut i = der_instance(t);
        i.set_parameter(name, x).expect("the parameter");
        let e = i.check_parameters().expect_err(name);
        assert!(e.contains(needle), "{name} = {x}: {e}");
        eprintln!("{name} = {x}: {e}");
    };
    refused("Tdes_H", -1.0, "'Tdes_H' = -1");
    refused("mode", 3.0, "'mode' = 3");
    refused("adpf_p_lpf_1_tau", f64::NAN, "'adpf_p_lpf_1_tau'");
    refused("t_s", 20e-6, "'t_s'");
    // Model_Initialize refuses what the library refuses, by the FMU's name.
    let mut i = der_instance(t);
    i.set_parameter("mode", 2.0).expect("mode");
    i.set_parameter("inner_kind", 1.0).expect("inner.kind");
    let s = slots(&i);
    i.set_inputs(&s.inputs, &t.init_inputs);
    i.set_inputs(&s.gains, &gains(t));
    let e = i
        .initialize(0.0)
        .expect_err("option B is for grid-forming units");
    assert!(e.contains("inner.kind"), "{e}");
    // A fixed parameter changed after Model_Initialize is refused by name; a tunable one
    // retunes the unit.
    let mut i = der_instance(t);
    i.set_inputs(&s.inputs, &t.init_inputs);
    i.set_inputs(&s.gains, &gains(t));
    i.initialize(0.0).expect("initialize");
    i.set_parameter("qpi_kp", 0.1).expect("qpi.kp");
    i.set_inputs(&s.inputs, &t.steps[0].inputs);
    i.outputs(0.0).expect("a tunable parameter retunes");
    i.set_parameter("Tdes_H", 3.0).expect("Tdes.H");
    let e = i.outputs(H).expect_err("a fixed parameter");
    assert!(e.contains("'Tdes_H'") && e.contains("fixed"), "{e}");
    // Inputs are checked too.
    let mut i = der_instance(t);
    i.set_inputs(&s.inputs, &t.init_inputs);
    i.set_inputs(&s.gains, &gains(t));
    i.initialize(0.0).expect("initialize");
    i.set_input("v_b", f64::INFINITY).expect("v_b");
    let e = i.outputs(0.0).expect_err("an infinite input");
    assert!(e.contains("'v_b'"), "{e}");
}

/// A conformance case's grid as the library's closed loop builds it
/// (controllers/tests/conformance.rs).
struct Grid {
    case: &'static str,
    mode: Mode,
    kind: InnerKind,
    toml: &'static str,
    thevenin: &'static [(&'static str, f64)],
}

const STIFF: &[(&str, f64)] = &[
    ("thevenin.X", 0.03),
    ("thevenin.R", 0.003),
    ("thevenin.jump", 0.05),
    ("thevenin.jump_t", 0.02),
];
const WEAK: &[(&str, f64)] = &[("thevenin.X", 0.667), ("thevenin.R", 0.0667)];

const GRIDS: [Grid; 3] = [
    Grid {
        case: "stiff_gfm_a",
        mode: Mode::GridForming,
        kind: InnerKind::OptionA,
        toml: "[model]\ncase = \"island\"\nthevenin = true\nunits = [{ name = \"unit\", s_rated = 60.0, tau_dc = 0.2, p0 = 0.3 }]\nloads = [{ name = \"base\", p = 0.3, q = 0.06 }]\n",
        thevenin: STIFF,
    },
    Grid {
        case: "weak_gfm_b",
        mode: Mode::GridForming,
        kind: InnerKind::OptionB,
        toml: "[model]\ncase = \"island\"\nthevenin = true\nunits = [{ name = \"unit\", s_rated = 60.0, tau_dc = 0.2, p0 = 0.3 }]\nloads = [{ name = \"base\", p = 0.3, q = 0.06 }, { name = \"step\", p = 0.1, q = 0.02, t_on = 0.02 }]\n",
        thevenin: WEAK,
    },
    Grid {
        case: "weak_gfl",
        mode: Mode::GridFollowing,
        kind: InnerKind::OptionA,
        toml: "[model]\ncase = \"island\"\nthevenin = true\nunits = [{ name = \"unit\", s_rated = 60.0, tau_dc = 0.2, p0 = 0.3 }]\nloads = [{ name = \"base\", p = 0.3, q = 0.06 }, { name = \"step\", p = 0.1, q = 0.02, t_on = 0.02 }]\n",
        thevenin: WEAK,
    },
];

/// The plant's command from the DLL's outputs (in the order of `OUTPUTS`).
fn to_command(o: &[f64; N_OUT]) -> EmtCommand {
    EmtCommand {
        m_abc: [o[0], o[1], o[2]],
        i_dc_ref: o[3],
        p_src_min: o[4],
        p_src_max: o[5],
        ..EmtCommand::default()
    }
}

#[test]
fn three_der_instances_in_closed_loop_with_the_emt_plant_and_the_operator_match_the_library() {
    let ts = trajectories();
    struct Loop {
        t: &'static Trajectory,
        plant: Harness<emt_plant_model::Plant>,
        dll: Inst<'static>,
        slots: Slots,
        init: [f64; N_OUT],
        steps: Vec<[f64; N_OUT]>,
        last: [f64; N_OUT],
    }
    let ts: &'static [Trajectory] = Box::leak(ts.into_boxed_slice());
    let mut loops: Vec<Loop> = GRIDS
        .iter()
        .map(|g| {
            let t = ts.iter().find(|t| t.case == g.case).expect("the case");
            let params = unit_params(g.mode, g.kind);
            let mut plant = plant_for(g.toml, &params);
            for (name, x) in g.thevenin {
                plant.set(name, *x);
            }
            assert_eq!(plant.enter_initialization_mode(), Status::Ok);
            assert_eq!(plant.exit_initialization_mode(), Status::Ok);
            let m0 = measure(&mut plant, 0.0);
            let mut dll = der_instance(t);
            let slots = slots(&dll);
            dll.set_inputs(&slots.inputs, &m0.inputs());
            dll.set_inputs(&slots.gains, &gains(t));
            dll.initialize(0.0)
                .unwrap_or_else(|e| panic!("{}: {e}", g.case));
            let init = read(&mut dll, &slots);
            Loop {
                t,
                plant,
                dll,
                slots,
                init,
                steps: Vec::new(),
                last: init,
            }
        })
        .collect();
    // The operator: the DLL and its FMU twin (the same model in process) on the same inputs,
    // the DERs' outputs (unit k as the operator's DER k) and their sums at the PCC.
    let op_lib = operator();
    let mut op = op_lib.instance().expect("an operator instance");
    op.check_parameters().expect("the operator's defaults");
    let mut twin = Harness::<operator_model::Operator>::new();
    assert_eq!(twin.setup_experiment(0.0, None), Status::Ok);
    assert_eq!(twin.enter_initialization_mode(), Status::Ok);
    let op_inputs = |loops: &[Loop]| -> Vec<(String, f64)> {
        let col = |n: &str| OUTPUTS.iter().position(|o| *o == n).expect("an output");
        let (p, q, v, df, pa, ps) = (
            col("p"),
            col("q"),
            col("v"),
            col("df"),
            col("P_avail"),
            col("p_set"),
        );
        let mut x = Vec::new();
        for (k, l) in loops.iter().enumerate() {
            for (name, c) in [("P_avail", pa), ("p", p), ("p_set", ps), ("q", q)] {
                x.push((format!("der[{}].{name}", k + 1), l.last[c]));
            }
        }
        x.push(("pcc.p".into(), loops.iter().map(|l| l.last[p]).sum()));
        x.push(("pcc.q".into(), loops.iter().map(|l| l.last[q]).sum()));
        x.push(("pcc.f".into(), 1.0 + loops[0].last[df]));
        x.push(("pcc.v".into(), loops[0].last[v]));
        x
    };
    let op_outputs: Vec<String> = op_lib.info.outputs.iter().map(|d| d.name.clone()).collect();
    let twin_names: Vec<String> = {
        let md = std::fs::read_to_string(
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("../../fmu-operator/modelDescription.xml"),
        )
        .expect("the operator's model description");
        md.lines()
            .filter(|l| l.contains("causality=\"output\""))
            .filter_map(|l| {
                l.split("name=\"")
                    .nth(1)?
                    .split('"')
                    .next()
                    .map(String::from)
            })
            .collect()
    };
    assert_eq!(twin_names.len(), op_outputs.len());
    let compare_operator =
        |op: &mut Inst<'_>, twin: &mut Harness<operator_model::Operator>, t: f64| {
            for (c, f) in op_outputs.iter().zip(&twin_names) {
                let (a, b) = (op.output(c).expect("an output"), twin.get(f));
                assert_eq!(
                    a.to_bits(),
                    b.to_bits(),
                    "operator output {f} at t = {t}: DLL {a}, FMU {b}"
                );
            }
        };
    for (name, x) in op_inputs(&loops) {
        op.set_input(&c_name(&name), x).expect("an operator input");
        twin.set(&name, x);
    }
    op.initialize(0.0).expect("the operator initializes");
    assert_eq!(twin.exit_initialization_mode(), Status::Ok);
    compare_operator(&mut op, &mut twin, 0.0);
    let n = loops.iter().map(|l| l.t.steps.len()).min().expect("three");
    let mut op_steps = 0;
    for k in 0..n {
        let t = k as f64 * H;
        if k % OPERATOR_EVERY == 0 && k > 0 {
            for (name, x) in op_inputs(&loops) {
                op.set_input(&c_name(&name), x).expect("an operator input");
                twin.set(&name, x);
            }
            let t_op = (k / OPERATOR_EVERY - 1) as f64 * op_lib.info.step;
            op.outputs(t_op)
                .unwrap_or_else(|e| panic!("operator at {t_op}: {e}"));
            assert_eq!(twin.do_step(t_op, op_lib.info.step), Status::Ok);
            compare_operator(&mut op, &mut twin, t_op);
            op_steps += 1;
        }
        for l in &mut loops {
            command(&mut l.plant, &to_command(&l.last));
            let m = measure(&mut l.plant, t);
            l.dll.set_inputs(&l.slots.inputs, &m.inputs());
            l.dll
                .outputs(t)
                .unwrap_or_else(|e| panic!("{}: t = {t}: {e}", l.t.case));
            assert_eq!(
                l.plant.do_step(t, H),
                Status::Ok,
                "{}: plant at {t}",
                l.t.case
            );
            l.last = read(&mut l.dll, &l.slots);
            l.steps.push(l.last);
        }
    }
    for l in &loops {
        if let Err(m) = l.t.compare(&l.init, &l.steps) {
            panic!("{} in closed loop through the DLL: {m}", l.t.case);
        }
        eprintln!(
            "{}: {} closed-loop steps through the DLL bit for bit with the library's",
            l.t.case,
            l.steps.len()
        );
    }
    eprintln!("operator: {op_steps} steps of 1 ms, DLL and FMU model bit for bit");
    assert!(op_steps > 50);
}

/// `Model_Outputs`' cost per call at 50 µs, beside the FMU model's `do_step` in process (the
/// same unit): printed; in an optimized build each must stay below 5 µs.
#[test]
fn model_outputs_cost_per_call() {
    let ts = trajectories();
    for case in ["stiff_gfm_a", "stiff_gfm_b", "stiff_gfl"] {
        let t = ts.iter().find(|t| t.case == case).expect("the case");
        let mut i = der_instance(t);
        let s = slots(&i);
        i.set_inputs(&s.inputs, &t.init_inputs);
        i.set_inputs(&s.gains, &gains(t));
        // The fastest of three passes over the trajectory (the machine is shared).
        let mut dll = f64::INFINITY;
        for _ in 0..3 {
            i.set_inputs(&s.inputs, &t.init_inputs);
            i.initialize(t.init_t).expect("initialize");
            let start = std::time::Instant::now();
            for st in &t.steps {
                i.set_inputs(&s.inputs, &st.inputs);
                i.outputs(st.t).expect("a step");
            }
            dll = dll.min(start.elapsed().as_secs_f64() / t.steps.len() as f64);
        }
        let mut fmu = Harness::<der_model::emt::DerEmt>::new();
        for (name, v) in &t.params {
            match v {
                ParamValue::Real(x) => fmu.set(name, *x),
                ParamValue::Integer(k) => fmu.set(name, *k),
                ParamValue::Boolean(b) => fmu.set(name, *b),
            }
        }
        assert_eq!(fmu.setup_experiment(t.init_t, None), Status::Ok);
        assert_eq!(fmu.enter_initialization_mode(), Status::Ok);
        let vrs: Vec<u32> = INPUTS.iter().map(|n| fmu.vr(n).1).collect();
        let gvrs: Vec<u32> = ["mu_p", "mu_q"].iter().map(|n| fmu.vr(n).1).collect();
        assert_eq!(fmu.set_real(&vrs, &t.init_inputs), Status::Ok);
        assert_eq!(
            fmu.set_real(&gvrs, &[t.gains.mu_p, t.gains.mu_q]),
            Status::Ok
        );
        assert_eq!(fmu.exit_initialization_mode(), Status::Ok);
        let start = std::time::Instant::now();
        for st in &t.steps {
            assert_eq!(fmu.set_real(&vrs, &st.inputs), Status::Ok);
            assert_eq!(fmu.do_step(st.t, st.h), Status::Ok);
        }
        let fmu_cost = start.elapsed().as_secs_f64() / t.steps.len() as f64;
        eprintln!(
            "{case}: Model_Outputs {:.2} µs per call (with setting the inputs), the FMU model's do_step in process {:.2} µs",
            dll * 1e6,
            fmu_cost * 1e6
        );
        if !cfg!(debug_assertions) {
            assert!(dll < 5e-6, "{case}: Model_Outputs takes {} µs", dll * 1e6);
        }
    }
}

/// The headers `cargo xtask bundle` ships (written by the describe program) compile with a C
/// compiler, and the model's structs have the sizes and offsets the import tool computed from
/// the model info.
#[test]
fn the_shipped_headers_compile_and_agree_with_the_model_info() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("realcode headers");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a directory");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_realcode-der-emt-describe"))
        .arg(&dir)
        .status()
        .expect("the describe program");
    assert!(status.success());
    for preset in ["wind", "pv", "bess"] {
        let text = std::fs::read_to_string(dir.join(format!("dvpp_der_emt.{preset}.params")))
            .expect("a preset's parameter set");
        assert_eq!(
            text.lines().count(),
            der().info.parameters.len(),
            "{preset}"
        );
    }
    let info = &der().info;
    let t_s = info
        .parameters
        .iter()
        .find(|p| p.name == "t_s")
        .expect("t_s")
        .offset;
    let c = dir.join("check.c");
    std::fs::write(
        &c,
        "#include <stddef.h>\n#include <stdio.h>\n#include \"dvpp_der_emt.h\"\n\
         int main(void) {\n    printf(\"%zu %zu %zu %zu %d\\n\", sizeof(dvpp_der_emt_Inputs), \
         sizeof(dvpp_der_emt_Outputs), sizeof(dvpp_der_emt_Parameters), \
         offsetof(dvpp_der_emt_Parameters, t_s), DVPP_DER_EMT_NUM_INT_STATES);\n    \
         return 0;\n}\n",
    )
    .expect("write the check");
    let exe = dir.join("check");
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let out = std::process::Command::new(&cc)
        .args(["-std=c11", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(&dir)
        .arg(&c)
        .arg("-o")
        .arg(&exe)
        .output()
        .expect("a C compiler");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let run = std::process::Command::new(&exe)
        .output()
        .expect("the check");
    let got = String::from_utf8_lossy(&run.stdout).trim().to_string();
    let want = format!(
        "{} {} {} {t_s} {}",
        info.sizes[0], info.sizes[1], info.sizes[2], info.int_states
    );
    assert_eq!(got, want, "the header's structs against the model info");
}

/// One DVPP in closed loop, twice in one process: case study I's three units (the wind, PV and
/// BESS presets, as `emt_thevenin` sets them) on one EMT plant with a Thevenin source and a load
/// step, the operator's dc gains into the units and the units' powers and the PCC into the
/// operator (every 20th step: its 1 ms), once through the DLLs (three DER instances and the
/// operator) and once through the FMUs' models in process (`fmi_export`'s harness, as the FMU
/// binaries run them); every output of every unit and of the operator, and the plant, bit for
/// bit at every step.
#[test]
fn a_dvpp_of_three_der_instances_and_the_operator_in_closed_loop_matches_the_fmus() {
    use dvpp_realcode::info::Layout;
    use dvpp_realcode::DllSpec;
    const PRESETS: [&str; 3] = ["wind", "pv", "bess"];
    // emt_thevenin's start values of the units.
    let overrides = |preset: &str| -> Vec<(&'static str, f64)> {
        match preset {
            "wind" => vec![("P_avail0", 0.43), ("deload", 0.8), ("qpi.kp", 0.12)],
            "pv" => vec![("P_avail0", 0.70), ("deload", 0.8), ("qpi.kp", 0.12)],
            _ => vec![("qpi.kp", 0.12)],
        }
    };
    let layouts: Vec<Layout> = PRESETS
        .iter()
        .map(|p| {
            let config: &'static str =
                Box::leak(format!("[model]\npreset = \"{p}\"\n").into_boxed_str());
            Layout::of::<der_model::emt::DerEmt>(&DllSpec {
                config,
                ..dvpp_der_emt_spec()
            })
            .expect("the preset's layout")
        })
        .collect();
    let value = |l: &Layout, preset: &str, fmu: &str| -> f64 {
        overrides(preset)
            .iter()
            .find(|(n, _)| *n == fmu)
            .map(|o| o.1)
            .unwrap_or_else(|| l.parameters.find(fmu).expect("a parameter").start)
    };
    // The plant: the three units at their dispatch, a load at the PCC and a step of it.
    let units: Vec<String> = PRESETS
        .iter()
        .zip(&layouts)
        .map(|(p, l)| {
            format!(
                "{{ name = \"{p}\", s_rated = {:?}, tau_dc = {:?}, p0 = {:?} }}",
                value(l, p, "S_rated"),
                value(l, p, "tau_dc"),
                der_model::PRESETS
                    .iter()
                    .find(|k| k.name == *p)
                    .expect("a preset")
                    .p
            )
        })
        .collect();
    let plant_toml = format!(
        "[model]\ncase = \"island\"\nthevenin = true\nunits = [{}]\nloads = [{{ name = \"base\", p = 0.9, q = 0.1 }}, {{ name = \"step\", p = 0.1, q = 0.02, t_on = 0.02 }}]\n",
        units.join(", ")
    );
    let plant = || {
        let mut p = Harness::<emt_plant_model::Plant>::from_toml(&plant_toml);
        assert_eq!(p.setup_experiment(0.0, None), Status::Ok);
        for (k, (preset, l)) in PRESETS.iter().zip(&layouts).enumerate() {
            for n in ["R_f", "L_f", "C_f", "R_t", "L_t", "C_dc", "G_dc"] {
                p.set(&format!("der[{}].{n}", k + 1), value(l, preset, n));
            }
        }
        assert_eq!(p.enter_initialization_mode(), Status::Ok);
        assert_eq!(p.exit_initialization_mode(), Status::Ok);
        p
    };
    let (mut plant_dll, mut plant_fmu) = (plant(), plant());
    // The plant's measurements of unit k and the PCC.
    let measured = |p: &mut Harness<emt_plant_model::Plant>, k: usize| -> Vec<f64> {
        INPUTS
            .iter()
            .map(|n| p.get(&format!("der[{k}].{n}")))
            .collect()
    };
    let pcc = |p: &mut Harness<emt_plant_model::Plant>| -> [f64; 4] {
        ["pcc.p", "pcc.q", "pcc.f", "pcc.v"].map(|n| p.get(n))
    };
    // The DLL side and the FMU side of each unit.
    let mut dlls: Vec<Inst<'static>> = Vec::new();
    let mut fmus: Vec<Harness<der_model::emt::DerEmt>> = Vec::new();
    // The operator's gains of unit k and the unit's inputs they go to (the BESS, the
    // complement unit, takes the low-pass units' active gains instead of its own).
    let gain_names = |k: usize| -> Vec<String> {
        if k == 3 {
            ["der[3].mu_q", "der[3].mu_p_lpf[1]", "der[3].mu_p_lpf[2]"]
                .map(String::from)
                .to_vec()
        } else {
            vec![format!("der[{k}].mu_p"), format!("der[{k}].mu_q")]
        }
    };
    let unit_gains = |k: usize| -> Vec<&'static str> {
        if k == 3 {
            vec!["mu_q", "mu_p_lpf[1]", "mu_p_lpf[2]"]
        } else {
            vec!["mu_p", "mu_q"]
        }
    };
    for (k, (preset, l)) in PRESETS.iter().zip(&layouts).enumerate() {
        let k = k + 1;
        let m = measured(&mut plant_dll, k);
        let mut d = der().instance().expect("an instance");
        for f in &l.parameters.fields {
            d.set_parameter(&f.name, value(l, preset, &f.fmu_name))
                .expect("a parameter");
        }
        d.check_parameters()
            .unwrap_or_else(|e| panic!("{preset}: {e}"));
        for (n, x) in INPUTS.iter().zip(&m) {
            d.set_input(n, *x).expect("an input");
        }
        let mut h = Harness::<der_model::emt::DerEmt>::from_toml(&format!(
            "[model]\npreset = \"{preset}\"\n"
        ));
        for (n, x) in overrides(preset) {
            h.set(n, x);
        }
        assert_eq!(h.setup_experiment(0.0, None), Status::Ok);
        assert_eq!(h.enter_initialization_mode(), Status::Ok);
        for (n, x) in INPUTS.iter().zip(&m) {
            h.set(n, *x);
        }
        // The gains start at the unit's declared start values on both sides.
        for f in l
            .inputs
            .fields
            .iter()
            .filter(|f| f.fmu_name.starts_with("mu_"))
        {
            d.set_input(&f.name, f.start).expect("a gain");
            h.set(&f.fmu_name, f.start);
        }
        d.initialize(0.0)
            .unwrap_or_else(|e| panic!("{preset}: {e}"));
        assert_eq!(h.exit_initialization_mode(), Status::Ok, "{preset}");
        dlls.push(d);
        fmus.push(h);
    }
    let compare_unit = |k: usize,
                        d: &mut Inst<'_>,
                        h: &mut Harness<der_model::emt::DerEmt>,
                        t: f64| {
        for f in &layouts[k].outputs.fields {
            let a = d.output(&f.name).expect("an output");
            let b = match f.kind {
                dvpp_realcode::info::Kind::Boolean => f64::from(u8::from(h.get_bool(&f.fmu_name))),
                _ => h.get(&f.fmu_name),
            };
            assert_eq!(
                a.to_bits(),
                b.to_bits(),
                "unit {} output {} at t = {t}: DLL {a}, FMU {b}",
                k + 1,
                f.fmu_name
            );
        }
    };
    for (k, (d, h)) in dlls.iter_mut().zip(&mut fmus).enumerate() {
        compare_unit(k, d, h, 0.0);
    }
    // The operator on both sides.
    let op_lib = operator();
    let mut op = op_lib.instance().expect("an operator");
    op.check_parameters().expect("the operator's defaults");
    let mut twin = Harness::<operator_model::Operator>::new();
    assert_eq!(twin.setup_experiment(0.0, None), Status::Ok);
    assert_eq!(twin.enter_initialization_mode(), Status::Ok);
    let feed_operator = |op: &mut Inst<'_>,
                         twin: &mut Harness<operator_model::Operator>,
                         dlls: &mut [Inst<'static>],
                         fmus: &mut [Harness<der_model::emt::DerEmt>],
                         pcc_dll: [f64; 4],
                         pcc_fmu: [f64; 4]| {
        for (k, (d, h)) in dlls.iter_mut().zip(fmus.iter_mut()).enumerate() {
            for n in ["P_avail", "p", "p_set", "q"] {
                let name = format!("der[{}].{n}", k + 1);
                op.set_input(&c_name(&name), d.output(n).expect("a DER output"))
                    .expect("an operator input");
                twin.set(&name, h.get(n));
            }
        }
        for ((n, a), b) in ["pcc.p", "pcc.q", "pcc.f", "pcc.v"]
            .iter()
            .zip(pcc_dll)
            .zip(pcc_fmu)
        {
            op.set_input(&c_name(n), a).expect("an operator input");
            twin.set(n, b);
        }
    };
    let op_outputs: Vec<(String, String)> = op_lib
        .info
        .outputs
        .iter()
        .map(|d| {
            let fmu = d
                .description
                .rsplit("(FMU: ")
                .next()
                .and_then(|s| s.strip_suffix(')'));
            (d.name.clone(), fmu.unwrap_or(&d.name).to_string())
        })
        .collect();
    let compare_operator =
        |op: &mut Inst<'_>, twin: &mut Harness<operator_model::Operator>, t: f64| {
            for (c, f) in &op_outputs {
                let (a, b) = (op.output(c).expect("an output"), twin.get(f));
                assert_eq!(
                    a.to_bits(),
                    b.to_bits(),
                    "operator {f} at t = {t}: DLL {a}, FMU {b}"
                );
            }
        };
    let (pd, pf) = (pcc(&mut plant_dll), pcc(&mut plant_fmu));
    feed_operator(&mut op, &mut twin, &mut dlls, &mut fmus, pd, pf);
    op.initialize(0.0).expect("the operator initializes");
    assert_eq!(twin.exit_initialization_mode(), Status::Ok);
    compare_operator(&mut op, &mut twin, 0.0);
    // The operator's gains into the units.
    let give_gains = |op: &mut Inst<'_>,
                      twin: &mut Harness<operator_model::Operator>,
                      dlls: &mut [Inst<'static>],
                      fmus: &mut [Harness<der_model::emt::DerEmt>]| {
        for (k, (d, h)) in dlls.iter_mut().zip(fmus.iter_mut()).enumerate() {
            for (from, to) in gain_names(k + 1).iter().zip(unit_gains(k + 1)) {
                d.set_input(&c_name(to), op.output(&c_name(from)).expect("a gain"))
                    .expect("a gain input");
                h.set(to, twin.get(from));
            }
        }
    };
    give_gains(&mut op, &mut twin, &mut dlls, &mut fmus);
    let steps = 2000;
    let mut op_steps = 0;
    let mut p_before = Vec::new();
    for n in 0..steps {
        let t = n as f64 * H;
        for (k, (d, h)) in dlls.iter_mut().zip(&mut fmus).enumerate() {
            let u = k + 1;
            for (plant, m, i_dc, lo, hi) in [
                (
                    &mut plant_dll,
                    [d.output("m_a"), d.output("m_b"), d.output("m_c")].map(|x| x.expect("m")),
                    d.output("i_dc_ref"),
                    d.output("p_src_min"),
                    d.output("p_src_max"),
                ),
                (
                    &mut plant_fmu,
                    [h.get("m_a"), h.get("m_b"), h.get("m_c")],
                    Ok(h.get("i_dc_ref")),
                    Ok(h.get("p_src_min")),
                    Ok(h.get("p_src_max")),
                ),
            ] {
                for (ph, x) in ["a", "b", "c"].iter().zip(m) {
                    plant.set(&format!("der[{u}].m_{ph}"), x);
                }
                plant.set(&format!("der[{u}].i_dc_ref"), i_dc.expect("i_dc_ref"));
                plant.set(&format!("der[{u}].p_src_min"), lo.expect("p_src_min"));
                plant.set(&format!("der[{u}].p_src_max"), hi.expect("p_src_max"));
            }
        }
        for (k, (d, h)) in dlls.iter_mut().zip(&mut fmus).enumerate() {
            let (md, mf) = (
                measured(&mut plant_dll, k + 1),
                measured(&mut plant_fmu, k + 1),
            );
            assert_eq!(md, mf, "unit {} measured at t = {t}", k + 1);
            for (name, x) in INPUTS.iter().zip(&md) {
                d.set_input(name, *x).expect("an input");
                h.set(name, *x);
            }
            d.outputs(t)
                .unwrap_or_else(|e| panic!("unit {} at {t}: {e}", k + 1));
            assert_eq!(h.do_step(t, H), Status::Ok, "unit {} at {t}", k + 1);
            compare_unit(k, d, h, t);
        }
        assert_eq!(plant_dll.do_step(t, H), Status::Ok);
        assert_eq!(plant_fmu.do_step(t, H), Status::Ok);
        if n == 399 {
            p_before = dlls.iter_mut().map(|d| d.output("p").expect("p")).collect();
        }
        if (n + 1) % OPERATOR_EVERY == 0 {
            let t_op = (n + 1 - OPERATOR_EVERY) as f64 * H;
            let (pd, pf) = (pcc(&mut plant_dll), pcc(&mut plant_fmu));
            feed_operator(&mut op, &mut twin, &mut dlls, &mut fmus, pd, pf);
            op.outputs(t_op)
                .unwrap_or_else(|e| panic!("operator at {t_op}: {e}"));
            assert_eq!(twin.do_step(t_op, op_lib.info.step), Status::Ok);
            compare_operator(&mut op, &mut twin, t_op);
            give_gains(&mut op, &mut twin, &mut dlls, &mut fmus);
            op_steps += 1;
        }
    }
    // The load step moved every unit (the DVPP responded).
    let after: Vec<f64> = dlls.iter_mut().map(|d| d.output("p").expect("p")).collect();
    for (k, (a, b)) in p_before.iter().zip(&after).enumerate() {
        assert!(
            (b - a).abs() > 1e-4,
            "unit {} did not respond: p {a} -> {b}",
            k + 1
        );
    }
    eprintln!(
        "DVPP: three DER DLL instances and the operator DLL, {steps} steps of 50 µs ({op_steps} operator steps), bit for bit as the FMUs' models; p of the units {p_before:.4?} before the load step, {after:.4?} at {} s",
        steps as f64 * H
    );
}

/// The DER DLL's spec (as its crate states it).
fn dvpp_der_emt_spec() -> dvpp_realcode::DllSpec {
    dvpp_realcode::DllSpec {
        step: H,
        emt_rms_mode: 1,
        state_words: der().info.int_states,
        step_parameter: Some("t_s"),
        config: "",
    }
}

/// Instances on two threads at once (as a multi-core real-time host runs them): each
/// trajectory bit for bit as the library; and `Model_Initialize` called again (a host holding
/// the model at its initial conditions until a release time) starts from the latest measured
/// operating point, as a fresh instance initialized there.
#[test]
fn instances_on_two_threads_and_repeated_initialization() {
    let ts = trajectories();
    std::thread::scope(|scope| {
        let handles: Vec<_> = ["weak_gfm_a", "stiff_gfl"]
            .iter()
            .map(|case| {
                let t = ts.iter().find(|t| t.case == *case).expect("the case");
                scope.spawn(move || {
                    let mut i = der_instance(t);
                    let s = slots(&i);
                    i.set_inputs(&s.inputs, &t.init_inputs);
                    i.set_inputs(&s.gains, &gains(t));
                    i.initialize(t.init_t).expect("initialize");
                    let init = read(&mut i, &s);
                    let steps: Vec<[f64; N_OUT]> = t
                        .steps
                        .iter()
                        .map(|st| {
                            i.set_inputs(&s.inputs, &st.inputs);
                            i.outputs(st.t).expect("a step");
                            read(&mut i, &s)
                        })
                        .collect();
                    t.compare(&init, &steps)
                        .unwrap_or_else(|m| panic!("{case} on its thread: {m}"));
                })
            })
            .collect();
        for h in handles {
            h.join().expect("a thread");
        }
    });
    // Initialized at the trajectory's first measurement, then again at its 100th: as a fresh
    // instance initialized at the 100th, call for call.
    let t = ts
        .iter()
        .find(|t| t.case == "stiff_gfm_b")
        .expect("the case");
    let mut held = der_instance(t);
    let mut fresh = der_instance(t);
    let s = slots(&held);
    held.set_inputs(&s.inputs, &t.init_inputs);
    held.set_inputs(&s.gains, &gains(t));
    held.initialize(t.init_t).expect("initialize");
    let at = &t.steps[100];
    for i in [&mut held, &mut fresh] {
        i.set_inputs(&s.inputs, &at.inputs);
        i.set_inputs(&s.gains, &gains(t));
        i.initialize(t.init_t).expect("initialize again");
    }
    assert_eq!(read(&mut held, &s), read(&mut fresh, &s));
    for st in &t.steps[101..300] {
        for i in [&mut held, &mut fresh] {
            i.set_inputs(&s.inputs, &st.inputs);
            i.outputs(st.t).expect("a step");
        }
        assert_eq!(read(&mut held, &s), read(&mut fresh, &s), "at {}", st.t);
    }
}
