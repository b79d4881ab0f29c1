//! `cargo xtask demo`: case study I (`case1_load`, `case1_cloud`) in our master, with CSVs and
//! figures in `results/`, figures in `tests/figures/` and the metrics table in
//! `docs/case-studies.md`; then case study III (as `case3`).

use std::path::Path;

/// The case study I runs of the demo and their labels.
pub const DEMO_RUNS: [(&str, &str); 2] = [("case1_load", "load step"), ("case1_cloud", "cloud")];

/// Time of case study I's event (the load step, the cloud), s.
pub const T_EVENT: f64 = 1.0;
/// The transient windows after the event the table reports beside the whole run, s.
pub const WINDOWS: [f64; 2] = [5.0, 1.0];

/// Case study I's tables (matching over the run and the transient, coherency of the units with
/// the PCC through its meter of time constant `t_f`, the cloud against the load step) for the
/// runs `(name, signals)`, the load step first, as Markdown.
pub fn case1_table(runs: &[(&str, &dvpp_report::casestudy::Signals)], t_f: f64) -> String {
    use dvpp_report::casestudy;
    let pct = |x: f64| format!("{:.2} %", x * 100.0);
    let mut table = format!(
        "| scenario | NRMSE Δf_pcc vs ref.df: run / first {} s / first {} s | NRMSE Δv_pcc vs ref.dv: run / first {} s / first {} s | nadir (desired) | max abs(v_dc − 1) |\n|---|---|---|---|---|\n",
        WINDOWS[0], WINDOWS[1], WINDOWS[0], WINDOWS[1]
    );
    let mut coherency = String::from(
        "| scenario | unit | NRMSE of Δf_i vs Δf_pcc: through the PCC's meter / as imposed | largest abs(Δf_i − Δf_pcc): through the meter / as imposed |\n|---|---|---|---|\n",
    );
    for (name, s) in runs {
        let m = s.metrics();
        let [a, b] = WINDOWS.map(|w| s.transient(T_EVENT, w));
        // Both against the operator's ref.df, which takes Δp_pcc against the DVPP's summed set
        // point: the cloud's lowered PV set point is its disturbance.
        let dc: Vec<String> = m
            .v_dc
            .iter()
            .map(|(d, x)| format!("{d} {:.2} %", x * 100.0))
            .collect();
        table.push_str(&format!(
            "| `{name}` | {} / {} / {} | {} / {} / {} | {:.4} Hz ({:.4} Hz) | {} |\n",
            pct(m.f_nrmse),
            pct(a.f_nrmse),
            pct(b.f_nrmse),
            pct(m.v_nrmse),
            pct(a.v_nrmse),
            pct(b.v_nrmse),
            m.f_nadir_hz,
            m.f_ref_nadir_hz,
            dc.join(", ")
        ));
        for c in s.coherency(t_f) {
            coherency.push_str(&format!(
                "| `{name}` | {} | {} / {} | {:.1} mHz / {:.1} mHz |\n",
                c.name,
                pct(c.metered_nrmse),
                pct(c.nrmse),
                c.metered_max_gap_hz * 1e3,
                c.max_gap_hz * 1e3,
            ));
        }
    }
    table.push_str(&format!(
        "\nNRMSE: the RMS error over the run or over the window after the event at t = 1 s, \
         always relative to the desired response's peak over the whole run.\n\n\
         Coherency: each unit's own frequency `df` against the PCC frequency `pcc.f` (the \
         PCC angle's rate of change through the scenario's meter, `pcc_f_filter_t` = {t_f} s), \
         through the same meter and as the unit imposes it; NRMSE relative to the PCC's peak \
         deviation.\n\n"
    ));
    table.push_str(&coherency);
    if let [(_, load), (_, cloud), ..] = runs {
        let (gap, worst) = casestudy::max_gap_at(&cloud.df, &load.df, 0);
        let settled = load.time.iter().position(|&t| t >= 1.02).unwrap_or(0);
        let gap_after = casestudy::max_gap(&cloud.df, &load.df, settled);
        let worst = load.time.get(worst).copied().unwrap_or(0.0);
        let gains: Vec<String> = cloud
            .der
            .iter()
            .flat_map(|d| {
                let mut g = Vec::new();
                if let Some(m) = &d.mu_p {
                    g.push(format!(
                        "{} μ_p {:.2} → {:.2}",
                        d.name,
                        m[0],
                        m[m.len() - 1]
                    ));
                }
                let m = &d.mu_q;
                g.push(format!(
                    "{} μ_q {:.2} → {:.2}",
                    d.name,
                    m[0],
                    m[m.len() - 1]
                ));
                g
            })
            .collect();
        table.push_str(&format!(
            "\nThe cloud's dc gains, at the start → at the end: {}.\n",
            gains.join(", ")
        ));
        table.push_str(&format!(
            "\nCloud vs load step, largest gap of Δf_pcc relative to the load step's peak deviation: \
             {:.2} % over the whole run (at t = {worst:.4} s), {:.2} % from t = 1.02 s on.\n",
            gap * 100.0,
            gap_after * 100.0
        ));
    }
    table
}

/// Run the demo in the workspace `root` (the FMUs and scenarios bundled in `dist/`).
pub fn demo(root: &Path) -> Result<(), String> {
    use dvpp_cosim::master::{self, CsvWriter, Options, Progress, Record, Recorder, Select};
    use dvpp_report::casestudy::{self, Signals};
    let results = root.join("results");
    std::fs::create_dir_all(&results).map_err(|e| e.to_string())?;
    let mut signals = Vec::new();
    for (name, _) in DEMO_RUNS {
        let ssp = root.join("dist").join(name).join(format!("{name}.ssp"));
        let started = std::time::Instant::now();
        let csv = results.join(format!("{name}.csv"));
        // What the figures and metrics need: the scenario's default record set.
        let (mut writer, mut progress, mut recorder) = (
            Select::new(CsvWriter::new(&csv), Record::system_default()),
            Progress::default(),
            Select::new(Recorder::default(), Record::system_default()),
        );
        let outcome = master::System::builder(&ssp)
            .run(
                &Options::default(),
                &mut [&mut writer, &mut progress, &mut recorder],
            )
            .map_err(|e| format!("{name}: {e}"))?;
        if outcome.end != master::End::Completed {
            return Err(format!("{name}: {:?}", outcome.end));
        }
        println!(
            "{name}: {} s simulated in {:.2} s -> {}",
            outcome.simulated,
            started.elapsed().as_secs_f64(),
            csv.display()
        );
        // The metrics find the DERs by their dc links: every unit of the scenario's.
        let units = crate::scenario::units(
            &root
                .join("studies")
                .join("scenarios")
                .join(format!("{name}.toml")),
        )?;
        crate::units_with(
            &recorder.inner.table.columns,
            der_model::ports::V_DC,
            &units,
        )
        .map_err(|e| format!("{name}: {e}"))?;
        signals.push(Signals::of(&recorder.inner.table).map_err(|e| format!("{name}: {e}"))?);
    }
    let (load, cloud) = (&signals[0], &signals[1]);
    let figures = root.join("tests").join("figures");
    std::fs::create_dir_all(&figures).map_err(|e| e.to_string())?;
    let save = |fig: dvpp_report::plot::Figure, file: &str| -> Result<(), String> {
        for dir in [&results, &figures] {
            let path = dir.join(file);
            fig.save(&path)
                .map_err(|e| format!("{}: {e}", path.display()))?;
        }
        println!("figure tests/figures/{file} (and results/{file})");
        Ok(())
    };
    save(
        casestudy::overview(
            "Case study I: 28 MW load increase at bus 2 (grid-forming DVPP replaces SG2)",
            load,
            None,
        ),
        "case1_load.svg",
    )?;
    save(
        casestudy::overview(
            "Case study I: a cloud cuts the PV's available power (28 MW set-point drop)",
            cloud,
            Some(("Δf_pcc of the load step", load)),
        ),
        "case1_cloud.svg",
    )?;
    // ADPF Bode magnitudes with the dc gains at the start and at the end of the cloud run.
    let lpf = low_pass_units(root, "case1_cloud")?;
    let gains_at = |s: &Signals, i: usize| -> Vec<f64> {
        s.der
            .iter()
            .filter_map(|d| d.mu_p.as_ref().map(|m| m[i.min(m.len() - 1)]))
            .collect()
    };
    let (nominal, after) = (gains_at(cloud, 0), gains_at(cloud, usize::MAX));
    save(
        casestudy::adpf_figure(
            "Case study I: active ADPFs at nominal availability and after the cloud",
            &lpf,
            "bess",
            &[("nominal", &nominal), ("after the cloud", &after)],
        ),
        "case1_adpf.svg",
    )?;

    // The PCC's frequency meter, for the units' coherency with it (the same in both scenarios).
    let scenario = |name: &str| {
        root.join("studies")
            .join("scenarios")
            .join(format!("{name}.toml"))
    };
    let t_f = crate::scenario::pcc_f_filter_t(&scenario(DEMO_RUNS[0].0))?
        .ok_or("case1_load sets no [grid] pcc_f_filter_t")?;
    let table = case1_table(&[(DEMO_RUNS[0].0, load), (DEMO_RUNS[1].0, cloud)], t_f);
    print!("{table}");
    crate::docs::update_between(
        root,
        crate::docs::CASE_STUDIES,
        "<!-- metrics:begin -->",
        "<!-- metrics:end -->",
        &table,
    )?;
    println!(
        "updated the metrics table in {}; results in {}",
        crate::docs::CASE_STUDIES,
        results.display()
    );
    crate::case3::case3(root, &[])
}

/// The low-pass units of a bundled scenario (ADPF time constant and order from their FMUs).
fn low_pass_units(
    root: &Path,
    scenario: &str,
) -> Result<Vec<dvpp_report::casestudy::LowPass>, String> {
    let dir = root.join("dist").join(scenario);
    let mut out = Vec::new();
    let ssp =
        dvpp_cosim::ssp::read(&dir.join(format!("{scenario}.ssp"))).map_err(|e| e.to_string())?;
    for c in &ssp.system.components {
        let fmu = dvpp_cosim::Fmu::load(&ssp.source_path(c)).map_err(|e| e.to_string())?;
        let start = |n: &str| {
            fmu.description
                .variable(n)
                .and_then(|v| v.start_text())
                .and_then(|s| s.parse::<f64>().ok())
        };
        if start("adpf.p.kind") == Some(1.0) {
            out.push(dvpp_report::casestudy::LowPass {
                name: c.name.clone(),
                tau: start("adpf.p.tau").unwrap_or(1.0),
                order: start("adpf.p.order").unwrap_or(1.0) as i32,
            });
        }
    }
    Ok(out)
}
