//! A table of C functions bound from a dlopen'ed library (FMU binaries, libhelics), declared once.

/// `dl_api!(/// doc; "missing {}"; field: "symbol" => fn(args) -> ret; ...)` declares a private
/// `struct Api` of the listed functions, its `NAMES` and an `unsafe fn resolve(handle)` that
/// looks every symbol up and names the first missing one with the given message.
macro_rules! dl_api {
    ($(#[$doc:meta])* $missing:literal; $($field:ident : $name:literal => fn($($arg:ty),*) $(-> $ret:ty)?;)*) => {
        $(#[$doc])*
        #[allow(non_snake_case)]
        struct Api { $($field: unsafe extern "C" fn($($arg),*) $(-> $ret)?,)* }

        impl Api {
            /// The symbols, in declaration order.
            #[allow(dead_code)]
            const NAMES: &'static [&'static str] = &[$($name),*];

            /// Resolve every function; the first missing one is named.
            ///
            /// # Safety
            /// `lib` is a live handle from `dlopen` whose symbols of these names have these
            /// C signatures.
            unsafe fn resolve(lib: *mut std::ffi::c_void) -> Result<Api, String> {
                Ok(Api { $($field: {
                    // SAFETY: a live handle and a NUL-terminated name.
                    let sym = unsafe {
                        libc::dlsym(lib, concat!($name, "\0").as_ptr() as *const std::ffi::c_char)
                    };
                    if sym.is_null() {
                        return Err(format!($missing, $name));
                    }
                    // SAFETY: a non-null symbol of this name has this signature (the caller's
                    // contract).
                    unsafe {
                        std::mem::transmute::<*mut std::ffi::c_void, unsafe extern "C" fn($($arg),*) $(-> $ret)?>(sym)
                    }
                },)* })
            }
        }
    };
}

pub(crate) use dl_api;
