//! Participation condition Σ m_i(jω) = 1 for random ADPF sets.

mod common;
use common::Rng;
use dvpp_control::*;

const TOL: f64 = 1e-12;

#[test]
fn lpf_plus_complement_random_gains() {
    let mut rng = Rng::new(0x5eed_0001);
    for _ in 0..200 {
        let n = rng.int(1, 5) as usize;
        let total = rng.range(0.2, 1.0);
        let mus = rng.simplex(n, total);
        let lpfs: Vec<Adpf> = mus
            .iter()
            .map(|mu| Adpf::low_pass(*mu, rng.log_range(0.01, 10.0), rng.int(1, 3)).unwrap())
            .collect();
        let mut set = lpfs.clone();
        set.push(Adpf::complement_of(&lpfs).unwrap());
        let e = check_participation(&set, &design_grid(), TOL).unwrap();
        assert!(e <= TOL, "{e}");
        // the rational-algebra form of the complement agrees with the factored form
        let c = set.last().unwrap();
        let tf = c.transfer_function();
        for w in [1e-3, 0.1, 3.0, 1e2, 1e4] {
            let (a, b) = (tf.freq_response(w), c.freq_response(w));
            assert!(
                dvpp_math::cabs(a - b) <= 1e-9 * (1.0 + dvpp_math::cabs(b)),
                "{w}: {a} vs {b}"
            );
        }
    }
}

#[test]
fn lpf_bpf_hpf_cascade_random_gains() {
    // LPF group at τ1 with gains summing to 1, BPF(τ1, τ2), HPF(τ2): telescoping sum = 1
    let mut rng = Rng::new(0x5eed_0002);
    for _ in 0..200 {
        let tau2 = rng.log_range(0.005, 1.0);
        let tau1 = tau2 * rng.range(1.5, 50.0);
        let n = rng.int(1, 4) as usize;
        let mut set: Vec<Adpf> = rng
            .simplex(n, 1.0)
            .iter()
            .map(|mu| Adpf::low_pass(*mu, tau1, 1).unwrap())
            .collect();
        set.push(Adpf::band_pass(tau1, tau2, 1, 1).unwrap());
        set.push(Adpf::high_pass(tau2, 1).unwrap());
        let e = max_participation_error(&set);
        assert!(e <= TOL, "{e}");
    }
}

#[test]
fn lpf_plus_hpf_same_tau() {
    let mut rng = Rng::new(0x5eed_0003);
    for _ in 0..100 {
        let tau = rng.log_range(0.01, 10.0);
        let mus = rng.simplex(3, 1.0);
        let mut set: Vec<Adpf> = mus
            .iter()
            .map(|m| Adpf::low_pass(*m, tau, 1).unwrap())
            .collect();
        set.push(Adpf::high_pass(tau, 1).unwrap());
        assert!(max_participation_error(&set) <= TOL);
        // complement of the LPFs equals the HPF here
        let c = Adpf::complement_of(&set[..3]).unwrap();
        let h = &set[3];
        for w in design_grid() {
            assert!(dvpp_math::cabs(c.freq_response(w) - h.freq_response(w)) <= TOL);
        }
    }
}

#[test]
fn hybrid_split_keeps_participation() {
    let mut rng = Rng::new(0x5eed_0004);
    for _ in 0..100 {
        let mus = rng.simplex(2, 1.0);
        let lpfs = vec![
            Adpf::low_pass(mus[0], rng.log_range(0.1, 5.0), 1).unwrap(),
            Adpf::low_pass(mus[1], rng.log_range(0.1, 5.0), 2).unwrap(),
        ];
        let comp = Adpf::complement_of(&lpfs).unwrap();
        let eps = rng.range(0.05, 0.95);
        let mut set = Vec::new();
        for a in lpfs.iter().chain(std::iter::once(&comp)) {
            set.push(a.scaled(eps).unwrap());
            set.push(a.scaled(1.0 - eps).unwrap());
        }
        assert!(max_participation_error(&set) <= TOL);
    }
}

#[test]
fn violated_participation_is_reported() {
    let set = vec![
        Adpf::low_pass(0.4, 1.5, 1).unwrap(),
        Adpf::low_pass(0.5, 0.6, 1).unwrap(),
    ];
    match check_participation(&set, &design_grid(), 1e-9) {
        Err(DvppError::ParticipationViolated { max_error, .. }) => assert!(max_error >= 0.1),
        other => panic!("expected violation, got {other:?}"),
    }
    // a complement not updated after the LPF gains moved also violates
    let old = Adpf::complement_of(&[
        Adpf::low_pass(0.5, 1.5, 1).unwrap(),
        Adpf::low_pass(0.5, 0.6, 1).unwrap(),
    ])
    .unwrap();
    let moved = vec![
        Adpf::low_pass(0.9, 1.5, 1).unwrap(),
        Adpf::low_pass(0.1, 0.6, 1).unwrap(),
        old,
    ];
    assert!(check_participation(&moved, &design_grid(), 1e-9).is_err());
}

#[test]
fn eval_set_and_grid() {
    let g = log_grid(1e-3, 1e4, 10);
    assert_eq!(g.len(), 71);
    assert!((g[0] - 1e-3).abs() < 1e-18 && (g[70] - 1e4).abs() < 1e-9);
    let cs = CaseStudyI::new();
    let [mw, mp] = cs.nominal_active_gains();
    let set = cs.active_adpfs(mw, mp).unwrap();
    let v = eval_set(&set, 0.0);
    assert!((v[0].re - 46.0 / 119.0).abs() < 1e-15);
    assert!((v[1].re - 73.0 / 119.0).abs() < 1e-15);
    assert!(dvpp_math::cabs(v[2]) < 1e-15);
}
