//! Typed errors of the DVPP design and runtime layer.

use serde::{Deserialize, Serialize};
use std::fmt;

/// Every way a design or runtime request of this crate can be rejected.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum DvppError {
    /// A coefficient, time constant, gain or step size was NaN or infinite.
    NonFinite {
        /// What was being checked.
        what: String,
    },
    /// A polynomial that must not be empty/zero was empty or identically zero.
    ZeroPolynomial {
        /// Which polynomial.
        what: String,
    },
    /// A rational function has more zeros than poles (numerator degree above denominator degree).
    Improper {
        /// What was being built.
        what: String,
        /// Numerator degree.
        num_degree: usize,
        /// Denominator degree.
        den_degree: usize,
    },
    /// The inverse (or a quotient) would not be proper.
    ImproperInverse {
        /// What was being inverted.
        what: String,
        /// Relative degree of the operand that was inverted (> 0 means strictly proper).
        relative_degree: i64,
    },
    /// A time constant was not strictly positive.
    NonPositiveTimeConstant {
        /// Which time constant.
        what: String,
        /// Offending value.
        value: f64,
    },
    /// A dc gain (participation) lies outside its admissible interval.
    GainOutOfRange {
        /// Which gain.
        what: String,
        /// Offending value.
        value: f64,
        /// Admissible lower bound.
        min: f64,
        /// Admissible upper bound.
        max: f64,
    },
    /// A generic parameter was rejected (with a reason).
    InvalidParameter {
        /// Which parameter.
        what: String,
        /// Why.
        reason: String,
    },
    /// A transfer function that must be stable has poles in the closed right half plane
    /// (or an origin pole where none is allowed).
    Unstable {
        /// What was checked.
        what: String,
    },
    /// Matrix dimensions of a state-space model do not fit together.
    DimensionMismatch {
        /// What was checked.
        what: String,
        /// Expected size.
        expected: usize,
        /// Found size.
        found: usize,
    },
    /// The participation condition `Σ m_i(jω) = 1` is violated beyond the tolerance.
    ParticipationViolated {
        /// Worst deviation `max_ω |Σ m_i(jω) − 1|`.
        max_error: f64,
        /// Frequency (rad/s) of the worst deviation.
        omega: f64,
        /// Tolerance that was requested.
        tol: f64,
    },
    /// An aggregation condition is violated beyond the tolerance.
    AggregationViolated {
        /// Which condition (grid-forming, hybrid, voltage).
        condition: String,
        /// Worst relative error on the grid.
        max_rel_error: f64,
        /// Frequency (rad/s) of the worst error.
        omega: f64,
        /// Tolerance that was requested.
        tol: f64,
    },
    /// The dc gains of the low-pass units cannot be renormalized under the μ_min bound.
    InfeasibleGains {
        /// Why.
        reason: String,
    },
    /// An operation was requested on a unit kind that does not support it.
    WrongUnitKind {
        /// What was attempted.
        what: String,
    },
}

impl fmt::Display for DvppError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DvppError::NonFinite { what } => write!(f, "{what}: value is not finite"),
            DvppError::ZeroPolynomial { what } => write!(f, "{what}: polynomial is empty or zero"),
            DvppError::Improper {
                what,
                num_degree,
                den_degree,
            } => write!(
                f,
                "{what}: improper rational (numerator degree {num_degree} > denominator degree {den_degree})"
            ),
            DvppError::ImproperInverse {
                what,
                relative_degree,
            } => write!(
                f,
                "{what}: inverse/quotient is not proper (relative degree {relative_degree})"
            ),
            DvppError::NonPositiveTimeConstant { what, value } => {
                write!(f, "{what}: time constant must be > 0, got {value}")
            }
            DvppError::GainOutOfRange {
                what,
                value,
                min,
                max,
            } => write!(f, "{what}: gain {value} outside [{min}, {max}]"),
            DvppError::InvalidParameter { what, reason } => write!(f, "{what}: {reason}"),
            DvppError::Unstable { what } => write!(f, "{what}: not stable"),
            DvppError::DimensionMismatch {
                what,
                expected,
                found,
            } => write!(f, "{what}: expected dimension {expected}, found {found}"),
            DvppError::ParticipationViolated {
                max_error,
                omega,
                tol,
            } => write!(
                f,
                "participation condition violated: max |Σ m_i(jω) − 1| = {max_error:e} at ω = {omega:e} rad/s (tol {tol:e})"
            ),
            DvppError::AggregationViolated {
                condition,
                max_rel_error,
                omega,
                tol,
            } => write!(
                f,
                "{condition} aggregation condition violated: relative error {max_rel_error:e} at ω = {omega:e} rad/s (tol {tol:e})"
            ),
            DvppError::InfeasibleGains { reason } => write!(f, "infeasible dc gains: {reason}"),
            DvppError::WrongUnitKind { what } => write!(f, "wrong unit kind: {what}"),
        }
    }
}

impl std::error::Error for DvppError {}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, DvppError>;

pub(crate) fn check_finite(what: &str, v: f64) -> Result<()> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(DvppError::NonFinite {
            what: what.to_string(),
        })
    }
}

pub(crate) fn check_tau(what: &str, tau: f64) -> Result<()> {
    check_finite(what, tau)?;
    if tau > 0.0 {
        Ok(())
    } else {
        Err(DvppError::NonPositiveTimeConstant {
            what: what.to_string(),
            value: tau,
        })
    }
}

pub(crate) fn check_unit_gain(what: &str, mu: f64) -> Result<()> {
    check_finite(what, mu)?;
    if (0.0..=1.0).contains(&mu) {
        Ok(())
    } else {
        Err(DvppError::GainOutOfRange {
            what: what.to_string(),
            value: mu,
            min: 0.0,
            max: 1.0,
        })
    }
}
