//! What can go wrong in a run, naming the unit, connection, file or time it concerns.

use std::fmt;

/// What went wrong, naming the unit, element or file.
#[derive(Debug, Clone, PartialEq)]
pub struct Error(pub String);

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Error {}

impl From<crate::ssp::Error> for Error {
    fn from(e: crate::ssp::Error) -> Self {
        Error(e.to_string())
    }
}
