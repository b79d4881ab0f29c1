//! A balanced bus fault: a shunt admittance `1/(R + jX)` at one bus of the network solution from its time to its clearing.
//!
//! The phasor twin of the EMT plant's three-phase fault (`fault.*`, docs/emt.md §13): the
//! fault is applied at `t` and cleared at `t + duration`, both exactly (the grid's internal
//! steps are split there, as at a scheduled event). A grid with no fault set solves the network
//! exactly as before: the admittance enters the matrix only while the fault is on.

use super::Grid;
use crate::error::GridError;
use crate::numerics::{C64, EVENT_EPS};
use serde::{Deserialize, Serialize};

/// A balanced fault at a bus: impedance `r + jx` (pu on S_base) to ground from `t` for
/// `duration` seconds.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BusFault {
    /// Bus id of the case.
    pub bus: u32,
    /// Fault resistance and reactance, pu on S_base (at least one positive).
    pub r: f64,
    pub x: f64,
    /// Time the fault is applied, s.
    pub t: f64,
    /// Time from application to clearing, s.
    pub duration: f64,
}

/// A fault as the simulation uses it: its bus index, admittance and whether it has been applied
/// and cleared.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct FaultRt {
    pub fault: BusFault,
    pub bus: usize,
    pub y: C64,
    pub applied: bool,
    pub cleared: bool,
}

impl FaultRt {
    /// Whether the fault is in the network now.
    pub fn on(&self) -> bool {
        self.applied && !self.cleared
    }
}

/// What a fault draws at the present network solution.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FaultOutput {
    /// The fault is in the network.
    pub on: bool,
    /// Magnitude of the fault current, pu on S_base (0 while the fault is off).
    pub i: f64,
    /// Voltage magnitude at the faulted bus, pu (also while the fault is off).
    pub v: f64,
}

impl Grid {
    /// Set (Some) or remove (None) the bus fault, before it is applied. Errors name the field:
    /// `fault.bus` (not a bus of the case), `fault.R`, `fault.X` (negative, not finite, or both
    /// zero), `fault.t`, `fault.duration` (negative or not finite).
    pub fn set_fault(&mut self, fault: Option<BusFault>) -> Result<(), GridError> {
        if self.fault.as_ref().is_some_and(|f| f.applied) {
            return Err(GridError::BadFault {
                field: "fault.t".into(),
                reason: "the fault has already been applied".into(),
            });
        }
        let Some(f) = fault else {
            self.fault = None;
            return Ok(());
        };
        let bad = |field: &str, reason: String| GridError::BadFault {
            field: field.into(),
            reason,
        };
        let idx = self.case.bus_index();
        let bus = *idx.get(&f.bus).ok_or_else(|| {
            let ids: Vec<String> = self.case.buses.iter().map(|b| b.id.to_string()).collect();
            bad(
                "fault.bus",
                format!(
                    "{} is not a bus of case {} (its buses: {}; 0: no fault)",
                    f.bus,
                    self.case.name,
                    ids.join(", ")
                ),
            )
        })?;
        for (field, v) in [("fault.R", f.r), ("fault.X", f.x)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(field, format!("{v} pu: need a finite value >= 0")));
            }
        }
        if f.r == 0.0 && f.x == 0.0 {
            return Err(bad(
                "fault.X",
                "fault.R = fault.X = 0: a bolted fault has no phasor solution; take a small \
                 reactance (e.g. 0.001 pu)"
                    .into(),
            ));
        }
        for (field, v) in [("fault.t", f.t), ("fault.duration", f.duration)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(field, format!("{v} s: need a finite time >= 0")));
            }
        }
        self.fault = Some(FaultRt {
            fault: f,
            bus,
            y: C64::new(1.0, 0.0) / C64::new(f.r, f.x),
            applied: false,
            cleared: false,
        });
        Ok(())
    }

    /// The bus fault set (None: none).
    pub fn fault(&self) -> Option<BusFault> {
        self.fault.as_ref().map(|f| f.fault)
    }

    /// The fault's bus index and admittance while it is in the network.
    pub(crate) fn fault_shunt(&self) -> Option<(usize, C64)> {
        self.fault.as_ref().filter(|f| f.on()).map(|f| (f.bus, f.y))
    }

    /// What the fault draws now (all zero without a fault).
    pub fn fault_output(&self) -> FaultOutput {
        let Some(f) = &self.fault else {
            return FaultOutput::default();
        };
        let v = self.sol.v[f.bus];
        FaultOutput {
            on: f.on(),
            i: if f.on() {
                dvpp_math::cabs(f.y * v)
            } else {
                0.0
            },
            v: dvpp_math::cabs(v),
        }
    }

    /// Apply or clear the fault when its time has come; whether the network changed.
    pub(crate) fn switch_fault(&mut self) -> bool {
        let t = self.t;
        let Some(f) = self.fault.as_mut() else {
            return false;
        };
        let (t_on, t_off) = (f.fault.t, f.fault.t + f.fault.duration);
        let mut changed = false;
        if !f.applied && t_on <= t + EVENT_EPS {
            f.applied = true;
            changed = true;
        }
        if f.applied && !f.cleared && t_off <= t + EVENT_EPS {
            f.cleared = true;
            changed = true;
        }
        changed
    }

    /// The fault's next switching time after now (infinite if none).
    pub(crate) fn next_fault_time(&self) -> f64 {
        let Some(f) = &self.fault else {
            return f64::INFINITY;
        };
        let (t_on, t_off) = (f.fault.t, f.fault.t + f.fault.duration);
        let next = |done: bool, at: f64| {
            if !done && at > self.t + EVENT_EPS {
                at
            } else {
                f64::INFINITY
            }
        };
        next(f.applied, t_on).min(next(f.cleared, t_off))
    }
}
