//! `cosim`: run an SSP system (or one FMU on its own) headless; write the results as CSV and plot.

use dvpp_cosim::master::{self, Algorithm, Options};
use dvpp_cosim::plot::{Figure, Panel, Style};
use dvpp_cosim::run::{simulate_alone, Table};
use dvpp_cosim::Fmu;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

const USAGE: &str = "usage: cosim SYSTEM.ssp|SYSTEM_DIR|FILE.fmu [--stop T] [--step H]
             [--algorithm jacobi|gauss-seidel] [--out FILE.csv]
             [--plot FILE.svg] [--signals component.variable,...]

Simulates an SSP system (an .ssp archive, a directory with SystemStructure.ssd, or an .ssd file)
from its DefaultExperiment and OSP step size, or one FMU on its own (inputs held at their start
values), and writes every output to FILE.csv (default: <system name>.csv): a `time` column, then
one `component.variable` column per output. --plot draws the --signals (default: the first six
columns) against time as an SVG figure.";

#[derive(Default)]
struct Args {
    system: PathBuf,
    opts: Options,
    out: Option<PathBuf>,
    plot: Option<PathBuf>,
    signals: Vec<String>,
}

fn parse() -> Result<Args, String> {
    let mut it = std::env::args().skip(1);
    let mut args = Args::default();
    let number = |flag: &str, v: Option<String>| -> Result<f64, String> {
        let v = v.ok_or(format!("{flag} needs a value"))?;
        v.parse::<f64>()
            .ok()
            .filter(|x| x.is_finite() && *x > 0.0)
            .ok_or(format!("{flag} {v}: not a positive number"))
    };
    while let Some(a) = it.next() {
        match a.as_str() {
            "--stop" => args.opts.stop = Some(number("--stop", it.next())?),
            "--step" => args.opts.step = Some(number("--step", it.next())?),
            "--algorithm" => {
                let v = it
                    .next()
                    .ok_or("--algorithm needs jacobi or gauss-seidel")?;
                args.opts.algorithm = v.parse::<Algorithm>().map_err(|e| e.to_string())?;
            }
            "--out" => args.out = Some(it.next().ok_or("--out needs a file")?.into()),
            "--plot" => args.plot = Some(it.next().ok_or("--plot needs a file")?.into()),
            "--signals" => {
                let v = it.next().ok_or("--signals needs a list")?;
                args.signals = v.split(',').map(str::trim).map(String::from).collect();
            }
            "-h" | "--help" => return Err(USAGE.into()),
            s if s.starts_with('-') => return Err(format!("unknown option {s}\n\n{USAGE}")),
            _ if args.system.as_os_str().is_empty() => args.system = a.into(),
            _ => return Err(format!("unexpected argument {a}\n\n{USAGE}")),
        }
    }
    if args.system.as_os_str().is_empty() {
        return Err(USAGE.into());
    }
    Ok(args)
}

/// Plot `signals` (all of them existing columns) of `table` against time.
fn plot(table: &Table, signals: &[String], title: &str, path: &Path) -> Result<(), String> {
    let time = table.column("time").ok_or("no time column")?;
    let mut panel = Panel::new(title, "time (s)", "value");
    for s in signals {
        let y = table
            .column(s)
            .ok_or_else(|| format!("--signals: no column '{s}' (see the CSV header)"))?;
        panel = panel.series(s.as_str(), &time, &y, Style::Solid);
    }
    Figure::new(title)
        .panel(panel)
        .save(path)
        .map_err(|e| format!("{}: {e}", path.display()))
}

fn main() -> ExitCode {
    // Like other command-line tools, end quietly when the reader of stdout goes away
    // (`cosim ... | head`) instead of panicking in println!.
    // SAFETY: restores the default disposition of SIGPIPE before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let result = parse().and_then(|mut args| {
        args.opts.progress = true;
        let is_fmu = args.system.extension().is_some_and(|e| e == "fmu");
        let (name, table) = if is_fmu {
            let fmu = Arc::new(Fmu::load(&args.system).map_err(|e| e.to_string())?);
            let table = simulate_alone(&fmu, args.opts.stop, args.opts.step, true)
                .map_err(|e| e.to_string())?;
            let id = fmu.description.model_identifier().unwrap_or("result");
            (id.to_owned(), table)
        } else {
            let stem = args
                .system
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("system")
                .to_owned();
            let outcome = master::run(&args.system, &args.opts).map_err(|e| e.to_string())?;
            if !outcome.warnings.is_empty() {
                eprintln!("cosim: {} warning(s), see above", outcome.warnings.len());
            }
            let simulated = outcome.table.rows.last().map_or(0.0, |r| r[0])
                - outcome.table.rows.first().map_or(0.0, |r| r[0]);
            let run = outcome.run_time.as_secs_f64();
            println!(
                "{stem}: loaded in {:.3} s; initialized and simulated {simulated} s in {run:.3} s ({:.0}x real time)",
                outcome.load_time.as_secs_f64(),
                simulated / run
            );
            (stem, outcome.table)
        };
        let out = args
            .out
            .unwrap_or_else(|| PathBuf::from(format!("{name}.csv")));
        table
            .write_csv(&out)
            .map_err(|e| format!("{}: {e}", out.display()))?;
        println!(
            "{name}: {} steps, {} columns -> {}",
            table.rows.len().saturating_sub(1),
            table.columns.len() - 1,
            out.display()
        );
        if let Some(path) = &args.plot {
            let signals = if args.signals.is_empty() {
                table.columns.iter().skip(1).take(6).cloned().collect()
            } else {
                args.signals.clone()
            };
            plot(&table, &signals, &name, path)?;
            println!("plot -> {}", path.display());
        }
        Ok(())
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("cosim: {e}");
            ExitCode::FAILURE
        }
    }
}
