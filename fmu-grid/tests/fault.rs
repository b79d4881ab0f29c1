//! The balanced bus fault (`fault.*`): the shunt's voltage divider, exact switching times, the
//! power balance during the fault, no change without one, and the FMU's checks of its parameters.

use fmi_export::harness::Harness;
use fmi_export::Status;
use grid_model::numerics::C64 as C;
use grid_model::{BusFault, Case, Grid, GridFmu, Outputs};

/// The Thevenin case (a classical machine behind a line, three grid-forming slots and a load at
/// the PCC, bus 2) with its load step cancelled.
fn thevenin() -> Grid {
    let mut g = Grid::new(&Case::builtin("thevenin_dvpp").unwrap()).unwrap();
    g.disable_events();
    g
}

/// Step `g` from its time to `t_end` in steps of `h` (the slots' inputs held).
fn run_to(g: &mut Grid, t_end: f64, h: f64) {
    while g.time() < t_end - 1e-9 {
        let t = g.time();
        g.step(t, h.min(t_end - t)).unwrap();
    }
}

/// The fault at bus 2 through `r + jx` from `t` for `duration`.
fn at_pcc(r: f64, x: f64, t: f64, duration: f64) -> BusFault {
    BusFault {
        bus: 2,
        r,
        x,
        t,
        duration,
    }
}

/// At the instant the fault is applied every source of the case is a fixed voltage behind its
/// impedance (the machine's E' behind x'_d, the slots' E behind r + jx, the load an
/// admittance): the PCC voltage is the Norton divider `V_pre Y_th / (Y_th + Y_f)`, with `Y_th`
/// the driving-point admittance at the PCC computed here from the case data.
#[test]
fn the_fault_is_the_shunt_divider_of_the_driving_point_admittance() {
    let mut g = thevenin();
    let v_pre = g.power_flow().v[1];
    let (r_f, x_f) = (0.01, 0.08);
    g.set_fault(Some(at_pcc(r_f, x_f, 0.0, 0.15))).unwrap();
    g.step(0.0, 1e-6).unwrap();
    let o = g.outputs();
    // Machine x'_d = 0.01 pu on 300 MVA, line 0.01 + j0.08; slots 0.01 + j0.10 on their
    // ratings; load 100 + j20 MW at the power-flow voltage.
    let y = |z: C| C::new(1.0, 0.0) / z;
    let mut y_th = y(C::new(0.01, 0.08 + 0.01 * 100.0 / 300.0));
    for rating in [46.0, 73.0, 60.0] {
        y_th += y(C::new(0.01, 0.10) * (100.0 / rating));
    }
    y_th += C::new(1.0, -0.2) / v_pre.norm_sqr();
    let y_f = y(C::new(r_f, x_f));
    let v_fault = v_pre * y_th / (y_th + y_f);
    let (v, i) = (o.fault.v, o.fault.i);
    println!(
        "PCC {:.6} pu before, {v:.6} pu in the fault (divider {:.6}); fault current {i:.4} pu",
        dvpp_math::cabs(v_pre),
        dvpp_math::cabs(v_fault)
    );
    assert!(o.fault.on);
    assert!(
        (v - dvpp_math::cabs(v_fault)).abs() < 1e-6,
        "{v} vs {}",
        dvpp_math::cabs(v_fault)
    );
    assert!((i - dvpp_math::cabs(v_fault * y_f)).abs() < 1e-5, "{i}");
    assert_eq!(o.pcc.v, o.fault.v, "the PCC is the faulted bus");
}

/// The fault switches at its times exactly, whatever the communication step: a run that steps
/// over the whole fault in one step ends where one in 10 ms steps does (to the integration's
/// rounding), and the outputs say whether the fault is on: from `fault.t` (included) to
/// `fault.t + fault.duration` (excluded).
#[test]
fn the_fault_switches_at_its_times_whatever_the_step() {
    let fault = at_pcc(0.02, 0.15, 0.5, 0.15);
    let mut fine = thevenin();
    fine.set_fault(Some(fault)).unwrap();
    let mut coarse = fine.clone();
    run_to(&mut fine, 0.49, 0.01);
    assert!(!fine.outputs().fault.on && fine.outputs().fault.i == 0.0);
    // At its time the fault is on (the step that reaches it ends with the fault applied).
    run_to(&mut fine, 0.5, 0.01);
    let during = fine.outputs();
    assert!(
        during.fault.on && during.fault.i > 1.0,
        "{:?}",
        during.fault
    );
    assert!(during.fault.v < 0.85, "{:?}", during.fault);
    run_to(&mut fine, 0.64, 0.01);
    assert!(fine.outputs().fault.on);
    run_to(&mut fine, 0.65, 0.01);
    assert!(!fine.outputs().fault.on);
    run_to(&mut fine, 0.9, 0.01);
    let after = fine.outputs();
    assert!(!after.fault.on && after.fault.i == 0.0, "{:?}", after.fault);
    assert!(after.fault.v > 0.9, "{:?}", after.fault);
    run_to(&mut coarse, 0.45, 0.01);
    run_to(&mut coarse, 0.9, 0.45);
    let c = coarse.outputs();
    let dev = (c.sg[0].omega - after.sg[0].omega)
        .abs()
        .max((c.sg[0].delta - after.sg[0].delta).abs())
        .max((c.pcc.v - after.pcc.v).abs());
    println!("one 0.45 s step over the fault against 10 ms steps: {dev:.2e}");
    assert!(dev < 1e-9, "{dev}");
}

/// During a resistive fault the balance `sys.p_gen - sys.p_load - sys.p_loss` stays zero:
/// the fault's resistance is a load.
#[test]
fn the_fault_resistance_counts_in_the_power_balance() {
    let mut g = thevenin();
    g.set_fault(Some(at_pcc(0.05, 0.05, 0.1, 0.15))).unwrap();
    run_to(&mut g, 0.2, 0.01);
    let o = g.outputs();
    let p_fault = 0.05 * o.fault.i * o.fault.i;
    println!(
        "in the fault: {p_fault:.4} pu in its resistance, mismatch {:.1e} pu",
        o.balance_p
    );
    assert!(p_fault > 0.5 && o.balance_p.abs() < 1e-8, "{o:?}");
}

/// A fault set for after the run, or none, changes nothing: the outputs are the same bits.
#[test]
fn a_grid_without_a_fault_in_its_run_is_unchanged() {
    let case = Case::builtin("thevenin_dvpp").unwrap();
    let run = |fault: Option<BusFault>| -> Outputs {
        let mut g = Grid::new(&case).unwrap();
        g.set_fault(fault).unwrap();
        run_to(&mut g, 1.5, 0.01);
        g.outputs()
    };
    let plain = run(None);
    let mut later = run(Some(at_pcc(0.0, 0.05, 2.0, 0.1)));
    assert!(!later.fault.on && later.fault.v > 0.0);
    later.fault = Default::default();
    assert_eq!(plain, later);
}

/// The FMU refuses a fault at a bus the case lacks, naming `fault.bus`; negative impedances at
/// `fmi2Set*`, naming the parameter; a fault with no impedance at initialization.
#[test]
fn the_fmu_checks_the_fault_parameters_naming_them() {
    let config = "[model]\ncase = \"thevenin_dvpp\"\n";
    let mut h = Harness::<GridFmu>::from_toml(config);
    h.set("fault.bus", 7);
    h.setup_experiment(0.0, None);
    assert_eq!(h.enter_initialization_mode(), Status::Ok);
    assert_eq!(h.exit_initialization_mode(), Status::Error);
    assert!(
        h.logged(
            Status::Error,
            "parameter 'fault.bus': 7 is not a bus of case thevenin_dvpp"
        ),
        "{:?}",
        h.log()
    );
    for name in ["fault.R", "fault.X", "fault.duration"] {
        let mut h = Harness::<GridFmu>::from_toml(config);
        assert_eq!(h.try_set(name, -0.1), Status::Error, "{name}");
        assert!(h.logged(Status::Error, name), "{:?}", h.log());
    }
    let mut h = Harness::<GridFmu>::from_toml(config);
    h.set_all(&[("fault.R", 0.0), ("fault.X", 0.0)]);
    h.set("fault.bus", 2);
    h.setup_experiment(0.0, None);
    h.enter_initialization_mode();
    assert_eq!(h.exit_initialization_mode(), Status::Error);
    assert!(h.logged(Status::Error, "'fault.X'"), "{:?}", h.log());
}

/// Through the FMU: a fault configured by its parameters acts in its interval, and a state
/// saved during the fault and restored continues it bit for bit.
#[test]
fn the_fmu_applies_the_fault_and_restores_a_state_saved_in_it() {
    let mut h = Harness::<GridFmu>::from_toml("[model]\ncase = \"thevenin_dvpp\"\n");
    h.set("event[1].enabled", false);
    h.set("fault.bus", 2);
    h.set_all(&[
        ("fault.R", 0.01),
        ("fault.X", 0.08),
        ("fault.t", 0.05),
        ("fault.duration", 0.1),
    ]);
    assert_eq!(h.init(), Status::Ok, "{:?}", h.log());
    assert!(!h.get_bool("fault.on"));
    for _ in 0..10 {
        h.step(0.01);
    }
    assert!(h.get_bool("fault.on"));
    let (i, v) = (h.get("fault.i"), h.get("fault.v"));
    assert!(i > 5.0 && v < 0.75 && h.get("pcc.v") == v, "{i} {v}");
    let saved = h.get_fmu_state().unwrap();
    let bytes = h.serialize_fmu_state(&saved).unwrap();
    let run = |h: &mut Harness<GridFmu>| {
        for _ in 0..10 {
            h.step(0.01);
        }
        h.get_many(["fault.i", "pcc.v", "sg[1].omega"])
    };
    let first = run(&mut h);
    assert!(!h.get_bool("fault.on") && first[0] == 0.0);
    let restored = h.deserialize_fmu_state(&bytes).unwrap();
    assert_eq!(h.set_fmu_state(&restored), Status::Ok);
    assert!(h.get_bool("fault.on"));
    assert_eq!(run(&mut h), first);
}
