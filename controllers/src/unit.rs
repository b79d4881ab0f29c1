//! The parameter groups and inputs every DVPP unit has alike, at any level of modelling: rating and bases, the PLL, the dc side, the primary source, the operator's dc gains.

use crate::layer;
use crate::MAX_LPF;
use serde::{Deserialize, Serialize};

/// Rating and bases (`S_rated`, `S_base`, `S_dvpp` in MVA, `f_nom` in Hz).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Rating {
    /// `S_rated`: the converter's rating; the unit's own per-unit base.
    pub s_rated: f64,
    /// `S_base`: the system base its powers are given on.
    pub s_base: f64,
    /// `S_dvpp`: the DVPP base `T_des` is specified on.
    pub s_dvpp: f64,
    /// `f_nom`.
    pub f_nom: f64,
}

/// The PLL's gains (`pll.kp`, `pll.ki`) and the grid-following references' roll-off
/// `1/(pll.tau s + 1)^pll.order`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PllParams {
    pub kp: f64,
    pub ki: f64,
    pub tau: f64,
    pub order: u32,
}

/// The dc side: the source's lag `tau_dc`, the link `C_dc`, `G_dc` (pu on `S_rated`), the
/// dc-voltage control's gain `k_dc` and the damping ratio `dc.zeta` its capacitor-power term gives.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DcLinkParams {
    pub tau_dc: f64,
    pub c_dc: f64,
    pub g_dc: f64,
    pub k_dc: f64,
    pub zeta: f64,
}

/// The primary source: `storage` (it can absorb power), `deload`, and its availability
/// `P_avail0` stepped by `avail.dP` at `avail.t_step` (pu on `S_base`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SourceParams {
    pub storage: bool,
    pub deload: f64,
    pub p_avail0: f64,
    pub avail_t: f64,
    pub avail_dp: f64,
}

impl SourceParams {
    /// The source's availability at `t` (pu on `S_base`).
    pub fn available(&self, t: f64) -> f64 {
        layer::availability(self.p_avail0, self.avail_t, self.avail_dp, t)
    }
}

/// The operator's dc gains at this step (`mu_p`, `mu_q`, and for a complement unit the gains
/// `mu_p_lpf[k]` of the low-pass units it closes).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OperatorGains {
    pub mu_p: f64,
    pub mu_q: f64,
    pub mu_p_lpf: [f64; MAX_LPF],
}
