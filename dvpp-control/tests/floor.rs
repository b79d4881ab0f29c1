//! Tests of the per-unit floor of a grid-forming low-pass unit's dc gain (`mu_min_gfm`).
//!
//! Feasible for any number of units, exact participation sums, every floor respected.

use dvpp_control::{
    mu_min_gfm, renormalize_with_floor, renormalize_with_floors, Adpf, CaseStudyI, DvppError,
    GfmPfModel, MU_FLOOR_KAPPA, MU_MIN_GFM,
};

fn assert_gains(mu: &[f64], floors: &[f64], what: &str) {
    let sum: f64 = mu.iter().sum();
    assert!((sum - 1.0).abs() < 1e-12, "{what}: Σμ = {sum}");
    for (i, (m, f)) in mu.iter().zip(floors).enumerate() {
        assert!(
            *m >= *f * (1.0 - 1e-12),
            "{what}: unit {i}: μ = {m} < floor {f}"
        );
        assert!(*m <= 1.0, "{what}: unit {i}: μ = {m} > 1");
    }
}

#[test]
fn large_units_keep_the_fixed_floor_small_ones_scale_with_their_share() {
    // Case study I: wind 46 MVA and PV 73 MVA in a 96 MVA DVPP keep 0.05.
    assert_eq!(mu_min_gfm(46.0, 96.0), MU_MIN_GFM);
    assert_eq!(mu_min_gfm(73.0, 96.0), MU_MIN_GFM);
    // The crossover at MU_MIN_GFM/κ of the DVPP rating.
    let cross = MU_MIN_GFM / MU_FLOOR_KAPPA * 96.0;
    assert!((mu_min_gfm(cross, 96.0) - MU_MIN_GFM).abs() < 1e-15);
    assert!((mu_min_gfm(0.5 * cross, 96.0) - 0.5 * MU_MIN_GFM).abs() < 1e-15);
    // Stiffness per unit of own rating μ S_dvpp/S_i is κ at the floor.
    let (s, sd) = (1.79, 96.0);
    assert!((mu_min_gfm(s, sd) * sd / s - MU_FLOOR_KAPPA).abs() < 1e-12);
    // Invalid ratings fall back to the fixed floor.
    for (s, sd) in [(0.0, 96.0), (-1.0, 96.0), (f64::NAN, 96.0), (10.0, 0.0)] {
        assert_eq!(mu_min_gfm(s, sd), MU_MIN_GFM, "{s} {sd}");
    }
}

#[test]
fn a_thousand_equal_units_are_feasible_and_sum_to_one() {
    // Case study I's low-pass totals (46 + 73 MVA) in a 96 MVA DVPP, split into n equal units.
    for n in [3usize, 20, 24, 200, 1000] {
        let s_i = 119.0 / n as f64;
        let floors = vec![mu_min_gfm(s_i, 96.0); n];
        // The fixed floor alone is infeasible from 21 units on.
        if n as f64 * MU_MIN_GFM > 1.0 {
            assert!(matches!(
                renormalize_with_floor(&vec![1.0; n], &vec![true; n], MU_MIN_GFM),
                Err(DvppError::InfeasibleGains { .. })
            ));
        }
        // Equal availability, availability all on one unit, and none at all.
        let mut one = vec![0.0; n];
        one[n / 2] = 1.0;
        for (w, what) in [
            (vec![1.0; n], "equal"),
            (one, "one unit available"),
            (vec![0.0; n], "none available"),
        ] {
            let mu = renormalize_with_floors(&w, &floors).unwrap();
            assert_gains(&mu, &floors, &format!("n = {n}, {what}"));
        }
    }
}

#[test]
fn unequal_floors_pin_the_units_below_them_and_share_the_rest() {
    // Two large units at 0.05 and 100 small ones at κ·0.002 = 0.0005.
    let mut floors = vec![MU_MIN_GFM, MU_MIN_GFM];
    floors.extend(vec![mu_min_gfm(0.192, 96.0); 100]);
    let mut w = vec![0.0, 1e-4];
    w.extend((0..100).map(|k| k as f64));
    let mu = renormalize_with_floors(&w, &floors).unwrap();
    assert_gains(&mu, &floors, "unequal");
    assert_eq!(mu[0], MU_MIN_GFM);
    assert_eq!(mu[1], MU_MIN_GFM);
    assert_eq!(mu[2], floors[2]);
    // The free units stay proportional to their weights.
    assert!((mu[101] / mu[51] - 99.0 / 49.0).abs() < 1e-12);
    // Floors summing to more than 1 are rejected with the sum in the message.
    match renormalize_with_floors(&[1.0; 3], &[0.5, 0.4, 0.2]) {
        Err(DvppError::InfeasibleGains { reason }) => assert!(reason.contains("1.1"), "{reason}"),
        r => panic!("{r:?}"),
    }
    assert!(renormalize_with_floors(&[1.0], &[-0.1]).is_err());
    assert!(renormalize_with_floors(&[1.0, 2.0], &[0.0]).is_err());
}

#[test]
fn a_unit_built_with_its_own_floor_clamps_there() {
    let cs = CaseStudyI::new();
    let floor = mu_min_gfm(0.6, 96.0);
    let adpf = Adpf::low_pass(floor, 0.6, 1).unwrap();
    // The fixed floor rejects the gain, the unit's own accepts it.
    assert!(matches!(
        GfmPfModel::new(&cs.tdes, &adpf),
        Err(DvppError::GainOutOfRange { .. })
    ));
    let mut unit = GfmPfModel::with_floor(&cs.tdes, &adpf, floor).unwrap();
    assert_eq!(unit.mu_min(), floor);
    assert_eq!(unit.set_mu(0.0).unwrap(), floor);
    assert_eq!(unit.set_mu(0.3).unwrap(), 0.3);
    // A floor above the fixed one or not positive is refused.
    for bad in [0.0, -0.01, 0.06, f64::NAN] {
        assert!(
            GfmPfModel::with_floor(&cs.tdes, &adpf, bad).is_err(),
            "{bad}"
        );
    }
}
