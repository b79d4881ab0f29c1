//! The in-process harness and the exported C functions agree: the same call sequences return
//! the same statuses and values and log the same records, failures of `fmi2Instantiate` included.

use fmi_export::ffi::{
    fmi2CallbackFunctions, fmi2Component, fmi2ComponentEnvironment, fmi2FMUstate, fmi2Status,
    fmi2String, FMI2_COSIMULATION, FMI2_DO_STEP_STATUS, FMI2_LAST_SUCCESSFUL_TIME,
};
use fmi_export::harness::Harness;
use fmi_export::instance::Phase;
use fmi_export::log::LogRecord;
use fmi_export::{
    Config, Context, Integer, Model, ModelError, Real, Spec, Status, Store, Variables,
};
use serde::{Deserialize, Serialize};
use std::ffi::{CStr, CString};
use std::sync::Mutex;

#[derive(Clone, Serialize, Deserialize)]
struct Probe {
    gain: Real,
    x: Real,
    n: Integer,
    y: Real,
    count: Real,
}

impl Model for Probe {
    type Config = ();
    type State = ();
    const IDENTIFIER: &'static str = "probe";
    const NAME: &'static str = "probe";
    const DESCRIPTION: &'static str = "y = gain x; panics when x > 1, fails when x < -1";
    const MAX_STEP: f64 = 1.0;

    fn declare(_: &(), _: Option<&std::path::Path>, v: &mut Variables) -> Result<Self, String> {
        Ok(Probe {
            gain: v.real(Spec::parameter("gain", 2.0, "", "gain").range(0.0, 10.0)),
            x: v.real(Spec::input("x", 0.0, "", "input")),
            n: v.integer(Spec::input("n", 1, "", "steps per call").range(1.0, 5.0)),
            y: v.real(Spec::output("y", "", "gain x").initial_dependencies(&["x"])),
            count: v.real(Spec::output("count", "", "steps taken")),
        })
    }

    fn initialize(
        &self,
        _: Option<&()>,
        s: &mut Store,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        if s[self.gain] == 0.0 {
            return Err("'gain' = 0: must be > 0".into());
        }
        s[self.y] = s[self.gain] * s[self.x];
        s[self.count] = 0.0;
        ctx.event(format!("initialized with y = {}", s[self.y]));
        Ok(())
    }

    fn do_step(
        &self,
        _: &mut (),
        s: &mut Store,
        _: f64,
        _: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        let x = s[self.x];
        if x > 1.0 {
            panic!("x = {x} is too large");
        }
        if x < -1.0 {
            return Err("x below -1".into());
        }
        if x == 0.5 {
            ctx.warn("x is 50%");
        }
        s[self.y] = s[self.gain] * x;
        s[self.count] += s[self.n] as f64;
        Ok(())
    }
}

fmi_export::export_fmu!(Probe);

type Records = Mutex<Vec<LogRecord>>;

// Stable Rust cannot define a C-variadic function; the layer passes no variadic arguments, so
// a logger with only the fixed parameters receives them correctly.
unsafe extern "C" fn capture(
    env: fmi2ComponentEnvironment,
    instance: fmi2String,
    status: fmi2Status,
    category: fmi2String,
    message: fmi2String,
) {
    // SAFETY: the FMU passes NUL-terminated strings that live for the call.
    let text = |p: fmi2String| unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned();
    // SAFETY: `env` is the `Records` this test registered as the component environment, alive
    // while the instance is.
    let records = unsafe { &*(env as *const Records) };
    records.lock().unwrap().push(LogRecord {
        instance: text(instance),
        status: Status::from_c(status),
        category: text(category),
        message: text(message),
    });
}

type Fixed =
    unsafe extern "C" fn(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String);
type Variadic = fmi_export::ffi::fmi2CallbackLoggerTYPE;

fn callbacks(records: &Records) -> fmi2CallbackFunctions {
    fmi2CallbackFunctions {
        // SAFETY: see `capture`.
        logger: Some(unsafe { std::mem::transmute::<Fixed, Variadic>(capture) }),
        allocate_memory: None,
        free_memory: None,
        step_finished: None,
        component_environment: records as *const Records as fmi2ComponentEnvironment,
    }
}

fn guid() -> String {
    fmi_export::describe::<Probe>(&Config::default(), None)
        .unwrap()
        .guid
}

/// A resources directory with an empty config.toml (the defaults).
struct Resources(std::path::PathBuf);

impl Resources {
    fn new(tag: &str, config: &str) -> Self {
        let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
            .join(format!("probe-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("config.toml"), config).unwrap();
        Resources(dir)
    }
}

impl Drop for Resources {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// One call of the sequence both drivers run.
#[derive(Debug, Clone)]
enum Op {
    Setup(f64, Option<f64>),
    Enter,
    Exit,
    SetReal(&'static [u32], &'static [f64]),
    SetInteger(&'static [u32], &'static [i32]),
    GetReal(&'static [u32]),
    Step(f64, f64),
    Terminate,
    Reset,
    SaveState,
    RestoreState,
    RoundTripState,
    DebugLogging(bool, &'static [&'static str]),
    RealStatus(i32),
    Cancel,
}

/// What a call returned: its status and any values.
type Outcome = (Status, Vec<f64>);

const GAIN: u32 = 0;
const X: u32 = 1;
const Y: u32 = 2;
const COUNT: u32 = 3;
const N: u32 = 0;

fn sequence() -> Vec<Op> {
    use Op::*;
    vec![
        // Illegal before initialization: an error state, left by reset.
        GetReal(&[Y]),
        Step(0.0, 0.1),
        Reset,
        SetReal(&[GAIN], &[0.0]),
        Setup(0.0, Some(1.0)),
        Enter,
        // Outputs computed on demand in initialization mode; the model fails on gain = 0.
        GetReal(&[Y]),
        Reset,
        DebugLogging(true, &[]),
        Setup(0.0, Some(1.0)),
        SetReal(&[GAIN, X], &[3.0, 0.25]),
        Enter,
        GetReal(&[Y, GAIN]),
        SetReal(&[X], &[0.2]),
        Exit,
        GetReal(&[Y, X]),
        // A fixed parameter cannot change after initialization; values out of range or not
        // finite are refused and change nothing.
        SetReal(&[GAIN], &[4.0]),
        Reset,
        Setup(0.0, Some(1.0)),
        Enter,
        Exit,
        SetReal(&[X], &[f64::NAN]),
        GetReal(&[X, Y]),
        Reset,
        Setup(0.0, Some(1.0)),
        Enter,
        Exit,
        SetInteger(&[N], &[9]),
        SetReal(&[X], &[0.5]),
        GetReal(&[X, Y, COUNT]),
        Reset,
        Setup(0.0, Some(1.0)),
        Enter,
        Exit,
        SetInteger(&[N], &[2]),
        SetReal(&[X], &[0.5]),
        Step(0.0, 0.1),
        SaveState,
        SetReal(&[X], &[0.1]),
        Step(0.1, 0.1),
        GetReal(&[Y, COUNT]),
        RealStatus(FMI2_LAST_SUCCESSFUL_TIME),
        RestoreState,
        GetReal(&[Y, COUNT]),
        RoundTripState,
        GetReal(&[Y, COUNT]),
        // Wrong time, past the stop time, a bad step size, an unknown reference.
        Step(0.5, 0.1),
        Reset,
        Setup(0.0, Some(0.15)),
        Enter,
        Exit,
        Step(0.0, 0.1),
        Step(0.1, 0.1),
        Reset,
        Setup(0.0, None),
        Enter,
        Exit,
        Step(0.0, -0.1),
        Reset,
        Setup(0.0, None),
        Enter,
        Exit,
        GetReal(&[7]),
        Reset,
        Setup(0.0, None),
        Enter,
        Exit,
        Cancel,
        Reset,
        DebugLogging(false, &["logEvents", "logNoSuchCategory"]),
        Reset,
        Setup(0.0, None),
        Enter,
        Exit,
        // A model error, then a terminate that is legal only after a recovery.
        SetReal(&[X], &[-2.0]),
        Step(0.0, 0.1),
        Terminate,
        Reset,
        Setup(0.0, None),
        Enter,
        Exit,
        Step(0.0, 0.1),
        Terminate,
        RealStatus(FMI2_LAST_SUCCESSFUL_TIME),
        RealStatus(FMI2_DO_STEP_STATUS),
        Reset,
        Setup(0.0, None),
        Enter,
        Exit,
        // A panic: contained, fmi2Fatal; afterwards nothing but freeing.
        SetReal(&[X], &[5.0]),
        Step(0.0, 0.1),
        GetReal(&[Y]),
        Reset,
        SaveState,
    ]
}

fn through_c(ops: &[Op], records: &Records) -> Vec<Outcome> {
    use self::fmi2::*;
    let cb = callbacks(records);
    let res = Resources::new("c", "");
    let (name, guid, loc) = (
        CString::new("probe").unwrap(),
        CString::new(guid()).unwrap(),
        CString::new(format!("file://{}", res.0.display())).unwrap(),
    );
    let mut out = Vec::new();
    // SAFETY: FMI calls on an instance this block creates and frees, with C strings and output
    // buffers that outlive each call.
    unsafe {
        let c: fmi2Component = fmi2Instantiate(
            name.as_ptr(),
            FMI2_COSIMULATION,
            guid.as_ptr(),
            loc.as_ptr(),
            &cb,
            0,
            0,
        );
        assert!(!c.is_null(), "{:#?}", records.lock().unwrap());
        let mut saved: fmi2FMUstate = std::ptr::null_mut();
        for op in ops {
            out.push(match *op {
                Op::Setup(start, stop) => (
                    fmi2SetupExperiment(
                        c,
                        0,
                        0.0,
                        start,
                        stop.is_some() as i32,
                        stop.unwrap_or(0.0),
                    ),
                    vec![],
                ),
                Op::Enter => (fmi2EnterInitializationMode(c), vec![]),
                Op::Exit => (fmi2ExitInitializationMode(c), vec![]),
                Op::SetReal(vr, v) => (fmi2SetReal(c, vr.as_ptr(), vr.len(), v.as_ptr()), vec![]),
                Op::SetInteger(vr, v) => {
                    (fmi2SetInteger(c, vr.as_ptr(), vr.len(), v.as_ptr()), vec![])
                }
                Op::GetReal(vr) => {
                    let mut v = vec![-1.0; vr.len()];
                    let s = fmi2GetReal(c, vr.as_ptr(), vr.len(), v.as_mut_ptr());
                    (s, v)
                }
                Op::Step(t, h) => (fmi2DoStep(c, t, h, 1), vec![]),
                Op::Terminate => (fmi2Terminate(c), vec![]),
                Op::Reset => (fmi2Reset(c), vec![]),
                Op::SaveState => (fmi2GetFMUstate(c, &mut saved), vec![]),
                Op::RestoreState => (fmi2SetFMUstate(c, saved), vec![]),
                Op::RoundTripState => {
                    let mut size = 0;
                    let mut s = fmi2SerializedFMUstateSize(c, saved, &mut size);
                    let mut bytes = vec![0 as std::os::raw::c_char; size];
                    s = s.max(fmi2SerializeFMUstate(c, saved, bytes.as_mut_ptr(), size));
                    let mut restored: fmi2FMUstate = std::ptr::null_mut();
                    s = s.max(fmi2DeSerializeFMUstate(
                        c,
                        bytes.as_ptr(),
                        size,
                        &mut restored,
                    ));
                    s = s.max(fmi2SetFMUstate(c, restored));
                    s = s.max(fmi2FreeFMUstate(c, &mut restored));
                    (s, vec![])
                }
                Op::DebugLogging(on, cats) => {
                    let names: Vec<CString> =
                        cats.iter().map(|n| CString::new(*n).unwrap()).collect();
                    let ptrs: Vec<fmi2String> = names.iter().map(|n| n.as_ptr()).collect();
                    (
                        fmi2SetDebugLogging(c, on as i32, ptrs.len(), ptrs.as_ptr()),
                        vec![],
                    )
                }
                Op::RealStatus(kind) => {
                    let mut t = -1.0;
                    let s = fmi2GetRealStatus(c, kind, &mut t);
                    (s, vec![t])
                }
                Op::Cancel => (fmi2CancelStep(c), vec![]),
            });
        }
        fmi2FreeInstance(c);
    }
    out.into_iter()
        .map(|(s, v)| (Status::from_c(s), v))
        .collect()
}

fn through_harness(ops: &[Op]) -> (Vec<Outcome>, Vec<LogRecord>) {
    let res = Resources::new("harness", "");
    let location = format!("file://{}", res.0.display());
    let mut h = Harness::<Probe>::instantiate(
        "probe",
        FMI2_COSIMULATION,
        Some(&guid()),
        Some(&location),
        false,
    )
    .unwrap();
    let mut saved = None;
    let mut out = Vec::new();
    for op in ops {
        out.push(match *op {
            Op::Setup(start, stop) => (h.setup_experiment(start, stop), vec![]),
            Op::Enter => (h.enter_initialization_mode(), vec![]),
            Op::Exit => (h.exit_initialization_mode(), vec![]),
            Op::SetReal(vr, v) => (h.set_real(vr, v), vec![]),
            Op::SetInteger(vr, v) => (h.set_integer(vr, v), vec![]),
            Op::GetReal(vr) => {
                let mut v = vec![-1.0; vr.len()];
                (h.get_real(vr, &mut v), v)
            }
            Op::Step(t, dt) => (h.do_step(t, dt), vec![]),
            Op::Terminate => (h.terminate(), vec![]),
            Op::Reset => (h.reset(), vec![]),
            Op::SaveState => match h.get_fmu_state() {
                Ok(s) => {
                    saved = Some(s);
                    (Status::Ok, vec![])
                }
                Err(s) => (s, vec![]),
            },
            Op::RestoreState => (h.set_fmu_state(saved.as_ref().unwrap()), vec![]),
            Op::RoundTripState => {
                let bytes = h.serialize_fmu_state(saved.as_ref().unwrap()).unwrap();
                let restored = h.deserialize_fmu_state(&bytes).unwrap();
                (h.set_fmu_state(&restored), vec![])
            }
            Op::DebugLogging(on, cats) => (h.set_debug_logging(on, cats), vec![]),
            Op::RealStatus(kind) => {
                let (s, t) = h.get_real_status(kind);
                (s, vec![t.unwrap_or(-1.0)])
            }
            Op::Cancel => (h.cancel_step(), vec![]),
        });
    }
    (out, h.free_instance())
}

fn same(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

#[test]
fn the_harness_returns_and_logs_what_the_c_functions_do() {
    let ops = sequence();
    let records = Records::default();
    let c = through_c(&ops, &records);
    let (h, log) = through_harness(&ops);
    for (k, (op, (a, b))) in ops.iter().zip(c.iter().zip(&h)).enumerate() {
        assert!(
            a.0 == b.0 && same(&a.1, &b.1),
            "call {k} {op:?}: C {a:?}, harness {b:?}"
        );
    }
    let c_log = records.into_inner().unwrap();
    assert_eq!(c_log, log);
    // The sequence exercises every outcome, so the agreement says something.
    let statuses: Vec<Status> = c.iter().map(|o| o.0).collect();
    for s in [
        Status::Ok,
        Status::Warning,
        Status::Discard,
        Status::Error,
        Status::Fatal,
    ] {
        assert!(statuses.contains(&s), "{s:?} never returned: {statuses:?}");
    }
    let has = |status: Status, needle: &str| {
        log.iter()
            .any(|r| r.status == status && r.message.contains(needle))
    };
    assert!(has(Status::Warning, "x is 50%%"), "{log:#?}");
    assert!(has(Status::Error, "'gain' = 0"), "{log:#?}");
    assert!(has(Status::Error, "not finite"), "{log:#?}");
    assert!(has(Status::Ok, "initialized with y = 0.6"), "{log:#?}");
    assert!(
        has(
            Status::Fatal,
            "internal error contained: x = 5 is too large"
        ),
        "{log:#?}"
    );
    assert!(log.iter().all(|r| r.instance == "probe"));
}

/// Arguments of `fmi2Instantiate` (name, type, GUID, resource location) and the log line's text.
type Case<'a> = (&'a str, i32, Option<&'a str>, Option<&'a str>, &'a str);

#[test]
fn failed_instantiations_log_what_the_c_function_logs() {
    let res = Resources::new("fail", "");
    let good = format!("file://{}", res.0.display());
    let missing = format!("file://{}/nowhere", res.0.display());
    let cases: [Case; 5] = [
        (
            "",
            FMI2_COSIMULATION,
            Some("g"),
            Some(good.as_str()),
            "instanceName",
        ),
        ("p", 0, Some("g"), Some(good.as_str()), "Co-Simulation only"),
        ("p", FMI2_COSIMULATION, None, Some(good.as_str()), "fmuGUID"),
        (
            "p",
            FMI2_COSIMULATION,
            Some("g"),
            None,
            "fmuResourceLocation",
        ),
        (
            "p",
            FMI2_COSIMULATION,
            Some("g"),
            Some(missing.as_str()),
            "missing resource file",
        ),
    ];
    let guid = guid();
    let wrong_guid = [(
        "p",
        FMI2_COSIMULATION,
        Some("{0}"),
        Some(good.as_str()),
        "GUID mismatch",
    )];
    for (name, ty, g, loc, needle) in cases.iter().chain(&wrong_guid) {
        let log = match Harness::<Probe>::instantiate(name, *ty, *g, *loc, false) {
            Ok(_) => panic!("{needle}: instantiated"),
            Err(log) => log,
        };
        assert!(
            log.len() == 1 && log[0].status == Status::Error && log[0].message.contains(needle),
            "{needle}: {log:#?}"
        );
        let records = Records::default();
        let cb = callbacks(&records);
        let cstr = |s: &str| CString::new(s).unwrap();
        let (n, g, l) = (cstr(name), g.map(cstr), loc.map(cstr));
        let ptr = |s: &Option<CString>| s.as_ref().map_or(std::ptr::null(), |s| s.as_ptr());
        // SAFETY: C strings and callbacks alive across the call (NULL where the case says so).
        let c =
            unsafe { self::fmi2::fmi2Instantiate(n.as_ptr(), *ty, ptr(&g), ptr(&l), &cb, 0, 0) };
        assert!(c.is_null(), "{needle}");
        assert_eq!(records.into_inner().unwrap(), log, "{needle}");
    }
    // The right GUID through the same path succeeds.
    assert!(Harness::<Probe>::instantiate(
        "p",
        FMI2_COSIMULATION,
        Some(&guid),
        Some(good.as_str()),
        false
    )
    .is_ok());
}

#[test]
fn by_name_conveniences_and_configurations() {
    // Defaults without a resources directory.
    let mut h = Harness::<Probe>::new();
    assert_eq!(h.phase(), Phase::Instantiated);
    h.set("gain", 4.0);
    h.set("n", 3);
    assert_eq!(h.init(), Status::Ok);
    h.set("x", 0.25);
    h.step(0.1);
    h.step(0.1);
    assert_eq!(h.get("y"), 1.0);
    assert_eq!(h.get_many(["y", "count", "gain"]), [1.0, 6.0, 4.0]);
    assert_eq!(h.get_int("n"), 3);
    assert!((h.time() - 0.2).abs() < 1e-15);
    // Refusals by name, and the log as the master sees it.
    assert_eq!(h.try_set("n", 9), Status::Error);
    assert!(h.logged(Status::Error, "value 9 for 'n' is outside its range [1, 5]"));
    assert_eq!(h.phase(), Phase::Error);
    assert_eq!(h.get_int("n"), 3, "a refused value changes nothing");
    assert_eq!(h.take_log().len(), 1);
    assert!(h.log().is_empty());
    // A configuration's start values, from a resources directory and from its text.
    let res = Resources::new("start", "[start]\ngain = 5.0\n");
    let mut h = Harness::<Probe>::with_resources(&res.0);
    h.set("x", 0.5);
    h.init();
    assert_eq!(h.get("y"), 2.5);
    let mut h = Harness::<Probe>::from_toml("[start]\ngain = 6.0\n");
    h.init();
    h.set("x", 0.5);
    assert_eq!(h.do_step(0.0, 0.1), Status::Warning);
    assert_eq!(h.warnings(), ["x is 50%%"]);
    assert_eq!(h.get("y"), 3.0);
}
