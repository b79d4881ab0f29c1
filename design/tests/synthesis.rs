//! The default synthesis passes its checks, the checks can fail, and the committed gains are what a fresh synthesis gives.

use dvpp_control::converter::hinf_gains as committed;
use dvpp_design::checks::{self, Report};
use dvpp_design::generate;
use dvpp_design::plant::{DesignSpec, N_INPUTS, N_STATES};
use dvpp_design::synthesis::{synthesize, Design};
use std::sync::OnceLock;

fn design() -> &'static Design {
    static D: OnceLock<Design> = OnceLock::new();
    D.get_or_init(|| synthesize(&DesignSpec::default()).expect("the default design solves"))
}

#[test]
fn the_default_design_passes_every_check() {
    let d = design();
    let r = Report::of(d);
    eprintln!(
        "gamma {:.6}, residuals {:.3e} {:.3e}, largest real part {:.3} rad/s, sampled |z| {:.6}, sweep {:.6} ({:.4} of gamma) at mu {} and {:.1} Hz",
        r.gamma,
        r.residuals[0],
        r.residuals[1],
        r.worst_real_part.0,
        r.worst_sampled_radius.0,
        r.worst_sweep.0,
        r.worst_sweep.0 / r.gamma,
        r.worst_sweep.1,
        r.worst_sweep.2
    );
    assert!(r.residuals.iter().all(|x| *x < 0.0), "{:?}", r.residuals);
    assert!(r.worst_real_part.0 < 0.0, "{:?}", r.worst_real_part);
    assert!(
        r.fastest_pole <= d.spec.pole_radius * d.spec.omega_b() * (1.0 + 1e-6),
        "{} outside the disk",
        r.fastest_pole
    );
    assert!(
        r.worst_sampled_radius.0 < 1.0,
        "{:?}",
        r.worst_sampled_radius
    );
    assert_eq!(r.sweep.len(), checks::GRID);
    for &(mu, s) in &r.sweep {
        assert!(
            s <= 1.01 * r.gamma,
            "sweep {s} above gamma {} at mu {mu}",
            r.gamma
        );
    }
    // γ is not loose: the worst μ reaches it within 5 %.
    assert!(
        r.worst_sweep.0 >= 0.95 * r.gamma,
        "{:?} {}",
        r.worst_sweep,
        r.gamma
    );
    assert!(r.passes());
}

/// The checks see a gain that is not the solution: the same gains ten times larger put the
/// sampled loop with its delay out of the unit circle.
#[test]
fn the_checks_reject_a_gain_that_is_too_high() {
    let mut d = design().clone();
    for k in &mut d.gains {
        *k *= 10.0;
    }
    let r = Report::of(&d);
    assert!(
        r.worst_sampled_radius.0 > 1.0,
        "{:?}",
        r.worst_sampled_radius
    );
    assert!(!r.passes());
}

/// The gains in `dvpp-control` are a fresh synthesis's: the design data exactly, the gains and
/// γ to 1e-6 of the largest gain (the interior-point solver's result moves at that level with
/// the BLAS's summation order; on one machine the file is reproduced byte for byte, which the
/// test reports).
#[test]
fn the_committed_gains_are_a_fresh_synthesis() {
    let d = design();
    let s = &d.spec;
    assert_eq!(committed::N_STATES, N_STATES);
    assert_eq!(committed::N_INPUTS, N_INPUTS);
    assert_eq!([committed::MU_MIN, committed::MU_MAX], d.mu);
    assert_eq!(committed::K_Q, s.k_q);
    assert_eq!(committed::TAU_Q, s.tau_q);
    assert_eq!(committed::R_V, s.r_v);
    assert_eq!(committed::T_DELAY, s.t_delay);
    assert_eq!(committed::P0, s.p0);
    assert_eq!(committed::W_TRACKING, s.weights.tracking);
    assert_eq!(committed::W_EFFORT, s.weights.effort);
    assert_eq!(committed::W_ROLLOFF, s.weights.rolloff);
    assert_eq!(committed::POLE_RADIUS, s.pole_radius);
    let scale = d.gains[0].amax().max(d.gains[1].amax());
    let mut worst: f64 = 0.0;
    for (k, fixed) in [committed::K_MU_MIN, committed::K_MU_MAX]
        .iter()
        .enumerate()
    {
        for (i, row) in fixed.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                worst = worst.max((v - d.gains[k][(i, j)]).abs());
            }
        }
    }
    assert!(
        worst <= 1e-6 * scale,
        "the committed gains differ from a fresh synthesis by {worst:e} (largest gain {scale}): run `cargo xtask hinf`"
    );
    assert!((committed::GAMMA / d.gamma - 1.0).abs() < 1e-6);
    let fresh = generate::render(d);
    let file = std::fs::read_to_string(generate::path()).unwrap();
    eprintln!(
        "committed file {} a fresh synthesis's byte for byte (largest gain difference {worst:e})",
        if fresh == file { "is" } else { "is not" }
    );
}
