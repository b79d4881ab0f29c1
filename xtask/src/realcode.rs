//! The IEEE/Cigré real-code DLLs (realcode/): built with the FMUs' `ship` profile for linux64 and win64, and written to `dist/realcode/` with the C headers their users compile against.

use crate::{cargo, root, run, target_dir, win64, Result};
use std::path::Path;
use std::process::Command;

/// The DLLs: (package, library name in target/, identifier of the shipped file).
pub const DLLS: [(&str, &str, &str); 2] = [
    ("realcode-der-emt", "dvpp_der_emt_dll", "dvpp_der_emt"),
    ("realcode-operator", "dvpp_operator_dll", "dvpp_operator"),
];

fn copy(from: &Path, to: &Path) -> Result {
    std::fs::copy(from, to)
        .map(|_| ())
        .map_err(|e| format!("{} -> {}: {e}", from.display(), to.display()))
}

/// Build the DLLs and write `dist/realcode/`: `linux64/<id>.so`, `win64/<id>.dll` (where the
/// cross toolchain is installed), `include/` (the interface's header and each DLL's) and
/// `params/` (the DER DLL's preset parameter sets).
pub fn bundle() -> Result {
    let mut c = cargo();
    c.args(["build", "--profile", "ship"]);
    for (package, _, _) in DLLS {
        c.args(["--package", package]);
    }
    run(&mut c)?;
    let packages: Vec<&str> = DLLS.iter().map(|d| d.0).collect();
    win64::build(cargo, "ship", &packages)?;
    let out = root().join("dist").join("realcode");
    if out.exists() {
        std::fs::remove_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    }
    for sub in ["linux64", "win64", "include", "params"] {
        std::fs::create_dir_all(out.join(sub)).map_err(|e| e.to_string())?;
    }
    let ship = target_dir().join("ship");
    for (package, lib, id) in DLLS {
        copy(
            &ship.join(format!("lib{lib}.so")),
            &out.join("linux64").join(format!("{id}.so")),
        )?;
        if win64::built() {
            copy(
                &target_dir()
                    .join(win64::TARGET)
                    .join("ship")
                    .join(format!("{lib}.dll")),
                &out.join("win64").join(format!("{id}.dll")),
            )?;
        }
        let describe = ship.join(format!("{package}-describe"));
        run(Command::new(&describe).arg(out.join("include")))?;
    }
    let include = out.join("include");
    let entries = std::fs::read_dir(&include).map_err(|e| e.to_string())?;
    for e in entries.filter_map(|e| e.ok()) {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.ends_with(".params") {
            std::fs::rename(e.path(), out.join("params").join(&name))
                .map_err(|e| format!("{name}: {e}"))?;
        }
    }
    if !win64::built() {
        std::fs::remove_dir(out.join("win64")).map_err(|e| e.to_string())?;
    }
    println!("bundled dist/realcode/ (the IEEE/Cigre real-code DLLs and their headers)");
    Ok(())
}
