//! The synchronous-reference-frame PLL of a grid-following unit, on instantaneous voltages.
//!
//! The measured voltage is taken into the PLL's dq frame; the angle error is
//! `e = atan2(v_q, v_d)` (the angle of the voltage in the frame), and
//! `Δω = k_p e + k_i ∫e` (rad/s), `θ' = ω_b + Δω`. Linearized, this is the phasor DER's PLL
//! (`e` = voltage angle − PLL angle) with the same gains, so the paper's `k_p`, `k_i` = 60, 240
//! mean the same in both settings.

use super::frame::{Abc, Dq};
use serde::{Deserialize, Serialize};

/// SRF-PLL state and gains.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Pll {
    /// Proportional gain (rad/s per rad).
    pub kp: f64,
    /// Integral gain (rad/s² per rad).
    pub ki: f64,
    /// Base angular frequency `ω_b` (rad/s).
    pub omega_b: f64,
    theta: f64,
    integral: f64,
    delta_omega: f64,
}

impl Pll {
    /// A PLL locked at `theta0` on the nominal frequency.
    pub fn new(kp: f64, ki: f64, omega_b: f64, theta0: f64) -> Pll {
        Pll {
            kp,
            ki,
            omega_b,
            theta: theta0,
            integral: 0.0,
            delta_omega: 0.0,
        }
    }

    /// The frame's angle (rad, wrapped to `[0, 2π)`).
    pub fn theta(&self) -> f64 {
        self.theta
    }

    /// The frequency deviation `Δω/ω_b` (pu).
    pub fn delta_f(&self) -> f64 {
        self.delta_omega / self.omega_b
    }

    /// The measured voltage in the PLL's present frame.
    pub fn frame(&self, v: Abc) -> Dq {
        v.to_dq(self.theta)
    }

    /// Hold: no sample of the voltage (it is too low to be measured, as in a fault); the frame
    /// turns on at the frequency the integral holds, `ω_b + k_i ∫e`, for `h` seconds, and the
    /// proportional path's contribution is dropped.
    pub fn hold(&mut self, h: f64) {
        self.delta_omega = self.integral;
        self.theta = (self.theta + (self.omega_b + self.delta_omega) * h)
            .rem_euclid(2.0 * std::f64::consts::PI);
    }

    /// Take one sample of the voltage and advance the angle over `h` seconds.
    pub fn step(&mut self, v: Abc, h: f64) {
        let dq = self.frame(v);
        let e = if dq.norm() > 1e-6 {
            dvpp_math::atan2(dq.q, dq.d)
        } else {
            0.0
        };
        self.delta_omega = self.kp * e + self.integral;
        self.integral += self.ki * e * h;
        self.theta = (self.theta + (self.omega_b + self.delta_omega) * h)
            .rem_euclid(2.0 * std::f64::consts::PI);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// The PLL locks to a voltage of another frequency and phase: its frequency settles on the
    /// voltage's, its frame on the voltage's angle (v_q → 0).
    #[test]
    fn locks_to_an_off_nominal_voltage() {
        let (wb, h) = (2.0 * PI * 50.0, 50e-6);
        let mut pll = Pll::new(60.0, 240.0, wb, 0.0);
        let (df, phase) = (-0.004, 0.5); // 49.8 Hz, 0.5 rad ahead
        let mut t = 0.0;
        for _ in 0..(6.0 / h) as usize {
            let angle = wb * (1.0 + df) * t + phase;
            let v = Dq { d: 1.0, q: 0.0 }.to_abc(angle);
            pll.step(v, h);
            t += h;
        }
        assert!((pll.delta_f() - df).abs() < 1e-5, "{}", pll.delta_f());
        let v = Dq { d: 1.0, q: 0.0 }.to_abc(wb * (1.0 + df) * t + phase);
        assert!(pll.frame(v).q.abs() < 1e-3, "{:?}", pll.frame(v));
    }

    /// Held, the PLL turns on at the frequency its integral had, whatever the voltage; sampled
    /// again it locks as before.
    #[test]
    fn holds_its_frequency() {
        let (wb, h) = (2.0 * PI * 50.0, 50e-6);
        let mut pll = Pll::new(60.0, 240.0, wb, 0.0);
        let df = 0.004;
        let mut t = 0.0;
        for _ in 0..(6.0 / h) as usize {
            pll.step(Dq { d: 1.0, q: 0.0 }.to_abc(wb * (1.0 + df) * t), h);
            t += h;
        }
        let held = pll.delta_f();
        let theta = pll.theta();
        for _ in 0..2000 {
            pll.hold(h);
        }
        // The proportional path's share (of a locked PLL's, ~1e-11 pu) is dropped.
        assert!((pll.delta_f() - held).abs() < 1e-9, "{}", pll.delta_f());
        let turned = (pll.theta() - theta).rem_euclid(2.0 * PI);
        let expected = (wb * (1.0 + pll.delta_f()) * 2000.0 * h).rem_euclid(2.0 * PI);
        assert!((turned - expected).abs() < 1e-9, "{turned} {expected}");
    }
}
