//! The operator's step logic driven in-process through the FMI call paths: dc gains, their
//! rate limit and delay, the desired aggregate response, and refused configurations and inputs.

use fmi_export::harness::Harness;
use fmi_export::instance::Phase;
use fmi_export::{Config, Status};
use operator_model::{Operator, OperatorConfig};

const DT: f64 = 1e-2;
const MU_P: [&str; 2] = ["der[1].mu_p", "der[2].mu_p"];
const MU_Q: [&str; 3] = ["der[1].mu_q", "der[2].mu_q", "der[3].mu_q"];

/// The case-study operator (wind, PV low-pass; BESS complement) with `values` set, initialized.
fn operator(values: &[(&str, f64)]) -> Harness<Operator> {
    let mut h = Harness::<Operator>::new();
    h.set_all(values);
    assert_eq!(h.init(), Status::Ok, "{:#?}", h.log());
    h
}

fn close(actual: f64, expected: f64, tol: f64, what: impl std::fmt::Display) {
    assert!(
        (actual - expected).abs() <= tol,
        "{what}: {actual} vs {expected} (difference {:.3e})",
        actual - expected
    );
}

/// Σ μ_p = Σ μ_q = 1, every gain in [0, 1], the complement receives the low-pass gains.
fn assert_participation(h: &mut Harness<Operator>, when: impl std::fmt::Display) {
    let p = h.get_many(MU_P);
    let q = h.get_many(MU_Q);
    for mu in p.iter().chain(&q) {
        assert!((0.0..=1.0).contains(mu), "{when}: gain {mu}");
    }
    close(p.iter().sum(), 1.0, 1e-12, format_args!("{when}: Σ μ_p"));
    close(q.iter().sum(), 1.0, 1e-12, format_args!("{when}: Σ μ_q"));
    assert_eq!(
        h.get_many(["der[3].mu_p_lpf[1]", "der[3].mu_p_lpf[2]"]),
        p,
        "{when}: the complement's gains"
    );
    let [sum_p, sum_q] = h.get_many(["check.sum_mu_p", "check.sum_mu_q"]);
    close(sum_p, 1.0, 1e-12, format_args!("{when}: check.sum_mu_p"));
    close(sum_q, 1.0, 1e-12, format_args!("{when}: check.sum_mu_q"));
}

#[test]
fn the_dc_gains_sum_to_one_at_every_step_while_the_inputs_move() {
    let mut h = operator(&[("rate_limit", 0.8), ("delay", 0.03)]);
    assert_participation(&mut h, "initialization");
    // Availabilities and outputs wander (a fixed pseudo-random sequence), sometimes to zero.
    let mut x: u64 = 0x2545_f491_4f6c_dd1d;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut moved = 0.0_f64;
    let first = h.get_many(MU_P);
    for k in 0..500 {
        if k % 7 == 0 {
            let zero = next() < 0.1;
            let avail = [0.5 * next(), if zero { 0.0 } else { 0.7 * next() }];
            h.set("der[1].P_avail", avail[0]);
            h.set("der[2].P_avail", avail[1]);
            for j in 1..=3 {
                h.set(&format!("der[{j}].p"), 0.5 * next());
            }
        }
        let status = h.do_step(h.time(), DT);
        assert!(status <= Status::Warning, "{status:?}: {:#?}", h.log());
        assert_participation(&mut h, format_args!("step {k}"));
        moved = moved.max((h.get("der[1].mu_p") - first[0]).abs());
    }
    assert!(moved > 0.1, "the gains hardly moved: {moved}");
}

#[test]
fn an_availability_drop_shifts_the_unit_s_gain_to_the_others() {
    let mut h = operator(&[
        ("der[1].P_avail", 0.40),
        ("der[2].P_avail", 0.60),
        ("der[1].p", 0.30),
        ("der[2].p", 0.50),
    ]);
    let [wind, pv] = h.get_many(MU_P);
    close(wind, 0.4, 1e-12, "wind before");
    close(pv, 0.6, 1e-12, "pv before");
    h.step(DT);
    // A cloud: the PV's availability and output fall; the next step moves its share to wind.
    h.set("der[2].P_avail", 0.2);
    h.set("der[2].p", 0.15);
    h.step(DT);
    let [wind, pv] = h.get_many(MU_P);
    close(wind, 0.4 / 0.6, 1e-12, "wind after");
    close(pv, 0.2 / 0.6, 1e-12, "pv after");
    // Reactive gains follow the PQ headroom sqrt(S² - P²) of every unit (MVA, MW).
    let [s1, s2, s3] = h.get_many(["der[1].S_rated", "der[2].S_rated", "der[3].S_rated"]);
    let headroom = [
        (s1 * s1 - dvpp_math::powi(30.0f64, 2)).sqrt(),
        (s2 * s2 - dvpp_math::powi(15.0f64, 2)).sqrt(),
        s3,
    ];
    let total: f64 = headroom.iter().sum();
    let q = h.get_many(MU_Q);
    for (k, (mu, c)) in q.iter().zip(headroom).enumerate() {
        close(*mu, c / total, 1e-12, format_args!("mu_q of DER {}", k + 1));
    }
    assert!(h.warnings().is_empty(), "{:?}", h.warnings());
}

#[test]
fn a_grid_forming_unit_without_availability_keeps_the_floor() {
    let mu_min = 0.1;
    let mut h = operator(&[
        ("mu_min", mu_min),
        ("der[1].P_avail", 0.4),
        ("der[2].P_avail", 0.6),
    ]);
    h.set("der[2].P_avail", 0.0);
    h.step(DT);
    let [wind, pv] = h.get_many(MU_P);
    close(pv, mu_min, 1e-15, "pv at the floor");
    close(wind, 1.0 - mu_min, 1e-15, "wind takes the rest");
    assert_participation(&mut h, "at the floor");
    assert!(h.warnings().is_empty(), "{:?}", h.warnings());
}

#[test]
fn the_rate_limit_bounds_every_change_and_reaches_the_target_in_change_over_rate() {
    let (rate, dt) = (0.5, 1e-3);
    let mut h = operator(&[
        ("rate_limit", rate),
        ("der[1].P_avail", 0.5),
        ("der[2].P_avail", 0.5),
    ]);
    h.set("der[2].P_avail", 0.05);
    let target = 0.5 / 0.55;
    let change = target - 0.5;
    let mut previous = h.get_many(MU_P);
    let mut reached = None;
    for _ in 0..1000 {
        h.step(dt);
        let mu = h.get_many(MU_P);
        let largest = (mu[0] - previous[0]).abs().max((mu[1] - previous[1]).abs());
        assert!(
            largest <= rate * dt * (1.0 + 1e-12),
            "a gain moved {largest}"
        );
        let t = h.time();
        assert_participation(&mut h, format_args!("t = {t}"));
        if reached.is_none() && (mu[0] - target).abs() < 1e-12 {
            reached = Some(h.time());
        }
        previous = mu;
    }
    let reached = reached.expect("the target was reached");
    let expected = (change / (rate * dt)).ceil() * dt;
    close(reached, expected, 1e-9, "time to reach the target");
}

#[test]
fn the_delay_holds_the_gains_for_exactly_the_delay() {
    let (delay, dt) = (0.05, 1e-3);
    let mut h = operator(&[
        ("delay", delay),
        ("der[1].P_avail", 0.5),
        ("der[2].P_avail", 0.5),
    ]);
    for _ in 0..10 {
        h.step(dt);
    }
    let changed_at = h.time();
    h.set("der[2].P_avail", 0.25);
    let mut moved = None;
    for _ in 0..200 {
        h.step(dt);
        let wind = h.get("der[1].mu_p");
        if moved.is_none() && wind != 0.5 {
            moved = Some(h.time());
            // No rate limit: the delayed target arrives whole.
            close(wind, 0.5 / 0.75, 1e-12, "wind after the delay");
        }
    }
    let moved = moved.expect("the gains moved");
    // The input set at `changed_at` is sampled by the step ending at changed_at + dt.
    close(moved, changed_at + dt + delay, 1e-9, "first move");
}

#[test]
fn ref_df_follows_t_pf_applied_to_the_pcc_power_change() {
    // Parameters away from the defaults, so the response shows which ones are used.
    let (hh, d, dq) = (3.0, 20.0, 0.02);
    let mut h = operator(&[
        ("Tdes.H", hh),
        ("Tdes.D", d),
        ("Tdes.Dq", dq),
        ("S_dvpp", 80.0),
        ("pcc.p", 0.5),
        ("pcc.q", 0.1),
    ]);
    h.step(DT);
    close(h.get("ref.df"), 0.0, 0.0, "no change, no response");
    let t0 = h.time();
    h.set("pcc.p", 0.7);
    h.set("pcc.q", 0.05);
    h.set("pcc.f", 0.9995);
    let dp = 0.2 * 100.0 / 80.0;
    for _ in 0..300 {
        h.step(DT);
        let t = h.time() - t0;
        let [ref_df, ref_dv, err_df] = h.get_many(["ref.df", "ref.dv", "err.df"]);
        let expected = -dp / d * (1.0 - dvpp_math::exp(-d * t / hh));
        close(ref_df, expected, 1e-12, format_args!("ref.df at t = {t}"));
        close(ref_dv, dq * 0.05 * 100.0 / 80.0, 1e-15, "ref.dv");
        close(err_df, -0.0005 - ref_df, 1e-15, "err.df");
    }
}

#[test]
fn a_lowered_set_point_is_the_same_disturbance_as_a_pcc_power_increase() {
    // Two operators at the same point: one sees the PCC power rise by 0.28 pu, the other sees
    // the PV's set point fall by 0.28 pu (a cloud) with the PCC power unchanged.
    let start = [
        ("pcc.p", 0.6),
        ("der[1].p_set", 0.2),
        ("der[2].p_set", 0.3),
        ("der[3].p_set", 0.1),
    ];
    let (mut load, mut cloud) = (operator(&start), operator(&start));
    load.step(DT);
    cloud.step(DT);
    load.set("pcc.p", 0.88);
    cloud.set("der[2].p_set", 0.02);
    for _ in 0..200 {
        load.step(DT);
        cloud.step(DT);
        let (a, b) = (load.get("ref.df"), cloud.get("ref.df"));
        assert!(a < 0.0, "a deficit lowers the desired frequency: {a}");
        close(b, a, 1e-15, format_args!("ref.df at t = {}", cloud.time()));
    }
    // A set point and the PCC power that move together are no disturbance at all.
    let mut both = operator(&start);
    both.step(DT);
    both.set("pcc.p", 0.32);
    both.set("der[2].p_set", 0.02);
    for _ in 0..50 {
        both.step(DT);
        close(both.get("ref.df"), 0.0, 1e-15, "ref.df");
    }
}

#[test]
fn a_unit_hovering_at_its_rating_is_one_warning_not_one_per_crossing() {
    // The wind's rating is 46 MVA on a 100 MVA base: 0.46 pu.
    let mut h = operator(&[]);
    h.set_debug_logging(true, &[]);
    // A warning makes the step return fmi2Warning, which is fine here.
    let step = |h: &mut Harness<Operator>| {
        let t = h.time();
        let s = h.do_step(t, DT);
        assert!(s <= Status::Warning, "{s:?} at t = {t}: {:?}", h.log());
    };
    for k in 0..400 {
        let wobble = if k % 2 == 0 { 0.005 } else { -0.005 };
        h.set("der[1].p", 0.46 + wobble);
        step(&mut h);
    }
    assert_eq!(h.warnings().len(), 1, "{:?}", h.warnings());
    assert!(h.warnings()[0].contains("exceeds its rating"));
    // Back below the rating by the margin: the episode ends after a second there.
    h.set("der[1].p", 0.40);
    for _ in 0..99 {
        step(&mut h);
    }
    assert!(!h.logged(Status::Ok, "DER 1 is back within its rating"));
    for _ in 0..3 {
        step(&mut h);
    }
    assert!(
        h.logged(Status::Ok, "DER 1 is back within its rating"),
        "{:?}",
        h.log()
    );
    h.set("der[1].p", 0.50);
    step(&mut h);
    assert_eq!(h.warnings().len(), 2, "a new episode is warned again");
}

#[test]
fn a_split_unit_shares_its_availability_by_its_parts() {
    // A hybrid DVPP: unit A split into a grid-forming part (ε = 0.3) and a grid-following one.
    let config = r#"
        [[model.ders]]
        name = "a-gfm"
        role = "low_pass"
        form = "grid_forming"
        s_rated = 50.0
        share = 0.3

        [[model.ders]]
        name = "a-gfl"
        role = "low_pass"
        form = "grid_following"
        s_rated = 50.0
        share = 0.7

        [[model.ders]]
        name = "b"
        role = "low_pass"
        form = "grid_following"
        s_rated = 100.0
    "#;
    let mut h = Harness::<Operator>::from_toml(config);
    for k in 1..=3 {
        h.set(&format!("der[{k}].P_avail"), 0.4);
    }
    h.set("der[3].p", 0.6);
    assert_eq!(h.init(), Status::Ok);
    let mu = h.get_many(["der[1].mu_p", "der[2].mu_p", "der[3].mu_p"]);
    for (k, expected) in [0.15, 0.35, 0.5].into_iter().enumerate() {
        close(
            mu[k],
            expected,
            1e-12,
            format_args!("mu_p of DER {}", k + 1),
        );
    }
    // Ratings scale by share too: headroom 15, 35 and sqrt(100² - 60²) = 80 MVA.
    let q = h.get_many(["der[1].mu_q", "der[2].mu_q", "der[3].mu_q"]);
    for (k, expected) in [15.0 / 130.0, 35.0 / 130.0, 80.0 / 130.0]
        .into_iter()
        .enumerate()
    {
        close(q[k], expected, 1e-12, format_args!("mu_q of DER {}", k + 1));
    }
}

#[test]
fn bad_configurations_parameters_and_inputs_are_refused() {
    // A DVPP without a low-pass unit cannot carry the steady state: no instance.
    let mut config = Config::<OperatorConfig>::default();
    config.model.ders.retain(|d| d.name == "bess");
    let log = match Harness::<Operator>::try_with_config(config, false) {
        Ok(_) => panic!("instantiated without a low-pass unit"),
        Err(log) => log,
    };
    assert!(
        log.iter()
            .any(|r| r.status == Status::Error && r.message.contains("no low-pass unit")),
        "{log:#?}"
    );
    // A negative delay fails initialization naming the parameter; a reset recovers.
    let mut h = Harness::<Operator>::new();
    h.set("delay", -0.1);
    assert_eq!(h.setup_experiment(0.0, None), Status::Ok);
    assert_eq!(h.enter_initialization_mode(), Status::Ok);
    assert_eq!(h.exit_initialization_mode(), Status::Error);
    assert!(h.logged(Status::Error, "'delay'"), "{:#?}", h.log());
    assert_eq!(h.reset(), Status::Ok);
    h.init();
    // A NaN availability is refused and the gains stay as they were.
    h.step(DT);
    let before = h.instance().core.store.clone();
    assert_eq!(h.try_set("der[1].P_avail", f64::NAN), Status::Error);
    assert!(h.logged(Status::Error, "'der[1].P_avail' is not finite"));
    assert_eq!(h.instance().core.store, before);
    assert_eq!(h.phase(), Phase::Error);
    assert_participation(&mut h, "after the refusal");
}

/// The case-study operator with `n` POCs and `rot.rx` = `rx`, `values` set, initialized.
fn operator_with_pocs(n: usize, rx: f64, values: &[(&str, f64)]) -> Harness<Operator> {
    let mut config = Config::<OperatorConfig>::default();
    config.model.pocs = n;
    config.model.rot_rx = rx;
    let mut h = Harness::<Operator>::with_config(config);
    h.set_all(values);
    assert_eq!(h.init(), Status::Ok, "{:#?}", h.log());
    h
}

#[test]
fn with_pocs_ref_df_follows_t_pf_applied_to_the_summed_rotated_poc_power_change() {
    let (hh, d) = (5.55, 33.33);
    for rx in [0.0, 1.0, 0.5] {
        let start = [
            ("poc[1].p", 0.3),
            ("poc[1].q", -0.1),
            ("poc[2].p", 0.2),
            ("poc[2].q", 0.05),
            // The PCC moves too: with POCs it is not what ref.df is matched at.
            ("pcc.p", 0.5),
        ];
        let mut h = operator_with_pocs(2, rx, &start);
        assert_eq!(h.get("rot.rx"), rx);
        h.step(DT);
        close(h.get("ref.df"), 0.0, 0.0, "no change, no response");
        let t0 = h.time();
        let (dp, dq) = ([0.08, 0.05], [0.03, -0.02]);
        h.set("poc[1].p", 0.3 + dp[0]);
        h.set("poc[1].q", -0.1 + dq[0]);
        h.set("poc[2].p", 0.2 + dp[1]);
        h.set("poc[2].q", 0.05 + dq[1]);
        h.set("pcc.p", 0.9);
        h.set("poc[1].f", 0.9996);
        h.set("poc[2].f", 0.9997);
        // p' = (p - rx q)/sqrt(1 + rx²), summed over the POCs, on S_dvpp = 96 MVA.
        let rotated: f64 = (0..2)
            .map(|k| (dp[k] - rx * dq[k]) / dvpp_math::hypot(rx, 1.0))
            .sum::<f64>()
            * 100.0
            / 96.0;
        for _ in 0..200 {
            h.step(DT);
            let t = h.time() - t0;
            let [ref_df, poc_dp, e1, e2] =
                h.get_many(["ref.df", "poc.dp", "poc[1].err_df", "poc[2].err_df"]);
            close(poc_dp, rotated, 1e-14, format_args!("poc.dp, rx = {rx}"));
            let expected = -rotated / d * (1.0 - dvpp_math::exp(-d * t / hh));
            close(
                ref_df,
                expected,
                1e-12,
                format_args!("ref.df, rx = {rx}, t = {t}"),
            );
            close(e1, -0.0004 - ref_df, 1e-15, "poc[1].err_df");
            close(e2, -0.0003 - ref_df, 1e-15, "poc[2].err_df");
        }
    }
}

#[test]
fn with_pocs_a_set_point_change_is_rotated_like_the_units_set_point() {
    // A unit lowering its set point by 0.1 pu moves its p' by cos = 1/sqrt(2) of it at R/X = 1;
    // the POCs' p' moving by as much is no disturbance.
    let rx = 1.0;
    let start = [("der[2].p_set", 0.3), ("poc[1].p", 0.4)];
    let mut h = operator_with_pocs(2, rx, &start);
    h.step(DT);
    h.set("der[2].p_set", 0.2);
    // The area delivers 0.1 pu less through POC 1, its reactive power unchanged.
    h.set("poc[1].p", 0.3);
    for _ in 0..50 {
        h.step(DT);
        close(h.get("poc.dp"), 0.0, 1e-15, "poc.dp");
        close(h.get("ref.df"), 0.0, 1e-15, "ref.df");
    }
}

#[test]
fn a_rotation_without_pocs_and_a_bad_ratio_are_refused() {
    for (pocs, rx, needle) in [
        (0, 1.0, "pocs = 0"),
        (2, -1.0, "rot_rx"),
        (operator_model::MAX_POCS + 1, 0.0, "points of coupling"),
    ] {
        let mut config = Config::<OperatorConfig>::default();
        config.model.pocs = pocs;
        config.model.rot_rx = rx;
        match Harness::<Operator>::try_with_config(config, false) {
            Ok(_) => panic!("instantiated with pocs = {pocs}, rot_rx = {rx}"),
            Err(log) => assert!(
                log.iter()
                    .any(|r| r.status == Status::Error && r.message.contains(needle)),
                "{log:#?}"
            ),
        }
    }
}

#[test]
fn a_subnormal_inertia_is_refused_by_name() {
    let mut h = Harness::<Operator>::new();
    assert_eq!(h.try_set("Tdes.H", 4.9e-324), Status::Error);
    assert!(
        h.logged(Status::Error, "for parameter 'Tdes.H' is subnormal"),
        "{:#?}",
        h.log()
    );
}

#[test]
fn a_degenerate_input_during_initialization_is_warned_once() {
    let mut h = Harness::<Operator>::new();
    h.set("der[1].P_avail", -0.1);
    assert_eq!(h.enter_initialization_mode(), Status::Ok);
    // Initialization runs again for every value set in initialization mode.
    h.set("der[2].P_avail", 0.3);
    let _ = h.get("der[1].mu_p");
    h.set("der[2].P_avail", 0.31);
    let _ = h.get("der[1].mu_p");
    assert!(h.exit_initialization_mode() <= Status::Warning);
    let warned: Vec<_> = h
        .warnings()
        .into_iter()
        .filter(|w| w.contains("negative available power"))
        .collect();
    assert_eq!(warned.len(), 1, "{warned:?}");
}
