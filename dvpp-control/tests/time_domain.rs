//! Exact sampled-data simulation: discretization accuracy, bank exactness, unit step responses.

mod common;
use common::Rng;
use dvpp_control::*;
use nalgebra::{DMatrix, DVector};

const STEPS: [f64; 3] = [1e-4, 1e-3, 1e-2];

#[test]
fn bank_shares_sum_to_input_while_gains_ramp() {
    let cs = CaseStudyI::new();
    let specs = cs.lpf_specs(46.0 / 119.0, 73.0 / 119.0).unwrap();
    for h in STEPS {
        let mut bank = ParticipationBank::new(&specs).unwrap();
        let mut rng = Rng::new(7);
        let n = (3.0 / h) as usize;
        let mut worst: f64 = 0.0;
        let mut u = 0.0;
        for k in 0..n {
            let t = k as f64 * h;
            // gains ramp from nominal to a PV cut-off and back
            let r = (t / 1.5).min(1.0) - ((t - 2.0) / 1.0).clamp(0.0, 1.0);
            let mp = (73.0 / 119.0) * (1.0 - r) + MU_MIN_GFM * r;
            bank.set_gains(&[1.0 - mp, mp]).unwrap();
            if k % 37 == 0 {
                u = rng.range(-1.0, 1.0) * 1e3;
            }
            let s = bank.step(u, h).unwrap();
            let sum: f64 = s.iter().sum();
            worst = worst.max((sum - u).abs() / u.abs().max(1.0));
        }
        assert!(worst <= 1e-12, "h={h}: {worst}");
    }
}

#[test]
fn bank_lpf_share_matches_analytic() {
    let specs = [
        LowPassSpec::new(0.3, 1.5, 1).unwrap(),
        LowPassSpec::new(0.7, 0.6, 1).unwrap(),
    ];
    for h in STEPS {
        let mut bank = ParticipationBank::new(&specs).unwrap();
        let n = (2.0 / h).round() as usize;
        let mut s = vec![];
        for _ in 0..n {
            s = bank.step(1.0, h).unwrap();
        }
        let t = n as f64 * h;
        let a0 = 0.3 * (1.0 - dvpp_math::exp(-t / 1.5f64));
        let a1 = 0.7 * (1.0 - dvpp_math::exp(-t / 0.6f64));
        assert!(
            (s[0] - a0).abs() < 1e-12 && (s[1] - a1).abs() < 1e-12,
            "h={h}"
        );
        assert!((s[2] - (1.0 - a0 - a1)).abs() < 1e-12);
    }
}

#[test]
fn gfm_lpf_step_response_matches_analytic() {
    let cs = CaseStudyI::new();
    let (hh, dd) = (5.55, 33.33);
    for (mu, tau) in [(46.0 / 119.0, 1.5), (73.0 / 119.0, 0.6), (MU_MIN_GFM, 0.6)] {
        let adpf = Adpf::low_pass(mu, tau, 1).unwrap();
        for h in STEPS {
            let mut unit = GfmPfModel::new(&cs.tdes, &adpf).unwrap();
            let n = (3.0 / h).round() as usize;
            let mut worst: f64 = 0.0;
            for k in 1..=n {
                let df = unit.step(1.0, h);
                let t = k as f64 * h;
                let exact = -(1.0 / dd + (tau / hh - 1.0 / dd) * dvpp_math::exp(-dd * t / hh)) / mu;
                worst = worst.max((df - exact).abs());
            }
            assert!(worst < 1e-6, "mu={mu} h={h}: {worst}");
            assert!(worst < 1e-11, "exactness lost: mu={mu} h={h}: {worst}");
        }
    }
}

#[test]
fn gfm_complement_matches_independent_realization() {
    // feedback realization vs. canonical realization of T_pf/m_c at frozen gains
    let cs = CaseStudyI::new();
    let units = cs.gfm_pf_models().unwrap();
    let mut fb = units[2].clone();
    let tf = fb.transfer_function().unwrap();
    let mut canon = LtiSimulator::new(tf.to_state_space(), Hold::Zero);
    let mut rng = Rng::new(99);
    let h = 1e-3;
    let mut u = 0.0;
    let mut worst: f64 = 0.0;
    for k in 0..5000 {
        if k % 250 == 0 {
            u = rng.range(-1.0, 1.0);
        }
        let a = fb.step(u, h);
        let b = -canon.step(u, h);
        worst = worst.max((a - b).abs() / (1.0 + b.abs()));
    }
    assert!(worst < 1e-8, "{worst}");
}

#[test]
fn gfl_units_aggregate_exactly_while_gains_move() {
    // Σ_i Δp_i of the three grid-following units = −T_pf⁻¹/(τ_pll s+1) Δf at every step,
    // although each unit realizes its share differently and the dc gains ramp.
    let cs = CaseStudyI::new();
    let [mw, mp] = cs.nominal_active_gains();
    let adpfs = cs.active_adpfs(mw, mp).unwrap();
    let mut units: Vec<GflFpModel> = adpfs
        .iter()
        .map(|a| GflFpModel::new(&cs.tdes, a, cs.tau_pll, 1).unwrap())
        .collect();
    let f = TransferFunction::lag_power(cs.tau_pll, 1)
        .unwrap()
        .div(cs.tdes.pf())
        .unwrap();
    let mut reference = LtiSimulator::new(f.to_state_space(), Hold::Zero);
    let mut rng = Rng::new(5);
    for h in STEPS {
        let n = (2.0 / h) as usize;
        let mut df = 0.0;
        let mut worst: f64 = 0.0;
        for k in 0..n {
            let t = k as f64 * h;
            let mpv = mp + (MU_MIN_GFM - mp) * (t / 2.0);
            units[0].set_mu(1.0 - mpv).unwrap();
            units[1].set_mu(mpv).unwrap();
            units[2].set_lpf_gains(&[1.0 - mpv, mpv]).unwrap();
            if k % 97 == 0 {
                df = rng.range(-1e-2, 1e-2);
            }
            let total: f64 = units.iter_mut().map(|u| u.step(df, h)).sum();
            let r = -reference.step(df, h);
            worst = worst.max((total - r).abs() / (1.0 + r.abs()));
        }
        assert!(worst < 1e-9, "h={h}: {worst}");
    }
}

#[test]
fn vq_step_response() {
    let cs = CaseStudyI::new();
    let mut u = VqModel::grid_forming(&cs.tdes, 0.25).unwrap();
    for h in STEPS {
        let mut u2 = u.clone();
        let n = (0.05 / h).round() as usize;
        let mut q = 0.0;
        for _ in 0..n {
            q = u2.step(0.01, h);
        }
        let t = n as f64 * h;
        let exact = -0.25 / 0.01 * 0.01 * (1.0 - dvpp_math::exp(-t / 0.01f64));
        assert!((q - exact).abs() < 1e-12, "h={h}");
    }
    assert_eq!(u.set_mu(1.5).unwrap(), 1.0);
}

#[test]
fn pv_availability_to_zero_is_bounded() {
    let cs = CaseStudyI::new();
    let [mw, mp] = cs.active_gains(46.0, 0.0).unwrap();
    assert!((mp - MU_MIN_GFM).abs() < 1e-15 && (mw - (1.0 - MU_MIN_GFM)).abs() < 1e-15);
    let mut units = cs.gfm_pf_models().unwrap();
    // runtime clamp
    assert_eq!(units[1].set_mu(0.0).unwrap(), MU_MIN_GFM);
    units[0].set_mu(mw).unwrap();
    units[2].set_lpf_gains(&[mw, mp]).unwrap();
    check_gfm_aggregation(&cs.tdes, &units, &design_grid(), 1e-9).unwrap();
    let mut peak: f64 = 0.0;
    for _ in 0..1000 {
        peak = peak.max(units[1].step(0.01, 1e-3).abs());
    }
    // |Δf| ≤ max(τ/H, 1/D)/μ_min · |Δp|
    assert!(
        peak <= (0.6 / 5.55f64).max(1.0 / 33.33) / MU_MIN_GFM * 0.01 + 1e-12,
        "{peak}"
    );
}

fn stiff_second_order() -> (StateSpace, f64, f64) {
    let (l1, l2) = (-1.0, -1e4);
    // G(s) = l1 l2 / ((s - l1)(s - l2)), unit dc gain
    let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -l1 * l2, l1 + l2]);
    let b = DVector::from_vec(vec![0.0, 1.0]);
    let c = DMatrix::from_row_slice(1, 2, &[l1 * l2, 0.0]);
    let d = DVector::from_vec(vec![0.0]);
    (StateSpace::new(a, b, c, d).unwrap(), l1, l2)
}

#[test]
fn stiff_second_order_zoh_is_exact() {
    let (sys, l1, l2) = stiff_second_order();
    for h in STEPS {
        let mut sim = LtiSimulator::new(sys.clone(), Hold::Zero);
        let n = (2.0 / h).round() as usize;
        let mut worst: f64 = 0.0;
        for k in 1..=n {
            let y = sim.step(1.0, h);
            let t = k as f64 * h;
            let exact =
                1.0 - (l2 * dvpp_math::exp(l1 * t) - l1 * dvpp_math::exp(l2 * t)) / (l2 - l1);
            worst = worst.max((y - exact).abs());
        }
        // per-step error ~1e-16; accumulated over up to 2·10⁴ steps it stays ~1e-12
        assert!(worst < 5e-12, "h={h}: {worst}");
    }
}

#[test]
fn lightly_damped_oscillator_zoh_and_foh() {
    // ω_n = 300 rad/s, ζ = 0.02 — ω_n h = 3 at h = 1e-2
    let (wn, z) = (300.0f64, 0.02f64);
    let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -wn * wn, -2.0 * z * wn]);
    let b = DVector::from_vec(vec![0.0, wn * wn]);
    let c = DMatrix::from_row_slice(1, 2, &[1.0, 0.0]);
    let sys = StateSpace::new(a, b, c, DVector::from_vec(vec![0.0])).unwrap();
    let wd = wn * (1.0 - z * z).sqrt();
    for h in STEPS {
        let mut sim = LtiSimulator::new(sys.clone(), Hold::Zero);
        let n = (0.5 / h).round() as usize;
        let mut worst: f64 = 0.0;
        for k in 1..=n {
            let y = sim.step(1.0, h);
            let t = k as f64 * h;
            let exact = 1.0
                - dvpp_math::exp(-z * wn * t)
                    * (dvpp_math::cos(wd * t) + z * wn / wd * dvpp_math::sin(wd * t));
            worst = worst.max((y - exact).abs());
        }
        assert!(worst < 1e-11, "zoh h={h}: {worst}");
    }
    // first-order hold is exact for a ramp input: first-order lag 1/(s/a + 1), u = t
    let aa = 1e3;
    let lag = TransferFunction::first_order_lag(1.0, 1.0 / aa)
        .unwrap()
        .to_state_space();
    for h in STEPS {
        let mut sim = LtiSimulator::new(lag.clone(), Hold::First);
        let n = (0.1 / h).round() as usize;
        let mut worst: f64 = 0.0;
        for k in 1..=n {
            let t = k as f64 * h;
            let y = sim.step(t, h);
            let exact = t - (1.0 - dvpp_math::exp(-aa * t)) / aa;
            worst = worst.max((y - exact).abs());
        }
        assert!(worst < 1e-12, "foh h={h}: {worst}");
    }
}

#[test]
fn expm_against_closed_forms() {
    // rotation generator
    let th = 2.5f64;
    let m = DMatrix::from_row_slice(2, 2, &[0.0, -th, th, 0.0]);
    let e = expm(&m);
    let r = DMatrix::from_row_slice(
        2,
        2,
        &[
            dvpp_math::cos(th),
            -dvpp_math::sin(th),
            dvpp_math::sin(th),
            dvpp_math::cos(th),
        ],
    );
    assert!((e - r).amax() < 1e-14);
    // Jordan block with large norm
    let l = -80.0f64;
    let m = DMatrix::from_row_slice(2, 2, &[l, 1.0, 0.0, l]);
    let e = expm(&m);
    // 8 squarings: relative error a few 1e-14 on entries of size e^-80
    assert!((e[(0, 0)] - dvpp_math::exp(l)).abs() < 1e-13 * dvpp_math::exp(l));
    assert!((e[(0, 1)] - dvpp_math::exp(l)).abs() < 1e-13 * dvpp_math::exp(l));
    assert_eq!(e[(1, 0)], 0.0);
}

#[test]
fn discretization_cache_follows_step_size() {
    let (sys, _, _) = stiff_second_order();
    let mut a = LtiSimulator::new(sys.clone(), Hold::Zero);
    let mut b = LtiSimulator::new(sys, Hold::Zero);
    // a: alternate step sizes; b: a fresh discretization every time via a clone reset
    for k in 0..50 {
        let h = if k % 2 == 0 { 1e-3 } else { 1e-2 };
        let ya = a.step(1.0, h);
        let mut fresh = LtiSimulator::new(b.system().clone(), Hold::Zero);
        fresh.set_state(b.state().as_slice(), 0.0).unwrap();
        let yb = fresh.step(1.0, h);
        b.set_state(fresh.state().as_slice(), 1.0).unwrap();
        assert_eq!(ya, yb);
    }
}

#[test]
fn snapshots_roundtrip_through_serde() {
    let cs = CaseStudyI::new();
    let mut units = cs.gfm_pf_models().unwrap();
    for _ in 0..100 {
        for u in units.iter_mut() {
            u.step(0.02, 1e-3);
        }
    }
    let bytes = postcard::to_stdvec(&units).unwrap();
    let mut restored: Vec<GfmPfModel> = postcard::from_bytes(&bytes).unwrap();
    for _ in 0..100 {
        for (u, r) in units.iter_mut().zip(restored.iter_mut()) {
            let (a, b) = (u.step(0.02, 1e-3), r.step(0.02, 1e-3));
            assert!((a - b).abs() <= 1e-12 * (1.0 + a.abs()));
        }
    }
    let bank = ParticipationBank::new(&cs.lpf_specs(0.4, 0.6).unwrap()).unwrap();
    let back: ParticipationBank =
        postcard::from_bytes(&postcard::to_stdvec(&bank).unwrap()).unwrap();
    assert_eq!(back.gains(), bank.gains());
}
