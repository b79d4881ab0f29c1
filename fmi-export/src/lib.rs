//! The FMI 2.0 Co-Simulation export layer, written once for every FMU of the project.
//!
//! A model implements [`Model`] (declare variables, initialize, `do_step`; its state is `serde`
//! serializable); [`export_fmu!`] emits the 34 `fmi2*` C functions for it. The layer provides the
//! state machine, logging by category, the GUID check, resource-location decoding, NaN/range
//! rejection, FMU state get/set/serialize, and panic containment on every export.

pub mod api;
pub mod describe;
pub mod ffi;
pub mod harness;
pub mod instance;
pub mod log;
pub mod model;
pub mod uri;

pub use describe::{assert_golden, describe, describe_main, Config, Experiment, CONFIG_FILE};
pub use ffi::Status;
pub use model::{
    Boolean, Context, Integer, Model, ModelError, Real, Spec, Store, Value, Variables,
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
            use $crate::{Status, Value};
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
            ) -> Status {
                api::set_debug_logging::<M>(c, on, n, cats)
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
            ) -> Status {
                api::setup_experiment::<M>(c, tol_defined, tol, start, stop_defined, stop)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2EnterInitializationMode(c: fmi2Component) -> Status {
                api::transition::<M>(c, Call::EnterInitializationMode)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2ExitInitializationMode(c: fmi2Component) -> Status {
                api::transition::<M>(c, Call::ExitInitializationMode)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Terminate(c: fmi2Component) -> Status {
                api::transition::<M>(c, Call::Terminate)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Reset(c: fmi2Component) -> Status {
                api::transition::<M>(c, Call::Reset)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetReal(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *mut f64,
            ) -> Status {
                api::get::<M, f64>(c, BaseType::Real, vr, n, v, api::read_real)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetInteger(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *mut fmi2Integer,
            ) -> Status {
                api::get::<M, fmi2Integer>(c, BaseType::Integer, vr, n, v, api::read_integer)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetBoolean(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *mut fmi2Boolean,
            ) -> Status {
                api::get::<M, fmi2Boolean>(c, BaseType::Boolean, vr, n, v, api::read_boolean)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetString(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *mut fmi2String,
            ) -> Status {
                api::get::<M, fmi2String>(c, BaseType::String, vr, n, v, api::string_out::<M>)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetReal(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *const f64,
            ) -> Status {
                api::set::<M, f64>(c, BaseType::Real, vr, n, v, |x| Some(Value::Real(x)))
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetInteger(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *const fmi2Integer,
            ) -> Status {
                api::set::<M, fmi2Integer>(c, BaseType::Integer, vr, n, v, |x| {
                    Some(Value::Integer(x))
                })
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetBoolean(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *const fmi2Boolean,
            ) -> Status {
                api::set::<M, fmi2Boolean>(c, BaseType::Boolean, vr, n, v, |x| {
                    Some(Value::Boolean(x != 0))
                })
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetString(
                c: fmi2Component,
                vr: *const u32,
                n: usize,
                v: *const fmi2String,
            ) -> Status {
                api::set::<M, fmi2String>(c, BaseType::String, vr, n, v, |x| api::string_in(x))
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetFMUstate(
                c: fmi2Component,
                s: *mut fmi2FMUstate,
            ) -> Status {
                api::get_fmu_state::<M>(c, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetFMUstate(c: fmi2Component, s: fmi2FMUstate) -> Status {
                api::set_fmu_state::<M>(c, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2FreeFMUstate(
                c: fmi2Component,
                s: *mut fmi2FMUstate,
            ) -> Status {
                api::free_fmu_state::<M>(c, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
                c: fmi2Component,
                s: fmi2FMUstate,
                size: *mut usize,
            ) -> Status {
                api::serialized_size::<M>(c, s, size)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SerializeFMUstate(
                c: fmi2Component,
                s: fmi2FMUstate,
                out: *mut fmi2Byte,
                size: usize,
            ) -> Status {
                api::serialize::<M>(c, s, out, size)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
                c: fmi2Component,
                bytes: *const fmi2Byte,
                size: usize,
                s: *mut fmi2FMUstate,
            ) -> Status {
                api::deserialize::<M>(c, bytes, size, s)
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
            ) -> Status {
                api::unsupported::<M>(c, Call::GetDirectionalDerivative)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
                c: fmi2Component,
                _vr: *const u32,
                _n: usize,
                _o: *const fmi2Integer,
                _v: *const f64,
            ) -> Status {
                api::unsupported::<M>(c, Call::SetRealInputDerivatives)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
                c: fmi2Component,
                _vr: *const u32,
                _n: usize,
                _o: *const fmi2Integer,
                _v: *mut f64,
            ) -> Status {
                api::unsupported::<M>(c, Call::GetRealOutputDerivatives)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2DoStep(
                c: fmi2Component,
                t: f64,
                h: f64,
                _no_prior: fmi2Boolean,
            ) -> Status {
                api::do_step::<M>(c, t, h)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2CancelStep(c: fmi2Component) -> Status {
                api::unsupported::<M>(c, Call::CancelStep)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetStatus(
                c: fmi2Component,
                k: fmi2StatusKind,
                v: *mut Status,
            ) -> Status {
                api::get_status::<M, Status>(c, k, v, api::read_do_step_status)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetRealStatus(
                c: fmi2Component,
                k: fmi2StatusKind,
                v: *mut f64,
            ) -> Status {
                api::get_status::<M, f64>(c, k, v, api::read_real_status)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetIntegerStatus(
                c: fmi2Component,
                k: fmi2StatusKind,
                v: *mut fmi2Integer,
            ) -> Status {
                api::get_status::<M, fmi2Integer>(c, k, v, api::read_no_status)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetBooleanStatus(
                c: fmi2Component,
                k: fmi2StatusKind,
                v: *mut fmi2Boolean,
            ) -> Status {
                api::get_status::<M, fmi2Boolean>(c, k, v, api::read_boolean_status)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetStringStatus(
                c: fmi2Component,
                k: fmi2StatusKind,
                v: *mut fmi2String,
            ) -> Status {
                api::get_status::<M, fmi2String>(c, k, v, api::read_no_status)
            }
        }
    };
}
