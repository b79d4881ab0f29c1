//! Typed errors on invalid parameters.

use dvpp_control::*;

#[test]
fn non_positive_time_constants() {
    for tau in [0.0, -1.0] {
        assert!(matches!(
            Adpf::low_pass(0.5, tau, 1),
            Err(DvppError::NonPositiveTimeConstant { .. })
        ));
        assert!(matches!(
            Adpf::high_pass(tau, 1),
            Err(DvppError::NonPositiveTimeConstant { .. })
        ));
        assert!(matches!(
            Adpf::band_pass(1.0, tau, 1, 1),
            Err(DvppError::NonPositiveTimeConstant { .. })
        ));
        assert!(matches!(
            TransferFunction::first_order_lag(1.0, tau),
            Err(DvppError::NonPositiveTimeConstant { .. })
        ));
        assert!(matches!(
            TDes::inertia_droop(5.55, 33.33, 0.01, tau),
            Err(DvppError::NonPositiveTimeConstant { .. })
        ));
        assert!(matches!(
            LowPassSpec::new(0.5, tau, 1),
            Err(DvppError::NonPositiveTimeConstant { .. })
        ));
    }
    assert!(matches!(
        Adpf::low_pass(0.5, f64::NAN, 1),
        Err(DvppError::NonFinite { .. })
    ));
    assert!(matches!(
        Adpf::band_pass(0.1, 1.0, 1, 1),
        Err(DvppError::InvalidParameter { .. })
    ));
    assert!(matches!(
        Adpf::low_pass(0.5, 1.0, 0),
        Err(DvppError::InvalidParameter { .. })
    ));
}

#[test]
fn gains_outside_unit_interval() {
    for mu in [-0.1, 1.2] {
        assert!(matches!(
            Adpf::low_pass(mu, 1.0, 1),
            Err(DvppError::GainOutOfRange { .. })
        ));
        let cs = CaseStudyI::new();
        assert!(matches!(
            VqModel::grid_forming(&cs.tdes, mu),
            Err(DvppError::GainOutOfRange { .. })
        ));
    }
    // complement of gains summing above 1
    let l = vec![
        Adpf::low_pass(0.7, 1.0, 1).unwrap(),
        Adpf::low_pass(0.6, 0.5, 1).unwrap(),
    ];
    assert!(matches!(
        Adpf::complement_of(&l),
        Err(DvppError::GainOutOfRange { .. })
    ));
    // complement of a non-LPF
    assert!(matches!(
        Adpf::complement_of(&[Adpf::high_pass(1.0, 1).unwrap()]),
        Err(DvppError::WrongUnitKind { .. })
    ));
    // grid-forming LPF below μ_min
    let cs = CaseStudyI::new();
    match GfmPfModel::new(&cs.tdes, &Adpf::low_pass(0.01, 0.6, 1).unwrap()) {
        Err(DvppError::GainOutOfRange { min, .. }) => assert_eq!(min, MU_MIN_GFM),
        other => panic!("{other:?}"),
    }
    // bank and complement gain updates
    let mut bank = ParticipationBank::new(&cs.lpf_specs(0.4, 0.6).unwrap()).unwrap();
    assert!(matches!(
        bank.set_gains(&[0.8, 0.5]),
        Err(DvppError::GainOutOfRange { .. })
    ));
    assert!(matches!(
        bank.set_gains(&[0.8]),
        Err(DvppError::DimensionMismatch { .. })
    ));
    let mut units = cs.gfm_pf_models().unwrap();
    assert!(units[2].set_lpf_gains(&[0.9, 0.9]).is_err());
    assert!(matches!(
        units[0].set_lpf_gains(&[0.5, 0.5]),
        Err(DvppError::WrongUnitKind { .. })
    ));
    assert!(matches!(
        units[2].set_mu(0.5),
        Err(DvppError::WrongUnitKind { .. })
    ));
    assert!(matches!(
        renormalize_with_floor(&[1.0; 30], &[true; 30], MU_MIN_GFM),
        Err(DvppError::InfeasibleGains { .. })
    ));
    assert!(matches!(
        active_gains(&[0.0, 0.0]),
        Err(DvppError::InfeasibleGains { .. })
    ));
}

#[test]
fn improper_inverse_and_quotients() {
    let lag = TransferFunction::first_order_lag(1.0, 0.5).unwrap();
    assert!(matches!(
        lag.inverse(),
        Err(DvppError::ImproperInverse {
            relative_degree: 1,
            ..
        })
    ));
    let bi = TransferFunction::new(vec![1.0, 2.0], vec![3.0, 1.0]).unwrap();
    let inv = bi.inverse().unwrap();
    assert!(dvpp_math::cabs(inv.mul(&bi).freq_response(3.0) - Complex::new(1.0, 0.0)) < 1e-15);
    assert!(matches!(
        TransferFunction::new(vec![0.0, 0.0, 1.0], vec![1.0, 1.0]),
        Err(DvppError::Improper { .. })
    ));
    assert!(matches!(
        TransferFunction::new(vec![1.0], vec![0.0, 0.0]),
        Err(DvppError::ZeroPolynomial { .. })
    ));
    let cs = CaseStudyI::new();
    // grid-following reference without PLL roll-off: T_pf⁻¹ = H s + D is improper
    assert!(matches!(
        GflFpModel::new(&cs.tdes, &Adpf::low_pass(0.5, 1.0, 1).unwrap(), 0.02, 0),
        Err(DvppError::ImproperInverse { .. })
    ));
    // second-order LPF on a grid-forming unit: (τ s+1)² / (H s + D) is improper
    assert!(matches!(
        GfmPfModel::new(&cs.tdes, &Adpf::low_pass(0.5, 1.0, 2).unwrap()),
        Err(DvppError::ImproperInverse { .. })
    ));
    // strictly proper T_qv (relative degree 2) has no proper inverse even with τ_q roll-off
    let qv = TransferFunction::new(vec![1.0], vec![1.0, 2.0, 1.0]).unwrap();
    assert!(matches!(
        TDes::general(cs.tdes.pf().clone(), qv, 0.01),
        Err(DvppError::ImproperInverse { .. })
    ));
}

#[test]
fn unstable_t_des() {
    assert!(matches!(
        TDes::inertia_droop(-5.55, 33.33, 0.01, 0.01),
        Err(DvppError::Unstable { .. })
    ));
    assert!(matches!(
        TDes::inertia_droop(5.55, -1.0, 0.01, 0.01),
        Err(DvppError::Unstable { .. })
    ));
    assert!(matches!(
        TDes::inertia_droop(5.55, 0.0, 0.01, 0.01),
        Err(DvppError::Unstable { .. })
    ));
    assert!(matches!(
        TDes::inertia_droop(5.55, 33.33, 0.0, 0.01),
        Err(DvppError::InvalidParameter { .. })
    ));
    let unstable = TransferFunction::new(vec![1.0], vec![-1.0, 1.0]).unwrap();
    assert!(matches!(
        TDes::general(unstable, TransferFunction::gain(0.01).unwrap(), 0.01),
        Err(DvppError::Unstable { .. })
    ));
    // marginal (pure integrator) is rejected too
    let integ = TransferFunction::new(vec![1.0], vec![0.0, 1.0]).unwrap();
    assert!(matches!(
        TDes::general(integ, TransferFunction::gain(0.01).unwrap(), 0.01),
        Err(DvppError::Unstable { .. })
    ));
}

#[test]
fn errors_are_std_errors_with_messages() {
    let e: Box<dyn std::error::Error> = Box::new(Adpf::low_pass(2.0, 1.0, 1).unwrap_err());
    let msg = e.to_string();
    assert!(msg.contains("outside [0, 1]"), "{msg}");
}

#[test]
fn general_t_des_works_end_to_end() {
    // T_pf with an extra governor-like lag: 1/((H s + D)(0.1 s + 1)) and a dynamic T_qv
    let pf = TransferFunction::new(vec![1.0], vec![33.33, 5.55])
        .unwrap()
        .mul(&TransferFunction::first_order_lag(1.0, 0.1).unwrap());
    let qv = TransferFunction::new(vec![0.01, 0.001], vec![1.0, 0.05]).unwrap();
    let tdes = TDes::general(pf, qv, 0.01).unwrap();
    let lp = vec![
        Adpf::low_pass(0.3, 1.5, 2).unwrap(),
        Adpf::low_pass(0.7, 0.6, 1).unwrap(),
    ];
    let mut set = lp.clone();
    set.push(Adpf::complement_of(&lp).unwrap());
    let gfm: Vec<GfmPfModel> = set
        .iter()
        .map(|a| GfmPfModel::new(&tdes, a).unwrap())
        .collect();
    check_gfm_aggregation(&tdes, &gfm, &design_grid(), 1e-9).unwrap();
    let vq: Vec<VqModel> = [0.2, 0.3, 0.5]
        .iter()
        .map(|m| VqModel::grid_forming(&tdes, *m).unwrap())
        .collect();
    check_voltage_aggregation(&tdes, &vq, &design_grid(), 1e-12).unwrap();
    for u in &gfm {
        u.check_stability().unwrap();
    }
}
