//! Power system stabilizers: case data, validation, states, output and derivatives.
//!
//! Every model is one variant of [`Pss`]; its output `V_s` adds to the exciter's voltage error
//! (see [`crate::exciter`]). Input: the rotor speed deviation Δω, pu.

use crate::error::{check_range, nonneg, pos, CaseError};
use crate::numerics::TimeConstant;
use serde::{Deserialize, Serialize};

/// Power system stabilizer, on the machine's field-voltage pu.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Pss {
    /// IEEE 421.5 PSS1A on the speed deviation, without its torsional filter:
    /// `V_s = ks · s t_w/(1 + s t_w) · (1 + s t_1)/(1 + s t_2) · (1 + s t_3)/(1 + s t_4) · Δω`,
    /// limited to [vs_min, vs_max].
    Pss1a {
        ks: f64,
        tw: f64,
        t1: f64,
        t2: f64,
        t3: f64,
        t4: f64,
        #[serde(default = "default_vs_min")]
        vs_min: f64,
        #[serde(default = "default_vs_max")]
        vs_max: f64,
    },
}

fn default_vs_min() -> f64 {
    -0.2
}
fn default_vs_max() -> f64 {
    0.2
}

/// States of `pss1a`, relative to the stabilizer's first state; all 0 at rest.
mod pss1a {
    /// Washout: the low-pass part of Δω (the output is Δω minus it).
    pub const WASHOUT: usize = 0;
    /// Lag state of the first lead-lag.
    pub const LL1: usize = 1;
    /// Lag state of the second lead-lag.
    pub const LL2: usize = 2;
    pub const N: usize = 3;
}

/// The signals of a PSS1A: washout output and the two lead-lags' outputs.
fn pss1a_chain(dw: f64, x: &[f64], (t1, t2, t3, t4): (f64, f64, f64, f64)) -> [f64; 3] {
    let w = dw - x[pss1a::WASHOUT];
    let y1 = x[pss1a::LL1] + t1 / t2 * (w - x[pss1a::LL1]);
    let y2 = x[pss1a::LL2] + t3 / t4 * (y1 - x[pss1a::LL2]);
    [w, y1, y2]
}

impl Pss {
    /// Number of states the model keeps.
    pub(crate) fn n_states(&self) -> usize {
        match self {
            Pss::Pss1a { .. } => pss1a::N,
        }
    }

    /// Check the parameters; `el` names the machine in errors.
    pub(crate) fn validate(&self, el: &str) -> Result<(), CaseError> {
        match self {
            Pss::Pss1a {
                ks,
                tw,
                t1,
                t2,
                t3,
                t4,
                vs_min,
                vs_max,
            } => {
                nonneg(el, "pss.ks", *ks)?;
                for (name, v) in [("tw", tw), ("t2", t2), ("t4", t4)] {
                    pos(el, &format!("pss.{name}"), *v)?;
                }
                nonneg(el, "pss.t1", *t1)?;
                nonneg(el, "pss.t3", *t3)?;
                check_range(el, "pss.vs_max", *vs_max, vs_max > vs_min, "> vs_min")
            }
        }
    }

    /// The time constants of the model's states; `prefix` names the machine.
    pub(crate) fn time_constants(&self, prefix: &str) -> Vec<TimeConstant> {
        let tc = |p: &str, v: f64| TimeConstant::new(format!("{prefix}.pss.{p}"), v);
        match self {
            Pss::Pss1a { tw, t2, t4, .. } => vec![tc("tw", *tw), tc("t2", *t2), tc("t4", *t4)],
        }
    }

    /// The stabilizer's output for speed deviation `dw` (pu) and states `x`.
    pub(crate) fn output(&self, dw: f64, x: &[f64]) -> f64 {
        match self {
            Pss::Pss1a {
                ks,
                t1,
                t2,
                t3,
                t4,
                vs_min,
                vs_max,
                ..
            } => {
                let [_, _, y2] = pss1a_chain(dw, x, (*t1, *t2, *t3, *t4));
                (ks * y2).clamp(*vs_min, *vs_max)
            }
        }
    }

    /// Derivatives `dx` of the states `x` for speed deviation `dw`.
    pub(crate) fn deriv(&self, dw: f64, x: &[f64], dx: &mut [f64]) {
        match self {
            Pss::Pss1a {
                tw, t1, t2, t3, t4, ..
            } => {
                let [w, y1, _] = pss1a_chain(dw, x, (*t1, *t2, *t3, *t4));
                dx[pss1a::WASHOUT] = w / tw;
                dx[pss1a::LL1] = (w - x[pss1a::LL1]) / t2;
                dx[pss1a::LL2] = (y1 - x[pss1a::LL2]) / t4;
            }
        }
    }
}
