//! Power flow, flat start, load step, power balance, events, inputs and snapshots.
use grid_model::analysis::{run_load_step, run_load_step_with};
use grid_model::{Case, DerInput, DerSetpoint, Event, EventOverride, Grid, LoadModel};

#[test]
fn ieee9_power_flow_matches_reference() {
    // published power-flow solution of the WSCC 9-bus system (Anderson & Fouad, MATPOWER case9)
    let vm = [
        1.04, 1.025, 1.025, 1.0258, 1.0127, 1.0324, 1.0159, 1.0258, 0.9956,
    ];
    let va = [
        0.0, 9.28, 4.665, -2.217, -3.687, 1.967, 0.728, 3.720, -3.989,
    ];
    let g = Grid::new(&Case::builtin("ieee9_af").unwrap()).unwrap();
    let pf = g.power_flow();
    for i in 0..9 {
        assert!(
            (dvpp_math::cabs(pf.v[i]) - vm[i]).abs() < 1e-3,
            "bus {} |V| {}",
            i + 1,
            dvpp_math::cabs(pf.v[i])
        );
        assert!(
            (dvpp_math::carg(pf.v[i]).to_degrees() - va[i]).abs() < 0.05,
            "bus {} angle {}",
            i + 1,
            dvpp_math::carg(pf.v[i]).to_degrees()
        );
    }
    assert!(
        (pf.machine_pq[0].0 * 100.0 - 71.64).abs() < 0.01,
        "gen 1 {}",
        pf.machine_pq[0].0
    );
    assert!((pf.machine_pq[1].0 - 1.63).abs() < 1e-12);
}

fn flat_start(name: &str) {
    let mut g = Grid::new(&Case::builtin(name).unwrap()).unwrap();
    g.disable_events();
    assert!(
        g.max_derivative().unwrap() < 1e-10,
        "{name}: initial derivative {}",
        g.max_derivative().unwrap()
    );
    let init = g.der_initial();
    let h = 0.01;
    for i in 0..1000 {
        // DER inputs held at their initial values, set every step as a master would
        for (k, s) in init.iter().enumerate() {
            let inp = match *s {
                DerSetpoint::GridForming { theta0, e0 } => DerInput::GridForming {
                    theta: theta0,
                    e: e0,
                },
                DerSetpoint::GridFollowing { p0, q0 } => DerInput::GridFollowing {
                    p_ref: p0,
                    q_ref: q0,
                },
            };
            g.set_der_input(k, inp).unwrap();
        }
        g.step(i as f64 * h, h).unwrap();
        let o = g.outputs();
        assert!(
            (o.coi_f - 1.0).abs() < 1e-6,
            "{name} t={} coi {}",
            o.t,
            o.coi_f
        );
        assert!(
            (o.pcc.f - 1.0).abs() < 1e-6,
            "{name} t={} pcc.f {}",
            o.t,
            o.pcc.f
        );
        for m in &o.sg {
            assert!(
                (m.omega - 1.0).abs() < 1e-6,
                "{name} t={} omega {}",
                o.t,
                m.omega
            );
        }
        assert!(o.balance_p.abs() < 1e-6, "{name} balance {}", o.balance_p);
    }
    assert!((g.time() - 10.0).abs() < 1e-9);
}

#[test]
fn flat_start_ieee9() {
    flat_start("ieee9");
}
#[test]
fn flat_start_ieee9_af() {
    flat_start("ieee9_af");
}

#[test]
fn flat_start_ieee9_dvpp() {
    flat_start("ieee9_dvpp");
}
#[test]
fn flat_start_ieee9_hybrid() {
    flat_start("ieee9_hybrid");
}

#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "300 s of dynamics: run with `cargo test -p grid-model --release`"
)]
fn load_step_28mw_bus5_ieee9() {
    let case = Case::builtin("ieee9").unwrap();
    let fig = run_load_step(&case, 5, 28.0, 1.0, 300.0, 0.01).unwrap();
    println!("{fig}");
    // power balance at every communication step
    assert!(
        fig.max_balance_error < 1e-6,
        "balance {}",
        fig.max_balance_error
    );
    // frequency falls, nadir below the settled value, RoCoF matches the swing equation
    assert!(fig.nadir < fig.f_settled && fig.f_settled < 1.0);
    assert!(fig.t_nadir > 1.0 && fig.t_nadir < 10.0);
    assert!(((fig.rocof_initial / fig.rocof_analytic) - 1.0).abs() < 0.02);
    // quasi steady state = droop law for the power the machines actually picked up
    let df = fig.f_settled - 1.0;
    assert!(
        ((df / fig.df_droop_measured_dp) - 1.0).abs() < 0.02,
        "droop: sim {df:e}, analytic {:e}",
        fig.df_droop_measured_dp
    );
    // and the machines picked up the step, less the constant-impedance load relief
    assert!(fig.dpe_total > 0.2 && fig.dpe_total < 0.3);
}

#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "300 s of dynamics: run with `cargo test -p grid-model --release`"
)]
fn load_step_constant_power_matches_nominal_droop() {
    // With constant-power loads the step is exactly 28 MW; only the change in losses separates
    // the machines' power change from it.
    let mut case = Case::builtin("ieee9").unwrap();
    for l in &mut case.loads {
        l.model = LoadModel::ConstantPower;
    }
    let fig =
        run_load_step_with(&case, 5, 28.0, LoadModel::ConstantPower, 1.0, 300.0, 0.01).unwrap();
    println!("{fig}");
    let df = fig.f_settled - 1.0;
    assert!(((df / fig.df_droop_measured_dp) - 1.0).abs() < 0.02);
    assert!(((df / fig.df_droop_nominal_dp) - 1.0).abs() < 0.05);
    assert!(fig.max_balance_error < 1e-6);
}

#[test]
fn dvpp_case_event_fires_and_dvpp_picks_up() {
    let mut g = Grid::new(&Case::builtin("ieee9_dvpp").unwrap()).unwrap();
    let p0 = g.outputs().pcc.p;
    assert!((p0 - 0.815).abs() < 1e-9);
    let h = 0.01;
    for i in 0..200 {
        g.step(i as f64 * h, h).unwrap();
        let o = g.outputs();
        assert!(o.balance_p.abs() < 1e-6);
        if o.t < 1.0 - 1e-9 {
            assert!((o.pcc.p - p0).abs() < 1e-9);
        }
    }
    assert!(g.events()[0].fired);
    let o = g.outputs();
    // inputs held: the DVPP is stiff and supplies most of the 28 MW at once
    assert!(o.pcc.p - p0 > 0.1, "pcc.p {}", o.pcc.p);
    assert_eq!(o.der.len(), 3);
    let sum: f64 = o.der.iter().map(|d| d.p).sum();
    assert!((sum - o.pcc.p).abs() < 1e-12);
}

#[test]
fn event_override_and_time() {
    let mut g = Grid::new(&Case::builtin("ieee9_dvpp").unwrap()).unwrap();
    g.set_event_override(
        0,
        EventOverride {
            time: Some(0.05),
            dp_mw: Some(10.0),
            ..Default::default()
        },
    )
    .unwrap();
    let p0 = g.outputs().pcc.p;
    g.step(0.0, 0.02).unwrap();
    assert!(!g.events()[0].fired);
    g.step(0.02, 0.02).unwrap();
    assert!(!g.events()[0].fired);
    g.step(0.04, 0.02).unwrap();
    assert!(g.events()[0].fired);
    let dp = g.outputs().pcc.p - p0;
    assert!(dp > 0.05 && dp < 0.11, "dp {dp}");
    assert!(g
        .set_event_override(
            0,
            EventOverride {
                enabled: Some(false),
                ..Default::default()
            }
        )
        .is_err());
}

#[test]
fn gfm_input_is_direct_feedthrough() {
    let mut g = Grid::new(&Case::builtin("ieee9_dvpp").unwrap()).unwrap();
    let DerSetpoint::GridForming { theta0, e0 } = g.der_initial()[0] else {
        panic!()
    };
    let p0 = g.outputs().der[0].p;
    g.set_der_input(
        0,
        DerInput::GridForming {
            theta: theta0 + 0.02,
            e: e0,
        },
    )
    .unwrap();
    assert!(g.outputs().der[0].p > p0 + 0.01);
    assert!(g
        .set_der_input(
            0,
            DerInput::GridFollowing {
                p_ref: 0.0,
                q_ref: 0.0
            }
        )
        .is_err());
    assert!(g
        .set_der_input(7, DerInput::GridForming { theta: 0.0, e: 1.0 })
        .is_err());
}

#[test]
fn gfl_injection_follows_reference() {
    let mut g = Grid::new(&Case::builtin("ieee9_hybrid").unwrap()).unwrap();
    g.disable_events();
    g.set_der_input(
        4,
        DerInput::GridFollowing {
            p_ref: 0.3,
            q_ref: 0.05,
        },
    )
    .unwrap();
    let o = g.outputs();
    assert!((o.der[4].p - 0.3).abs() < 1e-12 && (o.der[4].q - 0.05).abs() < 1e-12);
    assert!(o.balance_p.abs() < 1e-9);
    for i in 0..100 {
        g.step(i as f64 * 0.01, 0.01).unwrap();
    }
    // more generation at bus 2 than load: frequency of the machines rises (GFM held)
    assert!(g.outputs().balance_p.abs() < 1e-9);
}

#[test]
fn generator_and_line_trip() {
    let case = Case::builtin("ieee9").unwrap();
    let mut g = Grid::new(&case).unwrap();
    g.add_event(Event::GeneratorTrip {
        time: 0.5,
        machine: 3,
    })
    .unwrap();
    g.add_event(Event::LineTrip {
        time: 1.0,
        branch: "L5-6".into(),
    })
    .unwrap();
    for i in 0..300 {
        g.step(i as f64 * 0.01, 0.01).unwrap();
        assert!(g.outputs().balance_p.abs() < 1e-6);
    }
    let o = g.outputs();
    assert!(!o.sg[2].in_service && o.sg[2].p == 0.0);
    assert!(o.coi_f < 1.0);
    assert!(g
        .add_event(Event::LineTrip {
            time: 4.0,
            branch: "nope".into()
        })
        .is_err());
}

#[test]
fn snapshot_roundtrip_continues_identically() {
    let mut g = Grid::new(&Case::builtin("ieee9").unwrap()).unwrap();
    g.add_event(Event::LoadStep {
        time: 0.1,
        bus: 5,
        dp_mw: 28.0,
        dq_mvar: 0.0,
        model: LoadModel::ConstantImpedance,
    })
    .unwrap();
    for i in 0..50 {
        g.step(i as f64 * 0.01, 0.01).unwrap();
    }
    let bytes = postcard::to_stdvec(&g).unwrap();
    let mut h: Grid = postcard::from_bytes(&bytes).unwrap();
    let mut c = g.clone();
    for i in 50..100 {
        g.step(i as f64 * 0.01, 0.01).unwrap();
        h.step(i as f64 * 0.01, 0.01).unwrap();
        c.step(i as f64 * 0.01, 0.01).unwrap();
    }
    // A restored snapshot and a clone continue bit for bit.
    let (a, b, d) = (g.outputs(), h.outputs(), c.outputs());
    assert_eq!(a, b);
    assert_eq!(a, d);
}

#[test]
fn step_rejects_bad_time() {
    let mut g = Grid::new(&Case::builtin("ieee9").unwrap()).unwrap();
    assert!(g.step(0.0, -0.1).is_err());
    assert!(g.step(1.0, 0.1).is_err());
    assert!(g.step(0.0, 0.0).is_ok());
}

#[test]
fn hybrid_survives_outage_of_both_machines_with_inputs_held() {
    let mut g = Grid::new(&Case::builtin("ieee9_hybrid").unwrap()).unwrap();
    g.disable_events();
    g.add_event(Event::GeneratorTrip {
        time: 0.2,
        machine: 1,
    })
    .unwrap();
    g.add_event(Event::GeneratorTrip {
        time: 0.2,
        machine: 2,
    })
    .unwrap();
    for i in 0..100 {
        g.step(i as f64 * 0.01, 0.01).unwrap();
        assert!(g.outputs().balance_p.abs() < 1e-6);
    }
    let o = g.outputs();
    // the DVPP now carries the whole (voltage-dependent) load; GFL slots stay at their references
    assert!(o.sg.iter().all(|m| !m.in_service));
    assert!((o.gen_p - o.pcc.p).abs() < 1e-9);
    assert!(o.pcc.p > 1.5, "pcc.p {}", o.pcc.p);
    assert!((o.der[4].p - 0.25).abs() < 1e-12);
    assert_eq!(o.coi_f, o.pcc.f);
    assert!(
        (o.pcc.f - 1.0).abs() < 1e-9,
        "fixed-angle sources: nominal frequency"
    );
}

/// ieee9 with SG2's steam-chest time constant set to `t_ch` seconds and a 28 MW load step at
/// bus 5 at t = 0.2 s.
fn ieee9_with_t_ch(t_ch: f64) -> Case {
    let mut case = Case::builtin("ieee9").unwrap();
    match &mut case.machines[1].governor {
        Some(grid_model::case::Governor::TgovReheat { t_ch: t, .. }) => *t = t_ch,
        g => panic!("SG2 governor {g:?}"),
    }
    case.events.push(Event::LoadStep {
        time: 0.2,
        bus: 5,
        dp_mw: 28.0,
        dq_mvar: 0.0,
        model: LoadModel::ConstantImpedance,
    });
    case
}

/// Run `g` to `t_end` with communication step `h`; (ω, p_m) of SG2 at every step.
fn sg2_trace(g: &mut Grid, t_end: f64, h: f64) -> Vec<(f64, f64)> {
    let n = (t_end / h).round() as usize;
    (0..n)
        .map(|i| {
            g.step(i as f64 * h, h).unwrap();
            let o = g.outputs();
            assert!(
                o.balance_p.abs() < 1e-6,
                "t = {} balance {}",
                o.t,
                o.balance_p
            );
            (o.sg[1].omega, o.sg[1].pm)
        })
        .collect()
}

#[test]
fn fast_governor_reduces_the_internal_step_and_matches_a_fine_step() {
    // t_ch = 0.3 ms: RK4 at the default 1 ms internal step is unstable (h > 2.785 τ).
    let case = ieee9_with_t_ch(3e-4);
    let mut g = Grid::new(&case).unwrap();
    assert!(
        g.internal_step() <= 3e-4 / 3.0 + 1e-15,
        "{}",
        g.internal_step()
    );
    assert_eq!(g.internal_step(), g.max_internal_step());
    let note = g.internal_step_note().expect("the reduction is reported");
    assert!(
        note.contains("machine[2].governor.t_ch = 0.0003 s"),
        "{note}"
    );
    // the unstable step cannot be forced
    assert!(g.set_internal_step(1e-3).is_err());
    let mut fine = Grid::new(&case).unwrap();
    fine.set_internal_step(2.5e-5).unwrap();
    // 1 ms communication step, through the load step and past t = 2 s (at a 1 ms internal step
    // the steam-chest mode grows ×2.2 per step and overflows within about a second)
    let a = sg2_trace(&mut g, 2.0, 1e-3);
    let b = sg2_trace(&mut fine, 2.0, 1e-3);
    let (mut dw, mut dpm) = (0.0f64, 0.0f64);
    for ((wa, pa), (wb, pb)) in a.iter().zip(&b) {
        assert!(wa.is_finite() && pa.is_finite());
        dw = dw.max((wa - wb).abs());
        dpm = dpm.max((pa - pb).abs());
    }
    println!("t_ch = 0.3 ms: max |Δω| = {dw:e} pu, max |Δp_m| = {dpm:e} pu vs a 25 µs step");
    // the governor has responded (the load step is felt), and both runs agree
    let (w_end, pm_end) = a[a.len() - 1];
    assert!(
        w_end < 1.0 - 1e-4 && pm_end > a[0].1 + 1e-3,
        "ω {w_end}, p_m {pm_end}"
    );
    assert!(dw < 1e-9 && dpm < 1e-7, "Δω {dw:e}, Δp_m {dpm:e}");
}

#[test]
fn default_cases_keep_the_largest_internal_step() {
    for name in Case::builtin_names() {
        let g = Grid::new(&Case::builtin(name).unwrap()).unwrap();
        assert_eq!(g.internal_step(), grid_model::MAX_INTERNAL_STEP, "{name}");
        assert!(g.internal_step_note().is_none(), "{name}");
    }
}

#[test]
fn too_small_time_constant_is_refused_naming_the_parameter() {
    let e = Grid::new(&ieee9_with_t_ch(1e-6)).unwrap_err();
    assert!(
        matches!(e, grid_model::GridError::TimeConstantTooSmall { ref parameter, min }
            if parameter.starts_with("machine[2].governor.t_ch = 0.000001 s")
                && min == grid_model::MIN_INTERNAL_STEP * grid_model::STEPS_PER_TIME_CONSTANT),
        "{e:?}"
    );
    let text = e.to_string();
    assert!(
        text.contains("machine[2].governor.t_ch") && text.contains("below"),
        "{text}"
    );
    // an exciter and the PCC filter are checked the same way
    let mut case = Case::builtin("ieee9_af").unwrap();
    if let Some(grid_model::case::Exciter::IeeeT1 { ta, .. }) = &mut case.machines[2].exciter {
        *ta = 1e-5;
    }
    let e = Grid::new(&case).unwrap_err().to_string();
    assert!(e.contains("machine[3].exciter.ta"), "{e}");
    let mut case = Case::builtin("ieee9_af").unwrap();
    case.pcc.as_mut().unwrap().f_filter_t = 1e-5;
    let e = Grid::new(&case).unwrap_err().to_string();
    assert!(e.contains("pcc.f_filter_t"), "{e}");
}

#[test]
fn tripped_machine_is_out_of_service_and_coasts() {
    let case = Case::builtin("ieee9_af").unwrap();
    let mut g = Grid::new(&case).unwrap();
    g.add_event(Event::GeneratorTrip {
        time: 0.5,
        machine: 3,
    })
    .unwrap();
    let h_of = |j: usize| case.machines[j].h; // ieee9 gives H on the system base
    let h = 0.01;
    let mut omega3 = Vec::new();
    for i in 0..2000 {
        g.step(i as f64 * h, h).unwrap();
        let o = g.outputs();
        let tripped = o.t > 0.5 - 1e-9; // the trip fires at the end of the step reaching 0.5 s
        assert_eq!(o.sg[2].in_service, !tripped, "t = {}", o.t);
        assert!(o.sg[0].in_service && o.sg[1].in_service);
        // COI over the machines in service only
        let (hw, hs) =
            o.sg.iter()
                .enumerate()
                .filter(|(_, m)| m.in_service)
                .fold((0.0, 0.0), |(a, b), (j, m)| {
                    (a + h_of(j) * m.omega, b + h_of(j))
                });
        assert!((o.coi_f - hw / hs).abs() < 1e-12, "t = {}", o.t);
        if tripped {
            assert!(o.sg[2].p == 0.0 && o.sg[2].q == 0.0 && o.sg[2].pe == 0.0);
            omega3.push((o.t, o.sg[2].omega, o.coi_f));
        }
    }
    // The turbine trips with the breaker: no mechanical power, and the rotor coasts from its
    // speed at the trip through its damping alone (no torque: dω/dt = -D Δω / 2H).
    let d3 = case.machines[2].d;
    let (t0, w0, _) = omega3[0];
    for &(t, w, _) in &omega3 {
        let coast = 1.0 + (w0 - 1.0) * dvpp_math::exp(-d3 * (t - t0) / (2.0 * h_of(2)));
        assert!(
            (w - coast).abs() < 1e-6,
            "t = {t}: ω3 {w}, coasting {coast}"
        );
    }
    let (_, _, coi_1s) = omega3[50];
    assert!(coi_1s < 1.0, "the grid lost a generator: coi {coi_1s}");
    let o = g.outputs();
    assert_eq!(o.sg[2].pm, 0.0, "p_m after the trip");
}
