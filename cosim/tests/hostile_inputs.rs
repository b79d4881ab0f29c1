//! The `cosim` binary against hostile inputs and outputs: two runs on one `--out`, named pipes
//! in place of the system, the FMU or the results file, and an `--out` that names an input.
//!
//! The systems here have no component (an SSD with an empty system runs, recording the time
//! only), so that no FMU needs to be built.

use dvpp_cosim::tmp::TempDir;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

const EMPTY_SSD: &str = r#"<?xml version="1.0"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" version="1.0" name="empty">
  <ssd:System name="empty">
  </ssd:System>
</ssd:SystemStructureDescription>
"#;

fn cosim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_cosim"))
}

/// A named pipe at `path`.
fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
}

/// Wait for `child` at most `limit`; killed (and the test failed) when it takes longer.
fn wait_at_most(mut child: std::process::Child, limit: Duration, what: &str) -> Output {
    let started = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if started.elapsed() > limit {
            let _ = child.kill();
            let out = child.wait_with_output().unwrap();
            panic!(
                "{what}: still running after {limit:?}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    child.wait_with_output().unwrap()
}

/// The times of a CSV of the empty system, each row checked whole.
fn times(path: &Path) -> Vec<f64> {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(text.ends_with('\n'), "{} ends in a cut row", path.display());
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("time"), "{}", path.display());
    lines.map(|l| l.parse().expect("a number")).collect()
}

/// Whether `times` are 0, h, 2h, … in order, `n` of them.
fn steady(times: &[f64], n: usize, h: f64) -> bool {
    times.len() == n
        && times
            .iter()
            .enumerate()
            .all(|(k, t)| (t - k as f64 * h).abs() < 1e-9 * (1.0 + t.abs()))
}

/// Two runs write one `--out`: the one that completes leaves its own rows, whole, in `--out`;
/// the one interrupted names the file that holds its rows, which exists and holds them whole.
#[test]
fn two_runs_on_one_out_each_keep_their_own_rows() {
    let t = TempDir::new("test-two-runs").unwrap();
    let ssd = t.path().join("empty.ssd");
    std::fs::write(&ssd, EMPTY_SSD).unwrap();
    let out = t.path().join("out.csv");
    // The long run first: it takes out.csv.partial; the short one has to take another name.
    let long = cosim()
        .arg(&ssd)
        .args(["--stop", "1e5", "--step", "1e-3", "--out"])
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let first = t.path().join("out.csv.partial");
    let since = Instant::now();
    while std::fs::metadata(&first).map_or(0, |m| m.len()) < 1 << 16 {
        assert!(since.elapsed() < Duration::from_secs(60), "no rows");
        std::thread::sleep(Duration::from_millis(10));
    }
    let short = cosim()
        .arg(&ssd)
        .args(["--stop", "20", "--step", "1e-3", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(short.status.success(), "{short:?}");
    assert!(steady(&times(&out), 20_001, 1e-3), "the short run's rows");
    // SAFETY: kill(2) on our child, not yet waited for.
    assert_eq!(unsafe { libc::kill(long.id() as i32, libc::SIGINT) }, 0);
    let long = wait_at_most(long, Duration::from_secs(30), "the interrupted run");
    assert_eq!(long.status.code(), Some(130));
    let stderr = String::from_utf8_lossy(&long.stderr);
    let kept = stderr
        .lines()
        .find_map(|l| l.strip_prefix("cosim: incomplete results: "))
        .and_then(|l| l.split(" in ").last())
        .map(PathBuf::from)
        .unwrap_or_else(|| panic!("no kept file named: {stderr}"));
    assert_eq!(kept, first, "{stderr}");
    let kept_times = times(&kept);
    assert!(kept_times.len() > 100, "{}", kept_times.len());
    assert!(steady(&kept_times, kept_times.len(), 1e-3));
    // The completed run's file is still its own.
    assert!(steady(&times(&out), 20_001, 1e-3), "the short run's rows");
}

/// A named pipe as the `.ssp`, the `.fmu` or the `--out` blocked the run for ever in `open()`,
/// deaf to SIGINT and SIGTERM: each is refused at once with one line naming it.
#[test]
fn a_named_pipe_as_the_system_the_fmu_or_the_out_is_refused_at_once() {
    let t = TempDir::new("test-fifos").unwrap();
    let ssd = t.path().join("empty.ssd");
    std::fs::write(&ssd, EMPTY_SSD).unwrap();
    let (ssp, fmu, out) = (
        t.path().join("system.ssp"),
        t.path().join("unit.fmu"),
        t.path().join("out.csv"),
    );
    for p in [&ssp, &fmu, &out] {
        mkfifo(p);
    }
    let cases: [(&Path, &Path, &str); 3] = [
        (&ssp, &ssp, "not a regular file: a named pipe"),
        (&fmu, &fmu, "not a regular file: a named pipe"),
        (&ssd, &out, "a named pipe that nothing reads"),
    ];
    let results = t.path().join("r.csv");
    for (system, named, why) in cases {
        let child = cosim()
            .arg(system)
            .args(["--stop", "1", "--step", "1e-3", "--out"])
            .arg(if system == ssd { &out } else { &results })
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let output = wait_at_most(child, Duration::from_secs(10), why);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(
            stderr.contains(&named.display().to_string()) && stderr.contains(why),
            "{stderr}"
        );
    }
    // The pipes are pipes still, and nothing else was written.
    let mut left: Vec<_> = std::fs::read_dir(t.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    left.sort();
    assert_eq!(left, ["empty.ssd", "out.csv", "system.ssp", "unit.fmu"]);
}

/// A record pattern of the SSP's annotation that matches no output was dropped silently, while
/// the same pattern on `--record` is an error: both are errors now, in the same words.
#[test]
fn a_record_pattern_of_the_annotation_that_matches_nothing_is_an_error() {
    let t = TempDir::new("test-record").unwrap();
    let ssd = t.path().join("recorded.ssd");
    let annotated = EMPTY_SSD.replace(
        "  </ssd:System>\n",
        r#"  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="0.01">
    <ssd:Annotations>
      <ssc:Annotation type="org.dvpp-fmu.record"><Record signals="grid.pcc.*"/></ssc:Annotation>
    </ssd:Annotations>
  </ssd:DefaultExperiment>
"#,
    );
    std::fs::write(&ssd, annotated).unwrap();
    let out = t.path().join("out.csv");
    for extra in [&[][..], &["--record", "grid.pcc.*"][..]] {
        let output = cosim()
            .arg(&ssd)
            .args(["--step", "1e-3"])
            .args(extra)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains("record pattern 'grid.pcc.*'") && stderr.contains("matches no output"),
            "{extra:?}: {stderr}"
        );
        assert_eq!(
            extra.is_empty(),
            stderr.contains("of the system's record annotation"),
            "{stderr}"
        );
        assert!(!out.exists());
    }
}

/// `--out` could name an FMU inside an SSP directory, and a completed run replaced the FMU by
/// its results: an `--out` inside an SSP directory given as the input, or naming a file the
/// system reads, is refused before anything is loaded, and the file is left as it was.
#[test]
fn an_out_inside_the_input_or_naming_an_fmu_it_reads_is_refused() {
    let t = TempDir::new("test-out-input").unwrap();
    let dir = t.path().join("system");
    std::fs::create_dir_all(dir.join("resources")).unwrap();
    let fmu = dir.join("resources/a.fmu");
    std::fs::write(&fmu, "the FMU").unwrap();
    let ssd = EMPTY_SSD.replace(
        "<ssd:System name=\"empty\">",
        "<ssd:System name=\"empty\"><ssd:Elements><ssd:Component name=\"a\" source=\"resources/a.fmu\"/></ssd:Elements>",
    );
    std::fs::write(dir.join("SystemStructure.ssd"), ssd).unwrap();
    let cases: [(PathBuf, PathBuf, &str); 3] = [
        (dir.clone(), fmu.clone(), "lies inside the SSP directory"),
        (
            dir.clone(),
            dir.join("results.csv"),
            "lies inside the SSP directory",
        ),
        (
            dir.join("SystemStructure.ssd"),
            fmu.clone(),
            "is the FMU of component 'a'",
        ),
    ];
    for (system, out, why) in cases {
        let output = cosim()
            .arg(&system)
            .args(["--stop", "1", "--step", "1e-3", "--out"])
            .arg(&out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(why) && stderr.contains("--out"), "{stderr}");
        assert_eq!(std::fs::read_to_string(&fmu).unwrap(), "the FMU");
        assert!(!dir.join("results.csv").exists());
    }
    // Beside the directory is fine (the run then fails on the FMU, which is not one).
    let output = cosim()
        .arg(&dir)
        .args(["--stop", "1", "--step", "1e-3", "--out"])
        .arg(t.path().join("r.csv"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!stderr.contains("--out"), "{stderr}");
    assert_eq!(std::fs::read_to_string(&fmu).unwrap(), "the FMU");
}
