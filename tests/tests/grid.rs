//! End-to-end tests of the grid FMU (`dvpp_grid` and its variants) through its C API: initial
//! outputs, flat start, the 28 MW load step on the IEEE 9-bus system, power balance, no direct
//! feedthrough, and bad case files refused by `fmi2Instantiate` with the problem named.

use dvpp_cosim::{Fmu, Instance, Status};
use dvpp_e2e::*;
use std::path::PathBuf;
use std::sync::Arc;

/// A bundled grid variant, `dist/variants/dvpp_grid-<name>.fmu`.
fn variant(name: &str) -> Arc<Fmu> {
    let p = dist()
        .parent()
        .expect("dist has a parent")
        .join("variants")
        .join(format!("dvpp_grid-{name}.fmu"));
    assert!(
        p.is_file(),
        "{} is missing: run `cargo xtask bundle`",
        p.display()
    );
    Arc::new(Fmu::load(&p).unwrap_or_else(|e| panic!("{e}")))
}

/// The case the grid FMU was built from (its `resources/config.toml`).
fn case_of(fmu: &Fmu) -> grid_model::case::Case {
    let resources = fmu.dir.join("resources");
    fmi_export::Config::<grid_model::GridConfig>::load(&resources)
        .and_then(|c| c.model.load_case(Some(&resources)))
        .unwrap_or_else(|e| panic!("{}: {e}", fmu.description.model_name))
}

/// Value references of `<group>[k].<port>` for k = 1 … `n` (the count the case gives), checked
/// to be all there and no more: a renamed port fails here instead of giving a short or empty list.
fn indexed(fmu: &Fmu, group: &str, port: &str, n: usize) -> Vec<u32> {
    let name = |k: usize| format!("{group}[{k}].{port}");
    assert!(
        fmu.vr(&name(n + 1)).is_err(),
        "the case has {n} {group}[k] but the FMU has {}",
        name(n + 1)
    );
    (1..=n)
        .map(|k| {
            fmu.vr(&name(k))
                .unwrap_or_else(|e| panic!("{} of {n} is missing: {e}", name(k)))
        })
        .collect()
}

fn get(i: &mut Instance, vrs: &[u32]) -> Vec<f64> {
    let mut out = vec![0.0; vrs.len()];
    assert_eq!(
        i.get_real(vrs, &mut out),
        Status::Ok,
        "{:?}",
        i.last_message()
    );
    out
}

/// Instantiate with every scheduled event switched `on` or off, and enter initialization mode.
fn in_init_mode(fmu: &Arc<Fmu>, name: &str, events_on: bool) -> Instance {
    let mut i = fmu.instantiate(name).unwrap_or_else(|e| panic!("{e}"));
    let enabled = indexed(fmu, "event", "enabled", case_of(fmu).events.len());
    assert_eq!(
        i.set_boolean(&enabled, &vec![events_on; enabled.len()]),
        Status::Ok
    );
    assert_eq!(i.setup_experiment(0.0, None), Status::Ok);
    assert_eq!(i.enter_initialization_mode(), Status::Ok);
    i
}

#[test]
fn initial_outputs_are_the_power_flow_point_and_depend_on_no_input() {
    let fmu = load("dvpp_grid");
    let mut i = in_init_mode(&fmu, "init", true);
    let vr = |n: &str| fmu.vr(n).unwrap();
    let names = [
        "der[1].p", "der[2].p", "der[3].p", "pcc.p", "der[1].v", "pcc.v", "pcc.f", "coi.f",
    ];
    let vrs: Vec<u32> = names.iter().map(|n| vr(n)).collect();
    let init = get(&mut i, &vrs);
    // ieee9_dvpp dispatch: wind 31.5 MW, PV 50 MW, BESS 0 at bus 2 (PV bus, 1.025 pu).
    let expected = [0.315, 0.5, 0.0, 0.815, 1.025, 1.025, 1.0, 1.0];
    for ((n, x), e) in names.iter().zip(&init).zip(expected) {
        assert!((x - e).abs() < 1e-9, "{n} = {x}, expected {e}");
    }
    let angle = get(&mut i, &[vr("der[1].v_angle")])[0].to_degrees();
    // The power flow of ieee9_dvpp (SG3 at 48 MW, SG1 the slack): grid-model's own figure.
    assert!((angle - -6.271).abs() < 1e-3, "bus 2 angle {angle} deg");
    // Changing an input in initialization mode leaves the initial outputs alone ...
    let theta = vr("der[1].theta");
    let th0 = get(&mut i, &[theta])[0];
    assert_eq!(i.set_real(&[theta], &[th0 + 0.02]), Status::Ok);
    assert_eq!(get(&mut i, &vrs), init);
    assert_eq!(i.exit_initialization_mode(), Status::Ok);
    assert_eq!(get(&mut i, &vrs), init);
    // ... and in step mode an input acts through the next step only (no direct feedthrough).
    assert_eq!(i.do_step(0.0, 1e-3), Status::Ok);
    let p1 = get(&mut i, &[vr("der[1].p")])[0];
    assert!(p1 > 0.315 + 0.01, "der[1].p after the step {p1}");
    assert_eq!(i.set_real(&[theta], &[th0]), Status::Ok);
    assert_eq!(get(&mut i, &[vr("der[1].p")])[0], p1);
}

/// 10 s with every event off and the inputs at their start values: every frequency stays within
/// 1e-6 pu of nominal and the power balance within 1e-6 pu, at every step.
fn flat_start(fmu: &Arc<Fmu>, label: &str) {
    let mut i = in_init_mode(fmu, label, false);
    assert_eq!(i.exit_initialization_mode(), Status::Ok);
    let mut freqs = vec![fmu.vr("coi.f").unwrap(), fmu.vr("pcc.f").unwrap()];
    let case = case_of(fmu);
    freqs.extend(indexed(fmu, "sg", "omega", case.machines.len()));
    let mismatch = fmu.vr("sys.p_mismatch").unwrap();
    let powers: Vec<u32> = (1..=case.ders.len())
        .map(|k| {
            fmu.vr(&grid_model::ports::der_p(k))
                .unwrap_or_else(|e| panic!("{label}: {e}"))
        })
        .collect();
    let p0 = get(&mut i, &powers);
    let (h, n) = (1e-3, 10_000);
    let (mut worst_f, mut worst_b) = (0.0f64, 0.0f64);
    for k in 0..n {
        assert_eq!(i.do_step(k as f64 * h, h), Status::Ok, "{label}");
        for f in get(&mut i, &freqs) {
            worst_f = worst_f.max((f - 1.0).abs());
        }
        worst_b = worst_b.max(get(&mut i, &[mismatch])[0].abs());
        assert!(
            worst_f < 1e-6 && worst_b < 1e-6,
            "{label} at t = {}: |f - 1| = {worst_f:e}, balance {worst_b:e}",
            (k + 1) as f64 * h
        );
    }
    for (a, b) in get(&mut i, &powers).iter().zip(&p0) {
        assert!((a - b).abs() < 1e-9, "{label}: slot power moved {b} -> {a}");
    }
    println!("{label}: flat start 10 s, max |f - 1| = {worst_f:.2e} pu, max |balance| = {worst_b:.2e} pu");
}

#[test]
fn flat_start_through_every_packaged_grid() {
    flat_start(&load("dvpp_grid"), "default (ieee9_dvpp)");
    for name in ["ieee9", "ieee9_hybrid", "ieee9_dvpp_file"] {
        flat_start(&variant(name), name);
    }
}

#[test]
fn a_case_file_variant_of_the_default_case_has_the_default_guid() {
    assert_eq!(
        variant("ieee9_dvpp_file").description.guid,
        load("dvpp_grid").description.guid
    );
}

#[test]
fn load_step_28_mw_at_bus_5_of_ieee9() {
    let fmu = variant("ieee9");
    let mut i = in_init_mode(&fmu, "load-step", true);
    let vr = |n: &str| fmu.vr(n).unwrap();
    assert_eq!(get(&mut i, &[vr("event[1].dP")])[0], 0.28);
    assert_eq!(i.exit_initialization_mode(), Status::Ok);
    let sg_p = indexed(&fmu, "sg", "p", 3);
    let (coi, mismatch) = (vr("coi.f"), vr("sys.p_mismatch"));
    let pe0: f64 = get(&mut i, &sg_p).iter().sum();
    let (h, t_event, t_end) = (0.01, 1.0, 300.0);
    let n = (t_end / h) as usize;
    let mut trace = vec![(0.0, 1.0)];
    let mut pe_after = None;
    let mut max_balance = 0.0f64;
    for k in 0..n {
        assert_eq!(i.do_step(k as f64 * h, h), Status::Ok);
        let t = (k + 1) as f64 * h;
        trace.push((t, get(&mut i, &[coi])[0]));
        max_balance = max_balance.max(get(&mut i, &[mismatch])[0].abs());
        if pe_after.is_none() && t > t_event + 1e-9 {
            pe_after = Some(get(&mut i, &sg_p).iter().sum::<f64>());
        }
    }
    let pe_end: f64 = get(&mut i, &sg_p).iter().sum();
    let f_at = |tq: f64| trace.iter().find(|(t, _)| *t >= tq - 1e-9).unwrap().1;
    let &(t_nadir, nadir) = trace.iter().min_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
    let f_settled = trace.last().unwrap().1;
    let df = f_settled - 1.0;
    let rocof_10ms = (f_at(t_event + 0.01) - f_at(t_event)) / 0.01;
    let rocof_100ms = (f_at(t_event + 0.1) - f_at(t_event)) / 0.1;
    // Swing equation right after the step: 2 ΣH dω/dt = -ΔPe(0+), ΣH on the system base.
    let case = case_of(&fmu);
    let on_system_base = |m: &grid_model::case::Machine, x: f64| match m.base {
        grid_model::case::ParamBase::Machine => x * m.rating_mva / case.base_mva,
        grid_model::case::ParamBase::System => x,
    };
    let sum_h: f64 = case.machines.iter().map(|m| on_system_base(m, m.h)).sum();
    let rocof_analytic = -(pe_after.unwrap() - pe0) / (2.0 * sum_h);
    let settling = trace
        .iter()
        .filter(|(t, f)| *t > t_event && ((f - 1.0) - df).abs() > 0.05 * df.abs())
        .map(|(t, _)| t - t_event)
        .fold(0.0, f64::max);
    // Droop: Σ (S_j / S_base) / R_j = (250 + 96 + 64) / 100 / 0.03, no damping (D = 0).
    let stiffness: f64 = case
        .machines
        .iter()
        .map(|m| m.rating_mva / case.base_mva / 0.03)
        .sum();
    let df_droop = -(pe_end - pe0) / stiffness;
    let droop_error = df / df_droop - 1.0;
    println!(
        "ieee9, 28 MW load step at bus 5, t = 1 s (COI frequency, 50 Hz), through the FMU:\n  \
         nadir {nadir:.6} pu ({:.1} mHz) at t = {t_nadir:.2} s\n  \
         RoCoF {:.4} Hz/s over 10 ms, {:.4} Hz/s over 100 ms (swing equation {:.4} Hz/s)\n  \
         settled {f_settled:.7} pu ({:.2} mHz), within 5 % after {settling:.1} s\n  \
         droop: machines picked up {:.4} pu -> analytic {df_droop:.6e} pu, simulated {df:.6e} \
         pu, error {:.3} %\n  max |generation - load - losses| {max_balance:.2e} pu",
        (nadir - 1.0) * 50e3,
        rocof_10ms * 50.0,
        rocof_100ms * 50.0,
        rocof_analytic * 50.0,
        df * 50e3,
        pe_end - pe0,
        100.0 * droop_error
    );
    assert!(max_balance < 1e-6, "power balance {max_balance:e}");
    assert!(nadir < f_settled && f_settled < 1.0);
    // The same step in the library, without the FMU around it: the same nadir.
    let standalone = grid_model::analysis::run_load_step(&case, 5, 28.0, t_event, 30.0, h)
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(
        (nadir - standalone.nadir).abs() < 1e-9,
        "nadir {nadir} (standalone model: {})",
        standalone.nadir
    );
    assert!(t_nadir > 2.0 && t_nadir < 5.0, "nadir at {t_nadir} s");
    assert!(
        (rocof_10ms / rocof_analytic - 1.0).abs() < 0.02,
        "RoCoF {rocof_10ms} vs {rocof_analytic}"
    );
    assert!(droop_error.abs() < 0.02, "droop error {droop_error}");
    // The machines pick up the step less the load relief of the constant-impedance loads.
    assert!((0.2..0.3).contains(&(pe_end - pe0)));
    assert!(settling > 10.0 && settling < 200.0, "settling {settling} s");
}

/// A copy of the default grid's resources with `config.toml` pointing at `case_file` holding
/// `text`; returns the directory.
fn resources_with_case(fmu: &Fmu, tag: &str, text: &str) -> PathBuf {
    // A fresh private directory (the caller removes it).
    let dir = dvpp_cosim::tmp::create_dir(&format!("grid-case-{tag}")).unwrap();
    for entry in std::fs::read_dir(fmu.dir.join("resources")).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), dir.join(entry.file_name())).unwrap();
    }
    std::fs::write(
        dir.join("config.toml"),
        "[model]\ncase_file = \"case.toml\"\n",
    )
    .unwrap();
    std::fs::write(dir.join("case.toml"), text).unwrap();
    dir
}

fn case_text(name: &str) -> String {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../fmu-grid/cases")
        .join(format!("{name}.toml"));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn edit(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "the case has no '{from}'");
    text.replacen(from, to, 1)
}

#[test]
fn bad_case_files_make_instantiate_return_null_naming_the_problem() {
    let fmu = load("dvpp_grid");
    let guid = fmu.description.guid.clone();
    let dvpp = case_text("ieee9_dvpp");
    let base = case_text("ieee9");
    let cases: Vec<(&str, String, &[&str])> = vec![
        (
            "missing bus",
            edit(&dvpp, "[[load]]\nbus = 5", "[[load]]\nbus = 55"),
            &["load 1 (bus 55) refers to bus 55, which is not defined"],
        ),
        (
            "zero impedance",
            edit(&dvpp, "r = 0.017\nx = 0.092", "r = 0.0\nx = 0.0"),
            &["line 1 (4-5)", "non-positive series impedance"],
        ),
        (
            "negative impedance",
            edit(&dvpp, "x = 0.0576", "x = -0.0576"),
            &["transformer 1 (1-4)", "non-positive series impedance"],
        ),
        (
            "negative slot impedance",
            edit(&dvpp, "\nx = 0.10\n", "\nx = -0.10\n"),
            &["der slot 1 (bus 2)", "non-positive series impedance"],
        ),
        (
            "islanded bus",
            edit(
                &dvpp,
                "[[bus]]\nid = 9",
                "[[bus]]\nid = 10\n[[bus]]\nid = 9",
            ),
            &["bus 10 is islanded"],
        ),
        (
            "unknown machine model",
            edit(&dvpp, "model = \"sub_transient\"", "model = \"six_order\""),
            &["six_order", "unknown variant"],
        ),
        (
            "unknown governor type",
            edit(&base, "type = \"tgov_reheat\"", "type = \"ieeeg1\""),
            &["ieeeg1"],
        ),
        (
            "unknown DER kind",
            edit(&dvpp, "kind = \"grid_forming\"", "kind = \"virtual_sync\""),
            &["virtual_sync"],
        ),
        (
            "parameter out of range",
            edit(&dvpp, "h = 6.5", "h = -1.0"),
            &["machine 1 (bus 1)", "`h` = -1", "out of range"],
        ),
        (
            "governor droop out of range",
            edit(&dvpp, "\nr = 0.03\n", "\nr = 1.5\n"),
            &["`governor.r` = 1.5", "out of range"],
        ),
        (
            "not TOML",
            "this is not a case".to_string(),
            &["case file case.toml", "could not be parsed"],
        ),
    ];
    for (what, text, needles) in cases {
        let dir = resources_with_case(&fmu, &what.replace(' ', "-"), &text);
        let uri = format!("file://{}", dir.display());
        let e = match fmu.instantiate_with(what, &guid, &uri, 1) {
            Ok(_) => panic!("{what}: the bad case was instantiated"),
            Err(e) => e.0,
        };
        assert!(e.contains("returned NULL"), "{what}: {e}");
        // The case is checked in `declare`, before the GUID: the log line names the problem.
        assert!(!e.contains("GUID"), "{what}: {e}");
        assert!(e.contains("case file case.toml"), "{what}: {e}");
        for needle in needles {
            assert!(e.contains(needle), "{what}: '{needle}' not in: {e}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
    // Controls: the default case from a file is the default FMU (same GUID); a different valid
    // case passes `declare` and is then refused by the GUID check.
    let dir = resources_with_case(&fmu, "good", &dvpp);
    let uri = format!("file://{}", dir.display());
    assert!(fmu.instantiate_with("good", &guid, &uri, 1).is_ok());
    std::fs::write(dir.join("case.toml"), &base).unwrap();
    let e = fmu
        .instantiate_with("other-case", &guid, &uri, 1)
        .err()
        .unwrap();
    assert!(e.0.contains("GUID mismatch"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn event_parameters_move_and_resize_the_load_step() {
    let fmu = load("dvpp_grid");
    let vr = |n: &str| fmu.vr(n).unwrap();
    let pcc = vr("pcc.p");
    let run_with = |time: f64, dp: f64| -> Vec<f64> {
        let mut i = fmu.instantiate("event").unwrap();
        assert_eq!(
            i.set_real(&[vr("event[1].time"), vr("event[1].dP")], &[time, dp]),
            Status::Ok
        );
        assert_eq!(i.setup_experiment(0.0, None), Status::Ok);
        assert_eq!(i.enter_initialization_mode(), Status::Ok);
        assert_eq!(i.exit_initialization_mode(), Status::Ok);
        run(&mut i, &[pcc], 0.0, 0.01, 100)
            .into_iter()
            .map(|o| o[0])
            .collect()
    };
    let p0 = 0.815;
    let early = run_with(0.3, 0.1);
    // Nothing moves before the event; afterwards the grid-forming slots pick up most of it.
    assert!(early[..29].iter().all(|p| (p - p0).abs() < 1e-9));
    assert!(
        early[30] - p0 > 0.05 && early[30] - p0 < 0.1,
        "{}",
        early[30]
    );
    let bigger = run_with(0.3, 0.2);
    assert!(bigger[30] - p0 > 1.8 * (early[30] - p0));
}
