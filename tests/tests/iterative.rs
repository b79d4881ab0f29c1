//! The iterative master algorithm: it removes the exchange delay of Jacobi (case study I at a
//! 1 ms step comes closer to a 0.1 ms reference), reports its attempts, and refuses FMUs that
//! cannot roll back.

use dvpp_cosim::master::{self, End, Iterative, Jacobi, Options, Recorder};
use dvpp_e2e::{foreign, scenario};
use std::path::Path;

/// `grid.pcc.v` of case1_load from 0 to 1.3 s at step `h` with `algorithm`.
fn pcc_v(h: f64, algorithm: &mut dyn master::Algorithm) -> Vec<f64> {
    let opts = Options {
        stop: Some(1.3),
        step: Some(h),
        ..Options::default()
    };
    let mut rec = Recorder::default();
    let outcome = master::System::builder(&scenario("case1_load"))
        .algorithm(algorithm)
        .run(&opts, &mut [&mut rec])
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(outcome.end, End::Completed);
    rec.table.column("grid.pcc.v").expect("grid.pcc.v")
}

#[test]
fn iterative_coupling_removes_the_exchange_delay_of_case_study_i() {
    let reference = pcc_v(1e-4, &mut Jacobi);
    let at_1ms = |v: &[f64]| -> f64 {
        // Over the load step and the response after it (t from 0.99 s), at the 1 ms points.
        (990..=1300)
            .map(|k| (v[k] - reference[10 * k]).abs())
            .fold(0.0, f64::max)
    };
    let jacobi = at_1ms(&pcc_v(1e-3, &mut Jacobi));
    let mut iterative = Iterative::new();
    let err = at_1ms(&pcc_v(1e-3, &mut iterative));
    let (steps, attempts, unconverged) = iterative.counts();
    println!(
        "largest |Δv_pcc| against 0.1 ms Jacobi: Jacobi {jacobi:.3e}, iterative {err:.3e} pu; \
         {steps} steps, {:.2} attempts per step, {unconverged} not converged",
        attempts as f64 / steps as f64
    );
    assert!(err < 0.5 * jacobi, "iterative {err:e} vs Jacobi {jacobi:e}");
    assert!(
        attempts > steps,
        "the load step needs more than one attempt"
    );
    assert_eq!(unconverged, 0, "steps that did not converge");
}

#[test]
fn units_that_cannot_roll_back_are_refused() {
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("iterative");
    let _ = std::fs::remove_dir_all(&out);
    let fmus = foreign::build_foreign(&out);
    let (dir, _) = foreign::system(&out, "step_lag", &fmus);
    let opts = Options {
        step: Some(1e-3),
        ..Options::default()
    };
    let outcome = master::System::builder(&dir)
        .algorithm(&mut Iterative::new())
        .run(&opts, &mut [])
        .expect("the system loads");
    match outcome.end {
        End::Failed { error, .. } => {
            assert!(
                error.contains("canGetAndSetFMUstate") && error.contains("lag"),
                "{error}"
            );
        }
        other => panic!("ran without rollback: {other:?}"),
    }
}
