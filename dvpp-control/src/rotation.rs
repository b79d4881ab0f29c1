//! Rotated powers `p'`, `q'` for units behind lossy lines (the spatially distributed DVPP).
//!
//! With a homogeneous line ratio `r = R/X`, the rotation
//!
//! ```text
//! p' = ( X p - R q)/|Z| = (  p - r q)/sqrt(1 + r²)
//! q' = ( R p + X q)/|Z| = (r p +   q)/sqrt(1 + r²)
//! ```
//!
//! makes `p'` follow the angle and `q'` the voltage difference across such a line, as `p` and
//! `q` do across an inductive one. The back-rotation is the transpose. At `r = 0` both are the
//! identity, bit for bit.

use crate::error::{DvppError, Result};
use serde::{Deserialize, Serialize};

/// The rotation by the angle of a line impedance `R + jX` less 90°: `cos = X/|Z|`,
/// `sin = R/|Z|`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Rotation {
    /// `X/|Z|`.
    cos: f64,
    /// `R/|Z|`.
    sin: f64,
}

impl Rotation {
    /// The identity: classical `p`-`f` and `q`-`v` control (`R/X = 0`).
    pub const IDENTITY: Rotation = Rotation { cos: 1.0, sin: 0.0 };

    /// The rotation for lines with the ratio `rx = R/X` (finite, `>= 0`).
    pub fn from_rx(rx: f64) -> Result<Rotation> {
        if !(rx.is_finite() && rx >= 0.0) {
            return Err(DvppError::InvalidParameter {
                what: "R/X".into(),
                reason: format!("{rx} must be finite and >= 0"),
            });
        }
        if rx == 0.0 {
            return Ok(Rotation::IDENTITY);
        }
        let z = dvpp_math::hypot(rx, 1.0);
        Ok(Rotation {
            cos: 1.0 / z,
            sin: rx / z,
        })
    }

    /// The rotation for the line impedance `R + jX` (`X > 0`, `R >= 0`).
    pub fn from_impedance(r: f64, x: f64) -> Result<Rotation> {
        if !(x > 0.0 && x.is_finite()) {
            return Err(DvppError::InvalidParameter {
                what: "X".into(),
                reason: format!("{x} must be finite and > 0"),
            });
        }
        Rotation::from_rx(r / x)
    }

    /// `R/X` of the lines this rotation compensates.
    pub fn rx(&self) -> f64 {
        self.sin / self.cos
    }

    /// Whether this is the identity (no rotation).
    pub fn is_identity(&self) -> bool {
        self.sin == 0.0
    }

    /// `(p, q) → (p', q')`.
    pub fn rotate(&self, p: f64, q: f64) -> (f64, f64) {
        if self.is_identity() {
            return (p, q);
        }
        (self.cos * p - self.sin * q, self.sin * p + self.cos * q)
    }

    /// `(p', q') → (p, q)`, the inverse of [`Rotation::rotate`].
    pub fn unrotate(&self, p_rot: f64, q_rot: f64) -> (f64, f64) {
        if self.is_identity() {
            return (p_rot, q_rot);
        }
        (
            self.cos * p_rot + self.sin * q_rot,
            -self.sin * p_rot + self.cos * q_rot,
        )
    }
}

impl Default for Rotation {
    fn default() -> Self {
        Rotation::IDENTITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const POINTS: [(f64, f64); 5] = [
        (0.3, 0.1),
        (-0.2, 0.05),
        (0.0, -0.7),
        (1.3, 0.0),
        (-0.45, -0.8),
    ];

    #[test]
    fn zero_ratio_is_the_identity_bit_for_bit() {
        let rot = Rotation::from_rx(0.0).unwrap();
        assert!(rot.is_identity());
        for (p, q) in POINTS.into_iter().chain([(-0.0, 0.0), (1e-300, -3e300)]) {
            let (a, b) = rot.rotate(p, q);
            let (c, d) = rot.unrotate(p, q);
            for (x, y) in [(a, p), (b, q), (c, p), (d, q)] {
                assert_eq!(x.to_bits(), y.to_bits());
            }
        }
    }

    #[test]
    fn back_rotation_inverts_and_the_magnitude_is_kept() {
        for rx in [0.1, 0.4, 1.0, 2.0, 7.5] {
            let rot = Rotation::from_rx(rx).unwrap();
            assert!((rot.rx() - rx).abs() < 1e-14 * rx);
            for (p, q) in POINTS {
                let (pr, qr) = rot.rotate(p, q);
                let (p2, q2) = rot.unrotate(pr, qr);
                assert!((p2 - p).abs() < 1e-15 && (q2 - q).abs() < 1e-15);
                assert!((dvpp_math::hypot(pr, qr) - dvpp_math::hypot(p, q)).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn the_rotation_matches_the_impedance_form() {
        // p' = (X p - R q)/|Z|, q' = (R p + X q)/|Z| for a line R + jX.
        let (r, x) = (0.35_f64, 0.28);
        let z = dvpp_math::hypot(r, x);
        let rot = Rotation::from_impedance(r, x).unwrap();
        for (p, q) in POINTS {
            let (pr, qr) = rot.rotate(p, q);
            assert!((pr - (x * p - r * q) / z).abs() < 1e-15);
            assert!((qr - (r * p + x * q) / z).abs() < 1e-15);
        }
        // R/X = 1: p' = (p - q)/√2, q' = (p + q)/√2.
        let (pr, qr) = Rotation::from_rx(1.0).unwrap().rotate(0.3, 0.1);
        assert!((pr - 0.2 / 2f64.sqrt()).abs() < 1e-15);
        assert!((qr - 0.4 / 2f64.sqrt()).abs() < 1e-15);
    }

    #[test]
    fn bad_ratios_are_refused() {
        for rx in [-0.1, f64::NAN, f64::INFINITY] {
            assert!(Rotation::from_rx(rx).is_err(), "{rx}");
        }
        assert!(Rotation::from_impedance(0.1, 0.0).is_err());
    }
}
