//! The FMUs' win64 binaries under wine against their linux64 binaries: one C master (tests/wine/master.c), built for both, steps each bundled FMU with the same varied inputs and every output must agree.

use dvpp_e2e::{dist, root, IDS};
use model_description::{Causality, ModelDescription, VariableKind};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::Command;

const STEPS: usize = 2000;
const STEP_SIZE: f64 = 1e-3;
/// Largest difference allowed between the two platforms (relative for values above 1).
const TOLERANCE: f64 = 1e-12;
const MINGW: &str = "x86_64-w64-mingw32-gcc";

/// Print a line the test harness does not capture (the reason of a skip, the measured result).
fn say(line: &str) {
    let _ = writeln!(std::io::stderr(), "{line}");
}

/// Set by `cargo xtask test` (which installs wine and mingw-w64 and bundles the win64 binaries):
/// then anything missing fails the test instead of skipping it.
const REQUIRE: &str = "DVPP_REQUIRE_WIN64";

/// Skip the test, printing `reason`; or, with [`REQUIRE`] set, fail with it.
fn skip(reason: &str) {
    if std::env::var_os(REQUIRE).is_some_and(|v| !v.is_empty() && v != "0") {
        panic!("{REQUIRE} is set: {reason}");
    }
    say(&format!("win64 test skipped: {reason}"));
}

/// Whether `program --version` runs.
fn runs(program: &str) -> bool {
    Command::new(program)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// The 64-bit wine loader: `wine64` on the PATH, Debian's `/usr/lib/wine/wine64`, or `wine`.
fn wine() -> Option<PathBuf> {
    if runs("wine64") {
        return Some("wine64".into());
    }
    let debian = Path::new("/usr/lib/wine/wine64");
    if debian.is_file() {
        return Some(debian.into());
    }
    runs("wine").then(|| "wine".into())
}

/// `path` as wine sees it: drive `Z:` is the Unix root.
fn windows_path(path: &Path) -> String {
    format!("Z:{}", path.display()).replace('/', "\\")
}

/// The spellings of a local file URI that RFC 8089 allows, one per FMU: `file:///`, `file:/`,
/// `file://localhost/` before the path.
const URI_FORMS: [&str; 3] = ["file://", "file:", "file://localhost"];

/// A `file:` URI of the absolute `path` (`/a b` or `Z:\a b`), percent-encoded, in `form`.
fn file_uri(path: &str, form: &str) -> String {
    let path = path.replace('\\', "/");
    let mut uri = String::from(form);
    if !path.starts_with('/') {
        uri.push('/');
    }
    for b in path.bytes() {
        if b.is_ascii_alphanumeric() || b"/-_.~:".contains(&b) {
            uri.push(b as char);
        } else {
            uri.push_str(&format!("%{b:02X}"));
        }
    }
    uri
}

/// Compile `sources` with `compiler` into `out`; panics with the compiler's message on failure.
fn compile(compiler: &str, sources: &[PathBuf], args: &[&str], out: &Path) {
    let output = Command::new(compiler)
        .args(["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(root().join("fmi2").join("include"))
        .args(sources)
        .arg("-o")
        .arg(out)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {compiler}: {e}"));
    assert!(
        output.status.success(),
        "{compiler} {:?} failed:\n{}",
        sources,
        String::from_utf8_lossy(&output.stderr)
    );
}

/// The master's arguments after the library: GUID, the inputs `vr:lo:hi` (each around its start
/// value, within its bounds) and the Real outputs.
fn inputs_and_outputs(md: &ModelDescription) -> (String, String) {
    let mut inputs = Vec::new();
    let mut outputs = Vec::new();
    for v in &md.model_variables.variables {
        let VariableKind::Real(r) = &v.kind else {
            continue;
        };
        match v.causality() {
            Causality::Input => {
                let start = r.start.unwrap_or(0.0);
                let width = 0.05 * start.abs().max(0.2);
                let lo = (start - width).max(r.min.unwrap_or(f64::MIN));
                let hi = (start + width).min(r.max.unwrap_or(f64::MAX));
                inputs.push(format!("{}:{lo:e}:{hi:e}", v.value_reference));
            }
            Causality::Output => outputs.push(v.value_reference.to_string()),
            _ => {}
        }
    }
    let inputs = if inputs.is_empty() {
        "-".into()
    } else {
        inputs.join(",")
    };
    (inputs, outputs.join(","))
}

/// Run a master; its output as one row of values per step (checks the closing "done").
fn rows(cmd: &mut Command, what: &str) -> Vec<Vec<f64>> {
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("{what}: cannot start: {e}"));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.trim_end().ends_with("done"),
        "{what}: {}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
        .lines()
        .map(str::trim)
        .take_while(|l| *l != "done")
        .map(|l| {
            l.split_whitespace()
                .map(|h| f64::from_bits(u64::from_str_radix(h, 16).expect("16 hex digits")))
                .collect()
        })
        .collect()
}

#[test]
fn win64_binaries_under_wine_match_linux64() {
    let Some(wine) = wine() else {
        skip("no wine (apt-get install wine64; `cargo xtask test` installs it)");
        return;
    };
    if !runs(MINGW) {
        skip(&format!(
            "no {MINGW} to build the test master (apt-get install \
             gcc-mingw-w64-x86-64-win32; `cargo xtask test` installs it)"
        ));
        return;
    }
    // Unpack each FMU under a directory with a space, so the resource URI is percent-encoded.
    let work = Path::new(env!("CARGO_TARGET_TMPDIR")).join("win64 test");
    let _ = std::fs::remove_dir_all(&work);
    let mut fmus = Vec::new();
    for id in IDS {
        let path = dist().join(format!("{id}.fmu"));
        let file = std::fs::File::open(&path)
            .unwrap_or_else(|e| panic!("{}: {e} (run `cargo xtask bundle`)", path.display()));
        let mut zip = zip::ZipArchive::new(file).expect("an FMU is a zip archive");
        if zip.by_name(&format!("binaries/win64/{id}.dll")).is_err() {
            skip(&format!(
                "{} has no binaries/win64/{id}.dll (bundled without the \
                 x86_64-pc-windows-gnu target or mingw-w64; see `cargo xtask bundle`'s output)",
                path.display()
            ));
            return;
        }
        let mut xml = String::new();
        zip.by_name("modelDescription.xml")
            .expect("modelDescription.xml")
            .read_to_string(&mut xml)
            .expect("UTF-8");
        let dir = work.join(id);
        zip.extract(&dir).expect("unpack the FMU");
        fmus.push((id, dir, ModelDescription::from_xml(&xml).expect("parse")));
    }

    // The master for both platforms; next to the Windows one, the test-only stand-in for the
    // bcryptprimitives.dll that wine 8 lacks (found there first when the FMU's DLL is loaded).
    let src = root().join("tests").join("wine");
    let bin = work.join("master");
    std::fs::create_dir_all(&bin).expect("create the master's directory");
    let (native, exe) = (bin.join("master"), bin.join("master.exe"));
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    compile(&cc, &[src.join("master.c")], &["-ldl"], &native);
    compile(MINGW, &[src.join("master.c")], &[], &exe);
    compile(
        MINGW,
        &[src.join("bcryptprimitives.c")],
        &["-shared", "-ladvapi32"],
        &bin.join("bcryptprimitives.dll"),
    );
    let prefix = Path::new(env!("CARGO_TARGET_TMPDIR")).join("wineprefix");

    let mut worst_overall: f64 = 0.0;
    for ((id, dir, md), &form) in fmus.iter().zip(URI_FORMS.iter().cycle()) {
        let (inputs, outputs) = inputs_and_outputs(md);
        let resources = dir.join("resources");
        let common = |c: &mut Command, library: String, uri: &str| {
            c.arg(library)
                .arg(&md.guid)
                .arg(uri)
                .arg(format!("{STEP_SIZE:e}"))
                .arg(STEPS.to_string())
                .arg(&inputs)
                .arg(&outputs);
        };
        let mut linux = Command::new(&native);
        let so = dir
            .join("binaries")
            .join("linux64")
            .join(format!("{id}.so"));
        common(
            &mut linux,
            so.display().to_string(),
            &file_uri(&resources.display().to_string(), form),
        );
        let dll = dir.join("binaries").join("win64").join(format!("{id}.dll"));
        let mut windows = Command::new(&wine);
        windows
            .arg(&exe)
            .env("WINEPREFIX", &prefix)
            .env("WINEDEBUG", "-all")
            // No Mono or Gecko installer prompts when the prefix is made.
            .env("WINEDLLOVERRIDES", "mscoree,mshtml=");
        let uri = file_uri(&windows_path(&resources), form);
        assert!(uri.contains("/Z:/") && uri.contains("%20"), "{uri}");
        common(&mut windows, windows_path(&dll), &uri);

        let a = rows(&mut linux, &format!("{id}: linux64 master"));
        let b = rows(&mut windows, &format!("{id}: win64 master under wine"));
        assert_eq!(a.len(), STEPS, "{id}: linux64 steps");
        assert_eq!(b.len(), STEPS, "{id}: win64 steps");
        let names: Vec<&str> = md
            .model_variables
            .variables
            .iter()
            .filter(|v| {
                v.causality() == Causality::Output && matches!(v.kind, VariableKind::Real(_))
            })
            .map(|v| v.name.as_str())
            .collect();
        let (mut worst, mut at, mut exact) = (0.0_f64, (0, 0), 0usize);
        for (k, (ra, rb)) in a.iter().zip(&b).enumerate() {
            assert_eq!(ra.len(), names.len(), "{id}: outputs at step {k}");
            assert_eq!(rb.len(), names.len(), "{id}: outputs at step {k}");
            for (j, (x, y)) in ra.iter().zip(rb).enumerate() {
                if x.to_bits() == y.to_bits() {
                    exact += 1;
                    continue;
                }
                let d = (x - y).abs() / x.abs().max(1.0);
                assert!(
                    d <= TOLERANCE,
                    "{id}: {} differs at step {k}: linux64 {x:e}, win64 {y:e}",
                    names[j]
                );
                if d > worst {
                    (worst, at) = (d, (k, j));
                }
            }
        }
        let total = STEPS * names.len();
        say(&format!(
            "{id}: win64 under wine vs linux64, {STEPS} steps x {} outputs, resources at {uri}: \
             largest difference {worst:e}{}; {exact} of {total} values bit-identical",
            names.len(),
            if worst > 0.0 {
                format!(" ({} at step {})", names[at.1], at.0)
            } else {
                String::new()
            }
        ));
        worst_overall = worst_overall.max(worst);
    }
    assert!(worst_overall <= TOLERANCE);
}
