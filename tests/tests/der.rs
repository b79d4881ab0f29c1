//! The bundled DER FMU as a master drives it: bad parameters fail initialization and name the
//! parameter; the case-study variants initialize flat and keep their state across save/restore.

use dvpp_cosim::{Fmu, Instance, Status};
use dvpp_e2e::*;
use model_description::BaseType;
use std::sync::Arc;

fn load_path(path: std::path::PathBuf) -> Arc<Fmu> {
    assert!(
        path.is_file(),
        "{} is missing: run `cargo xtask bundle`",
        path.display()
    );
    Arc::new(Fmu::load(&path).unwrap_or_else(|e| panic!("{e}")))
}

fn variant(name: &str) -> Arc<Fmu> {
    load_path(
        dist()
            .join("../variants")
            .join(format!("dvpp_der-{name}.fmu")),
    )
}

/// Set parameters by name (Integer or Real as declared); each set must succeed.
fn set(fmu: &Fmu, i: &mut Instance, values: &[(&str, f64)]) {
    for (name, x) in values {
        let var = fmu
            .description
            .variable(name)
            .unwrap_or_else(|| panic!("no variable {name}"));
        let vr = [var.value_reference];
        let s = match var.base_type() {
            BaseType::Integer => i.set_integer(&vr, &[*x as i32]),
            _ => i.set_real(&vr, &[*x]),
        };
        assert_eq!(s, Status::Ok, "setting {name}: {:?}", i.last_message());
    }
}

fn logged(i: &Instance, needle: &str) -> bool {
    i.log().iter().any(|r| r.message.contains(needle))
}

/// A bad configuration: what it is, the parameters set, the name the log must show.
type BadCase<'a> = (&'a str, &'a [(&'a str, f64)], &'a str);

#[test]
fn bad_parameters_fail_initialization_and_name_the_parameter() {
    let fmu = load("dvpp_der");
    let cases: &[BadCase] = &[
        (
            "zero time constant",
            &[("adpf.p.kind", 1.0), ("adpf.p.tau", 0.0)],
            "'adpf.p.tau'",
        ),
        (
            "improper grid-forming reference (T_pf/m with m of order 2)",
            &[("adpf.p.kind", 1.0), ("adpf.p.order", 2.0)],
            "'adpf.p.order'",
        ),
        (
            "improper grid-following reference (no PLL roll-off)",
            &[("mode", 2.0), ("pll.order", 0.0)],
            "'pll.order'",
        ),
        ("unstable T_des (D = 0)", &[("Tdes.D", 0.0)], "'Tdes.D'"),
        (
            "band-pass with tau2 >= tau",
            &[
                ("adpf.p.kind", 3.0),
                ("adpf.p.tau", 0.5),
                ("adpf.p.tau2", 0.5),
            ],
            "'adpf.p.tau2'",
        ),
        (
            "complement gains above its share",
            &[
                ("adpf.p.kind", 4.0),
                ("adpf.p.n_lpf", 2.0),
                ("mu_p_lpf[1]", 0.7),
                ("mu_p_lpf[2]", 0.6),
            ],
            "'mu_p_lpf'",
        ),
        ("zero dc time constant", &[("tau_dc", 0.0)], "'tau_dc'"),
        ("zero q roll-off", &[("Tdes.tau_q", 0.0)], "'Tdes.tau_q'"),
    ];
    for (what, params, name) in cases {
        let mut i = fmu.instantiate(what).unwrap();
        assert_eq!(i.setup_experiment(0.0, None), Status::Ok);
        set(&fmu, &mut i, params);
        assert_eq!(i.enter_initialization_mode(), Status::Ok);
        assert_eq!(i.exit_initialization_mode(), Status::Error, "{what}");
        assert!(
            logged(&i, name) && logged(&i, "initialization failed"),
            "{what}: expected {name} in {:#?}",
            i.log().iter().map(|r| &r.message).collect::<Vec<_>>()
        );
        // The instance recovers with a reset and initializes with the declared values.
        assert_eq!(i.reset(), Status::Ok);
        assert_eq!(i.setup_experiment(0.0, None), Status::Ok);
        assert_eq!(i.enter_initialization_mode(), Status::Ok);
        assert_eq!(
            i.exit_initialization_mode(),
            Status::Ok,
            "{what}: after reset"
        );
    }
    // Gains outside [0, 1] are refused when set (their range is declared), naming the input.
    let mut i = fmu.instantiate("mu-range").unwrap();
    let mu = fmu.vr("mu_p").unwrap();
    assert_eq!(i.set_real(&[mu], &[1.5]), Status::Error);
    assert!(logged(&i, "'mu_p'"));
}

#[test]
fn variants_start_flat_and_restore_their_state() {
    for (name, mode) in [("wind", 1.0), ("pv", 2.0), ("bess", 1.0), ("bess", 2.0)] {
        let fmu = variant(name);
        let mut i = fmu.instantiate(name).unwrap();
        assert_eq!(i.setup_experiment(0.0, None), Status::Ok);
        // Driven open loop (the bus does not answer the unit's angle): limits lifted.
        let open_loop = [("I_max", 1e9), ("dc.t_budget", 1e-9), ("E_max", 1e9)];
        set(&fmu, &mut i, &[("mode", mode)]);
        set(&fmu, &mut i, &open_loop);
        assert_eq!(i.enter_initialization_mode(), Status::Ok);
        assert_eq!(i.exit_initialization_mode(), Status::Ok);
        // Inputs at their start values: nothing moves (but the energy counters, which integrate).
        let energy: Vec<u32> = ["energy.source", "energy.ac", "energy.loss"]
            .iter()
            .map(|n| fmu.vr(n).unwrap())
            .collect();
        let outs: Vec<u32> = real_outputs(&fmu)
            .into_iter()
            .filter(|vr| !energy.contains(vr))
            .collect();
        let mut first = vec![0.0; outs.len()];
        assert_eq!(i.get_real(&outs, &mut first), Status::Ok);
        let flat = run(&mut i, &outs, 0.0, 1e-3, 200);
        for row in &flat {
            for (a, b) in row.iter().zip(&first) {
                assert!((a - b).abs() < 1e-12, "{name} mode {mode}: {a} vs {b}");
            }
        }
        // A power step and moving gains, then a saved state continues identically.
        let (p, lpf1) = (fmu.vr("p").unwrap(), fmu.vr("mu_p_lpf[1]").unwrap());
        let (v_angle, lpf2) = (fmu.vr("v_angle").unwrap(), fmu.vr("mu_p_lpf[2]").unwrap());
        let mut x = [0.0];
        i.get_real(&[p], &mut x);
        assert_eq!(i.set_real(&[p, v_angle], &[x[0] + 0.01, -1e-3]), Status::Ok);
        let mut t = 0.2;
        for k in 0..300 {
            let mu = 0.3 + 0.2 * k as f64 / 300.0;
            assert_eq!(i.set_real(&[lpf1, lpf2], &[mu, 1.0 - mu]), Status::Ok);
            let s = i.do_step(t, 1e-3);
            assert_eq!(s, Status::Ok, "{name} mode {mode}: {:?}", i.last_message());
            t += 1e-3;
        }
        let (_, saved) = i.get_state();
        let saved = saved.unwrap();
        let bytes = i.serialize_state(&saved).unwrap();
        let expected = run(&mut i, &outs, t, 1e-3, 300);
        let mut j = fmu.instantiate("restored").unwrap();
        let (st, restored) = j.deserialize_state(&bytes);
        assert_eq!(st, Status::Ok);
        assert_eq!(j.set_state(&restored.unwrap()), Status::Ok);
        assert_eq!(
            run(&mut j, &outs, t, 1e-3, 300),
            expected,
            "{name} mode {mode}"
        );
    }
}
