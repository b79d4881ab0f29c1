//! The bundled operator FMU as a master drives it: the cloud of case study I, degenerate inputs,
//! rate limit and delay, and the desired aggregate response.

use dvpp_cosim::{Instance, Status};
use dvpp_e2e::*;

struct Op {
    i: Instance,
    vr: std::collections::HashMap<String, u32>,
}

impl Op {
    fn new(name: &str, params: &[(&str, f64)], inputs: &[(&str, f64)]) -> Op {
        let fmu = load("dvpp_operator");
        let vr = fmu
            .description
            .model_variables
            .variables
            .iter()
            .map(|v| (v.name.clone(), v.value_reference))
            .collect();
        let mut op = Op {
            i: fmu.instantiate(name).unwrap(),
            vr,
        };
        op.set(params);
        op.set(inputs);
        assert_eq!(op.i.setup_experiment(0.0, None), Status::Ok);
        assert_eq!(op.i.enter_initialization_mode(), Status::Ok);
        let s = op.i.exit_initialization_mode();
        assert!(s <= Status::Warning, "{s:?}: {:?}", op.i.last_message());
        op
    }

    fn set(&mut self, values: &[(&str, f64)]) {
        for (n, x) in values {
            let s = self.i.set_real(&[self.vr[*n]], &[*x]);
            assert_eq!(s, Status::Ok, "{n}: {:?}", self.i.last_message());
        }
    }

    fn get(&mut self, names: &[&str]) -> Vec<f64> {
        let vrs: Vec<u32> = names.iter().map(|n| self.vr[*n]).collect();
        let mut out = vec![0.0; vrs.len()];
        assert_eq!(self.i.get_real(&vrs, &mut out), Status::Ok);
        out
    }

    fn step(&mut self, t: f64, h: f64) -> Status {
        self.i.do_step(t, h)
    }

    fn warnings(&self) -> Vec<String> {
        self.i
            .log()
            .into_iter()
            .filter(|r| r.status == Status::Warning)
            .map(|r| r.message)
            .collect()
    }
}

const MU_P: [&str; 2] = ["der[1].mu_p", "der[2].mu_p"];
const MU_Q: [&str; 3] = ["der[1].mu_q", "der[2].mu_q", "der[3].mu_q"];
const SUMS: [&str; 2] = ["check.sum_mu_p", "check.sum_mu_q"];

fn assert_sums(op: &mut Op, t: f64) {
    let p: f64 = op.get(&MU_P).iter().sum();
    let q: f64 = op.get(&MU_Q).iter().sum();
    assert!(
        (p - 1.0).abs() <= 1e-12 && (q - 1.0).abs() <= 1e-12,
        "t = {t}: Σμ_p = {p}, Σμ_q = {q}"
    );
    let lpf = op.get(&["der[3].mu_p_lpf[1]", "der[3].mu_p_lpf[2]"]);
    assert_eq!(
        lpf,
        op.get(&MU_P),
        "the complement receives the low-pass gains"
    );
    let sums = op.get(&SUMS);
    assert!((sums[0] - 1.0).abs() <= 1e-12 && (sums[1] - 1.0).abs() <= 1e-12);
}

#[test]
fn a_cloud_moves_active_participation_to_wind_and_reactive_to_pv() {
    // Case study I operating point (pu on 100 MVA): wind 0.315 of 0.40 available, PV 0.5 of 0.6.
    let mut op = Op::new(
        "cloud",
        &[],
        &[
            ("der[1].P_avail", 0.40),
            ("der[2].P_avail", 0.60),
            ("der[1].p", 0.315),
            ("der[2].p", 0.50),
            ("der[3].p", 0.0),
        ],
    );
    let before = [op.get(&MU_P), op.get(&MU_Q)];
    assert!(
        (before[0][0] - 0.4).abs() < 1e-12 && (before[0][1] - 0.6).abs() < 1e-12,
        "{before:?}"
    );
    let h = 1e-2;
    for k in 0..300 {
        let t = k as f64 * h;
        if k == 100 {
            // The cloud: the PV's availability and output fall; wind takes over the steady state.
            op.set(&[
                ("der[2].P_avail", 0.2),
                ("der[2].p", 0.2),
                ("der[1].p", 0.4),
            ]);
        }
        assert_eq!(op.step(t, h), Status::Ok);
        assert_sums(&mut op, t + h);
    }
    let after = [op.get(&MU_P), op.get(&MU_Q)];
    assert!(
        after[0][1] < before[0][1] && after[0][0] > before[0][0],
        "active: {before:?} -> {after:?}"
    );
    assert!((after[0][0] - 2.0 / 3.0).abs() < 1e-12, "{after:?}");
    assert!(
        after[1][1] > before[1][1],
        "PV's reactive gain rises on its capability circle: {before:?} -> {after:?}"
    );
    assert!(op.warnings().is_empty(), "{:?}", op.warnings());
}

#[test]
fn all_availabilities_zero_gives_equal_shares_and_one_warning() {
    let mut op = Op::new(
        "zero",
        &[],
        &[("der[1].P_avail", 0.0), ("der[2].P_avail", 0.0)],
    );
    for k in 0..50 {
        assert_eq!(op.step(k as f64 * 1e-3, 1e-3), Status::Ok, "warned again");
        assert_sums(&mut op, k as f64);
    }
    assert_eq!(op.get(&MU_P), vec![0.5, 0.5]);
    assert_eq!(op.warnings().len(), 1, "{:?}", op.warnings());
    assert!(op.warnings()[0].contains("zero available power"));
}

#[test]
fn negative_availability_is_clamped_with_one_warning_and_the_floor_holds() {
    let mut op = Op::new(
        "negative",
        &[],
        &[("der[1].P_avail", 0.5), ("der[2].P_avail", -0.3)],
    );
    for k in 0..20 {
        assert_eq!(op.step(k as f64 * 1e-3, 1e-3), Status::Ok);
        assert_sums(&mut op, k as f64);
    }
    let mu = op.get(&MU_P);
    assert!(
        (mu[1] - 0.05).abs() < 1e-12,
        "a grid-forming unit keeps mu_min: {mu:?}"
    );
    assert_eq!(op.warnings().len(), 1, "{:?}", op.warnings());
    assert!(op.warnings()[0].contains("negative available power"));
}

#[test]
fn power_beyond_rating_leaves_no_reactive_capacity_with_one_warning() {
    // PV: 73 MVA; 0.9 pu on 100 MVA = 90 MW.
    let mut op = Op::new("over-rating", &[], &[("der[2].p", 0.9)]);
    for k in 0..20 {
        assert_eq!(op.step(k as f64 * 1e-3, 1e-3), Status::Ok);
        assert_sums(&mut op, k as f64);
    }
    assert_eq!(op.get(&["der[2].mu_q"]), vec![0.0]);
    assert_eq!(op.warnings().len(), 1, "{:?}", op.warnings());
    assert!(op.warnings()[0].contains("exceeds its rating"));
}

#[test]
fn a_nan_availability_is_refused_and_the_gains_stay() {
    let mut op = Op::new("nan", &[], &[]);
    let before = op.get(&MU_P);
    assert_eq!(
        op.i.set_real(&[op.vr["der[1].P_avail"]], &[f64::NAN]),
        Status::Error
    );
    assert_eq!(op.get(&MU_P), before);
    assert!(op.i.last_message().unwrap().contains("not finite"));
}

#[test]
fn rate_limit_and_delay_keep_the_sums_exact() {
    let (rate, delay, h) = (0.5, 0.05, 1e-3);
    let mut op = Op::new(
        "limited",
        &[("rate_limit", rate), ("delay", delay)],
        &[("der[1].P_avail", 0.5), ("der[2].P_avail", 0.5)],
    );
    let mut previous = op.get(&MU_P);
    let mut first_move = None;
    for k in 0..1000 {
        let t = k as f64 * h;
        if k == 100 {
            op.set(&[("der[2].P_avail", 0.05)]);
        }
        assert_eq!(op.step(t, h), Status::Ok);
        assert_sums(&mut op, t + h);
        let mu = op.get(&MU_P);
        let change = (mu[0] - previous[0]).abs().max((mu[1] - previous[1]).abs());
        assert!(
            change <= rate * h + 1e-15,
            "t = {t}: a gain moved {change} > {}",
            rate * h
        );
        if change > 0.0 && first_move.is_none() {
            first_move = Some(t + h);
        }
        previous = mu;
    }
    let moved = first_move.expect("the gains moved");
    assert!(
        (moved - (0.1 + h + delay)).abs() < 1.5 * h,
        "first move at {moved}, expected after the delay"
    );
    let final_target = 0.5 / 0.55;
    assert!((previous[0] - final_target).abs() < 1e-12, "{previous:?}");
}

#[test]
fn desired_response_is_t_pf_applied_to_the_pcc_power_change() {
    let mut op = Op::new(
        "reference",
        &[],
        &[("pcc.p", 0.8), ("pcc.q", 0.1), ("pcc.v", 1.02)],
    );
    let (hh, d, dq, s_base, s_dvpp) = (5.55, 33.33, 0.01, 100.0, 96.0);
    op.set(&[
        ("pcc.p", 1.08),
        ("pcc.q", 0.15),
        ("pcc.f", 0.999),
        ("pcc.v", 1.0),
    ]);
    let dp = 0.28 * s_base / s_dvpp;
    let h = 1e-2;
    for k in 0..200 {
        let t = (k + 1) as f64 * h;
        assert_eq!(op.step(k as f64 * h, h), Status::Ok);
        let [ref_df, ref_dv, err_df, err_dv] =
            op.get(&["ref.df", "ref.dv", "err.df", "err.dv"])[..]
        else {
            unreachable!()
        };
        let analytic = -dp / d * (1.0 - dvpp_math::exp(-d * t / hh));
        assert!(
            (ref_df - analytic).abs() < 1e-12,
            "t = {t}: {ref_df} vs {analytic}"
        );
        assert!((ref_dv - (-dq * 0.05 * s_base / s_dvpp)).abs() < 1e-15);
        assert!((err_df - (-0.001 - ref_df)).abs() < 1e-15);
        assert!((err_dv - (-0.02 - ref_dv)).abs() < 1e-15);
    }
}
