//! Scaling out (docs/scaling.md): case1_load as a HELICS federation on loopback (one federate
//! per component, or grouped, also out of SSD order) writes the CSV of our Jacobi master bit for bit; and a system of
//! 20 units as 20 federates. Skipped, with the reason printed, when libhelics is not installed,
//! except under `cargo xtask test`, which installs the `helics` wheel into target/venv first.

use dvpp_cosim::federate::find_library;
use dvpp_cosim::ssp;
use dvpp_e2e::{cosim, fmu_path, scenario};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// libhelics, or `None` after printing why the test is skipped; `cargo xtask test`, which
/// installs it, sets `DVPP_REQUIRE_HELICS` so that a missing library fails instead.
fn helics() -> Option<PathBuf> {
    match find_library(None) {
        Ok(p) => Some(p),
        Err(e) if std::env::var_os("DVPP_REQUIRE_HELICS").is_some() => {
            panic!("DVPP_REQUIRE_HELICS is set: {e}")
        }
        Err(e) => {
            eprintln!("skipped: {e}");
            None
        }
    }
}

fn dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("create the directory");
    d
}

/// Our master (Jacobi, one thread) on `system` to `stop` s into `out`: s it took to initialize
/// and simulate (as it prints it).
fn master(system: &Path, stop: &str, out: &Path) -> f64 {
    let done = Command::new(cosim())
        .arg(system)
        .args([
            "--stop",
            stop,
            "--algorithm",
            "jacobi",
            "--record",
            "all",
            "--out",
        ])
        .arg(out)
        .output()
        .expect("run cosim");
    let stdout = String::from_utf8_lossy(&done.stdout);
    assert!(
        done.status.success(),
        "cosim: {}",
        String::from_utf8_lossy(&done.stderr)
    );
    stdout
        .split_once("initialized and simulated ")
        .and_then(|(_, rest)| rest.split_once(" in ")?.1.split_once(" s")?.0.parse().ok())
        .unwrap_or_else(|| panic!("no run time in: {stdout}"))
}

/// `cosim federation` of `system` to `stop` s with `groups` into `out`: its stdout.
fn federation(system: &Path, stop: &str, groups: Option<&str>, lib: &Path, out: &Path) -> String {
    let mut c = Command::new(cosim());
    c.arg("federation")
        .arg(system)
        .args(["--stop", stop, "--helics-lib"])
        .arg(lib)
        .arg("--out")
        .arg(out);
    if let Some(g) = groups {
        c.args(["--groups", g]);
    }
    let done = c.output().expect("run cosim federation");
    let stdout = String::from_utf8_lossy(&done.stdout).into_owned();
    assert!(
        done.status.success(),
        "cosim federation ({groups:?}): {}\n{stdout}",
        String::from_utf8_lossy(&done.stderr)
    );
    stdout
}

/// The µs per step the federates printed (their stepping loop, from entering executing mode).
fn per_step(stdout: &str) -> Vec<f64> {
    stdout
        .lines()
        .filter(|l| l.contains("HELICS time grants"))
        .filter_map(|l| {
            let (head, _) = l.split_once(" us per step")?;
            head.rsplit('(').next()?.trim().parse().ok()
        })
        .collect()
}

/// The first difference between two CSVs, named by column and time.
fn first_difference(a: &str, b: &str) -> Option<String> {
    let (la, lb): (Vec<&str>, Vec<&str>) = (a.lines().collect(), b.lines().collect());
    if la.len() != lb.len() {
        return Some(format!("{} vs {} lines", la.len(), lb.len()));
    }
    let header: Vec<&str> = la[0].split(',').collect();
    for (ra, rb) in la.iter().zip(&lb) {
        if ra != rb {
            for ((x, y), name) in ra.split(',').zip(rb.split(',')).zip(&header) {
                if x != y {
                    return Some(format!(
                        "{name} at t = {}: {x} vs {y}",
                        &ra[..ra.find(',')?]
                    ));
                }
            }
            return Some(format!("{ra} vs {rb}"));
        }
    }
    None
}

fn assert_same_csv(master: &Path, federation: &Path, what: &str) {
    let a = std::fs::read_to_string(master).expect("the master's CSV");
    let b = std::fs::read_to_string(federation).expect("the federation's CSV");
    if let Some(d) = first_difference(&a, &b) {
        panic!("{what}: the federation's CSV differs from the master's: {d}");
    }
}

#[test]
fn case1_load_as_a_federation_gives_the_masters_results_bit_for_bit() {
    let Some(lib) = helics() else { return };
    let d = dir("federation-case1");
    let system = scenario("case1_load");
    let stop = "1";
    let steps = 1000.0; // 1 s at the system's 1 ms step
    let reference = d.join("master.csv");
    let run = master(&system, stop, &reference);
    eprintln!(
        "master (Jacobi, 1 thread): {:.1} us per step ({steps} steps)",
        run * 1e6 / steps
    );
    for (groups, n) in [
        (None, 5),
        (Some("grid,operator;wind,pv,bess"), 2),
        // Groups out of SSD order (wind alone): the merge restores the master's columns.
        (Some("bess,grid;pv,operator"), 3),
        (Some("grid,operator,wind,pv,bess"), 1),
    ] {
        let out = d.join(format!("federation{n}.csv"));
        let started = Instant::now();
        let stdout = federation(&system, stop, groups, &lib, &out);
        let wall = started.elapsed().as_secs_f64();
        assert_same_csv(&reference, &out, &format!("{n} federates"));
        let each = per_step(&stdout);
        assert_eq!(each.len(), n, "one summary per federate:\n{stdout}");
        eprintln!(
            "{n} federate(s): identical; {:.1} us per step in the federates' loops (slowest), {:.1} us per step process wall time",
            each.iter().cloned().fold(0.0, f64::max),
            wall * 1e6 / steps
        );
    }
}

#[test]
fn a_federate_names_a_missing_library_and_an_unknown_component() {
    let bad = Command::new(cosim())
        .args(["federate"])
        .arg(scenario("case1_load"))
        .args(["--component", "grid", "--broker", "127.0.0.1:9"])
        .args(["--helics-lib", "/nonexistent/libhelics.so"])
        .output()
        .expect("run cosim");
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("--helics-lib /nonexistent/libhelics.so"),
        "{err}"
    );
    let Some(lib) = helics() else { return };
    let started = Instant::now();
    let bad = Command::new(cosim())
        .args(["federate"])
        .arg(scenario("case1_load"))
        .args([
            "--component",
            "nosuch",
            "--broker",
            "127.0.0.1:9",
            "--helics-lib",
        ])
        .arg(&lib)
        .output()
        .expect("run cosim");
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("--component nosuch"), "{err}");
    eprintln!("unknown component refused in {:?}", started.elapsed());
}

/// A system of `n` units of the DER FMU, unconnected (as the scale bench writes them).
fn units(n: usize, dir: &Path) -> PathBuf {
    let sys = dir.join(format!("units{n}"));
    ssp::write_copies(&fmu_path("dvpp_der"), n, &sys, 1e-3).unwrap_or_else(|e| panic!("{e}"));
    sys
}

#[test]
fn twenty_units_as_twenty_federates() {
    let Some(lib) = helics() else { return };
    let d = dir("federation-20");
    let system = units(20, &d);
    // 50 steps: 20 processes time-share the cores of a test machine (docs/scaling.md).
    let (stop, steps) = ("0.05", 50.0);
    let reference = d.join("master.csv");
    let run = master(&system, stop, &reference);
    eprintln!("20 units, master: {:.1} us per step", run * 1e6 / steps);
    let halves = format!(
        "{};{}",
        (1..=10)
            .map(|k| format!("unit{k}"))
            .collect::<Vec<_>>()
            .join(","),
        (11..=20)
            .map(|k| format!("unit{k}"))
            .collect::<Vec<_>>()
            .join(",")
    );
    for (groups, n) in [(None, 20), (Some(halves.as_str()), 2)] {
        let out = d.join(format!("federation{n}.csv"));
        let started = Instant::now();
        let stdout = federation(&system, stop, groups, &lib, &out);
        let wall = started.elapsed().as_secs_f64();
        assert_same_csv(&reference, &out, &format!("20 units, {n} federates"));
        let each = per_step(&stdout);
        eprintln!(
            "20 units, {n} federates: identical; {:.1} us per step in the federates' loops (slowest), {:.1} us per step process wall time",
            each.iter().cloned().fold(0.0, f64::max),
            wall * 1e6 / steps
        );
    }
}

#[test]
fn two_federations_started_at_the_same_moment_both_give_the_masters_results() {
    let Some(lib) = helics() else { return };
    let d = dir("federation-twins");
    let system = scenario("case1_load");
    let stop = "0.05";
    let reference = d.join("master.csv");
    master(&system, stop, &reference);
    for round in 0..3 {
        let runs: Vec<_> = (0..2)
            .map(|k| {
                let (system, lib) = (system.clone(), lib.clone());
                let out = d.join(format!("twin{round}-{k}.csv"));
                std::thread::spawn(move || {
                    federation(&system, stop, None, &lib, &out);
                    out
                })
            })
            .collect();
        for r in runs {
            let out = r.join().expect("a federation failed");
            assert_same_csv(&reference, &out, "a federation beside another");
        }
    }
}

#[test]
fn a_federate_without_a_broker_fails_within_the_join_deadline_naming_the_broker() {
    let Some(lib) = helics() else { return };
    // A port that was free a moment ago: nothing listens there.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a port")
        .port();
    let broker = format!("127.0.0.1:{port}");
    let started = Instant::now();
    let done = Command::new(cosim())
        .arg("federate")
        .arg(scenario("case1_load"))
        .args(["--component", "grid", "--broker", &broker, "--helics-lib"])
        .arg(&lib)
        .output()
        .expect("run cosim");
    let took = started.elapsed();
    assert!(!done.status.success());
    let err = String::from_utf8_lossy(&done.stderr);
    let deadline = dvpp_cosim::federate::JOIN_TIMEOUT;
    assert!(
        err.contains(&format!("cannot join the federation at broker {broker}"))
            && err.contains(&format!("within {} s", deadline.as_secs())),
        "{err}"
    );
    assert!(
        took < deadline + std::time::Duration::from_secs(10),
        "gave up after {took:?}"
    );
    eprintln!("no broker at {broker}: refused in {took:?}");
}

/// The processes whose parent is `pid` (Linux /proc).
fn children(pid: u32) -> Vec<u32> {
    let Ok(all) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    all.filter_map(|e| e.ok()?.file_name().to_str()?.parse::<u32>().ok())
        .filter(|p| {
            std::fs::read_to_string(format!("/proc/{p}/stat"))
                .ok()
                .and_then(|s| {
                    // `pid (comm) state ppid ...`: the comm may hold spaces.
                    let rest = s.rsplit_once(')')?.1;
                    rest.split_whitespace().nth(1)?.parse::<u32>().ok()
                })
                == Some(pid)
        })
        .collect()
}

/// Whether process `pid` still runs (a zombie does not).
fn alive(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat")).is_ok_and(|s| {
        s.rsplit_once(')')
            .and_then(|(_, rest)| rest.split_whitespace().next())
            .is_some_and(|state| state != "Z")
    })
}

#[test]
fn a_terminated_federation_stops_its_broker_and_its_federates() {
    let Some(lib) = helics() else { return };
    let d = dir("federation-sigterm");
    for signal in [libc::SIGTERM, libc::SIGHUP, libc::SIGKILL] {
        let mut launcher = Command::new(cosim())
            .arg("federation")
            .arg(scenario("case1_load"))
            .args(["--stop", "20", "--helics-lib"])
            .arg(&lib)
            .arg("--out")
            .arg(d.join(format!("stopped{signal}.csv")))
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("start cosim federation");
        // The broker and the five federates.
        let since = Instant::now();
        let mut kids = Vec::new();
        while kids.len() < 6 {
            assert!(
                since.elapsed().as_secs() < 60,
                "the federation did not start: {kids:?}"
            );
            std::thread::sleep(std::time::Duration::from_millis(50));
            kids = children(launcher.id());
        }
        std::thread::sleep(std::time::Duration::from_millis(500));
        // SAFETY: a signal to our own child.
        assert_eq!(unsafe { libc::kill(launcher.id() as i32, signal) }, 0);
        let status = launcher.wait().expect("wait for the launcher");
        assert!(!status.success(), "signal {signal}: {status}");
        let since = Instant::now();
        while kids.iter().any(|&k| alive(k)) {
            assert!(
                since.elapsed().as_secs() < 10,
                "signal {signal}: still running after the launcher ended: {:?}",
                kids.iter().filter(|&&k| alive(k)).collect::<Vec<_>>()
            );
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        if signal != libc::SIGKILL {
            let mut err = String::new();
            use std::io::Read;
            launcher
                .stderr
                .take()
                .expect("stderr")
                .read_to_string(&mut err)
                .expect("read stderr");
            assert!(err.contains("stopped by signal"), "{err}");
        }
    }
}
