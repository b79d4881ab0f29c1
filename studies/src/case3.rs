//! `cargo xtask case3`: case study III, the spatially distributed DVPP: the four scenarios at
//! R/X = 1 (matching at each point of coupling, the units' Δp against the POCs' Δp) and the R/X
//! Monte Carlo (seeded random R/X per MV line), with a CSV, a table and the figures.
//!
//! Monte Carlo: per draw, every line of the grid case's `[mv]` group gets its own R/X from
//! U(0.4, 2) (grid parameters `mv.line[k].rx`, each line keeping |Z|; the power flow is re-solved
//! at initialization), the same draws for both disturbances; the DER and operator keep
//! `rot.rx` = 1 (the operator does not know the lines).

use der_model::ports;
use dvpp_cosim::master::{self, Options, Record, Scheme};
use dvpp_cosim::ssp::{self, Value};
use dvpp_cosim::Table;
use dvpp_report::casestudy::{nrmse, nrmse_window, window};
use dvpp_report::plot::{Figure, Panel, Style};
use grid_model::ports as grid_ports;
use std::path::Path;

use crate::sweep::{save_figure, set_start, Rng};

/// The scenarios at R/X = 1: (name, disturbance, control).
pub const NOMINAL: [(&str, &str, &str); 4] = [
    ("case3_ext_pf", "external", "p-f"),
    ("case3_ext_rot", "external", "rotational"),
    ("case3_int_pf", "internal", "p-f"),
    ("case3_int_rot", "internal", "rotational"),
];

/// The Monte Carlo's scenarios (rotational control, both disturbances).
pub const DRAWN: [&str; 2] = ["case3_ext_rot", "case3_int_rot"];

const F_NOM_HZ: f64 = 50.0;

/// Time of the disturbance, s, and the transient window after it the table reports, s.
pub const T_EVENT: f64 = 1.0;
pub const TRANSIENT: f64 = 5.0;

/// One run's measurements.
#[derive(Clone, Default)]
pub struct Run {
    pub scenario: String,
    /// 0: the nominal R/X = 1; k > 0: draw k.
    pub draw: usize,
    /// Per line, the drawn R/X (empty for the nominal run).
    pub rx: Vec<f64>,
    /// Per POC: frequency NRMSE against the operator's desired response over the run, and over
    /// the first [`TRANSIENT`] s after the step (normalized by the whole run's peak).
    pub nrmse: Vec<f64>,
    pub nrmse_transient: Vec<f64>,
    /// At the end of the run: Σ Δp of the units and Σ Δp of the POCs, MW.
    pub dp_units_mw: f64,
    pub dp_pocs_mw: f64,
    /// t, then per POC its Δf (Hz), then the desired Δf (Hz).
    series: Vec<Vec<f64>>,
    /// The scenario's DER units, in slot order.
    expected: Vec<String>,
    /// Per unit: name, Δp, Δq, Δp' (MW, Mvar).
    units: Vec<(String, [Vec<f64>; 3])>,
    pub error: Option<String>,
}

fn column(t: &Table, name: &str) -> Result<Vec<f64>, String> {
    t.column(name).ok_or(format!("no column {name}"))
}

fn delta(x: &[f64], scale: f64) -> Vec<f64> {
    let x0 = x.first().copied().unwrap_or(0.0);
    x.iter().map(|v| (v - x0) * scale).collect()
}

/// Measure one completed run.
fn measure(run: &mut Run, t: &Table) -> Result<(), String> {
    let time = column(t, "time")?;
    let df_ref = column(t, "operator.ref.df")?;
    let mut series = vec![time.clone()];
    let mut dp_pocs = 0.0;
    let mut k = 1;
    let w = window(&time, T_EVENT, TRANSIENT);
    while let Some(f) = t.column(&format!("grid.poc[{k}].f")) {
        let df: Vec<f64> = f.iter().map(|x| x - 1.0).collect();
        run.nrmse.push(nrmse(&df, &df_ref));
        run.nrmse_transient
            .push(nrmse_window(&df, &df_ref, w.start, w.end));
        series.push(df.iter().map(|x| x * F_NOM_HZ).collect());
        let p = column(t, &format!("grid.poc[{k}].p"))?;
        dp_pocs += (p[p.len() - 1] - p[0]) * 100.0;
        k += 1;
    }
    if k == 1 {
        return Err("the grid reports no point of coupling".into());
    }
    series.push(df_ref.iter().map(|x| x * F_NOM_HZ).collect());
    run.series = series;
    run.dp_pocs_mw = dp_pocs;
    let names = crate::units_with(&t.columns, ports::P_ROT, &run.expected)?;
    let mut dp_units = 0.0;
    for (slot, u) in names.iter().enumerate() {
        let p = column(t, &format!("grid.{}", grid_ports::der_p(slot + 1)))?;
        let q = column(t, &format!("grid.{}", grid_ports::der_q(slot + 1)))?;
        let p_rot = column(t, &format!("{u}.{}", ports::P_ROT))?;
        dp_units += (p[p.len() - 1] - p[0]) * 100.0;
        run.units.push((
            u.clone(),
            [delta(&p, 100.0), delta(&q, 100.0), delta(&p_rot, 100.0)],
        ));
    }
    run.dp_units_mw = dp_units;
    Ok(())
}

/// Run `pkg` and measure it into `run`.
fn simulate(pkg: &ssp::Package, run: &mut Run) {
    let table = master::System::builder(pkg)
        .load()
        .and_then(|mut s| {
            s.quiet();
            s.simulate_recording(
                &Options {
                    stop: None,
                    step: None,
                    algorithm: Scheme::Jacobi,
                },
                Record::system_default(),
            )
        })
        .map_err(|e| e.to_string());
    if let Err(e) = table.and_then(|t| measure(run, &t)) {
        run.error = Some(format!("{} draw {}: {e}", run.scenario, run.draw));
    }
}

/// The number of R/X parameters of the grid (`mv.line[k].rx`) in `pkg`'s grid FMU.
fn mv_lines(pkg: &ssp::Package) -> Result<usize, String> {
    let grid = pkg
        .system
        .components
        .iter()
        .find(|c| c.name == "grid")
        .ok_or("no component 'grid'")?;
    let fmu = dvpp_cosim::Fmu::load(&pkg.source_path(grid)).map_err(|e| e.to_string())?;
    Ok(fmu
        .description
        .model_variables
        .variables
        .iter()
        .filter(|v| v.name.starts_with("mv.line[") && v.name.ends_with("].rx"))
        .count())
}

/// Run every job on all cores with progress; results in job order.
fn run_all(jobs: Vec<(ssp::Package, Run)>) -> Vec<Run> {
    let workers = std::thread::available_parallelism().map_or(1, |n| n.get());
    crate::parallel::in_order("case3", jobs, workers, 8, |(pkg, mut run)| {
        simulate(&pkg, &mut run);
        run
    })
    .unwrap_or_else(|e| panic!("{e}"))
}

fn median(mut x: Vec<f64>) -> f64 {
    x.sort_by(f64::total_cmp);
    if x.is_empty() {
        f64::NAN
    } else {
        x[x.len() / 2]
    }
}

fn pct(x: &[f64]) -> String {
    x.iter()
        .map(|v| format!("{:.2} %", v * 100.0))
        .collect::<Vec<_>>()
        .join(" / ")
}

/// A scenario's R/X Monte Carlo: the number of completed draws, and per POC the median and the
/// largest frequency NRMSE over them.
#[derive(Debug, Clone, Copy)]
pub struct MonteCarlo {
    pub draws: usize,
    pub median: [f64; 2],
    pub worst: [f64; 2],
}

/// The Monte Carlo of `scenario` among `runs` (None: no completed draw).
pub fn monte_carlo(runs: &[Run], scenario: &str) -> Option<MonteCarlo> {
    let drawn: Vec<&Run> = runs
        .iter()
        .filter(|r| r.scenario == scenario && r.draw > 0 && r.error.is_none())
        .collect();
    if drawn.is_empty() {
        return None;
    }
    let per = |k: usize| -> Vec<f64> {
        drawn
            .iter()
            .filter_map(|r| r.nrmse.get(k).copied())
            .collect()
    };
    let (a, b) = (per(0), per(1));
    let worst = |x: &[f64]| x.iter().cloned().fold(0.0, f64::max);
    Some(MonteCarlo {
        draws: drawn.len(),
        median: [median(a.clone()), median(b.clone())],
        worst: [worst(&a), worst(&b)],
    })
}

/// The nominal table and the Monte Carlo summary, as Markdown.
pub fn table(runs: &[Run]) -> String {
    let mut out = format!(
        "| scenario | disturbance | control | f NRMSE at POC 1 / POC 2: run | first {TRANSIENT} s | Σ Δp of the units | Σ Δp at the POCs | R/X Monte Carlo: median / worst NRMSE (POC 1, POC 2) |\n|---|---|---|---|---|---|---|---|\n",
    );
    for (name, dist, control) in NOMINAL {
        let Some(r) = runs.iter().find(|r| r.scenario == name && r.draw == 0) else {
            continue;
        };
        let mc = match monte_carlo(runs, name) {
            None => "—".to_string(),
            Some(m) => format!(
                "{} runs: {:.2} / {:.2} %, {:.2} / {:.2} %",
                m.draws,
                m.median[0] * 100.0,
                m.worst[0] * 100.0,
                m.median[1] * 100.0,
                m.worst[1] * 100.0
            ),
        };
        out += &format!(
            "| `{name}` | {dist} | {control} | {} | {} | {:+.2} MW | {:+.2} MW | {mc} |\n",
            pct(&r.nrmse),
            pct(&r.nrmse_transient),
            r.dp_units_mw,
            r.dp_pocs_mw,
        );
    }
    out
}

/// POC frequencies against the desired response for the four scenarios, and the units' Δp,
/// Δq and Δp' under rotational control.
fn response_figure(runs: &[Run]) -> Figure {
    let mut fig = Figure::new("Case study III: frequency at the points of coupling (desired dashed) and the units' powers");
    for (name, dist, control) in NOMINAL {
        let Some(r) = runs.iter().find(|r| r.scenario == name && r.draw == 0) else {
            continue;
        };
        if r.series.is_empty() {
            continue;
        }
        let t = &r.series[0];
        let mut p = Panel::new(
            format!("{dist} disturbance, {control} control"),
            "t (s)",
            "Δf (Hz)",
        );
        let npoc = r.series.len() - 2;
        for k in 0..npoc {
            p = p.series(format!("POC {}", k + 1), t, &r.series[k + 1], Style::Solid);
        }
        p = p.series("desired", t, &r.series[npoc + 1], Style::Dashed);
        fig = fig.panel(p);
    }
    for (name, dist, _) in NOMINAL.iter().filter(|n| n.2 == "rotational") {
        let Some(r) = runs.iter().find(|r| r.scenario == *name && r.draw == 0) else {
            continue;
        };
        if r.series.is_empty() {
            continue;
        }
        let t = &r.series[0];
        let mut p = Panel::new(
            format!("{dist}, rotational: units' Δp (solid), Δp' (dashed)"),
            "t (s)",
            "MW",
        );
        let mut q = Panel::new(format!("{dist}, rotational: units' Δq"), "t (s)", "Mvar");
        for (u, [dp, dq, dp_rot]) in &r.units {
            p = p.series(format!("{u} Δp"), t, dp, Style::Solid);
            p = p.series(format!("{u} Δp'"), t, dp_rot, Style::Dashed);
            q = q.series(u.clone(), t, dq, Style::Solid);
        }
        fig = fig.panel(p).panel(q);
    }
    fig.columns(2)
}

/// The Monte Carlo envelope (dotted: lowest and highest over the draws) around the R/X = 1
/// response, per disturbance and POC.
fn envelope_figure(runs: &[Run]) -> Figure {
    let mut fig = Figure::new("Case study III: random R/X per MV line, rotational control");
    for name in DRAWN {
        let Some(nominal) = runs.iter().find(|r| r.scenario == name && r.draw == 0) else {
            continue;
        };
        if nominal.series.is_empty() {
            continue;
        }
        let t = &nominal.series[0];
        let npoc = nominal.series.len() - 2;
        let drawn: Vec<&Run> = runs
            .iter()
            .filter(|r| r.scenario == name && r.draw > 0 && r.series.len() == npoc + 2)
            .collect();
        for k in 0..npoc {
            let mut p = Panel::new(format!("{name}: POC {}", k + 1), "t (s)", "Δf (Hz)");
            let n = t.len();
            let at = |f: fn(f64, f64) -> f64, init: f64| -> Vec<f64> {
                (0..n)
                    .map(|i| {
                        drawn
                            .iter()
                            .filter_map(|r| r.series[k + 1].get(i))
                            .fold(init, |a, &b| f(a, b))
                    })
                    .collect()
            };
            if !drawn.is_empty() {
                p = p.series(
                    "lowest of the draws",
                    t,
                    &at(f64::min, f64::INFINITY),
                    Style::Dotted,
                );
                p = p.series(
                    "highest of the draws",
                    t,
                    &at(f64::max, f64::NEG_INFINITY),
                    Style::Dotted,
                );
            }
            p = p.series("R/X = 1", t, &nominal.series[k + 1], Style::Solid);
            p = p.series("desired", t, &nominal.series[npoc + 1], Style::Dashed);
            fig = fig.panel(p);
        }
    }
    fig.columns(2)
}

fn write_csv(path: &Path, runs: &[Run]) -> Result<(), String> {
    let mut text = String::from(
        "scenario,draw,nrmse_poc1,nrmse_poc2,dp_units_MW,dp_pocs_MW,rx_per_line,error\n",
    );
    for r in runs {
        let n = |k: usize| r.nrmse.get(k).map_or(String::new(), |x| x.to_string());
        text += &format!(
            "{},{},{},{},{},{},{},{}\n",
            r.scenario,
            r.draw,
            n(0),
            n(1),
            r.dp_units_mw,
            r.dp_pocs_mw,
            r.rx.iter()
                .map(|x| format!("{x:.4}"))
                .collect::<Vec<_>>()
                .join(" "),
            r.error.as_deref().unwrap_or("").replace([',', '\n'], ";")
        );
    }
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))
}

/// Run the four scenarios bundled in `root/dist/` at R/X = 1 and `draws` R/X draws (from
/// `seed`) of each of [`DRAWN`], on all cores; the runs in order, failed ones with their error.
pub fn study(root: &Path, draws: usize, seed: u64) -> Result<Vec<Run>, String> {
    let dist = root.join("dist");
    // The packages read (each unpacked once) live until every run is done: the runs' systems
    // refer to their unpacked FMUs.
    let mut bases = Vec::new();
    let mut jobs = Vec::new();
    let mut rx_draws: Vec<Vec<f64>> = Vec::new();
    for (name, _, _) in NOMINAL {
        let path = dist.join(name).join(format!("{name}.ssp"));
        let pkg = ssp::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        let expected = crate::scenario::units(
            &root
                .join("studies")
                .join("scenarios")
                .join(format!("{name}.toml")),
        )?;
        if DRAWN.contains(&name) {
            if rx_draws.is_empty() {
                let lines = mv_lines(&pkg)?;
                let mut rng = Rng::new(seed);
                rx_draws = (0..draws)
                    .map(|_| (0..lines).map(|_| rng.between(0.4, 2.0)).collect())
                    .collect();
            }
            for (d, rx) in rx_draws.iter().enumerate() {
                let mut drawn = pkg.with_system(pkg.system.clone());
                for (k, &x) in rx.iter().enumerate() {
                    set_start(
                        &mut drawn,
                        "grid",
                        &format!("mv.line[{}].rx", k + 1),
                        Value::Real(x),
                    )?;
                }
                jobs.push((
                    drawn,
                    Run {
                        scenario: name.into(),
                        draw: d + 1,
                        rx: rx.clone(),
                        expected: expected.clone(),
                        ..Run::default()
                    },
                ));
            }
        }
        jobs.push((
            pkg.with_system(pkg.system.clone()),
            Run {
                scenario: name.into(),
                expected,
                ..Run::default()
            },
        ));
        bases.push(pkg);
    }
    println!(
        "case3: {} runs (4 scenarios at R/X = 1, {draws} R/X draws each for {DRAWN:?}, seed {seed})",
        jobs.len()
    );
    let runs = run_all(jobs);
    drop(bases);
    Ok(runs)
}

/// The documented Monte Carlo: draws per rotational scenario and seed (the table in
/// docs/case-studies.md; `tests/tests/case3.rs` reruns it).
pub const DRAWS: usize = 24;
pub const SEED: u64 = 1;

/// `cargo xtask case3 [--draws N] [--seed S]` (default [`DRAWS`] draws, seed [`SEED`]; with both
/// the defaults it rewrites the table of docs/case-studies.md).
pub fn case3(root: &Path, args: &[String]) -> Result<(), String> {
    let (mut draws, mut seed) = (DRAWS, SEED);
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = |name: &str| {
            it.next()
                .and_then(|v| v.parse::<u64>().ok())
                .ok_or(format!("case3: {name} needs a whole number"))
        };
        match a.as_str() {
            "--draws" => draws = value("--draws")? as usize,
            "--seed" => seed = value("--seed")?,
            other => return Err(format!("case3: unknown argument '{other}'")),
        }
    }
    let started = std::time::Instant::now();
    let runs = study(root, draws, seed)?;
    let wall = started.elapsed().as_secs_f64();
    let results = root.join("results");
    std::fs::create_dir_all(&results).map_err(|e| e.to_string())?;
    let csv = results.join("case3.csv");
    write_csv(&csv, &runs)?;
    save_figure(root, &response_figure(&runs), "case3_response.svg")?;
    save_figure(root, &envelope_figure(&runs), "case3_rx_envelope.svg")?;
    let table = table(&runs);
    println!("{table}");
    let failed: Vec<&Run> = runs.iter().filter(|r| r.error.is_some()).collect();
    if failed.is_empty() && (draws, seed) == (DRAWS, SEED) {
        crate::docs::update_between(
            root,
            crate::docs::CASE_STUDIES,
            "<!-- case3:begin -->",
            "<!-- case3:end -->",
            &table,
        )?;
        println!("case3: updated the table in {}", crate::docs::CASE_STUDIES);
    }
    println!(
        "case3: {} runs in {wall:.0} s; {} failed; {} and tests/figures/case3_response.svg, case3_rx_envelope.svg",
        runs.len(),
        failed.len(),
        csv.display()
    );
    for r in failed.iter().take(5) {
        println!("  {}", r.error.as_deref().unwrap_or(""));
    }
    if failed.is_empty() {
        Ok(())
    } else {
        Err(format!("{} runs failed", failed.len()))
    }
}
