//! Mutation test of the SSP reader and the master: malformed variants of a shipped scenario's
//! SSD and parameter bindings (`dvpp_e2e::mutate::fixed`), each run by the `cosim` binary. Every
//! mutant must either run with results identical to the original or be refused with one line;
//! none may panic or die of a signal. The count of each outcome per class of mutation is printed.

use dvpp_e2e::mutate::{self, Exit};
use dvpp_e2e::{cosim, scenario};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// What a mutant did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Outcome {
    /// Ran, with results identical to the original system's.
    Unchanged,
    /// Refused (exit 1) with one `cosim:` line naming what is wrong.
    Refused,
    /// Anything else: a panic, a signal, a hang, other results, several or no error lines.
    Bad,
}

struct Runner {
    dir: PathBuf,
    baseline: String,
    count: usize,
}

impl Runner {
    /// Run `ssd` (written next to the unpacked FMUs); returns the outcome and what it printed.
    fn run(&mut self, ssd: &str) -> (Outcome, String) {
        self.count += 1;
        let file = self.dir.join("mutant.ssd");
        let out = self.dir.join("mutant.csv");
        let _ = std::fs::remove_file(&out);
        std::fs::write(&file, ssd).expect("write the mutant");
        let done = mutate::run_with_timeout(
            Command::new(cosim())
                .arg(&file)
                .args(["--stop", "0.02", "--out"])
                .arg(&out),
            Duration::from_secs(60),
        )
        .unwrap_or_else(|e| panic!("{e}"));
        let stderr = done.stderr;
        let errors: Vec<&str> = stderr
            .lines()
            .filter(|l| l.starts_with("cosim: ") && !l.contains("warning"))
            .collect();
        let outcome = match done.exit {
            Exit::Code(0)
                if std::fs::read_to_string(&out).ok().as_deref() == Some(&self.baseline) =>
            {
                Outcome::Unchanged
            }
            Exit::Code(1) if errors.len() == 1 && !stderr.contains("panicked") => Outcome::Refused,
            _ => Outcome::Bad,
        };
        (outcome, format!("{:?}: {stderr}", done.exit))
    }
}

#[test]
fn malformed_systems_are_refused_or_run_unchanged() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("mutants");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create the directory");
    let ssd = mutate::unpack(&scenario("case1_load"), &dir).unwrap_or_else(|e| panic!("{e}"));
    let mut runner = Runner {
        dir: dir.clone(),
        baseline: String::new(),
        count: 0,
    };
    let (first, stderr) = runner.run(&ssd);
    assert_eq!(
        first,
        Outcome::Bad,
        "the original cannot match an empty baseline"
    );
    runner.baseline = std::fs::read_to_string(dir.join("mutant.csv"))
        .unwrap_or_else(|e| panic!("the original system did not run ({e}): {stderr}"));

    let mutants = mutate::fixed(&ssd);

    let mut counts: BTreeMap<(&str, Outcome), usize> = BTreeMap::new();
    let mut bad = Vec::new();
    for m in &mutants {
        let class = m.class;
        let (outcome, stderr) = runner.run(&m.ssd);
        *counts.entry((class, outcome)).or_default() += 1;
        if outcome == Outcome::Bad || (m.must_refuse && outcome != Outcome::Refused) {
            bad.push(format!("[{class}] {outcome:?}: {}", stderr.trim()));
        } else if outcome == Outcome::Refused {
            eprintln!("[{class}] refused: {}", stderr.lines().last().unwrap_or(""));
        }
    }
    println!("{} mutants:", mutants.len());
    for ((class, outcome), n) in &counts {
        println!("  {class:<20} {outcome:?}: {n}");
    }
    assert!(
        bad.is_empty(),
        "mutants handled wrongly:\n{}",
        bad.join("\n\n")
    );
}
