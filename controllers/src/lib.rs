//! The DVPP controllers as host-independent library objects: typed parameters (validated, an
//! error names the field), typed measurements and commands, `initialize` and `step`; the FMUs
//! and any other host are adapters around them.
//!
//! * [`layer`]: the DVPP layer every DER controller runs (reference models, the operator's dc
//!   gains, set point, grid-forming angle, voltage matching), with [`adpf`] (an ADPF's typed
//!   parameters) and the codes [`Mode`], [`AdpfKind`].
//! * [`operator`]: the DVPP operator (online ADPF dc gains, the desired aggregate response).
//!
//! Nothing here knows a host: errors are [`Error`] (naming the parameter or input as the FMUs
//! name it), warnings and events are [`Notice`]s the host logs as it logs anything.

pub mod adpf;
mod codes;
pub mod dc;
pub mod emt;
pub mod layer;
pub mod operator;
pub mod phasor;
pub mod unit;

pub use adpf::{AdpfChannel, AdpfParams, ComplementParams};
pub use codes::{AdpfKind, Mode};
pub use unit::{DcLinkParams, OperatorGains, PllParams, Rating, SourceParams};

use serde::{Deserialize, Serialize};
use std::fmt;

/// Most low-pass units a complement unit can close (`mu_p_lpf[1..8]`).
pub const MAX_LPF: usize = 8;

/// Why a controller refuses its parameters or a step: the parameter or input at fault (as the
/// FMUs name it, e.g. `adpf.p.tau`) and why, or a failure of the running unit.
#[derive(Debug, Clone, PartialEq)]
pub struct Error {
    /// The parameter or input at fault; none for a failure of the running unit (a trip).
    pub field: Option<String>,
    /// Why: `= value: reason`, or the reason alone.
    pub message: String,
}

impl Error {
    /// An error naming the parameter (or input) at fault: shown as `'name' = value: why` or
    /// `'name': why`.
    pub fn field(name: &str, message: impl fmt::Display) -> Error {
        Error {
            field: Some(name.to_string()),
            message: message.to_string(),
        }
    }

    /// A failure of the running unit, not of one parameter.
    pub fn unit(message: impl fmt::Display) -> Error {
        Error {
            field: None,
            message: message.to_string(),
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.field {
            Some(name) => {
                let sep = if self.message.starts_with('=') {
                    " "
                } else {
                    ": "
                };
                write!(f, "'{name}'{sep}{}", self.message)
            }
            None => f.write_str(&self.message),
        }
    }
}

impl std::error::Error for Error {}

/// Its text, `'name' = value: why`: what a host that reports errors as text (an FMU) shows.
impl From<Error> for String {
    fn from(e: Error) -> String {
        e.to_string()
    }
}

/// What a controller tells its host besides its outputs: the host logs a warning as a warning
/// and an event as information (the FMUs through their logger).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Notice {
    /// Something the host's user should know: the controller changed what it was given.
    Warning(String),
    /// Something that happened as asked (a retuning, a design's figures).
    Event(String),
}

/// `x` if it is a positive, finite, normal number, else an error naming `name`.
pub fn positive(x: f64, name: &str) -> Result<f64, Error> {
    if x > 0.0 && x.is_finite() && x.is_normal() {
        Ok(x)
    } else if x > 0.0 && x.is_finite() {
        Err(Error::field(
            name,
            format!(
                "= {x:e}: must be > 0 and not subnormal (at least {:e})",
                f64::MIN_POSITIVE
            ),
        ))
    } else {
        Err(Error::field(name, format!("= {x}: must be > 0")))
    }
}
