//! Option B's current limit on the EMT plant's circuit: the grid-forming unit with option A and with option B on a Thevenin source of SCR 10 through a shallow and a deep dip, a phase jump, a frequency ramp and a three-phase fault at the PCC, its converter current within I_max and settled after each.
//!
//! The unit is the conformance test's generic 60 MVA grid-forming unit (the paper's filter and
//! transformer, static ADPFs carrying the whole DVPP's T_des, μ_p = μ_q = 1, the default reactive
//! droop `Tdes.Dq` = 0.01), feeding 0.3 pu of S_base into the source (X/R = 10) through its
//! filter and transformer. With option B (the H∞ state feedback, docs/hinf.md) the unit used to
//! trip at 1.5 `I_max` in each of these events; its current limit (§8.5) hands over to option A's
//! cascade while the current needs limiting and back to the state feedback after.

mod support;
use dvpp_control::converter::InnerDesign;
use dvpp_controllers::emt::{EmtUnit, InnerKind};
use dvpp_controllers::Mode;
use fmi_export::Status;
use support::{command, measure, plant_for, unit_params, GAINS, THEVENIN_UNIT};

/// The step (s).
const H: f64 = 50e-6;
/// The event's time (s) and the run's end (s).
const T_EVENT: f64 = 0.3;
const T_END: f64 = 2.0;
/// How far the converter current (its dq magnitude) may pass I_max (fraction).
const I_TOLERANCE: f64 = 0.05;

/// One event of the bench: its name and the plant's parameters that make it at `T_EVENT`.
struct Event {
    name: &'static str,
    plant: &'static [(&'static str, f64)],
}

/// The frequency ramp that leaves the source beyond what the unit's rating can answer.
const LONG_RAMP: &str = "-5 Hz/s for 0.2 s, then held";

const EVENTS: [Event; 6] = [
    Event {
        name: "dip to 0.9 pu for 150 ms",
        plant: &[("thevenin.dip", 0.1), ("thevenin.dip_duration", 0.15)],
    },
    Event {
        name: "dip to 0.7 pu for 150 ms",
        plant: &[("thevenin.dip", 0.3), ("thevenin.dip_duration", 0.15)],
    },
    Event {
        name: "25° phase jump",
        plant: &[("thevenin.jump", 25.0 * std::f64::consts::PI / 180.0)],
    },
    Event {
        name: "-5 Hz/s for 0.06 s, then held",
        plant: &[("thevenin.rocof", -5.0), ("thevenin.rocof_duration", 0.06)],
    },
    Event {
        name: LONG_RAMP,
        plant: &[("thevenin.rocof", -5.0), ("thevenin.rocof_duration", 0.2)],
    },
    Event {
        name: "three-phase fault at the PCC, 0.15 s",
        plant: &[
            ("fault.type", 1.0),
            ("fault.X", 0.05),
            ("fault.duration", 0.15),
        ],
    },
];

/// What a run shows.
#[derive(Debug, Default)]
struct Run {
    /// Largest converter current (dq magnitude, pu of the rated peak) over the run.
    i_peak: f64,
    /// How often `limit.current` rose, and the samples it was set.
    handovers: usize,
    limited: usize,
    /// Over the last 0.5 s: whether `limit.current` was set, the largest `|p - p_end|`,
    /// `|q - q_ref|` (pu on S_base).
    limited_at_end: bool,
    p_swing: f64,
    q_err: f64,
}

/// The unit with `kind` on the source of SCR 10 through `e`.
fn run(kind: InnerKind, e: &Event) -> Run {
    let params = unit_params(Mode::GridForming, kind);
    let mut plant = plant_for(THEVENIN_UNIT, &params);
    let x = params.rating.s_base / (params.rating.s_rated * 10.0);
    plant.set("thevenin.X", x);
    plant.set("thevenin.R", x / 10.0);
    for time in [
        "thevenin.dip_t",
        "thevenin.jump_t",
        "thevenin.rocof_t",
        "fault.t",
    ] {
        plant.set(time, T_EVENT);
    }
    for (name, value) in e.plant {
        if *name == "fault.type" {
            plant.set(name, *value as i32);
        } else {
            plant.set(name, *value);
        }
    }
    assert_eq!(plant.enter_initialization_mode(), Status::Ok);
    assert_eq!(
        plant.exit_initialization_mode(),
        Status::Ok,
        "{}: {:?}",
        e.name,
        plant.log()
    );
    let (mut unit, mut cmd) =
        EmtUnit::initialize(&params, &measure(&mut plant, 0.0), &GAINS).expect("initialize");
    let mut out = Run::default();
    let mut tail = vec![];
    let n = (T_END / H).round() as usize;
    for k in 0..n {
        let t = k as f64 * H;
        command(&mut plant, &cmd);
        let m = measure(&mut plant, t);
        let was = cmd.limit_current;
        cmd = unit
            .step(&m, &GAINS, H)
            .unwrap_or_else(|err| panic!("{} ({kind:?}): t = {t}: {err}", e.name));
        assert_eq!(plant.do_step(t, H), Status::Ok, "{}: plant at {t}", e.name);
        out.i_peak = out.i_peak.max(cmd.i_ac);
        out.handovers += usize::from(cmd.limit_current && !was);
        out.limited += usize::from(cmd.limit_current);
        if t >= T_END - 0.5 {
            out.limited_at_end |= cmd.limit_current;
            tail.push((cmd.p, cmd.q - cmd.q_ref));
        }
    }
    let p_end = tail.last().unwrap().0;
    out.p_swing = tail
        .iter()
        .map(|(p, _)| (p - p_end).abs())
        .fold(0.0, f64::max);
    out.q_err = tail.iter().map(|(_, q)| q.abs()).fold(0.0, f64::max);
    println!(
        "{} ({kind:?}): largest |i_f| {:.4} pu; {} handovers, {:.3} s limited; over the last 0.5 s limited {}, |p - p_end| <= {:.1e} pu, |q - q_ref| <= {:.1e} pu",
        e.name,
        out.i_peak,
        out.handovers,
        out.limited as f64 * H,
        out.limited_at_end,
        out.p_swing,
        out.q_err
    );
    out
}

/// Both options through each event on SCR 10 without an error, the converter current within
/// I_max to 5 % (option B's largest: 1.2533 pu in the fault, 1.2507 pu in the deep dip, the
/// two samples of delay at its handover; option A's 1.2379 pu in the fault). Option B is back on
/// its state feedback after one handover at most, and over the last 0.5 s tracking and settled:
/// `|q - q_ref|` below 5e-3 pu, the frame's swing `|p - p_end|` below 0.02 pu (measured at most
/// 2.2e-3 and 1.5e-2 pu, after the short ramp; option A's q PI and frame are slower: 0.13 to 0.31
/// pu of swing left at 2 s, printed, not asserted). The 25° jump does not reach option B's limit
/// on this grid (1.165 pu). After the long ramp the source stays 1 Hz low, where
/// the droop asks more than the rating: both options stay at their current limit.
#[test]
fn both_options_ride_through_the_bench_events_within_the_current_limit() {
    let i_max = InnerDesign::default().i_max;
    for e in &EVENTS {
        let held_beyond_rating = e.name == LONG_RAMP;
        for kind in [InnerKind::OptionA, InnerKind::OptionB] {
            let r = run(kind, e);
            assert!(
                r.i_peak <= i_max * (1.0 + I_TOLERANCE),
                "{} ({kind:?}): {}",
                e.name,
                r.i_peak
            );
            assert_eq!(
                r.limited_at_end, held_beyond_rating,
                "{} ({kind:?}): limited at the end",
                e.name
            );
            if kind == InnerKind::OptionB && !held_beyond_rating {
                assert!(r.handovers <= 1, "{}: {}", e.name, r.handovers);
                assert!(r.q_err < 5e-3, "{}: |q - q_ref| {}", e.name, r.q_err);
                assert!(r.p_swing < 0.02, "{}: |p - p_end| {}", e.name, r.p_swing);
            }
        }
    }
}
