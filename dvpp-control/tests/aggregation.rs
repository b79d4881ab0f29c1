//! Aggregation conditions evaluated on the realized local reference models.

mod common;
use common::Rng;
use dvpp_control::*;

#[test]
fn case_i_grid_forming_aggregation_equals_t_pf() {
    let cs = CaseStudyI::new();
    let units = cs.gfm_pf_models().unwrap();
    let e = check_gfm_aggregation(&cs.tdes, &units, &design_grid(), 1e-9).unwrap();
    assert!(e <= 1e-9, "{e}");
    for u in &units {
        u.check_stability().unwrap();
    }
}

#[test]
fn gfm_aggregation_random_gains_including_floor() {
    let cs = CaseStudyI::new();
    let mut rng = Rng::new(0xa99);
    for k in 0..30 {
        let (pw, pp) = if k == 0 {
            (46.0, 0.0)
        } else {
            (rng.range(0.0, 46.0), rng.range(0.0, 73.0))
        };
        let [mw, mp] = cs.active_gains(pw, pp).unwrap();
        assert!(mw >= MU_MIN_GFM && mp >= MU_MIN_GFM && (mw + mp - 1.0).abs() < 1e-15);
        let units: Vec<GfmPfModel> = cs
            .active_adpfs(mw, mp)
            .unwrap()
            .iter()
            .map(|a| GfmPfModel::new(&cs.tdes, a).unwrap())
            .collect();
        check_gfm_aggregation(&cs.tdes, &units, &design_grid(), 1e-9).unwrap();
    }
}

#[test]
fn online_gain_update_keeps_aggregation_and_stale_complement_breaks_it() {
    let cs = CaseStudyI::new();
    let mut units = cs.gfm_pf_models().unwrap();
    // cloud: PV availability drops to 10 % of nominal
    let [mw, mp] = cs.active_gains(46.0, 7.3).unwrap();
    units[0].set_mu(mw).unwrap();
    units[1].set_mu(mp).unwrap();
    // complement not yet informed -> aggregation violated
    assert!(matches!(
        check_gfm_aggregation(&cs.tdes, &units, &design_grid(), 1e-6),
        Err(DvppError::AggregationViolated { .. })
    ));
    units[2].set_lpf_gains(&[mw, mp]).unwrap();
    check_gfm_aggregation(&cs.tdes, &units, &design_grid(), 1e-9).unwrap();
}

#[test]
fn realization_matches_rational_algebra() {
    let cs = CaseStudyI::new();
    let gfm = cs.gfm_pf_models().unwrap();
    let (hgfm, hgfl) = cs.hybrid_pf_models(0.5).unwrap();
    let vq = cs.vq_models().unwrap();
    for w in log_grid(1e-2, 1e4, 5) {
        for u in gfm.iter().chain(hgfm.iter()) {
            let (a, b) = (
                u.freq_response(w),
                u.transfer_function().unwrap().freq_response(w),
            );
            assert!(
                dvpp_math::cabs(a - b) <= 1e-8 * dvpp_math::cabs(b),
                "gfm {w}: {a} {b}"
            );
        }
        for u in &hgfl {
            let (a, b) = (
                u.freq_response(w),
                u.transfer_function().unwrap().freq_response(w),
            );
            assert!(
                dvpp_math::cabs(a - b) <= 1e-8 * dvpp_math::cabs(b).max(1e-12),
                "gfl {w}: {a} {b}"
            );
        }
        for u in &vq {
            let (a, b) = (u.freq_response(w), u.transfer_function().freq_response(w));
            assert!(
                dvpp_math::cabs(a - b) <= 1e-10 * dvpp_math::cabs(b),
                "vq {w}"
            );
        }
    }
}

#[test]
fn hybrid_aggregation_up_to_pll_rolloff() {
    let cs = CaseStudyI::new();
    for eps in [0.25, 0.5, 0.75] {
        let (gfm, gfl) = cs.hybrid_pf_models(eps).unwrap();
        let rep = check_hybrid_aggregation(&cs.tdes, &gfm, &gfl, &design_grid(), 1e-9).unwrap();
        assert!(rep.compensated <= 1e-9, "{rep:?}");
        // below 0.1/τ_pll the raw mismatch is bounded by ~ (1-ε)·ωτ_pll ≤ 0.1
        assert!(rep.raw_in_band <= 0.1, "{rep:?}");
        assert!(
            rep.raw_in_band > 1e-6,
            "the PLL roll-off must be visible: {rep:?}"
        );
        for u in &gfm {
            u.check_stability().unwrap();
        }
        for u in &gfl {
            u.check_stability().unwrap();
        }
    }
}

#[test]
fn voltage_aggregation() {
    let cs = CaseStudyI::new();
    let vq = cs.vq_models().unwrap();
    let e = check_voltage_aggregation(&cs.tdes, &vq, &design_grid(), 1e-12).unwrap();
    assert!(e <= 1e-12);
    // mixed grid-forming / grid-following with a cloud-shifted operating point
    let mu = cs.reactive_gains([30.0, 10.0, 0.0]).unwrap();
    assert!(
        mu[1] > 73.0 / 179.0,
        "PV reactive participation rises when its P drops"
    );
    let units = vec![
        VqModel::grid_forming(&cs.tdes, mu[0]).unwrap(),
        VqModel::grid_following(&cs.tdes, mu[1], cs.tau_pll, 1).unwrap(),
        VqModel::grid_forming(&cs.tdes, mu[2]).unwrap(),
    ];
    check_voltage_aggregation(&cs.tdes, &units, &design_grid(), 1e-12).unwrap();
    // wrong gains are caught
    let bad = vec![VqModel::grid_forming(&cs.tdes, 0.5).unwrap()];
    assert!(check_voltage_aggregation(&cs.tdes, &bad, &design_grid(), 1e-6).is_err());
}

#[test]
fn full_design_validation_case_i() {
    let cs = CaseStudyI::new();
    let gfm = cs.gfm_pf_models().unwrap();
    let vq = cs.vq_models().unwrap();
    let rep = validate_design(&cs.tdes, &gfm, &[], &vq, &design_grid(), 1e-9).unwrap();
    assert!(
        rep.participation_pf <= 1e-12 && rep.voltage <= 1e-12,
        "{rep:?}"
    );
    let (hgfm, hgfl) = cs.hybrid_pf_models(0.25).unwrap();
    validate_design(&cs.tdes, &hgfm, &hgfl, &vq, &design_grid(), 1e-9).unwrap();
}

#[test]
fn complement_unit_has_exactly_one_integrator() {
    let cs = CaseStudyI::new();
    let units = cs.gfm_pf_models().unwrap();
    let t = units[2].transfer_function().unwrap();
    let origin = t
        .poles()
        .iter()
        .filter(|p| dvpp_math::cabs(**p) < 1e-9)
        .count();
    assert_eq!(origin, 1);
    assert!(!t.is_stable());
    assert!(t.is_stable_allowing_integrator(1e-9));
    // the LPF units are strictly stable, biproper
    let t0 = units[0].transfer_function().unwrap();
    assert!(t0.is_stable() && t0.is_biproper());
}

#[test]
fn random_gfm_sets_aggregate_and_are_stable() {
    let cs = CaseStudyI::new();
    let mut rng = Rng::new(0xbeef);
    for _ in 0..40 {
        let n = rng.int(1, 4) as usize;
        // gains ≥ μ_min, summing to a random total ≤ 1 (the complement closes the rest)
        let total = rng.range(0.3, 1.0);
        let raw = rng.simplex(n, 1.0);
        let mus = renormalize_with_floor(&raw, &vec![true; n], MU_MIN_GFM / total).unwrap();
        let lpfs: Vec<Adpf> = mus
            .iter()
            .map(|m| Adpf::low_pass(m * total, rng.log_range(0.05, 5.0), 1).unwrap())
            .collect();
        let mut set = lpfs.clone();
        set.push(Adpf::complement_of(&lpfs).unwrap());
        let units: Vec<GfmPfModel> = set
            .iter()
            .map(|a| GfmPfModel::new(&cs.tdes, a).unwrap())
            .collect();
        check_gfm_aggregation(&cs.tdes, &units, &design_grid(), 1e-9).unwrap();
        for u in &units {
            u.check_stability().unwrap();
        }
    }
}
