//! The same balanced fault at both levels: `phasor_thevenin_fault` (the grid's `fault.*` shunt at
//! the PCC, the phasor units' current limit) against `emt_thevenin_fault` (the EMT plant's
//! three-phase fault through the same R + jX, the EMT units' option A limit): the retained
//! voltage, each unit's current during the fault and its active/reactive split, and the
//! recovery after clearing.
//!
//! `phasor_thevenin_fault_q` is the phasor run with `limit.priority` = 1 (a grid-forming unit's
//! current beyond `I_max` turned toward reactive current).
//!
//! Re-run (after `cargo xtask bundle`):
//! `DVPP_DIST=$PWD/dist/default cargo test --release -p dvpp-e2e --test fault -- --nocapture`;
//! it prints every measure next to its tolerance (docs/emt.md §13, "the same fault at phasor
//! level").

use dvpp_cosim::master::{self, Options};
use dvpp_cosim::Table;
use dvpp_e2e::scenario;

/// Case study I's units (wind, PV, BESS): their ratings, MVA, on the 100 MVA system base.
const RATINGS: [f64; 3] = [46.0, 73.0, 60.0];
const UNITS: [&str; 3] = ["wind", "pv", "bess"];
const S_BASE: f64 = 100.0;
/// The fault (both scenarios): applied at 1 s, cleared at 1.15 s.
const T_FAULT: f64 = 1.0;
const T_CLEAR: f64 = 1.15;
/// The window the fault's currents are averaged over: from one cycle after the fault (the EMT
/// run's dc offsets and the inner loops' first response) to its clearing.
const WINDOW: (f64, f64) = (T_FAULT + 0.02, T_CLEAR);

/// The tolerances, phasor against EMT, of what the two levels agree on: the PCC voltage before
/// the fault and retained in it (pu), each unit's current magnitude over the window (pu of its
/// rating) and the time the PCC voltage takes to recover after clearing (s). Measured on
/// 2026-12-06 (main at 3caa6c6 with this branch): 0.0000, 0.066, at most 0.023 and 0.032 s.
/// The active/reactive split, the units' angle excursions and the post-fault power swing are
/// printed, not held: they differ in kind today (docs/emt.md §13, "the same fault at phasor
/// level").
const TOL_V_PRE: f64 = 0.01;
const TOL_V: f64 = 0.1;
const TOL_I: f64 = 0.05;
const TOL_RECOVERY: f64 = 0.1;

fn run(name: &str) -> Table {
    master::System::builder(&scenario(name))
        .simulate(&Options::default())
        .unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn column(t: &Table, name: &str) -> Vec<f64> {
    t.column(name).unwrap_or_else(|| panic!("no column {name}"))
}

/// One level's run: time, the PCC voltage, each unit's p and q into the PCC (on S_base).
struct Level {
    time: Vec<f64>,
    v: Vec<f64>,
    p: Vec<Vec<f64>>,
    q: Vec<Vec<f64>>,
    /// Each unit's internal angle (its `theta` output, unwrapped).
    theta: Vec<Vec<f64>>,
}

/// What the comparison measures on one level.
#[derive(Debug)]
struct Measured {
    /// Mean PCC voltage over the window, and before the fault.
    v_fault: f64,
    v_pre: f64,
    /// Per unit, mean over the window: current magnitude, active and reactive current (pu of
    /// its rating, at the PCC: |p + jq|/v, p/v, q/v).
    i: [f64; 3],
    ip: [f64; 3],
    iq: [f64; 3],
    /// After clearing: the time until the PCC voltage stays within 0.02 pu of its pre-fault
    /// value.
    v_recovery: f64,
    /// Per unit, the largest move of its internal angle from its value at the fault, rad,
    /// during the fault (2π: a pole slip).
    excursion: [f64; 3],
    /// The DVPP's largest active-power deviation from its pre-fault value (on S_base) in the
    /// first 0.5 s after clearing and over the last second (the post-fault swing's decay).
    p_swing: f64,
    p_swing_late: f64,
}

impl Level {
    fn phasor(t: &Table) -> Level {
        Level {
            time: column(t, "time"),
            v: column(t, "grid.pcc.v"),
            p: (1..=3)
                .map(|k| column(t, &format!("grid.der[{k}].p")))
                .collect(),
            q: (1..=3)
                .map(|k| column(t, &format!("grid.der[{k}].q")))
                .collect(),
            theta: UNITS
                .iter()
                .map(|u| column(t, &format!("{u}.theta")))
                .collect(),
        }
    }

    fn emt(t: &Table) -> Level {
        Level {
            time: column(t, "time"),
            v: column(t, "plant.pcc.v"),
            p: (1..=3)
                .map(|k| column(t, &format!("plant.der[{k}].p")))
                .collect(),
            q: (1..=3)
                .map(|k| column(t, &format!("plant.der[{k}].q")))
                .collect(),
            theta: UNITS
                .iter()
                .map(|u| column(t, &format!("{u}.theta")))
                .collect(),
        }
    }

    /// The mean of `f(row)` over the rows with time in `[a, b)`.
    fn mean(&self, (a, b): (f64, f64), f: impl Fn(usize) -> f64) -> f64 {
        let rows: Vec<usize> = (0..self.time.len())
            .filter(|&r| self.time[r] >= a - 1e-9 && self.time[r] < b - 1e-9)
            .collect();
        rows.iter().map(|&r| f(r)).sum::<f64>() / rows.len() as f64
    }

    /// The time after clearing from which `x` stays within `tol` of `x0` to the end.
    fn recovery(&self, x: &[f64], x0: f64, tol: f64) -> f64 {
        let last_out = (0..self.time.len())
            .rev()
            .find(|&r| self.time[r] >= T_CLEAR && (x[r] - x0).abs() > tol);
        last_out.map_or(0.0, |r| self.time[r] - T_CLEAR)
    }

    fn measure(&self) -> Measured {
        let pre = (T_FAULT - 0.1, T_FAULT);
        let per_unit = |f: &dyn Fn(usize, usize) -> f64| -> [f64; 3] {
            std::array::from_fn(|k| self.mean(WINDOW, |r| f(k, r)) * S_BASE / RATINGS[k])
        };
        let i = per_unit(&|k, r| dvpp_math::hypot(self.p[k][r], self.q[k][r]) / self.v[r]);
        let ip = per_unit(&|k, r| self.p[k][r] / self.v[r]);
        let iq = per_unit(&|k, r| self.q[k][r] / self.v[r]);
        let p_sum: Vec<f64> = (0..self.time.len())
            .map(|r| self.p.iter().map(|p| p[r]).sum())
            .collect();
        let v_pre = self.mean(pre, |r| self.v[r]);
        let p_pre = self.mean(pre, |r| p_sum[r]);
        let swing = |a: f64, b: f64| {
            (0..self.time.len())
                .filter(|&r| self.time[r] >= a && self.time[r] <= b)
                .map(|r| p_sum[r] - p_pre)
                .fold(0.0, |m: f64, d| if d.abs() > m.abs() { d } else { m })
        };
        let at_fault = self
            .time
            .iter()
            .position(|&t| t >= T_FAULT - 1e-9)
            .expect("the run reaches the fault");
        let excursion = std::array::from_fn(|k| {
            let th = &self.theta[k];
            (at_fault..self.time.len())
                .take_while(|&r| self.time[r] <= T_CLEAR + 1e-9)
                .map(|r| (th[r] - th[at_fault]).abs())
                .fold(0.0, f64::max)
        });
        let end = *self.time.last().expect("rows");
        Measured {
            v_fault: self.mean(WINDOW, |r| self.v[r]),
            v_pre,
            i,
            ip,
            iq,
            v_recovery: self.recovery(&self.v, v_pre, 0.02),
            excursion,
            p_swing: swing(T_CLEAR, T_CLEAR + 0.5),
            p_swing_late: swing(end - 1.0, end),
        }
    }
}

/// The phasor scenario held to the tolerances against the EMT one: the units' limit keeping the
/// request's direction, as the EMT unit's option A reference does today. When the EMT unit's
/// limited reference turns to reactive current, `phasor_thevenin_fault_q` (`limit.priority` = 1)
/// is its twin; both are measured and printed.
const TWIN: &str = "phasor_thevenin_fault";

#[test]
fn the_same_fault_at_phasor_and_emt_level() {
    let phasor = Level::phasor(&run("phasor_thevenin_fault")).measure();
    let phasor_q = Level::phasor(&run("phasor_thevenin_fault_q")).measure();
    let emt = Level::emt(&run("emt_thevenin_fault")).measure();
    let twin = if TWIN == "phasor_thevenin_fault" {
        &phasor
    } else {
        &phasor_q
    };
    println!("                    phasor phasor(q)      EMT  |ph-EMT| |q-EMT|  tolerance ({TWIN})");
    let mut worst: Vec<(String, f64, f64)> = Vec::new();
    // `tol` None: printed, not held.
    let mut row = |what: String, f: &dyn Fn(&Measured) -> f64, tol: Option<f64>| {
        let (a, b, c) = (f(&phasor), f(&phasor_q), f(&emt));
        let shown = tol.map_or("(shown)".to_string(), |t| format!("{t:8.3}"));
        println!(
            "{what:<18} {a:8.4} {b:8.4} {c:8.4} {:8.4} {:8.4} {shown}",
            (a - c).abs(),
            (b - c).abs()
        );
        if let Some(tol) = tol {
            worst.push((what, (f(twin) - c).abs(), tol));
        }
    };
    row("PCC v before".into(), &|m| m.v_pre, Some(TOL_V_PRE));
    row("PCC v in fault".into(), &|m| m.v_fault, Some(TOL_V));
    for (k, name) in UNITS.iter().enumerate() {
        row(format!("{name} |i|"), &|m| m.i[k], Some(TOL_I));
        row(format!("{name} i_p"), &|m| m.ip[k], None);
        row(format!("{name} i_q"), &|m| m.iq[k], None);
        row(format!("{name} angle (rad)"), &|m| m.excursion[k], None);
    }
    row(
        "v recovery (s)".into(),
        &|m| m.v_recovery,
        Some(TOL_RECOVERY),
    );
    row("p swing, 0.5 s".into(), &|m| m.p_swing, None);
    row("p swing, last 1 s".into(), &|m| m.p_swing_late, None);
    // Both levels see the fault (about half the voltage retained) at the current limit.
    for m in [&phasor, &phasor_q, &emt] {
        assert!(m.v_fault > 0.3 && m.v_fault < 0.7, "{m:?}");
        assert!(m.i.iter().all(|&i| i > 1.1 && i < 1.3), "{m:?}");
    }
    let over: Vec<_> = worst.iter().filter(|(_, d, tol)| d > tol).collect();
    assert!(over.is_empty(), "beyond tolerance: {over:?}");
}
