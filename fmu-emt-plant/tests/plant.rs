//! The EMT plant driven in-process through the FMI call paths: flat start, the steady state
//! against an independent phasor solution, exactness of the discretization, the LC resonance,
//! the energy accounts, FMU state round trips, and refused parameters and inputs.

use emt_plant_model::meter::clarke;
use emt_plant_model::Plant;
use fmi_export::harness::Harness;
use fmi_export::{Config, Status};
use nalgebra::Complex;
use std::f64::consts::PI;

type C = Complex<f64>;

const WB: f64 = 2.0 * PI * 50.0;
const PH: [&str; 3] = ["a", "b", "c"];

fn j() -> C {
    C::new(0.0, 1.0)
}

/// A plant of the built-in defaults with `values` set, initialized.
fn plant(values: &[(&str, f64)]) -> Harness<Plant> {
    let mut h = Harness::<Plant>::new();
    set_values(&mut h, values);
    h.init();
    h
}

/// Set parameters by name (`hold` is an Integer).
fn set_values(h: &mut Harness<Plant>, values: &[(&str, f64)]) {
    for &(name, v) in values {
        if name == "hold" {
            h.set(name, v as i32);
        } else {
            h.set(name, v);
        }
    }
}

fn plant_toml(toml: &str, values: &[(&str, f64)]) -> Harness<Plant> {
    let mut h = Harness::<Plant>::from_toml(toml);
    set_values(&mut h, values);
    h.init();
    h
}

/// The αβ space vector of the abc outputs `name_a`, `name_b`, `name_c`.
fn space_vector(h: &mut Harness<Plant>, name: &str) -> C {
    let abc = PH.map(|x| h.get(&format!("{name}{x}")));
    let [a, b] = clarke(abc);
    C::new(a, b)
}

/// The phasor (peak, at the run's start) of a space vector measured at time `t` since the start.
fn phasor(sv: C, t: f64) -> C {
    sv * dvpp_math::cpolar(1.0, -WB * t)
}

/// abc values of a balanced phasor at time `t`.
fn abc(x: C, t: f64) -> [f64; 3] {
    [0.0, 1.0, 2.0].map(|k| (x * dvpp_math::cpolar(1.0, WB * t - k * 2.0 * PI / 3.0)).re)
}

/// Steady-state modulation phasor and dc command of every unit, from the measurements at the
/// start alone: `v_conv = v_c + (R_f + jX_f) i_f`, `m = v_conv/(1.5 v_dc)`, `i_dc_ref = i_src`.
fn steady_inputs(h: &mut Harness<Plant>, n: usize) -> Vec<(C, f64)> {
    (1..=n)
        .map(|k| {
            let d = |w: &str| format!("der[{k}].{w}");
            let v_c = phasor(space_vector(h, &d("v_")), 0.0);
            let i_f = phasor(space_vector(h, &d("i_")), 0.0);
            let z = C::new(h.get(&d("R_f")), h.get(&d("L_f")));
            let v_conv = v_c + z * i_f;
            (v_conv / (1.5 * h.get(&d("v_dc"))), h.get(&d("i_src")))
        })
        .collect()
}

/// Set the units' inputs for the step that starts at `t` (since the run's start).
fn drive(h: &mut Harness<Plant>, inputs: &[(C, f64)], t: f64) {
    for (k, (m, i_ref)) in inputs.iter().enumerate() {
        for (x, v) in PH.iter().zip(abc(*m, t)) {
            h.set(&format!("der[{}].m_{x}", k + 1), v);
        }
        h.set(&format!("der[{}].i_dc_ref", k + 1), *i_ref);
    }
}

/// Largest deviation over `t_end` at step `dt` of each unit's p, q (from the start values) and
/// instantaneous capacitor voltage (from the initial sinusoid), with the steady-state inputs
/// sampled `lead` seconds after each step's start.
fn flat_start_drift(hold: f64, dt: f64, t_end: f64, lead: f64) -> (f64, f64) {
    let mut h = plant(&[("hold", hold)]);
    let n = 3;
    let inputs = steady_inputs(&mut h, n);
    let pq0: Vec<[f64; 2]> = (1..=n)
        .map(|k| [h.get(&format!("der[{k}].p")), h.get(&format!("der[{k}].q"))])
        .collect();
    let vc0: Vec<C> = (1..=n)
        .map(|k| phasor(space_vector(&mut h, &format!("der[{k}].v_")), 0.0))
        .collect();
    let (mut pq_drift, mut v_drift) = (0.0f64, 0.0f64);
    let steps = (t_end / dt).round() as usize;
    for i in 0..steps {
        let t = i as f64 * dt;
        drive(&mut h, &inputs, t + lead);
        h.step(dt);
        let t1 = (i + 1) as f64 * dt;
        for k in 1..=n {
            let p = h.get(&format!("der[{k}].p"));
            let q = h.get(&format!("der[{k}].q"));
            pq_drift = pq_drift
                .max((p - pq0[k - 1][0]).abs())
                .max((q - pq0[k - 1][1]).abs());
            let expect = abc(vc0[k - 1], t1);
            for (x, e) in PH.iter().zip(expect) {
                v_drift = v_drift.max((h.get(&format!("der[{k}].v_{x}")) - e).abs());
            }
        }
    }
    assert!(
        h.get("pcc.df").abs() < 1e-3,
        "PLL meter: {}",
        h.get("pcc.df")
    );
    (pq_drift, v_drift)
}

#[test]
fn flat_start_stays_flat_with_the_rotating_hold() {
    let (pq, v) = flat_start_drift(1.0, 50e-6, 1.0, 0.0);
    println!("flat start, hold = 1, 1 s at 50 us: p, q drift {pq:.3e} pu, v_c drift {v:.3e} pu");
    assert!(pq < 1e-6 && v < 1e-6, "drift p,q {pq:e}, v_c {v:e}");
}

/// With the zero-order hold, the sampled sinusoid lags on average by h/2: the plant leaves the
/// continuous steady state by an amount proportional to h (first order). Sampling the
/// modulation at the middle of the step (angle advanced by ω h/2) removes the first-order
/// error: what remains is of second order in h.
#[test]
fn flat_start_with_the_zero_order_hold_drifts_in_proportion_to_the_step() {
    let (pq50, v50) = flat_start_drift(0.0, 50e-6, 0.2, 0.0);
    let (pq25, v25) = flat_start_drift(0.0, 25e-6, 0.2, 0.0);
    println!(
        "flat start, hold = 0, 0.2 s: p, q drift {pq50:.3e} (50 us), {pq25:.3e} (25 us); v_c drift {v50:.3e}, {v25:.3e}"
    );
    let ratio = pq50 / pq25;
    assert!((1.8..2.2).contains(&ratio), "p,q drift ratio {ratio}");
    // Half a step of delay in the converter voltage: about ω h/2 = 7.9 mrad of angle.
    assert!(pq50 < 0.1, "{pq50}");
    let (mid50, vm50) = flat_start_drift(0.0, 50e-6, 0.2, 25e-6);
    let (mid25, vm25) = flat_start_drift(0.0, 25e-6, 0.2, 12.5e-6);
    println!(
        "  sampled at mid-step: p, q drift {mid50:.3e} (50 us), {mid25:.3e} (25 us); v_c drift {vm50:.3e}, {vm25:.3e}"
    );
    let ratio = mid50 / mid25;
    assert!((3.5..4.5).contains(&ratio), "mid-step drift ratio {ratio}");
    assert!(mid50 < pq50 / 20.0, "{mid50} vs {pq50}");
}

/// The circuit's phasor solution written independently: a fixed-point iteration on the PCC
/// voltage, then each branch.
#[test]
fn the_initial_state_is_the_phasor_steady_state() {
    let mut h = plant(&[]);
    let s_base = 100.0;
    let ratings = [46.0, 73.0, 60.0];
    let s0 = [C::new(0.315, 0.0), C::new(0.5, 0.0), C::new(0.0, 0.0)];
    let zs = C::new(0.015, 0.15);
    let e = C::new(1.02, 0.0);
    // Base load 0.8 + j0.1 at 1 pu: Z = 1/conj(S).
    let zl = 1.0 / C::new(0.8, 0.1).conj();
    let mut v = C::new(1.0, 0.0);
    for _ in 0..500 {
        let inj: C = s0.iter().map(|s| (s / v).conj()).sum();
        v = (e / zs + inj) / (1.0 / zs + 1.0 / zl);
    }
    let check = |h: &mut Harness<Plant>, name: String, x: C| {
        PH.iter()
            .zip(abc(x, 0.0))
            .map(|(ph, want)| (h.get(&format!("{name}{ph}")) - want).abs())
            .fold(0.0f64, f64::max)
    };
    let mut worst = check(&mut h, "pcc.v_".into(), v);
    for k in 0..3 {
        let c = ratings[k] / s_base;
        let i_g = (s0[k] / v).conj() / c;
        let v_c = v + C::new(0.01, 0.1) * i_g;
        let i_f = i_g + j() * 0.0942 * v_c;
        worst = worst
            .max(check(&mut h, format!("der[{}].v_", k + 1), v_c))
            .max(check(&mut h, format!("der[{}].i_", k + 1), i_f))
            .max(check(&mut h, format!("der[{}].ig_", k + 1), i_g));
        let p = h.get(&format!("der[{}].p", k + 1));
        let q = h.get(&format!("der[{}].q", k + 1));
        worst = worst.max((p - s0[k].re).abs()).max((q - s0[k].im).abs());
        // dc link at nominal with the source covering converter power and losses.
        let p_conv = ((v_c + C::new(0.01, 0.11) * i_f) * i_f.conj()).re;
        worst = worst
            .max((h.get(&format!("der[{}].v_dc", k + 1)) - 1.0).abs())
            .max((h.get(&format!("der[{}].i_src", k + 1)) - (p_conv + 0.05)).abs());
    }
    worst = worst.max(check(&mut h, "thevenin.i_".into(), (e - v) / zs));
    let s_th = v * ((e - v) / zs).conj();
    worst = worst
        .max((h.get("thevenin.p") - s_th.re).abs())
        .max((h.get("thevenin.q") - s_th.im).abs());
    let s_load = v * (v / zl).conj();
    worst = worst.max((h.get("load[1].p") - s_load.re).abs());
    assert_eq!(
        h.get("load[2].p"),
        0.0,
        "the step load is not connected yet"
    );
    println!(
        "steady state vs phasor solution: largest difference {worst:.3e}; pcc.v {:.4}, thevenin p {:.4} q {:.4}, base load p {:.4}",
        h.get("pcc.v"),
        h.get("thevenin.p"),
        h.get("thevenin.q"),
        h.get("load[1].p")
    );
    assert!(worst < 1e-9, "{worst:e}");

    // The island: unit 1's capacitor voltage v0 at angle 0 feeds the base load through its
    // transformer, a voltage divider.
    let mut h = plant_toml("[model]\ncase = \"island\"\n", &[("der[1].v0", 0.98)]);
    let c = 60.0 / s_base;
    let zt = C::new(0.01, 0.1) / c;
    let zl = 1.0 / C::new(0.3, 0.06).conj();
    let v_c = C::new(0.98, 0.0);
    let v = v_c * zl / (zt + zl);
    let i_g = (v_c - v) / zt / c;
    let mut worst = 0.0f64;
    for (name, x) in [
        ("pcc.v_".to_string(), v),
        ("der[1].v_".into(), v_c),
        ("der[1].ig_".into(), i_g),
        ("der[1].i_".into(), i_g + j() * 0.0942 * v_c),
    ] {
        for (ph, want) in PH.iter().zip(abc(x, 0.0)) {
            worst = worst.max((h.get(&format!("{name}{ph}")) - want).abs());
        }
    }
    println!("island steady state vs voltage divider: largest difference {worst:.3e}");
    assert!(worst < 1e-9, "{worst:e}");
}

/// Outputs of the ac circuit after each `dt` up to `t_end`, with the converters' voltage zero
/// (m = 0: the ac side is then independent of the dc side) and load 2 switched on at 10 ms.
fn transient(dt: f64, t_end: f64) -> Vec<Vec<f64>> {
    let mut h = plant(&[("load[2].t_on", 0.01)]);
    let names: Vec<String> = [
        "der[1].v_a",
        "der[2].i_b",
        "der[3].ig_c",
        "pcc.v_a",
        "load[2].p",
        "thevenin.q",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let steps = (t_end / dt).round() as usize;
    let mut out = Vec::new();
    for _ in 0..steps {
        h.step(dt);
        out.push(names.iter().map(|n| h.get(n)).collect());
    }
    out
}

#[test]
fn the_step_is_exact_for_held_inputs() {
    let t_end = 0.03;
    let a = transient(50e-6, t_end);
    let b = transient(25e-6, t_end);
    let mut worst = 0.0f64;
    for (i, row) in a.iter().enumerate() {
        for (x, y) in row.iter().zip(&b[2 * i + 1]) {
            worst = worst.max((x - y).abs());
        }
    }
    // The load's power jumped from zero: the step is in both runs.
    assert!(a.last().unwrap()[4] > 0.01, "{:?}", a.last());
    println!("load switched on, h = 50 us vs 25 us: largest difference {worst:.3e}");
    assert!(worst < 1e-9, "{worst:e}");
}

/// A unit on an (almost) open transformer: a step of its converter voltage rings at the LC
/// filter's resonance 1/sqrt(L_f C_f) = 9.82 pu, 491 Hz.
#[test]
fn the_open_filter_rings_at_the_lc_resonance() {
    let toml = r#"[model]
case = "island"
loads = [{ name = "tiny", p = 1e-4, q = 1e-4 }]
"#;
    let mut h = plant_toml(toml, &[("der[1].v0", 0.0), ("der[1].i_dc_ref", 0.05)]);
    let m = [0.2, -0.1, -0.1];
    for (x, v) in PH.iter().zip(m) {
        h.set(&format!("der[1].m_{x}"), v);
    }
    let dt = 20e-6;
    let mut samples = Vec::new();
    for _ in 0..1000 {
        h.step(dt);
        samples.push(h.get("der[1].v_a") - 1.5 * h.get("der[1].v_dc") * 0.2);
    }
    let mut crossings = Vec::new();
    for (i, w) in samples.windows(2).enumerate() {
        if w[0] < 0.0 && w[1] >= 0.0 {
            crossings.push((i as f64 + 1.0 + w[0] / (w[0] - w[1])) * dt);
        }
    }
    let f = (crossings.len() - 1) as f64 / (crossings.last().unwrap() - crossings[0]);
    let expected = 50.0 / (0.11f64 * 0.0942).sqrt();
    println!(
        "open filter ringing: {f:.2} Hz over {} periods (1/sqrt(L_f C_f): {expected:.2} Hz)",
        crossings.len() - 1
    );
    assert!((f / 490.0 - 1.0).abs() < 0.02, "{f}");
    assert!((f / expected - 1.0).abs() < 1e-3, "{f} vs {expected}");
}

fn residuals(h: &mut Harness<Plant>, dc0: f64, ac0: f64) -> (f64, f64) {
    let [src, ac, dc_loss, dc_st, ac_loss, th, loads, ac_st] = h.get_many([
        "energy.source",
        "energy.ac",
        "energy.dc_loss",
        "energy.dc_stored",
        "energy.ac_loss",
        "energy.thevenin",
        "energy.loads",
        "energy.ac_stored",
    ]);
    let dc = (src - ac - dc_loss - (dc_st - dc0)) / src.abs().max(ac.abs());
    let acr = (ac + th - ac_loss - loads - (ac_st - ac0)) / loads.abs().max(ac.abs());
    (dc, acr)
}

#[test]
fn the_energy_accounts_close() {
    for hold in [0.0, 1.0] {
        let mut h = plant(&[
            ("hold", hold),
            ("load[2].t_on", 0.05),
            ("thevenin.dip", 0.2),
            ("thevenin.dip_t", 0.1),
            ("thevenin.dip_duration", 0.05),
        ]);
        let mut inputs = steady_inputs(&mut h, 3);
        let dc0 = h.get("energy.dc_stored");
        let ac0 = h.get("energy.ac_stored");
        let dt = 50e-6;
        let (mut worst_dc, mut worst_ac) = (0.0f64, 0.0f64);
        for i in 0..4000 {
            let t = i as f64 * dt;
            // The dc command steps too: the links charge and discharge.
            if i == 1000 {
                for (k, x) in inputs.iter_mut().enumerate() {
                    x.1 += 0.02 * (k as f64 - 1.0);
                }
            }
            drive(&mut h, &inputs, t);
            h.step(dt);
            let (dc, ac) = residuals(&mut h, dc0, ac0);
            worst_dc = worst_dc.max(dc.abs());
            worst_ac = worst_ac.max(ac.abs());
        }
        let moved = h.get("energy.dc_stored") - dc0;
        println!(
            "energy, hold = {hold}: dc residual {worst_dc:.3e}, ac residual {worst_ac:.3e} (relative); ac {:.4} MJ, loads {:.4} MJ, dc stored change {moved:.3e} MJ",
            h.get("energy.ac"),
            h.get("energy.loads")
        );
        assert!(moved.abs() > 1e-3, "the dc links moved: {moved}");
        assert!(
            worst_dc < 1e-9 && worst_ac < 1e-9,
            "{worst_dc:e} {worst_ac:e}"
        );
    }
}

#[test]
fn fmu_state_round_trips() {
    let mut h = plant(&[("load[2].t_on", 0.001)]);
    let inputs = steady_inputs(&mut h, 3);
    drive(&mut h, &inputs, 0.0);
    h.step(50e-6);
    let saved = h.get_fmu_state().unwrap();
    let bytes = h.serialize_fmu_state(&saved).unwrap();
    let run = |h: &mut Harness<Plant>| {
        for i in 1..40 {
            drive(h, &inputs, i as f64 * 50e-6);
            h.step(50e-6);
        }
        h.get_many(["der[2].ig_a", "pcc.v_b", "energy.ac", "der[1].v_dc"])
    };
    let first = run(&mut h);
    let restored = h.deserialize_fmu_state(&bytes).unwrap();
    assert_eq!(h.set_fmu_state(&restored), Status::Ok);
    assert_eq!(run(&mut h), first);
}

#[test]
fn bad_parameters_and_nan_inputs_are_refused_by_name() {
    // Negative: outside the declared range, refused when set.
    let mut h = Harness::<Plant>::new();
    assert_eq!(h.try_set("der[1].C_f", -0.1), Status::Error);
    assert!(h.logged(Status::Error, "'der[1].C_f'"), "{:#?}", h.log());
    // Zero: refused at initialization, naming the parameter.
    let mut h = Harness::<Plant>::new();
    h.set("der[2].C_f", 0.0);
    assert_eq!(h.setup_experiment(0.0, None), Status::Ok);
    let status = h
        .enter_initialization_mode()
        .max(h.exit_initialization_mode());
    assert_eq!(status, Status::Error);
    assert!(
        h.logged(Status::Error, "'der[2].C_f' = 0 must be positive"),
        "{:#?}",
        h.log()
    );
    // A load without reactive power is no series R-L load.
    let mut h = Harness::<Plant>::new();
    h.set("load[1].Q", 0.0);
    h.setup_experiment(0.0, None);
    let status = h
        .enter_initialization_mode()
        .max(h.exit_initialization_mode());
    assert_eq!(status, Status::Error);
    assert!(h.logged(Status::Error, "'load[1].Q'"), "{:#?}", h.log());
    // A step far beyond the EMT steps (which the exponential could not resolve either).
    let mut h = plant(&[]);
    assert_eq!(h.do_step(0.0, 1e4), Status::Error);
    assert!(
        h.logged(Status::Error, "communicationStepSize = 10000 s exceeds"),
        "{:#?}",
        h.log()
    );
    // A bad configuration.
    let config = Config::from_toml("[model]\ncase = \"nowhere\"\n").unwrap();
    let log = Harness::<Plant>::try_with_config(config, true)
        .err()
        .unwrap();
    assert!(
        log.iter().any(|r| r.message.contains("nowhere")),
        "{log:#?}"
    );

    // NaN inputs are refused, change no value, and a reset starts over.
    let mut h = plant(&[]);
    let inputs = steady_inputs(&mut h, 3);
    drive(&mut h, &inputs, 0.0);
    h.step(50e-6);
    let first = h.get_many(["der[1].i_a", "der[1].v_dc", "pcc.v_c"]);
    for (name, bad) in [("der[1].m_b", f64::NAN), ("der[3].i_dc_ref", f64::INFINITY)] {
        let before = h.instance().core.store.clone();
        assert_eq!(h.try_set(name, bad), Status::Error, "{name}");
        assert!(
            h.logged(Status::Error, &format!("for '{name}' is not finite")),
            "{:#?}",
            h.log()
        );
        assert_eq!(
            h.instance().core.store,
            before,
            "{name} = {bad} changed a value"
        );
        assert_eq!(h.reset(), Status::Ok);
        h.init();
        drive(&mut h, &inputs, 0.0);
        h.step(50e-6);
        assert_eq!(h.get_many(["der[1].i_a", "der[1].v_dc", "pcc.v_c"]), first);
    }
}

/// The island variant: unit 1 holds its capacitor voltage; fed its own steady-state inputs with
/// the rotating hold it stays there, and the load step at 1 s (moved to 20 ms) is carried.
#[test]
fn the_island_starts_flat_and_carries_its_load_step() {
    let mut h = plant_toml(
        "[model]\ncase = \"island\"\n",
        &[("hold", 1.0), ("load[2].t_on", 0.02)],
    );
    let inputs = steady_inputs(&mut h, 1);
    let p0 = h.get("der[1].p");
    let dt = 50e-6;
    let mut drift = 0.0f64;
    for i in 0..800 {
        drive(&mut h, &inputs, i as f64 * dt);
        h.step(dt);
        if i < 399 {
            drift = drift.max((h.get("der[1].p") - p0).abs());
        }
    }
    let p1 = h.get("der[1].p");
    println!(
        "island: p {p0:.5} -> {p1:.5} pu after the step (load 2: {:.5} pu at {:.4} pu voltage), flat-start drift {drift:.2e}",
        h.get("load[2].p"),
        h.get("pcc.v")
    );
    assert!(drift < 1e-9, "{drift:e}");
    // Unit 1 is the only source: it carries the step, a constant impedance drawing
    // 0.06 |v_pcc|² pu, and the loads draw exactly what it sends into the PCC (KCL).
    let v = h.get("pcc.v");
    let step = h.get("load[2].p");
    assert!(
        (step / (0.06 * v * v) - 1.0).abs() < 0.02,
        "{step} at {v} pu"
    );
    let kcl = p1 - h.get("load[1].p") - step;
    assert!(kcl.abs() < 1e-12, "{kcl}");
}

/// `energy.thevenin` after each 50 µs step over 20 ms of the default case fed its steady-state
/// inputs (rotating hold), with the Thevenin parameters `values`.
fn thevenin_run(values: &[(&str, f64)]) -> Vec<(f64, f64)> {
    let mut all = vec![("hold", 1.0)];
    all.extend_from_slice(values);
    let mut h = plant(&all);
    let inputs = steady_inputs(&mut h, 3);
    (0..400)
        .map(|i| {
            let t = i as f64 * 50e-6;
            drive(&mut h, &inputs, t);
            h.step(50e-6);
            (h.get("energy.thevenin"), h.get("pcc.v_a"))
        })
        .collect()
}

/// A full dip zeroes the source from the first step boundary at or after `dip_t` for
/// `dip_duration`: the source then delivers no energy. A phase jump of 2π changes nothing; one
/// of π/2 changes the PCC voltage from the jump on only.
#[test]
fn thevenin_events_act_at_step_boundaries() {
    let dip = thevenin_run(&[
        ("thevenin.dip", 1.0),
        ("thevenin.dip_t", 0.005),
        ("thevenin.dip_duration", 0.005),
    ]);
    for (i, w) in dip.windows(2).enumerate() {
        // w[1] is the energy after the step that starts at (i + 1) · 50 µs.
        let start = (i + 1) as f64 * 50e-6;
        let delta = (w[1].0 - w[0].0).abs();
        if (0.005 - 1e-9..0.01 - 1e-9).contains(&start) {
            assert!(
                delta < 1e-12,
                "step at {start}: the dipped source delivered {delta}"
            );
        } else {
            assert!(delta > 1e-6, "step at {start}: {delta}");
        }
    }
    let plain = thevenin_run(&[]);
    let full_turn = thevenin_run(&[("thevenin.jump", 2.0 * PI), ("thevenin.jump_t", 0.005)]);
    let worst = plain
        .iter()
        .zip(&full_turn)
        .map(|(a, b)| (a.1 - b.1).abs())
        .fold(0.0f64, f64::max);
    assert!(worst < 1e-9, "a 2π jump changed v_a by {worst:e}");
    let quarter = thevenin_run(&[("thevenin.jump", PI / 2.0), ("thevenin.jump_t", 0.005)]);
    for (i, (a, b)) in plain.iter().zip(&quarter).enumerate() {
        // Output i is at (i + 1) · 50 µs: the first one after the jump is i = 100.
        if i == 100 {
            assert!(
                (a.1 - b.1).abs() > 1e-3,
                "the jump shows in the first step after it"
            );
        }
        if i < 100 {
            assert_eq!(a.1, b.1, "output {i} before the jump");
        }
    }
}

#[test]
fn clamped_modulation_is_flagged() {
    let mut h = plant(&[]);
    h.set("der[2].m_a", 1.4);
    h.step(50e-6);
    assert!(h.get_bool("der[2].m_clamped"));
    assert!(!h.get_bool("der[1].m_clamped"));
}
