//! `cargo xtask ride-through`: case study I's DVPP at EMT level (`emt_thevenin`) through the grid codes' events, per inner-control option, mode and short-circuit ratio, in our master with the EMT plant's test bench: one CSV, the table of docs/emt-unit.md and a figure.
//!
//! Each run is the bundled `emt_thevenin` (option A) or `emt_thevenin_hinf` (option B) with
//! its 28 MW load step disabled, the swinging source made stiff (`thevenin.H` = 0) and its
//! impedance set for the short-circuit ratio on the DVPP's rating (`|Z_th| = S_base/(SCR S_dvpp)`,
//! X/R 10); one event at [`T_EVENT`] and the run to [`T_END`]. Grid-following runs set `mode` = 2
//! and `vq.tau` = 2 s on every unit (docs/emt.md §9: 0.5 s is not stable below SCR 3).
//!
//! What is measured, per run:
//! - *rides through*: the run completes (no unit stops with an error), no unit's frame slips a
//!   pole against the grid (its angle against the grid's, `∫2π(f - f_grid)dt` from the event
//!   on, stays within ±π: [`slip`](Row::slip)), and every unit's frequency is within
//!   [`SYNC_HZ`] of the grid's over the last [`TAIL`] s (synchronism kept);
//! - the largest phase current of any unit, converter side, over its `I_max` (1.2 pu);
//! - the DVPP's active and reactive current while the event lasts (dips and faults: mean of
//!   `Σp/v`, `Σq/v` from 50 ms after the event to its clearing, pu of `S_dvpp`);
//! - recovery: from the event's end, the time until the DVPP's active power stays within 5 % of
//!   `S_dvpp` of its value at the end of the run;
//! - the energy account: the plant's ac balance residual over the run, relative to the energy
//!   the source and the converters exchanged.

use dvpp_cosim::master::{self, Options, Record, Scheme};
use dvpp_cosim::ssp::{self, Value};
use dvpp_cosim::table::csv_field;
use dvpp_cosim::Table;
use dvpp_report::plot::{Figure, Panel, Style};
use std::fmt::Write as _;
use std::path::Path;

/// When the event starts and when a run ends, s.
pub const T_EVENT: f64 = 1.0;
pub const T_END: f64 = 3.5;
/// Synchronism: each unit's frequency within this of the grid's over the last `TAIL` s, Hz.
pub const SYNC_HZ: f64 = 0.05;
pub const TAIL: f64 = 0.5;
/// The recovery band: the DVPP's active power within this fraction of `S_dvpp` of its final value.
pub const RECOVERY_BAND: f64 = 0.05;
/// The units' current limit (pu of their rated peak current: the FMU's default `I_max`).
const I_MAX: f64 = 1.2;
/// The DVPP's rating and the system base (MVA), as in `emt_thevenin`.
const S_DVPP: f64 = 96.0;
const S_BASE: f64 = 100.0;
const F_NOM: f64 = 50.0;
/// The units of `emt_thevenin`, in the plant's order.
const UNITS: [&str; 3] = ["wind", "pv", "bess"];

/// The short-circuit ratios on the DVPP's rating.
pub const SCRS: [f64; 3] = [10.0, 3.0, 1.5];

/// One event of the grid codes' tests, as the plant's test bench sets it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Event {
    /// The source's voltage dips to `retained` for 150 ms.
    Dip { retained: f64 },
    /// A fault at the PCC through 0.01 + j0.01 pu per phase for 150 ms: `fault.type` 1
    /// (three-phase), 2 (phase a to ground), 3 (phases b-c).
    Fault { kind: i64 },
    /// The source's phase jumps by `deg`.
    Jump { deg: f64 },
    /// The source's frequency ramps at `rate` Hz/s for 0.4 s.
    Rocof { rate: f64 },
}

/// How long dips and faults last, and how long a frequency ramp runs, s.
const DURATION: f64 = 0.15;
const RAMP: f64 = 0.4;

impl Event {
    /// The events of the table.
    pub const ALL: [Event; 9] = [
        Event::Dip { retained: 0.5 },
        Event::Dip { retained: 0.1 },
        Event::Fault { kind: 1 },
        Event::Fault { kind: 2 },
        Event::Fault { kind: 3 },
        Event::Jump { deg: 25.0 },
        Event::Jump { deg: -25.0 },
        Event::Rocof { rate: 5.0 },
        Event::Rocof { rate: -5.0 },
    ];

    pub fn name(self) -> String {
        match self {
            Event::Dip { retained } => format!("dip to {retained} pu, 150 ms"),
            Event::Fault { kind } => format!(
                "{} fault at the PCC, 150 ms",
                match kind {
                    1 => "three-phase",
                    2 => "phase-a-to-ground",
                    _ => "phase-b-to-c",
                }
            ),
            Event::Jump { deg } => format!("phase jump {deg:+}°"),
            Event::Rocof { rate } => format!("{rate:+} Hz/s for {RAMP} s"),
        }
    }

    /// When the event is over (s): a dip or fault cleared, a jump at once, a ramp at its end.
    fn end(self) -> f64 {
        match self {
            Event::Dip { .. } | Event::Fault { .. } => T_EVENT + DURATION,
            Event::Jump { .. } => T_EVENT,
            Event::Rocof { .. } => T_EVENT + RAMP,
        }
    }

    /// Whether it holds the voltage down (the window of the fault current).
    fn holds_voltage_down(self) -> bool {
        matches!(self, Event::Dip { .. } | Event::Fault { .. })
    }

    /// The plant's start values for it.
    fn plant_values(self) -> Vec<(&'static str, Value)> {
        match self {
            Event::Dip { retained } => vec![
                ("thevenin.dip", Value::Real(1.0 - retained)),
                ("thevenin.dip_t", Value::Real(T_EVENT)),
                ("thevenin.dip_duration", Value::Real(DURATION)),
            ],
            Event::Fault { kind } => vec![
                ("fault.type", Value::Integer(kind)),
                ("fault.location", Value::Integer(1)),
                ("fault.R", Value::Real(0.01)),
                ("fault.X", Value::Real(0.01)),
                ("fault.t", Value::Real(T_EVENT)),
                ("fault.duration", Value::Real(DURATION)),
            ],
            Event::Jump { deg } => vec![
                ("thevenin.jump", Value::Real(deg.to_radians())),
                ("thevenin.jump_t", Value::Real(T_EVENT)),
            ],
            Event::Rocof { rate } => vec![
                ("thevenin.rocof", Value::Real(rate)),
                ("thevenin.rocof_t", Value::Real(T_EVENT)),
                ("thevenin.rocof_duration", Value::Real(RAMP)),
            ],
        }
    }
}

/// The units' control: grid-forming with option A or B, or grid-following.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Control {
    FormingA,
    FormingB,
    Following,
}

impl Control {
    pub const ALL: [Control; 3] = [Control::FormingA, Control::FormingB, Control::Following];

    pub fn name(self) -> &'static str {
        match self {
            Control::FormingA => "grid-forming, option A",
            Control::FormingB => "grid-forming, option B",
            Control::Following => "grid-following",
        }
    }

    /// The bundled system it starts from.
    fn system(self) -> &'static str {
        match self {
            Control::FormingB => "emt_thevenin_hinf",
            _ => "emt_thevenin",
        }
    }
}

/// One run.
#[derive(Debug, Clone, Copy)]
pub struct Job {
    pub event: Event,
    pub control: Control,
    pub scr: f64,
}

/// What one run measured.
#[derive(Debug, Clone)]
pub struct Row {
    pub job: Job,
    pub rides_through: bool,
    /// The largest unit's frequency offset from the grid's over the last `TAIL` s, Hz.
    pub sync_hz: f64,
    /// The largest excursion of a unit's angle against the grid's from the event on (rad): a
    /// frame that slips a pole passes π.
    pub slip: f64,
    pub i_peak: f64,
    pub i_active: f64,
    pub i_reactive: f64,
    pub recovery: f64,
    pub energy_residual: f64,
    /// Why the run stopped, if it did.
    pub error: Option<String>,
    /// Traces for the figure: time, the grid's frequency and each unit's (Hz), the DVPP's
    /// active power (pu of S_dvpp), every 1 ms.
    pub traces: Traces,
}

#[derive(Debug, Clone, Default)]
pub struct Traces {
    pub t: Vec<f64>,
    pub f_grid: Vec<f64>,
    pub f_units: Vec<Vec<f64>>,
    pub p: Vec<f64>,
}

impl Job {
    /// Its name: event, control and SCR.
    pub fn name(&self) -> String {
        format!(
            "{}, {}, SCR {}",
            self.event.name(),
            self.control.name(),
            self.scr
        )
    }
}

/// Every run of the table.
pub fn jobs() -> Vec<Job> {
    let mut out = Vec::new();
    for control in Control::ALL {
        for scr in SCRS {
            for event in Event::ALL {
                out.push(Job {
                    event,
                    control,
                    scr,
                });
            }
        }
    }
    out
}

pub(crate) fn set(
    pkg: &mut ssp::Package,
    component: &str,
    name: &str,
    value: Value,
) -> Result<(), String> {
    crate::sweep::set_start(pkg, component, name, value)
}

/// The system of `job`.
fn prepare(base: &ssp::Package, job: &Job) -> Result<ssp::Package, String> {
    let mut pkg = base.with_system(base.system.clone());
    let z = S_BASE / (job.scr * S_DVPP);
    let (r, x) = (z / 101f64.sqrt(), 10.0 * z / 101f64.sqrt());
    for (name, value) in [
        ("load[2].enabled", Value::Boolean(false)),
        ("thevenin.H", Value::Real(0.0)),
        ("thevenin.D", Value::Real(0.0)),
        ("thevenin.R", Value::Real(r)),
        ("thevenin.X", Value::Real(x)),
    ] {
        set(&mut pkg, "plant", name, value)?;
    }
    for (name, value) in job.event.plant_values() {
        set(&mut pkg, "plant", name, value)?;
    }
    if job.control == Control::Following {
        for u in UNITS {
            set(&mut pkg, u, "mode", Value::Integer(2))?;
            set(&mut pkg, u, "vq.tau", Value::Real(2.0))?;
        }
    }
    Ok(pkg)
}

/// The recorded outputs.
fn record() -> Record {
    let mut patterns = vec![
        "plant.der[*].i_*".to_string(),
        "plant.der[*].p".into(),
        "plant.der[*].q".into(),
        "plant.der[*].v_dc".into(),
        "plant.pcc.v".into(),
        "plant.thevenin.f".into(),
        "plant.energy.*".into(),
    ];
    patterns.extend(UNITS.iter().map(|u| format!("{u}.df")));
    patterns.extend(UNITS.iter().map(|u| format!("{u}.limit.*")));
    Record {
        patterns: Some(patterns),
        interval: None,
    }
}

pub(crate) fn at(t: &[f64], time: f64) -> usize {
    t.partition_point(|&s| s < time - 1e-9).min(t.len() - 1)
}

fn measure(job: Job, table: Result<Table, String>) -> Row {
    let mut row = Row {
        job,
        rides_through: false,
        sync_hz: f64::NAN,
        slip: f64::NAN,
        i_peak: f64::NAN,
        i_active: f64::NAN,
        i_reactive: f64::NAN,
        recovery: f64::NAN,
        energy_residual: f64::NAN,
        error: None,
        traces: Traces::default(),
    };
    let measured = table.and_then(|t| {
        let col = |n: &str| t.column(n).ok_or(format!("no column {n}"));
        let time = col("time")?;
        let n = time.len();
        let f_grid: Vec<f64> = col("plant.thevenin.f")?.iter().map(|f| f * F_NOM).collect();
        let mut f_units = Vec::new();
        let mut i_peak = 0.0_f64;
        let (mut p, mut q) = (vec![0.0; n], vec![0.0; n]);
        for (k, u) in UNITS.iter().enumerate() {
            let df = col(&format!("{u}.df"))?;
            f_units.push(df.iter().map(|d| (1.0 + d) * F_NOM).collect::<Vec<_>>());
            for ph in ["a", "b", "c"] {
                let i = col(&format!("plant.der[{}].i_{ph}", k + 1))?;
                i_peak = i.iter().fold(i_peak, |m, x| m.max(x.abs()));
            }
            for (sum, name) in [(&mut p, "p"), (&mut q, "q")] {
                for (s, x) in sum
                    .iter_mut()
                    .zip(col(&format!("plant.der[{}].{name}", k + 1))?)
                {
                    *s += x * S_BASE / S_DVPP;
                }
            }
        }
        row.i_peak = i_peak / I_MAX;
        let tail = at(&time, T_END - TAIL);
        row.sync_hz = f_units
            .iter()
            .map(|f| {
                (tail..n)
                    .map(|k| (f[k] - f_grid[k]).abs())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        if job.event.holds_voltage_down() {
            let v = col("plant.pcc.v")?;
            let (a, b) = (at(&time, T_EVENT + 0.05), at(&time, job.event.end()));
            let m = (b - a).max(1) as f64;
            row.i_active = (a..b).map(|k| p[k] / v[k].max(1e-3)).sum::<f64>() / m;
            row.i_reactive = (a..b).map(|k| q[k] / v[k].max(1e-3)).sum::<f64>() / m;
        }
        let last = at(&time, T_END - 0.2);
        let p_end = p[last..].iter().sum::<f64>() / (n - last) as f64;
        let from = at(&time, job.event.end());
        let outside = (from..n)
            .rev()
            .find(|&k| (p[k] - p_end).abs() > RECOVERY_BAND);
        row.recovery = outside.map_or(0.0, |k| time[k] - job.event.end());
        let e = |name: &str| col(&format!("plant.energy.{name}"));
        let (ac, th, loss, loads, fault, sw, stored) = (
            e("ac")?,
            e("thevenin")?,
            e("ac_loss")?,
            e("loads")?,
            e("fault")?,
            e("switching")?,
            e("ac_stored")?,
        );
        let k = n - 1;
        let residual =
            ac[k] + th[k] - loss[k] - loads[k] - fault[k] - sw[k] - (stored[k] - stored[0]);
        let scale = ac
            .iter()
            .chain(th.iter())
            .fold(0.0_f64, |m, x| m.max(x.abs()))
            .max(1e-12);
        row.energy_residual = residual.abs() / scale;
        let start = at(&time, T_EVENT);
        row.slip = f_units
            .iter()
            .map(|f| {
                let mut angle = 0.0_f64;
                let mut largest = 0.0_f64;
                for k in start + 1..n {
                    let dt = time[k] - time[k - 1];
                    angle += 2.0 * std::f64::consts::PI * (f[k] - f_grid[k]) * dt;
                    largest = largest.max(angle.abs());
                }
                largest
            })
            .fold(0.0, f64::max);
        row.rides_through = row.sync_hz <= SYNC_HZ && row.slip < std::f64::consts::PI;
        let every = at(&time, 1e-3).max(1);
        row.traces = Traces {
            t: time.iter().step_by(every).copied().collect(),
            f_grid: f_grid.iter().step_by(every).copied().collect(),
            f_units: f_units
                .iter()
                .map(|f| f.iter().step_by(every).copied().collect())
                .collect(),
            p: p.iter().step_by(every).copied().collect(),
        };
        Ok(())
    });
    row.error = measured.err();
    row
}

/// Run `jobs` on `workers` threads with progress, from the bundled systems under `root/dist/`;
/// rows in job order.
pub fn run_all(
    root: &Path,
    jobs: Vec<Job>,
    workers: usize,
    keep: Option<&Path>,
) -> Result<Vec<Row>, String> {
    let mut bases = Vec::new();
    for control in [Control::FormingA, Control::FormingB] {
        let name = control.system();
        let path = root.join("dist").join(name).join(format!("{name}.ssp"));
        bases.push((
            name,
            ssp::read(&path)
                .map_err(|e| format!("{}: {e} (run `cargo xtask bundle`)", path.display()))?,
        ));
    }
    crate::parallel::in_order("ride-through", jobs, workers, 9, |job: Job| {
        let base = &bases
            .iter()
            .find(|b| b.0 == job.control.system())
            .expect("bundled")
            .1;
        let opts = Options {
            stop: Some(T_END),
            step: None,
            algorithm: Scheme::Jacobi,
        };
        let table = prepare(base, &job).and_then(|pkg| {
            master::System::builder(&pkg)
                .load()
                .and_then(|mut s| {
                    s.quiet();
                    s.simulate_recording(&opts, record())
                })
                .map_err(|e| e.to_string())
        });
        if let (Some(dir), Ok(t)) = (keep, &table) {
            let path = dir.join(format!("{}.csv", file_name(&job.name())));
            if let Err(e) = write_table(&path, t) {
                eprintln!("ride-through: {}: {e}", path.display());
            }
        }
        measure(job, table)
    })
}

fn number(x: f64, digits: usize) -> String {
    if x.is_finite() {
        format!("{x:.digits$}")
    } else {
        "-".into()
    }
}

/// Why a run stopped, short: the unit and its own message up to its first `;` (the master's
/// message names the component and quotes the unit's).
pub(crate) fn stopped(error: &str) -> String {
    let unit = error
        .split("component '")
        .nth(1)
        .and_then(|r| r.split('\'').next());
    let message = error
        .rsplit("returned Error: ")
        .next()
        .unwrap_or(error)
        .split(';')
        .next()
        .unwrap_or("")
        .lines()
        .next()
        .unwrap_or("");
    let message = message.replace('|', "/");
    match unit {
        Some(u) => format!("{u} stopped: {message}"),
        None => message,
    }
}

/// The table, as Markdown: one row per event and control, the SCRs side by side.
pub fn table(rows: &[Row]) -> String {
    let mut out = String::from(
        "| event | control | SCR | rides through | largest phase current / I_max | active, reactive current in the event (pu of S_dvpp) | recovery (s) | energy residual |\n|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let verdict = match (&r.error, r.rides_through) {
            (Some(e), _) => format!("no: {}", stopped(e)),
            (None, true) => "yes".into(),
            (None, false) if r.slip >= std::f64::consts::PI => format!(
                "no: slipped (angle {:.1} rad from the grid's), {:.2} Hz from it at the end",
                r.slip, r.sync_hz
            ),
            (None, false) => format!("no: {:.2} Hz from the grid at the end", r.sync_hz),
        };
        let currents = if r.job.event.holds_voltage_down() && r.error.is_none() {
            format!("{}, {}", number(r.i_active, 2), number(r.i_reactive, 2))
        } else {
            "".into()
        };
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} |",
            r.job.event.name(),
            r.job.control.name(),
            r.job.scr,
            verdict,
            number(r.i_peak, 2),
            currents,
            number(r.recovery, 2),
            if r.energy_residual.is_finite() {
                format!("{:.0e}", r.energy_residual)
            } else {
                "-".into()
            }
        );
    }
    out
}

fn write_csv(path: &Path, rows: &[Row]) -> Result<(), String> {
    let mut text = String::from(
        "event,control,scr,rides_through,sync_Hz,slip_rad,i_peak_over_i_max,i_active_pu,i_reactive_pu,recovery_s,energy_residual,error\n",
    );
    for r in rows {
        let _ = writeln!(
            text,
            "{},{},{},{},{},{},{},{},{},{},{},{}",
            csv_field(&r.job.event.name()),
            csv_field(r.job.control.name()),
            r.job.scr,
            r.rides_through,
            r.sync_hz,
            r.slip,
            r.i_peak,
            r.i_active,
            r.i_reactive,
            r.recovery,
            r.energy_residual,
            csv_field(r.error.as_deref().unwrap_or(""))
        );
    }
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))
}

/// Frequencies through the 5 Hz/s ramp and the 25° jump at SCR 3, and the DVPP's power after
/// the 0.5 pu dip at SCR 10, per control.
fn figure(rows: &[Row]) -> Figure {
    let find = |event: Event, control: Control, scr: f64| {
        rows.iter()
            .find(|r| r.job.event == event && r.job.control == control && r.job.scr == scr)
    };
    let mut fig = Figure::new("Case study I's DVPP at EMT level through grid-code events");
    for (event, scr) in [
        (Event::Rocof { rate: -5.0 }, 3.0),
        (Event::Jump { deg: 25.0 }, 3.0),
    ] {
        for control in Control::ALL {
            let mut panel = Panel::new(
                format!("{}, SCR {scr}: {}", event.name(), control.name()),
                "t (s)",
                "f (Hz)",
            );
            if let Some(r) = find(event, control, scr).filter(|r| !r.traces.t.is_empty()) {
                let tr = &r.traces;
                panel = panel.series("grid", &tr.t, &tr.f_grid, Style::Dashed);
                for (u, f) in UNITS.iter().zip(&tr.f_units) {
                    panel = panel.series(*u, &tr.t, f, Style::Solid);
                }
            }
            fig = fig.panel(panel);
        }
    }
    let mut panel = Panel::new(
        "dip to 0.5 pu for 150 ms, SCR 10: the DVPP's active power",
        "t (s)",
        "p (pu of S_dvpp)",
    );
    for (control, style) in Control::ALL
        .iter()
        .zip([Style::Solid, Style::Dashed, Style::Dotted])
    {
        if let Some(r) =
            find(Event::Dip { retained: 0.5 }, *control, 10.0).filter(|r| !r.traces.t.is_empty())
        {
            panel = panel.series(control.name(), &r.traces.t, &r.traces.p, style);
        }
    }
    fig.panel(panel).columns(3)
}

/// A run's name as a file name: letters, digits, `.`, `+` and `-`, the rest `_`.
pub(crate) fn file_name(name: &str) -> String {
    name.chars()
        .map(|c| match c {
            'a'..='z' | 'A'..='Z' | '0'..='9' | '.' | '+' | '-' => c,
            _ => '_',
        })
        .collect()
}

/// A run's recorded outputs as CSV.
fn write_table(path: &Path, t: &Table) -> std::io::Result<()> {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    dvpp_cosim::table::write_header(&mut w, &t.columns)?;
    for row in &t.rows {
        dvpp_cosim::table::write_row(&mut w, row)?;
    }
    std::io::Write::flush(&mut w)
}

/// `cargo xtask ride-through [--only TEXT]`: every run, `results/ride_through.csv`, the figure
/// `tests/figures/ride_through.svg` and the table between `ride-through:begin` and
/// `ride-through:end` in docs/emt-unit.md; with `--only`, the runs whose name (event, control,
/// SCR) contains TEXT, each run's recorded outputs in `results/ride_through/`, and no figure or
/// table.
pub fn ride_through(root: &Path, args: &[String]) -> Result<(), String> {
    let (all, only) = crate::parallel::only("ride-through", args, jobs(), Job::name)?;
    let workers = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!(
        "ride-through: {} runs of {T_END} s at 50 µs on {workers} threads",
        all.len()
    );
    std::fs::create_dir_all(root.join("results")).map_err(|e| e.to_string())?;
    if only.is_some() {
        let dir = root.join("results").join("ride_through");
        std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let rows = run_all(root, all, workers, Some(&dir))?;
        print!("{}", table(&rows));
        println!("ride-through: each run's outputs in {}", dir.display());
        return Ok(());
    }
    let rows = run_all(root, all, workers, None)?;
    write_csv(&root.join("results").join("ride_through.csv"), &rows)?;
    crate::sweep::save_figure(root, &figure(&rows), "ride_through.svg")?;
    let table = table(&rows);
    print!("{table}");
    crate::docs::update_between(
        root,
        "docs/emt-unit.md",
        "<!-- ride-through:begin -->",
        "<!-- ride-through:end -->",
        &table,
    )?;
    println!("ride-through: results/ride_through.csv, tests/figures/ride_through.svg and the table in docs/emt-unit.md");
    Ok(())
}
