//! How a run of the `cosim` binary ends: interrupted by SIGINT, SIGTERM or SIGHUP (once or
//! repeatedly), stopped by an FMU error or by a file size limit, it keeps every complete row (and
//! no part of one) in `<out>.partial`, writes no `<out>`, leaves no unpacked FMU behind and says
//! where it stopped. An `--out` that is a directory or the input is refused before the run.

use dvpp_e2e::{cosim, dist, foreign, scenario};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// A fresh directory under the test's target directory.
fn fresh(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create the directory");
    dir
}

/// The rows of a CSV file: header fields, then the rows' fields (each line ends in '\n').
fn rows(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).expect("read the CSV");
    assert!(
        text.ends_with('\n'),
        "the last row of {} is cut",
        path.display()
    );
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .expect("a header")
        .split(',')
        .map(String::from)
        .collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            let r: Vec<f64> = l.split(',').map(|x| x.parse().expect("a number")).collect();
            assert_eq!(r.len(), header.len(), "a row of {} fields: {l}", r.len());
            r
        })
        .collect();
    (header, rows)
}

/// Run `cosim` on `system` with a private TMPDIR, sending `signal` once `<out>.partial` holds
/// at least `after_rows` rows (`None`: let it run).
fn run(system: &Path, args: &[&str], dir: &Path, signal: Option<(&str, usize)>) -> Output {
    run_signals(system, args, dir, signal.map(|(s, n)| (vec![s], n)))
}

/// [`run`] sending the first of `signals`, then the last one every 50 µs until the run ends.
fn run_signals(
    system: &Path,
    args: &[&str],
    dir: &Path,
    signal: Option<(Vec<&str>, usize)>,
) -> Output {
    let tmp = dir.join("tmp");
    std::fs::create_dir_all(&tmp).expect("create TMPDIR");
    let out = dir.join("out.csv");
    let mut child = Command::new(cosim())
        .arg(system)
        .args(args)
        .arg("--out")
        .arg(&out)
        .env("TMPDIR", &tmp)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start cosim");
    if let Some((names, after_rows)) = signal {
        let partial = dir.join("out.csv.partial");
        let started = Instant::now();
        loop {
            let lines = std::fs::read(&partial)
                .map(|b| b.iter().filter(|&&c| c == b'\n').count())
                .unwrap_or(0);
            if lines > after_rows {
                break;
            }
            assert!(
                started.elapsed() < Duration::from_secs(120),
                "no rows after 120 s"
            );
            assert!(
                child.try_wait().expect("poll").is_none(),
                "cosim ended early"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        let number = |name: &str| match name {
            "INT" => libc::SIGINT,
            "TERM" => libc::SIGTERM,
            "HUP" => libc::SIGHUP,
            other => panic!("no signal {other}"),
        };
        let pid = child.id() as i32;
        // SAFETY: kill(2) on our child's pid, not yet waited for (a zombie at worst, never reused).
        let send = |name: &str| assert_eq!(unsafe { libc::kill(pid, number(name)) }, 0);
        send(names[0]);
        // Further signals: the last one over and over while the run stops (the CSV synced, the
        // unpacked FMUs removed), until it has ended.
        if let Some(last) = names.get(1..).and_then(<[&str]>::last) {
            for _ in 0..20_000 {
                std::thread::sleep(Duration::from_micros(50));
                send(last);
                if child.try_wait().expect("poll").is_some() {
                    break;
                }
            }
        }
    }
    let output = child.wait_with_output().expect("wait for cosim");
    let left: Vec<_> = std::fs::read_dir(&tmp)
        .expect("read TMPDIR")
        .map(|e| e.expect("entry").path())
        .collect();
    assert!(left.is_empty(), "temporary files left behind: {left:?}");
    output
}

/// The time in "... at t = X s" of cosim's stderr.
fn stopped_at(stderr: &str, marker: &str) -> f64 {
    let rest = &stderr[stderr
        .find(marker)
        .unwrap_or_else(|| panic!("no '{marker}' in {stderr}"))
        + marker.len()..];
    rest.split_whitespace()
        .next()
        .and_then(|x| x.parse().ok())
        .unwrap_or_else(|| panic!("no time after '{marker}' in {stderr}"))
}

fn interrupted_by(signal: &str, number: i32) {
    interrupted_by_all(&[signal], number);
}

/// Interrupted by `signals` sent back to back; the first one (`number`) is reported.
fn interrupted_by_all(signals: &[&str], number: i32) {
    let dir = fresh(&format!("interrupt-{}", signals.join("-")));
    let ssp = scenario("case1_load");
    let out = run_signals(
        &ssp,
        &["--stop", "600"],
        &dir,
        Some((signals.to_vec(), 2000)),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(128 + number), "{stderr}");
    assert!(
        !dir.join("out.csv").exists(),
        "an interrupted run wrote out.csv"
    );
    let (header, rows) = rows(&dir.join("out.csv.partial"));
    assert_eq!(header[0], "time");
    assert!(header.iter().any(|c| c == "grid.pcc.f"), "{header:?}");
    // Complete rows at every 1 ms communication point from 0 to where it says it stopped.
    let at = stopped_at(&stderr, "at t = ");
    assert!(
        rows.len() > 2000 && at < 600.0,
        "{} rows, stopped at {at}",
        rows.len()
    );
    for (k, r) in rows.iter().enumerate() {
        assert!(
            (r[0] - k as f64 * 1e-3).abs() < 1e-9,
            "row {k} at t = {}",
            r[0]
        );
    }
    assert_eq!(rows.last().map(|r| r[0]), Some(at), "{stderr}");
    assert!(stderr.contains("out.csv.partial"), "{stderr}");
}

#[test]
fn sigint_stops_at_a_communication_point_and_keeps_complete_rows() {
    interrupted_by("INT", 2);
}

#[test]
fn sighup_stops_like_sigterm_and_cleans_up() {
    interrupted_by("HUP", 1);
}

#[test]
fn a_second_sigint_while_stopping_still_cleans_up() {
    interrupted_by_all(&["INT", "INT"], 2);
}

#[test]
fn a_file_size_limit_is_an_error_naming_the_file_and_keeps_whole_rows() {
    let dir = fresh("file-size-limit");
    let tmp = dir.join("tmp");
    std::fs::create_dir_all(&tmp).expect("create TMPDIR");
    let out = dir.join("out.csv");
    // 10000 blocks of 512 or 1024 bytes: more than any unpacked file, a few seconds of rows.
    let output = Command::new("sh")
        .arg("-c")
        .arg("ulimit -f 10000 && exec \"$@\"")
        .arg("sh")
        .arg(cosim())
        .arg(scenario("case1_load"))
        .args(["--stop", "60", "--out"])
        .arg(&out)
        .env("TMPDIR", &tmp)
        .output()
        .expect("run cosim");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(
        output.status.code(),
        Some(1),
        "{:?}: {stderr}",
        output.status
    );
    let partial = dir.join("out.csv.partial");
    assert!(
        stderr.contains(&format!("{}: File too large", partial.display())),
        "{stderr}"
    );
    assert!(!out.exists());
    let (_, rows) = rows(&partial);
    assert!(!rows.is_empty());
    let left: Vec<_> = std::fs::read_dir(&tmp).expect("TMPDIR").collect();
    assert!(left.is_empty(), "temporary files left behind: {left:?}");
}

#[test]
fn an_out_that_is_the_input_or_a_directory_is_refused_before_the_run() {
    let dir = fresh("out-checks");
    let ssp = dir.join("system.ssp");
    std::fs::copy(scenario("case1_load"), &ssp).expect("copy the scenario");
    let original = std::fs::read(&ssp).expect("read the input");
    let linked = dir.join("linked.csv");
    std::fs::hard_link(&ssp, &linked).expect("a hard link");
    let started = Instant::now();
    for out in [ssp.clone(), dir.join(".").join("system.ssp"), linked] {
        let output = Command::new(cosim())
            .arg(&ssp)
            .args(["--stop", "0.05", "--out"])
            .arg(&out)
            .output()
            .expect("run cosim");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains("is the input"), "{stderr}");
        assert_eq!(std::fs::read(&ssp).expect("read the input"), original);
    }
    let output = Command::new(cosim())
        .arg(&ssp)
        .args(["--stop", "60", "--out"])
        .arg(&dir)
        .output()
        .expect("run cosim");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("is a directory"), "{stderr}");
    // Refused before loading anything: a 60 s run takes far longer than this.
    assert!(started.elapsed() < Duration::from_secs(20));
    assert!(!PathBuf::from(format!("{}.partial", dir.display())).exists());
}

#[test]
fn sigterm_stops_at_a_communication_point_and_keeps_complete_rows() {
    interrupted_by("TERM", 15);
}

/// A foreign step source feeds the DER's power input through a gain; at t_step the product
/// overflows to infinity, the DER refuses it and the run ends there.
#[test]
fn a_failing_unit_keeps_every_row_up_to_the_failure_and_is_named() {
    let dir = fresh("failing");
    let system = dir.join("system");
    std::fs::create_dir_all(system.join("resources")).expect("create the system");
    let fmus = foreign::build_foreign(&dir.join("foreign"));
    let source = fmus
        .iter()
        .find(|p| p.ends_with("foreign_source.fmu"))
        .expect("the source FMU");
    std::fs::copy(source, system.join("resources/foreign_source.fmu")).expect("copy");
    std::fs::copy(
        dist().join("dvpp_der.fmu"),
        system.join("resources/dvpp_der.fmu"),
    )
    .expect("copy");
    let ssd = r#"<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
  xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
  xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="failing">
  <ssd:System name="failing">
    <ssd:Elements>
      <ssd:Component name="source" source="resources/foreign_source.fmu">
        <ssd:Connectors><ssd:Connector name="y" kind="output"><ssc:Real/></ssd:Connector></ssd:Connectors>
        <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
          <ssv:ParameterSet version="1.0" name="p"><ssv:Parameters>
            <ssv:Parameter name="amplitude"><ssv:Real value="1e308"/></ssv:Parameter>
            <ssv:Parameter name="t_step"><ssv:Real value="0.25"/></ssv:Parameter>
          </ssv:Parameters></ssv:ParameterSet>
        </ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>
      </ssd:Component>
      <ssd:Component name="der" source="resources/dvpp_der.fmu">
        <ssd:Connectors>
          <ssd:Connector name="p" kind="input"><ssc:Real/></ssd:Connector>
          <ssd:Connector name="df" kind="output"><ssc:Real/></ssd:Connector>
        </ssd:Connectors>
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="source" startConnector="y" endElement="der" endConnector="p">
        <ssc:LinearTransformation factor="10" offset="0"/>
      </ssd:Connection>
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="1"/>
</ssd:SystemStructureDescription>
"#;
    std::fs::write(system.join("SystemStructure.ssd"), ssd).expect("write the SSD");
    let out = run(&system, &["--step", "0.001"], &dir, None);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    // The unit, the call, the time and the unit's own last message.
    for part in ["component 'der'", "fmi2SetReal", "t = 0.24", "inf"] {
        assert!(stderr.contains(part), "'{part}' missing from: {stderr}");
    }
    assert!(!dir.join("out.csv").exists());
    let (header, rows) = rows(&dir.join("out.csv.partial"));
    assert_eq!(header, ["time", "source.y", "der.df"]);
    assert_eq!(rows.len(), 250, "rows from t = 0 to 0.249 s");
    assert!(rows.iter().all(|r| r[1] == 0.0 && r[2].is_finite()));
    assert_eq!(stopped_at(&stderr, "stopped after t = "), 0.249);
}
