//! The FMUs' win64 binaries: the cross toolchain (Rust target and mingw-w64 linker), the cross-build, and its installation for the tests.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;

/// The Rust target of the `binaries/win64/<id>.dll` the FMUs carry.
pub const TARGET: &str = "x86_64-pc-windows-gnu";
/// The linker rustc uses for [`TARGET`] (its default; from mingw-w64).
pub const LINKER: &str = "x86_64-w64-mingw32-gcc";
/// Debian's package with [`LINKER`] (win32 threads: the DLLs need no libwinpthread).
const LINKER_PACKAGE: &str = "gcc-mingw-w64-x86-64-win32";
/// Debian's package with the wine that runs the win64 binaries in the tests.
const WINE_PACKAGE: &str = "wine64";
/// Set to `0` to bundle linux64 only even where the cross toolchain is installed.
pub const SWITCH: &str = "DVPP_WIN64";
/// Set by `cargo xtask test` for the tests: the wine test fails, instead of skipping, when wine,
/// mingw-w64 or the FMUs' win64 binaries are missing.
pub const REQUIRE: &str = "DVPP_REQUIRE_WIN64";

/// Whether this run of xtask built the win64 binaries (set by [`build`]).
static BUILT: OnceLock<bool> = OnceLock::new();

/// Whether [`build`] produced the win64 binaries in this run.
pub fn built() -> bool {
    BUILT.get().copied().unwrap_or(false)
}

/// The DLL of `package` built by [`build`] with `profile`.
pub fn library(target_dir: &Path, profile: &str, package: &str) -> PathBuf {
    target_dir
        .join(TARGET)
        .join(profile)
        .join(format!("{}.dll", package.replace('-', "_")))
}

/// Whether rustc has the standard library of [`TARGET`].
fn target_installed() -> bool {
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    Command::new(rustc)
        .args(["--print", "sysroot"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| {
            let sysroot = String::from_utf8_lossy(&o.stdout).trim().to_owned();
            Path::new(&sysroot)
                .join("lib")
                .join("rustlib")
                .join(TARGET)
                .join("lib")
                .is_dir()
        })
        .unwrap_or(false)
}

/// Whether `program --version` runs.
fn runs(program: &str) -> bool {
    Command::new(program)
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// What of the cross toolchain is missing (empty: nothing).
fn missing() -> Vec<String> {
    let mut out = Vec::new();
    if !target_installed() {
        out.push(format!("the Rust target {TARGET}"));
    }
    if !runs(LINKER) {
        out.push(format!("the linker {LINKER}"));
    }
    out
}

/// Cross-build the cdylibs of `packages` for [`TARGET`] with `profile` when the toolchain is
/// here (and [`SWITCH`] is not `0`); otherwise say in one line what is left out and how to add it.
pub fn build(cargo: impl FnOnce() -> Command, profile: &str, packages: &[&str]) -> crate::Result {
    let off = std::env::var(SWITCH).is_ok_and(|v| v == "0");
    let missing = missing();
    let reason = if off {
        Some(format!("{SWITCH}=0"))
    } else if !missing.is_empty() {
        Some(format!(
            "missing {}; install with `rustup target add {TARGET}` and \
             `apt-get install {LINKER_PACKAGE}`, or run `cargo xtask test`, which installs both",
            missing.join(" and ")
        ))
    } else {
        None
    };
    if let Some(reason) = reason {
        println!("bundle: linux64 binaries only, no binaries/win64 ({reason})");
        let _ = BUILT.set(false);
        return Ok(());
    }
    let mut c = cargo();
    c.args(["build", "--profile", profile, "--target", TARGET, "--lib"]);
    for p in packages {
        c.args(["--package", p]);
    }
    crate::run(&mut c)?;
    let _ = BUILT.set(true);
    Ok(())
}

/// Whether wine (64-bit) is installed, where the wine test looks for it.
fn wine_installed() -> bool {
    runs("wine64") || Path::new("/usr/lib/wine/wine64").is_file() || runs("wine")
}

/// Install what the win64 binaries and their wine test need, if missing: the Rust target (rustup)
/// and mingw-w64 and wine (apt-get). Says what it does and goes on on failure; returns whether
/// the wine test is required (it is, unless [`SWITCH`] is `0`): then `cargo xtask test` sets
/// [`REQUIRE`] and whatever could not be installed fails that test instead of skipping it.
pub fn install_for_tests() -> bool {
    if std::env::var(SWITCH).is_ok_and(|v| v == "0") {
        println!("test setup: {SWITCH}=0, no win64 binaries and no wine test");
        return false;
    }
    if !target_installed() {
        println!("test setup: installing the Rust target {TARGET} for the FMUs' win64 binaries");
        if !crate::apt::try_run("rustup", &["target", "add", TARGET]) {
            println!(
                "test setup: could not install {TARGET} (`rustup target add {TARGET}` failed); \
                 the FMUs get no win64 binaries and the wine test fails ({REQUIRE} is set; \
                 {SWITCH}=0 leaves win64 out on purpose)"
            );
        }
    }
    let mut packages = Vec::new();
    if !runs(LINKER) {
        packages.push(LINKER_PACKAGE);
    }
    if !wine_installed() {
        packages.push(WINE_PACKAGE);
    }
    if packages.is_empty() {
        return true;
    }
    println!(
        "test setup: installing {} with apt-get (the win64 linker, and wine to run the win64 \
         binaries in the tests)",
        packages.join(" ")
    );
    if !crate::apt::install(&packages) {
        println!(
            "test setup: could not install {} with apt-get (not Debian, or not root?); without \
             {LINKER} the FMUs get no win64 binaries, and the wine test fails ({REQUIRE} is set; \
             {SWITCH}=0 leaves win64 out on purpose)",
            packages.join(" ")
        );
    }
    true
}
