//! Bit-identical results on every machine: full-rate results of `case1_load` (phasor) and `emt_island` (EMT), run by `cosim` with every output recorded, against the digests committed in tests/digests/.
//!
//! The FMUs and the master take their transcendental functions from one implementation built
//! into the binaries (`dvpp-math`), so the results depend on the code alone, not on the CPU or
//! the platform's C library. A machine that disagrees fails with the first column and time that
//! differ. After a change that moves results on purpose, `DVPP_BLESS=1 cargo test -p dvpp-e2e
//! --test digest` rewrites the digests (say why in the commit).

use dvpp_e2e::digest::{Digest, Table};
use dvpp_e2e::{cosim, root, scenario};
use std::process::Command;

/// Rows per block of the digest: 1 s of `case1_load` at 1 ms, 0.1 s of `emt_island` at 50 µs.
const SCENARIOS: [(&str, usize); 2] = [("case1_load", 1000), ("emt_island", 2000)];

/// Run `name` in `cosim` recording every output at every communication point; its table.
fn full_rate(name: &str) -> Table {
    let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("digest_{name}.csv"));
    let _ = std::fs::remove_file(&out);
    let run = Command::new(cosim())
        .arg(scenario(name))
        .args(["--record", "all", "--out"])
        .arg(&out)
        .output()
        .expect("start cosim");
    assert!(
        run.status.success(),
        "{name}: cosim {}\n{}",
        run.status,
        String::from_utf8_lossy(&run.stderr)
    );
    Table::read_csv(&out).unwrap_or_else(|e| panic!("{e}"))
}

/// The committed digest of `name`, or with `DVPP_BLESS=1` the file rewritten from `d`.
fn check(name: &str, d: &Digest) {
    let path = root()
        .join("tests")
        .join("digests")
        .join(format!("{name}.txt"));
    if std::env::var_os("DVPP_BLESS").is_some_and(|v| v == "1") {
        let header = format!(
            "{name}: every output of `cosim dist/{name}/{name}.ssp --record all`, {} rows x {} columns.\n\
             FNV-1a 64 of each column's f64 bits, whole and per block of {} rows (tests/digest.rs).\n\
             Written by DVPP_BLESS=1 cargo test -p dvpp-e2e --test digest; checked by the same test.",
            d.rows,
            d.columns.len(),
            d.block
        );
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, d.to_text(&header)).unwrap();
        eprintln!("{name}: wrote {}", path.display());
        return;
    }
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (DVPP_BLESS=1 writes it)", path.display()));
    let expected = Digest::parse(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    if let Some(diff) = d.first_difference(&expected) {
        panic!(
            "{name}: this machine's results differ from {}: {diff}",
            path.display()
        );
    }
    eprintln!(
        "{name}: {} rows x {} columns bit-identical to {}",
        d.rows,
        d.columns.len(),
        path.display()
    );
}

#[test]
fn full_rate_results_match_the_committed_digests() {
    for (name, block) in SCENARIOS {
        let t = full_rate(name);
        check(name, &Digest::of(&t, block));
    }
}
