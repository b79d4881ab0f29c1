//! `cargo xtask sweep`: case study II over the grid-forming share ε, on all cores: the nominal
//! 42 MW step per ε and a seeded Monte Carlo over load disturbances, one summary CSV, a table and
//! the distributions figure.
//!
//! Monte Carlo spread (per run, drawn from a seeded xorshift generator, the same draws for every
//! ε): a load step of U(10, 50) MW at a bus drawn from {2, 5, 6, 8} (the scenario's events 2–5;
//! event 2 is the nominal one at bus 2, the PCC). The location gives the spread a size sweep
//! cannot (the model is nearly linear in the size). Random availabilities were tried and left
//! out: they move the operator's dc gains away from the units' bundled start values, so a run
//! would not start flat. Each Monte Carlo run is 10 s with the step at t = 1 s.

use der_model::ports;
use dvpp_cosim::master::{self, Options, Record, Scheme};
use dvpp_cosim::ssp::{self, Value};
use dvpp_cosim::Table;
use dvpp_report::casestudy::Signals;
use dvpp_report::plot::{Figure, Panel, Style};
use std::path::Path;
use std::sync::{mpsc, Arc, Mutex};

/// The family: ε in percent, as in the scenario names.
pub const EPS: [u32; 5] = [0, 25, 50, 75, 100];

/// Time of the disturbance, s, and the length of a run.
const T_EVENT: f64 = 1.0;
const T_RUN: f64 = 10.0;

/// Load buses a Monte Carlo step may hit, with the scenario event that steps each.
const BUSES: [(u32, usize); 4] = [(2, 2), (5, 3), (6, 4), (8, 5)];

/// One run: ε, its index (0: the nominal step) and the disturbance.
#[derive(Debug, Clone)]
struct Job {
    eps: u32,
    run: usize,
    bus: u32,
    dp_mw: f64,
}

/// What one run measured.
#[derive(Debug, Clone)]
struct Row {
    job: Job,
    coi_nadir_hz: f64,
    pcc_nadir_hz: f64,
    rocof_100: f64,
    rocof_500: f64,
    settle_hz: f64,
    f_nrmse: f64,
    v_nrmse: f64,
    v_dc_dev: f64,
    i_max: f64,
    error: Option<String>,
}

/// xorshift64*: a small seeded generator, enough for drawing disturbances.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }

    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (x >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn between(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }
}

fn jobs(runs: usize, seed: u64) -> Vec<Job> {
    let mut rng = Rng::new(seed);
    // The same disturbances for every ε: the distributions differ by ε only.
    let draws: Vec<(u32, f64)> = (0..runs)
        .map(|_| {
            let bus = BUSES[(rng.uniform() * BUSES.len() as f64) as usize % BUSES.len()].0;
            (bus, rng.between(10.0, 50.0))
        })
        .collect();
    let mut out = Vec::new();
    for eps in EPS {
        out.push(Job {
            eps,
            run: 0,
            bus: 2,
            dp_mw: 42.0,
        });
        for (k, &(bus, dp_mw)) in draws.iter().enumerate() {
            out.push(Job {
                eps,
                run: k + 1,
                bus,
                dp_mw,
            });
        }
    }
    out
}

/// Set (or add) a start value of a component.
pub fn set_start(
    pkg: &mut ssp::Package,
    component: &str,
    name: &str,
    value: Value,
) -> Result<(), String> {
    let c = pkg
        .system
        .components
        .iter_mut()
        .find(|c| c.name == component)
        .ok_or(format!("no component '{component}'"))?;
    match c.parameters.iter_mut().find(|p| p.name == name) {
        Some(p) => p.value = value,
        None => c.parameters.push(ssp::Parameter {
            name: name.into(),
            value,
        }),
    }
    Ok(())
}

/// The scenario with the job's disturbance.
fn prepare(base: &ssp::Package, job: &Job) -> Result<ssp::Package, String> {
    let mut pkg = base.with_system(base.system.clone());
    let event = BUSES
        .iter()
        .find(|b| b.0 == job.bus)
        .expect("a listed bus")
        .1;
    for (_, k) in BUSES {
        set_start(
            &mut pkg,
            "grid",
            &format!("event[{k}].enabled"),
            Value::Boolean(k == event),
        )?;
    }
    set_start(
        &mut pkg,
        "grid",
        &format!("event[{event}].dP"),
        Value::Real(job.dp_mw / 100.0),
    )?;
    Ok(pkg)
}

fn at(t: &[f64], x: &[f64], time: f64) -> f64 {
    let k = t.partition_point(|&s| s < time - 1e-9).min(x.len() - 1);
    x[k]
}

fn measure(job: Job, table: Result<Table, String>, units: &[String]) -> Row {
    let mut row = Row {
        job,
        coi_nadir_hz: f64::NAN,
        pcc_nadir_hz: f64::NAN,
        rocof_100: f64::NAN,
        rocof_500: f64::NAN,
        settle_hz: f64::NAN,
        f_nrmse: f64::NAN,
        v_nrmse: f64::NAN,
        v_dc_dev: f64::NAN,
        i_max: f64::NAN,
        error: None,
    };
    let measured = table.and_then(|t| {
        let col = |n: &str| t.column(n).ok_or(format!("no column {n}"));
        let time = col("time")?;
        let hz = |v: Vec<f64>| -> Vec<f64> { v.iter().map(|x| (x - 1.0) * 50.0).collect() };
        let coi = hz(col("grid.coi.f")?);
        let pcc = hz(col("grid.pcc.f")?);
        let c0 = at(&time, &coi, T_EVENT);
        row.coi_nadir_hz = coi.iter().fold(0.0, |m: f64, &x| m.min(x));
        row.pcc_nadir_hz = pcc.iter().fold(0.0, |m: f64, &x| m.min(x));
        row.rocof_100 = (at(&time, &coi, T_EVENT + 0.1) - c0) / 0.1;
        row.rocof_500 = (at(&time, &coi, T_EVENT + 0.5) - c0) / 0.5;
        row.settle_hz = *coi.last().ok_or("no rows")?;
        // The metrics find the units by their dc links: every unit of the scenario's.
        crate::units_with(&t.columns, ports::V_DC, units)?;
        let m = Signals::of(&t)?.metrics();
        row.f_nrmse = m.f_nrmse;
        row.v_nrmse = m.v_nrmse;
        row.v_dc_dev = m.v_dc.iter().map(|d| d.1).fold(0.0, f64::max);
        let mut i_max = 0.0_f64;
        for u in crate::units_with(&t.columns, ports::I_AC, units)? {
            i_max = col(&format!("{u}.{}", ports::I_AC))?
                .into_iter()
                .fold(i_max, f64::max);
        }
        row.i_max = i_max;
        Ok(())
    });
    row.error = measured.err();
    row
}

/// Run the family on `workers` threads with progress; rows in job order.
fn run_all(root: &Path, jobs: Vec<Job>, workers: usize) -> Result<Vec<Row>, String> {
    let mut bases = Vec::new();
    for eps in EPS {
        let name = format!("case2_load_eps{eps:03}");
        let path = root.join("dist").join(&name).join(format!("{name}.ssp"));
        let pkg = ssp::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        let scenario = root
            .join("studies")
            .join("scenarios")
            .join(format!("{name}.toml"));
        bases.push((eps, pkg, crate::scenario::units(&scenario)?));
    }
    let bases = Arc::new(bases);
    let n = jobs.len();
    let queue = Arc::new(Mutex::new(jobs.into_iter().enumerate().collect::<Vec<_>>()));
    let (tx, rx) = mpsc::channel();
    let started = std::time::Instant::now();
    let handles: Vec<_> = (0..workers)
        .map(|_| {
            let (queue, bases, tx) = (queue.clone(), bases.clone(), tx.clone());
            std::thread::spawn(move || loop {
                let Some((i, job)) = queue.lock().expect("queue").pop() else {
                    break;
                };
                let (_, base, units) = bases.iter().find(|b| b.0 == job.eps).expect("bundled");
                // The nominal run is the scenario as shipped (20 s); Monte Carlo runs are 10 s.
                let opts = Options {
                    stop: (job.run > 0).then_some(T_RUN),
                    step: None,
                    algorithm: Scheme::Jacobi,
                };
                let table = prepare(base, &job).and_then(|pkg| {
                    master::System::builder(&pkg)
                        .load()
                        .and_then(|mut s| {
                            s.quiet();
                            s.simulate_recording(&opts, Record::system_default())
                        })
                        .map_err(|e| e.to_string())
                });
                if tx.send((i, measure(job, table, units))).is_err() {
                    break;
                }
            })
        })
        .collect();
    drop(tx);
    let mut rows: Vec<Option<Row>> = vec![None; n];
    for (done, (i, row)) in rx.iter().enumerate() {
        rows[i] = Some(row);
        if (done + 1) % 10 == 0 || done + 1 == n {
            println!(
                "sweep: {}/{n} runs ({:.0} s)",
                done + 1,
                started.elapsed().as_secs_f64()
            );
        }
    }
    for h in handles {
        h.join().map_err(|_| "a sweep worker panicked")?;
    }
    Ok(rows
        .into_iter()
        .map(|r| r.expect("every job ran"))
        .collect())
}

fn write_csv(path: &Path, rows: &[Row]) -> Result<(), String> {
    let mut text = String::from(
        "eps,run,bus,dP_MW,coi_nadir_Hz,pcc_nadir_Hz,coi_rocof_100ms_Hz_per_s,\
         coi_rocof_500ms_Hz_per_s,coi_settling_Hz,f_nrmse,v_nrmse,max_v_dc_dev,max_i_ac_pu,error\n",
    );
    for r in rows {
        let j = &r.job;
        text += &format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            j.eps as f64 / 100.0,
            j.run,
            j.bus,
            j.dp_mw,
            r.coi_nadir_hz,
            r.pcc_nadir_hz,
            r.rocof_100,
            r.rocof_500,
            r.settle_hz,
            r.f_nrmse,
            r.v_nrmse,
            r.v_dc_dev,
            r.i_max,
            r.error.as_deref().unwrap_or("").replace([',', '\n'], ";")
        );
    }
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))
}

/// Empirical distribution (sorted values against their cumulative fraction).
fn cdf(mut x: Vec<f64>) -> (Vec<f64>, Vec<f64>) {
    x.retain(|v| v.is_finite());
    x.sort_by(f64::total_cmp);
    let n = x.len() as f64;
    let y = (1..=x.len()).map(|k| k as f64 / n).collect();
    (x, y)
}

fn figure(rows: &[Row]) -> Figure {
    let mut rocof = Panel::new(
        "COI RoCoF over 100 ms per 100 MW of disturbance",
        "Hz/s per 100 MW",
        "fraction of runs",
    );
    let mut nadir = Panel::new(
        "COI nadir per 100 MW of disturbance",
        "Hz per 100 MW",
        "fraction of runs",
    );
    let styles = [
        Style::Dotted,
        Style::Dashed,
        Style::Solid,
        Style::Dashed,
        Style::Solid,
    ];
    for (&eps, style) in EPS.iter().zip(styles) {
        let mc: Vec<&Row> = rows
            .iter()
            .filter(|r| r.job.eps == eps && r.job.run > 0)
            .collect();
        let per = |f: fn(&Row) -> f64| -> Vec<f64> {
            mc.iter().map(|r| f(r) / r.job.dp_mw * 100.0).collect()
        };
        let label = format!("ε = {:.2}", eps as f64 / 100.0);
        let (x, y) = cdf(per(|r| r.rocof_100));
        rocof = rocof.series(label.clone(), &x, &y, style);
        let (x, y) = cdf(per(|r| r.coi_nadir_hz));
        nadir = nadir.series(label, &x, &y, style);
    }
    Figure::new("Case study II: Monte Carlo over load disturbances, per grid-forming share ε")
        .panel(rocof)
        .panel(nadir)
        .columns(2)
}

fn quantile(mut x: Vec<f64>, q: f64) -> f64 {
    x.retain(|v| v.is_finite());
    x.sort_by(f64::total_cmp);
    if x.is_empty() {
        return f64::NAN;
    }
    x[((x.len() - 1) as f64 * q).round() as usize]
}

/// The table of the nominal runs and the Monte Carlo spread, as Markdown.
fn table(rows: &[Row]) -> String {
    let mut out = String::from(
        "| ε | f NRMSE | v NRMSE | COI nadir | COI RoCoF 100 ms | COI RoCoF 500 ms | largest dc-link deviation | largest current | Monte Carlo RoCoF/100 MW (5–95 %) | Monte Carlo nadir/100 MW (5–95 %) |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for eps in EPS {
        let Some(n) = rows.iter().find(|r| r.job.eps == eps && r.job.run == 0) else {
            continue;
        };
        let mc: Vec<&Row> = rows
            .iter()
            .filter(|r| r.job.eps == eps && r.job.run > 0)
            .collect();
        let norm = |f: fn(&Row) -> f64| -> Vec<f64> {
            mc.iter().map(|r| f(r) / r.job.dp_mw * 100.0).collect()
        };
        let (ro, na) = (norm(|r| r.rocof_100), norm(|r| r.coi_nadir_hz));
        out += &format!(
            "| {:.2} | {:.2} % | {:.1} % | {:.4} Hz | {:.4} Hz/s | {:.4} Hz/s | {:.2} % | {:.2} pu | {:.3} … {:.3} Hz/s | {:.3} … {:.3} Hz |\n",
            eps as f64 / 100.0,
            n.f_nrmse * 100.0,
            n.v_nrmse * 100.0,
            n.coi_nadir_hz,
            n.rocof_100,
            n.rocof_500,
            n.v_dc_dev * 100.0,
            n.i_max,
            quantile(ro.clone(), 0.05),
            quantile(ro, 0.95),
            quantile(na.clone(), 0.05),
            quantile(na, 0.95),
        );
    }
    out
}

/// Save `fig` as `results/NAME` and `tests/figures/NAME` (the docs show the latter).
pub fn save_figure(root: &Path, fig: &Figure, name: &str) -> Result<(), String> {
    for path in [
        root.join("results").join(name),
        root.join("tests/figures").join(name),
    ] {
        fig.save(&path)
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(())
}

/// `cargo xtask sweep [--runs N] [--seed S]`: `runs` Monte Carlo runs per ε (default 40).
pub fn sweep(root: &Path, args: &[String]) -> Result<(), String> {
    let mut runs = 40usize;
    let mut seed = 1u64;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = |name: &str| {
            it.next()
                .and_then(|v| v.parse::<u64>().ok())
                .ok_or(format!("sweep: {name} needs a whole number"))
        };
        match a.as_str() {
            "--runs" => runs = value("--runs")? as usize,
            "--seed" => seed = value("--seed")?,
            other => return Err(format!("sweep: unknown argument '{other}'")),
        }
    }
    let workers = std::thread::available_parallelism().map_or(1, |n| n.get());
    let all = jobs(runs, seed);
    println!(
        "sweep: {} runs of {T_RUN} s (ε in {EPS:?} %, {runs} Monte Carlo runs each, seed {seed}) on {workers} threads",
        all.len()
    );
    let started = std::time::Instant::now();
    let rows = run_all(root, all, workers)?;
    let wall = started.elapsed().as_secs_f64();
    let results = root.join("results");
    std::fs::create_dir_all(&results).map_err(|e| e.to_string())?;
    let csv = results.join("case2_sweep.csv");
    write_csv(&csv, &rows)?;
    save_figure(root, &figure(&rows), "case2_distributions.svg")?;
    let failed: Vec<&Row> = rows.iter().filter(|r| r.error.is_some()).collect();
    println!("{}", table(&rows));
    println!(
        "sweep: {} runs in {wall:.0} s on {workers} threads; {} failed; {} and the figure tests/figures/case2_distributions.svg",
        rows.len(),
        failed.len(),
        csv.display()
    );
    for r in failed.iter().take(5) {
        println!(
            "  ε = {}, run {}: {}",
            r.job.eps as f64 / 100.0,
            r.job.run,
            r.error.as_deref().unwrap_or("")
        );
    }
    if failed.is_empty() {
        Ok(())
    } else {
        Err(format!("{} runs failed", failed.len()))
    }
}
