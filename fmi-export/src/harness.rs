//! In-process test harness: drives a `Model` through the bodies of the exported `fmi2*` functions, without bundling or dlopen.
//!
//! Every call goes through the same [`api::guarded`] state mask, status escalation and panic
//! containment, and the same safe bodies ([`api::set_values`], [`api::get_values`],
//! [`api::apply_transition`], [`Instance::do_step`], ...) as the C functions that
//! [`crate::export_fmu!`] emits; only the decoding of C pointers is left out. Statuses are
//! returned as the C API returns them, and the log records are what the master's
//! `fmi2CallbackLogger` would receive (category, status, `%`-escaped text).
//!
//! ```text
//! let mut h = Harness::<MyModel>::new();
//! h.set("gain", 2.0);
//! h.init();
//! h.set("u", 1.0);
//! h.step(1e-3);
//! assert_eq!(h.get("y"), 2.0);
//! assert_eq!(h.try_set("u", f64::NAN), Status::Error);
//! assert!(h.logged(Status::Error, "'u'"));
//! ```
//!
//! Methods named after an FMI function (`set_real`, `do_step`, `exit_initialization_mode`, ...)
//! return its status; the by-name conveniences (`set`, `get`, `init`, `step`) panic, showing
//! the log, when the call does not succeed, and have `try_` forms where a failure is the point.

use crate::api;
use crate::describe::{describe, Config};
use crate::ffi::{fmi2StatusKind, fmi2Type, FMI2_COSIMULATION};
use crate::instance::{Call, Instance, Phase, Snapshot, NOT_FINITE};
use crate::log::{LogRecord, LogSink, Logger};
use crate::model::{Model, Value};
use crate::Status;
use model_description::BaseType;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::sync::{Arc, Mutex};

/// The instance name the harness instantiates with unless told otherwise.
pub const INSTANCE_NAME: &str = "harness";

/// The values [`Harness::hostile_sweep`] sets every Real parameter and input to (besides the
/// ends of its accepted range): what a campaign of hostile inputs tries first.
pub const HOSTILE_VALUES: [f64; 4] = [1e308, -1e308, f64::NAN, f64::INFINITY];

/// A saved FMU state (`fmi2FMUstate`); freeing it is dropping it.
pub type FmuState<M> = Snapshot<M>;

/// One model instance driven in-process, with the log its master would have received.
pub struct Harness<M: Model> {
    inst: Box<Instance<M>>,
    log: Arc<Mutex<Vec<LogRecord>>>,
}

impl<M: Model> Default for Harness<M> {
    fn default() -> Self {
        Self::new()
    }
}

fn new_log() -> Arc<Mutex<Vec<LogRecord>>> {
    Arc::new(Mutex::new(Vec::new()))
}

fn records(log: &Mutex<Vec<LogRecord>>) -> Vec<LogRecord> {
    log.lock().unwrap_or_else(|e| e.into_inner()).clone()
}

impl<M: Model> Harness<M> {
    /// An instance of the model's built-in defaults (no `resources/` directory, as when
    /// describing them), logging off; panics if it cannot be built.
    pub fn new() -> Self {
        Self::with_config(Config::default())
    }

    /// An instance for `config` (what `fmi2Instantiate` builds once it has read
    /// `resources/config.toml`; no `resources/` directory), logging off; panics if it cannot be
    /// built.
    pub fn with_config(config: Config<M::Config>) -> Self {
        Self::try_with_config(config, false)
            .unwrap_or_else(|log| panic!("{}: fmi2Instantiate failed: {log:#?}", M::IDENTIFIER))
    }

    /// An instance for the text of a `config.toml`; panics if it does not parse or the instance
    /// cannot be built.
    pub fn from_toml(text: &str) -> Self {
        let config = Config::from_toml(text).unwrap_or_else(|e| panic!("{e}"));
        Self::with_config(config)
    }

    /// An instance for `config` with the GUID it implies, or the log of the failed
    /// `fmi2Instantiate` (which would have returned NULL).
    pub fn try_with_config(
        config: Config<M::Config>,
        logging_on: bool,
    ) -> Result<Self, Vec<LogRecord>> {
        // A configuration the model cannot declare has no GUID; the instantiation then fails
        // on the declaration and logs why, as the C function does.
        let guid = describe::<M>(&config, None)
            .map(|d| d.guid)
            .unwrap_or_default();
        let log = new_log();
        let logger = Logger::with_sink(LogSink::Capture(log.clone()), INSTANCE_NAME, logging_on);
        match api::instantiate_config::<M>(INSTANCE_NAME, &guid, None, config, logger) {
            Some(inst) => Ok(Harness { inst, log }),
            None => Err(records(&log)),
        }
    }

    /// An instance of an FMU's `resources/` directory `dir` through the whole of
    /// `fmi2Instantiate` (resource location decoding, `config.toml` reading), with the GUID
    /// that directory's configuration implies; panics if it cannot be built.
    pub fn with_resources(dir: &Path) -> Self {
        let guid = Config::<M::Config>::load(dir)
            .and_then(|c| describe::<M>(&c, Some(dir)))
            .map(|d| d.guid)
            .unwrap_or_default();
        let location = format!("file://{}", dir.display());
        Self::instantiate(
            INSTANCE_NAME,
            FMI2_COSIMULATION,
            Some(&guid),
            Some(&location),
            false,
        )
        .unwrap_or_else(|log| panic!("{}: fmi2Instantiate failed: {log:#?}", M::IDENTIFIER))
    }

    /// `fmi2Instantiate` with these arguments (`None`: a NULL string): the instance, or the log
    /// of the failure (the C function returns NULL).
    pub fn instantiate(
        name: &str,
        fmu_type: fmi2Type,
        guid: Option<&str>,
        resource_location: Option<&str>,
        logging_on: bool,
    ) -> Result<Self, Vec<LogRecord>> {
        let log = new_log();
        let sink = LogSink::Capture(log.clone());
        match api::instantiate_from::<M>(name, fmu_type, guid, resource_location, sink, logging_on)
        {
            Some(inst) => Ok(Harness { inst, log }),
            None => Err(records(&log)),
        }
    }

    /// `fmi2FreeInstance`; returns the whole log.
    pub fn free_instance(self) -> Vec<LogRecord> {
        let Harness { inst, log } = self;
        let _ = catch_unwind(AssertUnwindSafe(move || drop(inst)));
        records(&log)
    }

    fn call(&mut self, call: Call, f: impl FnOnce(&mut Instance<M>) -> Status) -> Status {
        api::guarded(&mut self.inst, call, f)
    }

    // --- The FMI functions -----------------------------------------------------------------

    /// `fmi2SetDebugLogging`.
    pub fn set_debug_logging(&mut self, on: bool, categories: &[&str]) -> Status {
        let names: Vec<String> = categories.iter().map(|c| c.to_string()).collect();
        self.call(Call::SetDebugLogging, |i| api::debug_logging(i, on, &names))
    }

    /// `fmi2SetupExperiment` (the tolerance is not used by the layer).
    pub fn setup_experiment(&mut self, start: f64, stop: Option<f64>) -> Status {
        self.call(Call::SetupExperiment, |i| i.setup_experiment(start, stop))
    }

    /// `fmi2EnterInitializationMode`.
    pub fn enter_initialization_mode(&mut self) -> Status {
        self.transition(Call::EnterInitializationMode)
    }

    /// `fmi2ExitInitializationMode`.
    pub fn exit_initialization_mode(&mut self) -> Status {
        self.transition(Call::ExitInitializationMode)
    }

    /// `fmi2Terminate`.
    pub fn terminate(&mut self) -> Status {
        self.transition(Call::Terminate)
    }

    /// `fmi2Reset`.
    pub fn reset(&mut self) -> Status {
        self.transition(Call::Reset)
    }

    fn transition(&mut self, call: Call) -> Status {
        self.call(call, |i| api::apply_transition(i, call))
    }

    fn set_typed(&mut self, t: BaseType, vrs: &[u32], value: impl Fn(usize) -> Value) -> Status {
        self.call(Call::Set(t), |i| {
            api::set_values(i, t, vrs, |k| Some(value(k)))
        })
    }

    /// `fmi2SetReal`.
    pub fn set_real(&mut self, vrs: &[u32], values: &[f64]) -> Status {
        assert_eq!(vrs.len(), values.len(), "one value per reference");
        self.set_typed(BaseType::Real, vrs, |k| Value::Real(values[k]))
    }

    /// `fmi2SetInteger`.
    pub fn set_integer(&mut self, vrs: &[u32], values: &[i32]) -> Status {
        assert_eq!(vrs.len(), values.len(), "one value per reference");
        self.set_typed(BaseType::Integer, vrs, |k| Value::Integer(values[k]))
    }

    /// `fmi2SetBoolean`.
    pub fn set_boolean(&mut self, vrs: &[u32], values: &[bool]) -> Status {
        assert_eq!(vrs.len(), values.len(), "one value per reference");
        self.set_typed(BaseType::Boolean, vrs, |k| Value::Boolean(values[k]))
    }

    /// `fmi2SetString`.
    pub fn set_string(&mut self, vrs: &[u32], values: &[&str]) -> Status {
        assert_eq!(vrs.len(), values.len(), "one value per reference");
        self.set_typed(BaseType::String, vrs, |k| Value::from(values[k]))
    }

    fn get_typed<V>(
        &mut self,
        t: BaseType,
        vrs: &[u32],
        out: &mut [V],
        read: impl Fn(&mut Instance<M>, u32) -> V,
    ) -> Status {
        assert_eq!(vrs.len(), out.len(), "room for one value per reference");
        self.call(Call::Get(t), |i| {
            api::get_values(i, t, vrs, |i, k, vr| out[k] = read(i, vr))
        })
    }

    /// `fmi2GetReal`.
    pub fn get_real(&mut self, vrs: &[u32], out: &mut [f64]) -> Status {
        self.get_typed(BaseType::Real, vrs, out, api::read_real)
    }

    /// `fmi2GetInteger`.
    pub fn get_integer(&mut self, vrs: &[u32], out: &mut [i32]) -> Status {
        self.get_typed(BaseType::Integer, vrs, out, api::read_integer)
    }

    /// `fmi2GetBoolean`.
    pub fn get_boolean(&mut self, vrs: &[u32], out: &mut [bool]) -> Status {
        self.get_typed(BaseType::Boolean, vrs, out, |i, vr| {
            api::read_boolean(i, vr) != 0
        })
    }

    /// `fmi2GetString` (as the C function hands it out: escaped like a log message).
    pub fn get_string(&mut self, vrs: &[u32], out: &mut [String]) -> Status {
        self.get_typed(BaseType::String, vrs, out, |i, vr| {
            api::read_string(i, vr).to_string_lossy().into_owned()
        })
    }

    /// `fmi2DoStep` from `t` over `h`.
    pub fn do_step(&mut self, t: f64, h: f64) -> Status {
        self.call(Call::DoStep, |i| i.do_step(t, h))
    }

    /// `fmi2GetFMUstate`: a new state.
    pub fn get_fmu_state(&mut self) -> Result<FmuState<M>, Status> {
        let mut state = None;
        let status = self.call(Call::FmuState, |i| {
            state = Some(Snapshot {
                tag: i.tag,
                core: i.core.clone(),
            });
            Status::Ok
        });
        state.filter(|_| status < Status::Error).ok_or(status)
    }

    /// `fmi2SetFMUstate`.
    pub fn set_fmu_state(&mut self, state: &FmuState<M>) -> Status {
        self.call(Call::FmuState, |i| {
            i.core = state.core.clone();
            Status::Ok
        })
    }

    /// `fmi2SerializedFMUstateSize` and `fmi2SerializeFMUstate`: the bytes.
    pub fn serialize_fmu_state(&mut self, state: &FmuState<M>) -> Result<Vec<u8>, Status> {
        let mut bytes = None;
        let status = self.call(Call::FmuState, |i| match i.serialize(&state.core) {
            Ok(b) => {
                bytes = Some(b);
                Status::Ok
            }
            Err(e) => i.error(e),
        });
        bytes.filter(|_| status < Status::Error).ok_or(status)
    }

    /// `fmi2DeSerializeFMUstate`: a new state from bytes of this or another instance.
    pub fn deserialize_fmu_state(&mut self, bytes: &[u8]) -> Result<FmuState<M>, Status> {
        let mut state = None;
        let status = self.call(Call::FmuState, |i| match api::deserialize_core(i, bytes) {
            Ok(core) => {
                state = Some(Snapshot { tag: i.tag, core });
                Status::Ok
            }
            Err(status) => status,
        });
        state.filter(|_| status < Status::Error).ok_or(status)
    }

    /// `fmi2GetStatus`.
    pub fn get_status(&mut self, kind: fmi2StatusKind) -> (Status, Option<Status>) {
        let (status, v) = self.status_of(kind, api::read_do_step_status);
        (status, v.map(Status::from_c))
    }

    /// `fmi2GetRealStatus`.
    pub fn get_real_status(&mut self, kind: fmi2StatusKind) -> (Status, Option<f64>) {
        self.status_of(kind, api::read_real_status)
    }

    /// `fmi2GetBooleanStatus`.
    pub fn get_boolean_status(&mut self, kind: fmi2StatusKind) -> (Status, Option<bool>) {
        let (status, v) = self.status_of(kind, api::read_boolean_status);
        (status, v.map(|b| b != 0))
    }

    fn status_of<V>(
        &mut self,
        kind: fmi2StatusKind,
        read: impl Fn(&Instance<M>, fmi2StatusKind) -> Option<V>,
    ) -> (Status, Option<V>) {
        let mut out = None;
        let status = self.call(Call::GetStatus, |i| {
            api::status_value(i, kind, read, |v| out = Some(v))
        });
        (status, out)
    }

    /// `fmi2CancelStep` (not supported: always refused).
    pub fn cancel_step(&mut self) -> Status {
        self.call(Call::CancelStep, |i| {
            api::unsupported_body(i, Call::CancelStep)
        })
    }

    // --- By name ---------------------------------------------------------------------------

    /// Base type and value reference of `name`; panics if the model declares no such variable.
    pub fn vr(&self, name: &str) -> (BaseType, u32) {
        self.inst
            .variable(name)
            .unwrap_or_else(|| panic!("{} declares no variable '{name}'", M::IDENTIFIER))
    }

    /// `fmi2Set*` of one variable by name, with the setter of its declared type (an integer
    /// value is accepted for a Real); returns the status.
    pub fn try_set(&mut self, name: &str, value: impl Into<Value>) -> Status {
        let (t, vr) = self.vr(name);
        let value = match (t, value.into()) {
            (BaseType::Real, Value::Integer(i)) => Value::Real(i.into()),
            (t, v) if v.base_type() == t => v,
            (t, v) => panic!("'{name}' is {t}, the value {v:?} is not"),
        };
        self.set_typed(t, &[vr], |_| value.clone())
    }

    /// Set one variable by name; panics (showing the log) unless the call returns `fmi2OK`.
    pub fn set(&mut self, name: &str, value: impl Into<Value>) {
        let status = self.try_set(name, value);
        if status != Status::Ok {
            panic!("setting '{name}' returned {status:?}: {:#?}", self.log());
        }
    }

    /// Set several variables by name, one call each; panics unless every call returns `fmi2OK`.
    pub fn set_all<V: Into<Value> + Copy>(&mut self, values: &[(&str, V)]) {
        for &(name, v) in values {
            self.set(name, v);
        }
    }

    /// `fmi2Get*` of one variable by name: its value, or the status of a failed call.
    pub fn try_get(&mut self, name: &str) -> Result<Value, Status> {
        let (t, vr) = self.vr(name);
        let vrs = [vr];
        let (status, value) = match t {
            BaseType::Real => {
                let mut out = [0.0];
                (self.get_real(&vrs, &mut out), Value::Real(out[0]))
            }
            BaseType::Integer => {
                let mut out = [0];
                (self.get_integer(&vrs, &mut out), Value::Integer(out[0]))
            }
            BaseType::Boolean => {
                let mut out = [false];
                (self.get_boolean(&vrs, &mut out), Value::Boolean(out[0]))
            }
            BaseType::String => {
                let mut out = [String::new()];
                let status = self.get_string(&vrs, &mut out);
                let [s] = out;
                (status, Value::String(s))
            }
        };
        if status < Status::Error {
            Ok(value)
        } else {
            Err(status)
        }
    }

    fn get_value(&mut self, name: &str) -> Value {
        self.try_get(name).unwrap_or_else(|status| {
            panic!("getting '{name}' returned {status:?}: {:#?}", self.log())
        })
    }

    /// A Real variable by name; panics if the call fails or the variable is not Real.
    pub fn get(&mut self, name: &str) -> f64 {
        match self.get_value(name) {
            Value::Real(x) => x,
            v => panic!("'{name}' is not Real: {v:?}"),
        }
    }

    /// Several Real variables by name, in one `fmi2GetReal` call.
    pub fn get_many<const N: usize>(&mut self, names: [&str; N]) -> [f64; N] {
        let vrs = names.map(|n| match self.vr(n) {
            (BaseType::Real, vr) => vr,
            (t, _) => panic!("'{n}' is {t}, not Real"),
        });
        let mut out = [0.0; N];
        let status = self.get_real(&vrs, &mut out);
        if status >= Status::Error {
            panic!("getting {names:?} returned {status:?}: {:#?}", self.log());
        }
        out
    }

    /// An Integer variable by name.
    pub fn get_int(&mut self, name: &str) -> i32 {
        match self.get_value(name) {
            Value::Integer(x) => x,
            v => panic!("'{name}' is not Integer: {v:?}"),
        }
    }

    /// A Boolean variable by name.
    pub fn get_bool(&mut self, name: &str) -> bool {
        match self.get_value(name) {
            Value::Boolean(x) => x,
            v => panic!("'{name}' is not Boolean: {v:?}"),
        }
    }

    /// A String variable by name.
    pub fn get_str(&mut self, name: &str) -> String {
        match self.get_value(name) {
            Value::String(x) => x,
            v => panic!("'{name}' is not String: {v:?}"),
        }
    }

    // --- Sequences -------------------------------------------------------------------------

    /// `fmi2SetupExperiment` at the configured start time (no stop time),
    /// `fmi2EnterInitializationMode`, `fmi2ExitInitializationMode`: the worst status; panics
    /// (showing the log) if one of them fails.
    pub fn init(&mut self) -> Status {
        let start = self.inst.config().experiment.start;
        let mut worst = Status::Ok;
        for (what, status) in [
            ("fmi2SetupExperiment", self.setup_experiment(start, None)),
            (
                "fmi2EnterInitializationMode",
                self.enter_initialization_mode(),
            ),
            (
                "fmi2ExitInitializationMode",
                self.exit_initialization_mode(),
            ),
        ] {
            if status >= Status::Error {
                panic!("{what} returned {status:?}: {:#?}", self.log());
            }
            worst = worst.max(status);
        }
        worst
    }

    /// `fmi2DoStep` from the FMU's time over `h`; panics (showing the log) unless it returns
    /// `fmi2OK`.
    pub fn step(&mut self, h: f64) {
        let t = self.time();
        let status = self.do_step(t, h);
        if status != Status::Ok {
            panic!(
                "fmi2DoStep({t}, {h}) returned {status:?}: {:#?}",
                self.log()
            );
        }
    }

    // --- Hostile inputs ----------------------------------------------------------------------

    /// Every Real parameter and input of the instances `make` builds, set to each of
    /// [`HOSTILE_VALUES`] and to both ends of its accepted range: once before initialization
    /// (then initialized and stepped once over the default experiment's step), and, for inputs
    /// and tunable parameters, once between steps (then stepped once). Each call must either
    /// succeed (the step with finite values everywhere, which the layer checks) or return
    /// `fmi2Error` with a message that names the variable; never `fmi2Fatal` (a contained
    /// panic) or an error that names something else. At the ends of its range (legal values)
    /// the model may also fail naming what failed, but no value may go non-finite. Returns the
    /// violations, one line each.
    pub fn hostile_sweep(make: impl Fn() -> Self) -> Vec<String> {
        let probe = make();
        let step = probe.inst.config().experiment.step;
        let mut found = Vec::new();
        for (name, vr, later, (lo, hi)) in probe.inst.settable_reals() {
            let mut values = HOSTILE_VALUES.to_vec();
            values.extend([lo, hi]);
            for x in values {
                for between_steps in [false, true] {
                    if between_steps && !later {
                        continue;
                    }
                    let mut h = make();
                    if let Err(e) = h.hostile_run(&name, vr, x, between_steps, step) {
                        let when = if between_steps {
                            "between steps"
                        } else {
                            "before init"
                        };
                        found.push(format!("'{name}' = {x:e} ({when}): {e}"));
                    }
                }
            }
        }
        found
    }

    /// One run of [`Self::hostile_sweep`]: `Err` says what went wrong.
    fn hostile_run(
        &mut self,
        name: &str,
        vr: u32,
        x: f64,
        between_steps: bool,
        step: f64,
    ) -> Result<(), String> {
        let start = self.inst.config().experiment.start;
        let calls = if between_steps {
            ["setup", "enter", "exit", "set", "step"]
        } else {
            ["set", "setup", "enter", "exit", "step"]
        };
        for call in calls {
            let (call, status) = match call {
                "set" => ("fmi2SetReal", self.set_real(&[vr], &[x])),
                "setup" => ("fmi2SetupExperiment", self.setup_experiment(start, None)),
                "enter" => (
                    "fmi2EnterInitializationMode",
                    self.enter_initialization_mode(),
                ),
                "exit" => (
                    "fmi2ExitInitializationMode",
                    self.exit_initialization_mode(),
                ),
                _ => ("fmi2DoStep", self.do_step(self.time(), step)),
            };
            if status < Status::Error {
                continue;
            }
            let last = self
                .log()
                .into_iter()
                .rev()
                .find(|r| r.status >= Status::Error)
                .map(|r| r.message)
                .unwrap_or_default();
            // At an end of its range a value is legal, and the model may fail on what it does
            // (a machine losing synchronism names the machine); only a value gone non-finite
            // is a violation there.
            let legal = !HOSTILE_VALUES.iter().any(|v| v.to_bits() == x.to_bits());
            return match status {
                Status::Error if last.contains(name) => Ok(()),
                Status::Error if legal && !last.contains(NOT_FINITE) => Ok(()),
                _ => Err(format!("{call} returned {status:?}: {last}")),
            };
        }
        Ok(())
    }

    // --- Inspection (no FMI call) ----------------------------------------------------------

    /// The FMU's time: the last communication point reached.
    pub fn time(&self) -> f64 {
        self.inst.core.time
    }

    /// Where the instance is in the FMI 2.0 Co-Simulation state machine.
    pub fn phase(&self) -> Phase {
        self.inst.core.phase
    }

    /// The instance itself (configuration, store, model state).
    pub fn instance(&self) -> &Instance<M> {
        &self.inst
    }

    /// Every record logged so far.
    pub fn log(&self) -> Vec<LogRecord> {
        records(&self.log)
    }

    /// Every record logged so far; the log starts empty again.
    pub fn take_log(&mut self) -> Vec<LogRecord> {
        std::mem::take(&mut *self.log.lock().unwrap_or_else(|e| e.into_inner()))
    }

    /// Whether a record with `status` contains `needle` (as the master received it: `%%`).
    pub fn logged(&self, status: Status, needle: &str) -> bool {
        self.log()
            .iter()
            .any(|r| r.status == status && r.message.contains(needle))
    }

    /// The messages logged with `fmi2Warning`.
    pub fn warnings(&self) -> Vec<String> {
        self.log()
            .into_iter()
            .filter(|r| r.status == Status::Warning)
            .map(|r| r.message)
            .collect()
    }
}
