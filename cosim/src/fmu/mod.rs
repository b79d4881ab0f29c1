//! Loading an `.fmu`: unzip, read its modelDescription.xml, dlopen its binary, resolve the API.
//! FMUs whose binaries are identical (same `modelIdentifier`, same bytes) share one dlopen
//! ([`Library`]) and are instantiated from it many times, each with its own unpacked resources.

mod instance;
mod library;
mod load;
mod log;
pub mod trace;

pub use instance::{Instance, SavedState};
pub use library::{Library, Sharing};
pub use load::Fmu;
pub use log::LogRecord;
pub use trace::Trace;

use std::fmt;

use fmi2::Functions as Api;
pub use fmi2::Status;

/// Names of the functions every FMI 2.0 Co-Simulation binary must export.
pub const FMI2_CS_FUNCTIONS: &[&str] = Api::NAMES;

/// Why an FMU could not be loaded or used.
#[derive(Debug)]
pub struct Error(pub String);

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Error {}

fn err<T>(m: impl Into<String>) -> Result<T, Error> {
    Err(Error(m.into()))
}
