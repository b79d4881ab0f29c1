//! Debian packages the tasks need: what is installed (dpkg-query), and installing the rest (apt-get).

use std::process::{Command, Stdio};

/// Run `program args`, returning whether it succeeded; its output goes to the terminal.
pub fn try_run(program: &str, args: &[&str]) -> bool {
    println!("test setup: {program} {}", args.join(" "));
    Command::new(program)
        .args(args)
        .env("DEBIAN_FRONTEND", "noninteractive")
        .status()
        .is_ok_and(|s| s.success())
}

/// Whether dpkg knows `package` as installed (false where there is no dpkg).
pub fn installed(package: &str) -> bool {
    Command::new("dpkg-query")
        .args(["-W", "-f=${Status}", package])
        .stderr(Stdio::null())
        .output()
        .is_ok_and(|o| {
            o.status.success()
                && String::from_utf8_lossy(&o.stdout).ends_with("install ok installed")
        })
}

/// Install `packages` with apt-get (quietly, without recommends); when that fails, update the
/// package lists once (a fresh machine may have none) and try again. Returns whether they are
/// installed; says what it does.
pub fn install(packages: &[&str]) -> bool {
    let mut args = vec!["install", "-y", "-qq", "--no-install-recommends"];
    args.extend(packages);
    try_run("apt-get", &args)
        || (try_run("apt-get", &["update", "-qq"]) && try_run("apt-get", &args))
}
