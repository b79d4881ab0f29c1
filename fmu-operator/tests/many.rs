//! Tests of operators serving many units (24 to 1000).
//!
//! No cap on their number, the per-unit floor keeps 24 to 1000 equal grid-forming low-pass
//! units feasible with exact sums, and a step's cost grows linearly.

use fmi_export::harness::Harness;
use fmi_export::{Config, Status};
use operator_model::{DerEntry, Form, Operator, OperatorConfig, Role};
use std::time::Instant;

const DT: f64 = 1e-3;

/// `n` equal grid-forming low-pass units of case study I's low-pass total (119 MVA) in a 96 MVA
/// DVPP, each with availability `avail(k)` (pu on S_base), initialized.
fn operator(n: usize, avail: impl Fn(usize) -> f64) -> Harness<Operator> {
    let mut config = Config::<OperatorConfig>::default();
    config.model.ders = (1..=n)
        .map(|k| DerEntry {
            name: format!("u{k}"),
            role: Role::LowPass,
            form: Form::GridForming,
            s_rated: 119.0 / n as f64,
            share: 1.0,
        })
        .collect();
    let mut h = Harness::<Operator>::with_config(config);
    for k in 1..=n {
        h.set(&format!("der[{k}].P_avail"), avail(k));
    }
    assert_eq!(h.init(), Status::Ok, "{n} units: {:#?}", h.log());
    h
}

fn gains(h: &mut Harness<Operator>, n: usize, what: &str) -> (Vec<f64>, Vec<f64>) {
    let p: Vec<f64> = (1..=n).map(|k| h.get(&format!("der[{k}].mu_p"))).collect();
    let q: Vec<f64> = (1..=n).map(|k| h.get(&format!("der[{k}].mu_q"))).collect();
    for (sum, name) in [(p.iter().sum::<f64>(), "Σ μ_p"), (q.iter().sum(), "Σ μ_q")] {
        assert!((sum - 1.0).abs() < 1e-12, "{what}: {name} = {sum}");
    }
    (p, q)
}

#[test]
fn twenty_four_to_a_thousand_equal_units_initialize_with_their_floors() {
    for n in [24usize, 200, 1000] {
        // Every tenth unit has no available power: it sits at its floor.
        let mut h = operator(n, |k| if k % 10 == 0 { 0.0 } else { 1.0 / n as f64 });
        let floor = 0.25 * (119.0 / n as f64) / 96.0;
        let (p, _) = gains(&mut h, n, &format!("{n} units"));
        for (k, mu) in p.iter().enumerate() {
            if (k + 1) % 10 == 0 {
                assert!(
                    (mu - floor).abs() < 1e-15,
                    "{n} units: unit {k}: {mu} vs {floor}"
                );
            } else {
                assert!(*mu > floor, "{n} units: unit {k}: {mu}");
            }
        }
        h.step(DT);
        gains(&mut h, n, &format!("{n} units after a step"));
        assert!(h.warnings().is_empty(), "{:?}", h.warnings());
    }
}

#[test]
fn a_step_costs_time_linear_in_the_number_of_units() {
    // Best of several runs of 200 steps with availabilities that move every step.
    let per_step = |n: usize| -> f64 {
        let mut h = operator(n, |_| 1.0 / n as f64);
        let names: Vec<String> = (1..=n).map(|k| format!("der[{k}].P_avail")).collect();
        let vrs: Vec<u32> = names.iter().map(|x| h.vr(x).1).collect();
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            let t0 = Instant::now();
            for s in 0..200 {
                let values: Vec<f64> = (0..n)
                    .map(|k| (1.0 + ((k + s) % 7) as f64) / n as f64)
                    .collect();
                assert_eq!(h.set_real(&vrs, &values), Status::Ok);
                h.step(DT);
            }
            best = best.min(t0.elapsed().as_secs_f64() / 200.0);
        }
        best
    };
    let (small, large) = (per_step(100), per_step(1000));
    println!(
        "operator step: {:.1} µs at 100 units, {:.1} µs at 1000 units ({:.2}× for 10× the units)",
        small * 1e6,
        large * 1e6,
        large / small
    );
    // Linear: 10× the units costs about 10×; a quadratic step would cost about 100×.
    assert!(large / small < 30.0, "{small} s vs {large} s per step");
}
