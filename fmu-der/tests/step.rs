//! The DER's step logic driven in-process through the FMI call paths: responses against the
//! analytic reference models, the dc side, limits, and refused parameters and inputs.

use der_model::Der;
use fmi_export::harness::Harness;
use fmi_export::instance::Phase;
use fmi_export::Status;
use std::f64::consts::PI;

const H: f64 = 5.55;
const D: f64 = 33.33;
const F_NOM: f64 = 50.0;
/// `S_base / S_dvpp`: a power change on S_base seen on the DVPP base.
const TO_DVPP: f64 = 100.0 / 96.0;
const DT: f64 = 1e-3;

/// Limits lifted for a unit driven open loop, and its delay compensation off: it adds the
/// change its last angle move will make in the measured power, which a bus that does not answer
/// the angle never shows.
const OPEN_LOOP: [(&str, f64); 4] = [
    ("I_max", 1e9),
    ("dc.t_budget", 1e-9),
    ("E_max", 1e9),
    ("delay.c", 0.0),
];

/// The generic unit (grid-forming, static ADPF) with `params` set, initialized. These tests
/// drive the unit open loop (the bus does not answer its angle), so the converter limits are
/// lifted and the delay compensation is off unless `params` sets them: the reference models
/// are what is checked here.
fn unit(params: &[(&str, f64)]) -> Harness<Der> {
    let mut h = Harness::<Der>::new();
    for &(name, x) in OPEN_LOOP.iter().chain(params) {
        if matches!(
            name,
            "mode" | "adpf.p.kind" | "adpf.p.order" | "pll.order" | "adpf.p.n_lpf"
        ) {
            h.set(name, x as i32);
        } else {
            h.set(name, x);
        }
    }
    assert_eq!(h.init(), Status::Ok, "{:#?}", h.log());
    h
}

/// Steps with the inputs as they are; the outputs stay exactly where initialization put them.
fn assert_flat(h: &mut Harness<Der>, steps: usize) {
    let outputs = [
        "theta", "E", "df", "p_ref", "q_ref", "P_avail", "v_dc", "p_dc",
    ];
    let first: Vec<f64> = outputs.iter().map(|n| h.get(n)).collect();
    for _ in 0..steps {
        h.step(DT);
    }
    let now: Vec<f64> = outputs.iter().map(|n| h.get(n)).collect();
    assert_eq!(
        first, now,
        "outputs moved with the inputs at their start values"
    );
}

fn close(actual: f64, expected: f64, tol: f64, what: impl std::fmt::Display) {
    assert!(
        (actual - expected).abs() <= tol,
        "{what}: {actual} vs {expected} (difference {:.3e})",
        actual - expected
    );
}

#[test]
fn grid_forming_static_adpf_answers_a_power_step_with_its_first_order_reference() {
    // m = μ: Δf = -1/(μ (H s + D)) Δp on the DVPP base; θ integrates 2π f_nom Δf.
    let mu = 0.5;
    let mut h = unit(&[("mu_p", mu)]);
    assert_flat(&mut h, 100);
    let (p0, theta0) = (h.get("p"), h.get("theta"));
    let t0 = h.time();
    let dp = 0.02;
    h.set("p", p0 + dp);
    let gain = dp * TO_DVPP / (mu * D);
    for k in 1..=2000 {
        h.step(DT);
        let t = h.time() - t0;
        let decay = dvpp_math::exp(-D * t / H);
        let df = -gain * (1.0 - decay);
        let angle = -gain * (t - H / D * (1.0 - decay)) * 2.0 * PI * F_NOM;
        let [got_df, got_theta] = h.get_many(["df", "theta"]);
        close(got_df, df, 1e-12, format_args!("df at step {k}"));
        close(
            got_theta - theta0,
            angle,
            1e-10,
            format_args!("theta at step {k}"),
        );
    }
    // The steady state is the droop 1/(μ D), twice the unit's share of the full droop.
    close(h.get("df"), -dp * TO_DVPP / (mu * D), 1e-6, "steady state");
    assert!(h.warnings().is_empty(), "{:?}", h.warnings());
}

#[test]
fn grid_forming_low_pass_adpf_answers_a_power_step_with_its_reference() {
    // m = μ/(τ s + 1): Δf = -(τ s + 1)/(μ (H s + D)) Δp, a jump τ/(μ H) then the droop 1/(μ D).
    let (mu, tau) = (0.4, 1.5);
    let mut h = unit(&[("adpf.p.kind", 1.0), ("adpf.p.tau", tau), ("mu_p", mu)]);
    assert_flat(&mut h, 50);
    let p0 = h.get("p");
    let t0 = h.time();
    let dp = -0.01;
    h.set("p", p0 + dp);
    let u = dp * TO_DVPP / mu;
    let residue = (tau - H / D) / H;
    let mut worst: f64 = 0.0;
    for _ in 0..3000 {
        h.step(DT);
        let t = h.time() - t0;
        let expected = -u * (1.0 / D + residue * dvpp_math::exp(-D * t / H));
        worst = worst.max((h.get("df") - expected).abs());
    }
    assert!(
        worst < 1e-12,
        "largest deviation from the reference {worst:.3e}"
    );
    close(h.get("df"), -u / D, 1e-6, "steady state");
}

#[test]
fn dc_link_stays_near_one_pu_and_the_source_settles_on_the_ac_power() {
    let mut h = unit(&[]);
    let [p0, s_rated, s_base, g_dc] = h.get_many(["p", "S_rated", "S_base", "G_dc"]);
    close(h.get("v_dc"), 1.0, 0.0, "v_dc at initialization");
    let dp = 0.01;
    h.set("p", p0 + dp);
    let (mut lowest, mut highest) = (f64::INFINITY, f64::NEG_INFINITY);
    for _ in 0..3000 {
        h.step(DT);
        let v = h.get("v_dc");
        lowest = lowest.min(v);
        highest = highest.max(v);
    }
    // The link discharges while the source catches up (and overshoots a little), then the
    // voltage returns to 1 pu.
    assert!(lowest < 1.0, "the ac step drew nothing from the link");
    assert!(
        1.0 - lowest < 5e-3 && highest - 1.0 < 5e-3,
        "v_dc left 1 ± 0.5 %: [{lowest}, {highest}]"
    );
    close(h.get("v_dc"), 1.0, 1e-6, "v_dc after 3 s");
    // In steady state the dc source covers the ac power (at the terminal and in R_f) and the
    // link losses.
    let [q, v, r_f] = h.get_many(["q", "v", "R_f"]);
    let p = p0 + dp;
    let r_loss = r_f * s_base / s_rated * (p * p + q * q) / (v * v);
    let expected = p + r_loss + g_dc * s_rated / s_base;
    close(h.get("p_dc"), expected, 1e-5, "p_dc after 3 s");
    assert!(h.warnings().is_empty(), "{:?}", h.warnings());
}

#[test]
fn an_availability_drop_curtails_the_set_point_and_the_unit_answers_like_a_load_step() {
    let (t_step, drop) = (0.4995, -0.4);
    // A large dc link: open loop the measured power stays above what the source gives, and a
    // real link would run empty (and the converter cut its power) within tens of ms.
    let mut h = unit(&[
        ("avail.t_step", t_step),
        ("avail.dP", drop),
        ("C_dc", 100.0),
    ]);
    let [p, p_avail0, g_dc, s_rated, s_base, mu] =
        h.get_many(["p", "P_avail0", "G_dc", "S_rated", "S_base", "mu_p"]);
    let limit = (p_avail0 + drop) - g_dc * s_rated / s_base;
    assert!(limit < p, "the drop must cut below the dispatch");
    let mut t0 = None;
    for _ in 0..1500 {
        let start = h.time();
        if start >= t_step && t0.is_none() {
            t0 = Some(start);
        }
        // A step may warn (the dc source reaches its availability): it must not fail.
        let status = h.do_step(start, DT);
        assert!(status <= Status::Warning, "{status:?}: {:#?}", h.log());
        let [p_ref, df, avail] = h.get_many(["p_ref", "df", "P_avail"]);
        match t0 {
            None => {
                close(p_ref, p, 0.0, "set point before the drop");
                close(df, 0.0, 0.0, "df before the drop");
            }
            Some(t0) => {
                close(p_ref, limit, 1e-15, "curtailed set point");
                close(avail, p_avail0 + drop, 1e-15, "P_avail");
                // The deficit p - p_set is answered through Δf = -1/(μ (H s + D)) Δp.
                let t = h.time() - t0;
                let expected =
                    -(p - limit) * TO_DVPP / (mu * D) * (1.0 - dvpp_math::exp(-D * t / H));
                close(df, expected, 1e-12, format_args!("df at t = {}", h.time()));
            }
        }
    }
    assert!(t0.is_some());
    // The dc source cannot cover the measured power any more: one warning, not one per step.
    let warnings = h.warnings();
    assert!(
        warnings.len() == 1 && warnings[0].contains("primary source at its limit"),
        "{warnings:?}"
    );
}

#[test]
fn grid_following_unit_locks_to_a_frequency_offset_and_follows_its_droop() {
    for dt in [1e-3_f64, 1e-4] {
        let mut h = unit(&[("mode", 2.0), ("mu_p", 0.6)]);
        assert_flat(&mut h, 100);
        let [p0, mu, s_base, s_dvpp, kp] =
            h.get_many(["p_ref", "mu_p", "S_base", "S_dvpp", "pll.kp"]);
        // A 0.1 % frequency drop: the voltage angle falls behind the f_nom frame at 2π f_nom Δf.
        let df = -1e-3;
        let slope = 2.0 * PI * F_NOM * df;
        let t0 = h.time();
        let steps = (3.0 / dt).round() as usize;
        let mut theta_at = Vec::new();
        for k in 0..steps {
            h.set("v_angle", slope * (h.time() - t0));
            h.step(dt);
            if k + 1 == steps - 1000 || k + 1 == steps {
                theta_at.push((h.time(), h.get("theta")));
            }
        }
        // The PLL angle runs at the input's rate exactly.
        let [(t1, a1), (t2, a2)] = theta_at[..] else {
            unreachable!()
        };
        close(
            (a2 - a1) / (t2 - t1),
            slope,
            1e-5 * slope.abs(),
            "PLL angle rate",
        );
        // The frequency it reports at the communication points reads the input staircase
        // through the proportional path: low by at most kp·h/2 of the offset.
        let measured = h.get("df");
        let bias = (measured - df) / df;
        assert!(
            (-1e-9..=1.05 * kp * dt / 2.0).contains(&-bias),
            "h = {dt}: PLL frequency {measured} vs {df}"
        );
        // Steady state of T_fp = μ (H s + D)/(τ_pll s + 1)^d: Δp = -μ D Δf_pll on the DVPP base.
        let expected = p0 - mu * D * measured * s_dvpp / s_base;
        close(
            h.get("p_ref"),
            expected,
            1e-7,
            format_args!("h = {dt}: p_ref"),
        );
        assert!(h.warnings().is_empty(), "{:?}", h.warnings());
    }
}

#[test]
fn bad_parameters_fail_initialization_naming_the_parameter() {
    let cases: &[(&[(&str, f64)], &str)] = &[
        (&[("Tdes.D", 0.0)], "'Tdes.D'"),
        (&[("adpf.p.kind", 1.0), ("adpf.p.tau", 0.0)], "'adpf.p.tau'"),
        (&[("v_dc_min", 1.0)], "'v_dc_min'"),
        (&[("C_dc", 0.0)], "'C_dc'"),
        (
            &[
                ("adpf.p.kind", 3.0),
                ("adpf.p.tau", 0.2),
                ("adpf.p.tau2", 0.3),
            ],
            "'adpf.p.tau2'",
        ),
    ];
    for (params, name) in cases {
        let mut h = Harness::<Der>::new();
        assert_eq!(h.setup_experiment(0.0, None), Status::Ok);
        for &(n, x) in params.iter() {
            let status = match n {
                "mode" | "adpf.p.kind" => h.try_set(n, x as i32),
                _ => h.try_set(n, x),
            };
            assert_eq!(status, Status::Ok, "{n} = {x}");
        }
        assert_eq!(h.enter_initialization_mode(), Status::Ok);
        assert_eq!(h.exit_initialization_mode(), Status::Error, "{name}");
        assert_eq!(h.phase(), Phase::Error);
        let log = h.log();
        assert!(
            log.iter().any(|r| r.status == Status::Error
                && r.message.contains("initialization failed")
                && r.message.contains(name)),
            "{name}: {log:#?}"
        );
        assert_eq!(h.do_step(0.0, DT), Status::Error, "no step after a failure");
        // A reset restores the declared values, which initialize.
        assert_eq!(h.reset(), Status::Ok);
        assert_eq!(h.init(), Status::Ok, "{name}: after reset");
    }
    // Values outside a declared range are refused when set, naming the variable.
    let mut h = Harness::<Der>::new();
    assert_eq!(h.try_set("mode", 3), Status::Error);
    assert!(h.logged(Status::Error, "'mode'"), "{:#?}", h.log());
}

#[test]
fn a_nan_input_is_refused_and_changes_nothing() {
    let mut h = unit(&[]);
    let p0 = h.get("p");
    h.set("p", p0 + 0.01);
    for _ in 0..200 {
        h.step(DT);
    }
    for (name, bad) in [("p", f64::NAN), ("v", f64::INFINITY), ("mu_p", f64::NAN)] {
        let before = h.instance().core.store.clone();
        let status = h.try_set(name, bad);
        assert_eq!(status, Status::Error, "{name} = {bad}");
        assert!(
            h.logged(Status::Error, &format!("for '{name}' is not finite")),
            "{:#?}",
            h.log()
        );
        assert_eq!(
            h.instance().core.store,
            before,
            "{name} = {bad} changed a value"
        );
        // Outputs stay readable in the error state; a reset starts over from the start values.
        assert_eq!(h.phase(), Phase::Error);
        close(h.get("p"), p0 + 0.01, 0.0, "p after the refusal");
        assert_eq!(h.reset(), Status::Ok);
        h.init();
        h.set("p", p0 + 0.01);
        for _ in 0..200 {
            h.step(DT);
        }
    }
}

#[test]
fn a_restored_state_replays_the_same_trajectory() {
    for mode in [1, 2] {
        let mut h = Harness::<Der>::new();
        for (name, x) in OPEN_LOOP {
            h.set(name, x);
        }
        h.set("mode", mode);
        h.set("adpf.p.kind", 1);
        h.set("adpf.p.tau", 0.8);
        h.init();
        let p0 = h.get("p");
        h.set("p", p0 + 0.01);
        h.set("v_angle", -1e-3);
        for _ in 0..300 {
            h.step(DT);
        }
        let saved = h.get_fmu_state().unwrap();
        let bytes = h.serialize_fmu_state(&saved).unwrap();
        let outputs = ["theta", "E", "df", "p_ref", "q_ref", "v_dc", "p_dc"];
        let run = |h: &mut Harness<Der>| -> Vec<Vec<f64>> {
            (0..300)
                .map(|k| {
                    h.set("mu_p", 0.5 + 0.4 * k as f64 / 300.0);
                    h.step(DT);
                    outputs.iter().map(|n| h.get(n)).collect()
                })
                .collect()
        };
        let first = run(&mut h);
        assert_ne!(first[0], first[299], "mode {mode}: nothing moved");
        assert_eq!(h.set_fmu_state(&saved), Status::Ok);
        assert_eq!(run(&mut h), first, "mode {mode}: after fmi2SetFMUstate");
        // Another instance continues from the serialized bytes identically.
        let mut other = Harness::<Der>::new();
        let state = other.deserialize_fmu_state(&bytes).unwrap();
        assert_eq!(other.set_fmu_state(&state), Status::Ok);
        assert_eq!(run(&mut other), first, "mode {mode}: after deserialization");
    }
}

#[test]
fn gains_limits_and_set_points_are_tunable_between_steps_and_structure_is_not() {
    // A host retunes the PLL gains of a grid-following unit after initialization: from then on
    // it moves exactly like a unit initialized with those gains.
    let drive = |h: &mut Harness<Der>| -> Vec<f64> {
        (0..500)
            .map(|k| {
                h.set("v_angle", -2.0 * PI * F_NOM * 0.002 * k as f64 * DT);
                h.step(DT);
                h.get("df")
            })
            .collect()
    };
    let mut built = unit(&[("mode", 2.0), ("pll.kp", 30.0), ("pll.ki", 100.0)]);
    let mut retuned = unit(&[("mode", 2.0)]);
    assert_eq!(retuned.try_set("pll.kp", 30.0), Status::Ok);
    assert_eq!(retuned.try_set("pll.ki", 100.0), Status::Ok);
    assert_eq!(drive(&mut built), drive(&mut retuned));
    // In step mode tunable parameters are accepted, structure and fixed parameters refused (a
    // refused call is an fmi2Error, after which the instance only resets).
    for (name, x) in [
        ("qpi.kp", 0.2),
        ("I_max", 1.1),
        ("P_avail0", 0.5),
        ("deload", 0.9),
    ] {
        assert_eq!(retuned.try_set(name, x), Status::Ok, "{name}");
    }
    // A redispatch moves the set point by its amount at the next step.
    let before = retuned.get("p_set");
    assert_eq!(retuned.try_set("dispatch.dP", -0.05), Status::Ok);
    retuned.step(DT);
    close(
        retuned.get("p_set"),
        before - 0.05,
        1e-12,
        "redispatched set point",
    );
    for (name, x) in [("S_rated", 50.0), ("k_dc", 50.0), ("Tdes.H", 3.0)] {
        assert_eq!(retuned.try_set(name, x), Status::Error, "{name}");
    }
}

#[test]
fn subnormal_t_des_parameters_are_refused_by_name() {
    for name in ["Tdes.H", "Tdes.D", "Tdes.Dq", "Tdes.tau_q"] {
        let mut h = Harness::<Der>::new();
        assert_eq!(h.try_set(name, 4.9e-324), Status::Error, "{name}");
        assert!(
            h.logged(
                Status::Error,
                &format!("for parameter '{name}' is subnormal")
            ),
            "{:#?}",
            h.log()
        );
        // Nothing was contained: the instance is in the error state, not the fatal one.
        assert_eq!(h.phase(), Phase::Error, "{name}");
    }
}

/// `p + jq` that `E∠θ` injects through `z` into the bus `V∠0`.
fn injection(e: f64, theta: f64, v: f64, z: dvpp_control::Complex<f64>) -> (f64, f64) {
    let bus = dvpp_control::Complex::new(v, 0.0);
    let s = bus * ((dvpp_math::cpolar(e, theta) - bus) / z).conj();
    (s.re, s.im)
}

#[test]
fn a_virtual_resistance_acts_as_a_lossless_resistance_in_series_with_the_slot() {
    // Two units on an infinite bus through the exchange (their E∠θ answered within the step):
    // one with vi.r = 0.3 behind a slot 0.01 + j0.1, one without it behind 0.31 + j0.1. The
    // same currents flow; only the second loses power in its slot. A 0.1 % voltage dip at 0.5 s.
    // The q integral gain as the EMT controller's (0.5/s): at the phasor default of 5/s, q's
    // loop through a mostly resistive output impedance is unstable.
    let s_base_over_rated = 100.0 / 60.0;
    let run = |vi_r: f64, r_f: f64| {
        let mut h = unit(&[
            ("S_rated", 60.0),
            ("R_f", r_f),
            ("X_f", 0.1),
            ("vi.r", vi_r),
            ("qpi.ki", 0.5),
        ]);
        let z = dvpp_control::Complex::new(r_f, 0.1) * s_base_over_rated;
        let (p0, q0) = (h.get("p"), h.get("q"));
        let mut v = h.get("v");
        let mut trace = Vec::new();
        for k in 0..3000 {
            if k == 500 {
                v *= 0.999;
            }
            let (p, q) = injection(h.get("E"), h.get("theta"), v, z);
            if k == 0 {
                close(p, p0, 1e-12, "p at the start");
                close(q, q0, 1e-12, "q at the start");
            }
            h.set("p", p);
            h.set("q", q);
            h.set("v", v);
            h.step(DT);
            trace.push((p, q, h.get("p_dc")));
        }
        trace
    };
    let virtual_r = run(0.3, 0.01);
    let real_r = run(0.0, 0.31);
    let q_change = (real_r[2999].1 - real_r[0].1).abs();
    assert!(q_change > 1e-2, "the dip moves q by {q_change}");
    // The divider takes the bus voltage one step old: at the dip the two differ for two steps.
    let worst = virtual_r
        .iter()
        .zip(&real_r)
        .enumerate()
        .filter(|(k, _)| !(500..502).contains(k))
        .map(|(_, (a, b))| (a.0 - b.0).abs().max((a.1 - b.1).abs()))
        .fold(0.0, f64::max);
    assert!(worst < 1e-3 * q_change, "p, q differ by up to {worst:.3e}");
    let (a, b) = (virtual_r[2999], real_r[2999]);
    // The dc side: the slot's loss r i² (0.5 pu on S_base) with the real resistance only.
    let i2 = (a.0 * a.0 + a.1 * a.1) / (0.999f64 * 0.999);
    close(
        b.2 - a.2,
        0.3 * s_base_over_rated * i2,
        1e-5,
        "p_dc difference = r i²",
    );
}
