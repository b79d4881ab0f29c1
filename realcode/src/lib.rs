//! The DVPP controllers as IEEE/Cigré real-code DLLs (CIGRE TB958, API version 2): a second adapter, beside the FMU's, over the same `fmi_export::Model` and the library objects behind it.
//!
//! [`export_dll!`] emits the eight functions of the interface (`Model_GetInfo`,
//! `Model_FirstCall`, `Model_PrintInfo`, `Model_CheckParameters`, `Model_Initialize`,
//! `Model_Outputs`, `Model_Iterate`, `Model_Terminate`) for a model type; the model info is
//! built from the model's own variable declarations ([`info`]), the running state lives in
//! the host's int-state array ([`dll`]), and [`header`] writes the C headers. [`loader`] is
//! an import tool's view of such a DLL, for the tests.

pub mod dll;
pub mod ffi;
pub mod header;
pub mod info;
#[cfg(unix)]
pub mod loader;

pub use dll::{Cache, Workspace};
pub use info::{DllSpec, Info, Layout};

/// Emit the eight IEEE/Cigré DLL functions for a model type and its [`DllSpec`]. Use once per
/// cdylib.
#[macro_export]
macro_rules! export_dll {
    ($model:ty, $spec:expr) => {
        /// The IEEE/Cigré real-code DLL functions of this library (CIGRE TB958, API V2).
        #[allow(non_snake_case, clippy::missing_safety_doc)]
        pub mod tb958 {
            use super::*;
            use $crate::ffi::{Instance, ModelInfo};
            type M = $model;
            static CACHE: $crate::Cache<M> = $crate::Cache::new();

            /// The model info, built once from the model's declarations.
            pub fn info() -> Option<&'static $crate::Info> {
                static INFO: std::sync::OnceLock<Option<$crate::Info>> = std::sync::OnceLock::new();
                INFO.get_or_init(|| match $crate::Info::build::<M>(&$spec) {
                    Ok(i) => Some(i),
                    Err(e) => {
                        eprintln!("{}: {e}", <M as $crate::dll::ModelName>::identifier());
                        None
                    }
                })
                .as_ref()
            }

            /// The info, or an error if the model's declarations failed.
            fn with(f: impl FnOnce(&'static $crate::Info) -> i32) -> i32 {
                match info() {
                    Some(info) => f(info),
                    None => $crate::ffi::RETURN_ERROR,
                }
            }

            #[no_mangle]
            pub extern "C" fn Model_GetInfo() -> *const ModelInfo {
                $crate::dll::get_info(info)
            }
            #[no_mangle]
            pub extern "C" fn Model_PrintInfo() -> i32 {
                $crate::dll::print_info(info)
            }
            #[no_mangle]
            pub unsafe extern "C" fn Model_FirstCall(i: *mut Instance) -> i32 {
                // SAFETY: the host passes its instance.
                unsafe { with(|info| $crate::dll::first_call(&CACHE, info, i)) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn Model_CheckParameters(i: *mut Instance) -> i32 {
                // SAFETY: the host passes its instance.
                unsafe { with(|info| $crate::dll::check(&CACHE, info, i)) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn Model_Initialize(i: *mut Instance) -> i32 {
                // SAFETY: the host passes its instance.
                unsafe { with(|info| $crate::dll::initialize(&CACHE, info, i)) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn Model_Outputs(i: *mut Instance) -> i32 {
                // SAFETY: the host passes its instance.
                unsafe { with(|info| $crate::dll::outputs(&CACHE, info, i)) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn Model_Iterate(i: *mut Instance) -> i32 {
                // SAFETY: the host passes its instance.
                unsafe { with(|info| $crate::dll::iterate(&CACHE, info, i)) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn Model_Terminate(i: *mut Instance) -> i32 {
                // SAFETY: the host passes its instance.
                unsafe { $crate::dll::terminate(&CACHE, i) }
            }
        }
    };
}

/// A DLL's describe program: `DESCRIBE DIR` writes into `DIR` the interface header, the
/// model's header `<identifier>.h`, and for each of `presets` the preset's parameter set
/// `<identifier>.<preset>.params` (its defaults, declared as the FMU with `[model] preset`).
pub fn describe_main<M: fmi_export::Model>(spec: &DllSpec, presets: &[&str]) {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [dir] = args.as_slice() else {
        eprintln!(
            "usage: describe DIR\nwrites IEEE_Cigre_DLLInterface.h, {id}.h and the preset parameter sets of the DLL {id} into DIR",
            id = M::IDENTIFIER
        );
        std::process::exit(2);
    };
    if let Err(e) = describe::<M>(spec, presets, std::path::Path::new(dir)) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

/// The files of [`describe_main`] written into `dir`.
pub fn describe<M: fmi_export::Model>(
    spec: &DllSpec,
    presets: &[&str],
    dir: &std::path::Path,
) -> Result<(), String> {
    let write = |name: String, text: &str| {
        std::fs::write(dir.join(&name), text)
            .map_err(|e| format!("{}: {e}", dir.join(name).display()))
    };
    let layout = Layout::of::<M>(spec)?;
    write("IEEE_Cigre_DLLInterface.h".into(), header::INTERFACE_HEADER)?;
    write(
        format!("{}.h", M::IDENTIFIER),
        &header::model_header(&layout),
    )?;
    for preset in presets {
        let config = format!("[model]\npreset = \"{preset}\"\n");
        let leaked: &'static str = Box::leak(config.into_boxed_str());
        let l = Layout::of::<M>(&DllSpec {
            config: leaked,
            ..*spec
        })?;
        if l.digest != layout.digest {
            return Err(format!(
                "preset {preset}: its variables differ from the DLL's (a preset needs its own DLL)"
            ));
        }
        write(
            format!("{}.{preset}.params", M::IDENTIFIER),
            &header::parameter_set(&l),
        )?;
    }
    Ok(())
}
