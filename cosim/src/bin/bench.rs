//! `bench`: nanoseconds per `fmi2DoStep` of bundled FMUs, and per macro step of whole systems in
//! our master, measured one after another in one run.
//!
//! An argument `LABEL|FMU|H|NAME=VALUE,...` measures one FMU (the values set before
//! initialization); `system|LABEL|PATH|STOP` runs the SSP system at PATH to STOP s with each
//! algorithm and no observer (best of three), Jacobi on 2 threads, and once with its results
//! streamed to a CSV file. `scale|FMU|N,N,...|UNIT_STEPS` builds systems of N components of FMU
//! each (every output recorded, inputs held at their start values) and runs each N with shared
//! and separate binaries on 1 and 2 threads, each run a process of its own (for its peak RSS),
//! UNIT_STEPS / N steps of 1 ms, five runs interleaved: µs per macro step, the linear fit
//! of cost against N, load time, peak RSS, the 2-thread speed-up and its serial part
//! (docs/scaling.md). `results|LABEL|PATH|STOP` runs the system with no output, with its
//! default record set and with every output, each to CSV and to `.mat`, five rounds
//! interleaved: the best µs per step of each, its ratio to no output and the file's size
//! (docs/results.md).

#[path = "bench/scale.rs"]
mod scale;

use dvpp_cosim::master::{
    self, CsvWriter, End, MatWriter, Observer, Options, Record, Scheme, Select,
};
use dvpp_cosim::{Fmu, Status};
use model_description::BaseType;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::{Duration, Instant};

fn measure(spec: &str) -> Result<(String, f64, usize), String> {
    let parts: Vec<&str> = spec.split('|').collect();
    let [label, path, h, sets] = parts.as_slice() else {
        return Err(format!(
            "bad benchmark '{spec}': expected LABEL|FMU|H|NAME=VALUE,..."
        ));
    };
    let h: f64 = h.parse().map_err(|_| format!("{label}: bad step '{h}'"))?;
    let fmu = Arc::new(Fmu::load(std::path::Path::new(path)).map_err(|e| e.to_string())?);
    // Fresh instances of at most RUN steps each (timed apart from their initialization), until
    // half a second of stepping: a unit run alone with held inputs may drift out of the range it
    // is meant for (the grid with its DVPP slots held is an unstable system after a minute).
    const RUN: usize = 20_000;
    let mut stepping = Duration::ZERO;
    let mut steps = 0usize;
    while stepping < Duration::from_millis(500) {
        let mut i = initialized(&fmu, label, sets)?;
        let mut t = 0.0;
        for _ in 0..1000 {
            check(i.do_step(t, h), label, "step", &i)?;
            t += h;
        }
        let start = Instant::now();
        for _ in 0..RUN / 1000 - 1 {
            for _ in 0..1000 {
                check(i.do_step(t, h), label, "step", &i)?;
                t += h;
            }
            steps += 1000;
            if stepping + start.elapsed() >= Duration::from_millis(500) {
                break;
            }
        }
        stepping += start.elapsed();
    }
    Ok((
        label.to_string(),
        stepping.as_nanos() as f64 / steps as f64,
        steps,
    ))
}

/// `Err` naming the benchmark, the call and the FMU's last message above a warning.
fn check(s: Status, label: &str, what: &str, i: &dvpp_cosim::Instance) -> Result<(), String> {
    if s > Status::Warning {
        Err(format!("{label}: {what}: {:?}", i.last_message()))
    } else {
        Ok(())
    }
}

/// An instance of `fmu` with the `NAME=VALUE,...` settings `sets`, initialized at t = 0.
fn initialized(fmu: &Arc<Fmu>, label: &str, sets: &str) -> Result<dvpp_cosim::Instance, String> {
    let mut i = fmu.instantiate(label).map_err(|e| e.to_string())?;
    for set in sets.split(',').filter(|s| !s.is_empty()) {
        let (name, value) = set
            .split_once('=')
            .ok_or(format!("{label}: bad setting '{set}'"))?;
        let var = fmu
            .description
            .variable(name)
            .ok_or(format!("{label}: no variable '{name}'"))?;
        let x: f64 = value
            .parse()
            .map_err(|_| format!("{label}: bad value '{value}'"))?;
        let vr = [var.value_reference];
        let s = match var.base_type() {
            BaseType::Integer => i.set_integer(&vr, &[x as i32]),
            BaseType::Boolean => i.set_boolean(&vr, &[x != 0.0]),
            _ => i.set_real(&vr, &[x]),
        };
        if s != Status::Ok {
            return Err(format!("{label}: setting {name}: {:?}", i.last_message()));
        }
    }
    check(i.setup_experiment(0.0, None), label, "setup", &i)?;
    check(i.enter_initialization_mode(), label, "enter init", &i)?;
    check(i.exit_initialization_mode(), label, "exit init", &i)?;
    Ok(i)
}

/// Nanoseconds per macro step of one run of `path` to `stop` with `scheme`, `threads` and
/// `observers`.
fn macro_step(
    path: &std::path::Path,
    stop: f64,
    scheme: Scheme,
    threads: usize,
    observers: &mut [&mut dyn Observer],
) -> Result<(f64, u64), String> {
    let opts = Options {
        stop: Some(stop),
        algorithm: scheme,
        ..Options::default()
    };
    let outcome = master::System::builder(path)
        .threads(threads)
        .run(&opts, observers)
        .map_err(|e| e.to_string())?;
    if outcome.end != End::Completed {
        return Err(format!("{}: {:?}", path.display(), outcome.end));
    }
    let steps = outcome.samples.saturating_sub(1).max(1);
    Ok((outcome.run_time.as_nanos() as f64 / steps as f64, steps))
}

/// `system|LABEL|PATH|STOP`: rows per algorithm (best of three, no observer) and with a CSV.
fn measure_system(spec: &str) -> Result<Vec<(String, f64, u64)>, String> {
    let parts: Vec<&str> = spec.split('|').collect();
    let [_, label, path, stop] = parts.as_slice() else {
        return Err(format!(
            "bad benchmark '{spec}': expected system|LABEL|PATH|STOP"
        ));
    };
    let stop: f64 = stop
        .parse()
        .map_err(|_| format!("{label}: bad stop '{stop}'"))?;
    let path = std::path::Path::new(path);
    let mut rows = Vec::new();
    for (scheme, threads) in [
        (Scheme::Jacobi, 1),
        (Scheme::GaussSeidel, 1),
        (Scheme::Jacobi, 2),
    ] {
        let mut best = (f64::INFINITY, 0);
        for _ in 0..3 {
            let (ns, steps) = macro_step(path, stop, scheme, threads, &mut [])?;
            if ns < best.0 {
                best = (ns, steps);
            }
        }
        let on = if threads > 1 {
            format!(", {threads} threads")
        } else {
            String::new()
        };
        rows.push((format!("{label} ({scheme:?}{on})"), best.0, best.1));
    }
    let scratch = dvpp_cosim::tmp::TempDir::new("bench").map_err(|e| e.to_string())?;
    let csv = scratch.path().join("bench.csv");
    let mut writer = CsvWriter::new(&csv);
    let (ns, steps) = macro_step(path, stop, Scheme::Jacobi, 1, &mut [&mut writer])?;
    rows.push((format!("{label} (Jacobi, streamed CSV)"), ns, steps));
    Ok(rows)
}

/// An observer that takes every point and keeps nothing: what reading the outputs costs.
struct Discard;

impl Observer for Discard {
    fn start(&mut self, _: &master::RunInfo) -> Result<(), master::Error> {
        Ok(())
    }
    fn sample(&mut self, row: &[f64]) -> Result<(), master::Error> {
        std::hint::black_box(row);
        Ok(())
    }
    fn finish(&mut self, _: &End) -> Result<(), master::Error> {
        Ok(())
    }
}

/// `results|LABEL|PATH|STOP`: the cost of recording, side by side (see the module docs).
fn measure_results(spec: &str) -> Result<(), String> {
    let parts: Vec<&str> = spec.split('|').collect();
    let [_, label, path, stop] = parts.as_slice() else {
        return Err(format!(
            "bad benchmark '{spec}': expected results|LABEL|PATH|STOP"
        ));
    };
    let stop: f64 = stop
        .parse()
        .map_err(|_| format!("{label}: bad stop '{stop}'"))?;
    let path = std::path::Path::new(path);
    let scratch = dvpp_cosim::tmp::TempDir::new("bench-results").map_err(|e| e.to_string())?;
    const KINDS: [(&str, bool, bool); 6] = [
        ("no output", false, false),
        ("every output read, none written", true, false),
        ("default set, CSV", false, true),
        ("default set, .mat", false, false),
        ("every output, CSV", true, true),
        ("every output, .mat", true, false),
    ];
    let mut best = [f64::INFINITY; KINDS.len()];
    let mut size = [0u64; KINDS.len()];
    let mut columns = [0usize; KINDS.len()];
    for _ in 0..5 {
        for (k, (_, all, csv)) in KINDS.iter().enumerate() {
            let record = if *all {
                Record::parse("all")
            } else {
                Record::system_default()
            };
            let file = scratch
                .path()
                .join(format!("r{k}.{}", if *csv { "csv" } else { "mat" }));
            let (ns, cols) = if k == 0 {
                (macro_step(path, stop, Scheme::Jacobi, 1, &mut [])?.0, 0)
            } else if k == 1 {
                let mut w = Select::new(Discard, record);
                let ns = macro_step(path, stop, Scheme::Jacobi, 1, &mut [&mut w])?.0;
                (ns, w.columns().len())
            } else if *csv {
                let mut w = Select::new(CsvWriter::new(&file), record);
                let ns = macro_step(path, stop, Scheme::Jacobi, 1, &mut [&mut w])?.0;
                (ns, w.columns().len())
            } else {
                let mut w = Select::new(MatWriter::new(&file), record);
                let ns = macro_step(path, stop, Scheme::Jacobi, 1, &mut [&mut w])?.0;
                (ns, w.columns().len())
            };
            best[k] = best[k].min(ns);
            columns[k] = cols;
            size[k] = std::fs::metadata(&file).map_or(0, |m| m.len());
        }
    }
    println!("\nresults: {label} to {stop} s (best of 5, interleaved)");
    println!("| recording | columns | µs per step | speed against no output | file size |");
    println!("|---|---:|---:|---:|---:|");
    for (k, (what, _, _)) in KINDS.iter().enumerate() {
        println!(
            "| {what} | {} | {:.2} | {:.2}× | {:.1} MB |",
            columns[k],
            best[k] / 1e3,
            best[0] / best[k],
            size[k] as f64 / 1e6
        );
    }
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    // A child of `scale`: one run, one line of results on stdout.
    if let [first, spec] = args.as_slice() {
        if first == scale::CHILD {
            return match scale::child(spec) {
                Ok(line) => {
                    println!("{line}");
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("bench: {e}");
                    ExitCode::FAILURE
                }
            };
        }
    }
    println!("{:<48} {:>14} {:>10}", "benchmark", "ns/step", "steps");
    let mut failed = false;
    for spec in args {
        if spec.starts_with("scale|") {
            if let Err(e) = scale::measure(&spec) {
                eprintln!("bench: {e}");
                failed = true;
            }
            continue;
        }
        if spec.starts_with("results|") {
            if let Err(e) = measure_results(&spec) {
                eprintln!("bench: {e}");
                failed = true;
            }
            continue;
        }
        if spec.starts_with("system|") {
            match measure_system(&spec) {
                Ok(rows) => {
                    for (label, ns, steps) in rows {
                        println!("{label:<48} {ns:>14.1} {steps:>10}");
                    }
                }
                Err(e) => {
                    eprintln!("bench: {e}");
                    failed = true;
                }
            }
            continue;
        }
        match measure(&spec) {
            Ok((label, ns, steps)) => println!("{label:<48} {ns:>14.1} {steps:>10}"),
            Err(e) => {
                eprintln!("bench: {e}");
                failed = true;
            }
        }
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}
