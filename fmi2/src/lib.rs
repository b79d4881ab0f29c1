//! The FMI 2.0 Co-Simulation C ABI, defined once for the exporter and the importer.
//!
//! The platform types and callbacks of `fmi2TypesPlatform.h` and `fmi2FunctionTypes.h`, the 34
//! function types of a Co-Simulation binary ([`fmi2DoStepTYPE`], ...) and [`Functions`], the
//! table of them that a master resolves from a loaded binary. `fmi_export::export_fmu!` checks
//! at compile time that every function it exports has exactly its type here; the master's
//! loader calls FMUs through the same types. The C header of the same ABI
//! (`include/fmi2.h`, for the master's C logger shim and the C test FMUs) is checked against
//! this crate's layout by `_Static_assert`s in the shim.
//!
//! `fmi2Status` is a C `int` at the boundary, not a Rust enum: a foreign FMU may return any
//! integer, and reading one outside the enum's range would be undefined behaviour. [`Status`]
//! is the checked view of it.

#![allow(non_camel_case_types)]

use std::ffi::{c_char, c_int, c_void, CStr};

pub type fmi2Component = *mut c_void;
pub type fmi2ComponentEnvironment = *mut c_void;
pub type fmi2FMUstate = *mut c_void;
pub type fmi2ValueReference = u32;
pub type fmi2Real = f64;
pub type fmi2Integer = c_int;
pub type fmi2Boolean = c_int;
pub type fmi2Char = c_char;
pub type fmi2String = *const c_char;
pub type fmi2Byte = c_char;
pub type fmi2Type = c_int;
pub type fmi2StatusKind = c_int;
/// A C `enum fmi2Status`, as an FMU returns it: see [`Status`].
pub type fmi2Status = c_int;

pub const FMI2_TRUE: fmi2Boolean = 1;
pub const FMI2_FALSE: fmi2Boolean = 0;
pub const FMI2_MODEL_EXCHANGE: fmi2Type = 0;
pub const FMI2_COSIMULATION: fmi2Type = 1;

pub const FMI2_DO_STEP_STATUS: fmi2StatusKind = 0;
pub const FMI2_PENDING_STATUS: fmi2StatusKind = 1;
pub const FMI2_LAST_SUCCESSFUL_TIME: fmi2StatusKind = 2;
pub const FMI2_TERMINATED: fmi2StatusKind = 3;

/// `fmi2Status`, ordered by severity so that escalation is `max`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Status {
    Ok = 0,
    Warning = 1,
    Discard = 2,
    Error = 3,
    Fatal = 4,
    Pending = 5,
}

impl Status {
    /// The status an FMU returned; a value outside the standard's six is taken as
    /// [`Status::Fatal`] (the FMU broke the ABI, nothing it did can be trusted).
    pub fn from_c(s: fmi2Status) -> Status {
        match s {
            0 => Status::Ok,
            1 => Status::Warning,
            2 => Status::Discard,
            3 => Status::Error,
            5 => Status::Pending,
            _ => Status::Fatal,
        }
    }
}

impl From<Status> for fmi2Status {
    fn from(s: Status) -> fmi2Status {
        s as fmi2Status
    }
}

/// So that a status returned through the C types compares with [`Status`] directly.
impl PartialEq<Status> for fmi2Status {
    fn eq(&self, other: &Status) -> bool {
        *self == *other as fmi2Status
    }
}

impl PartialEq<fmi2Status> for Status {
    fn eq(&self, other: &fmi2Status) -> bool {
        *self as fmi2Status == *other
    }
}

/// The logger's function type: C-variadic, the message a printf format of the arguments that
/// follow.
pub type fmi2CallbackLoggerTYPE = unsafe extern "C" fn(
    fmi2ComponentEnvironment,
    fmi2String,
    fmi2Status,
    fmi2String,
    fmi2String,
    ...
);
/// `fmi2CallbackLogger` (nullable).
pub type fmi2CallbackLogger = Option<fmi2CallbackLoggerTYPE>;
pub type fmi2CallbackAllocateMemory = Option<unsafe extern "C" fn(usize, usize) -> *mut c_void>;
pub type fmi2CallbackFreeMemory = Option<unsafe extern "C" fn(*mut c_void)>;
pub type fmi2StepFinished = Option<unsafe extern "C" fn(fmi2ComponentEnvironment, fmi2Status)>;

/// `fmi2CallbackFunctions`.
#[repr(C)]
pub struct fmi2CallbackFunctions {
    pub logger: fmi2CallbackLogger,
    pub allocate_memory: fmi2CallbackAllocateMemory,
    pub free_memory: fmi2CallbackFreeMemory,
    pub step_finished: fmi2StepFinished,
    pub component_environment: fmi2ComponentEnvironment,
}

// The C header's `_Static_assert`s state the same layout.
const _: () = assert!(std::mem::size_of::<fmi2CallbackFunctions>() == 5 * size_of::<usize>());
const _: () = assert!(size_of::<Status>() == size_of::<fmi2Status>());

/// Declares each function type (`fmi2<Name>TYPE`, as `fmi2FunctionTypes.h` names them),
/// [`Functions`] with one field of each, and [`Functions::NAMES`].
macro_rules! functions {
    ($($field:ident: $name:ident, $ty:ident = fn($($arg:ty),*) $(-> $ret:ty)?;)*) => {
        $(
            #[doc = concat!("The type of `", stringify!($name), "`.")]
            pub type $ty = unsafe extern "C" fn($($arg),*) $(-> $ret)?;
        )*

        /// The 34 functions of an FMI 2.0 Co-Simulation binary, resolved by [`Functions::resolve`].
        #[derive(Clone, Copy)]
        pub struct Functions {
            $(#[doc = concat!("`", stringify!($name), "`")] pub $field: $ty,)*
        }

        impl Functions {
            /// The exported names, in the order of the fields.
            pub const NAMES: &'static [&'static str] = &[$(stringify!($name)),*];

            /// Look every function up with `lookup` (e.g. `dlsym` on a loaded binary); the
            /// first one it does not find is returned as the error.
            ///
            /// # Safety
            /// A non-null address `lookup` returns for a name is a function of that name's C
            /// signature in FMI 2.0, and stays valid while the [`Functions`] are used.
            pub unsafe fn resolve(
                mut lookup: impl FnMut(&CStr) -> *mut c_void,
            ) -> Result<Functions, &'static str> {
                Ok(Functions { $($field: {
                    let name = concat!(stringify!($name), "\0");
                    let c = CStr::from_bytes_with_nul(name.as_bytes()).expect("a C name");
                    let sym = lookup(c);
                    if sym.is_null() {
                        return Err(stringify!($name));
                    }
                    // SAFETY: a non-null address of this name has this signature (the
                    // caller's contract).
                    unsafe { std::mem::transmute::<*mut c_void, $ty>(sym) }
                },)* })
            }
        }
    };
}

functions! {
    get_types_platform: fmi2GetTypesPlatform, fmi2GetTypesPlatformTYPE = fn() -> fmi2String;
    get_version: fmi2GetVersion, fmi2GetVersionTYPE = fn() -> fmi2String;
    set_debug_logging: fmi2SetDebugLogging, fmi2SetDebugLoggingTYPE =
        fn(fmi2Component, fmi2Boolean, usize, *const fmi2String) -> fmi2Status;
    instantiate: fmi2Instantiate, fmi2InstantiateTYPE = fn(
        fmi2String,
        fmi2Type,
        fmi2String,
        fmi2String,
        *const fmi2CallbackFunctions,
        fmi2Boolean,
        fmi2Boolean
    ) -> fmi2Component;
    free_instance: fmi2FreeInstance, fmi2FreeInstanceTYPE = fn(fmi2Component);
    setup_experiment: fmi2SetupExperiment, fmi2SetupExperimentTYPE =
        fn(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real) -> fmi2Status;
    enter_initialization_mode: fmi2EnterInitializationMode, fmi2EnterInitializationModeTYPE =
        fn(fmi2Component) -> fmi2Status;
    exit_initialization_mode: fmi2ExitInitializationMode, fmi2ExitInitializationModeTYPE =
        fn(fmi2Component) -> fmi2Status;
    terminate: fmi2Terminate, fmi2TerminateTYPE = fn(fmi2Component) -> fmi2Status;
    reset: fmi2Reset, fmi2ResetTYPE = fn(fmi2Component) -> fmi2Status;
    get_real: fmi2GetReal, fmi2GetRealTYPE =
        fn(fmi2Component, *const fmi2ValueReference, usize, *mut fmi2Real) -> fmi2Status;
    get_integer: fmi2GetInteger, fmi2GetIntegerTYPE =
        fn(fmi2Component, *const fmi2ValueReference, usize, *mut fmi2Integer) -> fmi2Status;
    get_boolean: fmi2GetBoolean, fmi2GetBooleanTYPE =
        fn(fmi2Component, *const fmi2ValueReference, usize, *mut fmi2Boolean) -> fmi2Status;
    get_string: fmi2GetString, fmi2GetStringTYPE =
        fn(fmi2Component, *const fmi2ValueReference, usize, *mut fmi2String) -> fmi2Status;
    set_real: fmi2SetReal, fmi2SetRealTYPE =
        fn(fmi2Component, *const fmi2ValueReference, usize, *const fmi2Real) -> fmi2Status;
    set_integer: fmi2SetInteger, fmi2SetIntegerTYPE =
        fn(fmi2Component, *const fmi2ValueReference, usize, *const fmi2Integer) -> fmi2Status;
    set_boolean: fmi2SetBoolean, fmi2SetBooleanTYPE =
        fn(fmi2Component, *const fmi2ValueReference, usize, *const fmi2Boolean) -> fmi2Status;
    set_string: fmi2SetString, fmi2SetStringTYPE =
        fn(fmi2Component, *const fmi2ValueReference, usize, *const fmi2String) -> fmi2Status;
    get_fmu_state: fmi2GetFMUstate, fmi2GetFMUstateTYPE =
        fn(fmi2Component, *mut fmi2FMUstate) -> fmi2Status;
    set_fmu_state: fmi2SetFMUstate, fmi2SetFMUstateTYPE =
        fn(fmi2Component, fmi2FMUstate) -> fmi2Status;
    free_fmu_state: fmi2FreeFMUstate, fmi2FreeFMUstateTYPE =
        fn(fmi2Component, *mut fmi2FMUstate) -> fmi2Status;
    serialized_fmu_state_size: fmi2SerializedFMUstateSize, fmi2SerializedFMUstateSizeTYPE =
        fn(fmi2Component, fmi2FMUstate, *mut usize) -> fmi2Status;
    serialize_fmu_state: fmi2SerializeFMUstate, fmi2SerializeFMUstateTYPE =
        fn(fmi2Component, fmi2FMUstate, *mut fmi2Byte, usize) -> fmi2Status;
    deserialize_fmu_state: fmi2DeSerializeFMUstate, fmi2DeSerializeFMUstateTYPE =
        fn(fmi2Component, *const fmi2Byte, usize, *mut fmi2FMUstate) -> fmi2Status;
    get_directional_derivative: fmi2GetDirectionalDerivative, fmi2GetDirectionalDerivativeTYPE = fn(
        fmi2Component,
        *const fmi2ValueReference,
        usize,
        *const fmi2ValueReference,
        usize,
        *const fmi2Real,
        *mut fmi2Real
    ) -> fmi2Status;
    set_real_input_derivatives: fmi2SetRealInputDerivatives, fmi2SetRealInputDerivativesTYPE = fn(
        fmi2Component,
        *const fmi2ValueReference,
        usize,
        *const fmi2Integer,
        *const fmi2Real
    ) -> fmi2Status;
    get_real_output_derivatives: fmi2GetRealOutputDerivatives, fmi2GetRealOutputDerivativesTYPE = fn(
        fmi2Component,
        *const fmi2ValueReference,
        usize,
        *const fmi2Integer,
        *mut fmi2Real
    ) -> fmi2Status;
    do_step: fmi2DoStep, fmi2DoStepTYPE =
        fn(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean) -> fmi2Status;
    cancel_step: fmi2CancelStep, fmi2CancelStepTYPE = fn(fmi2Component) -> fmi2Status;
    get_status: fmi2GetStatus, fmi2GetStatusTYPE =
        fn(fmi2Component, fmi2StatusKind, *mut fmi2Status) -> fmi2Status;
    get_real_status: fmi2GetRealStatus, fmi2GetRealStatusTYPE =
        fn(fmi2Component, fmi2StatusKind, *mut fmi2Real) -> fmi2Status;
    get_integer_status: fmi2GetIntegerStatus, fmi2GetIntegerStatusTYPE =
        fn(fmi2Component, fmi2StatusKind, *mut fmi2Integer) -> fmi2Status;
    get_boolean_status: fmi2GetBooleanStatus, fmi2GetBooleanStatusTYPE =
        fn(fmi2Component, fmi2StatusKind, *mut fmi2Boolean) -> fmi2Status;
    get_string_status: fmi2GetStringStatus, fmi2GetStringStatusTYPE =
        fn(fmi2Component, fmi2StatusKind, *mut fmi2String) -> fmi2Status;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thirty_four_distinct_functions() {
        let mut names = Functions::NAMES.to_vec();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), 34);
        assert!(names.iter().all(|n| n.starts_with("fmi2")));
    }

    #[test]
    fn a_status_outside_the_standard_is_fatal() {
        for s in [
            Status::Ok,
            Status::Warning,
            Status::Discard,
            Status::Error,
            Status::Fatal,
            Status::Pending,
        ] {
            assert_eq!(Status::from_c(s.into()), s);
            assert!(fmi2Status::from(s) == s);
        }
        assert_eq!(Status::from_c(6), Status::Fatal);
        assert_eq!(Status::from_c(-1), Status::Fatal);
    }

    #[test]
    fn a_missing_function_is_named() {
        // SAFETY: the lookup returns no address, so nothing is transmuted.
        let missing = unsafe { Functions::resolve(|_| std::ptr::null_mut()) };
        assert_eq!(missing.err(), Some("fmi2GetTypesPlatform"));
    }
}
