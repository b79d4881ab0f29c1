//! An instance of a loaded FMU and its FMI 2.0 Co-Simulation calls.

use super::log::{dvpp_cosim_logger, LogRecord, LogSink};
use super::trace::Trace;
use super::{err, Error, Fmu, Status};
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::ptr::NonNull;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use fmi2::{fmi2CallbackFunctions as CallbackFunctions, fmi2Component as Component};
use fmi2::{fmi2FMUstate as FmuState, Functions as Api};

impl Fmu {
    /// Instantiate with the description's GUID and the unpacked resources.
    pub fn instantiate(self: &Arc<Self>, name: &str) -> Result<Instance, Error> {
        let guid = self.description.guid.clone();
        self.instantiate_with(name, &guid, &self.resource_uri(), 1)
    }

    /// [`Fmu::instantiate`], every call to the instance from `fmi2Instantiate` on written to
    /// `trace` (see [`super::trace`]).
    pub fn instantiate_traced(
        self: &Arc<Self>,
        name: &str,
        trace: Option<Trace>,
    ) -> Result<Instance, Error> {
        let guid = self.description.guid.clone();
        self.instantiate_inner(name, &guid, &self.resource_uri(), 1, trace.map(Box::new))
    }

    /// Instantiate with explicit GUID, resource URI and `fmuType` (for tests of bad calls).
    pub fn instantiate_with(
        self: &Arc<Self>,
        name: &str,
        guid: &str,
        resources: &str,
        fmu_type: i32,
    ) -> Result<Instance, Error> {
        self.instantiate_inner(name, guid, resources, fmu_type, None)
    }

    fn instantiate_inner(
        self: &Arc<Self>,
        name: &str,
        guid: &str,
        resources: &str,
        fmu_type: i32,
        mut trace: Option<Box<Trace>>,
    ) -> Result<Instance, Error> {
        // The sink and the callbacks are where the FMU's pointers lead for the instance's whole
        // life: each is allocated once here and never moved, re-boxed or borrowed uniquely
        // again (see `Instance`), and freed only after `fmi2FreeInstance`.
        let sink = Arc::new(LogSink {
            instance: name.to_owned(),
            records: Mutex::new(Vec::new()),
            held: AtomicUsize::new(0),
            echo: std::env::var_os("DVPP_FMU_LOG").is_some(),
        });
        let callbacks = NonNull::from(Box::leak(Box::new(CallbackFunctions {
            logger: Some(dvpp_cosim_logger),
            allocate_memory: Some(alloc_callback),
            free_memory: Some(free_callback),
            step_finished: None,
            // Only ever read through shared references (`log_sink`); the Arc keeps it alive.
            component_environment: Arc::as_ptr(&sink) as *mut c_void,
        })));
        let (c_name, c_guid, c_res) = (cstring(name)?, cstring(guid)?, cstring(resources)?);
        if let Some(t) = &mut trace {
            t.instantiate(name, fmu_type, guid, resources);
        }
        // SAFETY: valid C strings; the callbacks struct and the sink it points to stay at their
        // addresses until the instance is freed (`Instance`'s Drop), or until just below when
        // no instance was made.
        let component = unsafe {
            (self.library.api.instantiate)(
                c_name.as_ptr(),
                fmu_type,
                c_guid.as_ptr(),
                c_res.as_ptr(),
                callbacks.as_ptr(),
                0,
                0,
            )
        };
        if component.is_null() {
            // SAFETY: leaked from a Box above and not used by anyone now: no instance exists.
            drop(unsafe { Box::from_raw(callbacks.as_ptr()) });
            let last = sink
                .records
                .lock()
                .unwrap()
                .last()
                .map(|r| r.message.clone())
                .unwrap_or_default();
            return err(format!("fmi2Instantiate of '{name}' returned NULL: {last}"));
        }
        Ok(Instance {
            fmu: Arc::clone(self),
            component,
            sink,
            callbacks,
            trace,
        })
    }
}

fn cstring(s: &str) -> Result<CString, Error> {
    CString::new(s).map_err(|_| Error(format!("'{s}' contains a NUL byte")))
}

unsafe extern "C" fn alloc_callback(n: usize, size: usize) -> *mut c_void {
    // SAFETY: calloc accepts any sizes (NULL when it cannot).
    unsafe { libc::calloc(n, size) }
}

unsafe extern "C" fn free_callback(p: *mut c_void) {
    // SAFETY: the FMU frees what `alloc_callback` gave it (or NULL), as FMI 2.0 requires.
    unsafe { libc::free(p) }
}

/// An instance of a loaded FMU; freed on drop.
///
/// The FMU keeps two pointers of ours for as long as the instance lives: to the callbacks
/// struct, and (as its `componentEnvironment`) to the log sink, which it may call at any time.
/// Both stay at one address and are only ever shared: the sink is an `Arc` (moving the
/// `Instance` moves the handle, not the sink, and asserts no unique access to it), the
/// callbacks a leaked `Box` held by address. Both are freed after `fmi2FreeInstance`.
pub struct Instance {
    fmu: Arc<Fmu>,
    component: Component,
    sink: Arc<LogSink>,
    /// A leaked `Box`, freed in Drop.
    callbacks: NonNull<CallbackFunctions>,
    /// Where the calls that change the instance's state, and its reads, are recorded (only
    /// when asked: otherwise one test of `None` per call).
    trace: Option<Box<Trace>>,
}

// SAFETY: an FMI 2.0 instance shares no state with the other instances of its binary through
// the API (each has its own component, callbacks and log sink), and the master calls each
// instance from one thread at a time (`&mut self` on every call that reaches the FMU), so an
// instance may move to another thread between calls, which is what parallel stepping does.
// That instances of one binary may step in parallel threads at all is the FMU's property:
// ours keep no global mutable state (tested); `--threads` is the user's choice for others.
unsafe impl Send for Instance {}

/// A saved FMU state; must be freed through the instance that made it.
pub struct SavedState(FmuState);

impl Instance {
    pub fn fmu(&self) -> &Arc<Fmu> {
        &self.fmu
    }

    /// Everything the FMU logged so far.
    pub fn log(&self) -> Vec<LogRecord> {
        self.sink
            .records
            .lock()
            .map(|r| r.clone())
            .unwrap_or_default()
    }

    /// Whether the FMU logged anything since the last [`Instance::take_log`] (one atomic load:
    /// the master asks after every call).
    #[inline]
    pub fn has_log(&self) -> bool {
        self.sink.held.load(Ordering::Acquire) != 0
    }

    /// The messages logged since the last call (they are removed from the record).
    pub fn take_log(&self) -> Vec<LogRecord> {
        if self.sink.held.load(Ordering::Acquire) == 0 {
            return Vec::new();
        }
        self.sink
            .records
            .lock()
            .map(|mut r| {
                self.sink.held.store(0, Ordering::Release);
                std::mem::take(&mut *r)
            })
            .unwrap_or_default()
    }

    /// The last message the FMU logged.
    pub fn last_message(&self) -> Option<String> {
        self.sink
            .records
            .lock()
            .ok()?
            .last()
            .map(|r| r.message.clone())
    }

    /// The trace of the instance's calls, when it has one (to add [`Trace::sample`] marks).
    pub fn trace_mut(&mut self) -> Option<&mut Trace> {
        self.trace.as_deref_mut()
    }

    /// Flush the trace, if any: the first error writing it.
    pub fn finish_trace(&mut self) -> Result<(), String> {
        self.trace.as_mut().map_or(Ok(()), |t| t.finish())
    }

    fn api(&self) -> &Api {
        &self.fmu.library.api
    }

    pub fn set_debug_logging(&mut self, on: bool, categories: &[&str]) -> Status {
        let c: Vec<CString> = categories
            .iter()
            .map(|s| CString::new(*s).unwrap())
            .collect();
        let p: Vec<*const c_char> = c.iter().map(|s| s.as_ptr()).collect();
        // SAFETY: arrays of the stated length.
        Status::from_c(unsafe {
            (self.api().set_debug_logging)(self.component, on as c_int, p.len(), p.as_ptr())
        })
    }

    pub fn setup_experiment(&mut self, start: f64, stop: Option<f64>) -> Status {
        if let Some(t) = &mut self.trace {
            t.setup_experiment(None, start, stop);
        }
        // SAFETY: plain values.
        Status::from_c(unsafe {
            (self.api().setup_experiment)(
                self.component,
                0,
                0.0,
                start,
                stop.is_some() as c_int,
                stop.unwrap_or(0.0),
            )
        })
    }

    pub fn enter_initialization_mode(&mut self) -> Status {
        if let Some(t) = &mut self.trace {
            t.call("enter_initialization_mode");
        }
        // SAFETY: valid component.
        Status::from_c(unsafe { (self.api().enter_initialization_mode)(self.component) })
    }

    pub fn exit_initialization_mode(&mut self) -> Status {
        if let Some(t) = &mut self.trace {
            t.call("exit_initialization_mode");
        }
        // SAFETY: valid component.
        Status::from_c(unsafe { (self.api().exit_initialization_mode)(self.component) })
    }

    pub fn terminate(&mut self) -> Status {
        if let Some(t) = &mut self.trace {
            t.call("terminate");
        }
        // SAFETY: valid component.
        Status::from_c(unsafe { (self.api().terminate)(self.component) })
    }

    pub fn reset(&mut self) -> Status {
        if let Some(t) = &mut self.trace {
            t.call("reset");
        }
        // SAFETY: valid component.
        Status::from_c(unsafe { (self.api().reset)(self.component) })
    }

    pub fn get_real(&mut self, vrs: &[u32], out: &mut [f64]) -> Status {
        assert_eq!(vrs.len(), out.len());
        if let Some(t) = &mut self.trace {
            t.get("get_real", vrs);
        }
        // SAFETY: arrays of equal, stated length.
        Status::from_c(unsafe {
            (self.api().get_real)(self.component, vrs.as_ptr(), vrs.len(), out.as_mut_ptr())
        })
    }

    pub fn set_real(&mut self, vrs: &[u32], values: &[f64]) -> Status {
        assert_eq!(vrs.len(), values.len());
        if let Some(t) = &mut self.trace {
            t.set_real(vrs, values);
        }
        // SAFETY: arrays of equal, stated length.
        Status::from_c(unsafe {
            (self.api().set_real)(self.component, vrs.as_ptr(), vrs.len(), values.as_ptr())
        })
    }

    pub fn get_integer(&mut self, vrs: &[u32], out: &mut [i32]) -> Status {
        assert_eq!(vrs.len(), out.len());
        if let Some(t) = &mut self.trace {
            t.get("get_integer", vrs);
        }
        // SAFETY: arrays of equal, stated length.
        Status::from_c(unsafe {
            (self.api().get_integer)(self.component, vrs.as_ptr(), vrs.len(), out.as_mut_ptr())
        })
    }

    pub fn set_integer(&mut self, vrs: &[u32], values: &[i32]) -> Status {
        assert_eq!(vrs.len(), values.len());
        if let Some(t) = &mut self.trace {
            t.set_integer(vrs, values);
        }
        // SAFETY: arrays of equal, stated length.
        Status::from_c(unsafe {
            (self.api().set_integer)(self.component, vrs.as_ptr(), vrs.len(), values.as_ptr())
        })
    }

    pub fn get_boolean(&mut self, vrs: &[u32], out: &mut [bool]) -> Status {
        let mut raw = vec![0; vrs.len()];
        if let Some(t) = &mut self.trace {
            t.get("get_boolean", vrs);
        }
        // SAFETY: arrays of equal, stated length.
        let s = Status::from_c(unsafe {
            (self.api().get_boolean)(self.component, vrs.as_ptr(), vrs.len(), raw.as_mut_ptr())
        });
        for (o, r) in out.iter_mut().zip(raw) {
            *o = r != 0;
        }
        s
    }

    pub fn set_boolean(&mut self, vrs: &[u32], values: &[bool]) -> Status {
        let raw: Vec<c_int> = values.iter().map(|&b| b as c_int).collect();
        if let Some(t) = &mut self.trace {
            t.set_boolean(vrs, &raw);
        }
        // SAFETY: arrays of equal, stated length.
        Status::from_c(unsafe {
            (self.api().set_boolean)(self.component, vrs.as_ptr(), vrs.len(), raw.as_ptr())
        })
    }

    pub fn get_string(&mut self, vrs: &[u32]) -> (Status, Vec<String>) {
        let mut raw = vec![std::ptr::null(); vrs.len()];
        if let Some(t) = &mut self.trace {
            t.get("get_string", vrs);
        }
        // SAFETY: arrays of equal length; strings copied before the next call.
        unsafe {
            let s = Status::from_c((self.api().get_string)(
                self.component,
                vrs.as_ptr(),
                vrs.len(),
                raw.as_mut_ptr(),
            ));
            let v = raw
                .iter()
                .map(|&p| {
                    if p.is_null() {
                        String::new()
                    } else {
                        CStr::from_ptr(p).to_string_lossy().into_owned()
                    }
                })
                .collect();
            (s, v)
        }
    }

    pub fn set_string(&mut self, vrs: &[u32], values: &[&str]) -> Status {
        let c: Vec<CString> = values.iter().map(|s| CString::new(*s).unwrap()).collect();
        let p: Vec<*const c_char> = c.iter().map(|s| s.as_ptr()).collect();
        if let Some(t) = &mut self.trace {
            t.set_string(vrs, values);
        }
        // SAFETY: arrays of equal, stated length.
        Status::from_c(unsafe {
            (self.api().set_string)(self.component, vrs.as_ptr(), vrs.len(), p.as_ptr())
        })
    }

    pub fn do_step(&mut self, t: f64, h: f64) -> Status {
        if let Some(trace) = &mut self.trace {
            trace.do_step(t, h, true);
        }
        // SAFETY: plain values.
        Status::from_c(unsafe { (self.api().do_step)(self.component, t, h, 1) })
    }

    /// `fmi2GetFMUstate` into a new state.
    pub fn get_state(&mut self) -> (Status, Option<SavedState>) {
        let mut s: FmuState = std::ptr::null_mut();
        if let Some(t) = &mut self.trace {
            t.call("get_fmu_state");
        }
        // SAFETY: out-pointer to a null state asks for a new one.
        let status = Status::from_c(unsafe { (self.api().get_fmu_state)(self.component, &mut s) });
        (status, (!s.is_null()).then_some(SavedState(s)))
    }

    /// `fmi2GetFMUstate` into a state this FMU made before (overwritten, no allocation).
    pub fn update_state(&mut self, s: &mut SavedState) -> Status {
        if let Some(t) = &mut self.trace {
            t.call("get_fmu_state");
        }
        // SAFETY: out-pointer to a state of this FMU asks for an overwrite.
        Status::from_c(unsafe { (self.api().get_fmu_state)(self.component, &mut s.0) })
    }

    pub fn set_state(&mut self, s: &SavedState) -> Status {
        if let Some(t) = &mut self.trace {
            t.call("set_fmu_state");
        }
        // SAFETY: a state this FMU made.
        Status::from_c(unsafe { (self.api().set_fmu_state)(self.component, s.0) })
    }

    pub fn free_state(&mut self, mut s: SavedState) -> Status {
        if let Some(t) = &mut self.trace {
            t.call("free_fmu_state");
        }
        // SAFETY: a state this FMU made; freed once.
        Status::from_c(unsafe { (self.api().free_fmu_state)(self.component, &mut s.0) })
    }

    /// Serialize a saved state to bytes.
    pub fn serialize_state(&mut self, s: &SavedState) -> Result<Vec<u8>, Status> {
        let mut size = 0usize;
        // SAFETY: out-pointers valid; buffer of the reported size.
        unsafe {
            let st = Status::from_c((self.api().serialized_fmu_state_size)(
                self.component,
                s.0,
                &mut size,
            ));
            if st > Status::Warning {
                return Err(st);
            }
            let mut buf = vec![0u8; size];
            let st = Status::from_c((self.api().serialize_fmu_state)(
                self.component,
                s.0,
                buf.as_mut_ptr() as *mut c_char,
                size,
            ));
            if st > Status::Warning {
                return Err(st);
            }
            Ok(buf)
        }
    }

    /// Turn bytes back into a saved state of this instance.
    pub fn deserialize_state(&mut self, bytes: &[u8]) -> (Status, Option<SavedState>) {
        let mut s: FmuState = std::ptr::null_mut();
        if let Some(t) = &mut self.trace {
            t.call("unsupported fmi2DeSerializeFMUstate");
        }
        // SAFETY: buffer of the stated length; out-pointer to a null state.
        let st = Status::from_c(unsafe {
            (self.api().deserialize_fmu_state)(
                self.component,
                bytes.as_ptr() as *const c_char,
                bytes.len(),
                &mut s,
            )
        });
        (st, (!s.is_null()).then_some(SavedState(s)))
    }

    /// Call each optional function this project's FMUs do not provide; returns their statuses.
    pub fn call_unsupported(&mut self) -> Vec<(&'static str, Status)> {
        let (vr, order, mut x) = ([0u32], [1 as c_int], [0.0f64]);
        // SAFETY: one-element arrays as stated.
        unsafe {
            let a = self.api();
            vec![
                (
                    "fmi2GetDirectionalDerivative",
                    (a.get_directional_derivative)(
                        self.component,
                        vr.as_ptr(),
                        1,
                        vr.as_ptr(),
                        1,
                        x.as_ptr(),
                        x.as_mut_ptr(),
                    ),
                ),
                (
                    "fmi2SetRealInputDerivatives",
                    (a.set_real_input_derivatives)(
                        self.component,
                        vr.as_ptr(),
                        1,
                        order.as_ptr(),
                        x.as_ptr(),
                    ),
                ),
                (
                    "fmi2GetRealOutputDerivatives",
                    (a.get_real_output_derivatives)(
                        self.component,
                        vr.as_ptr(),
                        1,
                        order.as_ptr(),
                        x.as_mut_ptr(),
                    ),
                ),
                ("fmi2CancelStep", (a.cancel_step)(self.component)),
            ]
            .into_iter()
            .map(|(n, s)| (n, Status::from_c(s)))
            .collect()
        }
    }

    /// `fmi2GetRealStatus(fmi2LastSuccessfulTime)` and `fmi2GetBooleanStatus(fmi2Terminated)`.
    pub fn last_successful_time(&mut self) -> (Status, f64) {
        let mut t = f64::NAN;
        // SAFETY: out-pointer valid.
        let s = Status::from_c(unsafe { (self.api().get_real_status)(self.component, 2, &mut t) });
        (s, t)
    }

    /// Statuses the FMU reports for the other status queries (integer, string, boolean, status).
    pub fn status_queries(&mut self) -> Vec<Status> {
        let (mut i, mut b, mut st) = (0, 0, 0);
        let mut s: *const c_char = std::ptr::null();
        // SAFETY: out-pointers valid.
        unsafe {
            let a = self.api();
            vec![
                Status::from_c((a.get_status)(self.component, 0, &mut st)),
                Status::from_c((a.get_integer_status)(self.component, 0, &mut i)),
                Status::from_c((a.get_boolean_status)(self.component, 3, &mut b)),
                Status::from_c((a.get_string_status)(self.component, 1, &mut s)),
            ]
        }
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        // SAFETY: the component is valid and freed once; the callbacks and the sink outlive it.
        unsafe { (self.fmu.library.api.free_instance)(self.component) };
        // SAFETY: leaked from a Box in `instantiate_with` and freed once, here, after the
        // instance that used it (the sink's Arc is dropped with the other fields, after this).
        drop(unsafe { Box::from_raw(self.callbacks.as_ptr()) });
    }
}
