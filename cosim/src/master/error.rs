//! What can go wrong in a run, as a type: loading, connections, parameters, the experiment, a
//! step or an FMU call, each naming the unit, connection, file or time it concerns.

use crate::fmu::Status;
use std::fmt;

/// What went wrong, naming the unit, element, file or time.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// A system, component or FMU that cannot be read, unpacked, loaded or instantiated, or a
    /// connector the FMU does not have as the SSD declares it.
    Load(String),
    /// A connection the FMUs cannot carry (unknown element, types or causality that differ).
    Connection(String),
    /// A parameter binding that cannot be applied to its variable.
    Parameter(String),
    /// An experiment that cannot run: no stop time or step size, or times out of range.
    Experiment(String),
    /// An FMI call of a unit returned more than a warning.
    Fmu {
        /// The component.
        unit: String,
        /// The call, as the FMI names it (`fmi2DoStep(0.1, 0.001)`, `setting parameter 'k'`).
        call: String,
        status: Status,
        /// The unit's last log message before the failure, if any.
        log: Option<String>,
    },
    /// Initialization failed (experiment setup, parameters or the settling exchanges).
    Initialization(Box<Error>),
    /// A communication step failed: its start and end, s, and the algorithm stepping.
    Step {
        from: f64,
        to: f64,
        algorithm: Option<String>,
        cause: Box<Error>,
    },
    /// An algorithm that cannot run this system or with these settings.
    Algorithm(String),
    /// The results cannot be recorded (a file, an observer).
    Output(String),
    /// A federation: libhelics, the broker, the federates and their rounds.
    Federation(String),
    /// The run itself (threads, signals).
    Run(String),
}

impl Error {
    /// The failure at the root of an [`Error::Initialization`] or [`Error::Step`].
    pub fn cause(&self) -> &Error {
        match self {
            Error::Initialization(e) | Error::Step { cause: e, .. } => e.cause(),
            e => e,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Load(m)
            | Error::Connection(m)
            | Error::Parameter(m)
            | Error::Experiment(m)
            | Error::Algorithm(m)
            | Error::Output(m)
            | Error::Federation(m)
            | Error::Run(m) => f.write_str(m),
            Error::Fmu {
                unit,
                call,
                status,
                log,
            } => {
                write!(f, "component '{unit}': {call} returned {status:?}")?;
                if *status == Status::Discard {
                    f.write_str(" (the master cannot repeat a rejected step)")?;
                }
                if let Some(m) = log {
                    write!(f, ": {m}")?;
                }
                Ok(())
            }
            Error::Initialization(e) => write!(f, "during initialization: {e}"),
            Error::Step {
                from,
                to,
                algorithm,
                cause,
            } => {
                write!(f, "in the communication step from t = {from} s to {to} s")?;
                if let Some(a) = algorithm {
                    write!(f, " ({a})")?;
                }
                write!(f, ": {cause}")
            }
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Initialization(e) | Error::Step { cause: e, .. } => Some(&**e),
            _ => None,
        }
    }
}

impl From<crate::ssp::Error> for Error {
    fn from(e: crate::ssp::Error) -> Self {
        Error::Load(e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_fmu_failure_names_the_unit_the_call_and_the_last_message() {
        let e = Error::Fmu {
            unit: "grid".into(),
            call: "fmi2DoStep(0.1, 0.001)".into(),
            status: Status::Discard,
            log: Some("voltage collapse".into()),
        };
        let step = Error::Step {
            from: 0.1,
            to: 0.101,
            algorithm: Some("jacobi".into()),
            cause: Box::new(e.clone()),
        };
        assert_eq!(
            step.to_string(),
            "in the communication step from t = 0.1 s to 0.101 s (jacobi): component 'grid': \
             fmi2DoStep(0.1, 0.001) returned Discard (the master cannot repeat a rejected step): \
             voltage collapse"
        );
        assert_eq!(step.cause(), &e);
    }
}
