//! The FMUs' win64 binaries under wine against their linux64 binaries: one C master (tests/wine/master.c), built for both, steps each bundled FMU with the same varied inputs, replays each unit of a `cosim --trace` run of case study I, and replays the EMT unit's conformance trajectories; every value must agree bit for bit.

use dvpp_e2e::digest::{Digest, Table};
use dvpp_e2e::{cosim, dist, root, scenario, IDS};
use model_description::{Causality, ModelDescription, VariableKind};
use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;
use std::time::Instant;

const STEPS: usize = 2000;
const STEP_SIZE: f64 = 1e-3;
const MINGW: &str = "x86_64-w64-mingw32-gcc";
/// The system replayed unit by unit, and its committed digest (tests/tests/digest.rs).
const REPLAYED: &str = "case1_load";
/// Rows per block of the digest.
const DIGEST_BLOCK: usize = 1000;

/// The tests of this file one at a time: they share the wine prefix (made by the first run of
/// wine) and the two cores.
static WINE: Mutex<()> = Mutex::new(());

/// Print a line the test harness does not capture (the reason of a skip, the measured result).
fn say(line: &str) {
    let _ = writeln!(std::io::stderr(), "{line}");
}

/// Set by `cargo xtask test` (which installs wine and mingw-w64 and bundles the win64 binaries):
/// then anything missing fails the test instead of skipping it.
const REQUIRE: &str = "DVPP_REQUIRE_WIN64";

/// Skip the test, printing `reason`; or, with [`REQUIRE`] set, fail with it.
fn skip(reason: &str) {
    if std::env::var_os(REQUIRE).is_some_and(|v| !v.is_empty() && v != "0") {
        panic!("{REQUIRE} is set: {reason}");
    }
    say(&format!("win64 test skipped: {reason}"));
}

/// Whether `program --version` runs.
fn runs(program: &str) -> bool {
    Command::new(program)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// The 64-bit wine loader: `wine64` on the PATH, Debian's `/usr/lib/wine/wine64`, or `wine`.
fn wine() -> Option<PathBuf> {
    if runs("wine64") {
        return Some("wine64".into());
    }
    let debian = Path::new("/usr/lib/wine/wine64");
    if debian.is_file() {
        return Some(debian.into());
    }
    runs("wine").then(|| "wine".into())
}

/// `path` as wine sees it: drive `Z:` is the Unix root.
fn windows_path(path: &Path) -> String {
    format!("Z:{}", path.display()).replace('/', "\\")
}

/// The spellings of a local file URI that RFC 8089 allows, one per FMU: `file:///`, `file:/`,
/// `file://localhost/` before the path.
const URI_FORMS: [&str; 3] = ["file://", "file:", "file://localhost"];

/// A `file:` URI of the absolute `path` (`/a b` or `Z:\a b`), percent-encoded, in `form`.
fn file_uri(path: &str, form: &str) -> String {
    let path = path.replace('\\', "/");
    let mut uri = String::from(form);
    if !path.starts_with('/') {
        uri.push('/');
    }
    for b in path.bytes() {
        if b.is_ascii_alphanumeric() || b"/-_.~:".contains(&b) {
            uri.push(b as char);
        } else {
            uri.push_str(&format!("%{b:02X}"));
        }
    }
    uri
}

/// Compile `sources` with `compiler` into `out`; panics with the compiler's message on failure.
fn compile(compiler: &str, sources: &[PathBuf], args: &[&str], out: &Path) {
    let output = Command::new(compiler)
        .args(["-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(root().join("fmi2").join("include"))
        .args(sources)
        .arg("-o")
        .arg(out)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {compiler}: {e}"));
    assert!(
        output.status.success(),
        "{compiler} {:?} failed:\n{}",
        sources,
        String::from_utf8_lossy(&output.stderr)
    );
}

/// The master's arguments after the library: GUID, the inputs `vr:lo:hi` (each around its start
/// value, within its bounds) and the Real outputs.
fn inputs_and_outputs(md: &ModelDescription) -> (String, String) {
    let mut inputs = Vec::new();
    let mut outputs = Vec::new();
    for v in &md.model_variables.variables {
        let VariableKind::Real(r) = &v.kind else {
            continue;
        };
        match v.causality() {
            Causality::Input => {
                let start = r.start.unwrap_or(0.0);
                let width = 0.05 * start.abs().max(0.2);
                let lo = (start - width).max(r.min.unwrap_or(f64::MIN));
                let hi = (start + width).min(r.max.unwrap_or(f64::MAX));
                inputs.push(format!("{}:{lo:e}:{hi:e}", v.value_reference));
            }
            Causality::Output => outputs.push(v.value_reference.to_string()),
            _ => {}
        }
    }
    let inputs = if inputs.is_empty() {
        "-".into()
    } else {
        inputs.join(",")
    };
    (inputs, outputs.join(","))
}

/// Run a master to its end; its standard output (checks the exit status and the closing "done").
fn master_output(cmd: &mut Command, what: &str) -> String {
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("{what}: cannot start: {e}"));
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success() && stdout.trim_end().ends_with("done"),
        "{what}: {}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// Run a master; its output as one row of values per step (checks the closing "done").
fn rows(cmd: &mut Command, what: &str) -> Vec<Vec<f64>> {
    let stdout = master_output(cmd, what);
    stdout
        .lines()
        .map(str::trim)
        .take_while(|l| *l != "done")
        .map(|l| {
            l.split_whitespace()
                .map(|h| f64::from_bits(u64::from_str_radix(h, 16).expect("16 hex digits")))
                .collect()
        })
        .collect()
}

/// The two builds of the test master and how to run the Windows one.
struct Masters {
    wine: PathBuf,
    native: PathBuf,
    exe: PathBuf,
    prefix: PathBuf,
}

impl Masters {
    /// Build both masters in `work/master`; `None` (after [`skip`]) without wine or mingw-w64.
    fn build(work: &Path) -> Option<Masters> {
        let Some(wine) = wine() else {
            skip("no wine (apt-get install wine64; `cargo xtask test` installs it)");
            return None;
        };
        if !runs(MINGW) {
            skip(&format!(
                "no {MINGW} to build the test master (apt-get install \
                 gcc-mingw-w64-x86-64-win32; `cargo xtask test` installs it)"
            ));
            return None;
        }
        // The master for both platforms; next to the Windows one, the test-only stand-in for
        // the bcryptprimitives.dll that wine 8 lacks (found there first when the FMU's DLL is
        // loaded).
        let src = root().join("tests").join("wine");
        let bin = work.join("master");
        std::fs::create_dir_all(&bin).expect("create the master's directory");
        let (native, exe) = (bin.join("master"), bin.join("master.exe"));
        let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
        compile(&cc, &[src.join("master.c")], &["-ldl"], &native);
        compile(MINGW, &[src.join("master.c")], &[], &exe);
        compile(
            MINGW,
            &[src.join("bcryptprimitives.c")],
            &["-shared", "-ladvapi32"],
            &bin.join("bcryptprimitives.dll"),
        );
        let prefix = Path::new(env!("CARGO_TARGET_TMPDIR")).join("wineprefix");
        let masters = Masters {
            wine,
            native,
            exe,
            prefix,
        };
        masters.make_prefix();
        Some(masters)
    }

    /// Make the wine prefix once, before any test program runs under wine: `wineboot --init`,
    /// then wait for the prefix's wineserver to end (it writes the registry when it does).
    /// Left to the first program started under wine, the prefix is made by that program's own
    /// start, and on a fresh machine that start failed ("could not load kernel32.dll").
    fn make_prefix(&self) {
        let ready = |p: &Path| {
            p.join("system.reg").is_file()
                && p.join("drive_c/windows/system32/kernel32.dll").is_file()
        };
        if ready(&self.prefix) {
            return;
        }
        let _ = std::fs::remove_dir_all(&self.prefix);
        let mut boot = Command::new(&self.wine);
        boot.args(["wineboot", "--init"]);
        let out = self
            .environment(&mut boot)
            .output()
            .expect("start wineboot");
        assert!(
            out.status.success(),
            "wineboot --init in {}: {}\n{}",
            self.prefix.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
        // The wineserver that belongs to this loader (Debian keeps it beside `wine64`).
        let beside = self.wine.with_file_name("wineserver");
        let server = if beside.is_file() {
            beside
        } else {
            "wineserver".into()
        };
        let mut wait = Command::new(&server);
        let waited = self.environment(&mut wait).arg("--wait").status();
        assert!(
            waited.is_ok_and(|s| s.success()) && ready(&self.prefix),
            "the wine prefix {} is not complete after wineboot --init and {} --wait \
             (no system.reg or system32/kernel32.dll)\n{}",
            self.prefix.display(),
            server.display(),
            String::from_utf8_lossy(&out.stderr)
        );
    }

    /// The environment every wine process of the tests runs in.
    fn environment<'c>(&self, c: &'c mut Command) -> &'c mut Command {
        c.env("WINEPREFIX", &self.prefix)
            .env("WINEDEBUG", "-all")
            // No Mono or Gecko installer prompts when the prefix is made.
            .env("WINEDLLOVERRIDES", "mscoree,mshtml=")
    }

    /// The Windows master under wine, ready for its arguments.
    fn windows(&self) -> Command {
        let mut c = Command::new(&self.wine);
        c.arg(&self.exe);
        self.environment(&mut c);
        c
    }
}

/// Open the FMU at `path` (model identifier `id`); `None` (after [`skip`]) when it was bundled
/// without its win64 binary.
fn open_fmu(path: &Path, id: &str) -> Option<zip::ZipArchive<std::fs::File>> {
    let file = std::fs::File::open(path)
        .unwrap_or_else(|e| panic!("{}: {e} (run `cargo xtask bundle`)", path.display()));
    let mut zip = zip::ZipArchive::new(file).expect("an FMU is a zip archive");
    if zip.by_name(&format!("binaries/win64/{id}.dll")).is_err() {
        skip(&format!(
            "{} has no binaries/win64/{id}.dll (bundled without the \
             x86_64-pc-windows-gnu target or mingw-w64; see `cargo xtask bundle`'s output)",
            path.display()
        ));
        return None;
    }
    Some(zip)
}

/// The model description of an FMU archive.
fn description(zip: &mut zip::ZipArchive<std::fs::File>) -> ModelDescription {
    let mut xml = String::new();
    zip.by_name("modelDescription.xml")
        .expect("modelDescription.xml")
        .read_to_string(&mut xml)
        .expect("UTF-8");
    ModelDescription::from_xml(&xml).expect("parse")
}

/// How far apart `a` and `b` are in units in the last place (across zero and for NaNs by the
/// order of their bits; +0 and -0 are 0 apart).
fn ulps(a: f64, b: f64) -> u64 {
    let ordered = |x: f64| {
        let b = x.to_bits() as i64;
        if b < 0 {
            i64::MIN.wrapping_sub(b)
        } else {
            b
        }
    };
    ordered(a).wrapping_sub(ordered(b)).unsigned_abs()
}

#[test]
fn win64_binaries_under_wine_match_linux64() {
    let _one = WINE.lock().unwrap_or_else(|e| e.into_inner());
    // Unpack each FMU under a directory with a space, so the resource URI is percent-encoded.
    let work = Path::new(env!("CARGO_TARGET_TMPDIR")).join("win64 test");
    let _ = std::fs::remove_dir_all(&work);
    let mut fmus = Vec::new();
    for id in IDS {
        let path = dist().join(format!("{id}.fmu"));
        let Some(mut zip) = open_fmu(&path, id) else {
            return;
        };
        let md = description(&mut zip);
        let dir = work.join(id);
        zip.extract(&dir).expect("unpack the FMU");
        fmus.push((id, dir, md));
    }
    let Some(masters) = Masters::build(&work) else {
        return;
    };

    // Every output that differs anywhere: FMU, output, values that differ, the largest
    // difference (ULPs, relative), where.
    let mut differing = Vec::new();
    for ((id, dir, md), &form) in fmus.iter().zip(URI_FORMS.iter().cycle()) {
        let (inputs, outputs) = inputs_and_outputs(md);
        let resources = dir.join("resources");
        let common = |c: &mut Command, library: String, uri: &str| {
            c.arg(library)
                .arg(&md.guid)
                .arg(uri)
                .arg(format!("{STEP_SIZE:e}"))
                .arg(STEPS.to_string())
                .arg(&inputs)
                .arg(&outputs);
        };
        let mut linux = Command::new(&masters.native);
        let so = dir
            .join("binaries")
            .join("linux64")
            .join(format!("{id}.so"));
        common(
            &mut linux,
            so.display().to_string(),
            &file_uri(&resources.display().to_string(), form),
        );
        let dll = dir.join("binaries").join("win64").join(format!("{id}.dll"));
        let mut windows = masters.windows();
        let uri = file_uri(&windows_path(&resources), form);
        assert!(uri.contains("/Z:/") && uri.contains("%20"), "{uri}");
        common(&mut windows, windows_path(&dll), &uri);

        let a = rows(&mut linux, &format!("{id}: linux64 master"));
        let b = rows(&mut windows, &format!("{id}: win64 master under wine"));
        assert_eq!(a.len(), STEPS, "{id}: linux64 steps");
        assert_eq!(b.len(), STEPS, "{id}: win64 steps");
        let names: Vec<&str> = md
            .model_variables
            .variables
            .iter()
            .filter(|v| {
                v.causality() == Causality::Output && matches!(v.kind, VariableKind::Real(_))
            })
            .map(|v| v.name.as_str())
            .collect();
        // The two platforms must agree bit for bit (0 ULP): every transcendental function comes
        // from one implementation built into the binaries (dvpp-math over libm), so a
        // difference is a call that still reaches a platform's libm. Per output: values that
        // differ, the largest difference in ULPs (and relative, for values above 1), the step
        // of the first difference.
        let mut per_output = vec![(0usize, 0u64, 0.0f64, None::<usize>); names.len()];
        let mut exact = 0usize;
        for (k, (ra, rb)) in a.iter().zip(&b).enumerate() {
            assert_eq!(ra.len(), names.len(), "{id}: outputs at step {k}");
            assert_eq!(rb.len(), names.len(), "{id}: outputs at step {k}");
            for (j, (x, y)) in ra.iter().zip(rb).enumerate() {
                if x.to_bits() == y.to_bits() {
                    exact += 1;
                    continue;
                }
                // +0 and -0 are 0 ULPs apart but not the same bits.
                let u = ulps(*x, *y).max(1);
                let o = &mut per_output[j];
                o.0 += 1;
                o.1 = o.1.max(u);
                o.2 = o.2.max((x - y).abs() / x.abs().max(1.0));
                o.3.get_or_insert(k);
            }
        }
        for (j, (count, worst, rel, first)) in per_output.iter().enumerate() {
            if let Some(first) = first {
                differing.push(format!(
                    "{id}.{}: {count} of {STEPS} values differ, by up to {worst} ULPs \
                     ({rel:e} relative), first at step {first}",
                    names[j]
                ));
            }
        }
        let total = STEPS * names.len();
        say(&format!(
            "{id}: win64 under wine vs linux64, {STEPS} steps x {} outputs, resources at {uri}: \
             {exact} of {total} values bit-identical",
            names.len(),
        ));
    }
    for d in &differing {
        say(&format!("win64 differs: {d}"));
    }
    assert!(
        differing.is_empty(),
        "{} outputs of the win64 binaries differ from linux64 (a call that still reaches the \
         platform's libm?):\n{}",
        differing.len(),
        differing.join("\n")
    );
}

/// One unit of the replayed system: its component name, unpacked FMU, model description and
/// recorded columns (index in the CSV, the output as the replay names it: `VR`, `i:VR`, `b:VR`).
struct Replayed {
    name: String,
    dir: PathBuf,
    md: ModelDescription,
    columns: Vec<(usize, String)>,
}

/// A replay's output: the time and the outputs at each `sample` of the trace (as the master
/// recorded them there); checks the closing "done".
fn samples(cmd: &mut Command, what: &str, outputs: usize) -> Vec<(f64, Vec<f64>)> {
    let stdout = master_output(cmd, what);
    let bits = |h: &str| f64::from_bits(u64::from_str_radix(h, 16).expect("16 hex digits"));
    stdout
        .lines()
        .map(str::trim)
        .take_while(|l| *l != "done")
        .map(|line| {
            let mut values: Vec<f64> = line.split_whitespace().map(bits).collect();
            assert_eq!(values.len(), 1 + outputs, "{what}: {line:?}");
            let t = values.remove(0);
            (t, values)
        })
        .collect()
}

/// Check that `rows` (a replay of `unit`) gives the recorded `csv` columns bit for bit;
/// returns the values compared.
fn check_replay(unit: &Replayed, rows: &[(f64, Vec<f64>)], csv: &Table, what: &str) -> usize {
    assert_eq!(
        rows.len(),
        csv.rows(),
        "{what}: samples against the CSV's rows"
    );
    for (k, (t, values)) in rows.iter().enumerate() {
        assert_eq!(
            t.to_bits(),
            csv.columns[0][k].to_bits(),
            "{what}: sample {k} at t = {t} s, the CSV's row at {} s",
            csv.columns[0][k]
        );
        for ((c, _), v) in unit.columns.iter().zip(values) {
            let recorded = csv.columns[*c][k];
            assert!(
                v.to_bits() == recorded.to_bits(),
                "{what}: {} at t = {t} s: replayed {v:e} ({:016x}), recorded {recorded:e} \
                 ({:016x}), {} ULPs apart",
                csv.names[*c],
                v.to_bits(),
                recorded.to_bits(),
                ulps(*v, recorded)
            );
        }
    }
    rows.len() * unit.columns.len()
}

#[test]
fn case1_load_replayed_under_wine_matches_its_digest() {
    let _one = WINE.lock().unwrap_or_else(|e| e.into_inner());
    let work = Path::new(env!("CARGO_TARGET_TMPDIR")).join("win64 replay");
    let _ = std::fs::remove_dir_all(&work);
    std::fs::create_dir_all(&work).expect("create the work directory");
    let ssp = scenario(REPLAYED);
    let package = dvpp_cosim::ssp::read(&ssp).unwrap_or_else(|e| panic!("{e}"));

    // Each component's FMU (the one the SSD names), unpacked once per archive.
    let mut unpacked: BTreeMap<PathBuf, (PathBuf, ModelDescription)> = BTreeMap::new();
    let mut units = Vec::new();
    for c in &package.system.components {
        let path = package.source_path(c);
        if !unpacked.contains_key(&path) {
            let mut zip = zip::ZipArchive::new(std::fs::File::open(&path).expect("open the FMU"))
                .expect("an FMU is a zip archive");
            let md = description(&mut zip);
            let id = md.model_identifier().expect("co-simulation").to_owned();
            let Some(mut zip) = open_fmu(&path, &id) else {
                return;
            };
            let dir = work.join(format!("fmu {}", unpacked.len()));
            zip.extract(&dir).expect("unpack the FMU");
            unpacked.insert(path.clone(), (dir, md));
        }
        let (dir, md) = &unpacked[&path];
        units.push(Replayed {
            name: c.name.clone(),
            dir: dir.clone(),
            md: md.clone(),
            columns: Vec::new(),
        });
    }
    let Some(masters) = Masters::build(&work) else {
        return;
    };

    // The master's run, every output recorded and every unit traced.
    let (csv_path, traces) = (work.join("run.csv"), work.join("traces"));
    let started = Instant::now();
    let run = Command::new(cosim())
        .arg(&ssp)
        .args(["--record", "all", "--out"])
        .arg(&csv_path)
        .arg("--trace")
        .arg(&traces)
        .output()
        .expect("run cosim");
    assert!(
        run.status.success(),
        "cosim {}: {}",
        ssp.display(),
        String::from_utf8_lossy(&run.stderr)
    );
    let master_time = started.elapsed();
    let csv = Table::read_csv(&csv_path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(csv.names[0], "time");

    // Every column is one unit's Real output: `unit.variable`.
    for (c, column) in csv.names.iter().enumerate().skip(1) {
        let unit = units
            .iter_mut()
            .find(|u| {
                column
                    .strip_prefix(u.name.as_str())
                    .is_some_and(|rest| rest.starts_with('.'))
            })
            .unwrap_or_else(|| panic!("column {column}: no unit of that name"));
        let var = &column[unit.name.len() + 1..];
        let v = unit
            .md
            .variable(var)
            .unwrap_or_else(|| panic!("column {column}: no variable {var}"));
        let prefix = match v.kind {
            VariableKind::Real(_) => "",
            VariableKind::Integer(_) | VariableKind::Enumeration(_) => "i:",
            VariableKind::Boolean(_) => "b:",
            _ => panic!("column {column}: neither Real, Integer nor Boolean"),
        };
        unit.columns
            .push((c, format!("{prefix}{}", v.value_reference)));
    }

    // Each unit replayed from its trace by the native master on its .so and by the Windows one
    // under wine on its .dll.
    let mut wine: Vec<Vec<f64>> = vec![Vec::new(); csv.names.len()];
    let (mut compared, mut wine_time, mut units_done) = (0usize, std::time::Duration::ZERO, 0);
    for unit in &units {
        let id = unit.md.model_identifier().expect("co-simulation");
        let trace = traces.join(format!("{}.trace", unit.name));
        assert!(trace.is_file(), "{}: no trace", trace.display());
        let outputs: Vec<&str> = unit.columns.iter().map(|(_, o)| o.as_str()).collect();
        let outputs = if outputs.is_empty() {
            "-".to_owned()
        } else {
            outputs.join(",")
        };
        let resources = unit.dir.join("resources");
        let so = unit.dir.join("binaries/linux64").join(format!("{id}.so"));
        let dll = unit.dir.join("binaries/win64").join(format!("{id}.dll"));

        let mut linux = Command::new(&masters.native);
        linux
            .arg("replay")
            .arg(&so)
            .arg(&unit.md.guid)
            .arg(file_uri(&resources.display().to_string(), "file://"))
            .arg(&trace)
            .arg(&outputs);
        let what = format!("{}: linux64 replay", unit.name);
        let rows = samples(&mut linux, &what, unit.columns.len());
        compared += check_replay(unit, &rows, &csv, &what);

        let mut windows = masters.windows();
        windows
            .arg("replay")
            .arg(windows_path(&dll))
            .arg(&unit.md.guid)
            .arg(file_uri(&windows_path(&resources), "file://"))
            .arg(windows_path(&trace))
            .arg(&outputs);
        let what = format!("{}: win64 replay under wine", unit.name);
        let started = Instant::now();
        let rows = samples(&mut windows, &what, unit.columns.len());
        wine_time += started.elapsed();
        check_replay(unit, &rows, &csv, &what);

        // The result table of the wine replays: time from their samples, each column from its
        // unit's replay.
        let times: Vec<f64> = rows.iter().map(|r| r.0).collect();
        if units_done == 0 {
            wine[0] = times;
        } else {
            assert!(
                wine[0]
                    .iter()
                    .zip(&times)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{what}: other sample times than the first unit's"
            );
        }
        for (j, (c, _)) in unit.columns.iter().enumerate() {
            wine[*c] = rows.iter().map(|r| r.1[j]).collect();
        }
        units_done += 1;
    }

    let table = Table {
        names: csv.names.clone(),
        columns: wine,
    };
    let (rows, columns) = (table.rows(), table.names.len());
    say(&format!(
        "{REPLAYED}: the master's run ({} rows x {} columns, traced) in {:.1} s; {} units \
         replayed from their traces on linux64 and under wine: {compared} values bit-identical \
         to the run on both; the wine replays took {:.1} s",
        csv.rows(),
        columns,
        master_time.as_secs_f64(),
        units.len(),
        wine_time.as_secs_f64()
    ));
    let committed = root()
        .join("tests")
        .join("digests")
        .join(format!("{REPLAYED}.txt"));
    let text = std::fs::read_to_string(&committed).unwrap_or_else(|e| {
        panic!(
            "{}: {e} (the committed digest of {REPLAYED}, see tests/tests/digest.rs)",
            committed.display()
        )
    });
    let expected = Digest::parse(&text).unwrap_or_else(|e| panic!("{}: {e}", committed.display()));
    let got = Digest::of(&table, DIGEST_BLOCK);
    if let Some(difference) = got.first_difference(&expected) {
        panic!(
            "{REPLAYED} from the win64 binaries under wine ({rows} rows x {columns} columns) \
             differs from {}: {difference}",
            committed.display()
        );
    }
    say(&format!(
        "{REPLAYED}: the digest of the win64 replays ({rows} rows x {columns} columns) equals {}",
        committed.display()
    ));
}

/// The EMT unit's host-conformance trajectories (controllers/tests/conformance/, recorded from
/// `dvpp_controllers::emt::EmtUnit` in closed loop with the EMT plant), each written as an
/// `fmi2-trace` of the calls that feed its inputs to `dvpp_der_emt` and replayed by the test
/// master on the linux64 .so and, under wine, on the win64 .dll: every output of every step bit
/// for bit as the library gave it.
#[test]
fn emt_conformance_trajectories_replayed_under_wine_match_the_library() {
    use dvpp_controllers::emt::trajectory::N_OUT;
    use dvpp_e2e::conformance::{commands, trace, trajectories};
    let _one = WINE.lock().unwrap_or_else(|e| e.into_inner());
    let work = Path::new(env!("CARGO_TARGET_TMPDIR")).join("win64 conformance");
    let _ = std::fs::remove_dir_all(&work);
    std::fs::create_dir_all(&work).expect("create the work directory");
    let id = "dvpp_der_emt";
    let Some(mut zip) = open_fmu(&dist().join(format!("{id}.fmu")), id) else {
        return;
    };
    let md = description(&mut zip);
    let dir = work.join("fmu");
    zip.extract(&dir).expect("unpack the FMU");
    let Some(masters) = Masters::build(&work) else {
        return;
    };
    let resources = dir.join("resources");
    let so = dir.join("binaries/linux64").join(format!("{id}.so"));
    let dll = dir.join("binaries/win64").join(format!("{id}.dll"));
    for (path, t) in trajectories() {
        let (text, outputs) = trace(&md, &t);
        let trace_path = work.join(format!("{}.trace", t.case));
        std::fs::write(&trace_path, text).expect("write the trace");
        let mut linux = Command::new(&masters.native);
        linux
            .arg("replay")
            .arg(&so)
            .arg(&md.guid)
            .arg(file_uri(&resources.display().to_string(), "file://"))
            .arg(&trace_path)
            .arg(&outputs);
        let mut windows = masters.windows();
        windows
            .arg("replay")
            .arg(windows_path(&dll))
            .arg(&md.guid)
            .arg(file_uri(&windows_path(&resources), "file://"))
            .arg(windows_path(&trace_path))
            .arg(&outputs);
        for (mut cmd, platform) in [(linux, "linux64"), (windows, "win64 under wine")] {
            let what = format!("{}: {platform} replay", t.case);
            let started = Instant::now();
            let rows = samples(&mut cmd, &what, N_OUT);
            assert_eq!(rows.len(), t.steps.len() + 1, "{what}: samples");
            let (init, steps) = commands(&rows);
            if let Err(m) = t.compare(&init, &steps) {
                panic!(
                    "{} replayed by the test master ({platform}): {m}",
                    path.display()
                );
            }
            say(&format!(
                "{}: {} steps on {platform} bit for bit as the library ({:.1} s)",
                t.case,
                t.steps.len(),
                started.elapsed().as_secs_f64()
            ));
        }
    }
}

/// The real-code DLL of the EMT DER controller (dist/realcode/, docs/realcode.md) in a C import
/// host (tests/wine/realcode_host.c, built for linux64 and win64): three instances in one
/// process replay three of the library's host-conformance trajectories, bit for bit as the
/// library on both platforms, and each instance's second half again from a snapshot of its
/// state arrays; and the operator's DLL on both platforms, every output bit for bit.
#[test]
fn realcode_dll_under_wine_matches_linux64_and_the_library() {
    use dvpp_controllers::emt::trajectory::{INPUTS, N_OUT, OUTPUTS};
    use dvpp_controllers::emt::ParamValue;
    use dvpp_e2e::conformance::trajectories;
    let _one = WINE.lock().unwrap_or_else(|e| e.into_inner());
    let work = Path::new(env!("CARGO_TARGET_TMPDIR")).join("win64 realcode");
    let _ = std::fs::remove_dir_all(&work);
    std::fs::create_dir_all(&work).expect("create the work directory");
    let dist = dvpp_e2e::realcode_dist();
    let (so, dll) = (
        dist.join("linux64").join("dvpp_der_emt.so"),
        dist.join("win64").join("dvpp_der_emt.dll"),
    );
    assert!(so.is_file(), "{}: not bundled", so.display());
    if !dll.is_file() {
        skip(&format!(
            "{}: not bundled (no win64 cross toolchain when it was bundled)",
            dll.display()
        ));
        return;
    }
    let Some(masters) = Masters::build(&work) else {
        return;
    };
    // The host for both platforms, beside the win64 master (and its bcryptprimitives.dll).
    let bin = masters
        .exe
        .parent()
        .expect("the masters' directory")
        .to_path_buf();
    let (native, exe) = (bin.join("realcode_host"), bin.join("realcode_host.exe"));
    let src = root().join("tests").join("wine").join("realcode_host.c");
    let include = format!("-I{}", dist.join("include").display());
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    compile(
        &cc,
        std::slice::from_ref(&src),
        &[&include, "-ldl"],
        &native,
    );
    compile(MINGW, &[src], &[&include], &exe);
    // The C names of the DLL (FMU names with `_` for every other character).
    let c_name = |n: &str| -> String {
        let mut out = String::new();
        for ch in n.chars() {
            let ch = if ch.is_ascii_alphanumeric() { ch } else { '_' };
            if !(ch == '_' && out.ends_with('_')) {
                out.push(ch);
            }
        }
        out.trim_end_matches('_').to_string()
    };
    let hex = |x: f64| format!("{:016x}", x.to_bits());
    let cases = ["stiff_gfm_a", "weak_gfm_b", "weak_gfl"];
    let all = trajectories();
    let chosen: Vec<_> = cases
        .iter()
        .map(|c| &all.iter().find(|(_, t)| t.case == *c).expect("the case").1)
        .collect();
    let mut scripts = Vec::new();
    for t in &chosen {
        let mut s = String::new();
        for (name, v) in &t.params {
            let x = match v {
                ParamValue::Real(x) => *x,
                ParamValue::Integer(k) => f64::from(*k),
                ParamValue::Boolean(b) => f64::from(u8::from(*b)),
            };
            s.push_str(&format!("param {} {}\n", c_name(name), hex(x)));
        }
        let gains: Vec<String> = ["mu_p", "mu_q"]
            .into_iter()
            .map(String::from)
            .chain((1..=8).map(|k| format!("mu_p_lpf_{k}")))
            .collect();
        let mut g = vec![t.gains.mu_p, t.gains.mu_q];
        g.extend(t.gains.mu_p_lpf);
        s.push_str(&format!("input {} {}\n", INPUTS.join(" "), gains.join(" ")));
        let outs: Vec<String> = OUTPUTS.iter().map(|n| c_name(n)).collect();
        s.push_str(&format!("output {}\n", outs.join(" ")));
        let line = |kind: &str, time: f64, x: &[f64]| {
            let v: Vec<String> = x.iter().chain(&g).map(|x| hex(*x)).collect();
            format!("{kind} {time:e} {}\n", v.join(" "))
        };
        s.push_str(&line("init", t.init_t, &t.init_inputs));
        for st in &t.steps {
            assert_eq!(st.h, 50e-6, "{}: the DLL's fixed step", t.case);
            s.push_str(&line("step", st.t, &st.inputs));
        }
        let path = work.join(format!("{}.script", t.case));
        std::fs::write(&path, s).expect("write the script");
        scripts.push(path);
    }
    let mut linux = Command::new(&native);
    linux.arg(&so).args(&scripts);
    let mut windows = Command::new(&masters.wine);
    masters.environment(&mut windows);
    windows
        .arg(&exe)
        .arg(windows_path(&dll))
        .args(scripts.iter().map(|p| windows_path(p)));
    let mut seen = Vec::new();
    for (mut cmd, platform) in [(linux, "linux64"), (windows, "win64 under wine")] {
        let what = format!("the real-code DLL ({platform})");
        let started = Instant::now();
        let stdout = master_output(&mut cmd, &what);
        let mut per: Vec<Vec<[f64; N_OUT]>> = vec![Vec::new(); chosen.len()];
        for l in stdout.lines() {
            let w: Vec<&str> = l.split_whitespace().collect();
            if w.first() == Some(&"snapshot") {
                assert_eq!(w.get(2), Some(&"ok"), "{what}: {l}");
                continue;
            }
            if w.len() != N_OUT + 2 {
                continue;
            }
            let i: usize = w[0].parse().expect("an instance");
            let mut row = [0.0; N_OUT];
            for (o, h) in row.iter_mut().zip(&w[2..]) {
                *o = f64::from_bits(u64::from_str_radix(h, 16).expect("16 hex digits"));
            }
            per[i].push(row);
        }
        assert_eq!(
            stdout.matches("snapshot").count(),
            chosen.len(),
            "{what}: a snapshot line per instance"
        );
        for (t, rows) in chosen.iter().zip(&per) {
            assert_eq!(rows.len(), t.steps.len() + 1, "{what}: {}", t.case);
            if let Err(m) = t.compare(&rows[0], &rows[1..]) {
                panic!("{} through the real-code DLL ({platform}): {m}", t.case);
            }
        }
        say(&format!(
            "real-code DLL, {platform}: {} in one process, bit for bit as the library, snapshots restored ({:.1} s)",
            cases.join(", "),
            started.elapsed().as_secs_f64()
        ));
        seen.push(per);
    }
    assert_eq!(seen[0], seen[1], "linux64 and win64 outputs");

    // The operator DLL (1 ms): 1000 steps of a DVPP whose PCC frequency and powers swing, on
    // both platforms, every output bit for bit; and its second half again from a snapshot.
    let outputs = [
        "der_1_mu_p",
        "der_1_mu_q",
        "der_2_mu_p",
        "der_2_mu_q",
        "der_3_mu_q",
        "der_3_mu_p_lpf_1",
        "der_3_mu_p_lpf_2",
        "ref_df",
        "ref_dv",
        "err_df",
        "err_dv",
        "check_sum_mu_p",
        "check_sum_mu_q",
    ];
    let mut inputs = Vec::new();
    for k in 1..=3 {
        for n in ["P_avail", "p", "p_set", "q"] {
            inputs.push(format!("der_{k}_{n}"));
        }
    }
    inputs.extend(["pcc_p", "pcc_q", "pcc_f", "pcc_v"].map(String::from));
    let mut script = format!("input {}\noutput {}\n", inputs.join(" "), outputs.join(" "));
    for k in 0..=1000usize {
        let s = dvpp_math::sin(k as f64 * 0.01);
        let mut x = Vec::new();
        for d in 0..3 {
            x.extend([0.5, 0.3 + 0.01 * s * (d + 1) as f64, 0.3, 0.02]);
        }
        x.extend([
            0.9 + 0.03 * s,
            0.06 + 0.01 * s,
            1.0 - 1e-3 * s,
            1.0 + 1e-3 * s,
        ]);
        let v: Vec<String> = x.iter().map(|x| hex(*x)).collect();
        let kind = if k == 0 { "init" } else { "step" };
        script.push_str(&format!("{kind} {:e} {}\n", k as f64 * 1e-3, v.join(" ")));
    }
    let path = work.join("operator.script");
    std::fs::write(&path, script).expect("write the operator's script");
    let (so, dll) = (
        dist.join("linux64").join("dvpp_operator.so"),
        dist.join("win64").join("dvpp_operator.dll"),
    );
    let mut linux = Command::new(&native);
    linux.arg(&so).arg(&path);
    let mut windows = Command::new(&masters.wine);
    masters.environment(&mut windows);
    windows
        .arg(&exe)
        .arg(windows_path(&dll))
        .arg(windows_path(&path));
    let mut runs = Vec::new();
    for (mut cmd, platform) in [(linux, "linux64"), (windows, "win64 under wine")] {
        let what = format!("the operator's real-code DLL ({platform})");
        let stdout = master_output(&mut cmd, &what);
        assert!(stdout.contains("snapshot 0 ok"), "{what}: {stdout}");
        let rows: Vec<String> = stdout
            .lines()
            .filter(|l| l.starts_with("0 "))
            .map(String::from)
            .collect();
        assert_eq!(rows.len(), 1001, "{what}: a row per call");
        runs.push(rows);
    }
    assert_eq!(
        runs[0], runs[1],
        "the operator DLL: linux64 and win64 outputs"
    );
    // The response moved (ref_df, the 8th output, is not constant).
    let ref_df: std::collections::BTreeSet<&str> = runs[0]
        .iter()
        .filter_map(|r| r.split_whitespace().nth(2 + 7))
        .collect();
    assert!(ref_df.len() > 100, "the operator's ref_df hardly moved");
    say("real-code operator DLL: 1000 steps, linux64 and win64 under wine bit for bit, snapshot restored");
}
