//! The bodies of the FMI 2.0 C functions, generic over the model: pointer checks, state masks,
//! status escalation into the Error/Fatal states, and panic containment.
//!
//! Each `unsafe` function here decodes the C arguments and runs a safe body inside [`guarded`];
//! [`crate::harness`] runs the same safe bodies inside the same [`guarded`] without pointers.

use crate::describe::Config;
use crate::ffi::*;
use crate::instance::{model_tag, Call, Core, Instance, Phase, Snapshot};
use crate::log::{LogSink, Logger};
use crate::model::{Model, Value};
use crate::Status;
use model_description::BaseType;
use std::ffi::CStr;
use std::os::raw::c_char;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;

pub use crate::uri::resource_path;

fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

/// Run `f` on the instance behind `c` if `call` is legal in its state; contain panics.
///
/// # Safety
/// `c` must be null or a pointer returned by [`instantiate`] for the same model and not freed.
unsafe fn with_instance<M: Model>(
    c: fmi2Component,
    call: Call,
    f: impl FnOnce(&mut Instance<M>) -> Status,
) -> Status {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        if c.is_null() {
            return Status::Error;
        }
        let inst = &mut *(c as *mut Instance<M>);
        if inst.tag != model_tag::<M>() {
            return Status::Error;
        }
        guarded(inst, call, f)
    }
}

/// Run `f` on `inst` if `call` is legal in its state: the state mask, the escalation of
/// `fmi2Error`/`fmi2Fatal` into the Error/Fatal states, and panic containment (logged, `fmi2Fatal`)
/// that every function taking an instance goes through.
pub fn guarded<M: Model>(
    inst: &mut Instance<M>,
    call: Call,
    f: impl FnOnce(&mut Instance<M>) -> Status,
) -> Status {
    let phase = inst.core.phase;
    if !call.allowed_in(phase) {
        let status = inst.error(format!(
            "{}: illegal call sequence in state {phase:?}",
            call.name()
        ));
        if phase != Phase::Fatal {
            inst.core.phase = Phase::Error;
        }
        return status;
    }
    match catch_unwind(AssertUnwindSafe(|| f(&mut *inst))) {
        Ok(status) => {
            match status {
                Status::Error => inst.core.phase = Phase::Error,
                Status::Fatal => inst.core.phase = Phase::Fatal,
                _ => {}
            }
            status
        }
        Err(payload) => {
            inst.core.phase = Phase::Fatal;
            let mut text = panic_text(payload.as_ref());
            // Which parameters the model ran with: the likely cause, named for the user.
            if matches!(
                call,
                Call::EnterInitializationMode | Call::ExitInitializationMode | Call::DoStep
            ) {
                let changed = catch_unwind(AssertUnwindSafe(|| inst.changed_parameters(6)))
                    .unwrap_or_default();
                if !changed.is_empty() {
                    text.push_str(&format!(
                        " (parameters set away from their start values: {})",
                        changed.join(", ")
                    ));
                }
            }
            // The logger itself must not unwind into the host either.
            let _ = catch_unwind(AssertUnwindSafe(|| {
                inst.logger.log(
                    Status::Fatal,
                    &format!("{}: internal error contained: {text}", call.name()),
                )
            }));
            Status::Fatal
        }
    }
}

unsafe fn c_str<'a>(p: *const c_char) -> Option<&'a str> {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        if p.is_null() {
            None
        } else {
            CStr::from_ptr(p).to_str().ok()
        }
    }
}

/// `fmi2Instantiate`: NULL (with a log line, when a logger exists) on any problem.
///
/// # Safety
/// Pointer arguments as the FMI 2.0 standard specifies them.
pub unsafe fn instantiate<M: Model>(
    instance_name: fmi2String,
    fmu_type: fmi2Type,
    guid: fmi2String,
    resource_location: fmi2String,
    functions: *const fmi2CallbackFunctions,
    _visible: fmi2Boolean,
    logging_on: fmi2Boolean,
) -> fmi2Component {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        let Some(functions) = functions.as_ref() else {
            return std::ptr::null_mut();
        };
        if functions.logger.is_none() {
            return std::ptr::null_mut();
        }
        let sink = LogSink::Callback {
            callback: functions.logger,
            environment: functions.component_environment,
        };
        let instance = instantiate_from::<M>(
            c_str(instance_name).unwrap_or(""),
            fmu_type,
            c_str(guid),
            c_str(resource_location),
            sink,
            logging_on != 0,
        );
        match instance {
            Some(inst) => Box::into_raw(inst) as fmi2Component,
            None => std::ptr::null_mut(),
        }
    }
}

/// The body of `fmi2Instantiate` once its strings are decoded (`None`: NULL or not UTF-8): checks
/// the arguments, reads `resources/config.toml` from the resource location and builds the
/// instance; `None` (with a log line to `sink`) on any problem, panics included.
pub fn instantiate_from<M: Model>(
    name: &str,
    fmu_type: fmi2Type,
    guid: Option<&str>,
    resource_location: Option<&str>,
    sink: LogSink,
    logging_on: bool,
) -> Option<Box<Instance<M>>> {
    let result = catch_unwind(AssertUnwindSafe(|| {
        let logger = Logger::with_sink(sink.clone(), name, logging_on);
        let fail = |m: String| {
            logger.log(Status::Error, &format!("fmi2Instantiate: {m}"));
        };
        if name.is_empty() {
            fail("instanceName must be a non-empty string".into());
            return None;
        }
        if fmu_type != FMI2_COSIMULATION {
            fail(format!(
                "{} supports Co-Simulation only (fmuType = {fmu_type})",
                M::IDENTIFIER
            ));
            return None;
        }
        let Some(guid) = guid else {
            fail("fmuGUID is missing".into());
            return None;
        };
        let resources = match resource_location.map(resource_path) {
            None => {
                fail("fmuResourceLocation is missing; this FMU reads resources/config.toml".into());
                return None;
            }
            Some(Err(e)) => {
                fail(e);
                return None;
            }
            Some(Ok(p)) => p,
        };
        let config = match Config::<M::Config>::load(&resources) {
            Ok(c) => c,
            Err(e) => {
                fail(e);
                return None;
            }
        };
        instantiate_config(name, guid, Some(resources), config, logger)
    }));
    result.ok().flatten()
}

/// The last part of `fmi2Instantiate`: the instance for a configuration already read; `None`
/// (with a log line through a logger to the same sink, all categories on) when it cannot be
/// built, e.g. on a GUID mismatch.
pub fn instantiate_config<M: Model>(
    name: &str,
    guid: &str,
    resources: Option<PathBuf>,
    config: Config<M::Config>,
    logger: Logger,
) -> Option<Box<Instance<M>>> {
    let sink = logger.sink().clone();
    let result = catch_unwind(AssertUnwindSafe(|| {
        match Instance::<M>::new(name, guid, resources, config, logger) {
            Ok(inst) => Some(Box::new(inst)),
            Err(e) => {
                // The logger moved into the failed constructor; report through a fresh one.
                Logger::with_sink(sink.clone(), name, true)
                    .log(Status::Error, &format!("fmi2Instantiate: {e}"));
                None
            }
        }
    }));
    result.ok().flatten()
}

/// `fmi2FreeInstance`.
///
/// # Safety
/// `c` as returned by [`instantiate`]; not used afterwards.
pub unsafe fn free_instance<M: Model>(c: fmi2Component) {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        if c.is_null() || (*(c as *mut Instance<M>)).tag != model_tag::<M>() {
            return;
        }
        let _ = catch_unwind(AssertUnwindSafe(|| {
            let mut inst = Box::from_raw(c as *mut Instance<M>);
            inst.tag = 0;
            drop(inst);
        }));
    }
}

/// `fmi2SetDebugLogging`.
///
/// # Safety
/// FMI 2.0 pointer rules.
pub unsafe fn set_debug_logging<M: Model>(
    c: fmi2Component,
    on: fmi2Boolean,
    n: usize,
    categories: *const fmi2String,
) -> Status {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        with_instance::<M>(c, Call::SetDebugLogging, |inst| {
            if n > 0 && categories.is_null() {
                return inst.error("fmi2SetDebugLogging: categories is NULL");
            }
            let names: Option<Vec<String>> = (0..n)
                .map(|i| c_str(*categories.add(i)).map(str::to_owned))
                .collect();
            let Some(names) = names else {
                return inst.error("fmi2SetDebugLogging: a category name is NULL or not UTF-8");
            };
            debug_logging(inst, on != 0, &names)
        })
    }
}

/// The body of `fmi2SetDebugLogging` once its category names are decoded.
pub fn debug_logging<M: Model>(inst: &mut Instance<M>, on: bool, categories: &[String]) -> Status {
    match inst.logger.set_debug_logging(on, categories) {
        Ok(()) => Status::Ok,
        Err(e) => inst.error(format!("fmi2SetDebugLogging: {e}")),
    }
}

/// `fmi2SetupExperiment`.
///
/// # Safety
/// FMI 2.0 pointer rules.
pub unsafe fn setup_experiment<M: Model>(
    c: fmi2Component,
    _tolerance_defined: fmi2Boolean,
    _tolerance: f64,
    start: f64,
    stop_defined: fmi2Boolean,
    stop: f64,
) -> Status {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        with_instance::<M>(c, Call::SetupExperiment, |inst| {
            inst.setup_experiment(start, (stop_defined != 0).then_some(stop))
        })
    }
}

/// `fmi2EnterInitializationMode`, `fmi2ExitInitializationMode`, `fmi2Terminate`, `fmi2Reset`.
///
/// # Safety
/// FMI 2.0 pointer rules.
pub unsafe fn transition<M: Model>(c: fmi2Component, call: Call) -> Status {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe { with_instance::<M>(c, call, |inst| apply_transition(inst, call)) }
}

/// The body of the four state transitions.
///
/// # Panics
/// When `call` is not one of them.
pub fn apply_transition<M: Model>(inst: &mut Instance<M>, call: Call) -> Status {
    match call {
        Call::EnterInitializationMode => inst.enter_initialization_mode(),
        Call::ExitInitializationMode => inst.exit_initialization_mode(),
        Call::Terminate => inst.terminate(),
        Call::Reset => inst.reset(),
        _ => unreachable!("not a transition"),
    }
}

unsafe fn slices<'a, V>(
    vr: *const u32,
    nvr: usize,
    values: *const V,
) -> Option<(&'a [u32], *const V)> {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        if nvr == 0 {
            return Some((&[], values));
        }
        if vr.is_null() || values.is_null() {
            return None;
        }
        Some((std::slice::from_raw_parts(vr, nvr), values))
    }
}

/// `fmi2Get{Real,Integer,Boolean,String}`: `read` copies value `vr` to position `i`.
///
/// # Safety
/// FMI 2.0 pointer rules; `out` has room for `nvr` values.
pub unsafe fn get<M: Model, V>(
    c: fmi2Component,
    t: BaseType,
    vr: *const u32,
    nvr: usize,
    out: *mut V,
    read: impl Fn(&mut Instance<M>, u32) -> V,
) -> Status {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        with_instance::<M>(c, Call::Get(t), |inst| {
            let Some((vrs, _)) = slices(vr, nvr, out as *const V) else {
                return inst.error(format!("fmi2Get{t}: NULL array"));
            };
            get_values(inst, t, vrs, |inst, i, r| out.add(i).write(read(inst, r)))
        })
    }
}

/// The body of `fmi2Get{t}`: `write(inst, i, vr)` delivers value `vr` at position `i`; nothing
/// is delivered unless every reference exists and the outputs are current.
pub fn get_values<M: Model>(
    inst: &mut Instance<M>,
    t: BaseType,
    vrs: &[u32],
    mut write: impl FnMut(&mut Instance<M>, usize, u32),
) -> Status {
    if let Err(e) = inst.check_refs(t, vrs) {
        return inst.error(format!("fmi2Get{t}: {e}"));
    }
    let status = inst.before_get();
    if status >= Status::Error {
        return status;
    }
    inst.string_buffer.clear();
    for (i, &r) in vrs.iter().enumerate() {
        write(inst, i, r);
    }
    status
}

/// The value `fmi2GetReal` reads.
pub fn read_real<M: Model>(inst: &mut Instance<M>, vr: u32) -> f64 {
    inst.core.store.reals[vr as usize]
}

/// The value `fmi2GetInteger` reads.
pub fn read_integer<M: Model>(inst: &mut Instance<M>, vr: u32) -> fmi2Integer {
    inst.core.store.integers[vr as usize]
}

/// The value `fmi2GetBoolean` reads.
pub fn read_boolean<M: Model>(inst: &mut Instance<M>, vr: u32) -> fmi2Boolean {
    inst.core.store.booleans[vr as usize] as fmi2Boolean
}

/// `fmi2Set{Real,Integer,Boolean,String}`: `convert` reads value `i`; all-or-nothing.
///
/// # Safety
/// FMI 2.0 pointer rules; `values` holds `nvr` values.
pub unsafe fn set<M: Model, V: Copy>(
    c: fmi2Component,
    t: BaseType,
    vr: *const u32,
    nvr: usize,
    values: *const V,
    convert: impl Fn(V) -> Option<Value>,
) -> Status {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        with_instance::<M>(c, Call::Set(t), |inst| {
            let Some((vrs, values)) = slices(vr, nvr, values) else {
                return inst.error(format!("fmi2Set{t}: NULL array"));
            };
            set_values(inst, t, vrs, |i| convert(*values.add(i)))
        })
    }
}

/// The body of `fmi2Set{t}`: `value(i)` is the value for `vrs[i]` (`None`: NULL or not UTF-8);
/// all-or-nothing.
pub fn set_values<M: Model>(
    inst: &mut Instance<M>,
    t: BaseType,
    vrs: &[u32],
    value: impl Fn(usize) -> Option<Value>,
) -> Status {
    let mut converted = std::mem::take(&mut inst.set_buffer);
    converted.clear();
    for i in 0..vrs.len() {
        match value(i) {
            Some(v) => converted.push(v),
            None => {
                inst.set_buffer = converted;
                return inst.error(format!("fmi2Set{t}: a value is NULL or not UTF-8"));
            }
        }
    }
    let status = match inst.check_set(t, vrs, &converted) {
        Ok(()) => {
            inst.apply_set(vrs, &mut converted);
            Status::Ok
        }
        Err(e) => inst.error(format!("fmi2Set{t}: {e}")),
    };
    converted.clear();
    inst.set_buffer = converted;
    status
}

/// The string `fmi2GetString` hands out for `vr` (escaped like a log message).
pub fn read_string<M: Model>(inst: &Instance<M>, vr: u32) -> std::ffi::CString {
    crate::log::c_message(&inst.core.store.strings[vr as usize])
}

/// Read a string for `fmi2GetString`; the pointer lives until the next get call.
pub fn string_out<M: Model>(inst: &mut Instance<M>, vr: u32) -> fmi2String {
    let s = read_string(inst, vr);
    let p = s.as_ptr();
    inst.string_buffer.push(s);
    p
}

/// Convert an `fmi2SetString` argument.
///
/// # Safety
/// `p` is NULL or a NUL-terminated string.
pub unsafe fn string_in(p: fmi2String) -> Option<Value> {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe { c_str(p).map(|s| Value::String(s.to_owned())) }
}

/// `fmi2DoStep`.
///
/// # Safety
/// FMI 2.0 pointer rules.
pub unsafe fn do_step<M: Model>(c: fmi2Component, t: f64, h: f64) -> Status {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe { with_instance::<M>(c, Call::DoStep, |inst| inst.do_step(t, h)) }
}

/// `fmi2GetFMUstate`: a new snapshot, or an overwrite of the one `state` points to.
///
/// # Safety
/// FMI 2.0 pointer rules.
pub unsafe fn get_fmu_state<M: Model>(c: fmi2Component, state: *mut fmi2FMUstate) -> Status {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        with_instance::<M>(c, Call::FmuState, |inst| {
            if state.is_null() {
                return inst.error("fmi2GetFMUstate: FMUstate is NULL");
            }
            let core = inst.core.clone();
            match (*state as *mut Snapshot<M>).as_mut() {
                Some(snap) if snap.tag == inst.tag => snap.core = core,
                Some(_) => {
                    return inst.error("fmi2GetFMUstate: *FMUstate is not a state of this FMU")
                }
                None => {
                    *state = Box::into_raw(Box::new(Snapshot::<M> {
                        tag: inst.tag,
                        core,
                    })) as fmi2FMUstate
                }
            }
            Status::Ok
        })
    }
}

unsafe fn snapshot<'a, M: Model>(
    inst: &Instance<M>,
    state: fmi2FMUstate,
) -> Result<&'a Snapshot<M>, Status> {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        match (state as *const Snapshot<M>).as_ref() {
            Some(s) if s.tag == inst.tag => Ok(s),
            _ => Err(inst.error("FMUstate is NULL or not a state of this FMU")),
        }
    }
}

/// `fmi2SetFMUstate`.
///
/// # Safety
/// FMI 2.0 pointer rules.
pub unsafe fn set_fmu_state<M: Model>(c: fmi2Component, state: fmi2FMUstate) -> Status {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        with_instance::<M>(c, Call::FmuState, |inst| match snapshot(inst, state) {
            Ok(s) => {
                inst.core = s.core.clone();
                Status::Ok
            }
            Err(status) => status,
        })
    }
}

/// `fmi2FreeFMUstate`.
///
/// # Safety
/// FMI 2.0 pointer rules.
pub unsafe fn free_fmu_state<M: Model>(c: fmi2Component, state: *mut fmi2FMUstate) -> Status {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        with_instance::<M>(c, Call::FmuState, |inst| {
            if state.is_null() || (*state).is_null() {
                return Status::Ok;
            }
            if let Err(status) = snapshot(inst, *state) {
                return status;
            }
            let mut snap = Box::from_raw(*state as *mut Snapshot<M>);
            snap.tag = 0;
            drop(snap);
            *state = std::ptr::null_mut();
            Status::Ok
        })
    }
}

/// `fmi2SerializedFMUstateSize`.
///
/// # Safety
/// FMI 2.0 pointer rules.
pub unsafe fn serialized_size<M: Model>(
    c: fmi2Component,
    state: fmi2FMUstate,
    size: *mut usize,
) -> Status {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        with_instance::<M>(c, Call::FmuState, |inst| {
            let snap = match snapshot(inst, state) {
                Ok(s) => s,
                Err(status) => return status,
            };
            if size.is_null() {
                return inst.error("fmi2SerializedFMUstateSize: size is NULL");
            }
            match inst.serialize(&snap.core) {
                Ok(bytes) => {
                    *size = bytes.len();
                    Status::Ok
                }
                Err(e) => inst.error(e),
            }
        })
    }
}

/// `fmi2SerializeFMUstate`.
///
/// # Safety
/// FMI 2.0 pointer rules; `out` has room for `size` bytes.
pub unsafe fn serialize<M: Model>(
    c: fmi2Component,
    state: fmi2FMUstate,
    out: *mut fmi2Byte,
    size: usize,
) -> Status {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        with_instance::<M>(c, Call::FmuState, |inst| {
            let snap = match snapshot(inst, state) {
                Ok(s) => s,
                Err(status) => return status,
            };
            match inst.serialize(&snap.core) {
                Ok(bytes) if !out.is_null() && bytes.len() <= size => {
                    std::ptr::copy_nonoverlapping(bytes.as_ptr(), out as *mut u8, bytes.len());
                    Status::Ok
                }
                Ok(bytes) => inst.error(format!(
                    "fmi2SerializeFMUstate: buffer of {size} bytes, {} needed",
                    bytes.len()
                )),
                Err(e) => inst.error(e),
            }
        })
    }
}

/// `fmi2DeSerializeFMUstate`.
///
/// # Safety
/// FMI 2.0 pointer rules; `bytes` holds `size` bytes.
pub unsafe fn deserialize<M: Model>(
    c: fmi2Component,
    bytes: *const fmi2Byte,
    size: usize,
    state: *mut fmi2FMUstate,
) -> Status {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        with_instance::<M>(c, Call::FmuState, |inst| {
            if bytes.is_null() || state.is_null() {
                return inst.error("fmi2DeSerializeFMUstate: NULL argument");
            }
            let data = std::slice::from_raw_parts(bytes as *const u8, size);
            let core = match deserialize_core(inst, data) {
                Ok(core) => core,
                Err(status) => return status,
            };
            match (*state as *mut Snapshot<M>).as_mut() {
                Some(snap) if snap.tag == inst.tag => snap.core = core,
                Some(_) => {
                    return inst
                        .error("fmi2DeSerializeFMUstate: *FMUstate is not a state of this FMU")
                }
                None => {
                    *state = Box::into_raw(Box::new(Snapshot::<M> {
                        tag: inst.tag,
                        core,
                    })) as fmi2FMUstate
                }
            }
            Status::Ok
        })
    }
}

/// The body of `fmi2DeSerializeFMUstate`: the state in `bytes`, or the logged error.
pub fn deserialize_core<M: Model>(
    inst: &Instance<M>,
    bytes: &[u8],
) -> Result<Core<M::State>, Status> {
    inst.deserialize(bytes)
        .map_err(|e| inst.error(format!("fmi2DeSerializeFMUstate: {e}")))
}

/// An optional function this FMU does not provide (its capability flag says so).
///
/// # Safety
/// FMI 2.0 pointer rules.
pub unsafe fn unsupported<M: Model>(c: fmi2Component, call: Call) -> Status {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe { with_instance::<M>(c, call, |inst| unsupported_body(inst, call)) }
}

/// The body of an optional function this FMU does not provide.
pub fn unsupported_body<M: Model>(inst: &mut Instance<M>, call: Call) -> Status {
    inst.error(format!(
        "{} is not supported by {} (see its capability flags)",
        call.name(),
        M::IDENTIFIER
    ))
}

/// `fmi2GetStatus` and friends; only `fmi2LastSuccessfulTime` and `fmi2Terminated` are known.
///
/// # Safety
/// FMI 2.0 pointer rules.
pub unsafe fn get_status<M: Model, V>(
    c: fmi2Component,
    kind: fmi2StatusKind,
    out: *mut V,
    read: impl Fn(&Instance<M>, fmi2StatusKind) -> Option<V>,
) -> Status {
    // SAFETY: the caller keeps this function's contract (its `# Safety` section).
    unsafe {
        with_instance::<M>(c, Call::GetStatus, |inst| {
            if out.is_null() {
                return inst.error("fmi2Get*Status: value is NULL");
            }
            status_value(inst, kind, read, |v| out.write(v))
        })
    }
}

/// The body of `fmi2Get*Status`: `read` gives the value of `kind`, `write` delivers it;
/// `fmi2Discard` for a kind without one.
pub fn status_value<M: Model, V>(
    inst: &Instance<M>,
    kind: fmi2StatusKind,
    read: impl Fn(&Instance<M>, fmi2StatusKind) -> Option<V>,
    write: impl FnOnce(V),
) -> Status {
    match read(inst, kind) {
        Some(v) => {
            write(v);
            Status::Ok
        }
        None => Status::Discard,
    }
}

/// `fmi2GetStatus`: only `fmi2DoStepStatus` (a step always completes synchronously).
pub fn read_do_step_status<M: Model>(_: &Instance<M>, kind: fmi2StatusKind) -> Option<fmi2Status> {
    (kind == FMI2_DO_STEP_STATUS).then_some(Status::Ok.into())
}

/// `fmi2GetRealStatus`: only `fmi2LastSuccessfulTime`.
pub fn read_real_status<M: Model>(inst: &Instance<M>, kind: fmi2StatusKind) -> Option<f64> {
    (kind == FMI2_LAST_SUCCESSFUL_TIME).then_some(inst.core.time)
}

/// `fmi2GetBooleanStatus`: only `fmi2Terminated` (never: the FMU does not end a simulation).
pub fn read_boolean_status<M: Model>(_: &Instance<M>, kind: fmi2StatusKind) -> Option<fmi2Boolean> {
    (kind == FMI2_TERMINATED).then_some(FMI2_FALSE)
}

/// `fmi2GetIntegerStatus`, `fmi2GetStringStatus`: no kind has a value.
pub fn read_no_status<M: Model, V>(_: &Instance<M>, _: fmi2StatusKind) -> Option<V> {
    None
}

/// `fmi2GetVersion` and `fmi2GetTypesPlatform`.
pub fn static_string(s: &'static CStr) -> fmi2String {
    s.as_ptr()
}
