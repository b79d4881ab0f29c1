//! Converter limits end to end in our master: severe events (a 150 MW load step, a trip of SG1,
//! a trip of SG1 and SG3) keep every unit within its current limit and its dc link within its
//! range, each unit's energy account closes, and a run with no operating point left (on the
//! paper's machines both trips: SG1 carries 60 % of the generation) stops with a one-line cause
//! and its trajectory kept; an experiment that cannot run is refused as such.

use der_model::ports;
use dvpp_cosim::master::{self, Options, Recorder};
use dvpp_cosim::Table;
use dvpp_e2e::{der_units, scenario, units_with};

const UNITS: [&str; 3] = ["wind", "pv", "bess"];

fn column(t: &Table, name: &str) -> Vec<f64> {
    t.column(name).unwrap_or_else(|| panic!("no column {name}"))
}

/// The run's rows (all of them, or those up to a failure) and its outcome.
fn run(name: &str) -> (Table, Result<master::Outcome, master::Error>) {
    let mut recorder = Recorder::default();
    let outcome =
        master::System::builder(&scenario(name)).run(&Options::default(), &mut [&mut recorder]);
    (recorder.table, outcome)
}

/// Per unit: the largest current over its limit, the dc-link range, and the energy residual
/// `source - ac - loss - Δstored` relative to the energy moved.
fn check_units(name: &str, t: &Table) {
    let units = der_units(&scenario(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!(units, UNITS, "{name}: the scenario's DER units");
    for port in [
        ports::I_AC,
        ports::I_LIMIT,
        ports::V_DC,
        ports::ENERGY_STORED,
    ] {
        units_with(&t.columns, port, &units).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    for u in UNITS {
        let c = |v: &str| column(t, &format!("{u}.{v}"));
        let (i, limit) = (c(ports::I_AC), c(ports::I_LIMIT));
        let ratio = i.iter().zip(&limit).map(|(i, l)| i / l).fold(0.0, f64::max);
        let v_dc = c(ports::V_DC);
        let (lo, hi) = v_dc
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        let last = |v: &str| *c(v).last().expect("rows");
        let w0 = c(ports::ENERGY_STORED)[0];
        let (src, ac, loss, w) = (
            last(ports::ENERGY_SOURCE),
            last(ports::ENERGY_AC),
            last(ports::ENERGY_LOSS),
            last(ports::ENERGY_STORED),
        );
        let residual = (src - ac - loss - (w - w0)) / (src.abs() + ac.abs());
        println!(
            "{name} {u}: largest current {:.4} of I_max, v_dc in [{lo:.4}, {hi:.4}], energy residual {residual:.1e} of {:.1} MJ moved",
            ratio,
            src.abs() + ac.abs()
        );
        assert!(ratio <= 1.05, "{name} {u}: current {ratio:.3} x I_max");
        // No power from an empty link (nor into a full one): v_dc within [v_dc_min, v_dc_max]
        // of the defaults (0.8, 1.2) up to one step's overshoot.
        assert!(
            lo >= 0.8 - 0.01 && hi <= 1.2 + 0.01,
            "{name} {u}: v_dc in [{lo}, {hi}]"
        );
        assert!(
            residual.abs() <= 1e-6,
            "{name} {u}: energy residual {residual:e}"
        );
    }
}

/// The limits hold without cycling: after t = 1.5 s no unit's current changes by more than
/// 0.1 pu from one communication step to the next, and the BESS's dc link crosses 0.9 pu at most
/// twice (down once and back up), where the limiter switching each step made the wind and PV
/// currents jump by up to 0.42 pu and the link swing between its floor and nominal.
fn no_chatter(name: &str, t: &Table) {
    let time = column(t, "time");
    for u in UNITS {
        let i = column(t, &format!("{u}.i_ac"));
        let jump = (1..i.len())
            .filter(|&k| time[k - 1] >= 1.5)
            .map(|k| (i[k] - i[k - 1]).abs())
            .fold(0.0, f64::max);
        println!("{name} {u}: largest step-to-step change of i_ac after t = 1.5 s {jump:.4} pu");
        assert!(
            jump <= 0.1,
            "{name} {u}: i_ac jumps by {jump:.3} pu in one step"
        );
    }
    let v_dc = column(t, "bess.v_dc");
    let crossings = v_dc
        .windows(2)
        .filter(|w| (w[0] - 0.9) * (w[1] - 0.9) < 0.0)
        .count();
    println!("{name} bess: v_dc crosses 0.9 pu {crossings} times");
    assert!(
        crossings <= 2,
        "{name} bess: v_dc crosses 0.9 pu {crossings} times"
    );
}

#[test]
fn severe_events_stay_within_the_converter_limits() {
    for name in ["case1_load", "limits_load150"] {
        let (t, outcome) = run(name);
        let outcome = outcome.unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            matches!(outcome.end, master::End::Completed),
            "{name}: {:?}",
            outcome.end
        );
        println!("{name}: {} warning lines", outcome.warnings.len());
        assert!(
            outcome.warnings.len() <= 30,
            "{name}: {} warnings (a flood): {:#?}",
            outcome.warnings.len(),
            outcome.warnings
        );
        check_units(name, &t);
        // The DVPP stays in synchronism with the machines: at the end the PCC frequency is the
        // centre-of-inertia frequency (the measurement also holds beyond 0.1 pu off nominal).
        let (f_pcc, f_coi) = (column(&t, "grid.pcc.f"), column(&t, "grid.coi.f"));
        let gap = (f_pcc.last().unwrap() - f_coi.last().unwrap()).abs();
        println!(
            "{name}: f_pcc {:.4} pu, f_coi {:.4} pu at the end",
            f_pcc.last().unwrap(),
            f_coi.last().unwrap()
        );
        assert!(
            gap < 1e-3,
            "{name}: PCC and COI frequencies differ by {gap}"
        );
        if name == "limits_load150" {
            no_chatter(name, &t);
        }
        if name != "case1_load" {
            let acted = UNITS.iter().any(|u| {
                column(&t, &format!("{u}.limit.current"))
                    .iter()
                    .any(|&x| x != 0.0)
            });
            assert!(acted, "{name}: no unit reached its current limit");
        }
    }
}

#[test]
fn a_grid_with_no_operating_point_left_stops_with_its_cause_and_keeps_the_trajectory() {
    for name in ["limits_sg1_trip", "limits_sg13_trip"] {
        let (t, outcome) = run(name);
        let outcome = outcome.unwrap_or_else(|e| panic!("{e}"));
        let master::End::Failed { error: err, .. } = &outcome.end else {
            panic!(
                "{name}: what is left cannot carry the load: {:?}",
                outcome.end
            );
        };
        println!("{name}: {err} ({} warning lines)", outcome.warnings.len());
        assert!(outcome.warnings.len() <= 30, "{:#?}", outcome.warnings);
        assert!(
            err.contains("voltage collapse")
                || err.contains("synchronism")
                || err.contains("frequency collapse"),
            "{err}"
        );
        assert!(!err.trim().contains('\n'), "one line: {err}");
        let time = column(&t, "time");
        let end = *time.last().expect("rows kept");
        assert!(end > 1.0, "{name}: the trajectory stops at t = {end} s");
        check_units(name, &t);
        let acted = UNITS.iter().any(|u| {
            column(&t, &format!("{u}.limit.current"))
                .iter()
                .any(|&x| x != 0.0)
        });
        assert!(acted, "{name}: no unit reached its current limit");
    }
}

/// An experiment that cannot run is refused as an experiment error before the run starts.
#[test]
fn an_experiment_that_cannot_run_is_an_experiment_error() {
    let opts = Options {
        step: Some(-1e-3),
        ..Options::default()
    };
    match master::System::builder(&scenario("case1_load")).run(&opts, &mut []) {
        Err(e @ master::Error::Experiment(_)) => {
            assert!(e.to_string().contains("step size -0.001 s"), "{e}")
        }
        other => panic!("an experiment error expected: {other:?}"),
    }
}
