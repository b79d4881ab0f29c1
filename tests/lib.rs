//! Shared helpers of the end-to-end tests and the bench: the bundled FMUs and the `cosim` binary (made on demand), loading FMUs, and the foreign C FMUs.

use dvpp_cosim::{Fmu, Instance, Status};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use std::sync::Mutex;

/// The workspace root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the workspace root")
        .to_path_buf()
}

/// Run `cargo` with `args` in the workspace (once per test process for the same `args`).
fn cargo_once(args: &'static [&'static str]) {
    static DONE: Mutex<Vec<&'static [&'static str]>> = Mutex::new(Vec::new());
    let mut done = DONE.lock().unwrap_or_else(|e| e.into_inner());
    if done.contains(&args) {
        return;
    }
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    eprintln!("running cargo {}", args.join(" "));
    let status = Command::new(cargo)
        .args(args)
        .current_dir(root())
        .status()
        .expect("run cargo");
    assert!(status.success(), "cargo {} failed", args.join(" "));
    done.push(args);
}

/// The real-code DLLs and their headers (`dist/realcode/`, written by `cargo xtask bundle`):
/// beside `DVPP_DIST` when that is set, else bundled here (`cargo xtask bundle realcode`).
pub fn realcode_dist() -> PathBuf {
    if let Some(d) = std::env::var_os("DVPP_DIST") {
        let beside = PathBuf::from(d).with_file_name("realcode");
        if beside.is_dir() {
            return beside;
        }
    }
    cargo_once(&["xtask", "bundle", "realcode"]);
    root().join("dist").join("realcode")
}

/// The directory with the default FMUs. `cargo xtask test` bundles them and names the
/// directory in `DVPP_DIST`; without it, `dist/default` of the workspace, bundled here first
/// (`cargo xtask bundle`, the same FMUs and scenarios) so that `cargo test` works on a fresh
/// clone.
pub fn dist() -> PathBuf {
    if let Some(d) = std::env::var_os("DVPP_DIST") {
        return PathBuf::from(d);
    }
    cargo_once(&["xtask", "bundle"]);
    root().join("dist").join("default")
}

/// The bundled scenario systems, `dist/<name>/<name>.ssp` (see [`dist`]).
pub fn scenario(name: &str) -> PathBuf {
    let p = dist()
        .parent()
        .expect("dist/ holds default/")
        .join(name)
        .join(format!("{name}.ssp"));
    assert!(
        p.is_file(),
        "{} is missing: run `cargo xtask bundle`",
        p.display()
    );
    p
}

/// The master's `cosim` binary: `DVPP_COSIM` (set by `cargo xtask test`), or built here.
pub fn cosim() -> PathBuf {
    if let Some(p) = std::env::var_os("DVPP_COSIM") {
        return PathBuf::from(p);
    }
    cargo_once(&[
        "build",
        "--release",
        "--package",
        "dvpp-cosim",
        "--bin",
        "cosim",
    ]);
    std::env::var_os("CARGO_TARGET_DIR")
        .map(|d| root().join(d))
        .unwrap_or_else(|| root().join("target"))
        .join("release")
        .join("cosim")
}

pub mod conformance;
pub mod digest;
pub mod mutate;

/// The model identifiers of every FMU (the workspace's one list, `dvpp-catalog`).
pub use dvpp_catalog::IDS;

/// The DER units of a system (`.ssp` or its directory): the components whose FMU is the DER FMU
/// (model identifier `dvpp_der`), in the order of the SSD (the grid's slot order).
pub fn der_units(system: &Path) -> Result<Vec<String>, String> {
    use std::io::Read;
    let pkg = dvpp_cosim::ssp::read(system).map_err(|e| e.to_string())?;
    let mut units = Vec::new();
    for c in &pkg.system.components {
        let path = pkg.source_path(c);
        let at = |e: String| format!("{}: {e}", path.display());
        let file = std::fs::File::open(&path).map_err(|e| at(e.to_string()))?;
        let mut zip = zip::ZipArchive::new(file).map_err(|e| at(e.to_string()))?;
        let mut xml = String::new();
        zip.by_name("modelDescription.xml")
            .map_err(|e| at(e.to_string()))?
            .read_to_string(&mut xml)
            .map_err(|e| at(e.to_string()))?;
        let md =
            model_description::ModelDescription::from_xml(&xml).map_err(|e| at(e.to_string()))?;
        if md.model_identifier() == Some(dvpp_catalog::id::DER) {
            units.push(c.name.clone());
        }
    }
    Ok(units)
}

/// The studies' check of a result's unit columns, shared with the tests.
pub use dvpp_studies::units_with;

/// Path of a bundled FMU.
pub fn fmu_path(id: &str) -> PathBuf {
    let p = dist().join(format!("{id}.fmu"));
    assert!(
        p.is_file(),
        "{} is missing: run `cargo xtask bundle` (or `cargo xtask test`)",
        p.display()
    );
    p
}

/// Load a bundled FMU.
pub fn load(id: &str) -> Arc<Fmu> {
    Arc::new(Fmu::load(&fmu_path(id)).unwrap_or_else(|e| panic!("{e}")))
}

/// Instantiate, set up and initialize; returns an instance in step mode at t = 0.
pub fn initialized(fmu: &Arc<Fmu>, name: &str) -> Instance {
    let mut i = fmu.instantiate(name).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(i.setup_experiment(0.0, None), Status::Ok);
    assert_eq!(i.enter_initialization_mode(), Status::Ok);
    assert_eq!(i.exit_initialization_mode(), Status::Ok);
    i
}

/// Value references of all Real outputs, in index order.
pub fn real_outputs(fmu: &Fmu) -> Vec<u32> {
    fmu.description
        .model_variables
        .variables
        .iter()
        .filter(|v| {
            v.causality() == model_description::Causality::Output
                && matches!(v.kind, model_description::VariableKind::Real(_))
        })
        .map(|v| v.value_reference)
        .collect()
}

/// Step `n` times by `h` from `t0`, returning the outputs after each step.
pub fn run(i: &mut Instance, vrs: &[u32], t0: f64, h: f64, n: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|k| {
            let t = t0 + k as f64 * h;
            assert_eq!(
                i.do_step(t, h),
                Status::Ok,
                "step at {t}: {:?}",
                i.last_message()
            );
            let mut out = vec![0.0; vrs.len()];
            assert_eq!(i.get_real(vrs, &mut out), Status::Ok);
            out
        })
        .collect()
}

/// The foreign FMUs: plain C in `tests/foreign/` (not built with fmi-export), compiled with
/// the system C compiler and zipped, and the SSP systems of that directory around them.
pub mod foreign {
    use std::io::Write;
    use std::path::{Path, PathBuf};
    use std::process::Command;

    /// (C source stem, model identifier) of each foreign FMU.
    pub const MODELS: [(&str, &str); 3] = [
        ("source", "foreign_source"),
        ("lag", "foreign_lag"),
        ("gain", "foreign_gain"),
    ];

    /// Where the C sources, model descriptions and SSDs are.
    pub fn foreign_dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("foreign")
    }

    /// Compile each model with the shared skeleton and zip `<id>.fmu` (modelDescription.xml and
    /// `binaries/linux64/<id>.so`) into `out_dir`; returns the archives in `MODELS` order.
    pub fn build_foreign(out_dir: &Path) -> Vec<PathBuf> {
        let src = foreign_dir();
        std::fs::create_dir_all(out_dir).expect("create the output directory");
        let compiler = std::env::var("CC").unwrap_or_else(|_| "cc".into());
        MODELS
            .iter()
            .map(|(stem, id)| {
                let so = out_dir.join(format!("{id}.so"));
                let out = Command::new(&compiler)
                    .args(["-shared", "-fPIC", "-O2", "-std=c99"])
                    .args(["-Wall", "-Wextra", "-Werror", "-I"])
                    .arg(super::root().join("fmi2").join("include"))
                    .arg(src.join(format!("{stem}.c")))
                    .arg(src.join("skeleton.c"))
                    .arg("-o")
                    .arg(&so)
                    .arg("-lm")
                    .output()
                    .unwrap_or_else(|e| panic!("cannot run {compiler}: {e}"));
                assert!(
                    out.status.success(),
                    "compiling {stem}.c failed:\n{}",
                    String::from_utf8_lossy(&out.stderr)
                );
                let fmu = out_dir.join(format!("{id}.fmu"));
                let xml = read(&src.join(format!("{stem}.xml")));
                let binary = format!("binaries/linux64/{id}.so");
                write_zip(&fmu, &[("modelDescription.xml", xml), (&binary, read(&so))]);
                fmu
            })
            .collect()
    }

    pub fn read(path: &Path) -> Vec<u8> {
        std::fs::read(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
    }

    /// Write a deflated zip archive with these (name, contents) entries.
    pub fn write_zip(path: &Path, entries: &[(&str, Vec<u8>)]) {
        let file = std::fs::File::create(path)
            .unwrap_or_else(|e| panic!("cannot create {}: {e}", path.display()));
        let mut zip = zip::ZipWriter::new(file);
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated);
        for (name, bytes) in entries {
            zip.start_file(*name, options).expect("zip entry");
            zip.write_all(bytes).expect("zip write");
        }
        zip.finish().expect("zip finish");
    }

    /// `<out>/<name>/` (`SystemStructure.ssd` and `resources/<id>.fmu`) and the same zipped as `<name>.ssp`.
    pub fn system(out: &Path, name: &str, fmus: &[PathBuf]) -> (PathBuf, PathBuf) {
        let dir = out.join(name);
        std::fs::create_dir_all(dir.join("resources")).expect("create the system directory");
        let ssd = read(&foreign_dir().join(format!("{name}.ssd")));
        std::fs::write(dir.join("SystemStructure.ssd"), &ssd).expect("write the SSD");
        let mut entries = vec![("SystemStructure.ssd".to_owned(), ssd)];
        for fmu in fmus {
            let file = fmu.file_name().expect("a file name").to_string_lossy();
            std::fs::copy(fmu, dir.join("resources").join(&*file)).expect("copy the FMU");
            entries.push((format!("resources/{file}"), read(fmu)));
        }
        let ssp = out.join(format!("{name}.ssp"));
        let entries: Vec<(&str, Vec<u8>)> = entries
            .iter()
            .map(|(n, b)| (n.as_str(), b.clone()))
            .collect();
        write_zip(&ssp, &entries);
        (dir, ssp)
    }
}
