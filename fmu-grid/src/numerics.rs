//! Shared numerics of the grid: the complex type, solver constants, angle wrapping, limited
//! integrators and the time constants the internal step has to resolve.
//!
//! A leaf: it imports nothing from the crate.

use nalgebra::Complex;
use std::f64::consts::PI;

/// Complex number (phasors, admittances, powers).
pub type C64 = Complex<f64>;

/// Voltage below which constant-power loads turn into constant impedances, pu.
pub const CONST_POWER_V_MIN: f64 = 0.7;
/// Largest internal integration step, s.
pub const MAX_INTERNAL_STEP: f64 = 1e-3;
/// Smallest internal step the grid will choose, s: a case whose time constants need less is
/// refused (a phasor model does not represent dynamics that fast anyway).
pub const MIN_INTERNAL_STEP: f64 = 5e-5;
/// Internal steps per smallest time constant: h ≤ τ_min / 3 keeps RK4 well inside its stability
/// limit (h < 2.785 τ) and accurate on the fastest mode.
pub const STEPS_PER_TIME_CONSTANT: f64 = 3.0;

/// A time constant of the case that the internal step has to resolve.
#[derive(Clone, Debug, PartialEq)]
pub struct TimeConstant {
    /// Parameter it comes from, e.g. `machine[2].governor.t_ch`.
    pub name: String,
    /// The parameter's value.
    pub value: f64,
    /// The time constant it gives, s, and how (when it is not the parameter itself).
    pub tau: f64,
    pub how: Option<&'static str>,
}

impl TimeConstant {
    pub fn new(name: String, value: f64) -> TimeConstant {
        TimeConstant {
            name,
            value,
            tau: value,
            how: None,
        }
    }

    /// The parameter gives the time constant `tau` through the relation `how`.
    pub fn effective(mut self, tau: f64, how: &'static str) -> TimeConstant {
        self.tau = tau;
        self.how = Some(how);
        self
    }

    pub fn describe(&self) -> String {
        match self.how {
            None => format!("{} = {} s", self.name, self.value),
            Some(how) => format!("{} = {} ({how} = {:e} s)", self.name, self.value, self.tau),
        }
    }
}

/// Non-windup limit on an integrator state: hold at the limit while pushed outward.
pub fn limited(dx: f64, x: f64, lo: f64, hi: f64) -> f64 {
    if (x >= hi && dx > 0.0) || (x <= lo && dx < 0.0) {
        0.0
    } else {
        dx
    }
}

/// Tolerance on event times, s.
pub const EVENT_EPS: f64 = 1e-9;

/// Angle wrapped to (-π, π].
pub fn wrap(a: f64) -> f64 {
    let mut a = a % (2.0 * PI);
    if a > PI {
        a -= 2.0 * PI;
    } else if a <= -PI {
        a += 2.0 * PI;
    }
    a
}
