//! `cargo xtask fuzz`: seeded fuzzing of the SSD reader and master, the scenario compiler and the FMUs' C API, each case in a child process with a timeout, every outcome classified and counted.
//!
//! Case `k` of a run with seed `S` is one of three kinds (`k mod 3`), drawn from its own
//! generator (`Rng::for_case(S, k)`), so a run is the same for the same seed and count, and one
//! case can be re-run alone (`--first k --cases 1`):
//!
//! * `ssd`: a variant of `case1_load`'s SSD (`dvpp_e2e::mutate`), run by the `cosim` binary for
//!   0.02 s next to the unpacked FMUs; its CSV compared with the original's.
//! * `scenario`: a variant of a shipped scenario file (`studies/scenarios/*.toml`), compiled by
//!   the scenario compiler (`xtask fuzz-compile`, the FMUs described in process, not built); its
//!   SSD compared with the original's.
//! * `fmi`: a random sequence of FMI calls on a bundled FMU through its C API (`xtask fuzz-fmi`,
//!   the master's dlopen loader): calls in the wrong state, NaN, infinite, denormal and
//!   out-of-range values, unknown value references, forged serialized states; the child checks
//!   each status against the FMI 2.0 state machine and every value read outside the error
//!   state for finiteness; a quarter of the sequences make only allowed calls with valid
//!   values (a serialized state's round trip must leave every value as it was).

use dvpp_cosim::{Fmu, Instance, Status};
use dvpp_e2e::mutate::{self, Exit, Mutant, Rng};
use model_description::{Causality, VariableKind};
use std::collections::BTreeMap;
use std::io::Read;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Cases of the long form (the default).
pub const CASES: usize = 10_000;
/// Cases and seed of the short form `cargo xtask test` runs.
pub const SHORT: (usize, u64) = (300, 1);
const SEED: u64 = 1;
/// Per case: longer is a hang.
const TIMEOUT: Duration = Duration::from_secs(20);
/// Address space of a child, bytes: an unbounded read ends there instead of in the machine's
/// memory.
const MEMORY: u64 = 2 << 30;
/// Bad cases listed per kind of mutation and class.
const SHOWN: usize = 3;
/// Exit code of a child that saw an invalid input accepted.
const SILENT: i32 = 3;
/// Exit code of a child whose FMU contained a panic of its own.
const CONTAINED: i32 = 4;

/// The kinds of case, in the order `k mod 3` picks them.
const KINDS: [&str; 3] = ["ssd", "scenario", "fmi"];

/// What a case did. The first three are good.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Class {
    /// Refused with one error line.
    Refused,
    /// Accepted, with results identical to the original's.
    Same,
    /// Accepted, with other results (a valid change).
    Different,
    /// An invalid input accepted.
    Silent,
    /// Refused, but by a panic inside an FMU (contained by its export layer) rather than a check.
    Contained,
    /// Ran out of its address space ([`MEMORY`]): an input that makes it take without bound.
    Memory,
    /// A Rust panic reached the process (exit 101 or "panicked" in its output).
    Panic,
    /// Killed by a signal.
    Crash,
    /// Still running at the timeout.
    Hang,
    /// Refused, but not with one error line, or another exit code.
    Unclear,
}

impl Class {
    fn bad(self) -> bool {
        self > Class::Different
    }
}

/// One case's result.
struct Case {
    kind: &'static str,
    what: String,
    class: Class,
    detail: String,
}

/// `cargo xtask fuzz [--cases N] [--seed S] [--first K] [--jobs J]`.
pub fn fuzz(root: &Path, target: &Path, cosim: &Path, args: &[String]) -> Result<(), String> {
    let (mut cases, mut seed, mut first, mut jobs) = (CASES, SEED, 0usize, 1usize);
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = |name: &str| {
            it.next()
                .and_then(|v| v.parse::<u64>().ok())
                .ok_or(format!("fuzz: {name} needs a whole number"))
        };
        match a.as_str() {
            "--cases" => cases = value("--cases")? as usize,
            "--seed" => seed = value("--seed")?,
            "--first" => first = value("--first")? as usize,
            "--jobs" => jobs = (value("--jobs")? as usize).max(1),
            other => return Err(format!("fuzz: unknown argument '{other}'")),
        }
    }
    let work = target.join("fuzz");
    let _ = std::fs::remove_dir_all(&work);
    std::fs::create_dir_all(&work).map_err(|e| format!("{}: {e}", work.display()))?;
    let started = Instant::now();
    let setup = Setup::new(root, &work, cosim)?;
    println!(
        "fuzz: {cases} cases from case {first}, seed {seed}, {jobs} at a time, {} s per case at most",
        TIMEOUT.as_secs()
    );
    let next = AtomicUsize::new(first);
    let done = AtomicUsize::new(0);
    let results: Mutex<Vec<(usize, Case)>> = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for slot in 0..jobs {
            let (setup, next, done, results) = (&setup, &next, &done, &results);
            s.spawn(move || loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                if k >= first + cases {
                    break;
                }
                let case = setup.run(k, seed, slot);
                results.lock().expect("results").push((k, case));
                let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                if n % 500 == 0 {
                    println!(
                        "fuzz: {n} of {cases} cases in {:.0} s",
                        started.elapsed().as_secs_f64()
                    );
                }
            });
        }
    });
    let mut results = results.into_inner().expect("results");
    results.sort_by_key(|r| r.0);
    report(&results, seed, started.elapsed().as_secs_f64())
}

/// Print the counts per kind and class and every bad case; an error if there is any.
fn report(results: &[(usize, Case)], seed: u64, seconds: f64) -> Result<(), String> {
    let mut counts: BTreeMap<(&str, Class), usize> = BTreeMap::new();
    let mut by_mutation: BTreeMap<(&str, &str, Class), usize> = BTreeMap::new();
    for (_, c) in results {
        *counts.entry((c.kind, c.class)).or_default() += 1;
        *by_mutation
            .entry((c.kind, c.what.as_str(), c.class))
            .or_default() += 1;
    }
    println!(
        "fuzz: {} cases, seed {seed}, in {seconds:.0} s",
        results.len()
    );
    let classes = [
        Class::Refused,
        Class::Same,
        Class::Different,
        Class::Silent,
        Class::Contained,
        Class::Memory,
        Class::Panic,
        Class::Crash,
        Class::Hang,
        Class::Unclear,
    ];
    print!("  {:<10}", "");
    for c in classes {
        print!("{:>10}", format!("{c:?}").to_lowercase());
    }
    println!();
    for kind in KINDS {
        print!("  {kind:<10}");
        for c in classes {
            print!("{:>10}", counts.get(&(kind, c)).copied().unwrap_or(0));
        }
        println!();
    }
    println!("  by mutation:");
    for ((kind, what, class), n) in &by_mutation {
        println!(
            "    {kind:<9} {what:<28} {:<10} {n}",
            format!("{class:?}").to_lowercase()
        );
    }
    let bad: Vec<&(usize, Case)> = results.iter().filter(|(_, c)| c.class.bad()).collect();
    if bad.is_empty() {
        println!("fuzz: no panic, crash, hang or silent acceptance");
        return Ok(());
    }
    println!(
        "fuzz: bad cases, the first {SHOWN} of each kind of mutation and class (re-run one with \
         --seed {seed} --first K --cases 1):"
    );
    let mut shown: BTreeMap<(&str, &str, Class), usize> = BTreeMap::new();
    for (k, c) in &bad {
        let n = shown.entry((c.kind, c.what.as_str(), c.class)).or_default();
        *n += 1;
        if *n > SHOWN {
            continue;
        }
        println!(
            "  case {k} [{} {}] {:?}: {}",
            c.kind,
            c.what,
            c.class,
            c.detail
                .lines()
                .rev()
                .find(|l| !l.trim().is_empty())
                .unwrap_or("")
                .trim()
        );
    }
    Err(format!(
        "fuzz: {} of {} cases bad (silent acceptance, contained FMU panic, out of memory, panic, crash, hang or unclear refusal)",
        bad.len(),
        results.len()
    ))
}

/// What every case starts from.
struct Setup {
    /// The running xtask (its hidden `fuzz-compile` and `fuzz-fmi` commands).
    xtask: PathBuf,
    cosim: PathBuf,
    work: PathBuf,
    /// `case1_load` unpacked, its SSD, the fixed variants, and the CSV of the original.
    ssd_dir: PathBuf,
    ssd: String,
    fixed: Vec<Mutant>,
    baseline: String,
    /// Shipped scenarios: (name, text, SSD compiled from the original).
    scenarios: Vec<(String, String, String)>,
    /// The bundled FMUs.
    fmus: Vec<PathBuf>,
}

impl Setup {
    fn new(root: &Path, work: &Path, cosim: &Path) -> Result<Setup, String> {
        let xtask = std::env::current_exe().map_err(|e| e.to_string())?;
        let dist = root.join("dist");
        let ssd_dir = work.join("ssd");
        let ssd = mutate::unpack(&dist.join("case1_load").join("case1_load.ssp"), &ssd_dir)?;
        let fixed = mutate::fixed(&ssd);
        let mut setup = Setup {
            xtask,
            cosim: cosim.to_path_buf(),
            work: work.to_path_buf(),
            ssd_dir,
            ssd,
            fixed,
            baseline: String::new(),
            scenarios: Vec::new(),
            fmus: dvpp_e2e::IDS
                .iter()
                .map(|id| dist.join("default").join(format!("{id}.fmu")))
                .collect(),
        };
        let (ran, csv) = setup.cosim(&setup.ssd, 0)?;
        setup.baseline = csv
            .filter(|_| matches!(ran.exit, Exit::Code(0)))
            .ok_or(format!(
                "fuzz: the original case1_load did not run: {}",
                ran.stderr
            ))?;
        for f in super::shipped_scenarios()? {
            let name = f
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            let text = std::fs::read_to_string(&f).map_err(|e| format!("{}: {e}", f.display()))?;
            let (ran, compiled) = setup.compile(&name, &text, 0)?;
            let compiled = compiled.ok_or(format!(
                "fuzz: the shipped scenario {name} does not compile: {}",
                ran.stderr
            ))?;
            setup.scenarios.push((name, text, compiled));
        }
        Ok(setup)
    }

    /// Case `k` of the run seeded `seed`, on worker `slot` (its own files).
    fn run(&self, k: usize, seed: u64, slot: usize) -> Case {
        let mut rng = Rng::for_case(seed, k as u64);
        let kind = KINDS[k % KINDS.len()];
        let result = match kind {
            "ssd" => self.ssd_case(&mut rng, slot),
            "scenario" => self.scenario_case(&mut rng, slot),
            _ => self.fmi_case(k, seed, &mut rng),
        };
        match result {
            Ok((what, class, detail)) => Case {
                kind,
                what,
                class,
                detail,
            },
            Err(e) => Case {
                kind,
                what: "harness".into(),
                class: Class::Unclear,
                detail: e,
            },
        }
    }

    /// Run `ssd` in `cosim` next to the unpacked FMUs; how it ended and its CSV.
    fn cosim(&self, ssd: &str, slot: usize) -> Result<(mutate::Ran, Option<String>), String> {
        let file = self.ssd_dir.join(format!("mutant{slot}.ssd"));
        let out = self.ssd_dir.join(format!("mutant{slot}.csv"));
        let _ = std::fs::remove_file(&out);
        std::fs::write(&file, ssd).map_err(|e| format!("{}: {e}", file.display()))?;
        let mut cmd = Command::new(&self.cosim);
        cmd.arg(&file).args(["--stop", "0.02", "--out"]).arg(&out);
        let ran = mutate::run_with_timeout(limited(&mut cmd), TIMEOUT)?;
        Ok((ran, std::fs::read_to_string(&out).ok()))
    }

    fn ssd_case(&self, rng: &mut Rng, slot: usize) -> Result<(String, Class, String), String> {
        let m = mutate::random(&self.ssd, &self.fixed, rng);
        let (ran, csv) = self.cosim(&m.ssd, slot)?;
        let class = classify(&ran, "cosim: ", m.must_refuse, || {
            csv.as_deref() == Some(self.baseline.as_str())
        });
        Ok((m.class.to_owned(), class, ran.stderr))
    }

    /// Compile scenario `name` from `text` in a child; how it ended and the SSD it made.
    fn compile(
        &self,
        name: &str,
        text: &str,
        slot: usize,
    ) -> Result<(mutate::Ran, Option<String>), String> {
        let dir = self.work.join(format!("scenario{slot}"));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let file = dir.join(format!("{name}.toml"));
        std::fs::write(&file, text).map_err(|e| format!("{}: {e}", file.display()))?;
        let out = dir.join("out");
        let mut cmd = Command::new(&self.xtask);
        cmd.arg("fuzz-compile").arg(&file).arg(&out);
        let ran = mutate::run_with_timeout(limited(&mut cmd), TIMEOUT)?;
        let compiled = std::fs::read_to_string(out.join(COMPILED)).ok();
        Ok((ran, compiled))
    }

    fn scenario_case(&self, rng: &mut Rng, slot: usize) -> Result<(String, Class, String), String> {
        let (name, text, original) = rng.pick(&self.scenarios);
        let (what, mutated, must_refuse) = mutate_toml(text, rng);
        let (ran, compiled) = self.compile(name, &mutated, slot)?;
        let class = classify(&ran, "xtask: ", must_refuse, || {
            compiled.as_deref() == Some(original.as_str())
        });
        Ok((what.to_owned(), class, ran.stderr))
    }

    fn fmi_case(
        &self,
        k: usize,
        seed: u64,
        rng: &mut Rng,
    ) -> Result<(String, Class, String), String> {
        let fmu = rng.pick(&self.fmus);
        let mut cmd = Command::new(&self.xtask);
        cmd.arg("fuzz-fmi")
            .arg(fmu)
            .arg(seed.to_string())
            .arg(k.to_string());
        let ran = mutate::run_with_timeout(limited(&mut cmd), TIMEOUT)?;
        let id = fmu
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let id = match ran
            .stderr
            .lines()
            .find_map(|l| l.strip_prefix("fuzz: sequence of "))
        {
            Some(calls) => format!("{id}, {calls}"),
            None => id,
        };
        // The child says what it checked last: "fuzz: refused" or "fuzz: accepted".
        let class = match ran.exit {
            Exit::Code(0) if ran.stderr.contains("fuzz: refused") => Class::Refused,
            Exit::Code(0) => Class::Same,
            Exit::Code(SILENT) => Class::Silent,
            Exit::Code(CONTAINED) => Class::Contained,
            _ => classify(&ran, "fuzz: ", false, || false),
        };
        Ok((id, class, ran.stderr))
    }
}

/// A child limited to [`MEMORY`] of address space.
fn limited(cmd: &mut Command) -> &mut Command {
    // SAFETY: setrlimit is async-signal-safe; nothing else runs between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            let limit = libc::rlimit {
                rlim_cur: MEMORY,
                rlim_max: MEMORY,
            };
            libc::setrlimit(libc::RLIMIT_AS, &limit);
            Ok(())
        })
    }
}

/// The class of a child that ran a master or the compiler: `prefix` starts its error lines;
/// `same` tells whether an accepted input gave the original's results.
fn classify(ran: &mutate::Ran, prefix: &str, must_refuse: bool, same: impl Fn() -> bool) -> Class {
    let panicked = ran.stderr.contains("panicked");
    let errors = ran
        .stderr
        .lines()
        .filter(|l| l.starts_with(prefix) && !l.contains("warning"))
        .count();
    match ran.exit {
        Exit::TimedOut => Class::Hang,
        Exit::Signal(_) => Class::Crash,
        Exit::Code(101) => Class::Panic,
        Exit::Code(1) if panicked && ran.stderr.contains("internal error contained") => {
            Class::Contained
        }
        _ if panicked => Class::Panic,
        Exit::Code(_)
            if ran.stderr.contains("out of memory") || ran.stderr.contains("memory allocation") =>
        {
            Class::Memory
        }
        Exit::Code(0) if must_refuse => Class::Silent,
        Exit::Code(0) if same() => Class::Same,
        Exit::Code(0) => Class::Different,
        Exit::Code(1) if errors == 1 => Class::Refused,
        Exit::Code(_) => Class::Unclear,
    }
}

/// The file `fuzz-compile` writes the compiled SSD to.
const COMPILED: &str = "compiled.ssd";

/// `xtask fuzz-compile SCENARIO.toml OUT`: compile the scenario into `OUT` (FMUs described in
/// process, not built) and write its SSD to `OUT/compiled.ssd`.
pub fn compile_child(args: &[String]) -> ExitCode {
    let [path, out] = args else {
        eprintln!("xtask: usage: fuzz-compile SCENARIO.toml OUT");
        return ExitCode::from(2);
    };
    let (path, out) = (Path::new(path), Path::new(out));
    let staging = out.join("staging");
    let mut one =
        |b: &dvpp_studies::scenario::Build| dvpp_studies::scenario::described(&staging, b);
    let compiled = dvpp_studies::scenario::bundle(path, out, &mut one).and_then(|ssp| {
        let file = std::fs::File::open(&ssp).map_err(|e| e.to_string())?;
        let mut zip = zip::ZipArchive::new(file).map_err(|e| e.to_string())?;
        let mut ssd = String::new();
        zip.by_name("SystemStructure.ssd")
            .map_err(|e| e.to_string())?
            .read_to_string(&mut ssd)
            .map_err(|e| e.to_string())?;
        std::fs::write(out.join(COMPILED), ssd).map_err(|e| e.to_string())
    });
    match compiled {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: {}", e.replace('\n', " "));
            ExitCode::FAILURE
        }
    }
}

/// Numbers a scenario mutation writes, and whether the value is invalid wherever a number is.
const NUMBERS: [(&str, bool); 14] = [
    ("nan", true),
    ("inf", true),
    ("-inf", true),
    ("-1", false),
    ("0", false),
    ("-0.0", false),
    ("1e308", false),
    ("1e-320", false),
    ("9223372036854775807", false),
    ("-9223372036854775808", false),
    ("4294967297", false),
    ("0.5", false),
    ("1e3", false),
    ("true", true),
];

/// A seeded variant of a scenario file: (what changed, text, is it invalid?).
fn mutate_toml(text: &str, rng: &mut Rng) -> (&'static str, String, bool) {
    let lines: Vec<&str> = text.lines().collect();
    let keyed: Vec<usize> = (0..lines.len())
        .filter(|&i| key_value(lines[i]).is_some())
        .collect();
    let numeric: Vec<usize> = keyed
        .iter()
        .copied()
        .filter(|&i| {
            key_value(lines[i]).is_some_and(|(_, v)| v.replace('_', "").parse::<f64>().is_ok())
        })
        .collect();
    let headers: Vec<usize> = (0..lines.len())
        .filter(|&i| lines[i].trim_start().starts_with('['))
        .collect();
    let join = |ls: Vec<String>| ls.join("\n") + "\n";
    let owned = || lines.iter().map(|l| l.to_string()).collect::<Vec<String>>();
    match rng.below(8) {
        0 | 1 if !numeric.is_empty() => {
            let i = *rng.pick(&numeric);
            let (key, _) = key_value(lines[i]).expect("a key");
            let (value, invalid) = *rng.pick(&NUMBERS);
            let mut ls = owned();
            ls[i] = format!("{key} = {value}");
            ("number", join(ls), invalid)
        }
        2 if !keyed.is_empty() => {
            let i = *rng.pick(&keyed);
            let (key, value) = key_value(lines[i]).expect("a key");
            let mut ls = owned();
            let renamed = match key.strip_suffix('"') {
                Some(quoted) => format!("{quoted}_x\""),
                None => format!("{key}_x"),
            };
            ls[i] = format!("{renamed} = {value}");
            ("key renamed", join(ls), true)
        }
        3 if !headers.is_empty() => {
            let i = *rng.pick(&headers);
            let mut ls = owned();
            let h = lines[i].trim();
            let is_array = h.starts_with("[[");
            ls[i] = h.replacen(']', "_x]", 1);
            // An array-of-tables header renamed, or a table's: an unknown table either way,
            // except the free tables of start values (`[...start]`), where it is a new key.
            let free = h.contains("start");
            ("table renamed", join(ls), !free || is_array)
        }
        4 if !keyed.is_empty() => {
            let i = *rng.pick(&keyed);
            let mut ls = owned();
            ls.insert(i + 1, lines[i].to_owned());
            ("key repeated", join(ls), true)
        }
        5 => {
            let i = rng.below(lines.len().max(1));
            let mut ls = owned();
            if !ls.is_empty() {
                ls.remove(i);
            }
            ("line removed", join(ls), false)
        }
        6 => {
            let at = rng.below(text.len().max(1));
            let at = (0..=at)
                .rev()
                .find(|&i| text.is_char_boundary(i))
                .unwrap_or(0);
            let end = at + text[at..].chars().next().map_or(0, char::len_utf8);
            let with = *rng.pick(&["[", "]", "=", "\"", "#", "\n", ".", "0", "-", "'"]);
            (
                "character replaced",
                format!("{}{with}{}", &text[..at], &text[end..]),
                false,
            )
        }
        _ => {
            let at = rng.below(text.len().max(1));
            let at = (0..=at)
                .rev()
                .find(|&i| text.is_char_boundary(i))
                .unwrap_or(0);
            ("truncated", text[..at].to_owned(), false)
        }
    }
}

/// `key = value` of a line (not a comment, not a header), trimmed.
fn key_value(line: &str) -> Option<(&str, &str)> {
    let t = line.trim();
    if t.starts_with('#') || t.starts_with('[') {
        return None;
    }
    let (k, v) = t.split_once(" = ")?;
    let v = v.split(" #").next().unwrap_or(v).trim();
    (!k.is_empty() && !v.is_empty()).then_some((k.trim(), v))
}

/// Values an FMI case sets a Real to.
const REALS: [f64; 14] = [
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    5e-324,
    -5e-324,
    2.2e-308,
    -0.0,
    1e308,
    -1e308,
    0.0,
    1.0,
    -1.0,
    1e6,
    0.5,
];

/// Communication steps an FMI case asks for.
const STEPS: [f64; 11] = [
    1e-3,
    1e-3,
    1e-2,
    0.05,
    0.0,
    -1e-3,
    f64::NAN,
    f64::INFINITY,
    1e-300,
    5e-324,
    1e-4,
];

/// The phase the FMI 2.0 state machine is in, as far as the case knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Instantiated,
    Initialization,
    Step,
    Terminated,
    /// After a failed call: not checked until a reset (in the error state an FMU may hold
    /// values that are not finite, for inspection).
    Unknown,
    /// After a forged state was accepted: calls not checked, every value read must be finite.
    Forged,
}

/// `xtask fuzz-fmi FMU SEED K`: case K of the run seeded SEED on the FMU; exit 0 if every call
/// returned what the FMI 2.0 state machine allows, [`SILENT`] if an invalid call or value was
/// accepted (or a value read was not finite).
pub fn fmi_child(args: &[String]) -> ExitCode {
    let [path, seed, k] = args else {
        eprintln!("fuzz: usage: fuzz-fmi FMU SEED K");
        return ExitCode::from(2);
    };
    let (Ok(seed), Ok(k)) = (seed.parse::<u64>(), k.parse::<u64>()) else {
        eprintln!("fuzz: SEED and K are whole numbers");
        return ExitCode::from(2);
    };
    let fmu = match Fmu::load(Path::new(path)) {
        Ok(f) => Arc::new(f),
        Err(e) => {
            eprintln!("fuzz: {e}");
            return ExitCode::FAILURE;
        }
    };
    // The same generator as the parent's case k, advanced past its pick of the FMU.
    let mut rng = Rng::for_case(seed, k);
    rng.next_u64();
    match fmi_sequence(&fmu, &mut rng) {
        Ok((_, Some(contained))) => {
            eprintln!("fuzz: contained: {contained}");
            ExitCode::from(CONTAINED as u8)
        }
        Ok((refused, None)) => {
            eprintln!("fuzz: {}", if refused { "refused" } else { "accepted" });
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("fuzz: silent: {e}");
            ExitCode::from(SILENT as u8)
        }
    }
}

/// A random call sequence on a new instance of `fmu`: whether an invalid call was refused and
/// the log line of a panic the FMU contained, or what was accepted that must not be.
fn fmi_sequence(fmu: &Arc<Fmu>, rng: &mut Rng) -> Result<(bool, Option<String>), String> {
    let vars = &fmu.description.model_variables.variables;
    let of = |want: &dyn Fn(&model_description::ScalarVariable) -> bool| -> Vec<u32> {
        vars.iter()
            .filter(|v| want(v))
            .map(|v| v.value_reference)
            .collect()
    };
    let settable_reals = of(&|v| {
        matches!(v.kind, VariableKind::Real(_))
            && matches!(v.causality(), Causality::Input | Causality::Parameter)
    });
    let reals = of(&|v| matches!(v.kind, VariableKind::Real(_)));
    let outputs =
        of(&|v| matches!(v.kind, VariableKind::Real(_)) && v.causality() == Causality::Output);
    let integers = of(&|v| matches!(v.kind, VariableKind::Integer(_)));
    let booleans = of(&|v| matches!(v.kind, VariableKind::Boolean(_)));
    let unknown_vr = reals.iter().max().map_or(0, |m| m + 1000);
    // Real inputs with their start values and bounds, for the valid sequences.
    let inputs: Vec<(u32, f64, f64, f64)> = vars
        .iter()
        .filter(|v| v.causality() == Causality::Input)
        .filter_map(|v| match &v.kind {
            VariableKind::Real(r) => Some((
                v.value_reference,
                r.start.unwrap_or(0.0),
                r.min.unwrap_or(f64::MIN),
                r.max.unwrap_or(f64::MAX),
            )),
            _ => None,
        })
        .collect();

    let mut i = fmu
        .instantiate("fuzz")
        .map_err(|e| format!("instantiate: {e}"))?;
    let mut phase = Phase::Instantiated;
    // The instance's time where known (not after a reset until the next fmi2SetupExperiment).
    let mut time = Some(0.0_f64);
    let mut saved: Option<(dvpp_cosim::fmu::SavedState, Phase, Option<f64>)> = None;
    let mut refused = false;
    let mut log = Vec::new();
    // Most sequences start in step mode, to reach what only happens there.
    if rng.chance(0.6) {
        let start = [
            i.setup_experiment(0.0, None),
            i.enter_initialization_mode(),
            i.exit_initialization_mode(),
        ];
        log.push(format!("initialized: {start:?}"));
        phase = if start.iter().all(|s| *s == Status::Ok) {
            Phase::Step
        } else {
            Phase::Unknown
        };
    }
    // A quarter of the sequences make only calls the state machine allows, with valid values:
    // those must never give a value that is not finite, nor crash.
    let valid = rng.chance(0.25);
    eprintln!(
        "fuzz: sequence of {}",
        if valid { "valid calls" } else { "any calls" }
    );
    let calls = 5 + rng.below(40);
    for _ in 0..calls {
        if valid {
            let (call, status) = valid_call(&mut i, phase, time, &inputs, &reals, rng)?;
            log.push(format!("{call} -> {status:?}"));
            (phase, time) = match (status, call.as_str()) {
                (Status::Ok | Status::Warning, "fmi2EnterInitializationMode") => {
                    (Phase::Initialization, time)
                }
                (Status::Ok | Status::Warning, "fmi2ExitInitializationMode") => (Phase::Step, time),
                (Status::Ok | Status::Warning, "fmi2Reset") => (Phase::Instantiated, Some(0.0)),
                (Status::Ok | Status::Warning, c) if c.starts_with("fmi2DoStep") => {
                    (phase, time.map(|t| t + VALID_STEP))
                }
                (Status::Ok | Status::Warning, _) => (phase, time),
                // A valid call refused: start again.
                _ => (Phase::Unknown, time),
            };
            continue;
        }
        // Whether the call is legal in the phase (None: the phase is not known).
        let now = phase;
        let legal = move |allowed: &[Phase]| {
            (!matches!(now, Phase::Unknown | Phase::Forged)).then(|| allowed.contains(&now))
        };
        // (call, status, the call is invalid: it must not return Ok)
        let (call, status, invalid): (String, Status, bool) = match rng.below(14) {
            0 => {
                let start = *rng.pick(&[0.0, 0.0, 0.0, 1.0, -1.0, f64::NAN, f64::INFINITY, 1e300]);
                let stop = *rng.pick(&[None, None, Some(10.0), Some(-5.0), Some(f64::NAN)]);
                let s = i.setup_experiment(start, stop);
                let bad = !start.is_finite()
                    || stop.is_some_and(|x| !x.is_finite() || x < start)
                    || legal(&[Phase::Instantiated]) == Some(false);
                if s == Status::Ok && !bad {
                    time = Some(start);
                }
                (format!("fmi2SetupExperiment({start}, {stop:?})"), s, bad)
            }
            1 => {
                let s = i.enter_initialization_mode();
                let bad = legal(&[Phase::Instantiated]) == Some(false);
                if s == Status::Ok && !bad {
                    phase = Phase::Initialization;
                }
                ("fmi2EnterInitializationMode".into(), s, bad)
            }
            2 => {
                let s = i.exit_initialization_mode();
                let bad = legal(&[Phase::Initialization]) == Some(false);
                if s == Status::Ok && !bad {
                    phase = Phase::Step;
                }
                ("fmi2ExitInitializationMode".into(), s, bad)
            }
            3..=5 => {
                let h = *rng.pick(&STEPS);
                let now = time.unwrap_or(0.0);
                let t = if rng.chance(0.85) {
                    now
                } else {
                    *rng.pick(&[now + 1.0, now - 1e-3, f64::NAN, f64::INFINITY, -1.0])
                };
                let s = i.do_step(t, h);
                let elsewhere = !matches!(phase, Phase::Unknown | Phase::Forged)
                    && time.is_some_and(|now| (t - now).abs() > 1e-9 * now.abs().max(1.0));
                let bad = !(h > 0.0 && h.is_finite() && t.is_finite())
                    || elsewhere
                    || legal(&[Phase::Step]) == Some(false);
                if s == Status::Ok && !bad {
                    time = Some(t + h);
                }
                (format!("fmi2DoStep({t}, {h})"), s, bad)
            }
            6 | 7 => {
                let n = 1 + rng.below(3);
                let mut vrs = Vec::new();
                let mut values = Vec::new();
                let mut bad = legal(&[Phase::Instantiated, Phase::Initialization, Phase::Step])
                    == Some(false);
                for _ in 0..n {
                    let vr = if rng.chance(0.1) && !outputs.is_empty() {
                        bad = true;
                        *rng.pick(&outputs)
                    } else if rng.chance(0.05) || settable_reals.is_empty() {
                        bad = true;
                        unknown_vr
                    } else {
                        *rng.pick(&settable_reals)
                    };
                    let x = *rng.pick(&REALS);
                    bad |= !x.is_finite();
                    vrs.push(vr);
                    values.push(x);
                }
                let s = i.set_real(&vrs, &values);
                (format!("fmi2SetReal({vrs:?}, {values:?})"), s, bad)
            }
            8 if !integers.is_empty() => {
                let vr = *rng.pick(&integers);
                let x = *rng.pick(&[0, 1, 2, 3, -1, i32::MAX, i32::MIN]);
                let s = i.set_integer(&[vr], &[x]);
                let bad = legal(&[Phase::Instantiated, Phase::Initialization, Phase::Step])
                    == Some(false);
                (format!("fmi2SetInteger([{vr}], [{x}])"), s, bad)
            }
            9 if !booleans.is_empty() => {
                let vr = *rng.pick(&booleans);
                let x = rng.chance(0.5);
                let s = i.set_boolean(&[vr], &[x]);
                let bad = legal(&[Phase::Instantiated, Phase::Initialization, Phase::Step])
                    == Some(false);
                (format!("fmi2SetBoolean([{vr}], [{x}])"), s, bad)
            }
            10 => {
                let mut out = vec![0.0; reals.len()];
                let s = i.get_real(&reals, &mut out);
                let bad =
                    legal(&[Phase::Initialization, Phase::Step, Phase::Terminated]) == Some(false);
                if s == Status::Ok && phase != Phase::Unknown {
                    if let Some((vr, x)) = reals.iter().zip(&out).find(|(_, x)| !x.is_finite()) {
                        return Err(format!(
                            "fmi2GetReal returned {x} for value reference {vr} (after {})",
                            log.join("; ")
                        ));
                    }
                }
                ("fmi2GetReal(all)".into(), s, bad)
            }
            11 => {
                // Save the state, or restore the saved one.
                match saved.take() {
                    Some((state, p, t)) if rng.chance(0.5) => {
                        let s = i.set_state(&state);
                        if s == Status::Ok {
                            (phase, time) = (p, t);
                        }
                        saved = Some((state, p, t));
                        ("fmi2SetFMUstate".into(), s, false)
                    }
                    _ => {
                        let (s, state) = i.get_state();
                        saved = state.map(|st| (st, phase, time));
                        ("fmi2GetFMUstate".into(), s, false)
                    }
                }
            }
            12 => {
                // A forged serialized state: the saved one's bytes changed, or random bytes.
                let mut bytes = match &saved {
                    Some((state, _, _)) => i.serialize_state(state).unwrap_or_default(),
                    None => Vec::new(),
                };
                let how = forge(&mut bytes, rng);
                let (s, state) = i.deserialize_state(&bytes);
                let mut status = s;
                if let (Status::Ok, Some(state)) = (s, state) {
                    status = i.set_state(&state);
                    if status == Status::Ok {
                        phase = Phase::Forged;
                    }
                    i.free_state(state);
                }
                (format!("fmi2DeSerializeFMUstate({how})"), status, false)
            }
            _ => match rng.below(3) {
                0 => {
                    let s = i.terminate();
                    let bad = legal(&[Phase::Step]) == Some(false);
                    if s == Status::Ok && !bad {
                        phase = Phase::Terminated;
                    }
                    ("fmi2Terminate".into(), s, bad)
                }
                1 => {
                    let s = i.reset();
                    if s == Status::Ok {
                        (phase, time) = (Phase::Instantiated, None);
                    }
                    ("fmi2Reset".into(), s, false)
                }
                _ => {
                    let s = i.set_debug_logging(rng.chance(0.5), &["logAll", "nonsense"]);
                    ("fmi2SetDebugLogging".into(), s, false)
                }
            },
        };
        log.push(format!("{call} -> {status:?}"));
        if invalid {
            if status == Status::Ok {
                return Err(format!(
                    "{call} returned Ok in phase {phase:?} (after {})",
                    log.join("; ")
                ));
            }
            refused = true;
        }
        if status != Status::Ok && status != Status::Warning {
            phase = Phase::Unknown;
        }
    }
    if let Some((state, _, _)) = saved {
        i.free_state(state);
    }
    let contained = i
        .log()
        .into_iter()
        .find(|r| r.message.contains("internal error contained"))
        .map(|r| format!("{} (after {})", r.message, log.join("; ")));
    Ok((refused, contained))
}

/// The communication step of the valid sequences.
const VALID_STEP: f64 = 1e-3;

/// One call the state machine allows in `phase`, with valid values (inputs near their start
/// values); its name and status, or a value read that is not finite.
fn valid_call(
    i: &mut Instance,
    phase: Phase,
    time: Option<f64>,
    inputs: &[(u32, f64, f64, f64)],
    reals: &[u32],
    rng: &mut Rng,
) -> Result<(String, Status), String> {
    let set_input = |i: &mut Instance, rng: &mut Rng| {
        let Some((vr, start, lo, hi)) = (!inputs.is_empty()).then(|| *rng.pick(inputs)) else {
            return ("fmi2SetReal()".to_owned(), Status::Ok);
        };
        let x = (start + 0.01 * (rng.below(201) as f64 - 100.0) / 100.0 * start.abs().max(0.1))
            .clamp(lo, hi);
        (
            format!("fmi2SetReal([{vr}], [{x}])"),
            i.set_real(&[vr], &[x]),
        )
    };
    let get = |i: &mut Instance| {
        let mut out = vec![0.0; reals.len()];
        let s = i.get_real(reals, &mut out);
        match reals.iter().zip(&out).find(|(_, x)| !x.is_finite()) {
            Some((vr, x)) if s == Status::Ok => Err(format!(
                "fmi2GetReal returned {x} for value reference {vr} in a valid sequence"
            )),
            _ => Ok(("fmi2GetReal(all)".to_owned(), s)),
        }
    };
    Ok(match (phase, rng.below(4)) {
        (Phase::Instantiated, 0) => (
            "fmi2SetupExperiment".into(),
            i.setup_experiment(time.unwrap_or(0.0), None),
        ),
        (Phase::Instantiated, 1) => set_input(i, rng),
        (Phase::Instantiated, _) => (
            "fmi2EnterInitializationMode".into(),
            i.enter_initialization_mode(),
        ),
        (Phase::Initialization, 0) => set_input(i, rng),
        (Phase::Initialization, 1) => get(i)?,
        (Phase::Initialization, _) => (
            "fmi2ExitInitializationMode".into(),
            i.exit_initialization_mode(),
        ),
        (Phase::Step, 0) => set_input(i, rng),
        (Phase::Step, 1) => get(i)?,
        (Phase::Step, 2) => {
            // A round trip through a serialized state: the same values after it.
            let mut before = vec![0.0; reals.len()];
            let read = i.get_real(reals, &mut before);
            let (s, state) = i.get_state();
            let Some(state) = state else {
                return Ok(("fmi2GetFMUstate".into(), s));
            };
            let bytes = i.serialize_state(&state);
            i.free_state(state);
            let Ok(bytes) = bytes else {
                return Ok(("fmi2SerializeFMUstate".into(), Status::Error));
            };
            let (s, copy) = i.deserialize_state(&bytes);
            let Some(copy) = copy else {
                return Ok(("fmi2DeSerializeFMUstate".into(), s));
            };
            let s = i.set_state(&copy);
            i.free_state(copy);
            let mut after = vec![0.0; reals.len()];
            if read == Status::Ok && s == Status::Ok && i.get_real(reals, &mut after) == Status::Ok
            {
                let same = |(a, b): (&f64, &f64)| a.to_bits() == b.to_bits();
                if let Some(k) = (0..reals.len()).find(|&k| !same((&before[k], &after[k]))) {
                    return Err(format!(
                        "value reference {} is {} after a serialized state round trip, {} before",
                        reals[k], after[k], before[k]
                    ));
                }
            }
            ("fmi2SetFMUstate(serialized)".into(), s)
        }
        (Phase::Step, _) => (
            format!("fmi2DoStep({:?}, {VALID_STEP})", time),
            i.do_step(time.unwrap_or(0.0), VALID_STEP),
        ),
        (Phase::Terminated, 0) => get(i)?,
        (Phase::Unknown | Phase::Forged | Phase::Terminated, _) => ("fmi2Reset".into(), i.reset()),
    })
}

/// Change the serialized state `bytes` (or make some up) in one of several ways; what was done.
fn forge(bytes: &mut Vec<u8>, rng: &mut Rng) -> &'static str {
    if bytes.is_empty() || rng.chance(0.1) {
        let n = rng.below(4096);
        *bytes = (0..n).map(|_| rng.next_u64() as u8).collect();
        return "random bytes";
    }
    let len = bytes.len();
    match rng.below(6) {
        0 => {
            for _ in 0..1 + rng.below(8) {
                let at = rng.below(len);
                bytes[at] ^= 1 << rng.below(8);
            }
            "bits flipped"
        }
        1 => {
            bytes.truncate(rng.below(len));
            "truncated"
        }
        2 => {
            let n = 1 + rng.below(64);
            bytes.extend((0..n).map(|_| rng.next_u64() as u8));
            "extended"
        }
        3 if len >= 8 => {
            // An f64's bytes replaced by NaN or infinity somewhere.
            let at = rng.below(len - 7);
            let x = *rng.pick(&[f64::NAN, f64::INFINITY, 5e-324, -0.0]);
            bytes[at..at + 8].copy_from_slice(&x.to_le_bytes());
            "a non-finite f64 written"
        }
        4 => {
            let at = rng.below(len);
            let n = (len - at).min(1 + rng.below(16));
            for b in &mut bytes[at..at + n] {
                *b = 0xFF;
            }
            "0xFF run"
        }
        _ => {
            let at = rng.below(len);
            bytes[at] = 0;
            "a zero byte"
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cases_are_the_same_for_the_same_seed() {
        let text = "[grid]\ncase = \"ieee9\"\nx = 1.5\n";
        let a: Vec<_> = (0..50)
            .map(|k| mutate_toml(text, &mut Rng::for_case(7, k)))
            .collect();
        let b: Vec<_> = (0..50)
            .map(|k| mutate_toml(text, &mut Rng::for_case(7, k)))
            .collect();
        assert_eq!(a, b);
        assert_ne!(
            mutate_toml(text, &mut Rng::for_case(7, 0)),
            mutate_toml(text, &mut Rng::for_case(8, 0))
        );
    }
}
