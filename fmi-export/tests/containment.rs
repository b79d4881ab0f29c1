//! A model that panics and one that fails: the exported C functions contain both, log them
//! through the master's logger and return fmi2Fatal / fmi2Error; the host process lives on.

use fmi_export::ffi::{
    fmi2CallbackFunctions, fmi2ComponentEnvironment, fmi2Status, fmi2String, FMI2_COSIMULATION,
};
use fmi_export::{Config, Context, Model, ModelError, Real, Spec, Status, Store, Variables};
use serde::{Deserialize, Serialize};
use std::ffi::{CStr, CString};
use std::sync::Mutex;

#[derive(Clone, Serialize, Deserialize)]
struct Fragile {
    x: Real,
    y: Real,
}

impl Model for Fragile {
    type Config = ();
    type State = ();
    const IDENTIFIER: &'static str = "fragile";
    const NAME: &'static str = "fragile";
    const DESCRIPTION: &'static str = "panics when x > 1, fails when x < -1";
    const MAX_STEP: f64 = 1.0;

    fn declare(_: &(), _: Option<&std::path::Path>, v: &mut Variables) -> Result<Self, String> {
        Ok(Fragile {
            x: v.real(Spec::input("x", 0.0, "", "input")),
            y: v.real(Spec::output("y", "", "100% of x")),
        })
    }

    fn initialize(&self, _: Option<&()>, s: &mut Store, _: &mut Context) -> Result<(), ModelError> {
        s[self.y] = s[self.x];
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
        if s[self.x] > 1.0 {
            panic!("x = {} is too large", s[self.x]);
        }
        if s[self.x] < -1.0 {
            return Err("x below -1".into());
        }
        if s[self.x] == 0.5 {
            ctx.warn("x is 50%");
        }
        s[self.y] = s[self.x];
        Ok(())
    }
}

fmi_export::export_fmu!(Fragile);

static LOG: Mutex<Vec<(Status, String)>> = Mutex::new(Vec::new());

// Stable Rust cannot define a C-variadic function; our FMUs pass no variadic arguments, so a
// logger with only the fixed parameters receives them correctly (as the master's logger does).
unsafe extern "C" fn logger(
    _: fmi2ComponentEnvironment,
    _: fmi2String,
    status: fmi2Status,
    _: fmi2String,
    message: fmi2String,
) {
    LOG.lock().unwrap().push((
        Status::from_c(status),
        // SAFETY: the FMU passes a NUL-terminated message that lives for the call.
        unsafe { CStr::from_ptr(message) }
            .to_string_lossy()
            .into_owned(),
    ));
}

#[test]
fn panics_are_contained_and_errors_escalate() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("fragile-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("config.toml"), "").unwrap();
    let guid = fmi_export::describe::<Fragile>(&Config::default(), None)
        .unwrap()
        .guid;
    // SAFETY: the logger's C-variadic signature is called with no variadic arguments by these
    // FMUs, so the non-variadic function reads what it is given.
    let callbacks = unsafe {
        fmi2CallbackFunctions {
            logger: Some(std::mem::transmute::<
                unsafe extern "C" fn(
                    fmi2ComponentEnvironment,
                    fmi2String,
                    fmi2Status,
                    fmi2String,
                    fmi2String,
                ),
                fmi_export::ffi::fmi2CallbackLoggerTYPE,
            >(logger)),
            allocate_memory: None,
            free_memory: None,
            step_finished: None,
            component_environment: std::ptr::null_mut(),
        }
    };
    let (name, guid, res) = (
        CString::new("fragile").unwrap(),
        CString::new(guid).unwrap(),
        CString::new(dir.display().to_string()).unwrap(),
    );
    // SAFETY: FMI calls on an instance this block creates and frees, with C strings alive
    // across the calls.
    unsafe {
        use self::fmi2::*;
        let c = fmi2Instantiate(
            name.as_ptr(),
            FMI2_COSIMULATION,
            guid.as_ptr(),
            res.as_ptr(),
            &callbacks,
            0,
            0,
        );
        assert!(!c.is_null());
        assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), Status::Ok);
        assert_eq!(fmi2EnterInitializationMode(c), Status::Ok);
        assert_eq!(fmi2ExitInitializationMode(c), Status::Ok);
        let (x, y) = (0u32, 1u32);
        // A warning escalates the call's status but keeps the instance usable.
        assert_eq!(fmi2SetReal(c, &x, 1, &0.5), Status::Ok);
        assert_eq!(fmi2DoStep(c, 0.0, 0.1, 1), Status::Warning);
        // A model error: fmi2Error, error state, recoverable by reset.
        assert_eq!(fmi2SetReal(c, &x, 1, &-2.0), Status::Ok);
        assert_eq!(fmi2DoStep(c, 0.1, 0.1, 1), Status::Error);
        assert_eq!(fmi2DoStep(c, 0.1, 0.1, 1), Status::Error);
        assert_eq!(fmi2Reset(c), Status::Ok);
        assert_eq!(fmi2EnterInitializationMode(c), Status::Ok);
        assert_eq!(fmi2ExitInitializationMode(c), Status::Ok);
        // A panic: contained, logged, fmi2Fatal; afterwards only fmi2FreeInstance is legal.
        assert_eq!(fmi2SetReal(c, &x, 1, &5.0), Status::Ok);
        assert_eq!(fmi2DoStep(c, 0.0, 0.1, 1), Status::Fatal);
        let mut out = 0.0;
        assert_eq!(fmi2GetReal(c, &y, 1, &mut out), Status::Error);
        assert_eq!(fmi2Reset(c), Status::Error);
        fmi2FreeInstance(c);
    }
    let log = LOG.lock().unwrap().clone();
    let has =
        |status: Status, needle: &str| log.iter().any(|(s, m)| *s == status && m.contains(needle));
    assert!(
        has(Status::Warning, "x is 50%%"),
        "percent signs are escaped for printf-style masters: {log:?}"
    );
    assert!(has(Status::Error, "x below -1"), "{log:?}");
    assert!(
        has(
            Status::Fatal,
            "internal error contained: x = 5 is too large"
        ),
        "{log:?}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_hostile_sweep_reports_a_contained_panic() {
    use fmi_export::harness::Harness;
    let found = Harness::hostile_sweep(Harness::<Fragile>::new);
    // 1e12 (the end of its range) panics in the step, set before initialization and between
    // steps; -1e12 fails with the model's own error (legal at a range end), ±1e308 and the
    // non-finite values are refused by name at the setter.
    assert_eq!(found.len(), 2, "{found:#?}");
    assert!(
        found
            .iter()
            .all(|f| f.starts_with("'x' = 1e12") && f.contains("fmi2DoStep returned Fatal")),
        "{found:#?}"
    );
}
