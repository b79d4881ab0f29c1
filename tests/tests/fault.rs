//! The same balanced fault at both levels: `phasor_thevenin_fault` (the grid's `fault.*` shunt at
//! the PCC, the phasor units' current limit) against `emt_thevenin_fault` (the EMT plant's
//! three-phase fault through the same R + jX, the EMT units' option A limit): the retained
//! voltage, each unit's current during the fault and its active/reactive split, and the
//! recovery after clearing.
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
const S_BASE: f64 = 100.0;
/// The fault (both scenarios): applied at 1 s, cleared at 1.15 s.
const T_FAULT: f64 = 1.0;
const T_CLEAR: f64 = 1.15;
/// The window the fault's currents are averaged over: from one cycle after the fault (the EMT
/// run's dc offsets and the inner loops' first response) to its clearing.
const WINDOW: (f64, f64) = (T_FAULT + 0.02, T_CLEAR);

/// The tolerances, phasor against EMT: the retained PCC voltage (pu), each unit's current
/// magnitude, active and reactive current over the window (pu of its rating), and the time the
/// PCC voltage and the DVPP's active power take to recover after clearing (s).
const TOL_V: f64 = 0.05;
const TOL_I: f64 = 0.15;
const TOL_SPLIT: f64 = 0.35;
const TOL_RECOVERY: f64 = 0.5;

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
    /// value, and until the DVPP's active power stays within 0.02 pu (on S_base) of its own.
    v_recovery: f64,
    p_recovery: f64,
    /// The DVPP's largest active-power deviation from its pre-fault value after clearing (on
    /// S_base).
    p_swing: f64,
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
        let after: Vec<usize> = (0..self.time.len())
            .filter(|&r| self.time[r] >= T_CLEAR + 0.02)
            .collect();
        Measured {
            v_fault: self.mean(WINDOW, |r| self.v[r]),
            v_pre,
            i,
            ip,
            iq,
            v_recovery: self.recovery(&self.v, v_pre, 0.02),
            p_recovery: self.recovery(&p_sum, p_pre, 0.02),
            p_swing: after
                .iter()
                .map(|&r| p_sum[r] - p_pre)
                .fold(0.0, |a: f64, d| if d.abs() > a.abs() { d } else { a }),
        }
    }
}

#[test]
fn the_same_fault_at_phasor_and_emt_level() {
    let phasor = Level::phasor(&run("phasor_thevenin_fault")).measure();
    let emt = Level::emt(&run("emt_thevenin_fault")).measure();
    println!("                    phasor     EMT   |diff|  tolerance");
    let mut worst: Vec<(String, f64, f64)> = Vec::new();
    let mut row = |what: String, a: f64, b: f64, tol: f64| {
        println!("{what:<18} {a:8.4} {b:8.4} {:8.4} {tol:8.3}", (a - b).abs());
        worst.push((what, (a - b).abs(), tol));
    };
    row("PCC v before".into(), phasor.v_pre, emt.v_pre, TOL_V);
    row("PCC v in fault".into(), phasor.v_fault, emt.v_fault, TOL_V);
    for (k, name) in ["wind", "PV", "BESS"].iter().enumerate() {
        row(format!("{name} |i|"), phasor.i[k], emt.i[k], TOL_I);
        row(format!("{name} i_p"), phasor.ip[k], emt.ip[k], TOL_SPLIT);
        row(format!("{name} i_q"), phasor.iq[k], emt.iq[k], TOL_SPLIT);
    }
    row(
        "v recovery (s)".into(),
        phasor.v_recovery,
        emt.v_recovery,
        TOL_RECOVERY,
    );
    row(
        "p recovery (s)".into(),
        phasor.p_recovery,
        emt.p_recovery,
        TOL_RECOVERY,
    );
    println!(
        "DVPP p swing after clearing: {:.4} (phasor), {:.4} (EMT) pu on S_base",
        phasor.p_swing, emt.p_swing
    );
    println!("phasor {phasor:?}\nEMT    {emt:?}");
    // Both levels see the fault: about half the voltage retained, every unit at its limit.
    for m in [&phasor, &emt] {
        assert!(m.v_fault > 0.3 && m.v_fault < 0.7, "{m:?}");
    }
    let over: Vec<_> = worst.iter().filter(|(_, d, tol)| d > tol).collect();
    assert!(over.is_empty(), "beyond tolerance: {over:?}");
}
