//! The amplitude-invariant Park transform between three-phase instantaneous values and a dq frame.
//!
//! A balanced set `x_a = X cos(θ + φ)`, `x_b`, `x_c` (phases 120° apart, a-b-c sequence) maps to
//! `x_d + j x_q = X e^{jφ}` in the frame at angle `θ`: the d-axis is the frame's, the dq value
//! is the peak phasor. The zero sequence is dropped (a three-wire converter carries none).

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Instantaneous phase values.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Abc {
    /// Phase a.
    pub a: f64,
    /// Phase b.
    pub b: f64,
    /// Phase c.
    pub c: f64,
}

/// A value in a dq frame.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Dq {
    /// Direct axis.
    pub d: f64,
    /// Quadrature axis.
    pub q: f64,
}

const SHIFT: f64 = 2.0 * PI / 3.0;

impl Abc {
    /// The dq value of these phases in the frame at angle `theta`.
    pub fn to_dq(self, theta: f64) -> Dq {
        let (sa, ca) = dvpp_math::sincos(theta);
        let (sb, cb) = dvpp_math::sincos(theta - SHIFT);
        let (sc, cc) = dvpp_math::sincos(theta + SHIFT);
        Dq {
            d: 2.0 / 3.0 * (self.a * ca + self.b * cb + self.c * cc),
            q: -2.0 / 3.0 * (self.a * sa + self.b * sb + self.c * sc),
        }
    }

    /// The largest of the three magnitudes.
    pub fn peak(self) -> f64 {
        self.a.abs().max(self.b.abs()).max(self.c.abs())
    }
}

impl Dq {
    /// The phases of this dq value in the frame at angle `theta`.
    pub fn to_abc(self, theta: f64) -> Abc {
        let at = |angle: f64| {
            let (s, c) = dvpp_math::sincos(angle);
            self.d * c - self.q * s
        };
        Abc {
            a: at(theta),
            b: at(theta - SHIFT),
            c: at(theta + SHIFT),
        }
    }

    /// The magnitude `√(d² + q²)` (the peak phase value).
    pub fn norm(self) -> f64 {
        dvpp_math::hypot(self.d, self.q)
    }

    /// `j · self` (a quarter turn ahead).
    pub fn rot90(self) -> Dq {
        Dq {
            d: -self.q,
            q: self.d,
        }
    }

    /// The active power `v_d i_d + v_q i_q` of this voltage with `current` (pu, amplitude-invariant).
    pub fn p(self, current: Dq) -> f64 {
        self.d * current.d + self.q * current.q
    }

    /// The reactive power `v_q i_d - v_d i_q` of this voltage with `current`.
    pub fn q(self, current: Dq) -> f64 {
        self.q * current.d - self.d * current.q
    }
}

impl std::ops::Add for Dq {
    type Output = Dq;
    fn add(self, other: Dq) -> Dq {
        Dq {
            d: self.d + other.d,
            q: self.q + other.q,
        }
    }
}

impl std::ops::Sub for Dq {
    type Output = Dq;
    fn sub(self, other: Dq) -> Dq {
        Dq {
            d: self.d - other.d,
            q: self.q - other.q,
        }
    }
}

impl std::ops::Mul<f64> for Dq {
    type Output = Dq;
    fn mul(self, k: f64) -> Dq {
        Dq {
            d: k * self.d,
            q: k * self.q,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_balanced_set_is_its_peak_phasor() {
        let (x, phi, theta): (f64, f64, f64) = (0.8, 0.3, 1.1);
        let abc = Abc {
            a: x * dvpp_math::cos(theta + phi),
            b: x * dvpp_math::cos(theta + phi - SHIFT),
            c: x * dvpp_math::cos(theta + phi + SHIFT),
        };
        let dq = abc.to_dq(theta);
        assert!((dq.d - x * dvpp_math::cos(phi)).abs() < 1e-12);
        assert!((dq.q - x * dvpp_math::sin(phi)).abs() < 1e-12);
        let back = dq.to_abc(theta);
        assert!((back.a - abc.a).abs() < 1e-12 && (back.c - abc.c).abs() < 1e-12);
    }

    #[test]
    fn instantaneous_power_is_the_dq_power() {
        let theta = 0.7;
        let v = Dq { d: 1.0, q: 0.1 };
        let i = Dq { d: 0.5, q: -0.2 };
        let (va, ia) = (v.to_abc(theta), i.to_abc(theta));
        // Amplitude-invariant: p = (3/2)(v·i) in per unit of peak values, with S_b = (3/2) V I.
        let p3 = (va.a * ia.a + va.b * ia.b + va.c * ia.c) / 1.5;
        assert!((p3 - v.p(i)).abs() < 1e-12);
    }
}
