//! What both channels share: their common state, what a step hands them and what they report, the PLL model.

use super::dc::DcSide;
use super::limits::Episode;
use crate::MAX_LPF;
use dvpp_control::{Rotation, StateSpace, VqModel};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The state both channels share.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Common {
    pub(crate) vq: VqModel,
    pub(crate) dc: DcSide,
    pub(crate) p0: f64,
    pub(crate) q0: f64,
    pub(crate) v0: f64,
    pub(crate) e0: f64,
    pub(crate) theta0: f64,
    /// Grid-following: the PLL frequency held over the next step.
    pub(crate) df_held: f64,
    /// Grid-forming: the reactive reference held over the next step, rotated (`q'`; `q` when
    /// `rot.rx` = 0).
    pub(crate) q_ref: f64,
    /// `(p, q) ↔ (p', q')` for the lines' R/X (`rot.rx`; the identity at 0).
    pub(crate) rot: Rotation,
    /// Power the limits withheld at the last step (what the internal voltage would have
    /// delivered minus what the converter imposed), on S_base: the controls see the unlimited
    /// power, so the internal node stays synchronized while limited.
    pub(crate) withheld: (f64, f64),
    /// Waiting for the terminal voltage (a start from zero voltage); `None` once synchronized.
    pub(crate) startup: Option<Startup>,
    /// Time of synchronization after a start from zero voltage (the set point ramps from there).
    pub(crate) t_sync: Option<f64>,
    pub(crate) limit: LimitEpisodes,
    /// Warning already given in this episode.
    pub(crate) warned_gains: bool,
}

/// A unit waiting for the voltage to appear.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Startup {
    /// Since when the voltage has been above `startup.v_sync` and steady.
    pub(crate) ok_since: Option<f64>,
    pub(crate) v_last: f64,
}

/// The episodes of each limit (the `limit.*` outputs).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub(crate) struct LimitEpisodes {
    pub(crate) current: Episode,
    pub(crate) dc: Episode,
    pub(crate) source: Episode,
    pub(crate) modulation: Episode,
}

/// What the common part of a step hands to the channel's step.
#[derive(Clone, Copy)]
pub(crate) struct StepPoint {
    pub(crate) t: f64,
    pub(crate) h: f64,
    /// Terminal voltage deviation from the operating point, pu.
    pub(crate) dv: f64,
    /// S_base/S_dvpp and S_base/S_rated.
    pub(crate) to_dvpp: f64,
    pub(crate) to_rated: f64,
    /// The set point (dispatch, ramped, curtailed), pu on S_base.
    pub(crate) p_set: f64,
    /// The closed low-pass units' dc gains (a complement unit's, scaled to its share).
    pub(crate) lpf: [f64; MAX_LPF],
    pub(crate) v: f64,
    pub(crate) v_angle: f64,
    /// The dc link's active power budget for the ac side, pu on S_rated.
    pub(crate) budget: (f64, f64),
    pub(crate) i_max: f64,
    /// The operator's p-f dc gain `mu_p`.
    pub(crate) mu_p: f64,
}

/// What the channel's step reports to the limit episodes.
pub(crate) struct Outcome {
    pub(crate) current_limit: bool,
    pub(crate) dc_limit: bool,
    /// The current asked for, per unit of I_max.
    pub(crate) request: f64,
    pub(crate) modulation: bool,
}

/// Exact ZOH model of the PLL: `e = v_angle - θ_pll`, `Δω = k_p e + k_i ∫e`, `θ_pll' = Δω`;
/// outputs `Δf_pll = Δω/(2π f_nom)` (pu) and `θ_pll`.
pub(crate) fn pll_model(kp: f64, ki: f64, f_nom: f64) -> StateSpace {
    let w = 2.0 * PI * f_nom;
    StateSpace::new(
        DMatrix::from_row_slice(2, 2, &[0.0, -1.0, ki, -kp]),
        DVector::from_column_slice(&[1.0, kp]),
        DMatrix::from_row_slice(2, 2, &[ki / w, -kp / w, 0.0, 1.0]),
        DVector::from_column_slice(&[kp / w, 0.0]),
    )
    .expect("PLL realization")
}
