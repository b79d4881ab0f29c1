//! The launcher of a whole federation on one machine: `helics_broker` on loopback, one
//! `cosim federate` process per group of components, their CSVs merged in the master's column
//! order; and the commands to run the same federation on several machines. Each federate's
//! TMPDIR is a directory of the launcher's, removed once every federate has ended, so that what
//! they unpacked goes however they ended (stopped, killed or failed).

use super::{component_names, err, find_broker, find_library, DEFAULT_CORE};
use crate::master::{Error, Options, System};
use crate::ssp;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How long the launcher waits for its broker to listen.
const BROKER_TIMEOUT: Duration = Duration::from_secs(20);

/// A federation on one machine: the system, its federates' components, where the results go.
#[derive(Debug, Clone, Default)]
pub struct FederationOptions {
    pub system: PathBuf,
    /// `a,b;c;d`: the components of each federate; components left out run one per federate.
    pub groups: Option<String>,
    pub out: Option<PathBuf>,
    pub helics_lib: Option<PathBuf>,
    pub opts: Options,
    /// HELICS core type (default [`DEFAULT_CORE`]).
    pub core: Option<String>,
    /// The broker's time coordination (default: [`Timing::for_federates`]).
    pub timing: Option<Timing>,
    /// Where the federates write their CSVs (default: next to `out`).
    pub work_dir: Option<PathBuf>,
}

/// How a federation went.
#[derive(Debug, Clone)]
pub struct FederationReport {
    pub federates: Vec<Vec<String>>,
    pub rows: usize,
    /// Wall time from starting the broker to the last federate's exit.
    pub wall: Duration,
    /// Each federate's printed summary (its last stdout line).
    pub summaries: Vec<String>,
    /// The commands to run the same federation on several machines.
    pub commands: Vec<String>,
}

/// The federates of `groups` over `components` (in SSD order; unlisted ones alone).
pub fn groups(components: &[String], spec: Option<&str>) -> Result<Vec<Vec<String>>, Error> {
    let mut out: Vec<Vec<String>> = Vec::new();
    let mut seen = Vec::new();
    for g in spec
        .unwrap_or("")
        .split(';')
        .filter(|g| !g.trim().is_empty())
    {
        let mut group = Vec::new();
        for c in g.split(',').map(str::trim).filter(|c| !c.is_empty()) {
            if !components.iter().any(|n| n == c) {
                return err(format!(
                    "--groups: no component '{c}' ({})",
                    components.join(", ")
                ));
            }
            if seen.iter().any(|s| s == c) {
                return err(format!("--groups: '{c}' is in two groups"));
            }
            seen.push(c.to_owned());
            group.push(c.to_owned());
        }
        out.push(group);
    }
    for c in components {
        if !seen.contains(c) {
            out.push(vec![c.clone()]);
        }
    }
    Ok(out)
}

/// Split one CSV line into its fields (as written: quoted fields may hold commas).
fn fields(line: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let (mut start, mut quoted) = (0, false);
    for (i, ch) in line.char_indices() {
        match ch {
            '"' => quoted = !quoted,
            ',' if !quoted => {
                out.push(&line[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(&line[start..]);
    out
}

/// A CSV header field's name (unquoted).
fn unquote(f: &str) -> String {
    f.strip_prefix('"')
        .and_then(|f| f.strip_suffix('"'))
        .map_or_else(|| f.to_owned(), |f| f.replace("\"\"", "\""))
}

/// Merge the federates' CSVs (same times) into `out`, columns in `order` (the master's).
fn merge(parts: &[PathBuf], order: &[String], out: &Path) -> Result<usize, Error> {
    use std::io::{BufRead, BufReader, BufWriter, Write};
    let io = |p: &Path, e: std::io::Error| Error::Federation(format!("{}: {e}", p.display()));
    let mut readers = Vec::new();
    // (part, field) of each output column.
    let mut at: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    let mut header_text: BTreeMap<String, String> = BTreeMap::new();
    for (k, p) in parts.iter().enumerate() {
        let f = std::fs::File::open(p).map_err(|e| io(p, e))?;
        let mut lines = BufReader::new(f).lines();
        let header = lines
            .next()
            .ok_or_else(|| Error::Federation(format!("{}: empty", p.display())))?
            .map_err(|e| io(p, e))?;
        for (j, f) in fields(&header).into_iter().enumerate() {
            let name = unquote(f);
            if j > 0 || k == 0 {
                header_text.insert(name.clone(), f.to_owned());
                at.insert(name, (k, j));
            }
        }
        readers.push(lines);
    }
    let picks: Vec<(usize, usize)> = order
        .iter()
        .map(|c| {
            at.get(c)
                .copied()
                .ok_or_else(|| Error::Federation(format!("no federate wrote column '{c}'")))
        })
        .collect::<Result<_, _>>()?;
    let file = std::fs::File::create(out).map_err(|e| io(out, e))?;
    let mut w = BufWriter::new(file);
    let head: Vec<&str> = order.iter().map(|c| header_text[c].as_str()).collect();
    writeln!(w, "{}", head.join(",")).map_err(|e| io(out, e))?;
    let mut rows = 0;
    loop {
        let mut lines = Vec::with_capacity(readers.len());
        for (k, r) in readers.iter_mut().enumerate() {
            match r.next() {
                Some(l) => lines.push(l.map_err(|e| io(&parts[k], e))?),
                None => break,
            }
        }
        if lines.len() < readers.len() {
            if !lines.is_empty() {
                return err("the federates' CSVs have different numbers of rows");
            }
            break;
        }
        let split: Vec<Vec<&str>> = lines.iter().map(|l| fields(l)).collect();
        if split.iter().any(|f| f[0] != split[0][0]) {
            return err(format!(
                "the federates' CSVs disagree on the time at row {rows}"
            ));
        }
        let row: Vec<&str> = picks.iter().map(|&(k, j)| split[k][j]).collect();
        writeln!(w, "{}", row.join(",")).map_err(|e| io(out, e))?;
        rows += 1;
    }
    w.flush().map_err(|e| io(out, e))?;
    Ok(rows)
}

/// How the broker coordinates time ([`FederationOptions::timing`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Timing {
    /// HELICS's default: the federates' cores negotiate each grant among themselves.
    Distributed,
    /// One coordinator at the broker: every round is a barrier, a grant one request to the
    /// broker and one answer, whatever the number of federates.
    Global,
}

/// From this many federates on, [`Timing::Global`] by default. Measured on case study I (1 s at
/// 1 ms, this project's 2-core machine, idle): distributed 1.27, 1.96-2.28, 5.5 and 11.6 ms per
/// step for 2, 3, 4 and 5 federates, global 2.3-2.5, 2.7, 2.7 and 2.9 ms (docs/scaling.md).
pub const GLOBAL_FROM: usize = 4;

impl Timing {
    /// The default for `federates` federates.
    pub fn for_federates(federates: usize) -> Timing {
        if federates >= GLOBAL_FROM {
            Timing::Global
        } else {
            Timing::Distributed
        }
    }

    /// The broker's options for it.
    fn flags(self) -> &'static [&'static str] {
        match self {
            Timing::Distributed => &["--loglevel=error"],
            Timing::Global => &["--globaltime", "--loglevel=error"],
        }
    }
}

/// A child process of the launcher, which ends with it (SIGTERM when the launcher dies, also by
/// SIGKILL, so that no broker or federate outlives its federation).
fn child(program: &Path) -> std::process::Command {
    use std::os::unix::process::CommandExt;
    let mut c = std::process::Command::new(program);
    // SAFETY: prctl is async-signal-safe; it only sets this child's parent-death signal.
    unsafe {
        c.pre_exec(|| {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    c
}

/// Point `c`'s temporary directory (`TMPDIR`) into `scratch`, the launcher's: whatever a
/// federate unpacks (the SSP and every FMU of the system, each federate loading the whole
/// system) is removed with `scratch` once the federate has ended, however it ended (a
/// federate stopped by a signal or by SIGKILL runs no destructor of its own).
fn in_scratch<'c>(
    c: &'c mut std::process::Command,
    scratch: &crate::tmp::TempDir,
) -> &'c mut std::process::Command {
    c.env("TMPDIR", scratch.path())
}

/// End a child and reap it.
fn stop(c: &mut std::process::Child) {
    let _ = c.kill();
    let _ = c.wait();
}

/// `helics_broker` for `federates` federates on loopback, on a port the kernel chooses and holds
/// for it (port 0): no other process can take it between choosing and listening.
fn start_broker(
    exe: &Path,
    core: &str,
    federates: usize,
    timing: Timing,
) -> Result<std::process::Child, Error> {
    child(exe)
        .args(["-f", &federates.to_string()])
        .arg(format!("--coretype={core}"))
        .args(timing.flags())
        .arg("--local_interface=tcp://127.0.0.1")
        .arg("--port=0")
        .stdout(std::process::Stdio::null())
        .spawn()
        .map_err(|e| Error::Federation(format!("cannot start {}: {e}", exe.display())))
}

/// The port the broker listens on, once it does (within [`BROKER_TIMEOUT`]).
fn wait_listening(broker: &mut std::process::Child, exe: &Path) -> Result<u16, Error> {
    let since = Instant::now();
    loop {
        if let Some(port) = crate::listen::port_of(broker.id()) {
            return Ok(port);
        }
        if let Ok(Some(status)) = broker.try_wait() {
            return err(format!("{} ended at once ({status})", exe.display()));
        }
        if let Some(signal) = crate::interrupt::requested() {
            return err(format!(
                "stopped by signal {signal} while the broker started"
            ));
        }
        if since.elapsed() > BROKER_TIMEOUT {
            return err(format!(
                "{} does not listen on 127.0.0.1 after {} s",
                exe.display(),
                BROKER_TIMEOUT.as_secs()
            ));
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Run the system as a federation on this machine: `helics_broker` on loopback, one
/// `exe federate` process per group, their CSVs merged into `o.out` in the master's column order.
pub fn run_federation(o: &FederationOptions, exe: &Path) -> Result<FederationReport, Error> {
    use std::process::Stdio;
    let lib = find_library(o.helics_lib.as_deref())?;
    let broker_exe = find_broker(&lib)?;
    let package = ssp::read(&o.system)?;
    let names = component_names(&package);
    let feds = groups(&names, o.groups.as_deref())?;
    let order = System::builder(&package).load()?.columns();
    let out = o.out.clone().unwrap_or_else(|| {
        PathBuf::from(format!(
            "{}.csv",
            o.system
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("system")
        ))
    });
    let dir = o.work_dir.clone().unwrap_or_else(|| {
        let mut d = out.as_os_str().to_owned();
        d.push(".federates");
        PathBuf::from(d)
    });
    std::fs::create_dir_all(&dir)
        .map_err(|e| Error::Federation(format!("{}: {e}", dir.display())))?;
    // Declared before the children: dropped (removed) after every path below has reaped them.
    let scratch = crate::tmp::TempDir::new("federation")
        .map_err(|e| Error::Federation(format!("cannot make the federates' TMPDIR: {e}")))?;
    let core = o.core.as_deref().unwrap_or(DEFAULT_CORE);
    let started = Instant::now();
    let coordination = o.timing.unwrap_or(Timing::for_federates(feds.len()));
    let mut broker = start_broker(&broker_exe, core, feds.len(), coordination)?;
    let port = match wait_listening(&mut broker, &broker_exe) {
        Ok(p) => p,
        Err(e) => {
            stop(&mut broker);
            return Err(e);
        }
    };
    let address = format!("127.0.0.1:{port}");
    let mut timing = vec!["--core".to_owned(), core.to_owned()];
    if let Some(s) = o.opts.stop {
        timing.extend(["--stop".to_owned(), s.to_string()]);
    }
    if let Some(s) = o.opts.step {
        timing.extend(["--step".to_owned(), s.to_string()]);
    }
    let mut children = Vec::new();
    let mut parts = Vec::new();
    let mut commands = vec![format!(
        "{} -f {} --coretype={core} {} --local_interface=tcp://BROKER_HOST --port={port}",
        broker_exe.display(),
        feds.len(),
        coordination.flags().join(" ")
    )];
    let mut failure = None;
    for (k, g) in feds.iter().enumerate() {
        let name = format!("fed{k}");
        let csv = dir.join(format!("{name}.csv"));
        let args = |broker: &str, csv: &Path| -> Vec<String> {
            let mut a = vec![
                "federate".to_owned(),
                o.system.display().to_string(),
                "--component".to_owned(),
                g.join(","),
                "--broker".to_owned(),
                broker.to_owned(),
                "--name".to_owned(),
                name.clone(),
                "--out".to_owned(),
                csv.display().to_string(),
                "--helics-lib".to_owned(),
                lib.display().to_string(),
            ];
            a.extend(timing.iter().cloned());
            a
        };
        commands.push(format!(
            "{} {}",
            exe.display(),
            args(
                &format!("BROKER_HOST:{port}"),
                Path::new(&format!("{name}.csv"))
            )
            .join(" ")
        ));
        match in_scratch(&mut child(exe), &scratch)
            .args(args(&address, &csv))
            .stdout(Stdio::piped())
            .spawn()
        {
            Ok(c) => children.push(c),
            Err(e) => {
                failure = Some(Error::Federation(format!(
                    "cannot start {}: {e}",
                    exe.display()
                )));
                break;
            }
        }
        parts.push(csv);
    }
    // Wait for every federate; when one fails, the others would wait for it: stop them.
    let mut summaries = vec![String::new(); children.len()];
    let mut running: Vec<Option<std::process::Child>> = children.into_iter().map(Some).collect();
    while failure.is_none() && running.iter().any(Option::is_some) {
        if let Some(signal) = crate::interrupt::requested() {
            failure = Some(Error::Federation(format!(
                "stopped by signal {signal}: the broker and the federates were stopped"
            )));
            break;
        }
        for k in 0..running.len() {
            let Some(c) = running[k].as_mut() else {
                continue;
            };
            match c.try_wait() {
                Ok(None) => continue,
                Ok(Some(status)) if status.success() => {
                    let c = running[k].take().expect("running");
                    if let Ok(out) = c.wait_with_output() {
                        summaries[k] = String::from_utf8_lossy(&out.stdout)
                            .lines()
                            .last()
                            .unwrap_or("")
                            .to_owned();
                    }
                }
                Ok(Some(status)) => {
                    running[k] = None;
                    failure = Some(Error::Federation(format!(
                        "federate fed{k} ({}) failed ({status}); the others were stopped",
                        feds[k].join(",")
                    )));
                }
                Err(e) => failure = Some(Error::Federation(format!("federate fed{k}: {e}"))),
            }
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    for c in running.iter_mut().flatten() {
        stop(c);
    }
    if failure.is_some() {
        // The broker waits for federates that never came: stop it (it is our child).
        stop(&mut broker);
    }
    let _ = broker.wait();
    let wall = started.elapsed();
    if let Some(e) = failure {
        return Err(e);
    }
    let rows = merge(&parts, &order, &out)?;
    Ok(FederationReport {
        federates: feds,
        rows,
        wall,
        summaries,
        commands,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn groups_cover_every_component_once() {
        let all = names(&["grid", "operator", "wind", "pv", "bess"]);
        let g = groups(&all, Some("grid,operator; wind ,pv")).unwrap();
        assert_eq!(
            g,
            vec![
                names(&["grid", "operator"]),
                names(&["wind", "pv"]),
                names(&["bess"])
            ]
        );
        assert_eq!(groups(&all, None).unwrap().len(), 5);
        assert!(groups(&all, Some("grid;grid"))
            .unwrap_err()
            .to_string()
            .contains("two groups"));
        assert!(groups(&all, Some("nosuch"))
            .unwrap_err()
            .to_string()
            .contains("'nosuch'"));
    }

    /// A federate killed (SIGKILL, as `stop` does) leaves what it unpacked in its TMPDIR; the
    /// launcher's scratch directory takes it away once the federate is reaped.
    #[test]
    fn what_a_killed_federate_unpacked_goes_with_the_scratch_directory() {
        let scratch = crate::tmp::TempDir::new("test-federation").unwrap();
        let root = scratch.path().to_path_buf();
        let mut c = in_scratch(&mut child(Path::new("/bin/sh")), &scratch)
            .args([
                "-c",
                "mkdir \"$TMPDIR/dvpp-fmu-x\" && touch \"$TMPDIR/dvpp-fmu-x/model.so\" && sleep 60",
            ])
            .spawn()
            .unwrap();
        let since = Instant::now();
        while !root.join("dvpp-fmu-x/model.so").exists() {
            assert!(since.elapsed() < Duration::from_secs(10), "never unpacked");
            std::thread::sleep(Duration::from_millis(5));
        }
        stop(&mut c);
        assert!(
            root.join("dvpp-fmu-x").exists(),
            "a killed process cleans nothing"
        );
        drop(scratch);
        assert!(!root.exists(), "left behind");
    }

    #[test]
    fn csv_fields_keep_quoted_commas() {
        assert_eq!(fields("time,\"a,b\",c"), vec!["time", "\"a,b\"", "c"]);
        assert_eq!(unquote("\"a,\"\"b\"\"\""), "a,\"b\"");
        assert_eq!(unquote("grid.pcc.f"), "grid.pcc.f");
    }
}
