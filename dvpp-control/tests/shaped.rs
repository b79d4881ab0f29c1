//! Static ADPFs, shaped v-q references with moving gains, and the exact angle integral.

mod common;
use common::Rng;
use dvpp_control::*;

#[test]
fn static_units_close_the_participation_condition_with_the_others() {
    let mut rng = Rng::new(0x5eed_0042);
    for _ in 0..100 {
        let mu_static = rng.range(0.0, 0.5);
        let mus = rng.simplex(2, 1.0 - mu_static);
        let lpfs: Vec<Adpf> = mus
            .iter()
            .map(|mu| Adpf::low_pass(*mu, rng.log_range(0.05, 5.0), rng.int(1, 2)).unwrap())
            .collect();
        let specs: Vec<LowPassSpec> = lpfs
            .iter()
            .map(|a| match a {
                Adpf::LowPass(s) => *s,
                _ => unreachable!(),
            })
            .collect();
        let sum_lpf: f64 = mus.iter().sum();
        let mut set = lpfs.clone();
        set.push(Adpf::static_gain(mu_static).unwrap());
        // The complement closes what the static and low-pass units leave: c = 1 - μ_static.
        set.push(Adpf::complement_of_specs(1.0 - mu_static, specs).unwrap());
        assert!(sum_lpf <= 1.0 - mu_static + 1e-12);
        let e = check_participation(&set, &design_grid(), 1e-12).unwrap();
        assert!(e <= 1e-12, "{e}");
    }
    assert!(Adpf::static_gain(1.5).is_err());
    assert_eq!(Adpf::static_gain(0.3).unwrap().kind_name(), "static");
    // A complement needs a roll-off: a static member is refused.
    assert!(Adpf::complement_of_specs(1.0, vec![LowPassSpec::static_gain(0.5).unwrap()]).is_err());
}

#[test]
fn static_grid_forming_unit_is_t_pf_over_mu() {
    let cs = CaseStudyI::new();
    let unit = GfmPfModel::new(&cs.tdes, &Adpf::static_gain(0.4).unwrap()).unwrap();
    for w in design_grid() {
        let want = cs.tdes.pf_at(w) / 0.4;
        assert!(dvpp_math::cabs(unit.freq_response(w) - want) <= 1e-12 * dvpp_math::cabs(want));
    }
}

#[test]
fn shaped_vq_units_aggregate_while_gains_move() {
    // v-q ADPFs: wind and PV low-pass, the BESS their complement; every unit sees the same Δv.
    let cs = CaseStudyI::new();
    let [w, p, b] = cs.active_adpfs(0.4, 0.6).unwrap();
    let mut units: Vec<VqModel> = [&w, &p, &b]
        .iter()
        .map(|a| VqModel::grid_forming_shaped(&cs.tdes, a).unwrap())
        .collect();
    check_voltage_aggregation(&cs.tdes, &units, &design_grid(), 1e-12).unwrap();
    let mut whole = VqModel::grid_forming(&cs.tdes, 1.0).unwrap();
    let h = 1e-3;
    let mut worst: f64 = 0.0;
    for k in 0..4000 {
        let t = k as f64 * h;
        let mu_w = 0.2 + 0.6 * t / 4.0;
        units[0].set_mu(mu_w).unwrap();
        units[1].set_mu(1.0 - mu_w).unwrap();
        units[2].set_lpf_gains(&[mu_w, 1.0 - mu_w]).unwrap();
        let dv = 0.01 * dvpp_math::sin(2.0 * t) + if t > 1.0 { -0.02 } else { 0.0 };
        let sum: f64 = units.iter_mut().map(|u| u.step(dv, h)).sum();
        let want = whole.step(dv, h);
        worst = worst.max((sum - want).abs() / (1.0 + want.abs()));
    }
    assert!(worst <= 1e-9, "{worst}");
}

#[test]
fn grid_forming_angle_integral_is_exact() {
    // Static unit: Δf = -Δp/(μ D)(1 - e^{-D t/H}); ∫Δf = -Δp/(μ D)(t - H/D (1 - e^{-D t/H})).
    let cs = CaseStudyI::new();
    let (hh, dd, mu) = (5.55, 33.33, 0.5);
    for h in [1e-4_f64, 1e-3, 1e-2] {
        let mut unit = GfmPfModel::new(&cs.tdes, &Adpf::static_gain(mu).unwrap()).unwrap();
        let mut integral = 0.0;
        let n = (2.0 / h).round() as usize;
        for k in 1..=n {
            integral += unit.step_with_integral(0.1, h).1;
            let t = k as f64 * h;
            let exact = -0.1 / (mu * dd) * (t - hh / dd * (1.0 - dvpp_math::exp(-dd * t / hh)));
            assert!(
                (integral - exact).abs() < 1e-12,
                "h = {h}, t = {t}: {integral} vs {exact}"
            );
        }
    }
}
