//! The eight functions of a real-code DLL over any `fmi_export::Model`: the host's structs read into the model's store, the running state kept in the host's int-state array, no panic across the boundary.
//!
//! State: the host's `IntStates` array holds all of an instance's running state: a header
//! (`MAGIC`, the blob's length in bytes, the layout's digest) and the blob, the postcard
//! serialization of the model's store and its `Model::State` (the library object, e.g.
//! `EmtUnit`). The functions decode nothing per step: each instance has a decoded copy (a
//! [`Workspace`], allocated at `Model_FirstCall`) with the bytes it last wrote; a call compares
//! the array's bytes with those (a `memcmp`) and decodes the array only when they differ, i.e.
//! after the host restored a snapshot or gave the arrays of another run. The copy is a cache of
//! the arrays, never more: a snapshot of the arrays restored, in this process or another,
//! continues exactly. See docs/realcode.md for why.

use crate::ffi::{self, Instance};
use crate::info::{declared, Field, Info, Kind};
use fmi_export::log::{LogRecord, LogSink, Logger};
use fmi_export::{Context, Model, Status, Store};
use std::ffi::c_char;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Arc, Mutex, MutexGuard};

/// The first word of an initialized state array.
pub const MAGIC: i32 = 0x4456_5050;
/// Words before the blob: `MAGIC`, the blob's length in bytes, the layout's digest.
pub const HEADER: usize = 3;
/// The most bytes of a message the host gets (longer ones are cut).
const MESSAGE_BYTES: usize = 2048;

/// An instance's decoded copy of its state array, and its message buffers.
pub struct Workspace<M: Model> {
    model: M,
    store: Store,
    /// The store of the start values (`Model_Initialize` starts from it).
    start: Store,
    state: Option<M::State>,
    /// The blob this workspace last wrote to (or read from) the state array; empty: none is
    /// valid (the copy is re-read from the array at the next call).
    blob: Vec<u8>,
    /// The bytes of the host's parameters struct the store's parameters last equalled (empty:
    /// unknown): a call whose parameters struct is unchanged skips the field-by-field check.
    params_seen: Vec<u8>,
    records: Arc<Mutex<Vec<LogRecord>>>,
    logger: Logger,
    /// NUL-terminated texts `LastGeneralMessage` and `LastErrorMessage` point at.
    general: Vec<u8>,
    error: Vec<u8>,
}

/// A workspace behind its lock, as the cache holds it.
struct Slot<M: Model>(Mutex<Workspace<M>>);

// SAFETY: the workspace's logger has a `Capture` sink (an `Arc<Mutex<Vec>>`), never the raw
// callback pointers that make `Logger` not `Send`; everything else in it is `Send`
// (`Model: Send`, `Model::State: Send`).
unsafe impl<M: Model> Send for Slot<M> {}
// SAFETY: all access goes through the mutex.
unsafe impl<M: Model> Sync for Slot<M> {}

/// The decoded copies of the live instances of one DLL, by the address of the host's instance
/// struct (a cache only: every call checks its copy against the host's arrays).
pub struct Cache<M: Model> {
    slots: Mutex<Vec<(usize, Arc<Slot<M>>)>>,
}

impl<M: Model> Default for Cache<M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<M: Model> Cache<M> {
    pub const fn new() -> Self {
        Cache {
            slots: Mutex::new(Vec::new()),
        }
    }

    fn lock_slots(&self) -> MutexGuard<'_, Vec<(usize, Arc<Slot<M>>)>> {
        self.slots.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The instance's workspace, made if it has none.
    fn get(&self, info: &Info, key: usize) -> Result<Arc<Slot<M>>, String> {
        if let Some((_, s)) = self.lock_slots().iter().find(|(k, _)| *k == key) {
            return Ok(s.clone());
        }
        let slot = Arc::new(Slot(Mutex::new(Workspace::<M>::new(info)?)));
        let mut slots = self.lock_slots();
        if let Some((_, s)) = slots.iter().find(|(k, _)| *k == key) {
            return Ok(s.clone());
        }
        slots.push((key, slot.clone()));
        Ok(slot)
    }

    fn remove(&self, key: usize) {
        self.lock_slots().retain(|(k, _)| *k != key);
    }
}

impl<M: Model> Workspace<M> {
    fn new(info: &Info) -> Result<Workspace<M>, String> {
        let (model, vars) = declared::<M>(&info.layout.spec)?;
        let start = vars.start_store();
        let records = Arc::new(Mutex::new(Vec::with_capacity(16)));
        let logger = Logger::with_sink(
            LogSink::Capture(records.clone()),
            info.layout.identifier,
            true,
        );
        Ok(Workspace {
            model,
            store: start.clone(),
            start,
            state: None,
            blob: Vec::with_capacity(info.layout.spec.state_words * 4),
            params_seen: Vec::with_capacity(info.layout.parameters.size),
            records,
            logger,
            general: Vec::with_capacity(MESSAGE_BYTES + 1),
            error: Vec::with_capacity(MESSAGE_BYTES + 1),
        })
    }
}

/// `text` into the NUL-terminated buffer `buf` (cut at `MESSAGE_BYTES`, on a character).
fn put(buf: &mut Vec<u8>, text: &str) {
    let mut end = text.len().min(MESSAGE_BYTES);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    buf.clear();
    buf.extend(
        text.as_bytes()[..end]
            .iter()
            .map(|&b| if b == 0 { b' ' } else { b }),
    );
    buf.push(0);
}

/// The message of a failure with no workspace to hold a text.
const NO_WORKSPACE: &std::ffi::CStr =
    c"the DLL could not make this instance's workspace (see Model_PrintInfo; the model's declarations failed)";
const PANICKED: &std::ffi::CStr =
    c"internal error: the model panicked (contained at the DLL boundary); the instance's state arrays are unchanged since its last successful call";

/// Run `f` on the instance's workspace; an error is its message in `LastErrorMessage`
/// (return 2), messages of the call in `LastGeneralMessage` (return 1); a panic is contained.
///
/// # Safety
/// `inst` is null or points to a host instance whose pointers are valid for the layout.
unsafe fn call<M: Model>(
    cache: &Cache<M>,
    info: &Info,
    inst: *mut Instance,
    f: impl FnOnce(&mut Workspace<M>, &mut Instance, &Info) -> Result<(), String>,
) -> i32 {
    if inst.is_null() {
        return ffi::RETURN_ERROR;
    }
    let result = catch_unwind(AssertUnwindSafe(|| {
        // SAFETY: the host passes its instance, valid for this call and not used elsewhere
        // during it (the standard's calling convention).
        let inst = unsafe { &mut *inst };
        let slot = match cache.get(info, inst as *mut Instance as usize) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("{}: {e}", info.layout.identifier);
                inst.last_error_message = NO_WORKSPACE.as_ptr();
                return ffi::RETURN_ERROR;
            }
        };
        let mut ws = slot.0.lock().unwrap_or_else(|e| e.into_inner());
        let ws = &mut *ws;
        ws.records.lock().unwrap_or_else(|e| e.into_inner()).clear();
        match f(ws, inst, info) {
            Ok(()) => {
                let records = ws.records.lock().unwrap_or_else(|e| e.into_inner());
                if records.is_empty() {
                    ffi::RETURN_OK
                } else {
                    let text = records
                        .iter()
                        .map(|r| r.message.as_str())
                        .collect::<Vec<_>>()
                        .join("\n");
                    drop(records);
                    put(&mut ws.general, &text);
                    inst.last_general_message = ws.general.as_ptr() as *const c_char;
                    ffi::RETURN_MESSAGE
                }
            }
            Err(e) => {
                put(&mut ws.error, &format!("{}: {e}", info.layout.identifier));
                inst.last_error_message = ws.error.as_ptr() as *const c_char;
                ffi::RETURN_ERROR
            }
        }
    }));
    result.unwrap_or_else(|_| {
        // SAFETY: as above; the closure that held the reference has unwound.
        unsafe { (*inst).last_error_message = PANICKED.as_ptr() };
        ffi::RETURN_ERROR
    })
}

/// A field's value in a host struct at `base`, as f64 (Integer and Boolean exactly).
///
/// # Safety
/// `base` points to a host struct of the field's group layout.
unsafe fn read(base: *const u8, f: &Field) -> f64 {
    // SAFETY: the caller's struct has this field at this offset; unaligned reads accept any
    // host allocation.
    unsafe {
        match f.kind {
            Kind::Real => base.add(f.offset).cast::<f64>().read_unaligned(),
            Kind::Integer | Kind::Boolean => {
                f64::from(base.add(f.offset).cast::<i32>().read_unaligned())
            }
        }
    }
}

/// Write `x` to a field of a host struct at `base`.
///
/// # Safety
/// As [`read`], the struct writable.
unsafe fn write(base: *mut u8, f: &Field, x: f64) {
    // SAFETY: as in `read`.
    unsafe {
        match f.kind {
            Kind::Real => base.add(f.offset).cast::<f64>().write_unaligned(x),
            Kind::Integer | Kind::Boolean => {
                base.add(f.offset).cast::<i32>().write_unaligned(x as i32)
            }
        }
    }
}

fn store_get(s: &Store, f: &Field) -> f64 {
    match f.kind {
        Kind::Real => s.reals[f.vr as usize],
        Kind::Integer => f64::from(s.integers[f.vr as usize]),
        Kind::Boolean => {
            if s.booleans[f.vr as usize] {
                1.0
            } else {
                0.0
            }
        }
    }
}

fn store_set(s: &mut Store, f: &Field, x: f64) {
    match f.kind {
        Kind::Real => s.reals[f.vr as usize] = x,
        Kind::Integer => s.integers[f.vr as usize] = x as i32,
        Kind::Boolean => s.booleans[f.vr as usize] = x != 0.0,
    }
}

/// Why the value `x` of field `f` (a parameter or an input) is refused, if it is.
fn refused(f: &Field, x: f64, what: &str) -> Option<String> {
    let ok = match f.kind {
        Kind::Real => x.is_finite() && x >= f.min && x <= f.max,
        Kind::Integer | Kind::Boolean => x >= f.min && x <= f.max,
    };
    (!ok).then(|| {
        format!(
            "{what} '{}' = {x} is outside its range [{}, {}]{}",
            f.name,
            f.min,
            f.max,
            if f.name != f.fmu_name {
                format!(" (FMU: {})", f.fmu_name)
            } else {
                String::new()
            }
        )
    })
}

/// The host's parameters checked against their ranges, and against the DLL's fixed step.
///
/// # Safety
/// `inst.parameters` points to the host's parameters struct.
unsafe fn check_parameters(inst: &Instance, info: &Info) -> Result<(), String> {
    let base = inst.parameters as *const u8;
    if base.is_null() && !info.layout.parameters.fields.is_empty() {
        return Err("the instance has no parameters struct (Parameters is null)".into());
    }
    for f in &info.layout.parameters.fields {
        // SAFETY: the host's parameters struct has the layout the model info describes.
        let x = unsafe { read(base, f) };
        if let Some(e) = refused(f, x, "parameter") {
            return Err(e);
        }
        if info.layout.spec.step_parameter == Some(f.fmu_name.as_str())
            && x != info.layout.spec.step
        {
            return Err(format!(
                "parameter '{}' = {x} s differs from the DLL's fixed step {} s \
                 (FixedStepBaseSampleTime); the DLL runs at that step only",
                f.name, info.layout.spec.step
            ));
        }
    }
    Ok(())
}

/// The host's inputs into the store; a non-finite or out-of-range value is refused by name.
///
/// # Safety
/// `inst.external_inputs` points to the host's inputs struct.
unsafe fn read_inputs(store: &mut Store, inst: &Instance, info: &Info) -> Result<(), String> {
    let base = inst.external_inputs as *const u8;
    for f in &info.layout.inputs.fields {
        // SAFETY: the host's inputs struct has the layout the model info describes.
        let x = unsafe { read(base, f) };
        if let Some(e) = refused(f, x, "input") {
            return Err(e);
        }
        store_set(store, f, x);
    }
    Ok(())
}

/// The store's outputs into the host's outputs struct; a non-finite value is an error naming
/// the variable (as the FMU's `fmi2DoStep`).
///
/// # Safety
/// `inst.external_outputs` points to the host's outputs struct.
unsafe fn write_outputs(store: &Store, inst: &Instance, info: &Info) -> Result<(), String> {
    let any_bad = store
        .reals
        .iter()
        .fold(false, |bad, x| bad | !x.is_finite());
    if any_bad {
        let all = info
            .layout
            .outputs
            .fields
            .iter()
            .chain(&info.layout.parameters.fields)
            .chain(&info.layout.inputs.fields);
        for f in all.filter(|f| f.kind == Kind::Real) {
            let x = store.reals[f.vr as usize];
            if !x.is_finite() {
                return Err(format!("'{}' became {x}", f.name));
            }
        }
        return Err("a variable became non-finite".into());
    }
    let base = inst.external_outputs as *mut u8;
    for f in &info.layout.outputs.fields {
        // SAFETY: the host's outputs struct has the layout the model info describes.
        unsafe { write(base, f, store_get(store, f)) };
    }
    Ok(())
}

/// The instance's int-state array.
///
/// # Safety
/// `inst.int_states` points to `NumIntStates` words.
unsafe fn state_words<'a>(inst: &Instance, info: &Info) -> Result<&'a mut [i32], String> {
    let n = info.layout.spec.state_words;
    if inst.int_states.is_null() {
        return Err(format!(
            "IntStates is null: the DLL keeps its running state there ({n} int32 words, NumIntStates)"
        ));
    }
    // SAFETY: the host allocated NumIntStates words for this instance.
    Ok(unsafe { std::slice::from_raw_parts_mut(inst.int_states, n) })
}

/// The bytes of the blob area of the state words.
fn blob_area(words: &mut [i32]) -> &mut [u8] {
    let tail = &mut words[HEADER..];
    // SAFETY: i32 words reinterpreted as their bytes (any bit pattern is a valid u8; the
    // alignment of u8 is 1); the slice borrows `words` mutably for its life.
    unsafe { std::slice::from_raw_parts_mut(tail.as_mut_ptr().cast::<u8>(), tail.len() * 4) }
}

impl<M: Model> Workspace<M> {
    /// The decoded copy made equal to the instance's state array (decoded only if it differs).
    fn sync(&mut self, words: &mut [i32], info: &Info) -> Result<(), String> {
        if words[0] != MAGIC {
            return Err(
                "the state array holds no initialized state: call Model_Initialize first".into(),
            );
        }
        if words[2] != info.layout.digest as i32 {
            return Err(format!(
                "the state array was written by another model or version (layout digest {:#x}, this DLL's {:#x})",
                words[2] as u32, info.layout.digest
            ));
        }
        let len = words[1] as usize;
        let area = blob_area(words);
        if len > area.len() {
            return Err(format!(
                "the state array's length word ({len} bytes) exceeds its capacity"
            ));
        }
        let bytes = &area[..len];
        if self.state.is_none() || self.blob.as_slice() != bytes {
            self.blob.clear();
            let (store, state): (Store, M::State) = postcard::from_bytes(bytes)
                .map_err(|e| format!("the state array does not decode: {e}"))?;
            if store.reals.len() != self.start.reals.len()
                || store.integers.len() != self.start.integers.len()
                || store.booleans.len() != self.start.booleans.len()
            {
                return Err("the state array holds another model's variables".into());
            }
            self.store = store;
            self.state = Some(state);
            self.blob.extend_from_slice(bytes);
            self.params_seen.clear();
        }
        Ok(())
    }

    /// The store and state written to the instance's state array (and kept as the copy).
    fn save(&mut self, words: &mut [i32], info: &Info) -> Result<(), String> {
        let state = self.state.as_ref().ok_or("no running state")?;
        let area = blob_area(words);
        let cap = area.len();
        let used = postcard::to_slice(&(&self.store, state), area)
            .map_err(|e| {
                format!(
                    "the running state does not fit the state array ({cap} bytes, NumIntStates {}): {e}",
                    info.layout.spec.state_words
                )
            })?
            .len();
        self.blob.clear();
        self.blob.extend_from_slice(&blob_area(words)[..used]);
        words[0] = MAGIC;
        words[1] = used as i32;
        words[2] = info.layout.digest as i32;
        Ok(())
    }
}

/// A model's identifier (for messages before its info exists).
pub trait ModelName {
    fn identifier() -> &'static str;
}

impl<M: Model> ModelName for M {
    fn identifier() -> &'static str {
        M::IDENTIFIER
    }
}

/// `Model_GetInfo`: the info, or null if the model's declarations failed.
pub fn get_info(info: fn() -> Option<&'static Info>) -> *const ffi::ModelInfo {
    catch_unwind(info)
        .ok()
        .flatten()
        .map_or(std::ptr::null(), |i| &i.info as *const ffi::ModelInfo)
}

/// `Model_FirstCall`: the instance's workspace.
///
/// # Safety
/// As every instance-taking function: `inst` is the host's instance.
pub unsafe fn first_call<M: Model>(cache: &Cache<M>, info: &Info, inst: *mut Instance) -> i32 {
    // SAFETY: forwarded from the caller.
    unsafe { call(cache, info, inst, |_, _, _| Ok(())) }
}

/// `Model_CheckParameters`: every parameter within its range; an error names the first
/// that is not.
///
/// # Safety
/// As [`first_call`].
pub unsafe fn check<M: Model>(cache: &Cache<M>, info: &Info, inst: *mut Instance) -> i32 {
    // SAFETY: forwarded from the caller.
    unsafe {
        call(cache, info, inst, |_, inst, info| {
            check_parameters(inst, info)
        })
    }
}

/// `Model_Initialize`: the model initialized from the parameters and the inputs (the measured
/// operating point), as the FMU on leaving initialization mode; its outputs and state written.
///
/// # Safety
/// As [`first_call`].
pub unsafe fn initialize<M: Model>(cache: &Cache<M>, info: &Info, inst: *mut Instance) -> i32 {
    // SAFETY: forwarded from the caller.
    unsafe {
        call(cache, info, inst, |ws, inst, info| {
            check_parameters(inst, info)?;
            let words = state_words(inst, info)?;
            // Called again while the host holds the model at its initial conditions: the
            // earlier initialization is the model's `previous`.
            let previous = words[0] == MAGIC && ws.sync(words, info).is_ok();
            ws.blob.clear();
            let mut store = ws.start.clone();
            let base = inst.parameters as *const u8;
            for f in &info.layout.parameters.fields {
                store_set(&mut store, f, read(base, f));
            }
            read_inputs(&mut store, inst, info)?;
            let mut ctx = Context::for_host(Some(&ws.logger), false);
            let prev = if previous { ws.state.as_ref() } else { None };
            let state = ws
                .model
                .initialize(prev, &mut store, &mut ctx)
                .map_err(|e| e.0)?;
            write_outputs(&store, inst, info)?;
            ws.store = store;
            ws.state = Some(state);
            ws.params_seen.clear();
            if !base.is_null() {
                ws.params_seen.extend_from_slice(std::slice::from_raw_parts(
                    base,
                    info.layout.parameters.size,
                ));
            }
            ws.save(words, info)
        })
    }
}

/// `Model_Outputs`: one step of the fixed step from `Time` with the inputs sampled there;
/// changed tunable parameters retune the model first (a fixed one is refused by name).
///
/// # Safety
/// As [`first_call`].
pub unsafe fn outputs<M: Model>(cache: &Cache<M>, info: &Info, inst: *mut Instance) -> i32 {
    // SAFETY: forwarded from the caller.
    unsafe {
        call(cache, info, inst, |ws, inst, info| {
            let words = state_words(inst, info)?;
            ws.sync(words, info)?;
            // The copy is invalid until this call has written the array again.
            ws.blob.clear();
            let mut tuned = false;
            let base = inst.parameters as *const u8;
            if base.is_null() && info.layout.parameters.size > 0 {
                return Err("the instance has no parameters struct (Parameters is null)".into());
            }
            // The host's parameters struct as bytes (padding included: a change there only
            // costs the field-by-field check).
            let host: &[u8] = if base.is_null() {
                &[]
            } else {
                std::slice::from_raw_parts(base, info.layout.parameters.size)
            };
            let unchanged = ws.params_seen.as_slice() == host;
            for f in info.layout.parameters.fields.iter().filter(|_| !unchanged) {
                let x = read(base, f);
                let was = store_get(&ws.store, f);
                if x.to_bits() != was.to_bits() {
                    if !f.tunable {
                        return Err(format!(
                            "parameter '{}' changed from {was} to {x} after Model_Initialize; it is fixed (FixedValue 1)",
                            f.name
                        ));
                    }
                    if let Some(e) = refused(f, x, "parameter") {
                        return Err(e);
                    }
                    store_set(&mut ws.store, f, x);
                    tuned = true;
                }
            }
            if !unchanged {
                ws.params_seen.clear();
                ws.params_seen.extend_from_slice(host);
            }
            read_inputs(&mut ws.store, inst, info)?;
            let t = inst.time;
            if !t.is_finite() {
                return Err(format!("Time = {t} is not finite"));
            }
            let mut ctx = Context::for_host(Some(&ws.logger), tuned);
            let state = ws.state.as_mut().ok_or("no running state")?;
            ws.model
                .do_step(state, &mut ws.store, t, info.layout.spec.step, &mut ctx)
                .map_err(|e| format!("at Time = {t} s: {}", e.0))?;
            let _: Status = ctx.status();
            write_outputs(&ws.store, inst, info)?;
            ws.save(words, info)
        })
    }
}

/// `Model_Iterate`: nothing (an EMT model; an RMS host's iterations change no state).
///
/// # Safety
/// As [`first_call`].
pub unsafe fn iterate<M: Model>(cache: &Cache<M>, info: &Info, inst: *mut Instance) -> i32 {
    // SAFETY: forwarded from the caller.
    unsafe { call(cache, info, inst, |_, _, _| Ok(())) }
}

/// `Model_Terminate`: the instance's workspace freed (its arrays are the host's).
///
/// # Safety
/// As [`first_call`].
pub unsafe fn terminate<M: Model>(cache: &Cache<M>, inst: *mut Instance) -> i32 {
    if inst.is_null() {
        return ffi::RETURN_ERROR;
    }
    catch_unwind(AssertUnwindSafe(|| {
        cache.remove(inst as usize);
        ffi::RETURN_OK
    }))
    .unwrap_or(ffi::RETURN_ERROR)
}

/// `Model_PrintInfo`: the model info on standard output.
pub fn print_info(info: fn() -> Option<&'static Info>) -> i32 {
    catch_unwind(|| match info() {
        Some(i) => {
            print!("{}", crate::header::summary(&i.layout));
            ffi::RETURN_OK
        }
        None => ffi::RETURN_ERROR,
    })
    .unwrap_or(ffi::RETURN_ERROR)
}
