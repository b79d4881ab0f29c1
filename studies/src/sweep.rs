//! `cargo xtask sweep`: case study II over the grid-forming share ε, on all cores: the nominal
//! 42 MW step per ε and two seeded Monte Carlo families of load steps, one summary CSV, the table
//! of `docs/case-studies.md` and the distributions figure.
//!
//! Monte Carlo (per run, drawn from a seeded xorshift generator, the same draws for every ε):
//! - *bus 2* (the paper's): a load step of U(10, 50) MW at bus 2, the PCC (the scenario's
//!   event 2, the nominal one);
//! - *random bus*: a load step of U(10, 50) MW at a bus drawn from {2, 5, 6, 8} (events 2–5).
//!   The location gives a wider spread than the size alone (per MW of disturbance).
//!
//! Random availabilities were tried and left out: they move the operator's dc gains away from
//! the units' bundled start values, so a run would not start flat. Each Monte Carlo run is 10 s
//! with the step at t = 1 s.

use der_model::ports;
use dvpp_cosim::master::{self, Options, Record, Scheme};
use dvpp_cosim::ssp::{self, Value};
use dvpp_cosim::Table;
use dvpp_report::casestudy::Signals;
use dvpp_report::plot::{Figure, Panel, Style};
use std::path::Path;

/// The family: ε in percent, as in the scenario names.
pub const EPS: [u32; 5] = [0, 25, 50, 75, 100];

/// Time of the disturbance, s, and the length of a Monte Carlo run.
pub const T_EVENT: f64 = 1.0;
const T_RUN: f64 = 10.0;
/// The transient window after the step the table reports the frequency NRMSE over, s.
pub const TRANSIENT: f64 = 5.0;

/// The documented Monte Carlo: runs per family and ε, and the seed (the table in
/// docs/case-studies.md; `tests/tests/case2.rs` reruns it).
pub const RUNS: usize = 20;
pub const SEED: u64 = 1;

/// A run's disturbance family.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// The scenario's own 42 MW step at bus 2, 20 s.
    Nominal,
    /// The paper's Monte Carlo: U(10, 50) MW at bus 2.
    Bus2,
    /// U(10, 50) MW at a bus drawn from {2, 5, 6, 8}.
    RandomBus,
}

impl Family {
    /// Its name in the CSV.
    pub fn name(self) -> &'static str {
        match self {
            Family::Nominal => "nominal",
            Family::Bus2 => "bus2",
            Family::RandomBus => "random_bus",
        }
    }
}

/// Load buses a Monte Carlo step may hit, with the scenario event that steps each.
const BUSES: [(u32, usize); 4] = [(2, 2), (5, 3), (6, 4), (8, 5)];

/// One run: ε, its family, its index within the family (from 1; 0: the nominal step) and the
/// disturbance.
#[derive(Debug, Clone)]
pub struct Job {
    pub eps: u32,
    pub family: Family,
    pub run: usize,
    pub bus: u32,
    pub dp_mw: f64,
}

/// What one run measured.
#[derive(Debug, Clone)]
pub struct Row {
    pub job: Job,
    pub coi_nadir_hz: f64,
    pub pcc_nadir_hz: f64,
    /// COI RoCoF over the first 100 and 500 ms after the step, Hz/s.
    pub rocof_100: f64,
    pub rocof_500: f64,
    pub settle_hz: f64,
    /// NRMSE of Δf_pcc and Δv_pcc against the desired response over the run, and over the
    /// first [`TRANSIENT`] s after the step (same normalization).
    pub f_nrmse: f64,
    pub v_nrmse: f64,
    pub f_nrmse_transient: f64,
    pub v_nrmse_transient: f64,
    pub v_dc_dev: f64,
    pub i_max: f64,
    pub error: Option<String>,
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

/// The nominal run and `runs` runs of each Monte Carlo family per ε, drawn with `seed`.
pub fn jobs(runs: usize, seed: u64) -> Vec<Job> {
    let mut rng = Rng::new(seed);
    // The same disturbances for every ε: the distributions differ by ε only.
    let random_bus: Vec<(u32, f64)> = (0..runs)
        .map(|_| {
            let bus = BUSES[(rng.uniform() * BUSES.len() as f64) as usize % BUSES.len()].0;
            (bus, rng.between(10.0, 50.0))
        })
        .collect();
    let bus2: Vec<(u32, f64)> = (0..runs).map(|_| (2, rng.between(10.0, 50.0))).collect();
    let mut out = Vec::new();
    for eps in EPS {
        out.push(Job {
            eps,
            family: Family::Nominal,
            run: 0,
            bus: 2,
            dp_mw: 42.0,
        });
        for (family, draws) in [(Family::Bus2, &bus2), (Family::RandomBus, &random_bus)] {
            for (k, &(bus, dp_mw)) in draws.iter().enumerate() {
                out.push(Job {
                    eps,
                    family,
                    run: k + 1,
                    bus,
                    dp_mw,
                });
            }
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
        f_nrmse_transient: f64::NAN,
        v_nrmse_transient: f64::NAN,
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
        let signals = Signals::of(&t)?;
        let m = signals.metrics();
        let transient = signals.transient(T_EVENT, TRANSIENT);
        row.f_nrmse_transient = transient.f_nrmse;
        row.v_nrmse_transient = transient.v_nrmse;
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

/// Run `jobs` on `workers` threads with progress, the bundled `root/dist/case2_load_eps*`;
/// rows in job order.
pub fn run_all(root: &Path, jobs: Vec<Job>, workers: usize) -> Result<Vec<Row>, String> {
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
    crate::parallel::in_order("sweep", jobs, workers, 10, |job: Job| {
        let (_, base, units) = bases.iter().find(|b| b.0 == job.eps).expect("bundled");
        // The nominal run is the scenario as shipped (20 s); Monte Carlo runs are 10 s.
        let opts = Options {
            stop: (job.family != Family::Nominal).then_some(T_RUN),
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
        measure(job, table, units)
    })
}

fn write_csv(path: &Path, rows: &[Row]) -> Result<(), String> {
    let mut text = String::from(
        "eps,family,run,bus,dP_MW,coi_nadir_Hz,pcc_nadir_Hz,coi_rocof_100ms_Hz_per_s,\
         coi_rocof_500ms_Hz_per_s,coi_settling_Hz,f_nrmse,f_nrmse_first_5s,v_nrmse,\
         v_nrmse_first_5s,max_v_dc_dev,max_i_ac_pu,error\n",
    );
    for r in rows {
        let j = &r.job;
        text += &format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            j.eps as f64 / 100.0,
            j.family.name(),
            j.run,
            j.bus,
            j.dp_mw,
            r.coi_nadir_hz,
            r.pcc_nadir_hz,
            r.rocof_100,
            r.rocof_500,
            r.settle_hz,
            r.f_nrmse,
            r.f_nrmse_transient,
            r.v_nrmse,
            r.v_nrmse_transient,
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
    let styles = [
        Style::Dotted,
        Style::Dashed,
        Style::Solid,
        Style::Dashed,
        Style::Solid,
    ];
    let mut fig =
        Figure::new("Case study II: Monte Carlo over load disturbances, per grid-forming share ε");
    for (family, what) in [
        (Family::Bus2, "U(10, 50) MW at bus 2"),
        (Family::RandomBus, "U(10, 50) MW at a random bus"),
    ] {
        let mut rocof = Panel::new(
            format!("{what}: COI RoCoF over 100 ms per 100 MW"),
            "Hz/s per 100 MW",
            "fraction of runs",
        );
        let mut nadir = Panel::new(
            format!("{what}: COI nadir per 100 MW"),
            "Hz per 100 MW",
            "fraction of runs",
        );
        for (&eps, style) in EPS.iter().zip(styles) {
            let label = format!("ε = {:.2}", eps as f64 / 100.0);
            let (x, y) = cdf(per_100mw(rows, eps, family, |r| r.rocof_100));
            rocof = rocof.series(label.clone(), &x, &y, style);
            let (x, y) = cdf(per_100mw(rows, eps, family, |r| r.coi_nadir_hz));
            nadir = nadir.series(label, &x, &y, style);
        }
        fig = fig.panel(rocof).panel(nadir);
    }
    fig.columns(2)
}

/// `f` of the runs of `family` at `eps`, per 100 MW of their disturbance.
fn per_100mw(rows: &[Row], eps: u32, family: Family, f: fn(&Row) -> f64) -> Vec<f64> {
    rows.iter()
        .filter(|r| r.job.eps == eps && r.job.family == family)
        .map(|r| f(r) / r.job.dp_mw * 100.0)
        .collect()
}

/// The `q`-quantile of the finite values of `x` (nearest rank).
pub fn quantile(mut x: Vec<f64>, q: f64) -> f64 {
    x.retain(|v| v.is_finite());
    x.sort_by(f64::total_cmp);
    if x.is_empty() {
        return f64::NAN;
    }
    x[((x.len() - 1) as f64 * q).round() as usize]
}

/// A Monte Carlo family's spread at one ε: the 5 % and 95 % quantiles of the COI RoCoF over
/// 100 ms and of the COI nadir, each per 100 MW of disturbance (Hz/s, Hz).
#[derive(Debug, Clone, Copy)]
pub struct Spread {
    pub rocof: [f64; 2],
    pub nadir: [f64; 2],
}

/// The spread of `family`'s runs at `eps`.
pub fn spread(rows: &[Row], eps: u32, family: Family) -> Spread {
    let (ro, na) = (
        per_100mw(rows, eps, family, |r| r.rocof_100),
        per_100mw(rows, eps, family, |r| r.coi_nadir_hz),
    );
    Spread {
        rocof: [quantile(ro.clone(), 0.05), quantile(ro, 0.95)],
        nadir: [quantile(na.clone(), 0.05), quantile(na, 0.95)],
    }
}

/// The table of the nominal runs and the Monte Carlo spreads, as Markdown.
pub fn table(rows: &[Row]) -> String {
    let mut out = format!(
        "| ε | f NRMSE: run / first {TRANSIENT} s | v NRMSE: run / first {TRANSIENT} s | COI nadir | COI RoCoF 100 ms | COI RoCoF 500 ms | largest dc-link deviation | largest current | bus 2: RoCoF/100 MW (5–95 %) | bus 2: nadir/100 MW (5–95 %) | random bus: RoCoF/100 MW (5–95 %) | random bus: nadir/100 MW (5–95 %) |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for eps in EPS {
        let Some(n) = rows
            .iter()
            .find(|r| r.job.eps == eps && r.job.family == Family::Nominal)
        else {
            continue;
        };
        let (b, r) = (
            spread(rows, eps, Family::Bus2),
            spread(rows, eps, Family::RandomBus),
        );
        out += &format!(
            "| {:.2} | {:.2} % / {:.2} % | {:.1} % / {:.1} % | {:.4} Hz | {:.4} Hz/s | {:.4} Hz/s | {:.2} % | {:.2} pu | {:.3} … {:.3} Hz/s | {:.3} … {:.3} Hz | {:.3} … {:.3} Hz/s | {:.3} … {:.3} Hz |\n",
            eps as f64 / 100.0,
            n.f_nrmse * 100.0,
            n.f_nrmse_transient * 100.0,
            n.v_nrmse * 100.0,
            n.v_nrmse_transient * 100.0,
            n.coi_nadir_hz,
            n.rocof_100,
            n.rocof_500,
            n.v_dc_dev * 100.0,
            n.i_max,
            b.rocof[0],
            b.rocof[1],
            b.nadir[0],
            b.nadir[1],
            r.rocof[0],
            r.rocof[1],
            r.nadir[0],
            r.nadir[1],
        );
    }
    let runs = rows
        .iter()
        .filter(|r| r.job.eps == EPS[0] && r.job.family == Family::Bus2)
        .count();
    out += &format!(
        "\nNominal: the 42 MW step at bus 2, 20 s. Monte Carlo: {runs} runs of 10 s per family and ε, the same draws for every ε.\n"
    );
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

/// `cargo xtask sweep [--runs N] [--seed S]`: `runs` Monte Carlo runs per family and ε
/// (default [`RUNS`], seed [`SEED`]; with both the defaults it rewrites the table of
/// docs/case-studies.md).
pub fn sweep(root: &Path, args: &[String]) -> Result<(), String> {
    let mut runs = RUNS;
    let mut seed = SEED;
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
        "sweep: {} runs (ε in {EPS:?} %: the nominal 20 s run and {runs} Monte Carlo runs of {T_RUN} s per family, seed {seed}) on {workers} threads",
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
    let table = table(&rows);
    println!("{table}");
    if failed.is_empty() && (runs, seed) == (RUNS, SEED) {
        crate::docs::update_between(
            root,
            crate::docs::CASE_STUDIES,
            "<!-- case2:begin -->",
            "<!-- case2:end -->",
            &table,
        )?;
        println!("sweep: updated the table in {}", crate::docs::CASE_STUDIES);
    }
    println!(
        "sweep: {} runs in {wall:.0} s on {workers} threads; {} failed; {} and the figure tests/figures/case2_distributions.svg",
        rows.len(),
        failed.len(),
        csv.display()
    );
    for r in failed.iter().take(5) {
        println!(
            "  ε = {}, {} run {}: {}",
            r.job.eps as f64 / 100.0,
            r.job.family.name(),
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
