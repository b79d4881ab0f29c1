//! Case study III end to end in our master, as `cargo xtask case3` runs it: the spatially
//! distributed DVPP in the MV grid of `ieee9_mv` (two POCs, every MV line at R/X = 1), for a
//! 20 MW load step outside the area (bus 4, `case3_ext_*`) and a 20 MW constant-power step
//! inside it (d5, `case3_int_*`), with the classical p-f control (`*_pf`, rot.rx = 0) and the
//! rotational p'-f control (`*_rot`, rot.rx = 1); then the seeded R/X Monte Carlo of the
//! rotational scenarios (24 draws of U(0.4, 2) per MV line, seed 1). At each POC the frequency
//! deviation is compared with the operator's reference `ref.df = -T_pf Σ_k Δp'_poc,k` (NRMSE
//! over the run and over the first 5 s after the step); the units' summed Δp against the POCs'
//! shows what the MV lines lose. Every bound is the measured value with a margin (the measured
//! value beside it, docs/case-studies.md "Case study III" prints them).
//!
//! A load step inside the area lowers the POCs' export by the load itself; the grid reports what
//! the area's loads draw (`area.p_load`, `area.q_load`) and the operator adds its change back,
//! so its reference is that of the units' own contribution for either disturbance.
//!
//! The paper gives no number for the matching ("accurate matching", the Monte Carlo responses
//! "very similar" to R/X = 1): the bounds here are this model's.

use dvpp_studies::case3::{monte_carlo, study, table, Run, DRAWS, SEED};

/// `x` within `rel` (relative) of the measured `m`.
fn near(what: &str, x: f64, m: f64, rel: f64) {
    assert!(
        (x - m).abs() <= rel * m.abs(),
        "{what}: {x:.4}, measured {m:.4} (±{:.0} %)",
        rel * 100.0
    );
}

fn nominal<'a>(runs: &'a [Run], name: &str) -> &'a Run {
    runs.iter()
        .find(|r| r.scenario == name && r.draw == 0)
        .unwrap_or_else(|| panic!("no nominal run of {name}"))
}

#[test]
fn rotational_control_matches_t_des_at_every_poc_beats_the_classical_one_and_holds_under_random_rx()
{
    // Bundled FMUs and scenarios (DVPP_DIST or `cargo xtask bundle`), in the workspace root.
    let dist = dvpp_e2e::dist();
    let root = dist
        .parent()
        .and_then(|d| d.parent())
        .expect("dist/default in the workspace root");
    let runs = study(root, DRAWS, SEED).unwrap_or_else(|e| panic!("{e}"));
    let failed: Vec<&String> = runs.iter().filter_map(|r| r.error.as_ref()).collect();
    assert!(failed.is_empty(), "failed runs: {failed:?}");
    assert_eq!(runs.len(), 4 + 2 * DRAWS);
    for r in runs.iter().filter(|r| r.draw == 0) {
        println!(
            "{}: NRMSE POC 1 / POC 2 {:.2} / {:.2} % over the run, {:.2} / {:.2} % over the first 5 s; Σ Δp units {:+.2} MW, POCs {:+.2} MW",
            r.scenario,
            r.nrmse[0] * 100.0,
            r.nrmse[1] * 100.0,
            r.nrmse_transient[0] * 100.0,
            r.nrmse_transient[1] * 100.0,
            r.dp_units_mw,
            r.dp_pocs_mw
        );
    }
    // Every figure of the table within a margin of the value measured: NRMSE at POC 1 / POC 2
    // over the run and over the first 5 s (10 %), Σ Δp of the units and at the POCs, MW (5 %).
    for (name, m) in [
        ("case3_ext_pf", [0.0328, 0.0337, 0.0463, 0.0489, 3.46, 3.26]),
        (
            "case3_ext_rot",
            [0.0248, 0.0269, 0.0488, 0.0531, 5.51, 5.11],
        ),
        (
            "case3_int_pf",
            [0.2169, 0.2166, 0.2413, 0.2397, 3.43, -15.23],
        ),
        (
            "case3_int_rot",
            [0.0630, 0.0604, 0.1260, 0.1207, 8.69, -10.35],
        ),
    ] {
        let r = nominal(&runs, name);
        let x = [
            r.nrmse[0],
            r.nrmse[1],
            r.nrmse_transient[0],
            r.nrmse_transient[1],
            r.dp_units_mw,
            r.dp_pocs_mw,
        ];
        let what = [
            "NRMSE POC 1",
            "NRMSE POC 2",
            "NRMSE POC 1, first 5 s",
            "NRMSE POC 2, first 5 s",
            "Σ Δp of the units",
            "Σ Δp at the POCs",
        ];
        for (k, ((w, x), m)) in what.iter().zip(x).zip(m).enumerate() {
            near(
                &format!("{name}: {w}"),
                x,
                m,
                if k < 4 { 0.10 } else { 0.05 },
            );
        }
    }
    // The table `cargo xtask case3` wrote into docs/case-studies.md is this study's.
    dvpp_studies::docs::check_between(
        root,
        dvpp_studies::docs::CASE_STUDIES,
        "<!-- case3:begin -->",
        "<!-- case3:end -->",
        &table(&runs),
        "cargo xtask case3",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let (ext_pf, ext_rot, int_pf, int_rot) = (
        nominal(&runs, "case3_ext_pf"),
        nominal(&runs, "case3_ext_rot"),
        nominal(&runs, "case3_int_pf"),
        nominal(&runs, "case3_int_rot"),
    );
    // The rotational control at both POCs, over the run and over the transient.
    for (r, run_bound, transient_bound) in [
        // measured: 2.48 / 2.69 % over the run, 4.88 / 5.31 % over the first 5 s
        (ext_rot, 0.03, 0.06),
        // measured: 6.30 / 6.04 %, 12.60 / 12.07 %
        (int_rot, 0.075, 0.15),
    ] {
        for k in 0..2 {
            assert!(
                r.nrmse[k] <= run_bound && r.nrmse_transient[k] <= transient_bound,
                "{}: POC {} frequency NRMSE {:.2} % (bound {:.1} %), first 5 s {:.2} % (bound {:.1} %)",
                r.scenario,
                k + 1,
                r.nrmse[k] * 100.0,
                run_bound * 100.0,
                r.nrmse_transient[k] * 100.0,
                transient_bound * 100.0
            );
        }
    }
    // The classical p-f control, blind to the lossy lines, matches worse over the run at every
    // POC: for the internal step by at least 10 percentage points (measured 21.69 / 21.66 %
    // against 6.30 / 6.04 %), for the external one by at least 0.4 (measured 3.28 / 3.37 %
    // against 2.48 / 2.69 %; over the first 5 s the classical control is the closer one there,
    // 4.63 / 4.89 % against 4.88 / 5.31 %, and the test does not order them).
    for (pf, rot, margin) in [(ext_pf, ext_rot, 0.004), (int_pf, int_rot, 0.10)] {
        for k in 0..2 {
            assert!(
                pf.nrmse[k] >= rot.nrmse[k] + margin,
                "{}: POC {}: p-f {:.2} % is not {:.1} points worse than rotational {:.2} %",
                pf.scenario,
                k + 1,
                pf.nrmse[k] * 100.0,
                margin * 100.0,
                rot.nrmse[k] * 100.0
            );
        }
    }
    // The MV lines lose part of what the units add for the external step: the POCs deliver
    // 3-15 % less than the units inject (measured: p-f 3.46 vs 3.26 MW, 5.8 %; rotational
    // 5.51 vs 5.11 MW, 7.3 %).
    for m in [ext_pf, ext_rot] {
        let loss = m.dp_units_mw - m.dp_pocs_mw;
        assert!(
            m.dp_units_mw > 0.0 && loss > 0.03 * m.dp_units_mw && loss < 0.15 * m.dp_units_mw,
            "{}: units {:.2} MW, POCs {:.2} MW",
            m.scenario,
            m.dp_units_mw,
            m.dp_pocs_mw
        );
    }
    // The R/X Monte Carlo (seeded: the same draws every time): every draw completes and the
    // worst draw's NRMSE stays within the bound at both POCs.
    for (name, median_bound, worst_bound) in [
        // measured: median 3.24 / 3.36 %, worst 4.98 / 5.11 %
        ("case3_ext_rot", 0.04, 0.06),
        // measured: median 6.78 / 6.56 %, worst 9.67 / 9.53 %
        ("case3_int_rot", 0.08, 0.115),
    ] {
        let m = monte_carlo(&runs, name).unwrap_or_else(|| panic!("{name}: no draw"));
        println!(
            "{name}: {} R/X draws, median {:.2} / {:.2} %, worst {:.2} / {:.2} %",
            m.draws,
            m.median[0] * 100.0,
            m.median[1] * 100.0,
            m.worst[0] * 100.0,
            m.worst[1] * 100.0
        );
        assert_eq!(m.draws, DRAWS, "{name}: every draw completes");
        for k in 0..2 {
            assert!(
                m.median[k] <= median_bound && m.worst[k] <= worst_bound,
                "{name}: POC {}: median {:.2} % (bound {:.1} %), worst {:.2} % (bound {:.1} %)",
                k + 1,
                m.median[k] * 100.0,
                median_bound * 100.0,
                m.worst[k] * 100.0,
                worst_bound * 100.0
            );
        }
    }
}
