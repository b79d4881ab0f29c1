//! Turbine-governor models: case data, validation, states, initialization and derivatives.
//!
//! Every model is one variant of [`Governor`]; all that the grid needs of it (state count,
//! initialization, mechanical power, derivatives, limits, time constants) is in this file, so a
//! new model is added here alone. Powers are in pu of the machine rating, speeds in pu.

use crate::error::{check_range, nonneg, pos, CaseError};
use crate::numerics::{limited, TimeConstant};
use serde::{Deserialize, Serialize};

/// Turbine-governor. All powers in pu of the machine rating; `r` is the permanent droop.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Governor {
    /// Steam: droop 1/r, governor lag t_g, steam chest t_ch, reheater t_rh with HP fraction f_hp.
    TgovReheat {
        r: f64,
        t_g: f64,
        t_ch: f64,
        t_rh: f64,
        f_hp: f64,
        #[serde(default = "default_pmax")]
        p_max: f64,
        #[serde(default)]
        p_min: f64,
    },
    /// Hydro: droop 1/r, transient-droop lead-lag (t_r s + 1)/(t_2 s + 1), gate servo t_g,
    /// water column (1 - t_w s)/(1 + 0.5 t_w s).
    Hygov {
        r: f64,
        t_r: f64,
        t_2: f64,
        t_g: f64,
        t_w: f64,
        #[serde(default = "default_pmax")]
        p_max: f64,
        #[serde(default)]
        p_min: f64,
    },
}

fn default_pmax() -> f64 {
    10.0
}

/// States of `tgov_reheat`, relative to the governor's first state.
mod tgov {
    /// Valve position (governor lag output), limited.
    pub const VALVE: usize = 0;
    /// Steam-chest (HP) power.
    pub const CHEST: usize = 1;
    /// Reheater (LP) power.
    pub const REHEAT: usize = 2;
    pub const N: usize = 3;
}

/// States of `hygov`, relative to the governor's first state.
mod hygov {
    /// Lag state of the transient-droop lead-lag.
    pub const DROOP: usize = 0;
    /// Gate position, limited.
    pub const GATE: usize = 1;
    /// Water-column state (flow).
    pub const FLOW: usize = 2;
    pub const N: usize = 3;
}

impl Governor {
    /// Number of states the model keeps.
    pub(crate) fn n_states(&self) -> usize {
        match self {
            Governor::TgovReheat { .. } => tgov::N,
            Governor::Hygov { .. } => hygov::N,
        }
    }

    /// Permanent droop, pu speed per pu power on the machine rating.
    pub(crate) fn droop(&self) -> f64 {
        match self {
            Governor::TgovReheat { r, .. } | Governor::Hygov { r, .. } => *r,
        }
    }

    /// Check the parameters; `el` names the machine in errors.
    pub(crate) fn validate(&self, el: &str) -> Result<(), CaseError> {
        match self {
            Governor::TgovReheat {
                r,
                t_g,
                t_ch,
                t_rh,
                f_hp,
                p_max,
                p_min,
            } => {
                check_range(el, "governor.r", *r, *r > 0.0 && *r < 1.0, "0 < r < 1")?;
                pos(el, "governor.t_g", *t_g)?;
                pos(el, "governor.t_ch", *t_ch)?;
                pos(el, "governor.t_rh", *t_rh)?;
                check_range(
                    el,
                    "governor.f_hp",
                    *f_hp,
                    (0.0..=1.0).contains(f_hp),
                    "0..1",
                )?;
                check_range(el, "governor.p_max", *p_max, p_max > p_min, "> p_min")
            }
            Governor::Hygov {
                r,
                t_r,
                t_2,
                t_g,
                t_w,
                p_max,
                p_min,
            } => {
                check_range(el, "governor.r", *r, *r > 0.0 && *r < 1.0, "0 < r < 1")?;
                nonneg(el, "governor.t_r", *t_r)?;
                pos(el, "governor.t_2", *t_2)?;
                pos(el, "governor.t_g", *t_g)?;
                pos(el, "governor.t_w", *t_w)?;
                check_range(el, "governor.p_max", *p_max, p_max > p_min, "> p_min")
            }
        }
    }

    /// The time constants of the model's states (what the integration step must resolve);
    /// `prefix` names the machine, e.g. `machine[2]`.
    pub(crate) fn time_constants(&self, prefix: &str) -> Vec<TimeConstant> {
        let tc = |p: &str, v: f64| TimeConstant::new(format!("{prefix}.governor.{p}"), v);
        match self {
            Governor::TgovReheat {
                t_g, t_ch, t_rh, ..
            } => {
                vec![tc("t_g", *t_g), tc("t_ch", *t_ch), tc("t_rh", *t_rh)]
            }
            Governor::Hygov { t_2, t_g, t_w, .. } => vec![
                tc("t_2", *t_2),
                tc("t_g", *t_g),
                tc("t_w", *t_w).effective(0.5 * t_w, "water column 0.5 t_w"),
            ],
        }
    }

    /// Initialize the states `x` for the steady mechanical power `pm` (machine base) and return
    /// the reference `p_ref` that holds it at nominal speed.
    pub(crate) fn init(&self, pm: f64, x: &mut [f64]) -> Result<f64, String> {
        match self {
            Governor::TgovReheat { p_max, p_min, .. } => {
                if pm > *p_max || pm < *p_min {
                    return Err(format!(
                        "initial mechanical power {pm:.4} pu outside governor limits"
                    ));
                }
                x[tgov::VALVE] = pm;
                x[tgov::CHEST] = pm;
                x[tgov::REHEAT] = pm;
            }
            Governor::Hygov { p_max, p_min, .. } => {
                if pm > *p_max || pm < *p_min {
                    return Err(format!("initial gate {pm:.4} pu outside governor limits"));
                }
                x[hygov::DROOP] = 0.0;
                x[hygov::GATE] = pm;
                x[hygov::FLOW] = pm;
            }
        }
        Ok(pm)
    }

    /// Mechanical power, pu on the machine rating.
    pub(crate) fn pm(&self, x: &[f64]) -> f64 {
        match self {
            Governor::TgovReheat { f_hp, .. } => {
                f_hp * x[tgov::CHEST] + (1.0 - f_hp) * x[tgov::REHEAT]
            }
            Governor::Hygov { .. } => 3.0 * x[hygov::FLOW] - 2.0 * x[hygov::GATE],
        }
    }

    /// Derivatives `dx` of the states `x` at speed deviation `dw` (pu) and reference `pref`.
    pub(crate) fn deriv(&self, pref: f64, dw: f64, x: &[f64], dx: &mut [f64]) {
        match self {
            Governor::TgovReheat {
                r,
                t_g,
                t_ch,
                t_rh,
                p_max,
                p_min,
                ..
            } => {
                let (valve, chest, reheat) = (x[tgov::VALVE], x[tgov::CHEST], x[tgov::REHEAT]);
                let u = pref - dw / r;
                dx[tgov::VALVE] = limited((u - valve) / t_g, valve, *p_min, *p_max);
                dx[tgov::CHEST] = (valve - chest) / t_ch;
                dx[tgov::REHEAT] = (chest - reheat) / t_rh;
            }
            Governor::Hygov {
                r,
                t_r,
                t_2,
                t_g,
                t_w,
                p_max,
                p_min,
            } => {
                let (droop, gate, flow) = (x[hygov::DROOP], x[hygov::GATE], x[hygov::FLOW]);
                let u = dw / r;
                dx[hygov::DROOP] = (u - droop) / t_2;
                let c = droop + t_r / t_2 * (u - droop);
                let gref = pref - c;
                dx[hygov::GATE] = limited((gref - gate) / t_g, gate, *p_min, *p_max);
                dx[hygov::FLOW] = (gate - flow) / (0.5 * t_w);
            }
        }
    }

    /// Hold the limited states inside their limits (after an integration step).
    pub(crate) fn clamp(&self, x: &mut [f64]) {
        match self {
            Governor::TgovReheat { p_max, p_min, .. } => {
                x[tgov::VALVE] = x[tgov::VALVE].clamp(*p_min, *p_max)
            }
            Governor::Hygov { p_max, p_min, .. } => {
                x[hygov::GATE] = x[hygov::GATE].clamp(*p_min, *p_max)
            }
        }
    }
}
