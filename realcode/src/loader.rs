//! An import tool's view of a real-code DLL (for the tests): `dlopen` it, read its model info into Rust values, allocate an instance's structs and state arrays as the info describes them (C layout computed here, not taken from the DLL), and call the eight functions.

use crate::ffi::{self, Instance, ModelInfo};
use std::ffi::{c_char, c_void, CStr, CString};
use std::path::Path;

type GetInfo = unsafe extern "C" fn() -> *const ModelInfo;
type PrintInfo = unsafe extern "C" fn() -> i32;
type Call = unsafe extern "C" fn(*mut Instance) -> i32;

/// The interface's eight symbols, in the order a host resolves them.
pub const SYMBOLS: [&str; 8] = [
    "Model_GetInfo",
    "Model_FirstCall",
    "Model_PrintInfo",
    "Model_CheckParameters",
    "Model_Initialize",
    "Model_Outputs",
    "Model_Iterate",
    "Model_Terminate",
];

/// A port or parameter as the info describes it.
#[derive(Debug, Clone)]
pub struct Described {
    pub name: String,
    pub description: String,
    pub unit: String,
    pub data_type: ffi::DataType,
    pub width: i32,
    /// Parameters: default, minimum, maximum (as f64), fixed.
    pub default: f64,
    pub min: f64,
    pub max: f64,
    pub fixed: bool,
    /// Byte offset in the struct this loader allocates.
    pub offset: usize,
}

/// The model info read into Rust values.
#[derive(Debug, Clone)]
pub struct ReadInfo {
    pub version: [u8; 4],
    pub name: String,
    pub description: String,
    pub general: String,
    pub step: f64,
    pub emt_rms_mode: u8,
    pub inputs: Vec<Described>,
    pub outputs: Vec<Described>,
    pub parameters: Vec<Described>,
    pub sizes: [usize; 3],
    pub int_states: usize,
    pub float_states: usize,
    pub double_states: usize,
}

/// A loaded DLL and its functions.
pub struct Library {
    handle: *mut c_void,
    get_info: GetInfo,
    first_call: Call,
    print_info: PrintInfo,
    check: Call,
    initialize: Call,
    outputs: Call,
    iterate: Call,
    terminate: Call,
    pub info: ReadInfo,
}

// SAFETY: the handle and function pointers are process-wide and immutable; the DLL's functions
// take their instance explicitly.
unsafe impl Send for Library {}
// SAFETY: as above.
unsafe impl Sync for Library {}

/// A C string (empty for null).
///
/// # Safety
/// `p` is null or a NUL-terminated string.
unsafe fn text(p: *const c_char) -> String {
    if p.is_null() {
        String::new()
    } else {
        // SAFETY: the caller's NUL-terminated string.
        unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
    }
}

/// A union value of data type `t` as f64.
///
/// # Safety
/// The union holds a value of type `t`.
unsafe fn value(t: ffi::DataType, v: ffi::MinMaxValue) -> f64 {
    // SAFETY: the caller's union holds a `t`.
    unsafe {
        match t {
            ffi::REAL64 => v.real64_val,
            ffi::REAL32 => f64::from(v.real32_val),
            ffi::INT32 => f64::from(v.int32_val),
            ffi::UINT32 => f64::from(v.uint32_val),
            ffi::INT16 => f64::from(v.int16_val),
            ffi::UINT16 => f64::from(v.uint16_val),
            ffi::INT8 => f64::from(v.int8_val),
            ffi::UINT8 => f64::from(v.uint8_val),
            _ => f64::NAN,
        }
    }
}

impl Library {
    /// Load the DLL at `path` and read its info.
    pub fn open(path: &Path) -> Result<Library, String> {
        let c = CString::new(path.to_string_lossy().as_bytes()).map_err(|e| e.to_string())?;
        // SAFETY: a NUL-terminated path; RTLD_LOCAL keeps each DLL's symbols apart.
        let handle = unsafe { libc::dlopen(c.as_ptr(), libc::RTLD_NOW | libc::RTLD_LOCAL) };
        if handle.is_null() {
            // SAFETY: dlerror returns the last error's text or null.
            let e = unsafe { text(libc::dlerror()) };
            return Err(format!("{}: {e}", path.display()));
        }
        let sym = |name: &str| -> Result<*mut c_void, String> {
            let n = CString::new(name).expect("a symbol name");
            // SAFETY: a live handle and a NUL-terminated name.
            let p = unsafe { libc::dlsym(handle, n.as_ptr()) };
            if p.is_null() {
                Err(format!("{}: no symbol {name}", path.display()))
            } else {
                Ok(p)
            }
        };
        // SAFETY: each symbol is the interface's function of that name and signature.
        let lib = unsafe {
            let get_info: GetInfo = std::mem::transmute::<*mut c_void, GetInfo>(sym(SYMBOLS[0])?);
            let call = |n: &str| -> Result<Call, String> {
                Ok(std::mem::transmute::<*mut c_void, Call>(sym(n)?))
            };
            Library {
                handle,
                get_info,
                first_call: call(SYMBOLS[1])?,
                print_info: std::mem::transmute::<*mut c_void, PrintInfo>(sym(SYMBOLS[2])?),
                check: call(SYMBOLS[3])?,
                initialize: call(SYMBOLS[4])?,
                outputs: call(SYMBOLS[5])?,
                iterate: call(SYMBOLS[6])?,
                terminate: call(SYMBOLS[7])?,
                info: read_info(get_info())?,
            }
        };
        Ok(lib)
    }

    /// `Model_PrintInfo`.
    pub fn print_info(&self) -> i32 {
        // SAFETY: the interface's function, no arguments.
        unsafe { (self.print_info)() }
    }

    /// `Model_GetInfo` again (the same pointer every time).
    pub fn info_ptr(&self) -> *const ModelInfo {
        // SAFETY: the interface's function, no arguments.
        unsafe { (self.get_info)() }
    }

    /// A new instance: its structs and arrays allocated, parameters at their defaults,
    /// `Model_FirstCall` called.
    pub fn instance(&self) -> Result<Inst<'_>, String> {
        let i = &self.info;
        let words = |bytes: usize| vec![0u64; bytes.div_ceil(8).max(1)];
        let mut inst = Inst {
            lib: self,
            raw: Box::new(Instance::unattached()),
            inputs: words(i.sizes[0]),
            outputs: words(i.sizes[1]),
            parameters: words(i.sizes[2]),
            ints: vec![0; i.int_states.max(1)],
            floats: vec![0.0; i.float_states.max(1)],
            doubles: vec![0.0; i.double_states.max(1)],
        };
        inst.point();
        for k in 0..i.parameters.len() {
            let p = &i.parameters[k];
            inst.put(2, p.data_type, p.offset, p.default);
        }
        inst.call(self.first_call, "Model_FirstCall")?;
        Ok(inst)
    }
}

impl Drop for Library {
    fn drop(&mut self) {
        // SAFETY: the handle dlopen gave; no instance outlives the library (they borrow it).
        unsafe { libc::dlclose(self.handle) };
    }
}

/// The info at `p` read into Rust values, with the C layout of the three structs.
///
/// # Safety
/// `p` is null or the DLL's model info.
unsafe fn read_info(p: *const ModelInfo) -> Result<ReadInfo, String> {
    if p.is_null() {
        return Err("Model_GetInfo returned null".into());
    }
    // SAFETY: the DLL's info, static for the library's life.
    let m = unsafe { &*p };
    let signals = |n: i32, s: *const ffi::Signal| -> Vec<Described> {
        (0..n.max(0) as usize)
            .map(|k| {
                // SAFETY: the info's array has `n` entries.
                let s = unsafe { &*s.add(k) };
                // SAFETY: the info's strings are NUL-terminated.
                unsafe {
                    Described {
                        name: text(s.name),
                        description: text(s.description),
                        unit: text(s.unit),
                        data_type: s.data_type,
                        width: s.width,
                        default: 0.0,
                        min: f64::NEG_INFINITY,
                        max: f64::INFINITY,
                        fixed: false,
                        offset: 0,
                    }
                }
            })
            .collect()
    };
    let mut inputs = signals(m.num_input_ports, m.input_ports_info);
    let mut outputs = signals(m.num_output_ports, m.output_ports_info);
    let mut parameters: Vec<Described> = (0..m.num_parameters.max(0) as usize)
        .map(|k| {
            // SAFETY: the info's array has `NumParameters` entries, its strings NUL-terminated,
            // each union holding a value of the parameter's type.
            unsafe {
                let q = &*m.parameters_info.add(k);
                let default = ffi::MinMaxValue {
                    real64_val: q.default_value.real64_val,
                };
                Described {
                    name: text(q.name),
                    description: text(q.description),
                    unit: text(q.unit),
                    data_type: q.data_type,
                    width: 1,
                    default: value(q.data_type, default),
                    min: value(q.data_type, q.min_value),
                    max: value(q.data_type, q.max_value),
                    fixed: q.fixed_value != 0,
                    offset: 0,
                }
            }
        })
        .collect();
    let mut sizes = [0; 3];
    for (k, group) in [&mut inputs, &mut outputs, &mut parameters]
        .into_iter()
        .enumerate()
    {
        if let Some(d) = group
            .iter()
            .find(|d| ffi::scalar_size(d.data_type).is_none())
        {
            return Err(format!(
                "'{}': unsupported data type {}",
                d.name, d.data_type
            ));
        }
        let (offsets, size) = ffi::c_layout(group.iter().map(|d| (d.data_type, d.width)));
        for (d, at) in group.iter_mut().zip(offsets) {
            d.offset = at;
        }
        sizes[k] = size;
    }
    // SAFETY: the info's strings are NUL-terminated.
    let (name, description, general) = unsafe {
        (
            text(m.model_name),
            text(m.model_description),
            text(m.general_information),
        )
    };
    Ok(ReadInfo {
        version: m.dll_interface_version,
        name,
        description,
        general,
        step: m.fixed_step_base_sample_time,
        emt_rms_mode: m.emt_rms_mode,
        inputs,
        outputs,
        parameters,
        sizes,
        int_states: m.num_int_states.max(0) as usize,
        float_states: m.num_float_states.max(0) as usize,
        double_states: m.num_double_states.max(0) as usize,
    })
}

/// A snapshot of an instance's state arrays, as a host saves it.
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    pub ints: Vec<i32>,
    pub floats: Vec<f32>,
    pub doubles: Vec<f64>,
}

/// One instance: the host's structs and arrays (8-byte aligned buffers) and its instance struct.
pub struct Inst<'a> {
    lib: &'a Library,
    raw: Box<Instance>,
    inputs: Vec<u64>,
    outputs: Vec<u64>,
    parameters: Vec<u64>,
    ints: Vec<i32>,
    floats: Vec<f32>,
    doubles: Vec<f64>,
}

impl Inst<'_> {
    fn point(&mut self) {
        self.raw.external_inputs = self.inputs.as_mut_ptr().cast();
        self.raw.external_outputs = self.outputs.as_mut_ptr().cast();
        self.raw.parameters = self.parameters.as_mut_ptr().cast();
        self.raw.int_states = self.ints.as_mut_ptr();
        self.raw.float_states = self.floats.as_mut_ptr();
        self.raw.double_states = self.doubles.as_mut_ptr();
    }

    fn buffer(&mut self, k: usize) -> *mut u8 {
        match k {
            0 => self.inputs.as_mut_ptr().cast(),
            1 => self.outputs.as_mut_ptr().cast(),
            _ => self.parameters.as_mut_ptr().cast(),
        }
    }

    fn put(&mut self, k: usize, t: ffi::DataType, offset: usize, x: f64) {
        let base = self.buffer(k);
        // SAFETY: `offset` is within the buffer (laid out from the info); unaligned writes.
        unsafe {
            match t {
                ffi::REAL64 => base.add(offset).cast::<f64>().write_unaligned(x),
                ffi::INT32 => base.add(offset).cast::<i32>().write_unaligned(x as i32),
                _ => panic!("data type {t} is not used by this loader"),
            }
        }
    }

    fn get(&mut self, k: usize, t: ffi::DataType, offset: usize) -> f64 {
        let base = self.buffer(k);
        // SAFETY: as in `put`.
        unsafe {
            match t {
                ffi::REAL64 => base.add(offset).cast::<f64>().read_unaligned(),
                ffi::INT32 => f64::from(base.add(offset).cast::<i32>().read_unaligned()),
                _ => panic!("data type {t} is not used by this loader"),
            }
        }
    }

    fn find(list: &[Described], name: &str) -> Result<(ffi::DataType, usize), String> {
        list.iter()
            .find(|d| d.name == name)
            .map(|d| (d.data_type, d.offset))
            .ok_or_else(|| format!("no port or parameter '{name}'"))
    }

    /// Set a parameter by its (C) name.
    pub fn set_parameter(&mut self, name: &str, x: f64) -> Result<(), String> {
        let (t, at) = Self::find(&self.lib.info.parameters, name)?;
        self.put(2, t, at, x);
        Ok(())
    }

    /// Set an input by name.
    pub fn set_input(&mut self, name: &str, x: f64) -> Result<(), String> {
        let (t, at) = Self::find(&self.lib.info.inputs, name)?;
        self.put(0, t, at, x);
        Ok(())
    }

    /// Set the inputs at `slots` (from [`Inst::slots`]) to `xs`: the per-step path.
    pub fn set_inputs(&mut self, slots: &[(ffi::DataType, usize)], xs: &[f64]) {
        for (&(t, at), &x) in slots.iter().zip(xs) {
            self.put(0, t, at, x);
        }
    }

    /// The (type, offset) of named inputs or outputs (`output`: of outputs).
    pub fn slots(
        &self,
        names: &[&str],
        output: bool,
    ) -> Result<Vec<(ffi::DataType, usize)>, String> {
        let list = if output {
            &self.lib.info.outputs
        } else {
            &self.lib.info.inputs
        };
        names.iter().map(|n| Self::find(list, n)).collect()
    }

    /// Read the outputs at `slots`.
    pub fn get_outputs(&mut self, slots: &[(ffi::DataType, usize)], out: &mut [f64]) {
        for (&(t, at), o) in slots.iter().zip(out) {
            *o = self.get(1, t, at);
        }
    }

    /// An output by name.
    pub fn output(&mut self, name: &str) -> Result<f64, String> {
        let (t, at) = Self::find(&self.lib.info.outputs, name)?;
        Ok(self.get(1, t, at))
    }

    fn call(&mut self, f: Call, what: &str) -> Result<i32, String> {
        // SAFETY: the interface's function on this instance, whose pointers are this value's
        // buffers, sized from the info.
        let r = unsafe { f(&mut *self.raw) };
        match r {
            ffi::RETURN_OK | ffi::RETURN_MESSAGE => Ok(r),
            _ => {
                // SAFETY: the DLL set the error text (or left it null).
                let e = unsafe { text(self.raw.last_error_message) };
                Err(format!("{what} returned {r}: {e}"))
            }
        }
    }

    /// The last general message.
    pub fn message(&self) -> String {
        // SAFETY: the DLL's text or null.
        unsafe { text(self.raw.last_general_message) }
    }

    pub fn check_parameters(&mut self) -> Result<i32, String> {
        self.call(self.lib.check, "Model_CheckParameters")
    }

    /// `Model_Initialize` at time `t`.
    pub fn initialize(&mut self, t: f64) -> Result<i32, String> {
        self.raw.time = t;
        self.call(self.lib.initialize, "Model_Initialize")
    }

    /// `Model_Outputs` at time `t`.
    pub fn outputs(&mut self, t: f64) -> Result<i32, String> {
        self.raw.time = t;
        self.call(self.lib.outputs, "Model_Outputs")
    }

    pub fn iterate(&mut self) -> Result<i32, String> {
        self.call(self.lib.iterate, "Model_Iterate")
    }

    /// The state arrays copied (a host's snapshot).
    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            ints: self.ints.clone(),
            floats: self.floats.clone(),
            doubles: self.doubles.clone(),
        }
    }

    /// The state arrays overwritten with a snapshot's.
    pub fn restore(&mut self, s: &Snapshot) {
        self.ints.copy_from_slice(&s.ints);
        self.floats.copy_from_slice(&s.floats);
        self.doubles.copy_from_slice(&s.doubles);
    }

    /// The instance's parameters struct copied into another instance's (same DLL).
    pub fn copy_parameters_to(&self, other: &mut Inst<'_>) {
        other.parameters.copy_from_slice(&self.parameters);
    }
}

impl Drop for Inst<'_> {
    fn drop(&mut self) {
        let terminate = self.lib.terminate;
        let _ = self.call(terminate, "Model_Terminate");
    }
}
