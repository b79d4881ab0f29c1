//! DER slots as the simulation uses them: their inputs, set points, converter limits and the
//! current a slot injects at a bus voltage.

use crate::case::DerKind;
use crate::numerics::C64;
use serde::{Deserialize, Serialize};

/// Initial DER set points (what the DER controllers must hold for a flat start).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum DerSetpoint {
    /// Internal voltage angle (rad, frame at f_nom) and magnitude (pu).
    GridForming { theta0: f64, e0: f64 },
    /// Injected powers at the bus, pu on S_base.
    GridFollowing { p0: f64, q0: f64 },
}

/// Input of a DER slot.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum DerInput {
    GridForming { theta: f64, e: f64 },
    GridFollowing { p_ref: f64, q_ref: f64 },
}

/// The limits of a slot's converter output stage, enforced inside every network solution (a
/// converter's inner current loop acts within a fraction of a communication step, so its
/// saturation is algebraic): the active power it injects within `[p_min, p_max]` (pu on S_base;
/// the dc link's budget, grid-forming slots), then the current magnitude at most `i_max` (pu of
/// the slot rating at 1 pu voltage), keeping the current's direction.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SlotLimit {
    pub i_max: f64,
    pub p_min: f64,
    pub p_max: f64,
}

impl SlotLimit {
    /// No limit.
    pub const NONE: SlotLimit = SlotLimit {
        i_max: f64::INFINITY,
        p_min: f64::NEG_INFINITY,
        p_max: f64::INFINITY,
    };

    /// Whether this is [`SlotLimit::NONE`].
    pub fn is_none(&self) -> bool {
        *self == SlotLimit::NONE
    }
}

/// Below this bus voltage (pu) the active-power limits of a slot are not applied (a dead bus
/// has no direction; the current limit still holds).
const LIMIT_V_MIN: f64 = 1e-3;

/// A DER slot as the simulation uses it.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct DerRt {
    pub kind: DerKind,
    pub bus: usize,
    /// Series admittance on the system base (grid-forming).
    pub y: C64,
    pub input: DerInput,
    pub initial: DerSetpoint,
    /// Slot rating over S_base (converts `i_max` to the system base).
    pub rating: f64,
    pub limit: SlotLimit,
}

impl DerRt {
    /// The current the slot injects into its bus at voltage `v`: `y (E - V)` (grid-forming) or
    /// `conj(S/V)` (grid-following), within the slot's limits.
    pub(crate) fn current(&self, v: C64) -> C64 {
        let free = match self.input {
            DerInput::GridForming { theta, e } => self.y * (dvpp_math::cpolar(e, theta) - v),
            DerInput::GridFollowing { p_ref, q_ref } => {
                if dvpp_math::cabs(v) > 0.0 {
                    (C64::new(p_ref, q_ref) / v).conj()
                } else {
                    C64::new(0.0, 0.0)
                }
            }
        };
        if self.limit.is_none() {
            return free;
        }
        let mut i = free;
        let vm = dvpp_math::cabs(v);
        if vm > LIMIT_V_MIN {
            // Active part along the voltage: p = |V| i_p.
            let u = v / vm;
            let local = i * u.conj();
            let ip = local.re.clamp(self.limit.p_min / vm, self.limit.p_max / vm);
            i = C64::new(ip, local.im) * u;
        }
        let i_max = self.limit.i_max * self.rating;
        if dvpp_math::cabs(i) > i_max {
            i *= i_max / dvpp_math::cabs(i);
        }
        i
    }
}
