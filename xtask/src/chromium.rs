//! The headless browser the qualification report's test renders the HTML in: Debian's `chromium`, installed for the tests.

use std::path::Path;
use std::process::{Command, Stdio};

/// Debian's package with the browser.
const PACKAGE: &str = "chromium";
/// Set by `cargo xtask test` for the tests: the browser test fails, instead of skipping, when
/// the browser is missing (`tests/tests/qualify.rs` reads it).
pub const REQUIRE: &str = "DVPP_REQUIRE_CHROMIUM";

/// Whether the browser runs, where the test looks for it.
fn installed() -> bool {
    Path::new("/usr/bin/chromium").is_file()
        || Command::new("chromium")
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
}

/// Install the browser if missing (apt-get), saying what it does; goes on on failure (the
/// browser test then fails, as [`REQUIRE`] is set).
pub fn install_for_tests() {
    if installed() {
        return;
    }
    println!(
        "test setup: installing {PACKAGE} with apt-get (the qualification report's browser test)"
    );
    if !crate::apt::install(&[PACKAGE]) {
        println!(
            "test setup: could not install {PACKAGE} with apt-get (not Debian, or not root?); \
             the browser test fails ({REQUIRE} is set)"
        );
    }
}
