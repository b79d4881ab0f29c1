//! Excitation-system models: case data, validation, states, initialization and derivatives.
//!
//! Every model is one variant of [`Exciter`]; all that the grid needs of it (state count,
//! initialization, field voltage, derivatives, limits, time constants) is in this file, so a new
//! model is added here alone. Voltages are in pu, the field voltage on the machine's E_fd base.

use crate::error::{check_range, nonneg, pos, CaseError};
use crate::numerics::{limited, TimeConstant};
use serde::{Deserialize, Serialize};

/// Excitation system (voltage regulator), on the machine's field-voltage pu.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Exciter {
    /// Simplified exciter: lead-lag (ta_tb·t_b s + 1)/(t_b s + 1), then k/(t_e s + 1), limited.
    Sexs {
        k: f64,
        ta_tb: f64,
        t_b: f64,
        t_e: f64,
        #[serde(default = "default_emin")]
        e_min: f64,
        #[serde(default = "default_emax")]
        e_max: f64,
    },
    /// IEEE type 1 (DC exciter with rate feedback); saturation S_E = se_a·exp(se_b·E_fd).
    IeeeT1 {
        ka: f64,
        ta: f64,
        ke: f64,
        te: f64,
        kf: f64,
        tf: f64,
        #[serde(default)]
        se_a: f64,
        #[serde(default)]
        se_b: f64,
        #[serde(default = "default_emin")]
        vr_min: f64,
        #[serde(default = "default_emax")]
        vr_max: f64,
    },
}

fn default_emin() -> f64 {
    -10.0
}
fn default_emax() -> f64 {
    10.0
}

/// States of `sexs`, relative to the exciter's first state.
mod sexs {
    /// Lag state of the lead-lag.
    pub const LEAD_LAG: usize = 0;
    /// Field voltage, limited.
    pub const EFD: usize = 1;
    pub const N: usize = 2;
}

/// States of `ieee_t1`, relative to the exciter's first state.
mod ieee_t1 {
    /// Field voltage (exciter output).
    pub const EFD: usize = 0;
    /// Regulator output, limited.
    pub const VR: usize = 1;
    /// Rate-feedback state.
    pub const RF: usize = 2;
    pub const N: usize = 3;
}

impl Exciter {
    /// Number of states the model keeps.
    pub(crate) fn n_states(&self) -> usize {
        match self {
            Exciter::Sexs { .. } => sexs::N,
            Exciter::IeeeT1 { .. } => ieee_t1::N,
        }
    }

    /// Check the parameters; `el` names the machine in errors.
    pub(crate) fn validate(&self, el: &str) -> Result<(), CaseError> {
        match self {
            Exciter::Sexs {
                k,
                ta_tb,
                t_b,
                t_e,
                e_min,
                e_max,
            } => {
                pos(el, "exciter.k", *k)?;
                nonneg(el, "exciter.ta_tb", *ta_tb)?;
                pos(el, "exciter.t_b", *t_b)?;
                pos(el, "exciter.t_e", *t_e)?;
                check_range(el, "exciter.e_max", *e_max, e_max > e_min, "> e_min")
            }
            Exciter::IeeeT1 {
                ka,
                ta,
                ke,
                te,
                kf,
                tf,
                se_a,
                se_b,
                vr_min,
                vr_max,
            } => {
                pos(el, "exciter.ka", *ka)?;
                pos(el, "exciter.ta", *ta)?;
                nonneg(el, "exciter.ke", *ke)?;
                pos(el, "exciter.te", *te)?;
                nonneg(el, "exciter.kf", *kf)?;
                pos(el, "exciter.tf", *tf)?;
                nonneg(el, "exciter.se_a", *se_a)?;
                nonneg(el, "exciter.se_b", *se_b)?;
                check_range(el, "exciter.vr_max", *vr_max, vr_max > vr_min, "> vr_min")
            }
        }
    }

    /// The time constants of the model's states (what the integration step must resolve);
    /// `prefix` names the machine, e.g. `machine[2]`.
    pub(crate) fn time_constants(&self, prefix: &str) -> Vec<TimeConstant> {
        let tc = |p: &str, v: f64| TimeConstant::new(format!("{prefix}.exciter.{p}"), v);
        match self {
            Exciter::Sexs { t_b, t_e, .. } => vec![tc("t_b", *t_b), tc("t_e", *t_e)],
            Exciter::IeeeT1 { ta, te, tf, .. } => vec![tc("ta", *ta), tc("te", *te), tc("tf", *tf)],
        }
    }

    /// Initialize the states `x` for the steady field voltage `efd` at terminal voltage `vt`
    /// and return the voltage reference that holds it.
    pub(crate) fn init(&self, efd: f64, vt: f64, x: &mut [f64]) -> Result<f64, String> {
        match self {
            Exciter::Sexs {
                k, e_min, e_max, ..
            } => {
                if efd > *e_max || efd < *e_min {
                    return Err(format!(
                        "initial field voltage {efd:.4} outside exciter limits"
                    ));
                }
                let u0 = efd / k;
                x[sexs::LEAD_LAG] = u0;
                x[sexs::EFD] = efd;
                Ok(vt + u0)
            }
            Exciter::IeeeT1 {
                ka,
                ke,
                kf,
                tf,
                se_a,
                se_b,
                vr_min,
                vr_max,
                ..
            } => {
                let se = se_a * (se_b * efd).exp();
                let vr = (ke + se) * efd;
                if vr > *vr_max || vr < *vr_min {
                    return Err(format!("initial regulator output {vr:.4} outside limits"));
                }
                x[ieee_t1::EFD] = efd;
                x[ieee_t1::VR] = vr;
                x[ieee_t1::RF] = kf / tf * efd;
                Ok(vt + vr / ka)
            }
        }
    }

    /// Field voltage.
    pub(crate) fn efd(&self, x: &[f64]) -> f64 {
        match self {
            Exciter::Sexs { .. } => x[sexs::EFD],
            Exciter::IeeeT1 { .. } => x[ieee_t1::EFD],
        }
    }

    /// Derivatives `dx` of the states `x` for reference `vref` and terminal voltage `vt`.
    pub(crate) fn deriv(&self, vref: f64, vt: f64, x: &[f64], dx: &mut [f64]) {
        match self {
            Exciter::Sexs {
                k,
                ta_tb,
                t_b,
                t_e,
                e_min,
                e_max,
            } => {
                let (ll, efd) = (x[sexs::LEAD_LAG], x[sexs::EFD]);
                let e = vref - vt;
                dx[sexs::LEAD_LAG] = (e - ll) / t_b;
                let u = ll + ta_tb * (e - ll);
                dx[sexs::EFD] = limited((k * u - efd) / t_e, efd, *e_min, *e_max);
            }
            Exciter::IeeeT1 {
                ka,
                ta,
                ke,
                te,
                kf,
                tf,
                se_a,
                se_b,
                vr_min,
                vr_max,
            } => {
                let (efd, vr, rf) = (x[ieee_t1::EFD], x[ieee_t1::VR], x[ieee_t1::RF]);
                let se = se_a * (se_b * efd).exp();
                dx[ieee_t1::EFD] = (-(ke + se) * efd + vr) / te;
                let dvr = (-vr + ka * rf - ka * kf / tf * efd + ka * (vref - vt)) / ta;
                dx[ieee_t1::VR] = limited(dvr, vr, *vr_min, *vr_max);
                dx[ieee_t1::RF] = (-rf + kf / tf * efd) / tf;
            }
        }
    }

    /// Hold the limited states inside their limits (after an integration step).
    pub(crate) fn clamp(&self, x: &mut [f64]) {
        match self {
            Exciter::Sexs { e_min, e_max, .. } => x[sexs::EFD] = x[sexs::EFD].clamp(*e_min, *e_max),
            Exciter::IeeeT1 { vr_min, vr_max, .. } => {
                x[ieee_t1::VR] = x[ieee_t1::VR].clamp(*vr_min, *vr_max)
            }
        }
    }
}
