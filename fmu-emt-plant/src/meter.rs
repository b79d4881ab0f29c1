//! Frame conversions (amplitude-invariant Clarke transform) and the PCC's measurement SRF-PLL.

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

const SQRT3: f64 = 1.732_050_807_568_877_2;

/// abc → αβ, amplitude invariant; the zero sequence is dropped (three-wire).
pub fn clarke([a, b, c]: [f64; 3]) -> [f64; 2] {
    [(2.0 * a - b - c) / 3.0, (b - c) / SQRT3]
}

/// αβ → abc (no zero sequence).
pub fn inverse_clarke([al, be]: [f64; 2]) -> [f64; 3] {
    [
        al,
        -0.5 * al + 0.5 * SQRT3 * be,
        -0.5 * al - 0.5 * SQRT3 * be,
    ]
}

/// Wrap an angle to (-π, π].
pub fn wrap(x: f64) -> f64 {
    let y = x.rem_euclid(2.0 * PI);
    if y > PI {
        y - 2.0 * PI
    } else {
        y
    }
}

/// A synchronous-reference-frame PLL on the PCC voltage, used as a meter: the phase error
/// `ε = atan2(v_q, v_d)` in the frame at `θ` drives `Δω = k_p ε + k_i ∫ε` (rad/s), and
/// `θ' = ω_b + Δω`, integrated with the step (error sampled at the step's end).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pll {
    /// Estimated angle, rad (unwrapped).
    pub theta: f64,
    /// Frequency deviation, rad/s.
    pub dw: f64,
    /// Integral part of `dw`, rad/s.
    pub xi: f64,
}

impl Pll {
    /// Locked on a voltage of angle `theta`.
    pub fn locked(theta: f64) -> Self {
        Pll {
            theta,
            dw: 0.0,
            xi: 0.0,
        }
    }

    fn error(&self, v: [f64; 2]) -> f64 {
        let (s, c) = dvpp_math::sincos(self.theta);
        let vd = v[0] * c + v[1] * s;
        let vq = -v[0] * s + v[1] * c;
        if dvpp_math::hypot(vd, vq) < 1e-9 {
            0.0
        } else {
            dvpp_math::atan2(vq, vd)
        }
    }

    /// Advance over `h` and take the voltage `v` (αβ) at the step's end.
    pub fn step(&mut self, v: [f64; 2], h: f64, omega_b: f64, kp: f64, ki: f64) {
        self.theta += (omega_b + self.dw) * h;
        let e = self.error(v);
        self.xi += ki * e * h;
        self.dw = kp * e + self.xi;
    }
}
