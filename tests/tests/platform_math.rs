//! No shipped binary takes a transcendental function from the platform: the FMUs' linux64 and win64 binaries and the `cosim` master import no `sin`, `exp`, `pow`, `hypot`, … from the C library, so their results do not depend on the CPU or the platform.
//!
//! clippy.toml forbids calling the platform's versions from our code; this test catches the
//! calls the lint cannot see (a dependency's, a method that calls one inside). Exact functions
//! (`sqrt`, `floor`, `fmod`, `fma`, …) are allowed: IEEE 754 defines one result for them.

use dvpp_e2e::{cosim, dist, IDS};
use std::io::Read;
use std::process::Command;

/// The C library's transcendental functions (and their `f` and `l` forms): none may be imported.
const FORBIDDEN: &[&str] = &[
    "sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "asinh", "acosh",
    "atanh", "exp", "exp2", "exp10", "expm1", "log", "log2", "log10", "log1p", "logb", "pow",
    "hypot", "cbrt", "sincos", "erf", "erfc", "tgamma", "lgamma", "cexp", "clog", "cpow", "cabs",
    "carg", "csqrt",
];

/// Whether `symbol` (without a version suffix) is a forbidden function.
fn forbidden(symbol: &str) -> bool {
    let name = symbol.split('@').next().unwrap_or(symbol);
    let name = name
        .strip_prefix("__")
        .map_or(name, |n| n.trim_end_matches("_finite"));
    FORBIDDEN.iter().any(|f| {
        name == *f || name.strip_suffix('f') == Some(f) || name.strip_suffix('l') == Some(f)
    })
}

/// The output of `program args` (panics naming what is missing).
fn output(program: &str, args: &[&str]) -> String {
    let out = Command::new(program)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {program}: {e} (binutils)"));
    assert!(out.status.success(), "{program} {args:?}: {}", out.status);
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The undefined dynamic symbols of an ELF file.
fn elf_imports(path: &str) -> Vec<String> {
    output("nm", &["-D", "--undefined-only", path])
        .lines()
        .filter_map(|l| l.split_whitespace().last().map(str::to_string))
        .collect()
}

/// The functions a PE DLL imports (the tables under each "DLL Name" in `objdump -p`). The
/// MinGW runtime links part of its math statically, which no import table shows: the win64
/// test's bit-for-bit comparison with linux64 under wine covers that part.
fn pe_imports(path: &str) -> Option<Vec<String>> {
    let objdump = "x86_64-w64-mingw32-objdump";
    let text = Command::new(objdump).args(["-p", path]).output().ok()?;
    let text = String::from_utf8_lossy(&text.stdout).into_owned();
    // The rows of an import table: "<vma> <hint> <name>" after a "vma: Hint/Ord Member-Name"
    // heading, up to the first row of another shape.
    let mut names = Vec::new();
    let mut in_table = false;
    for line in text.lines() {
        if line.contains("Hint/Ord") {
            in_table = true;
            continue;
        }
        if in_table {
            let w: Vec<&str> = line.split_whitespace().collect();
            match w.as_slice() {
                [_, hint, name, ..] if hint.chars().all(|c| c.is_ascii_digit()) => {
                    names.push(name.to_string())
                }
                _ => in_table = false,
            }
        }
    }
    Some(names)
}

#[test]
fn the_forbidden_names_are_recognized() {
    for s in [
        "sin@GLIBC_2.2.5",
        "exp",
        "powf",
        "hypotl",
        "__exp_finite",
        "atan2",
    ] {
        assert!(forbidden(s), "{s}");
    }
    for s in [
        "sqrt",
        "floor",
        "fmod",
        "fma",
        "memcpy",
        "sinf64x_not",
        "cosmos",
        "expect",
    ] {
        assert!(!forbidden(s), "{s}");
    }
}

#[test]
fn no_shipped_binary_imports_a_platform_transcendental() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("platform_math");
    std::fs::create_dir_all(&dir).unwrap();
    let mut checked = Vec::new();
    let mut bad = Vec::new();
    for id in IDS {
        let path = dist().join(format!("{id}.fmu"));
        let file = std::fs::File::open(&path)
            .unwrap_or_else(|e| panic!("{}: {e} (run `cargo xtask bundle`)", path.display()));
        let mut zip = zip::ZipArchive::new(file).expect("an FMU is a zip archive");
        for (platform, ext) in [("linux64", "so"), ("win64", "dll")] {
            let Ok(mut entry) = zip.by_name(&format!("binaries/{platform}/{id}.{ext}")) else {
                assert_ne!(platform, "linux64", "{id}: no linux64 binary");
                continue;
            };
            let mut bytes = Vec::new();
            entry.read_to_end(&mut bytes).unwrap();
            let out = dir.join(format!("{id}.{ext}"));
            std::fs::write(&out, bytes).unwrap();
            let out = out.display().to_string();
            let imports = if ext == "so" {
                elf_imports(&out)
            } else {
                match pe_imports(&out) {
                    Some(i) => i,
                    None => {
                        eprintln!("{id}.dll not checked: no x86_64-w64-mingw32-objdump");
                        continue;
                    }
                }
            };
            assert!(
                !imports.is_empty(),
                "{id}.{ext}: no imports read (the C runtime at least)"
            );
            bad.extend(
                imports
                    .iter()
                    .filter(|s| forbidden(s))
                    .map(|s| format!("{id}.{ext}: {s}")),
            );
            checked.push(format!("{id}.{ext} ({} imports)", imports.len()));
        }
    }
    let master = cosim().display().to_string();
    let imports = elf_imports(&master);
    bad.extend(
        imports
            .iter()
            .filter(|s| forbidden(s))
            .map(|s| format!("cosim: {s}")),
    );
    checked.push(format!("cosim ({} imports)", imports.len()));
    eprintln!("checked: {}", checked.join(", "));
    assert!(
        bad.is_empty(),
        "platform transcendental functions imported (results would depend on the CPU): {}",
        bad.join(", ")
    );
}
