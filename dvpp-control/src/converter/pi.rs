//! A sampled proportional-integral controller with output limits and anti-windup.

use serde::{Deserialize, Serialize};

/// `u = ff + k_p e + k_i ∫e`, clamped to `[lo, hi]`; while the output is clamped the integral
/// only moves in the direction that brings it back (conditional integration), so it does not
/// wind up.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Pi {
    /// Proportional gain.
    pub kp: f64,
    /// Integral gain (per second).
    pub ki: f64,
    /// Lower output limit.
    pub lo: f64,
    /// Upper output limit.
    pub hi: f64,
    integral: f64,
}

impl Pi {
    /// A PI controller without limits, its integral at zero.
    pub fn new(kp: f64, ki: f64) -> Pi {
        Pi::limited(kp, ki, f64::NEG_INFINITY, f64::INFINITY)
    }

    /// A PI controller with output limits `[lo, hi]`.
    pub fn limited(kp: f64, ki: f64, lo: f64, hi: f64) -> Pi {
        Pi {
            kp,
            ki,
            lo,
            hi,
            integral: 0.0,
        }
    }

    /// The integral's contribution to the output (`k_i ∫e`).
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// Start with the integral's contribution at `value` (an output in steady state).
    pub fn set_integral(&mut self, value: f64) {
        self.integral = value;
    }

    /// The output for the error `e` and feed-forward `ff`, then integrate `e` over `h` seconds
    /// (forward Euler: the output of this sample uses the integral of the samples before).
    pub fn step(&mut self, e: f64, ff: f64, h: f64) -> f64 {
        let raw = ff + self.kp * e + self.integral;
        let out = raw.clamp(self.lo, self.hi);
        let winding_up = (raw > self.hi && e > 0.0) || (raw < self.lo && e < 0.0);
        if !winding_up {
            self.integral += self.ki * e * h;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_integral_removes_a_constant_error_and_does_not_wind_up() {
        let mut pi = Pi::limited(0.5, 10.0, -1.0, 1.0);
        // A plant y = u: the loop settles at the reference.
        let (mut y, h) = (0.0, 1e-3);
        for _ in 0..5000 {
            y = pi.step(0.4 - y, 0.0, h);
        }
        assert!((y - 0.4).abs() < 1e-9, "{y}");
        // An unreachable reference: the output sits at the limit, the integral stays bounded.
        for _ in 0..5000 {
            pi.step(10.0, 0.0, h);
        }
        assert!(pi.integral() <= 1.0 + 10.0 * 10.0 * h, "{}", pi.integral());
        // Back in range at once when the error reverses.
        let u = pi.step(-0.1, 0.0, h);
        assert!(u < 1.0, "{u}");
    }
}
