//! The crate's error types, [`CaseError`] and [`GridError`], and the range checks of case parameters.
//!
//! A leaf: it imports nothing from the grid, so that every model can report through it.

use crate::numerics::{CONST_POWER_V_MIN, MIN_INTERNAL_STEP, STEPS_PER_TIME_CONSTANT};
use serde::{Deserialize, Serialize};
use std::fmt;

/// Everything that can be wrong with a case file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum CaseError {
    /// TOML syntax or schema error (missing field, unknown model type, wrong value type).
    Parse(String),
    /// No bus at all, or a bus id defined twice.
    DuplicateBus(u32),
    /// The case has no bus.
    NoBus,
    /// An element refers to a bus that is not defined.
    UnknownBus { element: String, bus: u32 },
    /// An element refers to a machine, slot or branch that is not defined.
    UnknownReference { element: String, name: String },
    /// Two elements share a name that must be unique.
    DuplicateName(String),
    /// Series impedance zero or negative (x ≤ 0 or r < 0 or |z| = 0).
    NonPositiveImpedance { element: String, r: f64, x: f64 },
    /// A bus cannot be reached from the slack bus through in-service branches.
    IslandedBus(u32),
    /// Exactly one slack bus is required.
    Slack(String),
    /// A parameter is outside its admissible range.
    OutOfRange {
        element: String,
        parameter: String,
        value: f64,
        expected: String,
    },
    /// A structural inconsistency (PV bus without a source, exciter on a classical machine...).
    Inconsistent(String),
}

impl fmt::Display for CaseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CaseError::Parse(m) => write!(f, "case file could not be parsed: {m}"),
            CaseError::DuplicateBus(b) => write!(f, "bus {b} is defined more than once"),
            CaseError::NoBus => write!(f, "the case defines no bus"),
            CaseError::UnknownBus { element, bus } => {
                write!(f, "{element} refers to bus {bus}, which is not defined")
            }
            CaseError::UnknownReference { element, name } => {
                write!(f, "{element} refers to `{name}`, which is not defined")
            }
            CaseError::DuplicateName(n) => write!(f, "name `{n}` is used more than once"),
            CaseError::NonPositiveImpedance { element, r, x } => write!(
                f,
                "{element} has a non-positive series impedance (r = {r}, x = {x}); need r >= 0, x > 0"
            ),
            CaseError::IslandedBus(b) => {
                write!(f, "bus {b} is islanded (not connected to the slack bus)")
            }
            CaseError::Slack(m) => write!(f, "slack bus: {m}"),
            CaseError::OutOfRange { element, parameter, value, expected } => write!(
                f,
                "{element}: parameter `{parameter}` = {value} is out of range (expected {expected})"
            ),
            CaseError::Inconsistent(m) => write!(f, "inconsistent case: {m}"),
        }
    }
}

impl std::error::Error for CaseError {}

pub(crate) fn check_range(
    element: &str,
    parameter: &str,
    value: f64,
    ok: bool,
    expected: &str,
) -> Result<(), CaseError> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(CaseError::OutOfRange {
            element: element.to_string(),
            parameter: parameter.to_string(),
            value,
            expected: expected.to_string(),
        })
    }
}

pub(crate) fn pos(element: &str, parameter: &str, v: f64) -> Result<(), CaseError> {
    check_range(element, parameter, v, v > 0.0, "> 0")
}
pub(crate) fn nonneg(element: &str, parameter: &str, v: f64) -> Result<(), CaseError> {
    check_range(element, parameter, v, v >= 0.0, ">= 0")
}

/// Errors while building or running the grid.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum GridError {
    Case(CaseError),
    PowerFlowDiverged {
        iterations: usize,
        mismatch: f64,
    },
    Init(String),
    SingularNetwork,
    /// The network solution did not converge (in practice: the voltages collapsed). `bus` is
    /// the bus with the lowest voltage magnitude `v_min` (pu) over the last two iterates,
    /// `mismatch_bus` the bus whose voltage changed most in the last iteration (`residual`, pu);
    /// both are bus ids of the case.
    NetworkNotConverged {
        t: f64,
        residual: f64,
        bus: u32,
        v_min: f64,
        mismatch_bus: u32,
    },
    /// A machine or grid-forming DER slot (`unit`: `machine SG1`, `DER slot 2`) drifted more
    /// than [`crate::grid::LOSS_OF_SYNCHRONISM_ANGLE`] from the centre-of-inertia angle: `angle` is its
    /// rotor (slot: internal voltage) angle minus the COI angle, rad.
    LossOfSynchronism {
        t: f64,
        unit: String,
        angle: f64,
    },
    /// The centre-of-inertia frequency `f` (pu) left [`crate::grid::FREQUENCY_BAND`].
    FrequencyCollapse {
        t: f64,
        f: f64,
        f_nom: f64,
    },
    BadSlot {
        index: usize,
        reason: String,
    },
    BadEvent {
        index: usize,
        reason: String,
    },
    /// A bus fault's parameter `field` (`fault.bus`, `fault.R`, ...) is not admissible.
    BadFault {
        field: String,
        reason: String,
    },
    InvalidStep {
        t: f64,
        h: f64,
    },
    TimeMismatch {
        expected: f64,
        got: f64,
    },
    NonFinite {
        t: f64,
    },
    /// A time constant of the case is too short for the smallest internal step
    /// ([`MIN_INTERNAL_STEP`]): `parameter` names it and its value, `min` is the shortest
    /// admissible time constant, s.
    TimeConstantTooSmall {
        parameter: String,
        min: f64,
    },
}

impl fmt::Display for GridError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GridError::Case(e) => write!(f, "{e}"),
            GridError::PowerFlowDiverged {
                iterations,
                mismatch,
            } => write!(
                f,
                "power flow did not converge ({iterations} iterations, mismatch {mismatch:e} pu)"
            ),
            GridError::Init(m) => write!(f, "initialization failed: {m}"),
            GridError::SingularNetwork => write!(f, "network admittance matrix is singular"),
            GridError::NetworkNotConverged {
                t,
                residual,
                bus,
                v_min,
                mismatch_bus,
            } => {
                let t = round_time(*t);
                let cause = if *v_min < CONST_POWER_V_MIN {
                    "voltage collapse: "
                } else {
                    ""
                };
                write!(
                    f,
                    "t = {t} s: {cause}the network solution did not converge (residual \
                     {residual:.3e} pu at bus {mismatch_bus}); lowest voltage {v_min:.3} pu at \
                     bus {bus}"
                )
            }
            GridError::FrequencyCollapse { t, f: freq, f_nom } => {
                let t = round_time(*t);
                let (lo, hi) = crate::grid::FREQUENCY_BAND;
                write!(
                    f,
                    "t = {t} s: frequency collapse: the centre-of-inertia frequency reached \
                     {:.3} Hz, outside {:.1}-{:.1} Hz where the machines' frequency protection \
                     disconnects them",
                    freq * f_nom,
                    lo * f_nom,
                    hi * f_nom
                )
            }
            GridError::LossOfSynchronism { t, unit, angle } => {
                let t = round_time(*t);
                let what = if unit.starts_with("machine") {
                    "rotor angle"
                } else {
                    "internal voltage angle"
                };
                let side = if *angle >= 0.0 { "ahead of" } else { "behind" };
                write!(
                    f,
                    "t = {t} s: {unit} lost synchronism: its {what} is {:.2} rad {side} the \
                     centre of inertia (limit π)",
                    angle.abs()
                )
            }
            GridError::BadSlot { index, reason } => write!(f, "DER slot {index}: {reason}"),
            GridError::BadEvent { index, reason } => write!(f, "event {index}: {reason}"),
            GridError::BadFault { field, reason } => {
                write!(f, "parameter '{field}': {reason}")
            }
            GridError::InvalidStep { t, h } => write!(f, "invalid step t = {t}, h = {h}"),
            GridError::TimeMismatch { expected, got } => {
                write!(
                    f,
                    "step starts at t = {got} but the grid is at t = {expected}"
                )
            }
            GridError::NonFinite { t } => write!(f, "non-finite state at t = {t} s"),
            GridError::TimeConstantTooSmall { parameter, min } => write!(
                f,
                "{parameter} is below {min} s, the shortest time constant the fixed-step RK4 \
                 integration resolves (internal step at least {} s and at most 1/{} of the \
                 smallest time constant)",
                MIN_INTERNAL_STEP, STEPS_PER_TIME_CONSTANT
            ),
        }
    }
}

impl std::error::Error for GridError {}

/// A time for messages: rounded to the microsecond, so that sums of steps print as `3.412`.
fn round_time(t: f64) -> f64 {
    (t * 1e6).round() / 1e6
}

impl From<CaseError> for GridError {
    fn from(e: CaseError) -> Self {
        GridError::Case(e)
    }
}
