//! `dvpp-study`: runs a case study on the bundled systems (`cargo xtask demo | sweep | case3 |
//! outage` bundle first, then run this binary in release).

use std::path::PathBuf;
use std::process::ExitCode;

const USAGE: &str = "usage: dvpp-study [--root DIR] <study> [ARGS]

Runs a case study on the systems `cargo xtask bundle` wrote to DIR/dist/ (DIR: the workspace
root, default the current directory); results go to DIR/results/, figures to DIR/tests/figures/,
tables to DIR/docs/case-studies.md (sweep and case3 with their default N and seed).

studies:
  demo                       case study I (case1_load, case1_cloud), then case study III
  case3 [--draws N] [--seed S]
                             case study III and its R/X Monte Carlo (default 24 draws, seed 1)
  sweep [--runs N] [--seed S]
                             case study II over ε with N (default 20) Monte Carlo load steps
                             per family (at bus 2, at a random bus; seed 1)
  outage                     case study II's outage of SG1 and SG3, a verdict per ε
  ride-through [--only TEXT] case study I's DVPP at EMT level through the grid codes' events
                             (dips, faults, 25° jumps, 5 Hz/s) per option, mode and SCR
  qualify [--only TEXT]      the grid-forming qualification suite: each preset unit alone and
                             case study I's DVPP through the grid codes' tests, per option and
                             mode; results/qualification.html and the matrix of
                             docs/qualification.md";

fn main() -> ExitCode {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut root = PathBuf::from(".");
    if args.first().map(String::as_str) == Some("--root") {
        let Some(dir) = args.get(1) else {
            eprintln!("{USAGE}");
            return ExitCode::FAILURE;
        };
        root = PathBuf::from(dir);
        args.drain(..2);
    }
    let result = match args.first().map(String::as_str) {
        Some("demo") if args.len() == 1 => dvpp_studies::demo::demo(&root),
        Some("case3") => dvpp_studies::case3::case3(&root, &args[1..]),
        Some("sweep") => dvpp_studies::sweep::sweep(&root, &args[1..]),
        Some("outage") if args.len() == 1 => dvpp_studies::outage::outage(&root).map(|_| ()),
        Some("ride-through") => dvpp_studies::ride_through::ride_through(&root, &args[1..]),
        Some("qualify") => dvpp_studies::qualify::qualify(&root, &args[1..]),
        _ => Err(USAGE.into()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("dvpp-study: {e}");
            ExitCode::FAILURE
        }
    }
}
