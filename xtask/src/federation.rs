//! `cargo xtask bench`'s federation part: µs per macro step of our master and of HELICS
//! federations of 1, 2, 5 and 20 federates, measured side by side in one run.

use std::path::Path;
use std::process::Command;

/// The µs per step `cosim` prints after initialization (master), or the slowest federate's
/// loop (federation).
fn per_step(stdout: &str, federation: bool) -> Option<f64> {
    let key = if federation {
        " us per step; "
    } else {
        " µs per step after initialization"
    };
    stdout
        .lines()
        .filter_map(|l| {
            let (head, _) = l.split_once(key)?;
            head.rsplit(['(', ' ']).next()?.trim().parse::<f64>().ok()
        })
        .fold(None, |m: Option<f64>, x| Some(m.map_or(x, |m| m.max(x))))
}

/// Run `cosim ARGS`, its stdout, or the error with its stderr.
fn cosim(exe: &Path, args: &[&str]) -> Result<String, String> {
    let done = Command::new(exe)
        .args(args)
        .output()
        .map_err(|e| format!("{}: {e}", exe.display()))?;
    if !done.status.success() {
        return Err(format!(
            "cosim {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&done.stderr)
        ));
    }
    Ok(String::from_utf8_lossy(&done.stdout).into_owned())
}

/// Case study I (1 s at 1 ms) as 1, 2 and 5 federates and 20 unconnected DER units as 2 and 20
/// federates, each against our master on the same system, into a table on stdout.
pub fn bench(exe: &Path, case1: &Path, der: &Path, work: &Path) -> Result<(), String> {
    std::fs::create_dir_all(work).map_err(|e| format!("{}: {e}", work.display()))?;
    let units = work.join("units20");
    let _ = std::fs::remove_dir_all(&units);
    dvpp_cosim::ssp::write_copies(der, 20, &units, 1e-3)?;
    let halves = |a: usize, b: usize| {
        (a..=b)
            .map(|k| format!("unit{k}"))
            .collect::<Vec<_>>()
            .join(",")
    };
    let twenty = format!("{};{}", halves(1, 10), halves(11, 20));
    let runs: [(&str, &Path, &str, Option<&str>, usize); 5] = [
        (
            "case1_load",
            case1,
            "1",
            Some("grid,operator,wind,pv,bess"),
            1,
        ),
        (
            "case1_load",
            case1,
            "1",
            Some("grid,operator;wind,pv,bess"),
            2,
        ),
        ("case1_load", case1, "1", None, 5),
        ("20 DER units", &units, "0.2", Some(&twenty), 2),
        ("20 DER units", &units, "0.2", None, 20),
    ];
    println!(
        "\nHELICS federations on this machine (tcpss core, global time coordinator), µs per step:"
    );
    println!("| system | master | federates | federation | × master |");
    println!("|---|---:|---:|---:|---:|");
    for (label, system, stop, groups, n) in runs {
        let sys = system.to_str().ok_or("a non-UTF-8 path")?;
        let csv = work.join("out.csv");
        let csv = csv.to_str().ok_or("a non-UTF-8 path")?;
        let master = cosim(
            exe,
            &[sys, "--stop", stop, "--algorithm", "jacobi", "--no-csv"],
        )?;
        let m = per_step(&master, false).ok_or(format!("no time per step in: {master}"))?;
        let mut args = vec!["federation", sys, "--stop", stop, "--out", csv];
        if let Some(g) = groups {
            args.extend(["--groups", g]);
        }
        let fed = cosim(exe, &args)?;
        let f = per_step(&fed, true).ok_or(format!("no time per step in: {fed}"))?;
        println!("| {label} | {m:.1} | {n} | {f:.1} | {:.0} |", f / m);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::per_step;

    #[test]
    fn reads_the_masters_and_the_slowest_federates_time_per_step() {
        let fed = "fed0: loaded in 0.1 s; 200 steps in 0.5 s (2600.5 us per step; 4 HELICS time grants per step, 2 initialization passes)\n\
                   fed1: loaded in 0.1 s; 200 steps in 0.5 s (2700.0 us per step; 2 HELICS time grants per step, 2 initialization passes)\n";
        assert_eq!(per_step(fed, true), Some(2700.0));
        assert_eq!(per_step(fed, false), None);
        let master = "case1_load: loaded in 0.142 s; initialized and simulated 0.2 s in 0.001 s (168x real time); 5.21 µs per step after initialization";
        assert_eq!(per_step(master, false), Some(5.21));
    }
}
