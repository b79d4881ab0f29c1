//! `cosim`: run an SSP system (or one FMU on its own) headless, streaming the results to CSV.

use dvpp_cosim::federate::{self, FederateOptions, FederationOptions};
use dvpp_cosim::master::{
    self, CsvWriter, End, MatWriter, Observer, Options, Progress, Record, Recorder, Scheme, Select,
    Source, System,
};
use dvpp_cosim::{interrupt, ssp, Table};
use dvpp_report::plot::{Figure, Panel, Style};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

const USAGE: &str = "usage: cosim SYSTEM.ssp|SYSTEM_DIR|SYSTEM.ssd|FILE.fmu [--stop T] [--step H]
             [--algorithm jacobi|gauss-seidel|iterative [--tolerance RTOL]
             [--relaxation W] [--max-iterations N]] [--threads N|all]
             [--out FILE.csv|FILE.mat | --no-csv] [--record PATTERN,...|all]
             [--output-interval T] [--plot FILE.svg] [--signals component.variable,...]
             [--trace DIR]

Simulates an SSP system (an .ssp archive, a directory with SystemStructure.ssd, or an .ssd file)
from its DefaultExperiment and OSP step size, or one FMU on its own (inputs held at their start
values), and streams its outputs to FILE.csv (default: <system name>.csv) as the run goes: a
`time` column, then one `component.variable` column per output (RFC 4180 quoting, full f64
precision); an --out ending in .mat writes a MATLAB v4 result file as Modelica tools do
(scipy.io.loadmat, MATLAB, Modelica result readers; docs/results.md). What is recorded: the
system's default set (the patterns its SSP's record annotation names, which the bundler sets
to what the case-study figures plot; every output if it has none), or --record with
comma-separated `component.variable` patterns (`*` matches any text: grid.pcc.*,*.p,
operator.ref.*; `all` for every output); a pattern that matches nothing, given or the
system's, is an error, every
--output-interval seconds (a whole multiple of the step; default: every step). Jacobi (default) steps every unit from the same inputs; gauss-seidel one after the
other in dependency order; iterative repeats each step from the saved FMU states until the
exchanged values settle (--tolerance: relative, default 1e-2, absolute 1e-3 of it; each new
attempt moves --relaxation (default 1) of the way to the values obtained; at most
--max-iterations, default 30), which removes the exchange delay at the cost of the attempts.
--threads N steps the units of each Jacobi step (and iterative attempt) on N threads (`all`:
one per core; default 1) with results identical bit for bit; it pays where cores are idle
(docs/scaling.md). Components with identical binaries share one loaded library, each with its
own resources. Rows go to FILE.csv.partial (created new; when that name is taken, by another
run writing FILE.csv or by rows an earlier run kept, FILE.csv.<pid>-<n>.partial), renamed to
FILE.csv when the run completes; a run that fails or is stopped by SIGINT/SIGTERM/SIGHUP (at
the next communication point; further signals are ignored while it stops) leaves every
complete row, and never part of one, in its own .partial file, which it names, removes its
unpacked files and exits non-zero (1 on an error, such as a full disk or a file size limit,
128 + the signal's number when interrupted); a device or named pipe (/dev/null) is written in
place (a pipe nothing reads is refused); FILE.csv may not be a directory, the input, inside
an SSP directory given as the input, or a file the system reads. --no-csv
records nothing (benchmarks). --plot draws the --signals (default: the first six columns)
against time as an SVG figure; it keeps the results in memory. --trace DIR writes, per
component, DIR/<component>.trace: every call the master makes to its instance, in order, as
text (reals as the hex digits of their bits), with a `sample` line where a communication point
was recorded, so that one unit can be replayed alone in another tool (docs/usage.md).

       cosim federate SYSTEM.ssp --component NAME[,NAME...] --broker HOST[:PORT] [--name FED]
             [--out FILE.csv] [--stop T] [--step H] [--helics-lib PATH] [--core tcpss|zmq|tcp|...]
       cosim federation SYSTEM.ssp [--groups a,b;c;d] [--out FILE.csv] [--stop T] [--step H]
             [--helics-lib PATH] [--core tcpss|zmq|tcp|...] [--timing global|distributed]

`federate` runs the listed components as one HELICS value federate (tcpss core by default: one
TCP connection out to the broker, no port of its own) with the results of --algorithm jacobi bit
for bit, writing their outputs to FILE.csv; a federate that cannot join its broker within 20 s
fails naming the broker. `federation` runs the whole system so on this machine (helics_broker on
127.0.0.1 on a port the kernel picks, one federate process per group, by default one per
component; --timing: the broker's time coordination, by default distributed for up to 3
federates and global from 4, whichever was faster measured), merges the CSVs (default <system
name>.csv) and prints the commands for several machines; SIGINT/SIGTERM/SIGHUP, or the launcher's death, stop the broker and every federate. libhelics (the `helics` Python wheel): --helics-lib, $HELICS_LIB, or the test
venv target/venv (docs/scaling.md).";

#[derive(Default)]
struct Args {
    system: PathBuf,
    opts: Options,
    out: Option<PathBuf>,
    no_csv: bool,
    iterative: master::Iterative,
    /// Threads stepping the units (0: the default, one).
    threads: usize,
    plot: Option<PathBuf>,
    signals: Vec<String>,
    record: Record,
    trace: Option<PathBuf>,
}

/// The result file of a run: CSV, or MATLAB v4 for an `--out` ending in `.mat`.
enum Results {
    Csv(Select<CsvWriter>),
    Mat(Select<MatWriter>),
}

impl Results {
    fn new(out: &Path, record: Record) -> Results {
        if out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("mat"))
        {
            Results::Mat(Select::new(MatWriter::new(out), record))
        } else {
            Results::Csv(Select::new(CsvWriter::new(out), record))
        }
    }

    fn observer(&mut self) -> &mut dyn Observer {
        match self {
            Results::Csv(s) => s,
            Results::Mat(s) => s,
        }
    }

    fn rows(&self) -> u64 {
        match self {
            Results::Csv(s) => s.inner.rows(),
            Results::Mat(s) => s.inner.rows(),
        }
    }

    fn columns(&self) -> usize {
        match self {
            Results::Csv(s) => s.columns().len(),
            Results::Mat(s) => s.columns().len(),
        }
    }

    /// The file that holds the rows of a run that did not complete, if there is one.
    fn kept(&self) -> Option<&Path> {
        match self {
            Results::Csv(s) => s.inner.kept(),
            Results::Mat(s) => s.inner.kept(),
        }
    }
}

/// The value of `flag`: a positive finite number.
fn number(flag: &str, v: Option<String>) -> Result<f64, String> {
    let v = v.ok_or(format!("{flag} needs a value"))?;
    v.parse::<f64>()
        .ok()
        .filter(|x| x.is_finite() && *x > 0.0)
        .ok_or(format!("{flag} {v}: not a positive number"))
}

fn parse() -> Result<Args, String> {
    let mut it = std::env::args().skip(1);
    let mut args = Args {
        iterative: master::Iterative::new(),
        record: Record::system_default(),
        ..Args::default()
    };
    while let Some(a) = it.next() {
        match a.as_str() {
            "--stop" => args.opts.stop = Some(number("--stop", it.next())?),
            "--step" => args.opts.step = Some(number("--step", it.next())?),
            "--algorithm" => {
                let v = it
                    .next()
                    .ok_or("--algorithm needs jacobi, gauss-seidel or iterative")?;
                args.opts.algorithm = v.parse::<Scheme>().map_err(|e| e.to_string())?;
            }
            "--out" => args.out = Some(it.next().ok_or("--out needs a file")?.into()),
            "--no-csv" => args.no_csv = true,
            "--record" => {
                let list = it.next().ok_or("--record needs patterns (or 'all')")?;
                args.record = Record {
                    interval: args.record.interval,
                    ..Record::parse(&list)
                };
            }
            "--output-interval" => {
                args.record.interval = Some(number("--output-interval", it.next())?)
            }
            "--tolerance" => {
                args.iterative.rtol = number("--tolerance", it.next())?;
                args.iterative.atol = 1e-3 * args.iterative.rtol;
            }
            "--relaxation" => args.iterative.relaxation = number("--relaxation", it.next())?,
            "--threads" => {
                let v = it.next().ok_or("--threads needs a number or 'all'")?;
                args.threads = if v == "all" {
                    std::thread::available_parallelism().map_or(1, |n| n.get())
                } else {
                    v.parse().ok().filter(|n| *n > 0).ok_or(format!(
                        "--threads {v}: not a positive whole number or 'all'"
                    ))?
                };
            }
            "--max-iterations" => {
                let v = it.next().ok_or("--max-iterations needs a value")?;
                args.iterative.max_iterations = v
                    .parse()
                    .ok()
                    .filter(|n| *n > 0)
                    .ok_or(format!("--max-iterations {v}: not a positive whole number"))?;
            }
            "--trace" => args.trace = Some(it.next().ok_or("--trace needs a directory")?.into()),
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
    if args.no_csv && args.out.is_some() {
        return Err("--out and --no-csv exclude each other".into());
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

/// Whether `a` and `b` are the same file (device and inode), both existing.
fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

/// Refuse, before the run, a CSV path the run could not write or must not: a directory, or the
/// input itself (a complete run renames its rows over `out`).
fn check_out(out: &Path, system: &Path) -> Result<(), String> {
    if out.is_dir() {
        return Err(format!(
            "--out {}: is a directory; name a file",
            out.display()
        ));
    }
    let mut inputs = vec![system.to_path_buf()];
    if system.is_dir() {
        inputs.push(system.join(dvpp_cosim::ssp::SSD_FILE));
    }
    // The rows go to a `.partial` file created new, which cannot be an input; only the
    // rename on completion could replace one.
    if let Some(input) = inputs.iter().find(|i| same_file(out, i)) {
        return Err(format!(
            "--out {}: is the input {}; it would be overwritten",
            out.display(),
            input.display()
        ));
    }
    // An SSP directory is the system's package (its SSD, FMUs and parameter files): results
    // go elsewhere. The directory holding an .ssd is not: results beside it are usual.
    if system.is_dir() {
        let inside = |dir: &Path| {
            let parent = match out.parent() {
                Some(p) if !p.as_os_str().is_empty() => p,
                _ => Path::new("."),
            };
            match (parent.canonicalize(), dir.canonicalize()) {
                (Ok(p), Ok(d)) => p.starts_with(d),
                _ => false,
            }
        };
        if inside(system) {
            return Err(format!(
                "--out {}: lies inside the SSP directory {} (the system's input); write the results elsewhere",
                out.display(),
                system.display()
            ));
        }
    }
    Ok(())
}

/// Refuse an `out` that is a file the system `package` reads: a component's FMU (which may lie
/// outside the package, `file://`), before anything is loaded.
fn check_out_sources(out: &Path, package: &ssp::Package) -> Result<(), String> {
    for c in &package.system.components {
        let source = package.source_path(c);
        if same_file(out, &source) {
            return Err(format!(
                "--out {}: is the FMU of component '{}' ({}), an input of the system; it would be overwritten",
                out.display(),
                c.name,
                source.display()
            ));
        }
    }
    Ok(())
}

/// The name results are filed under: the FMU's file stem or the system's.
fn stem(path: &Path) -> String {
    path.file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("system")
        .to_owned()
}

fn main() -> ExitCode {
    // Like other command-line tools, end quietly when the reader of stdout goes away
    // (`cosim ... | head`) instead of panicking in println!.
    // SAFETY: restores the default disposition of SIGPIPE before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    // A file size limit (`ulimit -f`) makes writes fail with EFBIG, reported with the path.
    interrupt::ignore_file_size_limit();
    // A federate blocks in HELICS calls: SIGINT/SIGTERM keep their default (end the process).
    // The launcher stops its broker and federates on them.
    match std::env::args().nth(1).as_deref() {
        Some("federate") => return federate_main(),
        Some("federation") => {
            interrupt::install();
            return federation_main();
        }
        _ => {}
    }
    interrupt::install();
    let mut args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("cosim: {e}");
            return ExitCode::FAILURE;
        }
    };
    let name = stem(&args.system);
    let out = (!args.no_csv).then(|| {
        args.out
            .clone()
            .unwrap_or_else(|| PathBuf::from(format!("{name}.csv")))
    });
    if let Some(out) = &out {
        if let Err(e) = check_out(out, &args.system) {
            eprintln!("cosim: {e}");
            return ExitCode::FAILURE;
        }
    }
    let mut results = out
        .as_deref()
        .map(|out| Results::new(out, args.record.clone()));
    let mut progress = Progress::default();
    let mut recorder = args.plot.as_ref().map(|_| Recorder::default());
    let mut observers: Vec<&mut dyn Observer> = vec![&mut progress];
    if let Some(r) = results.as_mut() {
        observers.push(r.observer());
    }
    if let Some(r) = recorder.as_mut() {
        observers.push(r);
    }
    let mut builtin = args.opts.algorithm.algorithm();
    let algorithm: &mut dyn master::Algorithm = if args.opts.algorithm == Scheme::Iterative {
        &mut args.iterative
    } else {
        &mut *builtin
    };
    // The system read once, here, so that --out is checked against the files it names before
    // any FMU is loaded (one .fmu on its own is the input itself, checked above).
    let is_fmu = args.system.extension().is_some_and(|e| e == "fmu");
    let package = if is_fmu {
        None
    } else {
        match ssp::read(&args.system) {
            Ok(p) => Some(p),
            Err(e) => {
                eprintln!("cosim: {e}");
                return ExitCode::FAILURE;
            }
        }
    };
    if let (Some(out), Some(package)) = (&out, &package) {
        if let Err(e) = check_out_sources(out, package) {
            eprintln!("cosim: {e}");
            return ExitCode::FAILURE;
        }
    }
    let source: Source = match &package {
        Some(p) => p.into(),
        None => (&args.system).into(),
    };
    let mut builder = System::builder(source)
        .threads(args.threads)
        .algorithm(algorithm);
    if let Some(dir) = &args.trace {
        builder = builder.trace(dir);
    }
    let outcome = match builder.run(&args.opts, &mut observers) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("cosim: {e}");
            return ExitCode::FAILURE;
        }
    };
    drop(observers);
    if !outcome.warnings.is_empty() {
        eprintln!("cosim: {} warning(s), see above", outcome.warnings.len());
    }
    let rows = results.as_ref().map_or(0, Results::rows);
    // What a run that did not complete kept, naming the file that holds it (its own).
    let partial = || match results.as_ref().and_then(Results::kept) {
        Some(kept) => format!(
            "{rows} complete rows up to t = {} s in {}",
            outcome.simulated,
            kept.display()
        ),
        None => "no row was written, and no file is left".to_owned(),
    };
    match &outcome.end {
        End::Completed => {
            let run = outcome.run_time.as_secs_f64();
            let steps = outcome.samples.saturating_sub(1);
            println!(
                "{name}: loaded in {:.3} s; initialized and simulated {} s in {run:.3} s ({:.0}x real time); {:.2} µs per step after initialization",
                outcome.load_time.as_secs_f64(),
                outcome.simulated,
                outcome.simulated / run,
                outcome.advance_time.as_secs_f64() * 1e6 / steps.max(1) as f64
            );
            if let Some(out) = &out {
                println!(
                    "{name}: {steps} steps; {rows} rows of {} of {} outputs -> {}",
                    results
                        .as_ref()
                        .map_or(0, Results::columns)
                        .saturating_sub(1),
                    outcome.columns,
                    out.display()
                );
            }
        }
        End::Interrupted { signal, at } => {
            eprintln!("cosim: {name}: interrupted by signal {signal} at t = {at} s");
            if out.is_some() {
                eprintln!("cosim: incomplete results: {}", partial());
            }
            return ExitCode::from((128 + signal).clamp(1, 255) as u8);
        }
        End::Failed { error, at } => {
            eprintln!("cosim: {error}");
            if outcome.samples > 0 {
                eprintln!("cosim: {name}: the run stopped after t = {at} s");
                if out.is_some() {
                    eprintln!("cosim: incomplete results: {}", partial());
                }
            }
            return ExitCode::FAILURE;
        }
    }
    if let (Some(path), Some(r)) = (&args.plot, &recorder) {
        let table = &r.table;
        let signals = if args.signals.is_empty() {
            table.columns.iter().skip(1).take(6).cloned().collect()
        } else {
            args.signals.clone()
        };
        if let Err(e) = plot(table, &signals, &name, path) {
            eprintln!("cosim: {e}");
            return ExitCode::FAILURE;
        }
        println!("plot -> {}", path.display());
    }
    ExitCode::SUCCESS
}

/// The options of `cosim federate` / `cosim federation` (after the subcommand).
fn parse_federated() -> Result<(FederateOptions, FederationOptions), String> {
    let mut fed = FederateOptions::default();
    let mut all = FederationOptions::default();
    let mut it = std::env::args().skip(2);
    let mut system = None;
    while let Some(a) = it.next() {
        let mut value = |what: &str| it.next().ok_or(format!("{a} needs {what}"));
        match a.as_str() {
            "--component" => {
                fed.components = value("a list of components")?
                    .split(',')
                    .map(str::trim)
                    .filter(|c| !c.is_empty())
                    .map(String::from)
                    .collect()
            }
            "--broker" => fed.broker = value("an address")?,
            "--name" => fed.name = Some(value("a name")?),
            "--out" => fed.out = Some(value("a file")?.into()),
            "--helics-lib" => fed.helics_lib = Some(value("a path")?.into()),
            "--groups" => all.groups = Some(value("groups like a,b;c")?),
            "--core" => fed.core = Some(value("a HELICS core type")?),
            "--timing" => {
                all.timing = Some(match value("global or distributed")?.as_str() {
                    "global" => federate::Timing::Global,
                    "distributed" => federate::Timing::Distributed,
                    t => return Err(format!("--timing {t}: global or distributed")),
                })
            }
            "--stop" => fed.opts.stop = Some(number("--stop", it.next())?),
            "--step" => fed.opts.step = Some(number("--step", it.next())?),
            "-h" | "--help" => return Err(USAGE.into()),
            s if s.starts_with('-') => return Err(format!("unknown option {s}\n\n{USAGE}")),
            _ if system.is_none() => system = Some(PathBuf::from(a)),
            _ => return Err(format!("unexpected argument {a}\n\n{USAGE}")),
        }
    }
    fed.system = system.ok_or(USAGE)?;
    all.system = fed.system.clone();
    all.out = fed.out.clone();
    all.helics_lib = fed.helics_lib.clone();
    all.opts = fed.opts.clone();
    all.core = fed.core.clone();
    Ok((fed, all))
}

fn federate_main() -> ExitCode {
    let fed = match parse_federated() {
        Ok((f, _)) if f.components.is_empty() || f.broker.is_empty() => {
            eprintln!("cosim federate: --component and --broker are required\n\n{USAGE}");
            return ExitCode::FAILURE;
        }
        Ok((f, _)) => f,
        Err(e) => {
            eprintln!("cosim: {e}");
            return ExitCode::FAILURE;
        }
    };
    match federate::run_federate(&fed) {
        Ok(r) => {
            let per_step = r.run_time.as_secs_f64() * 1e6 / r.steps.max(1) as f64;
            println!(
                "{}: loaded in {:.3} s; {} steps in {:.3} s ({per_step:.1} us per step; {} HELICS time grants per step, {} initialization passes)",
                r.name,
                r.load_time.as_secs_f64(),
                r.steps,
                r.run_time.as_secs_f64(),
                r.step_rounds,
                r.init_passes
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("cosim federate: {e}");
            ExitCode::FAILURE
        }
    }
}

fn federation_main() -> ExitCode {
    let all = match parse_federated() {
        Ok((_, a)) => a,
        Err(e) => {
            eprintln!("cosim: {e}");
            return ExitCode::FAILURE;
        }
    };
    let exe = match std::env::current_exe() {
        Ok(e) => e,
        Err(e) => {
            eprintln!("cosim federation: cannot find the cosim binary: {e}");
            return ExitCode::FAILURE;
        }
    };
    match federate::run_federation(&all, &exe) {
        Ok(r) => {
            println!("to run it on several machines (BROKER_HOST: the broker's address):");
            for c in &r.commands {
                println!("  {c}");
            }
            for s in &r.summaries {
                println!("{s}");
            }
            let steps = r.rows.saturating_sub(1).max(1);
            println!(
                "federation of {} federates: {} rows in {:.3} s wall ({:.1} us per step, broker and start-up included)",
                r.federates.len(),
                r.rows,
                r.wall.as_secs_f64(),
                r.wall.as_secs_f64() * 1e6 / steps as f64
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("cosim federation: {e}");
            ExitCode::FAILURE
        }
    }
}
