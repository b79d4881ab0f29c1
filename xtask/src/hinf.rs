//! Option B's synthesis as a task: the solver's BLAS and Fortran runtime installed, then the `dvpp-design` binary run as a process of its own (xtask does not link the solver).

/// Debian's packages the `dvpp-design` package links against: OpenBLAS (the SDP solver's
/// BLAS/LAPACK) and the Fortran runtime OpenBLAS's LAPACK needs (without it the link fails on
/// `-lgfortran`).
pub const PACKAGES: &[&str] = &["libopenblas-dev", "libgfortran-12-dev"];

/// Install [`PACKAGES`] if missing. Says what it does; returns whether they are there (when not,
/// whatever builds `dvpp-design` fails to link, and the message says why).
pub fn install() -> bool {
    let missing: Vec<&str> = PACKAGES
        .iter()
        .copied()
        .filter(|p| !crate::apt::installed(p))
        .collect();
    if missing.is_empty() {
        return true;
    }
    println!(
        "setup: installing {} with apt-get (the BLAS and Fortran runtime of the H-infinity \
         synthesis, package dvpp-design)",
        missing.join(" ")
    );
    let ok = crate::apt::install(&missing);
    if !ok {
        println!(
            "setup: could not install {} with apt-get (not Debian, or not root?); the package \
             dvpp-design will not link until they are installed",
            missing.join(" ")
        );
    }
    ok
}

/// `cargo xtask hinf [ARGS]`: synthesize option B's gains, check them, print the figures and
/// write `dvpp-control/src/converter/hinf_gains.rs` (ARGS go to `dvpp-design`).
pub fn hinf(args: &[String]) -> crate::Result {
    install();
    let mut c = crate::cargo();
    c.args([
        "run",
        "--release",
        "--quiet",
        "--package",
        "dvpp-design",
        "--",
    ]);
    if args.is_empty() {
        c.arg("--write");
    } else {
        c.args(args);
    }
    crate::run(&mut c)
}

/// The synthesis's time for `cargo xtask bench`: `dvpp-design` without `--write` (it prints the
/// checks' figures and the time the SDP took).
pub fn bench() -> crate::Result {
    install();
    crate::run(crate::cargo().args(["run", "--release", "--quiet", "--package", "dvpp-design"]))
}
