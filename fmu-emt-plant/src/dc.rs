//! One unit's dc side: the primary source's first-order lag and the dc link as an energy store,
//! stepped as an exact energy balance (pu on the unit's rating, energies in pu·s).
//!
//! The source current follows `τ_dc i_src' = i_dc_ref - i_src` exactly (held command). The link
//! stores `W = C_dc v_dc²/2` and `W(t+h) = W(t) + E_src - E_loss - E_ac`: `E_ac` is the exact
//! integral of the converter power over the step (from the ac circuit), `E_src = v̄ ∫ i_src`
//! and `E_loss = G_dc h (v_dc(t)² + v̂²)/2` with `v̄` the mean of `v_dc(t)` and a predicted
//! `v̂ = v_dc(t+h)`: a second-order rule whose terms sum, by construction, to the change of the
//! stored energy, so the account closes to rounding.

use serde::{Deserialize, Serialize};

/// Parameters of the dc side.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DcParams {
    /// Dc-link capacitance as the link's energy time constant: `W = C_dc v_dc²/2` pu·s.
    pub c: f64,
    /// Link conductance (losses `G_dc v_dc²`).
    pub g: f64,
    /// Source lag, s.
    pub tau: f64,
}

/// The dc side's state.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DcState {
    /// Source current, pu of `S_rated/v_dc*`.
    pub i_src: f64,
    /// Stored energy, pu·s on `S_rated`.
    pub w: f64,
}

/// Energies over one step, pu·s.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DcStep {
    pub source: f64,
    pub loss: f64,
}

impl DcState {
    /// At `v_dc = 1` with the source covering `p_conv` and the link losses.
    pub fn steady(p: &DcParams, p_conv: f64) -> Self {
        DcState {
            i_src: p_conv + p.g,
            w: 0.5 * p.c,
        }
    }

    /// Dc voltage, pu of `v_dc*`.
    pub fn v(&self, p: &DcParams) -> f64 {
        (2.0 * self.w.max(0.0) / p.c).sqrt()
    }

    /// One step of `h` with the command `i_ref` held and `e_ac` drawn by the converter.
    pub fn step(&mut self, p: &DcParams, i_ref: f64, e_ac: f64, h: f64) -> DcStep {
        let decay = (-h / p.tau).exp();
        let d = self.i_src - i_ref;
        // ∫ i_src over the step: i_ref h + d τ (1 - e^{-h/τ}) (the last with exp_m1 for accuracy).
        let charge = i_ref * h - d * p.tau * (-h / p.tau).exp_m1();
        let v0 = self.v(p);
        let predicted = self.w + v0 * charge - p.g * v0 * v0 * h - e_ac;
        let v1 = (2.0 * predicted.max(0.0) / p.c).sqrt();
        let source = 0.5 * (v0 + v1) * charge;
        let loss = p.g * h * 0.5 * (v0 * v0 + v1 * v1);
        self.w += source - loss - e_ac;
        self.i_src = i_ref + d * decay;
        DcStep { source, loss }
    }
}
