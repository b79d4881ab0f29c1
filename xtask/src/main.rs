//! `cargo xtask`: builds and bundles the FMUs, runs the tests, and runs the case studies (the
//! release `dvpp-study` binary of `studies/`).

mod apt;
mod catalog;
mod chromium;
mod docs;
mod federation;
mod fuzz;
mod hinf;
mod realcode;
mod win64;

use dvpp_studies::scenario;

use catalog::{BENCHES, FMUS};

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

/// Python packages the tests install into their own virtual environment. DPsim (the EMT host of
/// `tests/python/test_dpsim.py`) has wheels for CPython 3.10-3.13 on x86_64 Linux (and win_amd64)
/// only, so it installs only there (its marker); elsewhere that test skips and says why.
const PYTHON_PACKAGES: &[&str] = &[
    "fmpy==0.3.32",
    "libcosimpy==0.0.6",
    "pytest==8.4.2",
    "helics==3.6.1",
    // tests/python/test_results.py reads the .mat result files as users do.
    "scipy==1.17.1",
    "dpsim==1.4.0; sys_platform == 'linux' and platform_machine == 'x86_64' and python_version >= '3.10' and python_version < '3.14'",
    // tests/python/test_andes.py: the grid model against ANDES's on the same case file.
    "andes==2.0.0",
];

type Result<T = ()> = std::result::Result<T, String>;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("workspace root")
        .to_path_buf()
}

/// Cargo's target directory: `CARGO_TARGET_DIR` (relative to the workspace root) if set, else
/// `target/`.
fn target_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(|d| root().join(d))
        .unwrap_or_else(|| root().join("target"))
}

fn run(cmd: &mut Command) -> Result {
    let shown = format!("{cmd:?}");
    let status = cmd
        .status()
        .map_err(|e| format!("cannot run {shown}: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{shown} failed ({status})"))
    }
}

fn cargo() -> Command {
    let mut c = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    c.current_dir(root());
    c
}

const USAGE: &str = "usage: cargo xtask <task>

tasks:
  bundle [ID...]  build the FMUs (all, or those named) in release; write dist/default/<id>.fmu
                  and dist/variants/<id>-<variant>.fmu; with no ID also every shipped scenario
                  (studies/scenarios/*.toml) as dist/<scenario>/ with <scenario>.ssp; each FMU has
                  binaries/linux64 and, where the x86_64-pc-windows-gnu target and mingw-w64 are
                  installed (and DVPP_WIN64 is not 0), binaries/win64; with no ID, or the ID
                  `realcode`, also the IEEE/Cigre real-code DLLs (realcode/) into dist/realcode/:
                  linux64/*.so, win64/*.dll, include/*.h, params/*.params (docs/realcode.md)
  bundle --scenario PATH
                  bundle the scenario file PATH into dist/<its name>/
  cosim SYSTEM.ssp [--stop T] [--step H] [--algorithm jacobi|gauss-seidel|iterative]
                  [--threads N|all] [--out FILE.csv] [--plot FILE.svg --signals a.x,b.y]
                  run an SSP system (or one FMU) in our master
  bench    the H-infinity synthesis's time (as `hinf` without writing); bundle, then measure
           side by side in one run: case1_load in our master, fmpy.ssp
           and libcosim; the coupling error and cost of jacobi, gauss-seidel and iterative
           against a 0.05 ms run; our master's ns per macro step (a ring of three C FMUs,
           case1_load); ns per fmi2DoStep of each benchmark FMU; cost per unit for 3 to
           768 DER units, shared and separate binaries, 1 and 2 threads, and the same
           systems in libcosim
  demo     bundle, then run case study I (case1_load, case1_cloud) in our master: CSVs and
           figures in results/, figures in tests/figures/, metrics table into
           docs/case-studies.md; then
           case study III with its R/X Monte Carlo (as `case3`)
  emt-case1 [--end T] [--events load,cloud]
           bundle, then run case study I in DPsim EMT (tests/python/emt_case1.py in target/venv):
           the nine-bus system with the DVPP's EMT controller FMUs, each event for T s (default
           20) beside our master's phasor runs; CSVs in results/, figures
           tests/figures/emt_case1_<event>.svg, the table of docs/emt.md (full runs only); fails
           when a criterion of docs/emt.md §12 is not met
  test     install the win64 toolchain and wine, dvpp-design's libopenblas-dev and
           libgfortran-12-dev, and chromium (the qualification report's browser test,
           required: DVPP_REQUIRE_CHROMIUM=1), if missing (rustup, apt-get), bundle, run the
           Rust tests (the win64 binaries under wine among them, required: DVPP_REQUIRE_WIN64=1
           unless DVPP_WIN64=0), the short fuzz (`fuzz --cases 300 --seed 1`), the API docs
           without warnings, then the Python (fmpy) tests in target/venv
  sweep [--runs N] [--seed S]
           bundle, then run case study II (case2_load_eps000 ... eps100) on all cores: the 42 MW
           step per ε and N (default 20) seeded Monte Carlo load steps of U(10, 50) MW per
           family, at bus 2 (the paper's) and at a random bus; summary in
           results/case2_sweep.csv, distributions in tests/figures/case2_distributions.svg, the
           table of docs/case-studies.md (with the default N and seed)
  case3 [--draws N] [--seed S]
           bundle, then run case study III (case3_ext_pf, case3_ext_rot, case3_int_pf,
           case3_int_rot) and N (default 24) seeded random R/X per MV line for each rotational
           scenario, on all cores: results/case3.csv, tests/figures/case3_response.svg and
           case3_rx_envelope.svg, the table of docs/case-studies.md (with the default N and seed)
  outage   bundle, then run case study II's outage of SG1 and SG3 (case2_outage_eps000 ...
           eps100): a verdict per ε in results/case2_outage.csv, tests/figures/case2_outage.svg
           and the table of docs/case-studies.md
  ride-through
           bundle, then run case study I's DVPP at EMT level (emt_thevenin, emt_thevenin_hinf)
           through the grid codes' events (dips to 0.5 and 0.1 pu, three-phase, single-line and
           line-to-line faults, ±25° phase jumps, ±5 Hz/s) per control (option A, option B,
           grid-following) and SCR (10, 3, 1.5) on all cores: results/ride_through.csv,
           tests/figures/ride_through.svg and the table of docs/emt-unit.md
  qualify [--only TEXT]
           bundle, then run the grid-forming qualification suite on all cores: each preset unit
           (wind, PV, BESS) alone on its rating and case study I's DVPP at the PCC, option A, B
           and grid-following, through the grid codes' tests (phase jumps, RoCoF, voltage step,
           dips and faults, SCR step, loss of the grid, damping), judged against each source's
           bound or the subject's reference model: results/qualification.html (self-contained),
           results/qualification.csv and the matrix of docs/qualification.md; with --only, the
           runs whose name contains TEXT, printed only
  fuzz [--cases N] [--seed S] [--jobs J] [--first K]
           bundle the FMUs and case1_load, then run N (default 10000) seeded cases, in turn: a
           variant of case1_load's SSD run by the `cosim` binary, a variant of a shipped
           scenario file compiled by the scenario compiler, a random sequence of FMI calls
           (wrong order, NaN, infinite and denormal values, unknown references, forged
           serialized states) on a bundled FMU through its C API; each in a child process with
           a 20 s timeout and 2 GiB of address space; prints the count per class (refused,
           same, different: good; silent acceptance, contained FMU panic, out of memory,
           panic, crash, hang, unclear refusal: bad) and the first bad cases of each kind,
           and fails if there is one; J cases at a time (default 1); `--first K --cases 1`
           re-runs case K alone
  docs     regenerate docs/variables.md's tables from the FMUs' model descriptions
  hinf [--set NAME=VALUE]...
           install libopenblas-dev and libgfortran-12-dev if missing (apt-get), then run the
           release `dvpp-design` binary: synthesize option B's LPV H-infinity gains, check them
           (LMI residuals, closed-loop eigenvalues continuous and sampled on 50 values of mu,
           the H-infinity norm by a frequency sweep), print the figures and the synthesis time,
           and write dvpp-control/src/converter/hinf_gains.rs; with --set, explore a changed
           weight without writing (docs/hinf.md)";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("bundle") if args.get(1).map(String::as_str) == Some("--scenario") => {
            match &args[2..] {
                [path] => bundle_packages()
                    .and_then(|_| bundle_scenario(Path::new(path)))
                    .map(|_| ()),
                _ => Err("usage: cargo xtask bundle --scenario PATH".into()),
            }
        }
        Some("bundle") => bundle(&args[1..]).map(|_| ()),
        Some("cosim") => run(master_binary("cosim").args(&args[1..])),
        // The case studies: bundle, then the studies' release binary.
        Some(study @ ("demo" | "sweep" | "case3" | "outage" | "ride-through" | "qualify")) => {
            bundle(&[]).and_then(|_| run(study_binary()?.arg(study).args(&args[1..])))
        }
        Some("bench") => bench(),
        Some("emt-case1") => emt_case1(&args[1..]),
        Some("test") => test(),
        // The default FMUs and case1_load only: the scenario cases compile, not bundle.
        Some("fuzz") => bundle(&FMUS.iter().map(|f| f.id.to_string()).collect::<Vec<_>>())
            .and_then(|_| {
                bundle_scenario(
                    &root()
                        .join("studies")
                        .join("scenarios")
                        .join("case1_load.toml"),
                )
            })
            .and_then(|_| cosim_binary())
            .and_then(|cosim| fuzz::fuzz(&root(), &target_dir(), &cosim, &args[1..])),
        // The children of `fuzz` (not for direct use).
        Some("fuzz-compile") => return fuzz::compile_child(&args[1..]),
        Some("fuzz-fmi") => return fuzz::fmi_child(&args[1..]),
        Some("docs") => write_docs(),
        Some("hinf") => hinf::hinf(&args[1..]),
        _ => Err(USAGE.into()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Build the cdylibs and describe binaries of `fmus` with the `ship` profile (release with LTO),
/// and their win64 cdylibs where the cross toolchain is installed.
fn build_release(fmus: &[&catalog::Fmu]) -> Result {
    let mut c = cargo();
    c.args(["build", "--profile", "ship"]);
    for fmu in fmus {
        c.args(["--package", fmu.package]);
    }
    run(&mut c)?;
    let packages: Vec<&str> = fmus.iter().map(|f| f.package).collect();
    win64::build(cargo, "ship", &packages)
}

/// Write one `.fmu`: modelDescription.xml from the describe binary, the binaries (linux64, and
/// win64 if built), resources.
fn write_fmu(package: &str, id: &str, resources: &Path, out: &Path) -> Result<String> {
    let release = target_dir().join("ship");
    let describe = release.join(format!("{package}-describe"));
    let output = Command::new(&describe)
        .arg(resources)
        .output()
        .map_err(|e| format!("cannot run {}: {e}", describe.display()))?;
    if !output.status.success() {
        return Err(format!(
            "{package}: {}",
            String::from_utf8_lossy(&output.stderr).trim()
        ));
    }
    let library = release.join(format!("lib{}.so", package.replace('-', "_")));
    let binary = std::fs::read(&library).map_err(|e| format!("{}: {e}", library.display()))?;
    let windows = if win64::built() {
        let dll = win64::library(&target_dir(), "ship", package);
        Some(std::fs::read(&dll).map_err(|e| format!("{}: {e}", dll.display()))?)
    } else {
        None
    };

    let file = std::fs::File::create(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let mut zip = zip::ZipWriter::new(file);
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .unix_permissions(0o644);
    let mut add = |name: &str, bytes: &[u8], options| -> Result {
        zip.start_file(name, options).map_err(|e| e.to_string())?;
        zip.write_all(bytes).map_err(|e| e.to_string())
    };
    add("modelDescription.xml", &output.stdout, options)?;
    // The binary is stored, not deflated: every master unpacks it on every load, and inflating
    // it was most of the load time of a system.
    let stored = options.compression_method(zip::CompressionMethod::Stored);
    add(&format!("binaries/linux64/{id}.so"), &binary, stored)?;
    if let Some(dll) = &windows {
        add(&format!("binaries/win64/{id}.dll"), dll, stored)?;
    }
    let mut entries: Vec<_> = std::fs::read_dir(resources)
        .map_err(|e| format!("{}: {e}", resources.display()))?
        .filter_map(|e| e.ok())
        .collect();
    entries.sort_by_key(|e| e.file_name());
    for entry in entries {
        let bytes = std::fs::read(entry.path()).map_err(|e| e.to_string())?;
        add(
            &format!("resources/{}", entry.file_name().to_string_lossy()),
            &bytes,
            options,
        )?;
    }
    zip.finish().map_err(|e| e.to_string())?;
    String::from_utf8(output.stdout).map_err(|e| format!("{package}: {e}"))
}

/// Write a resources directory with `config` and `files`, then the `.fmu` from it; returns its
/// modelDescription.xml.
fn bundle_one(
    package: &str,
    id: &str,
    staging: &str,
    config: &str,
    files: &[PathBuf],
    out: &Path,
) -> Result<String> {
    let resources = target_dir().join("bundle").join(staging).join("resources");
    if resources.exists() {
        std::fs::remove_dir_all(&resources).map_err(|e| e.to_string())?;
    }
    std::fs::create_dir_all(&resources).map_err(|e| e.to_string())?;
    std::fs::write(resources.join("config.toml"), config).map_err(|e| e.to_string())?;
    for src in files {
        let name = src
            .file_name()
            .ok_or(format!("{}: not a file", src.display()))?;
        std::fs::copy(src, resources.join(name)).map_err(|e| format!("{}: {e}", src.display()))?;
    }
    let xml = write_fmu(package, id, &resources, out)?;
    println!(
        "bundled {}",
        out.strip_prefix(root()).unwrap_or(out).display()
    );
    Ok(xml)
}

/// Build and bundle the default FMUs (all, or those whose ids are in `only`) into
/// `dist/default/` and their variants into `dist/variants/`; returns the default FMUs' paths.
fn bundle(only: &[String]) -> Result<Vec<PathBuf>> {
    // `realcode`: the real-code DLLs (with no ID: after the FMUs).
    if only.iter().any(|id| id == "realcode") {
        realcode::bundle()?;
        let rest: Vec<String> = only
            .iter()
            .filter(|id| *id != "realcode")
            .cloned()
            .collect();
        return if rest.is_empty() {
            Ok(Vec::new())
        } else {
            bundle(&rest)
        };
    }
    if let Some(unknown) = only
        .iter()
        .find(|id| !FMUS.iter().any(|f| f.id == id.as_str()))
    {
        let known: Vec<&str> = FMUS.iter().map(|f| f.id).collect();
        return Err(format!(
            "unknown FMU '{unknown}'; the FMUs are {}",
            known.join(", ")
        ));
    }
    let chosen: Vec<&catalog::Fmu> = FMUS
        .iter()
        .filter(|f| only.is_empty() || only.iter().any(|id| id == f.id))
        .collect();
    build_release(&chosen)?;
    let dist = root().join("dist");
    for sub in ["default", "variants"] {
        std::fs::create_dir_all(dist.join(sub)).map_err(|e| e.to_string())?;
    }
    let mut written = Vec::new();
    for fmu in &chosen {
        let out = dist.join("default").join(format!("{}.fmu", fmu.id));
        let config = "# Default configuration: declared start values, default experiment.\n";
        bundle_one(fmu.package, fmu.id, fmu.id, config, &[], &out)?;
        written.push(out);
    }
    for v in catalog::variants()
        .iter()
        .filter(|v| chosen.iter().any(|f| f.id == v.id))
    {
        let fmu = FMUS
            .iter()
            .find(|f| f.id == v.id)
            .ok_or(format!("variant of unknown FMU {}", v.id))?;
        let out = dist
            .join("variants")
            .join(format!("{}-{}.fmu", v.id, v.name));
        let files: Vec<PathBuf> = v.files.iter().map(|f| root().join(f)).collect();
        bundle_one(
            fmu.package,
            fmu.id,
            &format!("{}-{}", v.id, v.name),
            &v.config,
            &files,
            &out,
        )?;
    }
    if only.is_empty() {
        for path in shipped_scenarios()? {
            bundle_scenario(&path)?;
        }
        realcode::bundle()?;
    }
    Ok(written)
}

/// Build every FMU package (a scenario uses all three).
fn bundle_packages() -> Result {
    let all: Vec<&catalog::Fmu> = FMUS.iter().collect();
    build_release(&all)
}

/// The scenario files the project ships, by name.
fn shipped_scenarios() -> Result<Vec<PathBuf>> {
    let dir = root().join("studies").join("scenarios");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    Ok(files)
}

/// Bundle one scenario file into `dist/<name>/` (FMUs built already); returns the `.ssp`.
fn bundle_scenario(path: &Path) -> Result<PathBuf> {
    let name = scenario::name_of(path)?;
    if ["default", "variants"].contains(&name.as_str()) {
        return Err(format!(
            "{}: a scenario cannot be named '{name}' (dist/{name}/ holds the plain FMUs)",
            path.display()
        ));
    }
    let out_dir = root().join("dist").join(&name);
    let mut one = |b: &scenario::Build| -> Result<model_description::ModelDescription> {
        let xml = bundle_one(
            b.fmu.package,
            b.fmu.id,
            &b.staging,
            &b.config,
            &b.files,
            &b.out,
        )?;
        model_description::ModelDescription::from_xml(&xml).map_err(|e| e.to_string())
    };
    let ssp = scenario::bundle(path, &out_dir, &mut one)?;
    println!(
        "bundled {}",
        ssp.strip_prefix(root()).unwrap_or(&ssp).display()
    );
    Ok(ssp)
}

/// `cargo run` of one of the master's binaries (`cosim`, `bench`) in release mode.
fn master_binary(name: &str) -> Command {
    let mut c = cargo();
    c.args([
        "run",
        "--release",
        "--quiet",
        "--package",
        "dvpp-cosim",
        "--bin",
        name,
        "--",
    ]);
    c
}

/// Build the studies' `dvpp-study` binary in release (a study runs many systems: at release
/// speed, as `cosim` runs them) and return the command that runs it on the workspace root.
fn study_binary() -> Result<Command> {
    run(cargo().args([
        "build",
        "--release",
        "--package",
        "dvpp-studies",
        "--bin",
        "dvpp-study",
    ]))?;
    let mut c = Command::new(target_dir().join("release").join("dvpp-study"));
    c.current_dir(root()).arg("--root").arg(root());
    Ok(c)
}

/// Build the master's `cosim` binary in release and return its path.
fn cosim_binary() -> Result<PathBuf> {
    run(cargo().args([
        "build",
        "--release",
        "--package",
        "dvpp-cosim",
        "--bin",
        "cosim",
    ]))?;
    Ok(target_dir().join("release").join("cosim"))
}

fn bench() -> Result {
    // Option B's synthesis time (and its checks), before the simulations.
    hinf::bench()?;
    bundle(&[])?;
    // The masters side by side on case study I (same system, horizon and step).
    let python = python_env()?;
    let cosim = cosim_binary()?;
    let ssp = root()
        .join("dist")
        .join("case1_load")
        .join("case1_load.ssp");
    run(Command::new(&python)
        .arg(root().join("tests").join("python").join("bench_masters.py"))
        .arg(&ssp)
        .arg(&cosim)
        .args(["--stop", "20", "--step", "1e-3"]))?;
    // The coupling error of each algorithm against a 0.05 ms Jacobi run, and its cost.
    run(Command::new(&python)
        .arg(
            root()
                .join("tests")
                .join("python")
                .join("coupling_error.py"),
        )
        .arg(&ssp)
        .arg(&cosim))?;
    let mut c = master_binary("bench");
    // The master's own overhead: a ring of three trivial C units; then case study I per step.
    let foreign = root().join("target").join("bench").join("foreign");
    let _ = std::fs::remove_dir_all(&foreign);
    let fmus = dvpp_e2e::foreign::build_foreign(&foreign);
    let (ring, _) = dvpp_e2e::foreign::system(&foreign, "ring", &fmus);
    c.arg(format!(
        "system|ring of three C lags|{}|300",
        ring.display()
    ));
    c.arg(format!("system|case1_load|{}|20", ssp.display()));
    // The EMT level: case study I's DVPP with the paper's converters at 50 µs.
    let emt = root()
        .join("dist")
        .join("emt_thevenin")
        .join("emt_thevenin.ssp");
    c.arg(format!("system|emt_thevenin|{}|10", emt.display()));
    // The cost of recording (docs/results.md): case study I, and 192 DER units (the scale
    // bench's system, written below) at 1 ms.
    c.arg(format!("results|case1_load|{}|20", ssp.display()));
    for b in BENCHES {
        let sets: Vec<String> = b.set.iter().map(|(n, v)| format!("{n}={v}")).collect();
        c.arg(format!(
            "{}|{}|{}|{}",
            b.label,
            root().join("dist").join(b.fmu).display(),
            b.h,
            sets.join(",")
        ));
    }
    // Cost per unit against the number of units, shared and separate binaries, 1 and 2
    // threads (docs/scaling.md).
    let der = root().join("dist").join("default").join("dvpp_der.fmu");
    let systems = root().join("target").join("bench").join("scale");
    let _ = std::fs::remove_dir_all(&systems);
    c.arg(format!(
        "scale|{}|3,48,192,768|200000|{}",
        der.display(),
        systems.display()
    ));
    run(&mut c)?;
    run(master_binary("bench").arg(format!(
        "results|192 DER units|{}|1",
        systems.join("n192").display()
    )))?;
    // Our master against HELICS federations of the same systems (docs/scaling.md).
    federation::bench(
        &cosim,
        &ssp,
        &der,
        &root().join("target").join("bench").join("federation"),
    )?;
    // The same systems in libcosim, side by side with ours.
    run(Command::new(&python)
        .arg(root().join("tests").join("python").join("bench_scale.py"))
        .arg(&systems)
        .arg(&cosim)
        .arg("200000"))
}

/// The virtual environment with the Python test dependencies, created on first use.
fn python_env() -> Result<PathBuf> {
    let venv = root().join("target").join("venv");
    let python = venv.join("bin").join("python");
    let marker = venv.join(".installed");
    let wanted = PYTHON_PACKAGES.join(" ");
    if std::fs::read_to_string(&marker).ok().as_deref() == Some(wanted.as_str()) && python.exists()
    {
        return Ok(python);
    }
    let system = std::env::var("PYTHON").unwrap_or_else(|_| "python3".into());
    println!("creating {} with {wanted}", venv.display());
    run(Command::new(&system)
        .args(["-m", "venv", "--clear"])
        .arg(&venv))?;
    run(Command::new(&python)
        .args([
            "-m",
            "pip",
            "install",
            "--quiet",
            "--disable-pip-version-check",
        ])
        .args(PYTHON_PACKAGES))?;
    // ANDES generates its models' numerical code on first use (about 40 s): done once here, into
    // the venv's own copy of the package (where ANDES looks after ~/.andes), so that no test
    // pays for it.
    run(Command::new(&python).args([
        "-c",
        "import pathlib, andes, andes.main; \
         andes.main.prepare(quick=True, pycode_path=str(pathlib.Path(andes.__file__).parent / 'pycode'))",
    ]))?;
    std::fs::write(&marker, wanted).map_err(|e| e.to_string())?;
    Ok(python)
}

fn test() -> Result {
    let started = std::time::Instant::now();
    // The lints first (formatting costs a second): clippy.toml forbids the platform's
    // transcendental functions (docs/architecture.md, "Determinism"), and the workspace's
    // `unsafe` lints hold only where clippy runs.
    components(&["rustfmt", "clippy"])?;
    run(cargo().args(["fmt", "--all", "--check"]))?;
    let win64_required = win64::install_for_tests();
    chromium::install_for_tests();
    // Before anything builds the workspace: dvpp-design links OpenBLAS and libgfortran.
    hinf::install();
    run(cargo().args([
        "clippy",
        "--workspace",
        "--all-targets",
        "--quiet",
        "--",
        "-D",
        "warnings",
    ]))?;
    bundle(&[])?;
    let dist = root().join("dist").join("default");
    let cosim = cosim_binary()?;
    // The venv first: the federation test loads libhelics from it.
    let python = python_env()?;
    let mut tests = cargo();
    tests
        .args(["test", "--workspace"])
        .env("DVPP_DIST", &dist)
        .env("DVPP_COSIM", &cosim)
        .env("DVPP_REQUIRE_HELICS", "1")
        .env(chromium::REQUIRE, "1");
    if win64_required {
        tests.env(win64::REQUIRE, "1");
    }
    run(&mut tests)?;
    // The short form of the fuzzer: a fixed seed, a few hundred cases.
    let (cases, seed) = fuzz::SHORT;
    fuzz::fuzz(
        &root(),
        &target_dir(),
        &cosim,
        &[
            "--cases".into(),
            cases.to_string(),
            "--seed".into(),
            seed.to_string(),
        ],
    )?;
    // The 300 s grid dynamics tests are ignored in debug builds; run them optimized.
    run(cargo().args([
        "test",
        "--release",
        "--package",
        "grid-model",
        "--test",
        "dynamics",
    ]))?;
    // The API documentation builds without a warning (a broken intra-doc link, stray HTML).
    run(cargo()
        .args(["doc", "--workspace", "--no-deps", "--quiet"])
        .env("RUSTDOCFLAGS", "-D warnings"))?;
    run(Command::new(&python)
        .args(["-m", "pytest", "-q", "tests/python"])
        .current_dir(root())
        .env("DVPP_DIST", &dist)
        .env("DVPP_COSIM", &cosim))?;
    println!(
        "cargo xtask test: all passed in {:.0} s",
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Install the rustup components `names` where `cargo <name>` does not run (a toolchain
/// installed with rustup's minimal profile has neither rustfmt nor clippy).
fn components(names: &[&str]) -> Result {
    for name in names {
        let sub = if *name == "rustfmt" { "fmt" } else { name };
        let there = cargo()
            .args([sub, "--version"])
            .output()
            .is_ok_and(|o| o.status.success());
        if !there {
            println!("test setup: rustup component add {name}");
            run(Command::new("rustup").args(["component", "add", name]))?;
        }
    }
    Ok(())
}

/// Case study I in DPsim EMT, both events, with the table of docs/emt.md when run in full.
fn emt_case1(args: &[String]) -> Result {
    bundle(&[])?;
    let cosim = cosim_binary()?;
    let python = python_env()?;
    let mut c = Command::new(&python);
    c.arg(root().join("tests").join("python").join("emt_case1.py"))
        .args(args)
        .current_dir(root())
        .env("DVPP_DIST", root().join("dist").join("default"))
        .env("DVPP_COSIM", &cosim);
    // The documented table is the full runs': a shorter or partial run leaves it alone.
    if args.is_empty() {
        c.arg("--docs").arg(root().join("docs").join("emt.md"));
    }
    run(&mut c)
}

fn write_docs() -> Result {
    let path = root().join(docs::VARIABLES);
    let page = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let models: Vec<&str> = FMUS.iter().map(|f| f.model).collect();
    let fresh = docs::replace_section(&page, &docs::section(&root(), &models)?)?;
    std::fs::write(&path, fresh).map_err(|e| e.to_string())?;
    println!("updated the variable tables in {}", docs::VARIABLES);
    Ok(())
}
