//! The FMI 2.0 Co-Simulation export layer, written once for every FMU of the project.
//!
//! A model implements [`Model`] (declare variables, initialize, `do_step`; its state is `serde`
//! serializable); [`export_fmu!`] emits the 34 `fmi2*` C functions for it. The layer provides the
//! state machine, logging by category, the GUID check, resource-location decoding, NaN/range
//! rejection, FMU state get/set/serialize, and panic containment on every export.

pub mod api;
pub mod describe;
pub mod harness;
pub mod instance;
pub mod log;
pub mod model;
pub mod uri;

/// The FMI 2.0 C ABI the exported functions have (the [`fmi2`] crate, shared with the master).
pub use fmi2 as ffi;

pub use describe::{
    assert_golden, describe, describe_main, read_resource, Config, Experiment, CONFIG_FILE,
    MAX_RESOURCE_BYTES,
};
pub use ffi::Status;
pub use model::{
    Boolean, Context, Integer, Model, ModelError, Real, Spec, Store, Value, Variables,
    MAX_MAGNITUDE,
};
pub use model_description;

/// Emit the 34 FMI 2.0 Co-Simulation functions for a [`Model`] type. Use once per cdylib.
#[macro_export]
macro_rules! export_fmu {
    ($model:ty) => {
        /// The FMI 2.0 Co-Simulation C API of this FMU (FMI 2.0 standard, section 2.1 and 4.2).
        #[allow(non_snake_case, clippy::missing_safety_doc)]
        pub mod fmi2 {
            use super::*;
            use $crate::api;
            use $crate::ffi::*;
            use $crate::instance::Call;
            use $crate::model_description::BaseType;
            use $crate::Value;
            type M = $model;

            #[no_mangle]
            pub extern "C" fn fmi2GetTypesPlatform() -> fmi2String {
                api::static_string(c"default")
            }
            #[no_mangle]
            pub extern "C" fn fmi2GetVersion() -> fmi2String {
                api::static_string(c"2.0")
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetDebugLogging(
                c: fmi2Component,
                on: fmi2Boolean,
                n: usize,
                cats: *const fmi2String,
            ) -> fmi2Status {
                api::set_debug_logging::<M>(c, on, n, cats).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Instantiate(
                name: fmi2String,
                ty: fmi2Type,
                guid: fmi2String,
                res: fmi2String,
                f: *const fmi2CallbackFunctions,
                visible: fmi2Boolean,
                logging: fmi2Boolean,
            ) -> fmi2Component {
                api::instantiate::<M>(name, ty, guid, res, f, visible, logging)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2FreeInstance(c: fmi2Component) {
                api::free_instance::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetupExperiment(
                c: fmi2Component,
                tol_defined: fmi2Boolean,
                tol: f64,
                start: f64,
                stop_defined: fmi2Boolean,
                stop: f64,
            ) -> fmi2Status {
                api::setup_experiment::<M>(c, tol_defined, tol, start, stop_defined, stop).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2EnterInitializationMode(c: fmi2Component) -> fmi2Status {
                api::transition::<M>(c, Call::EnterInitializationMode).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2ExitInitializationMode(c: fmi2Component) -> fmi2Status {
                api::transition::<M>(c, Call::ExitInitializationMode).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Terminate(c: fmi2Component) -> fmi2Status {
                api::transition::<M>(c, Call::Terminate).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Reset(c: fmi2Component) -> fmi2Status {
                api::transition::<M>(c, Call::Reset).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetReal(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *mut f64,
            ) -> fmi2Status {
                api::get::<M, f64>(c, BaseType::Real, vr, n, v, api::read_real).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetInteger(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *mut fmi2Integer,
            ) -> fmi2Status {
                api::get::<M, fmi2Integer>(c, BaseType::Integer, vr, n, v, api::read_integer).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetBoolean(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *mut fmi2Boolean,
            ) -> fmi2Status {
                api::get::<M, fmi2Boolean>(c, BaseType::Boolean, vr, n, v, api::read_boolean).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetString(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *mut fmi2String,
            ) -> fmi2Status {
                api::get::<M, fmi2String>(c, BaseType::String, vr, n, v, api::string_out::<M>)
                    .into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetReal(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *const f64,
            ) -> fmi2Status {
                api::set::<M, f64>(c, BaseType::Real, vr, n, v, |x| Some(Value::Real(x))).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetInteger(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *const fmi2Integer,
            ) -> fmi2Status {
                api::set::<M, fmi2Integer>(c, BaseType::Integer, vr, n, v, |x| {
                    Some(Value::Integer(x))
                })
                .into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetBoolean(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *const fmi2Boolean,
            ) -> fmi2Status {
                api::set::<M, fmi2Boolean>(c, BaseType::Boolean, vr, n, v, |x| {
                    Some(Value::Boolean(x != 0))
                })
                .into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetString(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *const fmi2String,
            ) -> fmi2Status {
                api::set::<M, fmi2String>(c, BaseType::String, vr, n, v, |x| api::string_in(x))
                    .into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetFMUstate(
                c: fmi2Component,
                s: *mut fmi2FMUstate,
            ) -> fmi2Status {
                api::get_fmu_state::<M>(c, s).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetFMUstate(
                c: fmi2Component,
                s: fmi2FMUstate,
            ) -> fmi2Status {
                api::set_fmu_state::<M>(c, s).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2FreeFMUstate(
                c: fmi2Component,
                s: *mut fmi2FMUstate,
            ) -> fmi2Status {
                api::free_fmu_state::<M>(c, s).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
                c: fmi2Component,
                s: fmi2FMUstate,
                size: *mut usize,
            ) -> fmi2Status {
                api::serialized_size::<M>(c, s, size).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SerializeFMUstate(
                c: fmi2Component,
                s: fmi2FMUstate,
                out: *mut fmi2Byte,
                size: usize,
            ) -> fmi2Status {
                api::serialize::<M>(c, s, out, size).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
                c: fmi2Component,
                bytes: *const fmi2Byte,
                size: usize,
                s: *mut fmi2FMUstate,
            ) -> fmi2Status {
                api::deserialize::<M>(c, bytes, size, s).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
                c: fmi2Component,
                _u: *const u32,
                _nu: usize,
                _k: *const u32,
                _nk: usize,
                _dk: *const f64,
                _du: *mut f64,
            ) -> fmi2Status {
                api::unsupported::<M>(c, Call::GetDirectionalDerivative).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
                c: fmi2Component,
                _vr: *const u32,
                _n: usize,
                _o: *const fmi2Integer,
                _v: *const f64,
            ) -> fmi2Status {
                api::unsupported::<M>(c, Call::SetRealInputDerivatives).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
                c: fmi2Component,
                _vr: *const u32,
                _n: usize,
                _o: *const fmi2Integer,
                _v: *mut f64,
            ) -> fmi2Status {
                api::unsupported::<M>(c, Call::GetRealOutputDerivatives).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2DoStep(
                c: fmi2Component,
                t: f64,
                h: f64,
                _no_prior: fmi2Boolean,
            ) -> fmi2Status {
                api::do_step::<M>(c, t, h).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2CancelStep(c: fmi2Component) -> fmi2Status {
                api::unsupported::<M>(c, Call::CancelStep).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetStatus(
                c: fmi2Component,
                k: fmi2StatusKind,
                v: *mut fmi2Status,
            ) -> fmi2Status {
                api::get_status::<M, fmi2Status>(c, k, v, api::read_do_step_status).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetRealStatus(
                c: fmi2Component,
                k: fmi2StatusKind,
                v: *mut f64,
            ) -> fmi2Status {
                api::get_status::<M, f64>(c, k, v, api::read_real_status).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetIntegerStatus(
                c: fmi2Component,
                k: fmi2StatusKind,
                v: *mut fmi2Integer,
            ) -> fmi2Status {
                api::get_status::<M, fmi2Integer>(c, k, v, api::read_no_status).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetBooleanStatus(
                c: fmi2Component,
                k: fmi2StatusKind,
                v: *mut fmi2Boolean,
            ) -> fmi2Status {
                api::get_status::<M, fmi2Boolean>(c, k, v, api::read_boolean_status).into()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetStringStatus(
                c: fmi2Component,
                k: fmi2StatusKind,
                v: *mut fmi2String,
            ) -> fmi2Status {
                api::get_status::<M, fmi2String>(c, k, v, api::read_no_status).into()
            }

            // Each export has exactly the type the ABI gives it (the importer calls through it).
            const _: fmi2GetTypesPlatformTYPE = fmi2GetTypesPlatform;
            const _: fmi2GetVersionTYPE = fmi2GetVersion;
            const _: fmi2SetDebugLoggingTYPE = fmi2SetDebugLogging;
            const _: fmi2InstantiateTYPE = fmi2Instantiate;
            const _: fmi2FreeInstanceTYPE = fmi2FreeInstance;
            const _: fmi2SetupExperimentTYPE = fmi2SetupExperiment;
            const _: fmi2EnterInitializationModeTYPE = fmi2EnterInitializationMode;
            const _: fmi2ExitInitializationModeTYPE = fmi2ExitInitializationMode;
            const _: fmi2TerminateTYPE = fmi2Terminate;
            const _: fmi2ResetTYPE = fmi2Reset;
            const _: fmi2GetRealTYPE = fmi2GetReal;
            const _: fmi2GetIntegerTYPE = fmi2GetInteger;
            const _: fmi2GetBooleanTYPE = fmi2GetBoolean;
            const _: fmi2GetStringTYPE = fmi2GetString;
            const _: fmi2SetRealTYPE = fmi2SetReal;
            const _: fmi2SetIntegerTYPE = fmi2SetInteger;
            const _: fmi2SetBooleanTYPE = fmi2SetBoolean;
            const _: fmi2SetStringTYPE = fmi2SetString;
            const _: fmi2GetFMUstateTYPE = fmi2GetFMUstate;
            const _: fmi2SetFMUstateTYPE = fmi2SetFMUstate;
            const _: fmi2FreeFMUstateTYPE = fmi2FreeFMUstate;
            const _: fmi2SerializedFMUstateSizeTYPE = fmi2SerializedFMUstateSize;
            const _: fmi2SerializeFMUstateTYPE = fmi2SerializeFMUstate;
            const _: fmi2DeSerializeFMUstateTYPE = fmi2DeSerializeFMUstate;
            const _: fmi2GetDirectionalDerivativeTYPE = fmi2GetDirectionalDerivative;
            const _: fmi2SetRealInputDerivativesTYPE = fmi2SetRealInputDerivatives;
            const _: fmi2GetRealOutputDerivativesTYPE = fmi2GetRealOutputDerivatives;
            const _: fmi2DoStepTYPE = fmi2DoStep;
            const _: fmi2CancelStepTYPE = fmi2CancelStep;
            const _: fmi2GetStatusTYPE = fmi2GetStatus;
            const _: fmi2GetRealStatusTYPE = fmi2GetRealStatus;
            const _: fmi2GetIntegerStatusTYPE = fmi2GetIntegerStatus;
            const _: fmi2GetBooleanStatusTYPE = fmi2GetBooleanStatus;
            const _: fmi2GetStringStatusTYPE = fmi2GetStringStatus;
        }
    };
}
