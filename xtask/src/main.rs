//! `cargo xtask`: builds and bundles the FMUs, runs the tests and the demo.

mod catalog;
mod docs;

use catalog::{BENCHES, FMUS, VARIANTS};

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

/// Python packages the tests install into their own virtual environment.
const PYTHON_PACKAGES: &[&str] = &["fmpy==0.3.32", "pytest==8.4.2"];

type Result<T = ()> = std::result::Result<T, String>;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("workspace root")
        .to_path_buf()
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
                  and dist/variants/<id>-<variant>.fmu
  bench    bundle, then measure ns per fmi2DoStep of each benchmark FMU
  demo     bundle, then simulate every default FMU headless; results in results/
  test     bundle, run the Rust tests, then the Python (fmpy) tests in target/venv
  docs     regenerate README.md's variable tables from the FMUs' model descriptions";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("bundle") => bundle(&args[1..]).map(|_| ()),
        Some("demo") => demo(),
        Some("bench") => bench(),
        Some("test") => test(),
        Some("docs") => write_docs(),
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

/// Build the cdylibs and describe binaries of `fmus` in release mode.
fn build_release(fmus: &[&catalog::Fmu]) -> Result {
    let mut c = cargo();
    c.args(["build", "--release"]);
    for fmu in fmus {
        c.args(["--package", fmu.package]);
    }
    run(&mut c)
}

/// Write one `.fmu`: modelDescription.xml from the describe binary, the binary, resources.
fn write_fmu(package: &str, id: &str, resources: &Path, out: &Path) -> Result {
    let release = root().join("target").join("release");
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

    let file = std::fs::File::create(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let mut zip = zip::ZipWriter::new(file);
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .unix_permissions(0o644);
    let mut add = |name: &str, bytes: &[u8]| -> Result {
        zip.start_file(name, options).map_err(|e| e.to_string())?;
        zip.write_all(bytes).map_err(|e| e.to_string())
    };
    add("modelDescription.xml", &output.stdout)?;
    add(&format!("binaries/linux64/{id}.so"), &binary)?;
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
        )?;
    }
    zip.finish().map_err(|e| e.to_string())?;
    Ok(())
}

/// Write a resources directory with `config` and `files`, then the `.fmu` from it.
fn bundle_one(
    package: &str,
    id: &str,
    staging: &str,
    config: &str,
    files: &[&str],
    out: &Path,
) -> Result {
    let resources = root()
        .join("target")
        .join("bundle")
        .join(staging)
        .join("resources");
    if resources.exists() {
        std::fs::remove_dir_all(&resources).map_err(|e| e.to_string())?;
    }
    std::fs::create_dir_all(&resources).map_err(|e| e.to_string())?;
    std::fs::write(resources.join("config.toml"), config).map_err(|e| e.to_string())?;
    for file in files {
        let src = root().join(file);
        let name = src.file_name().ok_or(format!("{file}: not a file"))?;
        std::fs::copy(&src, resources.join(name)).map_err(|e| format!("{}: {e}", src.display()))?;
    }
    write_fmu(package, id, &resources, out)?;
    println!(
        "bundled {}",
        out.strip_prefix(root()).unwrap_or(out).display()
    );
    Ok(())
}

/// Build and bundle the default FMUs (all, or those whose ids are in `only`) into
/// `dist/default/` and their variants into `dist/variants/`; returns the default FMUs' paths.
fn bundle(only: &[String]) -> Result<Vec<PathBuf>> {
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
    for v in VARIANTS
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
        bundle_one(
            fmu.package,
            fmu.id,
            &format!("{}-{}", v.id, v.name),
            v.config,
            v.files,
            &out,
        )?;
    }
    Ok(written)
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

fn bench() -> Result {
    bundle(&[])?;
    let mut c = master_binary("bench");
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
    run(&mut c)
}

fn demo() -> Result {
    let fmus = bundle(&[])?;
    let results = root().join("results");
    std::fs::create_dir_all(&results).map_err(|e| e.to_string())?;
    for fmu in &fmus {
        let stem = fmu.file_stem().unwrap().to_string_lossy().into_owned();
        run(master_binary("cosim")
            .arg(fmu)
            .arg("--out")
            .arg(results.join(format!("{stem}.csv"))))?;
    }
    println!("results in {}", results.display());
    Ok(())
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
    std::fs::write(&marker, wanted).map_err(|e| e.to_string())?;
    Ok(python)
}

fn test() -> Result {
    let started = std::time::Instant::now();
    bundle(&[])?;
    let dist = root().join("dist").join("default");
    run(cargo()
        .args(["test", "--workspace"])
        .env("DVPP_DIST", &dist))?;
    // The 300 s grid dynamics tests are ignored in debug builds; run them optimized.
    run(cargo().args([
        "test",
        "--release",
        "--package",
        "fmu-grid",
        "--test",
        "dynamics",
    ]))?;
    let python = python_env()?;
    run(Command::new(&python)
        .args(["-m", "pytest", "-q", "tests/python"])
        .current_dir(root())
        .env("DVPP_DIST", &dist))?;
    println!(
        "cargo xtask test: all passed in {:.0} s",
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

fn write_docs() -> Result {
    let path = root().join("README.md");
    let readme = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let packages: Vec<&str> = FMUS.iter().map(|f| f.package).collect();
    let fresh = docs::replace_section(&readme, &docs::section(&root(), &packages)?)?;
    std::fs::write(&path, fresh).map_err(|e| e.to_string())?;
    println!("updated the variable tables in README.md");
    Ok(())
}
