//! `cosim`: run FMUs headless and write their results as CSV.

use dvpp_cosim::{run::simulate_alone, Fmu};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;

const USAGE: &str = "usage: cosim FILE.fmu [--stop T] [--step H] [--out FILE.csv]

Simulates one FMU on its own (inputs held at their start values) over its default experiment
and writes every Real output to FILE.csv (default: <model identifier>.csv).";

struct Args {
    fmu: PathBuf,
    stop: Option<f64>,
    step: Option<f64>,
    out: Option<PathBuf>,
}

fn parse() -> Result<Args, String> {
    let mut it = std::env::args().skip(1);
    let mut args = Args {
        fmu: PathBuf::new(),
        stop: None,
        step: None,
        out: None,
    };
    let number = |flag: &str, v: Option<String>| -> Result<f64, String> {
        let v = v.ok_or(format!("{flag} needs a value"))?;
        v.parse::<f64>()
            .ok()
            .filter(|x| x.is_finite() && *x > 0.0)
            .ok_or(format!("{flag} {v}: not a positive number"))
    };
    while let Some(a) = it.next() {
        match a.as_str() {
            "--stop" => args.stop = Some(number("--stop", it.next())?),
            "--step" => args.step = Some(number("--step", it.next())?),
            "--out" => args.out = Some(it.next().ok_or("--out needs a file")?.into()),
            "-h" | "--help" => return Err(USAGE.into()),
            s if s.starts_with('-') => return Err(format!("unknown option {s}\n\n{USAGE}")),
            _ if args.fmu.as_os_str().is_empty() => args.fmu = a.into(),
            _ => return Err(format!("unexpected argument {a}\n\n{USAGE}")),
        }
    }
    if args.fmu.as_os_str().is_empty() {
        return Err(USAGE.into());
    }
    Ok(args)
}

fn main() -> ExitCode {
    let result = parse().and_then(|args| {
        let fmu = Arc::new(Fmu::load(&args.fmu).map_err(|e| e.to_string())?);
        let table = simulate_alone(&fmu, args.stop, args.step, true).map_err(|e| e.to_string())?;
        let id = fmu
            .description
            .model_identifier()
            .unwrap_or("result")
            .to_owned();
        let out = args
            .out
            .unwrap_or_else(|| PathBuf::from(format!("{id}.csv")));
        table
            .write_csv(&out)
            .map_err(|e| format!("{}: {e}", out.display()))?;
        println!(
            "{}: {} steps, {} outputs -> {}",
            id,
            table.rows.len() - 1,
            table.columns.len() - 1,
            out.display()
        );
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
