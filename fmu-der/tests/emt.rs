//! The EMT-level controller in closed loop with the paper's filter against a stiff grid (in-process): a flat start, the droop law on a grid-frequency step in both modes, the current limit, and option B (H∞) against option A on a voltage dip.

use der_model::emt::DerEmt;
use dvpp_control::converter::filter::{Lcl, LclState};
use dvpp_control::converter::{Abc, ConverterData, Dq};
use dvpp_control::Complex;
use fmi_export::harness::Harness;
use fmi_export::Status;
use std::f64::consts::PI;

const H: f64 = 50e-6;
const F_NOM: f64 = 50.0;
const S_RATED: f64 = 60.0;
const S_BASE: f64 = 100.0;

/// The paper's LCL filter between the converter and a stiff grid `v_g = 1∠0` turning at
/// `ω_b (1 + df_grid)`, integrated exactly in the grid's frame; the converter voltage is the
/// modulation held over the step, taken at the step's middle.
struct Plant {
    lcl: Lcl,
    x: LclState,
    omega_g: f64,
    /// The grid voltage's magnitude (pu).
    v_g: f64,
    /// The grid voltage's angle against the frame turning at the grid frequency (rad).
    jump: f64,
    t: f64,
}

impl Plant {
    /// The steady state with the unit injecting `p + j q` (pu on S_rated) into the grid.
    fn at(p: f64, q: f64) -> Plant {
        let d = ConverterData::PAPER;
        let c = |z: Complex<f64>| Dq { d: z.re, q: z.im };
        let vg = Complex::new(1.0, 0.0);
        let ig = (Complex::new(p, q) / vg).conj();
        let vc = vg + Complex::new(d.r_t, d.l_t) * ig;
        let i_f = ig + Complex::new(0.0, d.c_f) * vc;
        let omega_b = 2.0 * PI * F_NOM;
        Plant {
            lcl: Lcl::discretize(&d, omega_b, 1.0, H),
            x: LclState {
                i_f: c(i_f),
                v_c: c(vc),
                i_g: c(ig),
            },
            omega_g: omega_b,
            v_g: 1.0,
            jump: 0.0,
            t: 0.0,
        }
    }

    fn set_grid_frequency(&mut self, df: f64) {
        let omega_b = 2.0 * PI * F_NOM;
        self.omega_g = omega_b * (1.0 + df);
        self.lcl = Lcl::discretize(&ConverterData::PAPER, omega_b, 1.0 + df, H);
    }

    fn angle(&self, t: f64) -> f64 {
        // The grid frame's angle, continuous across frequency changes.
        self.omega_g * t
    }

    /// The measurements into the controller.
    fn measure(&self, h: &mut Harness<DerEmt>, rho: f64) {
        let set3 = |h: &mut Harness<DerEmt>, p: &str, x: Dq| {
            let v = x.to_abc(rho);
            for (ph, val) in ["a", "b", "c"].iter().zip([v.a, v.b, v.c]) {
                h.set(&format!("{p}_{ph}"), val);
            }
        };
        set3(h, "v", self.x.v_c);
        set3(h, "i", self.x.i_f);
        set3(h, "ig", self.x.i_g);
    }

    /// One step with the modulation `[ma, mb, mc]` held, at `v_dc` = 1.
    fn step(&mut self, [ma, mb, mc]: [f64; 3], rho_mid: f64) {
        let k = 0.5 * ConverterData::PAPER.v_dc_ratio;
        let v_m = Abc {
            a: ma * k,
            b: mb * k,
            c: mc * k,
        }
        .to_dq(rho_mid);
        self.x = self.lcl.step(
            &self.x,
            v_m,
            Dq {
                d: self.v_g * dvpp_math::cos(self.jump),
                q: self.v_g * dvpp_math::sin(self.jump),
            },
        );
        self.t += H;
    }
}

/// A unit on the stiff grid, initialized at `p0` (pu on S_base), run for `t_end`, with the grid's
/// frequency stepped by `df` at 0.1 s; returns the controller's `p` (S_base) and `df` traces.
fn run(
    mode: i32,
    p0: f64,
    df: f64,
    t_end: f64,
    start: &[(&str, f64)],
) -> (Vec<f64>, Vec<f64>, Harness<DerEmt>) {
    run_unit(None, mode, p0, df, t_end, start, &[])
}

/// [`run`] for one of the DER presets (`None`: the generic unit), with the tunable parameters
/// `tuned` set after initialization, before the first step.
fn run_unit(
    preset: Option<&str>,
    mode: i32,
    p0: f64,
    df: f64,
    t_end: f64,
    start: &[(&str, f64)],
    tuned: &[(&str, f64)],
) -> (Vec<f64>, Vec<f64>, Harness<DerEmt>) {
    let mut plant = Plant::at(p0 * S_BASE / S_RATED, 0.0);
    let mut h = match preset {
        Some(p) => Harness::<DerEmt>::from_toml(&format!("[model]\npreset = \"{p}\"\n")),
        None => Harness::<DerEmt>::new(),
    };
    assert_eq!(h.setup_experiment(0.0, None), Status::Ok);
    h.set("S_rated", S_RATED);
    h.set("mode", mode);
    for (name, value) in start {
        if *name == "inner.kind" {
            h.set(name, *value as i32);
        } else {
            h.set(name, *value);
        }
    }
    assert_eq!(h.enter_initialization_mode(), Status::Ok);
    plant.measure(&mut h, 0.0);
    assert_eq!(h.exit_initialization_mode(), Status::Ok);
    for (name, value) in tuned {
        assert_eq!(h.try_set(name, *value), Status::Ok, "{name}");
    }
    let (mut p, mut f) = (vec![], vec![]);
    let n = (t_end / H).round() as usize;
    // The phase of the grid frame at the frequency step, kept continuous.
    let mut phase = 0.0;
    let mut t_ref = 0.0;
    for k in 0..n {
        let t = k as f64 * H;
        if df != 0.0 && (t - 0.1).abs() < H / 2.0 {
            phase += plant.angle(t - t_ref);
            t_ref = t;
            plant.set_grid_frequency(df);
        }
        let rho = phase + plant.angle(t - t_ref);
        // As a master's exchange: the plant holds the modulation the controller output at t
        // (computed from the measurement one step earlier) while the controller steps.
        let m = h.get_many(["m_a", "m_b", "m_c"]);
        plant.measure(&mut h, rho);
        assert_eq!(h.do_step(t, H), Status::Ok, "t = {t}");
        p.push(h.get("p"));
        f.push(h.get("df"));
        let rho_mid = phase + plant.angle(t + 0.5 * H - t_ref);
        plant.step(m, rho_mid);
    }
    (p, f, h)
}

#[test]
fn grid_forming_starts_flat_on_a_stiff_grid() {
    let (p, f, _) = run(1, 0.3, 0.0, 0.2, &[]);
    let dp = p.iter().map(|x| (x - 0.3).abs()).fold(0.0, f64::max);
    let dfm = f.iter().map(|x| x.abs()).fold(0.0, f64::max);
    println!("flat start: largest |p - p0| {dp:.2e} pu, |df| {dfm:.2e} pu over 0.2 s");
    assert!(dp < 1e-3, "{dp}");
    assert!(dfm < 1e-5, "{dfm}");
}

/// A host retunes a running unit between steps (the layer tells the adapter a parameter was
/// set): from then on it moves exactly as a unit built with those values, and not as one left
/// alone. Grid-forming: the q PI's gains; grid-following: the PLL's.
#[test]
fn tunable_parameters_set_between_steps_take_effect_at_the_next_step() {
    for (mode, tuned) in [
        (1, [("qpi.kp", 0.2), ("qpi.ki", 2.0)]),
        (2, [("pll.kp", 30.0), ("pll.ki", 100.0)]),
    ] {
        let (built, _, _) = run_unit(None, mode, 0.3, -1e-3, 0.3, &tuned, &[]);
        let (retuned, _, _) = run_unit(None, mode, 0.3, -1e-3, 0.3, &[], &tuned);
        let (alone, _, _) = run_unit(None, mode, 0.3, -1e-3, 0.3, &[], &[]);
        assert_eq!(built, retuned, "mode {mode}: retuned between steps");
        assert_ne!(
            built, alone,
            "mode {mode}: the tuned values change the response"
        );
    }
}

/// The droop law at the grid's frequency: `Δp = -m D Δf` on S_dvpp (m = mu_p = 1 for the
/// generic unit), reached by the grid-forming unit through its angle and by the grid-following
/// one through its PLL. The grid-forming unit's swing against the stiff grid rings (at about
/// 1.5 Hz): the law is checked on the mean over the last second, the ringing's decay on its
/// amplitude there.
#[test]
fn both_modes_meet_the_droop_law_on_a_frequency_step() {
    for mode in [1, 2] {
        let df = -1e-3;
        let (p, f, _) = run(mode, 0.3, df, 5.0, &[]);
        let law = -33.33 * df * 96.0 / S_BASE;
        let last = &p[p.len() - (1.0 / H) as usize..];
        let mean = last.iter().sum::<f64>() / last.len() as f64 - 0.3;
        let ringing = last
            .iter()
            .map(|x| (x - 0.3 - mean).abs())
            .fold(0.0, f64::max);
        let f_mean = f[f.len() - last.len()..].iter().sum::<f64>() / last.len() as f64;
        println!(
            "mode {mode}: grid df {df}: dp {mean:.6} pu (law {law:.6}), ringing {ringing:.1e} pu, unit df {f_mean:.4e}"
        );
        assert!(
            (mean - law).abs() < 5e-3 * law.abs(),
            "mode {mode}: {mean} vs {law}"
        );
        assert!(ringing < 0.05 * law.abs(), "mode {mode}: ringing {ringing}");
        assert!((f_mean - df).abs() < 1e-5, "mode {mode}");
    }
}

/// Case study I's units (their ADPFs and the operator's start gains) on the stiff grid: each
/// settles after the frequency step, its swing damped by the virtual resistance `vi.r`. Without
/// it (`vi.r` = 0) the same units oscillate into their current limit: the swing of the frame's
/// angle through the transformer's inductance (R/X = 0.1), which the phasor network does not
/// have, is undamped.
#[test]
fn case_study_units_settle_on_a_stiff_grid_with_the_virtual_resistance() {
    for preset in ["wind", "pv", "bess"] {
        let (p, f, _) = run_unit(Some(preset), 1, 0.3, -1e-3, 5.0, &[], &[]);
        let last = &p[p.len() - (1.0 / H) as usize..];
        let mean = last.iter().sum::<f64>() / last.len() as f64;
        let ringing = last.iter().map(|x| (x - mean).abs()).fold(0.0, f64::max);
        println!(
            "{preset}: p over the last second {mean:.4} +- {ringing:.1e} pu, df {:.4e}",
            f.last().unwrap()
        );
        assert!(ringing < 0.01, "{preset}: ringing {ringing}");
        assert!((f.last().unwrap() + 1e-3).abs() < 5e-5, "{preset}: df");
        let (p0, _, _) = run_unit(Some(preset), 1, 0.3, -1e-3, 1.0, &[("vi.r", 0.0)], &[]);
        let swing = p0.iter().map(|x| (x - 0.3).abs()).fold(0.0, f64::max);
        println!("{preset}, vi.r = 0: largest |p - p0| {swing:.3} pu");
        assert!(
            swing > 0.1,
            "{preset}: stable without the virtual resistance ({swing})"
        );
    }
}

/// A run of [`run_dip`]: the controller's `q`, `q_ref` and `p` (S_base) per step, and the time
/// the modulation limit first acted (the run stops there).
struct Dip {
    q: Vec<f64>,
    q_ref: Vec<f64>,
    p: Vec<f64>,
    limited_at: Option<f64>,
    /// How often option B handed over to its current-limited mode (`limit.current` rising),
    /// when first, and for how long in all (s).
    handovers: usize,
    first_handover: Option<f64>,
    limited_time: f64,
    /// The largest converter current, pu of the rated peak.
    i_peak: f64,
}

/// `I_max` in [`run_dip`]'s runs: raised from the default 1.2 pu so that option B's current
/// limit (docs/hinf.md §8.5) does not act in them. Those runs measure the state feedback
/// itself, whose current reaches 1.345 pu in a 0.2 % dip at μ = 1; at the default `I_max` the
/// limit acts there ([`options_a_and_b_compared`]). Option A's current stays at 0.55 pu.
const I_MAX_DIP: f64 = 1.5;

/// The generic unit at the H∞ design's operating point (0.5 pu of its rating) on the stiff grid,
/// option `kind` (0 = A, 1 = B), `Tdes.Dq` = `dq`, the grid voltage stepped by `dv` at 0.1 s,
/// `I_max` = [`I_MAX_DIP`].
fn run_dip(kind: i32, dq: f64, dv: f64, t_end: f64) -> Dip {
    run_dip_with(kind, dq, dv, t_end, &[])
}

/// [`run_dip`] with the controller's parameters `extra` set (the plant keeps the paper's filter).
fn run_dip_with(kind: i32, dq: f64, dv: f64, t_end: f64, extra: &[(&str, f64)]) -> Dip {
    let mut plant = Plant::at(0.3 * S_BASE / S_RATED, 0.0);
    let mut h = Harness::<DerEmt>::new();
    assert_eq!(h.setup_experiment(0.0, None), Status::Ok);
    h.set("S_rated", S_RATED);
    h.set("mode", 1);
    h.set("inner.kind", kind);
    h.set("Tdes.Dq", dq);
    h.set("I_max", I_MAX_DIP);
    for (name, value) in extra {
        h.set(name, *value);
    }
    assert_eq!(h.enter_initialization_mode(), Status::Ok);
    plant.measure(&mut h, 0.0);
    assert_eq!(h.exit_initialization_mode(), Status::Ok);
    let mut out = Dip {
        q: vec![],
        q_ref: vec![],
        p: vec![],
        limited_at: None,
        handovers: 0,
        first_handover: None,
        limited_time: 0.0,
        i_peak: 0.0,
    };
    let omega_b = 2.0 * PI * F_NOM;
    for k in 0..(t_end / H).round() as usize {
        let t = k as f64 * H;
        if (t - 0.1).abs() < H / 2.0 {
            plant.v_g = 1.0 + dv;
        }
        let m = h.get_many(["m_a", "m_b", "m_c"]);
        plant.measure(&mut h, omega_b * t);
        let was_limited = h.get_bool("limit.current");
        assert_eq!(h.do_step(t, H), Status::Ok, "t = {t}");
        if h.get_bool("limit.current") {
            out.limited_time += H;
            if !was_limited {
                out.handovers += 1;
                out.first_handover.get_or_insert(t);
            }
        }
        out.i_peak = out.i_peak.max(h.get("i_ac"));
        out.q.push(h.get("q"));
        out.q_ref.push(h.get("q_ref"));
        out.p.push(h.get("p"));
        if h.get_bool("limit.modulation") {
            out.limited_at = Some(t);
            break;
        }
        plant.step(m, omega_b * (t + 0.5 * H));
    }
    out
}

/// Option B (`inner.kind` = 1, the LPV H∞ state feedback, docs/hinf.md) in the controller,
/// against option A on the same run. With `Tdes.Dq` = 1 (the reference `q₀ - μ_q/D_q Δv` moves
/// by 0.0019 pu on S_base after a 0.2 % dip of the grid voltage): option B starts flat, follows
/// the reference without steady-state error, the frame's swing settles, and its tracking error
/// is smaller than option A's (whose q integral is 0.5/s).
#[test]
fn option_b_tracks_the_reactive_reference_on_a_voltage_dip() {
    let (dv, t_end) = (-2e-3, 1.5);
    let step = (0.1 / H).round() as usize;
    let mut rms = [0.0; 2];
    for kind in [0, 1] {
        let r = run_dip(kind, 1.0, dv, t_end);
        assert_eq!((r.limited_at, r.handovers), (None, 0), "option {kind}");
        let flat = r.q[..step]
            .iter()
            .map(|x| (x - r.q[0]).abs())
            .fold(0.0, f64::max);
        let err: Vec<f64> = r.q.iter().zip(&r.q_ref).map(|(a, b)| a - b).collect();
        let change = r.q_ref.last().unwrap() - r.q_ref[0];
        rms[kind as usize] =
            (err[step..].iter().map(|e| e * e).sum::<f64>() / (err.len() - step) as f64).sqrt();
        let last = *err.last().unwrap();
        let p_swing = r.p[r.p.len() - (0.2 / H) as usize..]
            .iter()
            .map(|x| (x - 0.3).abs())
            .fold(0.0, f64::max);
        println!(
            "option {}: flat {flat:.1e} pu; q_ref moves by {change:.5} pu; |q - q_ref| at {t_end} s {:.2e} pu, rms after the dip {:.3e} pu; |p - p0| over the last 0.2 s {p_swing:.1e} pu",
            ["A", "B"][kind as usize],
            last.abs(),
            rms[kind as usize]
        );
        // The reference model's change: -mu_q/D_q dv on S_dvpp, 0.00192 pu on S_base.
        assert!((change - 0.00192).abs() < 2e-5, "{change}");
        if kind == 1 {
            assert!(flat < 1e-9, "flat start {flat}");
            assert!(last.abs() < 0.02 * change, "q - q_ref {last}");
            assert!(p_swing < 2e-3, "p swing {p_swing}");
        }
    }
    println!("rms tracking error, B over A: {:.3}", rms[1] / rms[0]);
    assert!(rms[1] < rms[0], "{rms:?}");
}

/// The figures of a dip run after the dip at 0.1 s: the rms of `q - q_ref` against the
/// controller's own reference and against the reference model's exact response to the grid's
/// step, `Δq_∞ (1 - e^{-(t - 0.1)/τ_q})`, the largest `|q - q_ref|` after 50 ms, and the largest
/// `|p - p₀|` in the whole run, from 1 to 1.5 s and in the last 0.5 s (S_base).
struct DipFigures {
    rms_own: f64,
    rms_model: f64,
    after_50ms: f64,
    p_peak: f64,
    p_mid: f64,
    p_last: f64,
}

fn dip_figures(r: &Dip, dq_inf: f64) -> DipFigures {
    let step = (0.1 / H).round() as usize;
    let n = r.q.len();
    let (q0, tau) = (r.q[0], 0.01);
    let rms = |f: &dyn Fn(usize) -> f64| {
        ((step..n).map(|k| dvpp_math::powi(f(k), 2)).sum::<f64>() / (n - step) as f64).sqrt()
    };
    let model = |k: usize| q0 + dq_inf * (1.0 - dvpp_math::exp(-((k - step) as f64 * H) / tau));
    let peak = |r0: std::ops::Range<usize>| r0.map(|k| (r.p[k] - 0.3).abs()).fold(0.0, f64::max);
    DipFigures {
        rms_own: rms(&|k| r.q[k] - r.q_ref[k]),
        rms_model: rms(&|k| r.q[k] - model(k)),
        after_50ms: (step + (0.05 / H) as usize..n)
            .map(|k| (r.q[k] - r.q_ref[k]).abs())
            .fold(0.0, f64::max),
        p_peak: peak(0..n),
        p_mid: peak((1.0 / H) as usize..(1.5 / H) as usize),
        p_last: peak(n - (0.5 / H) as usize..n),
    }
}

/// Option B at the default `Tdes.Dq` = 0.01 over the range of μ (the equivalent dc gain
/// `0.01/D_q`: 1, 0.5, 0.2, 0.1, 0.033) after a 0.2 % dip of the grid voltage: the frame's swing
/// decays and q follows the reference without steady-state error. The reference model reads
/// the MV-side voltage with the transformer's `L_t di_g/dt` (docs/hinf.md §8); with the phasor
/// estimate alone the same run at μ = 1 swung into the modulation limit at 1.24 s.
#[test]
fn option_b_is_stable_over_the_range_of_mu_at_the_default_reactive_droop() {
    let (dv, t_end) = (-2e-3, 3.0);
    for dq in [0.01, 0.02, 0.05, 0.1, 0.3] {
        let r = run_dip(1, dq, dv, t_end);
        let dq_inf = -dv / dq * 96.0 / S_BASE;
        let f = dip_figures(&r, dq_inf);
        let last = (r.q.last().unwrap() - r.q_ref.last().unwrap()).abs();
        println!(
            "option B, Dq {dq} (mu {:.3}): q_ref moves by {dq_inf:.4} pu; largest |p - p0| {:.3} pu, from 1 to 1.5 s {:.1e} pu, over the last 0.5 s {:.1e} pu; |q - q_ref| at {t_end} s {last:.1e} pu, largest after 50 ms {:.1e} pu, rms {:.3e} pu (against the model's response {:.3e} pu)",
            0.01 / dq,
            f.p_peak,
            f.p_mid,
            f.p_last,
            f.after_50ms,
            f.rms_own,
            f.rms_model
        );
        assert_eq!((r.limited_at, r.handovers), (None, 0), "Dq {dq}");
        // The swing decays: over the last 0.5 s below a third of what it was from 1 to 1.5 s,
        // and below 5e-3 pu.
        assert!(
            f.p_last < 0.35 * f.p_mid,
            "Dq {dq}: {} {}",
            f.p_last,
            f.p_mid
        );
        assert!(f.p_last < 5e-3, "Dq {dq}: {}", f.p_last);
        assert!(last < 1e-4, "Dq {dq}: {last}");
    }
}

/// Options A and B at the default `Tdes.Dq` = 0.01 (μ = 1) on the same dip: B follows the
/// reactive reference more closely (rms error after the dip, against its own reference and
/// against the reference model's exact response), at the price of a larger swing of the frame
/// (its fast change of q turns the voltage behind the virtual resistance before the p-f
/// reference model's frame follows); both settle.
#[test]
fn option_b_against_option_a_at_the_default_reactive_droop() {
    let (dv, dq) = (-2e-3, 0.01);
    let dq_inf = -dv / dq * 96.0 / S_BASE;
    let mut f = Vec::new();
    for kind in [0, 1] {
        let r = run_dip(kind, dq, dv, 3.0);
        assert_eq!((r.limited_at, r.handovers), (None, 0), "option {kind}");
        let x = dip_figures(&r, dq_inf);
        println!(
            "option {}, Dq 0.01: rms |q - q_ref| after the dip {:.3e} pu (against the model's response {:.3e} pu), largest after 50 ms {:.2e} pu; largest |p - p0| {:.3} pu, from 1 to 1.5 s {:.1e} pu, over the last 0.5 s {:.1e} pu",
            ["A", "B"][kind as usize],
            x.rms_own,
            x.rms_model,
            x.after_50ms,
            x.p_peak,
            x.p_mid,
            x.p_last
        );
        f.push(x);
    }
    println!(
        "B over A: rms {:.3}, against the model {:.3}; largest |p - p0| {:.1}",
        f[1].rms_own / f[0].rms_own,
        f[1].rms_model / f[0].rms_model,
        f[1].p_peak / f[0].p_peak
    );
    assert!(f[1].rms_own < 0.5 * f[0].rms_own);
    assert!(f[1].rms_model < 0.5 * f[0].rms_model);
    assert!(f[1].after_50ms < f[0].after_50ms);
    for x in &f {
        assert!(x.p_last < 0.02 * x.p_peak && x.p_last < 0.35 * x.p_mid);
    }
}

/// How exactly option B needs the transformer: its reactive reference model reads the MV-side
/// voltage the controller computes with `L_t di_g/dt`, and at μ = 1 (reference gain 160 on the
/// rating) an error in the controller's `L_t` puts back part of the loop through the grid's
/// voltage. With the design over the box of grids the dip of
/// [`option_b_is_stable_over_the_range_of_mu_at_the_default_reactive_droop`] settles with the
/// controller's `L_t` 10 % low; 5 % high the state feedback's loop is unstable: its current
/// reaches `I_max` within 20 ms of the dip, and at the default `I_max` the current limit
/// (docs/hinf.md §8.5) hands over to option A's cascade, which holds the current at `I_max` and
/// does not come off it (the reactive reference reads the same wrong `L_t`): the unit stays in
/// the limited mode to the end. This pins that limitation: the test fails when a design removes
/// it.
#[test]
fn option_b_needs_the_transformer_within_10_percent_low_and_hands_over_at_5_percent_high() {
    let low = run_dip_with(1, 0.01, -2e-3, 3.0, &[("L_t", 0.09)]);
    assert_eq!((low.limited_at, low.handovers), (None, 0));
    let f = dip_figures(&low, 0.192);
    println!(
        "option B, Dq 0.01, the controller's L_t 0.09: largest |p - p0| {:.3} pu, largest |i_f| {:.3} pu, from 1 to 1.5 s {:.1e} pu, over the last 0.5 s {:.1e} pu; rms |q - q_ref| {:.3e} pu",
        f.p_peak, low.i_peak, f.p_mid, f.p_last, f.rms_own
    );
    assert!(f.p_last < 1e-5, "{}", f.p_last);
    assert!(low.i_peak < 1.2, "{}", low.i_peak);
    let high = run_dip_with(1, 0.01, -2e-3, 3.0, &[("L_t", 0.105), ("I_max", 1.2)]);
    let first = high.first_handover.expect("no handover");
    println!(
        "the controller's L_t 0.105: first handover at {first:.5} s, {} handovers in 3 s, {:.2} s in the limited mode, largest |i_f| {:.3} pu",
        high.handovers, high.limited_time, high.i_peak
    );
    assert!(first < 0.12, "{first}");
    assert!(high.i_peak <= 1.05 * 1.2, "{}", high.i_peak);
    assert!(high.limited_time > 2.8, "{}", high.limited_time);
}

/// The frame (the p-f reference model, whose gain on the unit's power is `1/μ_p`) swings
/// against the grid; option B's gains were designed with it fixed, and its stabilizer (the
/// alignment's integral follows `Δw_q - k_a Δf`) damps it. On the stiff grid after the 0.2 %
/// dip at the default reactive droop the swing falls by at least 10⁴ within two seconds for
/// every p-f dc gain down to the grid-forming floor 0.05 (without the stabilizer, the gains let it
/// grow on this grid already at `mu_p` = 1 at `Tdes.Dq` = 1, and the unit tripped at 0.84 s at
/// `mu_p` = 0.3 with the stiff grid's design: docs/hinf.md §8).
#[test]
fn option_b_damps_the_frame_down_to_the_p_f_floor() {
    for mu_p in [1.0, 0.3, 0.1, 0.05] {
        let r = run_dip_with(1, 0.01, -2e-3, 3.0, &[("mu_p", mu_p)]);
        assert_eq!((r.limited_at, r.handovers), (None, 0), "mu_p {mu_p}");
        let w = (1.0 / H) as usize;
        let s: Vec<f64> =
            r.p.chunks(w)
                .map(|c| c.iter().map(|x| (x - 0.3).abs()).fold(0.0, f64::max))
                .collect();
        println!(
            "option B, mu_p {mu_p}: largest |p - p0| per second {}; largest |i_f| {:.3} pu",
            s.iter()
                .map(|x| format!("{x:.1e}"))
                .collect::<Vec<_>>()
                .join(", "),
            r.i_peak
        );
        // Down by at least 10⁴ within two seconds: a decay faster than 4.6/s.
        assert!(s[2] < 1e-4 * s[0], "mu_p {mu_p}: {s:?}");
    }
}

/// One experiment of the comparison of options A and B: the stiff grid's voltage (magnitude,
/// angle in rad) and the unit's reactive dc gain `mu_q` as functions of time.
struct Experiment {
    name: &'static str,
    t_end: f64,
    grid: fn(f64) -> (f64, f64),
    mu_q: fn(f64) -> f64,
}

/// The appendix's four experiments, from 0.1 s: a 0.2 % voltage dip (tracking of the reference
/// model), a 30 % dip for 150 ms, a 20° jump of the grid's phase, and the dip while the reactive
/// dc gain moves from 1 to 0.3 (as the cloud moves it); each `t_end` long.
fn experiments(t_end: f64) -> [Experiment; 4] {
    [
        Experiment {
            name: "0.2 % dip",
            t_end,
            grid: |t| (if t >= 0.1 { 0.998 } else { 1.0 }, 0.0),
            mu_q: |_| 1.0,
        },
        Experiment {
            name: "30 % dip for 150 ms",
            t_end,
            grid: |t| (if (0.1..0.25).contains(&t) { 0.7 } else { 1.0 }, 0.0),
            mu_q: |_| 1.0,
        },
        Experiment {
            name: "20° phase jump",
            t_end,
            grid: |t| (1.0, if t >= 0.1 { 20f64.to_radians() } else { 0.0 }),
            mu_q: |_| 1.0,
        },
        Experiment {
            name: "0.2 % dip, mu_q 1 → 0.3 over 0.5-1 s",
            t_end,
            grid: |t| (if t >= 0.1 { 0.998 } else { 1.0 }, 0.0),
            mu_q: |t| 1.0 - 0.7 * ((t - 0.5) / 0.5).clamp(0.0, 1.0),
        },
    ]
}

/// What one option did in one experiment (powers in pu of S_base, current of the rated peak),
/// `limit.current` per step and the controller's log.
struct Trace {
    t: Vec<f64>,
    q: Vec<f64>,
    q_ref: Vec<f64>,
    p: Vec<f64>,
    i: Vec<f64>,
    limited: Vec<bool>,
    log: Vec<String>,
}

impl Trace {
    /// How often `limit.current` rose (for option B: handovers to its current-limited mode),
    /// and how long it was set in all (s).
    fn handovers(&self) -> (usize, f64) {
        let rises = self
            .limited
            .iter()
            .zip(std::iter::once(&false).chain(&self.limited))
            .filter(|(now, before)| **now && !**before)
            .count();
        let time = self.limited.iter().filter(|l| **l).count() as f64 * H;
        (rises, time)
    }
}

/// The generic unit at 0.3 pu of S_base on the stiff grid, option `kind`, the default droop,
/// the controller's parameters `extra` set, through `e`.
fn run_experiment(kind: i32, e: &Experiment, extra: &[(&str, f64)]) -> Trace {
    let mut plant = Plant::at(0.3 * S_BASE / S_RATED, 0.0);
    let mut h = Harness::<DerEmt>::new();
    assert_eq!(h.setup_experiment(0.0, None), Status::Ok);
    h.set("S_rated", S_RATED);
    h.set("mode", 1);
    h.set("inner.kind", kind);
    for (name, value) in extra {
        h.set(name, *value);
    }
    h.set_debug_logging(true, &[]);
    assert_eq!(h.enter_initialization_mode(), Status::Ok);
    plant.measure(&mut h, 0.0);
    assert_eq!(h.exit_initialization_mode(), Status::Ok);
    let omega_b = 2.0 * PI * F_NOM;
    let mut out = Trace {
        t: vec![],
        q: vec![],
        q_ref: vec![],
        p: vec![],
        i: vec![],
        limited: vec![],
        log: vec![],
    };
    for k in 0..(e.t_end / H).round() as usize {
        let t = k as f64 * H;
        (plant.v_g, plant.jump) = (e.grid)(t);
        h.set("mu_q", (e.mu_q)(t));
        let m = h.get_many(["m_a", "m_b", "m_c"]);
        plant.measure(&mut h, omega_b * t);
        assert_eq!(h.do_step(t, H), Status::Ok, "{} t = {t}", e.name);
        out.t.push(t);
        out.q.push(h.get("q"));
        out.q_ref.push(h.get("q_ref"));
        out.p.push(h.get("p"));
        out.i.push(h.get("i_ac"));
        out.limited.push(h.get_bool("limit.current"));
        plant.step(m, omega_b * (t + 0.5 * H));
    }
    out.log = h.free_instance().into_iter().map(|r| r.message).collect();
    out
}

/// The figures of one trace: rms of `q - q_ref` from 0.1 s on, largest `|p - p₀|`, largest
/// `|p - p₀|` over the last 0.2 s, largest current.
fn trace_figures(r: &Trace) -> (f64, f64, f64, f64) {
    let from = ((0.1 / H).round() as usize).min(r.q.len());
    let n = r.q.len();
    let rms = if n > from {
        ((from..n)
            .map(|k| dvpp_math::powi(r.q[k] - r.q_ref[k], 2))
            .sum::<f64>()
            / (n - from) as f64)
            .sqrt()
    } else {
        0.0
    };
    let dev =
        |range: std::ops::Range<usize>| range.map(|k| (r.p[k] - r.p[0]).abs()).fold(0.0, f64::max);
    let last = n.saturating_sub((0.2 / H) as usize);
    let i_peak = r.i.iter().copied().fold(0.0, f64::max);
    (rms, dev(0..n), dev(last..n), i_peak)
}

/// Option B's current limit (docs/hinf.md §8.5) on the stiff grid at the default reactive
/// droop and `I_max` = 1.2 pu: through a 30 % dip for 150 ms and a 20° jump of the grid's phase
/// the converter current stays within `I_max` to 5 % (the handover acts on the command of the
/// next step: for about two samples of delay the current rises on, by up to 0.05 pu a sample
/// in the dip), where without the limit it passed 1.75 pu (and the unit used to trip at 1.5
/// `I_max`). The unit hands over to the limited mode within 12 ms of the event, logs it, and
/// after the event hands back to the state feedback, which follows the reactive reference
/// again: over the last 0.5 s of 2 s it runs the state feedback, `|q - q_ref|` below 5e-3 pu
/// and the frame's swing, `|p - p₀|`, below 0.02 pu of S_base.
#[test]
fn option_b_rides_through_a_deep_dip_and_a_phase_jump_within_its_current_limit() {
    let i_max = 1.2;
    for e in &experiments(2.0)[1..3] {
        let r = run_experiment(1, e, &[]);
        let (handovers, limited_time) = r.handovers();
        let (_, p_peak, _, i_peak) = trace_figures(&r);
        let first = r.limited.iter().position(|l| *l).map(|k| r.t[k]);
        let tail = r.t.len() - (0.5 / H) as usize;
        let q_err = (tail..r.t.len())
            .map(|k| (r.q[k] - r.q_ref[k]).abs())
            .fold(0.0, f64::max);
        let p_swing = (tail..r.t.len())
            .map(|k| (r.p[k] - r.p[0]).abs())
            .fold(0.0, f64::max);
        let events = r.log.iter().filter(|m| m.starts_with("option B:")).count();
        println!(
            "{}: largest |i_f| {i_peak:.4} pu (I_max {i_max}); first handover at {first:?} s, {handovers} in all, {limited_time:.3} s in the limited mode, {events} events logged; largest |p - p0| {p_peak:.3} pu; over the last 0.5 s largest |q - q_ref| {q_err:.1e} pu, |p - p0| {p_swing:.1e} pu",
            e.name
        );
        assert!(i_peak <= 1.05 * i_max, "{}: {i_peak}", e.name);
        assert!(
            first.is_some_and(|t| (0.1..0.112).contains(&t)),
            "{}: {first:?}",
            e.name
        );
        assert_eq!(events, 2 * handovers, "{}: {:?}", e.name, r.log);
        assert!(
            r.limited[tail..].iter().all(|l| !l),
            "{}: still limited",
            e.name
        );
        assert!(q_err < 5e-3, "{}: {q_err}", e.name);
        assert!(p_swing < 0.02, "{}: {p_swing}", e.name);
    }
}

/// The appendix's comparison, measured: the same unit with option A and with option B on the
/// same stiff grid at the default reactive droop through [`experiments`], and option B once
/// more with `I_max` raised to 1.5 pu, where its current limit does not act in the small-signal
/// experiments (the state feedback alone). Prints the table of docs/hinf.md §9; with
/// `DVPP_FIGURE_DIR` set writes `hinf_compare.svg` there. Asserts what each option does better,
/// as measured: both ride through all four within `I_max` to 5 %; option B tracks the reference
/// more closely in the two small-signal experiments (by a factor 1.4 with its limit acting, 6.8
/// without) and moves the active power more; option A's swing decays.
#[test]
fn options_a_and_b_compared() {
    let experiments = experiments(1.5);
    let i_max = 1.2;
    println!("| experiment | option | rms of q - q_ref from the event (pu) | largest abs(p - p0) (pu) | over the last 0.2 s | largest current (pu of rated) | handovers, time in the limited mode |");
    println!("|---|---|---|---|---|---|---|");
    let mut panels = vec![];
    let mut results = vec![];
    for e in &experiments {
        let (a, b) = (run_experiment(0, e, &[]), run_experiment(1, e, &[]));
        let unlimited = [0, 3]
            .iter()
            .any(|k| experiments[*k].name == e.name)
            .then(|| run_experiment(1, e, &[("I_max", 1.5)]));
        let mut panel = dvpp_report::plot::Panel::new(e.name, "t (s)", "q - q_ref (pu on 100 MVA)");
        let mut rows = vec![("A", &a), ("B", &b)];
        if let Some(u) = &unlimited {
            rows.push(("B, I_max 1.5", u));
        }
        for (label, r) in rows {
            let (rms, p_peak, p_last, i_peak) = trace_figures(r);
            let (n, time) = r.handovers();
            let limited = if label == "A" {
                "-".to_string()
            } else {
                format!("{n}, {time:.3} s")
            };
            println!(
                "| {} | {label} | {rms:.3e} | {p_peak:.3} | {p_last:.1e} | {i_peak:.3} | {limited} |",
                e.name
            );
            let err: Vec<f64> =
                r.q.iter()
                    .zip(&r.q_ref)
                    .map(|(q, q_ref)| q - q_ref)
                    .collect();
            let style = match label {
                "A" => dvpp_report::plot::Style::Solid,
                "B" => dvpp_report::plot::Style::Dashed,
                _ => dvpp_report::plot::Style::Dotted,
            };
            panel = panel.series(format!("option {label}"), &r.t, &err, style);
        }
        panels.push(panel);
        results.push((
            trace_figures(&a),
            trace_figures(&b),
            b.handovers(),
            unlimited.map(|u| (trace_figures(&u), u.handovers())),
        ));
    }
    if let Some(dir) = std::env::var_os("DVPP_FIGURE_DIR") {
        let path = std::path::Path::new(&dir).join("hinf_compare.svg");
        let mut figure = dvpp_report::plot::Figure::new(
            "Options A (PI cascade) and B (LPV H∞, with its current limit) on a stiff grid, default reactive droop: reactive tracking error",
        );
        for panel in panels {
            figure = figure.panel(panel);
        }
        figure
            .columns(2)
            .save(&path)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        println!("wrote {}", path.display());
    }
    for (k, (a, b, (handovers, _), unlimited)) in results.iter().enumerate() {
        let name = experiments[k].name;
        // Both ride through all four within their current limit...
        assert!(a.3 <= i_max * 1.05, "{name}: A {}", a.3);
        assert!(b.3 <= i_max * 1.05, "{name}: B {}", b.3);
        // ... option B by handing over to its limited mode: in every experiment at I_max 1.2,
        // its own current reaching 1.345 pu already in the 0.2 % dip.
        assert!(*handovers >= 1, "{name}");
        // Option A's frame's swing decays: over the last 0.2 s below a quarter of the largest.
        assert!(a.2 < 0.25 * a.1, "{name}: {} of {}", a.2, a.1);
        // Option B moves the active power more.
        assert!(b.1 > a.1, "{name}: {} vs {}", b.1, a.1);
        if let Some((u, (n, _))) = unlimited {
            // Option B tracks more closely in the small-signal experiments: with its limit
            // acting, and by far more without it (the state feedback alone).
            assert_eq!(*n, 0, "{name}");
            assert!(b.0 < 0.8 * a.0, "{name}: {} vs {}", b.0, a.0);
            assert!(u.0 < 0.2 * a.0, "{name}: {} vs {}", u.0, a.0);
            assert!(u.3 > i_max, "{name}: {}", u.3);
        }
    }
}
