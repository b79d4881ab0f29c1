//! End-to-end tests of fleets and several DVPPs with operators of their own, in our master.
//!
//! `scale_fleet200` (one DVPP of 200
//! grid-forming static-ADPF units over four buses) and `scale_two_dvpps` (case study I's DVPP
//! and a 24-unit fleet, each with its own operator) complete; every operator keeps Σμ_p = Σμ_q = 1
//! over its own units at every output row, every unit's μ_p respects its own floor
//! `min(0.05, 0.25 S_i/S_dvpp)`, each DVPP's PCC frequency follows its operator's `ref.df`, and
//! the grid's power balance closes.

use dvpp_cosim::master::{self, End, Error, Observer, Options, RunInfo};
use dvpp_cosim::Table;
use dvpp_e2e::{cosim, scenario};
use dvpp_report::casestudy::{nrmse, peak};
use std::process::Command;
use std::time::Instant;

/// Keeps the columns of the operators and the grid's PCCs and balance (the DERs' own outputs,
/// most of a 200-unit system's columns, are dropped as the run goes).
#[derive(Default)]
struct Keep {
    index: Vec<usize>,
    table: Table,
}

impl Observer for Keep {
    fn start(&mut self, run: &RunInfo) -> Result<(), Error> {
        let wanted = |c: &str| {
            c == "time"
                || c.starts_with("operator")
                || c.starts_with("grid.pcc")
                || c == "grid.sys.p_mismatch"
                || c == "grid.sys.p_gen"
        };
        self.index = (0..run.columns.len())
            .filter(|&i| wanted(&run.columns[i]))
            .collect();
        self.table.columns = self.index.iter().map(|&i| run.columns[i].clone()).collect();
        Ok(())
    }

    fn sample(&mut self, row: &[f64]) -> Result<(), Error> {
        self.table
            .rows
            .push(self.index.iter().map(|&i| row[i]).collect());
        Ok(())
    }

    fn finish(&mut self, _: &End) -> Result<(), Error> {
        Ok(())
    }
}

fn column(t: &Table, name: &str) -> Vec<f64> {
    t.column(name).unwrap_or_else(|| panic!("no column {name}"))
}

/// Run `name` in our master (in process, the `cosim` binary's code), keeping [`Keep`]'s columns.
fn run(name: &str) -> Table {
    let mut keep = Keep::default();
    let started = Instant::now();
    let outcome = master::System::builder(&scenario(name))
        .run(&Options::default(), &mut [&mut keep])
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    println!(
        "{name}: {} rows in {:.1} s",
        keep.table.rows.len(),
        started.elapsed().as_secs_f64()
    );
    assert_eq!(outcome.end, End::Completed, "{name}");
    keep.table
}

/// A DVPP as the test checks it: its operator, PCC output prefix, S_dvpp (MVA), and its units'
/// ratings (MVA) with whether each has an active dc gain (a low-pass or static ADPF).
struct Dvpp<'a> {
    operator: &'a str,
    pcc: &'a str,
    s_dvpp: f64,
    units: Vec<(f64, bool)>,
}

/// The largest NRMSE of the PCC frequency against `ref.df` each DVPP is held to (measured:
/// printed by the test, at most 8.13 % on the paper's grid; see docs/usage.md "Scaling up and
/// out").
const F_NRMSE_MAX: f64 = 0.10;

fn check(name: &str, t: &Table, dvpps: &[Dvpp]) {
    let time = column(t, "time");
    let rows = time.len();
    for d in dvpps {
        let o = d.operator;
        let n = d.units.len();
        // Every unit's gains, in the operator's order.
        let mu_q: Vec<Vec<f64>> = (1..=n)
            .map(|k| column(t, &format!("{o}.der[{k}].mu_q")))
            .collect();
        let mu_p: Vec<(f64, Vec<f64>)> = d
            .units
            .iter()
            .enumerate()
            .filter(|(_, u)| u.1)
            .map(|(k, u)| (u.0, column(t, &format!("{o}.der[{}].mu_p", k + 1))))
            .collect();
        let (mut worst_p, mut worst_q, mut closest) = (0.0_f64, 0.0_f64, f64::INFINITY);
        for r in 0..rows {
            let sp: f64 = mu_p.iter().map(|(_, m)| m[r]).sum();
            let sq: f64 = mu_q.iter().map(|m| m[r]).sum();
            worst_p = worst_p.max((sp - 1.0).abs());
            worst_q = worst_q.max((sq - 1.0).abs());
            for (k, (s_i, m)) in mu_p.iter().enumerate() {
                // The documented floor of a grid-forming low-pass unit (all units here are).
                let floor = 0.05_f64.min(0.25 * s_i / d.s_dvpp);
                assert!(
                    m[r] >= floor - 1e-12,
                    "{name} {o}: unit {} at t = {}: μ_p = {} below its floor {floor}",
                    k + 1,
                    time[r],
                    m[r]
                );
                closest = closest.min(m[r] / floor);
            }
        }
        assert!(worst_p <= 1e-9, "{name} {o}: |Σμ_p - 1| = {worst_p:e}");
        assert!(worst_q <= 1e-9, "{name} {o}: |Σμ_q - 1| = {worst_q:e}");
        // The PCC frequency against the operator's desired response.
        let df: Vec<f64> = column(t, &format!("grid.{}.f", d.pcc))
            .iter()
            .map(|f| f - 1.0)
            .collect();
        let df_ref = column(t, &format!("{o}.ref.df"));
        let e = nrmse(&df, &df_ref);
        // The DVPP took part: its PCC power moved by the load step.
        let p = column(t, &format!("grid.{}.p", d.pcc));
        let dp = p[rows - 1] - p[0];
        println!(
            "{name} {o}: {n} units, |Σμ_p - 1| ≤ {worst_p:.1e}, |Σμ_q - 1| ≤ {worst_q:.1e}, \
             lowest μ_p/floor {closest:.2}, NRMSE f {:.2} % (peak ref.df {:.2e} pu), Δp_pcc {:.1} MW",
            e * 100.0,
            peak(&df_ref),
            dp * 100.0
        );
        assert!(e <= F_NRMSE_MAX, "{name} {o}: NRMSE f {:.2} %", e * 100.0);
        assert!(peak(&df_ref) > 1e-4, "{name} {o}: no desired response");
        assert!(
            dp > 0.01,
            "{name} {o}: Δp_pcc = {dp} pu: the DVPP did not respond"
        );
    }
    // Power balance: generation - load - losses closes at every row.
    let mismatch = peak(&column(t, "grid.sys.p_mismatch"));
    println!("{name}: largest power mismatch {mismatch:.1e} pu");
    assert!(mismatch <= 1e-6, "{name}: power mismatch {mismatch:e} pu");
}

#[test]
fn a_fleet_of_200_units_keeps_its_gains_and_matches_t_des() {
    let t = run("scale_fleet200");
    // 200 equal units of 179/200 MVA in a 96 MVA DVPP: floor 0.25 · 0.895/96 = 0.0023, where
    // 200 units at the fixed 0.05 would need 10 > 1.
    let units = vec![(179.0 / 200.0, true); 200];
    check(
        "scale_fleet200",
        &t,
        &[Dvpp {
            operator: "operator",
            pcc: "pcc",
            s_dvpp: 96.0,
            units,
        }],
    );
}

#[test]
fn two_dvpps_each_keep_their_gains_and_match_their_own_t_des() {
    let t = run("scale_two_dvpps");
    check(
        "scale_two_dvpps",
        &t,
        &[
            Dvpp {
                operator: "operator_ci",
                pcc: "pcc_ci",
                s_dvpp: 96.0,
                // Case study I's fleet: wind, PV low-pass; the BESS complement has no μ_p of
                // its own.
                units: dvpp_control::Fleet::case_study_i()
                    .units
                    .iter()
                    .map(|u| {
                        (
                            u.kind.s_rated,
                            u.kind.shape == dvpp_control::fleet::Shape::LowPass,
                        )
                    })
                    .collect(),
            },
            Dvpp {
                operator: "operator_fleet",
                pcc: "pcc_fleet",
                s_dvpp: 60.0,
                units: vec![(2.5, true); 24],
            },
        ],
    );
}

#[test]
fn the_cosim_binary_runs_both_systems() {
    for name in ["scale_two_dvpps", "scale_fleet200"] {
        let started = Instant::now();
        let out = Command::new(cosim())
            .arg(scenario(name))
            .args(["--stop", "1.5", "--no-csv"])
            .output()
            .expect("start cosim");
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        println!(
            "cosim {name} --stop 1.5: {:.1} s",
            started.elapsed().as_secs_f64()
        );
    }
}
