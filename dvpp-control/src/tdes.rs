//! The desired aggregate DVPP behaviour `T_des`: p-f channel `T_pf` and v-q channel `T_qv`.
//!
//! Sign convention (grid-forming causality, DVPP base `S_dvpp`):
//! `Δf_pcc = −T_pf(s) Δp_pcc`, `Δv_pcc = −T_qv(s) Δq_pcc`. The inverse of the v-q channel used by
//! the units is augmented by the noise roll-off `1/(τ_q s + 1)`.

use crate::error::{check_finite, check_tau, DvppError, Result};
use crate::ss::{Hold, LtiSimulator};
use crate::tf::TransferFunction;
use nalgebra::Complex;
use serde::{Deserialize, Serialize};

/// Desired DVPP behaviour `T_des = diag(T_pf, T_qv)` plus the v-q roll-off `τ_q`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TDes {
    pf: TransferFunction,
    qv: TransferFunction,
    tau_q: f64,
}

impl TDes {
    /// Case-study form: `T_pf = 1/(H s + D)`, `T_qv = D_q`, roll-off `τ_q`.
    ///
    /// Errors: non-finite or subnormal values; `H s + D` not Hurwitz (`H < 0`, `D ≤ 0`, …) →
    /// [`DvppError::Unstable`]; `D_q ≤ 0` → [`DvppError::InvalidParameter`]; `τ_q ≤ 0`.
    pub fn inertia_droop(h: f64, d: f64, dq: f64, tau_q: f64) -> Result<Self> {
        check_finite("T_des H", h)?;
        check_finite("T_des D", d)?;
        check_finite("T_des D_q", dq)?;
        // Zero or normal: a subnormal coefficient overflows when the channels are realized.
        for (what, x) in [
            ("T_des H", h),
            ("T_des D", d),
            ("T_des D_q", dq),
            ("T_des tau_q", tau_q),
        ] {
            if x != 0.0 && !x.is_normal() {
                return Err(DvppError::InvalidParameter {
                    what: what.into(),
                    reason: format!(
                        "{x:e} is subnormal (nonzero but below {:e})",
                        f64::MIN_POSITIVE
                    ),
                });
            }
        }
        if dq <= 0.0 {
            return Err(DvppError::InvalidParameter {
                what: "T_des D_q".into(),
                reason: format!("q-v droop must be > 0, got {dq}"),
            });
        }
        let pf = TransferFunction::new(vec![1.0], vec![d, h])?;
        let qv = TransferFunction::gain(dq)?;
        Self::general(pf, qv, tau_q)
    }

    /// General proper rational channels. `T_pf` and `T_qv` must be stable and non-zero, and
    /// `T_qv⁻¹/(τ_q s + 1)` must be proper (`T_qv` of relative degree ≤ 1).
    pub fn general(pf: TransferFunction, qv: TransferFunction, tau_q: f64) -> Result<Self> {
        check_tau("T_des tau_q", tau_q)?;
        if pf.is_zero() || qv.is_zero() {
            return Err(DvppError::ZeroPolynomial {
                what: "T_des channel".into(),
            });
        }
        if !pf.is_stable() {
            return Err(DvppError::Unstable {
                what: "T_des p-f channel T_pf".into(),
            });
        }
        if !qv.is_stable() {
            return Err(DvppError::Unstable {
                what: "T_des q-v channel T_qv".into(),
            });
        }
        let out = Self { pf, qv, tau_q };
        out.vq_reference()?;
        Ok(out)
    }

    /// `T_pf`.
    pub fn pf(&self) -> &TransferFunction {
        &self.pf
    }

    /// `T_qv`.
    pub fn qv(&self) -> &TransferFunction {
        &self.qv
    }

    /// `τ_q`.
    pub fn tau_q(&self) -> f64 {
        self.tau_q
    }

    /// `T_qv⁻¹ / (τ_q s + 1)`: the aggregate v→q reference the units share.
    pub fn vq_reference(&self) -> Result<TransferFunction> {
        TransferFunction::lag_power(self.tau_q, 1)?.div(&self.qv)
    }

    /// `T_pf(jω)`.
    pub fn pf_at(&self, omega: f64) -> Complex<f64> {
        self.pf.freq_response(omega)
    }

    /// `T_pf(jω)⁻¹` (the aggregate admittance `H jω + D` in the case-study form).
    pub fn pf_inverse_at(&self, omega: f64) -> Complex<f64> {
        Complex::new(1.0, 0.0) / self.pf.freq_response(omega)
    }

    /// Simulator of `T_pf` (input `Δp_pcc`, output `+T_pf Δp`; negate for `Δf_pcc`).
    pub fn pf_simulator(&self, hold: Hold) -> LtiSimulator {
        LtiSimulator::new(self.pf.to_state_space(), hold)
    }
}
