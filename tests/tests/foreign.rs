//! Foreign FMUs (plain C in tests/foreign/, not built with fmi-export): alone, and as SSP systems run by our master.

use dvpp_cosim::master::{Error, Options, Scheme as Algorithm, System};
use dvpp_cosim::Table;
use dvpp_cosim::{Fmu, Instance, Status};
use dvpp_e2e::foreign::{build_foreign, foreign_dir, system, MODELS};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, OnceLock};

/// The system at `path` simulated to its end, every output in memory.
fn simulate(path: &Path, opts: &Options) -> Result<Table, Error> {
    System::builder(path).simulate(opts)
}

/// The built FMUs and both forms of each system, made once per test process.
struct Built {
    fmus: Vec<PathBuf>,
    step_lag_dir: PathBuf,
    step_lag_ssp: PathBuf,
    loop_dir: PathBuf,
}

fn built() -> &'static Built {
    static BUILT: OnceLock<Built> = OnceLock::new();
    BUILT.get_or_init(|| {
        let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("foreign");
        let _ = std::fs::remove_dir_all(&out);
        let fmus = build_foreign(&out);
        let (step_lag_dir, step_lag_ssp) = system(&out, "step_lag", &fmus);
        let (loop_dir, _) = system(&out, "loop", &fmus);
        Built {
            fmus,
            step_lag_dir,
            step_lag_ssp,
            loop_dir,
        }
    })
}

fn load(id: &str) -> Arc<Fmu> {
    let i = MODELS
        .iter()
        .position(|m| m.1 == id)
        .expect("a foreign model");
    Arc::new(Fmu::load(&built().fmus[i]).unwrap_or_else(|e| panic!("{e}")))
}

fn vr(fmu: &Fmu, name: &str) -> u32 {
    fmu.vr(name).unwrap_or_else(|e| panic!("{e}"))
}

fn get(i: &mut Instance, name: &str) -> f64 {
    let r = vr(i.fmu(), name);
    let mut x = [f64::NAN];
    assert_eq!(i.get_real(&[r], &mut x), Status::Ok, "get {name}");
    x[0]
}

fn set(i: &mut Instance, name: &str, value: f64) -> Status {
    let r = vr(i.fmu(), name);
    i.set_real(&[r], &[value])
}

/// A new instance of `fmu` named `name`, in initialization mode with start time `start`.
fn in_initialization(fmu: &Arc<Fmu>, name: &str, start: f64) -> Instance {
    let mut i = fmu.instantiate(name).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(i.setup_experiment(start, None), Status::Ok, "{name}");
    assert_eq!(i.enter_initialization_mode(), Status::Ok, "{name}");
    i
}

// ---------------------------------------------------------------------------------------------
// The step_lag system (tests/foreign/step_lag.ssd) and its reference, derived independently.

/// Communication step and number of steps to the SSD's stopTime 1.
const H: f64 = 0.01;
const N: usize = 100;
/// Parameter bindings of step_lag.ssd (each differs from the start value in the XML).
const AMPLITUDE: f64 = 2.0;
const OFFSET: f64 = 0.25;
const T_STEP: f64 = 0.105; // between communication points: no rounding decides when it shows
const T1: f64 = 0.25;
const K1: f64 = 1.5;
const Y01: f64 = 0.1;
const G: f64 = 3.0;
const T2: f64 = 0.5; // lag2: k and y0 stay at the XML start values 1 and 0
const K2: f64 = 1.0;
const Y02: f64 = 0.0;
/// The LinearTransformation on source.y -> lag.u.
const FACTOR: f64 = 2.0;
const SHIFT: f64 = 0.5;

/// source.y at communication point k: the source evaluates its step at the end of each step.
fn source_at(k: usize) -> f64 {
    OFFSET
        + if k as f64 * H >= T_STEP {
            AMPLITUDE
        } else {
            0.0
        }
}

/// Expected columns of step_lag, index k = time k * H.
#[derive(Debug)]
struct Reference {
    source: Vec<f64>,
    lag: Vec<f64>,
    gain: Vec<f64>,
    lag2: Vec<f64>,
}

/// The reference for our master's coupling (see cosim/src/master.rs): initialization exchanges
/// until every input is consistent, so at t = 0 gain.y = G * y0. Each communication point ends
/// with an exchange in dependency order, so the feedthrough gain always shows G * lag.y of the
/// same point, and every input is held (zero-order) over the next step. Jacobi steps all units
/// from the exchange at t_k: lag holds 2 source(t_k) + 0.5 and lag2 holds G lag(t_k). Gauss-Seidel
/// steps source, lag, gain, lag2 in this order, each after the outputs of the ones before were
/// exchanged: lag holds 2 source(t_k+1) + 0.5 and lag2 holds G lag(t_k+1).
fn reference(algorithm: Algorithm) -> Reference {
    let source: Vec<f64> = (0..=N).map(source_at).collect();
    let (a1, a2) = (dvpp_math::exp(-H / T1), dvpp_math::exp(-H / T2));
    let (mut lag, mut lag2) = (vec![Y01], vec![Y02]);
    for k in 0..N {
        // The exact lag for an input held over [t_k, t_k+1].
        let seen = match algorithm {
            Algorithm::Jacobi => k,
            // A converged iterative step sees the end-of-step value, as Gauss-Seidel does on a
            // chain without feedback (these FMUs cannot roll back, so it is never run here).
            Algorithm::GaussSeidel | Algorithm::Iterative => k + 1,
        };
        let u1 = FACTOR * source[seen] + SHIFT;
        lag.push(a1 * lag[k] + (1.0 - a1) * K1 * u1);
        let u2 = G * lag[seen];
        lag2.push(a2 * lag2[k] + (1.0 - a2) * K2 * u2);
    }
    let gain = lag.iter().map(|y| G * y).collect();
    Reference {
        source,
        lag,
        gain,
        lag2,
    }
}

/// The lag's closed-form response: its input steps from 2 OFFSET + 0.5 to 2 (OFFSET +
/// AMPLITUDE) + 0.5 at `t_switch`, the communication point from which the lag holds the new value.
fn lag_closed_form(t: f64, t_switch: f64) -> f64 {
    let (low, high) = (
        FACTOR * OFFSET + SHIFT,
        FACTOR * (OFFSET + AMPLITUDE) + SHIFT,
    );
    let before = |t: f64| K1 * low + (Y01 - K1 * low) * dvpp_math::exp(-t / T1);
    if t <= t_switch {
        before(t)
    } else {
        K1 * high + (before(t_switch) - K1 * high) * dvpp_math::exp(-(t - t_switch) / T1)
    }
}

/// When the lag starts holding the stepped source: the first communication point at or after
/// T_STEP (Jacobi: the step is seen one step after it happened), or the one before (Gauss-Seidel).
fn switch_time(algorithm: Algorithm) -> f64 {
    let first = (T_STEP / H).ceil();
    match algorithm {
        Algorithm::Jacobi => first * H,
        Algorithm::GaussSeidel | Algorithm::Iterative => (first - 1.0) * H,
    }
}

fn options(algorithm: Algorithm) -> Options {
    Options {
        stop: None, // the SSD's DefaultExperiment: 1 s
        step: Some(H),
        algorithm,
    }
}

fn column(table: &Table, name: &str) -> Vec<f64> {
    table
        .column(name)
        .unwrap_or_else(|| panic!("no column {name} in {:?}", table.columns))
}

/// `got` matches `want` at every communication point within `tol`.
fn assert_close(what: &str, got: &[f64], want: &[f64], tol: f64) {
    assert_eq!(got.len(), want.len(), "{what}: number of points");
    for (k, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            (g - w).abs() <= tol,
            "{what} at t = {} (point {k}): got {g:.17}, want {w:.17}, error {:e}",
            k as f64 * H,
            (g - w).abs()
        );
    }
}

fn check_step_lag(algorithm: Algorithm) {
    let table = simulate(&built().step_lag_dir, &options(algorithm))
        .unwrap_or_else(|e| panic!("step_lag ({algorithm:?}): {e}"));
    let want = reference(algorithm);

    // The reference recursion is the closed-form exponential at every point.
    let closed: Vec<f64> = (0..=N)
        .map(|k| lag_closed_form(k as f64 * H, switch_time(algorithm)))
        .collect();
    assert_close("reference lag vs closed form", &want.lag, &closed, 1e-13);

    let times: Vec<f64> = (0..=N).map(|k| k as f64 * H).collect();
    assert_close("time", &column(&table, "time"), &times, 1e-12);
    // Start values from the SSD, not the XML (offset 0, y0 0, g 1 would give 0 everywhere here).
    let row0 = |name: &str| column(&table, name)[0];
    assert_eq!(row0("source.y"), OFFSET);
    assert_eq!(row0("lag.y"), Y01);
    assert!((row0("gain.y") - G * Y01).abs() <= 1e-15);
    assert_close("source.y", &column(&table, "source.y"), &want.source, 1e-12);
    assert_close("lag.y", &column(&table, "lag.y"), &want.lag, 1e-12);
    assert_close("gain.y", &column(&table, "gain.y"), &want.gain, 1e-12);
    assert_close("lag2.y", &column(&table, "lag2.y"), &want.lag2, 1e-12);
}

#[test]
fn step_lag_jacobi_matches_the_reference() {
    check_step_lag(Algorithm::Jacobi);
}

#[test]
fn step_lag_gauss_seidel_matches_the_reference() {
    check_step_lag(Algorithm::GaussSeidel);
}

#[test]
fn the_references_tell_the_algorithms_apart() {
    // Without this the two reference tests could pass with the algorithm option ignored.
    let (j, g) = (
        reference(Algorithm::Jacobi),
        reference(Algorithm::GaussSeidel),
    );
    let k = (switch_time(Algorithm::Jacobi) / H).round() as usize;
    assert!(
        (j.lag[k] - g.lag[k]).abs() > 0.1,
        "{} vs {}",
        j.lag[k],
        g.lag[k]
    );
    assert!((j.lag2[k + 1] - g.lag2[k + 1]).abs() > 0.01);
    assert_eq!(j.lag[..k], g.lag[..k]);
}

#[test]
fn step_lag_as_ssp_archive_equals_the_directory_form() {
    for algorithm in [Algorithm::Jacobi, Algorithm::GaussSeidel] {
        let b = built();
        let dir = simulate(&b.step_lag_dir, &options(algorithm)).unwrap_or_else(|e| panic!("{e}"));
        let ssp = simulate(&b.step_lag_ssp, &options(algorithm)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(dir.columns, ssp.columns);
        assert_eq!(dir.rows, ssp.rows, "{algorithm:?}");
    }
}

/// The master runs an algebraic loop broken at one connection and reports it as a warning
/// (`Builder::run`'s `Outcome::warnings`); the report must name both gains and say "loop" or
/// "cycle". Both algorithms order the exchange by feedthrough, so both must see the loop.
#[test]
fn algebraic_loop_is_reported() {
    for algorithm in [Algorithm::GaussSeidel, Algorithm::Jacobi] {
        // Documented behaviour: the loop is reported as a warning and broken, the run goes on.
        let report = match System::builder(&built().loop_dir).run(&options(algorithm), &mut []) {
            Err(e) => panic!("{algorithm:?}: the loop should be broken, not fatal: {e}"),
            Ok(outcome) => outcome.warnings.join("\n"),
        };
        assert!(
            report.contains("gain1")
                && report.contains("gain2")
                && (report.contains("loop") || report.contains("cycle")),
            "{algorithm:?}: the loop gain1 <-> gain2 is not reported: {report:?}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Bad systems: one clear error naming the element, nothing run.

/// The step_lag system with its SSD text edited by `edit` and `drop` left out of resources/.
fn bad_system(name: &str, edit: impl Fn(&str) -> String, drop: Option<&str>) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("bad")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("resources")).expect("create the system directory");
    let ssd = std::fs::read_to_string(foreign_dir().join("step_lag.ssd")).expect("the SSD");
    std::fs::write(dir.join("SystemStructure.ssd"), edit(&ssd)).expect("write the SSD");
    for fmu in &built().fmus {
        let file = fmu.file_name().expect("a file name").to_string_lossy();
        if Some(&*file) != drop {
            std::fs::copy(fmu, dir.join("resources").join(&*file)).expect("copy the FMU");
        }
    }
    dir
}

fn error_of(dir: &Path) -> String {
    match simulate(dir, &options(Algorithm::Jacobi)) {
        Ok(_) => panic!("{}: a bad system ran", dir.display()),
        Err(e) => e.to_string(),
    }
}

fn assert_names(error: &str, words: &[&str]) {
    for w in words {
        assert!(error.contains(w), "the error does not name {w:?}: {error}");
    }
}

#[test]
fn a_missing_fmu_file_is_named() {
    let e = error_of(&bad_system(
        "missing",
        str::to_owned,
        Some("foreign_gain.fmu"),
    ));
    assert_names(&e, &["gain", "foreign_gain.fmu"]);
}

#[test]
fn an_unknown_element_is_named() {
    let e = error_of(&bad_system(
        "element",
        |s| s.replace(r#"endElement="lag2""#, r#"endElement="lag3""#),
        None,
    ));
    assert_names(&e, &["lag3"]);
}

#[test]
fn an_unknown_connector_is_named() {
    // Declared on the component but not a variable of the FMU.
    let e = error_of(&bad_system(
        "connector",
        |s| {
            s.replacen(
                r#"<ssd:Connector name="t_step""#,
                r#"<ssd:Connector name="t_stop""#,
                1,
            )
            .replacen(
                r#"<ssv:Parameter name="t_step">"#,
                r#"<ssv:Parameter name="t_stop">"#,
                1,
            )
        },
        None,
    ));
    assert_names(&e, &["source", "t_stop"]);
}

#[test]
fn mismatched_types_are_named() {
    let e = error_of(&bad_system(
        "types",
        |s| {
            s.replacen(
                "<ssd:Connector name=\"y\" kind=\"output\">\n            <ssc:Real/>",
                "<ssd:Connector name=\"y\" kind=\"output\">\n            <ssc:Integer/>",
                1,
            )
        },
        None,
    ));
    assert_names(&e, &["y", "Integer"]);
}

#[test]
fn malformed_xml_is_reported_with_the_file() {
    let e = error_of(&bad_system("xml", |s| s[..s.len() / 2].to_owned(), None));
    assert_names(&e, &["SystemStructure.ssd"]);
}

#[test]
fn an_unknown_element_kind_is_named() {
    let e = error_of(&bad_system(
        "kind",
        |s| s.replacen("<ssd:Connection ", "<ssd:Conection ", 1),
        None,
    ));
    assert_names(&e, &["Conection"]);
}

#[test]
fn the_cosim_binary_exits_non_zero_on_a_bad_system() {
    let dir = bad_system("binary", str::to_owned, Some("foreign_lag.fmu"));
    // Beside the system's directory: an --out inside it is refused before the system is read.
    let results = dir.with_file_name("binary_out.csv");
    let _ = std::fs::remove_file(&results);
    let out = Command::new(dvpp_e2e::cosim())
        .arg(&dir)
        .arg("--out")
        .arg(&results)
        .output()
        .expect("run cosim");
    assert!(!out.status.success(), "cosim succeeded on a bad system");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_names(&stderr, &["foreign_lag.fmu"]);
    assert!(!results.exists(), "a failed run wrote results");
}

// ---------------------------------------------------------------------------------------------
// The FMUs on their own, through our FMU loader.

#[test]
fn printf_arguments_of_foreign_log_messages_are_substituted() {
    let fmu = load("foreign_lag");
    let mut i = in_initialization(&fmu, "lag_under_test", 0.0);
    assert_eq!(i.set_debug_logging(true, &["logAll"]), Status::Ok);
    assert_eq!(set(&mut i, "T", 0.25), Status::Ok);
    assert_eq!(set(&mut i, "y0", -1e-7), Status::Ok);
    assert_eq!(i.exit_initialization_mode(), Status::Ok);
    let info = i
        .log()
        .into_iter()
        .find(|r| r.message.starts_with("initialized"))
        .expect("an 'initialized' message with debug logging on");
    assert_eq!(
        info.message,
        "initialized lag_under_test (T = 0.25, k = 1, y0 = -1e-07)"
    );
    assert_eq!(
        (info.status, info.category.as_str()),
        (Status::Ok, "logAll")
    );

    // Error paths log with %g and %u.
    assert_eq!(i.do_step(0.0, -0.5), Status::Error);
    assert_eq!(
        i.last_message().as_deref(),
        Some("fmi2DoStep: invalid communication step size h = -0.5 at t = 0")
    );
    assert_eq!(i.get_real(&[4_000_000_000], &mut [0.0]), Status::Error);
    assert_eq!(
        i.last_message().as_deref(),
        Some("fmi2GetReal: unknown value reference 4000000000")
    );
    assert!(
        i.log().iter().all(|r| !r.message.contains('%')),
        "{:?}",
        i.log()
    );
}

#[test]
fn long_formatted_log_messages_are_not_truncated() {
    let fmu = load("foreign_gain");
    let name = format!("gain_{}", "x".repeat(20_000));
    let mut i = in_initialization(&fmu, &name, 0.0);
    assert_eq!(i.set_debug_logging(true, &[]), Status::Ok);
    assert_eq!(i.exit_initialization_mode(), Status::Ok);
    assert_eq!(
        i.last_message(),
        Some(format!("initialized {name} (g = 1)"))
    );
}

#[test]
fn errors_are_logged_formatted_without_debug_logging() {
    let fmu = load("foreign_lag");
    let mut i = in_initialization(&fmu, "bad_lag", 0.0);
    assert_eq!(set(&mut i, "T", -0.25), Status::Ok);
    assert_eq!(i.exit_initialization_mode(), Status::Error);
    let log = i.log();
    assert_eq!(log.len(), 1, "only the error, no debug messages: {log:?}");
    assert_eq!(log[0].status, Status::Error);
    assert_eq!(log[0].category, "logError");
    assert_eq!(
        log[0].message,
        "bad_lag: the time constant T = -0.25 must be positive"
    );

    // A GUID mismatch is reported with both GUIDs substituted, and no instance is made.
    let e = fmu
        .instantiate_with("wrong", "{not-the-guid}", &fmu.resource_uri(), 1)
        .err()
        .expect("instantiate with a wrong GUID fails");
    let text = e.to_string();
    assert!(
        text.contains("GUID {not-the-guid} does not match {a1e4b7c0-"),
        "{text}"
    );
}

#[test]
fn every_foreign_fmu_loads_and_follows_the_fmi_rules() {
    for (_, id) in MODELS {
        let fmu = load(id); // resolves all FMI 2.0 Co-Simulation functions
        assert_eq!(
            fmu.version_and_platform(),
            ("2.0".to_owned(), "default".to_owned())
        );
        let md = &fmu.description;
        assert_eq!(
            (md.model_name.as_str(), md.model_identifier()),
            (id, Some(id))
        );
        let problems = model_description::check(md);
        assert!(problems.is_empty(), "{id}: {problems:?}");

        let mut i = in_initialization(&fmu, id, 0.0);
        assert_eq!(i.exit_initialization_mode(), Status::Ok);
        // Outputs cannot be set; fixed parameters not in step mode; no such Integer variable.
        assert_eq!(set(&mut i, "y", 1.0), Status::Error, "{id}");
        let param = md
            .model_variables
            .variables
            .iter()
            .find(|v| v.causality() == model_description::Causality::Parameter)
            .expect("a parameter");
        assert_eq!(set(&mut i, &param.name, 1.0), Status::Error, "{id}");
        assert_eq!(i.get_integer(&[0], &mut [0]), Status::Error, "{id}");
        // Optional capabilities are declared absent and refused.
        assert!(i.get_state().1.is_none(), "{id}");
        for (name, status) in i.call_unsupported() {
            assert_eq!(status, Status::Error, "{id}: {name}");
        }
        assert_eq!(i.last_successful_time(), (Status::Ok, 0.0), "{id}");
        assert_eq!(i.do_step(0.0, H), Status::Ok, "{id}");
        assert_eq!(i.last_successful_time(), (Status::Ok, H), "{id}");
        // A step that does not start where the last one ended is refused.
        assert_eq!(i.do_step(0.5, H), Status::Error, "{id}");
        assert_eq!(i.terminate(), Status::Ok);
    }
}

#[test]
fn model_structures_declare_feedthrough_only_for_the_gain() {
    for (id, feedthrough) in [
        ("foreign_source", vec![]),
        ("foreign_lag", vec![]),
        ("foreign_gain", vec![1]), // y (index 2) depends on u (index 1)
    ] {
        let fmu = load(id);
        let deps = model_description::direct_feedthrough(&fmu.description);
        assert_eq!(deps.len(), 1, "{id}: one output");
        assert_eq!(deps.values().next(), Some(&feedthrough), "{id}");
    }
}

#[test]
fn lag_alone_is_the_exact_exponential() {
    let fmu = load("foreign_lag");
    let mut i = in_initialization(&fmu, "lag", 0.0);
    for (name, value) in [("T", T1), ("k", K1), ("y0", Y01), ("u", 2.0)] {
        assert_eq!(set(&mut i, name, value), Status::Ok, "{name}");
    }
    assert_eq!(get(&mut i, "y"), Y01, "y = y0 in initialization mode");
    assert_eq!(i.exit_initialization_mode(), Status::Ok);
    // Uneven steps: the discretization is exact for any step size.
    let mut t = 0.0;
    for k in 0..60 {
        let h = [0.01, 0.037, 0.2][k % 3];
        assert_eq!(i.do_step(t, h), Status::Ok);
        t += h;
        let exact = K1 * 2.0 + (Y01 - K1 * 2.0) * dvpp_math::exp(-t / T1);
        assert!((get(&mut i, "y") - exact).abs() < 1e-13, "t = {t}");
    }
}

#[test]
fn gain_output_follows_its_input_at_once() {
    let fmu = load("foreign_gain");
    let mut i = in_initialization(&fmu, "gain", 0.0);
    assert_eq!(set(&mut i, "g", G), Status::Ok);
    assert_eq!(set(&mut i, "u", 1.5), Status::Ok);
    assert_eq!(get(&mut i, "y"), G * 1.5, "in initialization mode");
    assert_eq!(i.exit_initialization_mode(), Status::Ok);
    assert_eq!(set(&mut i, "u", -2.0), Status::Ok);
    assert_eq!(
        get(&mut i, "y"),
        G * -2.0,
        "after fmi2SetReal, before fmi2DoStep"
    );
    assert_eq!(i.do_step(0.0, H), Status::Ok);
    assert_eq!(get(&mut i, "y"), G * -2.0, "after the step");
}

#[test]
fn source_gives_its_value_at_the_start_time_and_at_step_ends() {
    let fmu = load("foreign_source");
    for (start, before_step) in [(0.0, true), (0.2, false)] {
        let mut i = in_initialization(&fmu, "source", start);
        for (name, value) in [
            ("amplitude", AMPLITUDE),
            ("offset", OFFSET),
            ("t_step", T_STEP),
        ] {
            assert_eq!(set(&mut i, name, value), Status::Ok, "{name}");
        }
        let at_start = if before_step {
            OFFSET
        } else {
            OFFSET + AMPLITUDE
        };
        assert_eq!(get(&mut i, "y"), at_start, "start {start}");
        assert_eq!(i.exit_initialization_mode(), Status::Ok);
        // One step over T_STEP: the value at its end.
        assert_eq!(i.do_step(start, 0.15), Status::Ok);
        assert_eq!(get(&mut i, "y"), OFFSET + AMPLITUDE, "start {start}");
    }
}
