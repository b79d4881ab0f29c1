//! Case study I's DVPP at EMT level through the grid codes' events in our master (`cargo xtask ride-through`'s runs): every control rides through every event at every short-circuit ratio but the open cases listed here (docs/emt-unit.md §6), no unit ever stops, each unit's phase currents stay within its current limit, the plant's energy account closes.

use dvpp_studies::ride_through::{jobs, run_all, Control, Row};
use std::path::PathBuf;

/// How far a unit's phase current may pass `I_max` (fraction): the limit acts on the current
/// reference, and the current loop's 800 Hz answer to a sudden voltage change carries the
/// current past it for a few samples (docs/emt-unit.md §6).
const I_TOLERANCE: f64 = 0.05;
/// The plant's ac energy balance over a run, relative to the energy exchanged.
const ENERGY: f64 = 1e-9;
/// The phase current's bound where a unit lost synchronism (it slips poles at its limit).
const I_TOLERANCE_SLIPPING: f64 = 0.12;

/// The runs that do not keep synchronism today (event, SCR), per control: the open cases of
/// docs/emt-unit.md §6. Each must still fail (a run that rides through is taken off the list).
const OPEN_A: [(&str, f64); 7] = [
    ("dip to 0.1 pu, 150 ms", 10.0),
    ("-5 Hz/s for 0.4 s", 10.0),
    ("three-phase fault at the PCC, 150 ms", 3.0),
    ("-5 Hz/s for 0.4 s", 3.0),
    ("three-phase fault at the PCC, 150 ms", 1.5),
    ("+5 Hz/s for 0.4 s", 1.5),
    ("-5 Hz/s for 0.4 s", 1.5),
];
const OPEN_B: [(&str, f64); 22] = [
    ("dip to 0.5 pu, 150 ms", 10.0),
    ("dip to 0.1 pu, 150 ms", 10.0),
    ("three-phase fault at the PCC, 150 ms", 10.0),
    ("phase-a-to-ground fault at the PCC, 150 ms", 10.0),
    ("phase-b-to-c fault at the PCC, 150 ms", 10.0),
    ("phase jump +25°", 10.0),
    ("phase jump -25°", 10.0),
    ("+5 Hz/s for 0.4 s", 10.0),
    ("-5 Hz/s for 0.4 s", 10.0),
    ("dip to 0.1 pu, 150 ms", 3.0),
    ("three-phase fault at the PCC, 150 ms", 3.0),
    ("phase-a-to-ground fault at the PCC, 150 ms", 3.0),
    ("phase-b-to-c fault at the PCC, 150 ms", 3.0),
    ("phase jump -25°", 3.0),
    ("+5 Hz/s for 0.4 s", 3.0),
    ("-5 Hz/s for 0.4 s", 3.0),
    ("dip to 0.1 pu, 150 ms", 1.5),
    ("three-phase fault at the PCC, 150 ms", 1.5),
    ("phase-a-to-ground fault at the PCC, 150 ms", 1.5),
    ("phase-b-to-c fault at the PCC, 150 ms", 1.5),
    ("+5 Hz/s for 0.4 s", 1.5),
    ("-5 Hz/s for 0.4 s", 1.5),
];
const OPEN_FOLLOWING: [(&str, f64); 3] = [
    ("dip to 0.1 pu, 150 ms", 3.0),
    ("dip to 0.1 pu, 150 ms", 1.5),
    ("-5 Hz/s for 0.4 s", 1.5),
];

/// The runs that ride through with a phase current beyond `I_max` by more than `I_TOLERANCE`
/// today (event, SCR, the bound held to, in I_max), per control: grid-following at ±5 Hz/s on
/// SCR 3 (1.151 and 1.052 I_max since its ride-through is entered on the 5 ms voltage,
/// docs/emt.md §9). Each must still pass `I_TOLERANCE`, so that a fix shows up.
const OVER_LIMIT_FOLLOWING: [(&str, f64, f64); 2] = [
    ("-5 Hz/s for 0.4 s", 3.0, 1.16),
    ("+5 Hz/s for 0.4 s", 3.0, 1.06),
];

/// The workspace root the bundled systems are under (`DVPP_DIST` is `ROOT/dist/default`).
fn root() -> PathBuf {
    let dist = dvpp_e2e::dist();
    dist.parent()
        .and_then(|d| d.parent())
        .expect("DVPP_DIST is ROOT/dist/default")
        .to_path_buf()
}

fn rows(control: Control) -> Vec<Row> {
    let mine: Vec<_> = jobs()
        .into_iter()
        .filter(|j| j.control == control)
        .collect();
    let workers = std::thread::available_parallelism().map_or(1, |n| n.get());
    run_all(&root(), mine, workers, None).unwrap_or_else(|e| panic!("{e}"))
}

/// Every run but the `open` ones rode through within the limit, the `open` ones still do not;
/// none stopped, every one closed its energy account. The failures, named.
fn check(rows: &[Row], open: &[(&str, f64)], over_limit: &[(&str, f64, f64)]) {
    let mut failed = Vec::new();
    for r in rows {
        let name = r.job.name();
        let listed = |list: &[(&str, f64)]| {
            list.iter()
                .any(|&(event, scr)| r.job.event.name() == event && r.job.scr == scr)
        };
        let is_open = listed(open);
        let over = over_limit
            .iter()
            .find(|&&(event, scr, _)| r.job.event.name() == event && r.job.scr == scr)
            .map(|o| o.2);
        if over.is_some() && r.i_peak <= 1.0 + I_TOLERANCE {
            failed.push(format!(
                "{name}: phase current {:.3} I_max, within the limit now: take it off the over-limit cases",
                r.i_peak
            ));
        }
        let tolerance = match over {
            Some(bound) => bound - 1.0,
            None if is_open => I_TOLERANCE_SLIPPING,
            None => I_TOLERANCE,
        };
        if let Some(e) = &r.error {
            failed.push(format!("{name}: stopped: {e}"));
        } else if r.i_peak > 1.0 + tolerance {
            failed.push(format!("{name}: phase current {:.3} I_max", r.i_peak));
        } else if r.energy_residual > ENERGY {
            failed.push(format!("{name}: energy residual {:.1e}", r.energy_residual));
        } else if !is_open && !r.rides_through {
            failed.push(format!(
                "{name}: angle against the grid up to {:.2} rad, {:.3} Hz from it over the last 0.5 s",
                r.slip, r.sync_hz
            ));
        } else if is_open && r.rides_through {
            failed.push(format!(
                "{name}: rides through now: take it off the open cases here and in docs/emt-unit.md"
            ));
        }
    }
    assert!(
        failed.is_empty(),
        "{} of {} runs:\n{}",
        failed.len(),
        rows.len(),
        failed.join("\n")
    );
}

#[test]
fn grid_forming_option_a_rides_through_every_event_but_the_open_cases() {
    check(&rows(Control::FormingA), &OPEN_A, &[]);
}

#[test]
fn grid_forming_option_b_rides_through_every_event_but_the_open_cases_and_never_stops() {
    check(&rows(Control::FormingB), &OPEN_B, &[]);
}

#[test]
fn grid_following_rides_through_every_event_but_the_open_cases() {
    check(
        &rows(Control::Following),
        &OPEN_FOLLOWING,
        &OVER_LIMIT_FOLLOWING,
    );
}
