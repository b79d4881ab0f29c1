//! The paper's converter data and the filter's linear dq model: resonances and exact discretization.
//!
//! Between the converter's switched (averaged) voltage `v_m` and the grid voltage `v_g` lie the
//! filter inductor (`R_f`, `L_f`, current `i_f`), the filter capacitor (`C_f`, voltage `v_c`)
//! and the LV/MV transformer (`R_t`, `L_t`, current `i_g`). In a dq frame turning at `ω` (pu):
//!
//! ```text
//! (L_f/ω_b) i_f' = v_m - v_c - R_f i_f - jω L_f i_f
//! (C_f/ω_b) v_c' = i_f - i_g - jω C_f v_c
//! (L_t/ω_b) i_g' = v_c - v_g - R_t i_g - jω L_t i_g
//! ```
//!
//! a linear system of six states and four inputs, which [`Lcl::discretize`] samples exactly for
//! inputs held over the step (zero-order hold), stable at any step.

use super::frame::Dq;
use crate::ss::expm;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// The converter interface's data, pu on the converter's rating (the paper's converter table).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ConverterData {
    /// Dc-link capacitance `C_dc`.
    pub c_dc: f64,
    /// Dc-link conductance `G_dc`.
    pub g_dc: f64,
    /// Filter resistance `R_f`.
    pub r_f: f64,
    /// Filter inductance `L_f`.
    pub l_f: f64,
    /// Filter capacitance `C_f`.
    pub c_f: f64,
    /// Transformer resistance `R_t`.
    pub r_t: f64,
    /// Transformer inductance `L_t`.
    pub l_t: f64,
    /// PLL proportional gain `k_p^pll` (rad/s per rad).
    pub kp_pll: f64,
    /// PLL integral gain `k_i^pll`.
    pub ki_pll: f64,
    /// Dc-voltage control gain `k_dc`.
    pub k_dc: f64,
    /// Dc voltage reference `v_dc*` in units of the rated ac peak phase voltage `v_r`.
    pub v_dc_ratio: f64,
}

impl ConverterData {
    /// The paper's values: `C_dc` 0.096, `G_dc` 0.05, `R_f` 0.01, `L_f` 0.11, `C_f` 0.0942,
    /// `R_t` 0.01, `L_t` 0.1 pu, PLL 60/240, `k_dc` 100, `v_dc* = 3 v_r`.
    pub const PAPER: ConverterData = ConverterData {
        c_dc: 0.096,
        g_dc: 0.05,
        r_f: 0.01,
        l_f: 0.11,
        c_f: 0.0942,
        r_t: 0.01,
        l_t: 0.1,
        kp_pll: 60.0,
        ki_pll: 240.0,
        k_dc: 100.0,
        v_dc_ratio: 3.0,
    };

    /// The resonance of the `L_f C_f` filter alone, `1/√(L_f C_f)` (pu of `ω_b`).
    pub fn lc_resonance(&self) -> f64 {
        1.0 / (self.l_f * self.c_f).sqrt()
    }

    /// The resonance of the LCL formed with the transformer against a stiff grid,
    /// `√((L_f + L_t)/(L_f L_t C_f))` (pu of `ω_b`).
    pub fn lcl_resonance(&self) -> f64 {
        ((self.l_f + self.l_t) / (self.l_f * self.l_t * self.c_f)).sqrt()
    }
}

/// The state of the filter: converter-side current, capacitor voltage, grid-side current.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct LclState {
    /// Converter-side (filter inductor) current `i_f`.
    pub i_f: Dq,
    /// Filter-capacitor voltage `v_c`.
    pub v_c: Dq,
    /// Grid-side (transformer) current `i_g`.
    pub i_g: Dq,
}

impl LclState {
    fn vector(&self) -> DVector<f64> {
        DVector::from_column_slice(&[
            self.i_f.d, self.i_f.q, self.v_c.d, self.v_c.q, self.i_g.d, self.i_g.q,
        ])
    }

    fn from_vector(x: &DVector<f64>) -> LclState {
        LclState {
            i_f: Dq { d: x[0], q: x[1] },
            v_c: Dq { d: x[2], q: x[3] },
            i_g: Dq { d: x[4], q: x[5] },
        }
    }
}

/// The filter's linear model in a frame at a fixed frequency, sampled exactly at one step.
#[derive(Debug, Clone, PartialEq)]
pub struct Lcl {
    a_d: DMatrix<f64>,
    b_d: DMatrix<f64>,
    h: f64,
}

impl Lcl {
    /// The continuous model `x' = A x + B u`, `x = [i_f, v_c, i_g]` (d, q each),
    /// `u = [v_m, v_g]`, in a frame turning at `omega` pu; `omega_b` in rad/s.
    pub fn continuous(
        data: &ConverterData,
        omega_b: f64,
        omega: f64,
    ) -> (DMatrix<f64>, DMatrix<f64>) {
        let mut a = DMatrix::zeros(6, 6);
        let mut b = DMatrix::zeros(6, 4);
        // Rows 0-1: i_f; 2-3: v_c; 4-5: i_g.
        let (kf, kc, kt) = (omega_b / data.l_f, omega_b / data.c_f, omega_b / data.l_t);
        for (axis, sign) in [(0usize, 1.0), (1, -1.0)] {
            let other = 1 - axis;
            // i_f
            a[(axis, axis)] = -kf * data.r_f;
            a[(axis, other)] = sign * omega_b * omega;
            a[(axis, 2 + axis)] = -kf;
            b[(axis, axis)] = kf;
            // v_c
            a[(2 + axis, axis)] = kc;
            a[(2 + axis, 4 + axis)] = -kc;
            a[(2 + axis, 2 + other)] = sign * omega_b * omega;
            // i_g
            a[(4 + axis, 2 + axis)] = kt;
            a[(4 + axis, 4 + axis)] = -kt * data.r_t;
            a[(4 + axis, 4 + other)] = sign * omega_b * omega;
            b[(4 + axis, 2 + axis)] = -kt;
        }
        (a, b)
    }

    /// The model sampled at `h` seconds with inputs held over the step.
    pub fn discretize(data: &ConverterData, omega_b: f64, omega: f64, h: f64) -> Lcl {
        let (a, b) = Lcl::continuous(data, omega_b, omega);
        let mut m = DMatrix::zeros(10, 10);
        m.view_mut((0, 0), (6, 6)).copy_from(&(a * h));
        m.view_mut((0, 6), (6, 4)).copy_from(&(b * h));
        let e = expm(&m);
        Lcl {
            a_d: e.view((0, 0), (6, 6)).into_owned(),
            b_d: e.view((0, 6), (6, 4)).into_owned(),
            h,
        }
    }

    /// The step the model was sampled at.
    pub fn h(&self) -> f64 {
        self.h
    }

    /// The state one step on, with `v_m` and `v_g` held over the step.
    pub fn step(&self, x: &LclState, v_m: Dq, v_g: Dq) -> LclState {
        let u = DVector::from_column_slice(&[v_m.d, v_m.q, v_g.d, v_g.q]);
        LclState::from_vector(&(&self.a_d * x.vector() + &self.b_d * u))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn resonances_of_the_paper_filter() {
        let d = ConverterData::PAPER;
        // 1/√(0.11·0.0942) = 9.8 pu, √(0.21/(0.11·0.1·0.0942)) = 14.2 pu.
        assert!(
            (d.lc_resonance() - 9.82).abs() < 0.01,
            "{}",
            d.lc_resonance()
        );
        assert!(
            (d.lcl_resonance() - 14.24).abs() < 0.01,
            "{}",
            d.lcl_resonance()
        );
        // The model's eigenvalues in a frame at zero speed: the LCL resonance, lightly damped.
        let (a, _) = Lcl::continuous(&d, 2.0 * PI * 50.0, 0.0);
        let w = a
            .complex_eigenvalues()
            .iter()
            .map(|l| l.im.abs())
            .fold(0.0, f64::max);
        assert!(
            (w / (2.0 * PI * 50.0) - d.lcl_resonance()).abs() < 0.05,
            "{w}"
        );
    }

    #[test]
    fn steady_state_of_the_sampled_model_is_the_phasor_solution() {
        // Rotating frame at nominal speed: constant inputs give constant states, equal to the
        // phasor circuit's (impedances jX at 1 pu frequency).
        let d = ConverterData::PAPER;
        let lcl = Lcl::discretize(&d, 2.0 * PI * 50.0, 1.0, 50e-6);
        let (vm, vg) = (Dq { d: 1.05, q: 0.12 }, Dq { d: 1.0, q: 0.0 });
        let mut x = LclState::default();
        for _ in 0..40_000 {
            x = lcl.step(&x, vm, vg);
        }
        // Phasor: i_g = (v_c - v_g)/(R_t + jL_t), i_f = i_g + jC_f v_c, v_m = v_c + (R_f + jL_f) i_f.
        let c = |re: f64, im: f64| nalgebra::Complex::new(re, im);
        let (vc, ig, i_f) = (
            c(x.v_c.d, x.v_c.q),
            c(x.i_g.d, x.i_g.q),
            c(x.i_f.d, x.i_f.q),
        );
        let ig_phasor = (vc - c(vg.d, vg.q)) / c(d.r_t, d.l_t);
        let if_phasor = ig + c(0.0, d.c_f) * vc;
        let vm_phasor = vc + c(d.r_f, d.l_f) * i_f;
        assert!(dvpp_math::cabs(ig - ig_phasor) < 1e-9, "{ig} {ig_phasor}");
        assert!(dvpp_math::cabs(i_f - if_phasor) < 1e-9);
        assert!(dvpp_math::cabs(vm_phasor - c(vm.d, vm.q)) < 1e-9);
    }
}
