//! Scheduled events (load steps, generator and line trips): their state, overrides and firing;
//! under-frequency load shedding.

use super::Grid;
use crate::case::{Event, LoadModel};
use crate::error::GridError;
use crate::numerics::{C64, EVENT_EPS};
use serde::{Deserialize, Serialize};

/// Changes to a scheduled event (None keeps the case value).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EventOverride {
    pub enabled: Option<bool>,
    pub time: Option<f64>,
    /// Load steps only.
    pub dp_mw: Option<f64>,
    pub dq_mvar: Option<f64>,
}

/// A scheduled event and whether it has fired.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EventState {
    pub event: Event,
    pub enabled: bool,
    pub fired: bool,
}

impl Grid {
    /// Scheduled events and their state.
    pub fn events(&self) -> &[EventState] {
        &self.events
    }

    /// Change a scheduled event (0-based index) before it fires.
    pub fn set_event_override(&mut self, i: usize, ov: EventOverride) -> Result<(), GridError> {
        let es = self.events.get_mut(i).ok_or(GridError::BadEvent {
            index: i,
            reason: "no such event".into(),
        })?;
        if es.fired {
            return Err(GridError::BadEvent {
                index: i,
                reason: "event has already fired".into(),
            });
        }
        if let Some(en) = ov.enabled {
            es.enabled = en;
        }
        if let Some(t) = ov.time {
            if !(t.is_finite() && t >= 0.0) {
                return Err(GridError::BadEvent {
                    index: i,
                    reason: format!("bad time {t}"),
                });
            }
            match &mut es.event {
                Event::LoadStep { time, .. }
                | Event::GeneratorTrip { time, .. }
                | Event::LineTrip { time, .. } => *time = t,
            }
        }
        if ov.dp_mw.is_some() || ov.dq_mvar.is_some() {
            match &mut es.event {
                Event::LoadStep { dp_mw, dq_mvar, .. } => {
                    if let Some(p) = ov.dp_mw {
                        *dp_mw = p;
                    }
                    if let Some(q) = ov.dq_mvar {
                        *dq_mvar = q;
                    }
                }
                _ => {
                    return Err(GridError::BadEvent {
                        index: i,
                        reason: "dp/dq override on an event that is not a load step".into(),
                    })
                }
            }
        }
        Ok(())
    }

    /// Disable every scheduled event.
    pub fn disable_events(&mut self) {
        for e in &mut self.events {
            e.enabled = false;
        }
    }

    /// Add an event (validated against the case).
    pub fn add_event(&mut self, ev: Event) -> Result<(), GridError> {
        let mut c = self.case.clone();
        c.events = vec![ev.clone()];
        c.validate().map_err(|e| GridError::BadEvent {
            index: self.events.len(),
            reason: e.to_string(),
        })?;
        self.events.push(EventState {
            event: ev,
            enabled: true,
            fired: false,
        });
        Ok(())
    }

    pub(crate) fn fire_due_events(&mut self) -> Result<(), GridError> {
        let mut changed = false;
        for i in 0..self.events.len() {
            let es = &self.events[i];
            if !es.enabled || es.fired || es.event.time() > self.t + EVENT_EPS {
                continue;
            }
            let ev = es.event.clone();
            let idx = self.case.bus_index();
            match ev {
                Event::LoadStep {
                    bus,
                    dp_mw,
                    dq_mvar,
                    model,
                    ..
                } => {
                    let b = idx[&bus];
                    let s = C64::new(dp_mw, dq_mvar) / self.sb;
                    match model {
                        LoadModel::ConstantImpedance => {
                            self.load_y[b] += s.conj() / self.sol.v[b].norm_sqr().max(1e-6)
                        }
                        LoadModel::ConstantPower => self.load_s[b] += s,
                    }
                }
                Event::GeneratorTrip { machine, .. } => {
                    self.machines[machine - 1].in_service = false;
                }
                Event::LineTrip { branch, .. } => {
                    let k = self.branches.iter().position(|b| b.name == branch).ok_or(
                        GridError::BadEvent {
                            index: i,
                            reason: format!("unknown branch {branch}"),
                        },
                    )?;
                    self.branches[k].in_service = false;
                }
            }
            self.events[i].fired = true;
            changed = true;
        }
        if self.switch_fault() {
            changed = true;
        }
        if changed {
            self.net = None;
            self.resolve()?;
        }
        Ok(())
    }

    /// Time of the next enabled event that has not fired yet, or of the fault's next switching
    /// (infinite if none).
    pub(crate) fn next_event_time(&self) -> f64 {
        self.events
            .iter()
            .filter(|e| e.enabled && !e.fired && e.event.time() > self.t + EVENT_EPS)
            .map(|e| e.event.time())
            .fold(f64::INFINITY, f64::min)
            .min(self.next_fault_time())
    }
}

/// The state of one under-frequency shedding stage.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub(crate) struct UflsState {
    /// Since when the centre-of-inertia frequency has been below the stage's threshold.
    pub below_since: Option<f64>,
    pub acted: bool,
}

impl Grid {
    /// Under-frequency load shedding after an internal step: every stage whose threshold the
    /// centre-of-inertia frequency has been below for the stage's delay sheds its share of the
    /// loads at the power-flow point. Nothing to do without machines in service.
    pub(crate) fn shed_load(&mut self) -> Result<(), GridError> {
        if self.ufls.is_empty() {
            return Ok(());
        }
        let Some(f) = self.coi_frequency() else {
            return Ok(());
        };
        let f_hz = f * self.case.f_nom;
        let mut shed = 0.0;
        for (st, s) in self.case.ufls.iter().zip(&mut self.ufls) {
            if s.acted {
                continue;
            }
            if f_hz < st.f_hz {
                let since = *s.below_since.get_or_insert(self.t);
                if self.t - since >= st.delay - EVENT_EPS {
                    s.acted = true;
                    shed += st.shed;
                }
            } else {
                s.below_since = None;
            }
        }
        if shed > 0.0 {
            for b in 0..self.n {
                self.load_y[b] -= self.load_y0[b] * shed;
                self.load_s[b] -= self.load_s0[b] * shed;
            }
            self.net = None;
            self.resolve()?;
        }
        Ok(())
    }

    /// The share of the power-flow point's load shed so far by under-frequency stages.
    pub fn load_shed(&self) -> f64 {
        self.case
            .ufls
            .iter()
            .zip(&self.ufls)
            .filter(|(_, s)| s.acted)
            .map(|(st, _)| st.shed)
            .sum()
    }
}
