//! Case study III end to end in our master: the spatially distributed DVPP in the MV grid of
//! `ieee9_mv` (two POCs, every MV line at R/X = 1), for a 20 MW load step outside the area
//! (bus 4, `case3_ext_*`) and inside it (d5, `case3_int_*`), with the classical p-f control
//! (`*_pf`, rot.rx = 0) and the rotational p'-f control (`*_rot`, rot.rx = 1). At each POC the
//! frequency deviation is compared with the operator's reference `ref.df = -T_pf Σ_k Δp'_poc,k`
//! (NRMSE); the units' summed Δp against the POCs' shows what the MV lines lose.
//!
//! A load step inside the area lowers the POCs' export by the load itself; the grid reports what
//! the area's loads draw (`area.p_load`, `area.q_load`) and the operator adds its change back,
//! so its reference is that of the units' own contribution for either disturbance.

use dvpp_cosim::master::{self, Options};
use dvpp_cosim::Table;
use dvpp_e2e::scenario;
use dvpp_report::casestudy::{nrmse, S_BASE_MVA};

const POCS: usize = 2;
const UNITS: usize = 3;

fn column(t: &Table, name: &str) -> Vec<f64> {
    t.column(name).unwrap_or_else(|| panic!("no column {name}"))
}

/// What one run measures.
struct Measured {
    /// NRMSE of `poc[k].f - 1` against `ref.df`, per POC.
    nrmse: [f64; POCS],
    /// At the end of the run, MW: Σ Δp of the units, Σ Δp of the POCs, Σ Δp' of the POCs
    /// (the operator's `poc.dp`, back on S_base).
    units_dp: f64,
    poc_dp: f64,
    poc_dp_rot: f64,
    /// Peak |Σ Δp| of the units, MW.
    units_peak: f64,
    /// Lowest POC 1 frequency deviation and its reference, mHz.
    nadir_mhz: f64,
    ref_nadir_mhz: f64,
}

/// The DVPP rating of the scenarios, MVA.
const S_DVPP: f64 = 96.0;

/// `name` run in our master.
fn run(name: &str) -> Measured {
    let t = master::System::builder(&scenario(name))
        .simulate(&Options::default())
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    let r = column(&t, "operator.ref.df");
    let last = r.len() - 1;
    let delta = |c: &str| {
        let x = column(&t, c);
        x.iter().map(|v| v - x[0]).collect::<Vec<f64>>()
    };
    let sum = |cols: Vec<Vec<f64>>| -> Vec<f64> {
        (0..=last)
            .map(|i| cols.iter().map(|c| c[i]).sum())
            .collect()
    };
    let mut nrmse_k = [0.0; POCS];
    for (k, e) in nrmse_k.iter_mut().enumerate() {
        let df: Vec<f64> = column(&t, &format!("grid.poc[{}].f", k + 1))
            .iter()
            .map(|f| f - 1.0)
            .collect();
        *e = nrmse(&df, &r);
    }
    let units = sum((1..=UNITS)
        .map(|k| delta(&format!("grid.der[{k}].p")))
        .collect());
    let pocs = sum((1..=POCS)
        .map(|k| delta(&format!("grid.poc[{k}].p")))
        .collect());
    let f1 = column(&t, "grid.poc[1].f");
    let m = Measured {
        nrmse: nrmse_k,
        units_dp: units[last] * S_BASE_MVA,
        poc_dp: pocs[last] * S_BASE_MVA,
        poc_dp_rot: column(&t, "operator.poc.dp")[last] * S_DVPP,
        units_peak: units.iter().fold(0.0_f64, |m, v| m.max(v.abs())) * S_BASE_MVA,
        nadir_mhz: f1.iter().fold(0.0_f64, |m, v| m.min(v - 1.0)) * 50e3,
        ref_nadir_mhz: r.iter().fold(0.0_f64, |m, v| m.min(*v)) * 50e3,
    };
    println!(
        "{name}: NRMSE POC 1 {:.2} %, POC 2 {:.2} %; nadir POC 1 {:.1} mHz (ref {:.1}); \
         at 20 s: Σ Δp units {:.2} MW, Σ Δp POCs {:.2} MW, Σ Δp' POCs {:.2} MW; \
         peak |Σ Δp units| {:.2} MW",
        m.nrmse[0] * 100.0,
        m.nrmse[1] * 100.0,
        m.nadir_mhz,
        m.ref_nadir_mhz,
        m.units_dp,
        m.poc_dp,
        m.poc_dp_rot,
        m.units_peak
    );
    m
}

#[test]
fn rotational_control_matches_t_des_at_every_poc_and_beats_the_classical_one() {
    let ext_pf = run("case3_ext_pf");
    let ext_rot = run("case3_ext_rot");
    let int_pf = run("case3_int_pf");
    let int_rot = run("case3_int_rot");
    for (name, m, bound) in [
        // The paper's 5 % for both disturbances; measured 1.59 %, 1.71 % (external) and
        // 3.33 %, 3.19 % (internal) (docs/case-studies.md: "Case study III").
        ("case3_ext_rot", &ext_rot, 0.05),
        ("case3_int_rot", &int_rot, 0.05),
    ] {
        for (k, e) in m.nrmse.iter().enumerate() {
            assert!(
                *e <= bound,
                "{name}: POC {} frequency NRMSE {:.2} % > {:.0} %",
                k + 1,
                e * 100.0,
                bound * 100.0
            );
        }
    }
    // The classical p-f control, blind to the lossy lines, matches worse at every POC
    // (measured: external 7.62 %, 7.56 %; internal 11.26 %, 11.26 %).
    for (name, pf, rot) in [
        ("external", &ext_pf, &ext_rot),
        ("internal", &int_pf, &int_rot),
    ] {
        for k in 0..POCS {
            assert!(
                pf.nrmse[k] >= rot.nrmse[k] + 0.02,
                "{name}: POC {}: p-f {:.2} % is not worse than rotational {:.2} %",
                k + 1,
                pf.nrmse[k] * 100.0,
                rot.nrmse[k] * 100.0
            );
        }
    }
    // The MV lines lose part of what the units add for the external step: the POCs deliver
    // less than the units inject (measured: p-f 3.53 vs 3.05 MW, rotational 4.85 vs 4.23 MW).
    for (name, m) in [("case3_ext_pf", &ext_pf), ("case3_ext_rot", &ext_rot)] {
        let loss = m.units_dp - m.poc_dp;
        assert!(
            m.units_dp > 0.0 && loss > 0.05 * m.units_dp && loss < 0.3 * m.units_dp,
            "{name}: units {:.2} MW, POCs {:.2} MW",
            m.units_dp,
            m.poc_dp
        );
    }
}
