//! Serialization of a [`Grid`] (FMU states): the case as TOML text plus the evolving state.

use super::events::{EventState, UflsState};
use super::fault::FaultRt;
use crate::case::{Case, Event};
use crate::grid::{DerInput, Grid, SlotLimit};
use crate::powerflow::C64;
use serde::{Deserialize, Serialize};

/// The serialized form of a [`Grid`]: the case (TOML text) and everything that evolves.
///
/// The case and event types use internally tagged enums (`type = "hygov"`), which only
/// self-describing formats can read back, so they travel as TOML text inside the snapshot.
#[derive(Serialize, Deserialize)]
struct GridSnapshot {
    case: String,
    /// The scheduled events, as TOML (`[[event]]` tables).
    events: String,
    /// (enabled, fired) per event.
    event_flags: Vec<(bool, bool)>,
    branch_in_service: Vec<bool>,
    machine_in_service: Vec<bool>,
    load_y: Vec<C64>,
    load_s: Vec<C64>,
    der_inputs: Vec<DerInput>,
    der_limits: Vec<SlotLimit>,
    x: Vec<f64>,
    t: f64,
    v: Vec<C64>,
    der_angle: Vec<f64>,
    pcc_angle: f64,
    poc_angle: Vec<f64>,
    h_max: f64,
    ufls: Vec<UflsState>,
    fault: Option<FaultRt>,
}

/// `[[event]]` tables of a snapshot.
#[derive(Serialize, Deserialize)]
struct EventList {
    #[serde(default)]
    event: Vec<Event>,
}

impl GridSnapshot {
    fn of(g: &Grid) -> Result<GridSnapshot, String> {
        let events = EventList {
            event: g.events.iter().map(|e| e.event.clone()).collect(),
        };
        Ok(GridSnapshot {
            case: toml::to_string(&g.case).map_err(|e| format!("case: {e}"))?,
            events: toml::to_string(&events).map_err(|e| format!("events: {e}"))?,
            event_flags: g.events.iter().map(|e| (e.enabled, e.fired)).collect(),
            branch_in_service: g.branches.iter().map(|b| b.in_service).collect(),
            machine_in_service: g.machines.iter().map(|m| m.in_service).collect(),
            load_y: g.load_y.clone(),
            load_s: g.load_s.clone(),
            der_inputs: g.ders.iter().map(|d| d.input).collect(),
            der_limits: g.ders.iter().map(|d| d.limit).collect(),
            x: g.x.clone(),
            t: g.t,
            v: g.sol.v.clone(),
            der_angle: g.der_angle.clone(),
            pcc_angle: g.pcc_angle,
            poc_angle: g.poc_angle.clone(),
            h_max: g.h_max,
            ufls: g.ufls.clone(),
            fault: g.fault.clone(),
        })
    }

    fn restore(self) -> Result<Grid, String> {
        let case = Case::from_toml_str(&self.case).map_err(|e| e.to_string())?;
        let mut g = Grid::new(&case).map_err(|e| e.to_string())?;
        let events: EventList = toml::from_str(&self.events).map_err(|e| e.to_string())?;
        let sizes = [
            (events.event.len(), self.event_flags.len(), "event flags"),
            (g.branches.len(), self.branch_in_service.len(), "branches"),
            (g.machines.len(), self.machine_in_service.len(), "machines"),
            (g.n, self.load_y.len(), "load admittances"),
            (g.n, self.load_s.len(), "load powers"),
            (g.n, self.v.len(), "bus voltages"),
            (g.ders.len(), self.der_inputs.len(), "DER inputs"),
            (g.ders.len(), self.der_limits.len(), "DER limits"),
            (g.ders.len(), self.der_angle.len(), "DER angles"),
            (g.x.len(), self.x.len(), "states"),
            (g.pocs.len(), self.poc_angle.len(), "POC angles"),
            (g.ufls.len(), self.ufls.len(), "shedding stages"),
        ];
        for (want, got, what) in sizes {
            if want != got {
                return Err(format!("snapshot has {got} {what}, the case needs {want}"));
            }
        }
        g.events = events
            .event
            .into_iter()
            .zip(self.event_flags)
            .map(|(event, (enabled, fired))| EventState {
                event,
                enabled,
                fired,
            })
            .collect();
        for (b, s) in g.branches.iter_mut().zip(self.branch_in_service) {
            b.in_service = s;
        }
        for (m, s) in g.machines.iter_mut().zip(self.machine_in_service) {
            m.in_service = s;
        }
        for (k, input) in self.der_inputs.into_iter().enumerate() {
            g.set_der_input_deferred(k, input)
                .map_err(|e| e.to_string())?;
        }
        for (k, limit) in self.der_limits.into_iter().enumerate() {
            g.set_der_limit(k, limit).map_err(|e| e.to_string())?;
        }
        g.load_y = self.load_y;
        g.load_s = self.load_s;
        g.x = self.x;
        g.t = self.t;
        g.sol.v = self.v;
        g.der_angle = self.der_angle;
        g.pcc_angle = self.pcc_angle;
        g.poc_angle = self.poc_angle;
        g.h_max = self.h_max;
        g.ufls = self.ufls;
        g.fault = self.fault;
        g.net = None;
        Ok(g)
    }
}

impl Serialize for Grid {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        GridSnapshot::of(self)
            .map_err(serde::ser::Error::custom)?
            .serialize(s)
    }
}

impl<'de> Deserialize<'de> for Grid {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Grid, D::Error> {
        GridSnapshot::deserialize(d)?
            .restore()
            .map_err(serde::de::Error::custom)
    }
}
