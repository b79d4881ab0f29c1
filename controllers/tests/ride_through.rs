//! The grid-forming EMT unit's ride-through (option A): `EmtUnit` in closed loop with the EMT plant's test bench, synchronism kept through 5 Hz/s ramps and a 25° jump at SCR 3 while current-limited, the post-fault swing damped, reactive fault current injected and every phase current within I_max through balanced and unbalanced faults with either grounding.
//!
//! The unit is the conformance test's generic 60 MVA unit (the paper's filter and transformer,
//! static ADPFs carrying the whole DVPP's T_des, μ_p = μ_q = 1, `vq.tau` = 0.5 s), grid-forming
//! with option A's inner loops, as storage (the source's range ±P_avail, so that the ramps
//! up and down are alike). It feeds 0.3 pu on S_base (0.5 pu of its rating) into a Thevenin
//! source (X/R = 10) through its filter and transformer, no load. `P_avail` = 0.9 pu on S_base
//! (1.5 of the rating), so that the current limit, not the source, binds.
//!
//! `cargo test --release` runs every case (6 s); a debug build a lean set (one of each kind).
//! `RIDE_THROUGH_TRACE=FILE` appends each run's trace to FILE (every 40th step, or
//! `RIDE_THROUGH_EVERY`): t, the frame's and the grid's frequency (Hz), the PCC voltage's angle
//! in the frame (rad), p, q, v, the phase peak, active and reactive current, the limit flag, E,
//! v_dc and the modulation and source limit flags.

mod support;
use dvpp_control::converter::{Abc, Dq};
use dvpp_controllers::emt::{EmtParams, EmtUnit, InnerKind};
use dvpp_controllers::Mode;
use emt_plant_model::Plant;
use fmi_export::harness::Harness;
use fmi_export::Status;
use std::f64::consts::PI;
use support::{command, measure, plant_for, GAINS, THEVENIN_UNIT};

/// The step (s).
const H: f64 = 50e-6;
/// When every event starts (s).
const T_EVENT: f64 = 0.5;

/// A bench event.
#[derive(Clone, Copy, Debug)]
enum Event {
    /// The source's frequency ramps at `rocof` (Hz/s) for `duration` (s), then holds.
    Ramp { rocof: f64, duration: f64 },
    /// The source's angle jumps (rad).
    Jump(f64),
    /// The source dips to `1 - depth` of its voltage for 150 ms.
    Dip(f64),
    /// A fault at the PCC for 150 ms: `kind` as `fault.type`, through `r` + j`x` (pu on S_base).
    Fault { kind: i32, r: f64, x: f64 },
}

/// One run's setting.
#[derive(Clone, Copy, Debug)]
struct Setting {
    scr: f64,
    event: Event,
    /// `der[1].grounding`: 0 three-wire, 1 grounded star.
    grounding: i32,
    t_end: f64,
}

/// One sample of a run.
#[derive(Clone, Copy, Debug, Default)]
struct Sample {
    t: f64,
    /// The unit's frame frequency and the source's (Hz beyond f_nom).
    f_unit: f64,
    f_grid: f64,
    /// The PCC voltage's angle in the unit's frame, unwrapped (rad).
    delta: f64,
    /// Power (S_base), voltage magnitude at the MV side.
    p: f64,
    q: f64,
    v: f64,
    /// Largest converter phase current (pu of the rated peak) and its zero sequence.
    i_peak: f64,
    i_zero: f64,
    /// The converter current's negative sequence in a frame turning backward at `f_nom` (its
    /// mean over whole cycles is the negative-sequence phasor).
    i_neg: Dq,
    /// Converter current in the MV voltage's frame: active (along it) and reactive (lagging
    /// it by 90°: injected reactive power) components, pu of the rated peak.
    i_active: f64,
    i_reactive: f64,
    limited: bool,
    /// The q PI's E.
    e: f64,
    /// The dc voltage (pu), and the modulation and the source at their limits.
    v_dc: f64,
    limit_modulation: bool,
    limit_source: bool,
}

/// The conformance test's generic unit, grid-forming, option A, as storage with 0.9 pu of
/// S_base available.
fn unit_params() -> EmtParams {
    let mut p = support::unit_params(Mode::GridForming, InnerKind::OptionA);
    p.source.storage = true;
    p.source.p_avail0 = 0.9;
    p
}

fn three(plant: &mut Harness<Plant>, w: &str) -> Abc {
    let [a, b, c] = ["a", "b", "c"].map(|ph| plant.get(&format!("{w}_{ph}")));
    Abc { a, b, c }
}

/// The closed loop over `s`; one sample per step.
fn run(s: Setting) -> Vec<Sample> {
    let params = unit_params();
    let mut plant = plant_for(THEVENIN_UNIT, &params);
    let f = params.filter;
    let x = params.rating.s_base / (params.rating.s_rated * s.scr);
    plant.set("thevenin.X", x);
    plant.set("thevenin.R", x / 10.0);
    plant.set("der[1].grounding", s.grounding);
    match s.event {
        Event::Ramp { rocof, duration } => {
            plant.set("thevenin.rocof", rocof);
            plant.set("thevenin.rocof_t", T_EVENT);
            plant.set("thevenin.rocof_duration", duration);
        }
        Event::Jump(angle) => {
            plant.set("thevenin.jump", angle);
            plant.set("thevenin.jump_t", T_EVENT);
        }
        Event::Dip(depth) => {
            plant.set("thevenin.dip", depth);
            plant.set("thevenin.dip_t", T_EVENT);
            plant.set("thevenin.dip_duration", 0.15);
        }
        Event::Fault { kind, r, x } => {
            plant.set("fault.type", kind);
            plant.set("fault.R", r);
            plant.set("fault.X", x);
            plant.set("fault.t", T_EVENT);
            plant.set("fault.duration", 0.15);
        }
    }
    assert_eq!(plant.enter_initialization_mode(), Status::Ok);
    assert_eq!(
        plant.exit_initialization_mode(),
        Status::Ok,
        "{s:?}: {:?}",
        plant.log()
    );
    let (mut unit, mut cmd) =
        EmtUnit::initialize(&params, &measure(&mut plant, 0.0), &GAINS).expect("initialize");
    let f_nom = params.rating.f_nom;
    let omega_b = 2.0 * PI * f_nom;
    let n = (s.t_end / H).round() as usize;
    let mut out = Vec::with_capacity(n);
    let mut delta_prev: Option<f64> = None;
    let mut turns = 0.0;
    for k in 0..n {
        let t = k as f64 * H;
        command(&mut plant, &cmd);
        let m = measure(&mut plant, t);
        // The frame the unit reads these measurements in.
        let rho = (omega_b * t).rem_euclid(2.0 * PI) + cmd.theta;
        let pcc = three(&mut plant, "pcc.v").to_dq(rho);
        let raw = dvpp_math::atan2(pcc.q, pcc.d);
        if let Some(prev) = delta_prev {
            let d: f64 = raw + turns - prev;
            if d > PI {
                turns -= 2.0 * PI;
            } else if d < -PI {
                turns += 2.0 * PI;
            }
        }
        let delta = raw + turns;
        delta_prev = Some(delta);
        let f_grid = (plant.get("thevenin.f") - 1.0) * f_nom;
        // The converter current against the MV voltage's direction.
        let fm_i = m.i_f.to_dq(rho);
        let fm_v = m.v_c.to_dq(rho);
        let fm_ig = m.i_g.to_dq(rho);
        let vg = fm_v - fm_ig * f.r_t - fm_ig.rot90() * f.l_t;
        let u = vg.norm().max(1e-6);
        let dir = Dq {
            d: vg.d / u,
            q: vg.q / u,
        };
        let i_active = fm_i.d * dir.d + fm_i.q * dir.q;
        let i_reactive = fm_i.d * dir.q - fm_i.q * dir.d;
        cmd = unit
            .step(&m, &GAINS, H)
            .unwrap_or_else(|e| panic!("{s:?}: t = {t}: {e}"));
        assert_eq!(plant.do_step(t, H), Status::Ok, "{s:?}: plant at {t}");
        out.push(Sample {
            t,
            f_unit: cmd.df * f_nom,
            f_grid,
            delta,
            p: cmd.p,
            q: cmd.q,
            v: cmd.v,
            i_peak: m.i_f.peak(),
            i_zero: (m.i_f.a + m.i_f.b + m.i_f.c) / 3.0,
            // The a-c-b sequence in the forward frame is the a-b-c negative sequence.
            i_neg: Abc {
                a: m.i_f.a,
                b: m.i_f.c,
                c: m.i_f.b,
            }
            .to_dq((omega_b * t).rem_euclid(2.0 * PI)),
            i_active,
            i_reactive,
            limited: cmd.limit_current,
            e: cmd.e,
            v_dc: m.v_dc,
            limit_modulation: cmd.limit_modulation,
            limit_source: cmd.limit_source,
        });
    }
    if let Ok(path) = std::env::var("RIDE_THROUGH_TRACE") {
        use std::io::Write;
        let mut f = std::fs::OpenOptions::new()
            .append(true)
            .create(true)
            .open(path)
            .unwrap();
        writeln!(f, "# {s:?}").unwrap();
        for x in out
            .iter()
            .step_by(std::env::var("RIDE_THROUGH_EVERY").map_or(40, |v| v.parse().unwrap()))
        {
            writeln!(
                f,
                "{:.4} {:.4} {:.4} {:.4} {:.4} {:.4} {:.4} {:.3} {:.3} {:.3} {} {:.3} {:.3} {} {}",
                x.t,
                x.f_unit,
                x.f_grid,
                x.delta,
                x.p,
                x.q,
                x.v,
                x.i_peak,
                x.i_active,
                x.i_reactive,
                u8::from(x.limited),
                x.e,
                x.v_dc,
                u8::from(x.limit_modulation),
                u8::from(x.limit_source)
            )
            .unwrap();
        }
    }
    out
}

/// The samples within `[t0, t1)`.
fn window(r: &[Sample], t0: f64, t1: f64) -> impl Iterator<Item = &Sample> {
    r.iter().filter(move |s| s.t >= t0 && s.t < t1)
}

fn max_of(r: &[Sample], t0: f64, t1: f64, f: impl Fn(&Sample) -> f64) -> f64 {
    window(r, t0, t1).map(f).fold(f64::NEG_INFINITY, f64::max)
}

fn mean_of(r: &[Sample], t0: f64, t1: f64, f: impl Fn(&Sample) -> f64) -> f64 {
    let (s, n) = window(r, t0, t1).fold((0.0, 0usize), |(s, n), x| (s + f(x), n + 1));
    s / n as f64
}

/// What a synchronism run shows.
#[derive(Debug)]
struct Sync {
    /// Largest |f_unit - f_grid| (Hz) over the run after the event, and over its last 0.5 s.
    df_max: f64,
    df_end: f64,
    /// Range of the angle difference (rad) over the run after the event.
    delta_range: f64,
    /// The frame's and the grid's frequency extremes (Hz).
    f_unit: (f64, f64),
    f_grid: (f64, f64),
    /// Samples limited.
    limited: usize,
    /// |p - p_ref| over the last 0.5 s (S_base), p_ref the reference model's steady state.
    dp_end: f64,
}

fn sync(s: Setting) -> Sync {
    let r = run(s);
    let p = unit_params();
    let t_end = s.t_end;
    let lo_hi = |f: &dyn Fn(&Sample) -> f64| {
        window(&r, T_EVENT, t_end).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
            (lo.min(f(x)), hi.max(f(x)))
        })
    };
    let d = lo_hi(&|x| x.delta);
    let f_end = r.last().unwrap().f_grid;
    // The reference model's steady state at the grid's final frequency: Δp = -D Δf (S_dvpp).
    let p_ref = 0.3 - p.tdes.d * (f_end / p.rating.f_nom) * p.rating.s_dvpp / p.rating.s_base;
    let out = Sync {
        df_max: max_of(&r, T_EVENT, t_end, |x| (x.f_unit - x.f_grid).abs()),
        df_end: max_of(&r, t_end - 0.5, t_end, |x| (x.f_unit - x.f_grid).abs()),
        delta_range: d.1 - d.0,
        f_unit: lo_hi(&|x| x.f_unit),
        f_grid: lo_hi(&|x| x.f_grid),
        limited: r.iter().filter(|x| x.limited).count(),
        dp_end: max_of(&r, t_end - 0.5, t_end, |x| (x.p - p_ref).abs()),
    };
    println!("{s:?}: {out:?}");
    out
}

/// The post-event swing of `r` after `t0`: the damping ratio from the logarithmic decrement of
/// the first two peaks of the same sign of `p` (10 ms moving average) about its final value,
/// the swing's frequency (Hz), and the recovery time after `t0` (s): when `|p - p_end|` falls
/// below 5 % of the unit's rating for good.
fn swing(r: &[Sample], t0: f64) -> (f64, f64, f64) {
    let n_avg = (0.02 / H) as usize;
    let s_rated = unit_params().rating.s_rated / unit_params().rating.s_base;
    let p_end = mean_of(r, r.last().unwrap().t - 0.2, f64::INFINITY, |x| x.p);
    let seg: Vec<&Sample> = window(r, t0, f64::INFINITY).collect();
    let avg: Vec<(f64, f64)> = seg
        .windows(n_avg)
        .step_by(10)
        .map(|w| {
            (
                w[n_avg / 2].t,
                w.iter().map(|x| x.p).sum::<f64>() / n_avg as f64 - p_end,
            )
        })
        .collect();
    // Extrema: sign changes of the slope.
    let mut peaks = Vec::new();
    for k in 1..avg.len() - 1 {
        let (a, b, c) = (avg[k - 1].1, avg[k].1, avg[k + 1].1);
        let spaced = peaks
            .last()
            .is_none_or(|x: &(f64, f64)| avg[k].0 - x.0 > 0.05);
        if (b > a && b >= c || b < a && b <= c) && b.abs() > 1e-3 && spaced {
            peaks.push(avg[k]);
        }
    }
    // From the second peak on (the first is the event's own), half a period each.
    let half: Vec<(f64, f64)> = peaks
        .iter()
        .skip(1)
        .zip(peaks.iter().skip(2))
        .take(4)
        .filter(|(a, b)| a.1 * b.1 < 0.0)
        .map(|(a, b)| {
            (
                2.0 * dvpp_math::log(a.1.abs() / b.1.abs()),
                2.0 * (b.0 - a.0),
            )
        })
        .collect();
    let zeta = if half.is_empty() {
        (1.0, 0.0)
    } else {
        let n = half.len() as f64;
        let dec = half.iter().map(|x| x.0).sum::<f64>() / n;
        let period = half.iter().map(|x| x.1).sum::<f64>() / n;
        (dec / dvpp_math::hypot(2.0 * PI, dec), 1.0 / period)
    };
    let tol = 0.05 * s_rated;
    let last_out = seg
        .iter()
        .rev()
        .find(|x| (x.p - p_end).abs() > tol)
        .map_or(t0, |x| x.t);
    (zeta.0, zeta.1, last_out - t0)
}

/// Whether the run is the lean one of a debug build (the workspace's `cargo test`): one case of
/// each kind, shorter; `cargo test --release` runs them all (6.5 s).
const LEAN: bool = cfg!(debug_assertions);

/// The ramps: 5 Hz/s for 0.2 s (to ∓1 Hz: the reference model's power at 1 Hz, 1.37 pu of the
/// rating, stays beyond the limit) and for 0.1 s (to ∓0.5 Hz, within it), down and up.
const RAMPS: [(f64, f64); 4] = [(-5.0, 0.2), (5.0, 0.2), (-5.0, 0.1), (5.0, 0.1)];

/// Synchronism at 5 Hz/s while current-limited: the frame's frequency follows the grid's (within
/// 0.6 Hz over the ramp, 0.05 Hz over the last 0.5 s), the PCC voltage's angle in the frame
/// moves by less than 1 rad, and where the reference model's power is within the limit the
/// power returns to it (within 0.08 pu on S_base, 0.13 of the rating, over the last 0.5 s).
/// Before the frame's synchronizing term the frame ran to +1.46 Hz while the grid fell to -0.5
/// Hz (-1 Hz alike).
#[test]
fn synchronism_is_kept_through_5_hz_per_s_ramps() {
    for (rocof, duration) in RAMPS.into_iter().take(if LEAN { 1 } else { 4 }) {
        let s = sync(Setting {
            scr: 10.0,
            event: Event::Ramp { rocof, duration },
            grounding: 0,
            t_end: if LEAN { 2.0 } else { 2.5 },
        });
        let what = format!("{rocof} Hz/s for {duration} s: {s:?}");
        assert!(s.df_max < 0.6, "{what}");
        assert!(s.df_end < 0.05, "{what}");
        assert!(s.delta_range < 1.0, "{what}");
        // The frame's frequency moves the grid's way and no further than 0.6 Hz beyond it.
        let f_end = rocof * duration;
        let f_grid = if rocof < 0.0 { s.f_grid.0 } else { s.f_grid.1 };
        assert!((f_grid - f_end).abs() < 1e-9, "{what}");
        if rocof < 0.0 {
            assert!(s.f_unit.0 > f_end - 0.6 && s.f_unit.1 < 0.01, "{what}");
        } else {
            assert!(s.f_unit.1 < f_end + 0.6 && s.f_unit.0 > -0.01, "{what}");
        }
        if duration < 0.15 {
            assert!(s.dp_end < 0.08, "{what}");
        }
    }
    // The limit acts in the ramp down to -1 Hz (the case that lost synchronism).
    let s = sync(Setting {
        scr: 10.0,
        event: Event::Ramp {
            rocof: -5.0,
            duration: 0.2,
        },
        grounding: 0,
        t_end: 0.8,
    });
    assert!(s.limited > 1000, "{s:?}");
}

/// A 25° phase jump at SCR 3 (either sign): the frame follows (the angle difference settles,
/// the frequencies meet).
#[test]
fn synchronism_is_kept_through_a_25_degree_jump_at_scr_3() {
    for sign in [-1.0, 1.0].into_iter().take(if LEAN { 1 } else { 2 }) {
        let s = sync(Setting {
            scr: 3.0,
            event: Event::Jump(sign * 25f64.to_radians()),
            grounding: 0,
            t_end: 2.0,
        });
        assert!(s.df_max < 0.6, "{s:?}");
        assert!(s.df_end < 0.05, "{s:?}");
        assert!(s.delta_range < 0.6, "{s:?}");
    }
}

/// How far a phase current may exceed I_max (fraction): the reference is limited in the dq
/// frame, which bounds every phase of the reference (a phase is a projection of the αβ vector);
/// the current loop's tracking error over the faults' edges is what passes (measured 1.033).
const I_TOLERANCE: f64 = 0.05;

/// The largest negative-sequence current (pu) in the unbalanced faults: not controlled, what the
/// voltage loop asks to hold the capacitor voltage (measured up to 0.38 pu, in the LL fault).
const NEG_MAX: f64 = 0.45;

/// Every phase of the converter current within `I_max (1 + I_TOLERANCE)` through three-phase
/// (bolted and resistive), single line to ground, line to line and line to line to ground
/// faults at the PCC, for a three-wire converter and a grounded star; with the star grounded,
/// the zero-sequence current is controlled to below 0.1 pu (before: 1.40 pu in a SLG fault,
/// phase peaks 2.37 pu, and 2.64 pu in a LLG fault).
#[test]
fn phase_currents_stay_within_i_max_in_every_fault() {
    let i_max = unit_params().inner.i_max;
    let faults = [
        (1, 0.0, 0.05),
        (1, 0.1, 1e-4),
        (2, 0.01, 0.01),
        (3, 0.01, 0.01),
        (4, 0.01, 0.01),
    ];
    for grounding in [0, 1] {
        for (kind, r, x) in faults {
            // Lean: the SLG and LLG faults with the star grounded, the LL fault three-wire.
            if LEAN && !matches!((kind, grounding), (2 | 4, 1) | (3, 0)) {
                continue;
            }
            let run = run(Setting {
                scr: 10.0,
                event: Event::Fault { kind, r, x },
                grounding,
                t_end: 1.0,
            });
            let peak = max_of(&run, 0.0, 1.0, |x| x.i_peak);
            let zero = max_of(&run, 0.0, 1.0, |x| x.i_zero.abs());
            let after = max_of(&run, 0.9, 1.0, |x| (x.f_unit - x.f_grid).abs());
            // Negative sequence over the fault's last 100 ms (5 cycles).
            let (t0, t1) = (T_EVENT + 0.05, T_EVENT + 0.15);
            let neg = Dq {
                d: mean_of(&run, t0, t1, |x| x.i_neg.d),
                q: mean_of(&run, t0, t1, |x| x.i_neg.q),
            }
            .norm();
            let pos = mean_of(&run, t0, t1, |x| dvpp_math::hypot(x.i_active, x.i_reactive));
            println!(
                "fault {kind} (R {r}, X {x}), grounding {grounding}: phase peak {peak:.3} pu = {:.3} I_max, zero sequence up to {zero:.3} pu, negative sequence {neg:.3} pu (mean |i_dq| {pos:.3}); |f_unit - f_grid| {after:.3} Hz 0.25 s after",
                peak / i_max
            );
            assert!(
                peak <= i_max * (1.0 + I_TOLERANCE),
                "fault {kind}, grounding {grounding}: phase peak {peak}"
            );
            assert!(
                zero < 0.1,
                "fault {kind}, grounding {grounding}: zero sequence {zero}"
            );
            assert!(
                after < 0.5,
                "fault {kind}, grounding {grounding}: {after} Hz"
            );
            // Negative sequence: not controlled (what the voltage loop asks to hold the
            // capacitor voltage, within the instantaneous limit).
            assert!(
                neg < NEG_MAX,
                "fault {kind}, grounding {grounding}: negative sequence {neg}"
            );
        }
    }
}

/// A 150 ms dip of the source to 0.5 pu at SCR 10: the unit injects reactive current
/// (positive: lagging the MV voltage) while limited, at least half the rated current and more
/// than its active current (measured 0.95 reactive, 0.73 active; before the threshold virtual
/// impedance 0.40 and 1.13 — a grid code's `K` = 2 asks about 1 pu for this dip).
#[test]
fn reactive_current_is_injected_in_a_dip() {
    let r = run(Setting {
        scr: 10.0,
        event: Event::Dip(0.5),
        grounding: 0,
        t_end: 0.7,
    });
    let t1 = T_EVENT + 0.15;
    let reactive = mean_of(&r, T_EVENT + 0.02, t1, |x| x.i_reactive);
    let active = mean_of(&r, T_EVENT + 0.02, t1, |x| x.i_active);
    println!("0.5 pu dip: active {active:.3}, reactive {reactive:.3} pu");
    assert!(
        reactive > 0.5 && reactive > active,
        "reactive {reactive}, active {active}"
    );
    assert!(window(&r, T_EVENT, t1).filter(|x| x.limited).count() > 100);
}

/// A 150 ms dip of the source to 0.5 pu at SCR 10: the swing after it (the frame against the
/// grid, with the q PI's E) has a damping ratio of at least 0.3 and the power is back within
/// 5 % of the rating within 1 s of the dip's end (measured ζ 0.41 at 1.4 Hz, 0.49 s; before the
/// frame damping ζ 0.094 at 1.70 Hz, 1.9 s).
#[test]
fn the_swing_after_a_dip_is_damped() {
    let r = run(Setting {
        scr: 10.0,
        event: Event::Dip(0.5),
        grounding: 0,
        t_end: 2.5,
    });
    let (zeta, f, recovery) = swing(&r, T_EVENT + 0.15);
    println!("0.5 pu dip: zeta {zeta:.3} at {f:.2} Hz, recovery {recovery:.3} s");
    assert!(zeta >= 0.3, "zeta {zeta} at {f} Hz");
    assert!(recovery <= 1.0, "recovery {recovery} s");
}

/// Not met yet (docs/emt.md §9, current limit and ride-through): reactive current injected in a
/// resistive three-phase fault (measured -0.99 pu: absorbed; before -1.10).
#[test]
#[ignore = "open: the limited current keeps the voltage loop's direction"]
fn reactive_current_in_a_resistive_fault() {
    let resistive = run(Setting {
        scr: 10.0,
        event: Event::Fault {
            kind: 1,
            r: 0.1,
            x: 1e-4,
        },
        grounding: 0,
        t_end: 0.7,
    });
    let reactive = mean_of(&resistive, T_EVENT + 0.02, T_EVENT + 0.15, |x| x.i_reactive);
    println!("resistive three-phase fault: reactive {reactive:.3} pu");
    assert!(reactive > 0.0, "reactive {reactive}");
}
