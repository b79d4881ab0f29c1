//! The scenario file's schema: its tables as types, read, checked and with its fleets expanded.

use serde::Deserialize;
use std::path::{Path, PathBuf};
use toml::{Table, Value};

use super::split::SPLIT_POWERS;
use super::{plain_name, real};

/// A scenario file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// One line shown in the SSD and the demo.
    pub description: String,
    pub experiment: Experiment,
    /// The grid case (absent only in an EMT-level system whose plant is given by `[emt] plant`).
    #[serde(default)]
    pub grid: GridSpec,
    /// Present: the system runs at EMT level (the EMT plant and EMT-level DER controllers).
    pub emt: Option<super::emt::EmtSpec>,
    /// The DVPP's desired behaviour, given to the operator and every DER (`[dvpp]` holding
    /// `S_dvpp`, `H`, `D`, `Dq`).
    #[serde(skip)]
    pub dvpp: Option<DvppSpec>,
    /// Several DVPPs sharing the grid, by name (`[dvpp.<name>]` tables), in file order; each
    /// DER names its DVPP (`dvpp = "<name>"`).
    #[serde(skip)]
    pub dvpps: Vec<(String, DvppSpec)>,
    /// `[dvpp]` as written: one DVPP, or one table per named DVPP.
    #[serde(rename = "dvpp", default)]
    dvpp_table: Option<Table>,
    /// Present: the system has a DVPP operator serving the DERs (with named DVPPs: one per DVPP,
    /// `operator_<name>`, each with these start values).
    pub operator: Option<StartOnly>,
    #[serde(default)]
    pub der: Vec<DerSpec>,
    /// Fleets of equal units spread over buses, expanded into DERs after `[[der]]`.
    #[serde(default)]
    pub fleet: Vec<FleetSpec>,
}

/// A fleet: `count` equal units `<name>1` … `<name><count>` of one preset, spread over `buses`
/// in turn (unit `k` at `buses[(k - 1) % len]`), each with `1/count` of the fleet's rating,
/// dispatch and available power; each gets a DER slot of its own in the grid.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FleetSpec {
    /// Prefix of the units' component names.
    pub name: String,
    /// The DER FMU's preset (absent: the generic unit, a static ADPF).
    pub preset: Option<String>,
    pub count: usize,
    pub buses: Vec<u32>,
    /// Total converter rating, MVA.
    pub rating_mva: f64,
    /// Total active dispatch, MW.
    #[serde(default)]
    pub p_mw: f64,
    /// Total reactive dispatch, Mvar (used on PQ buses).
    #[serde(default)]
    pub q_mvar: f64,
    /// Slot kind (default grid-forming).
    #[serde(default = "grid_forming")]
    pub kind: grid_model::DerKind,
    /// Each unit's series resistance and reactance to its bus, pu on its own rating.
    #[serde(default = "fleet_r")]
    pub r: f64,
    #[serde(default = "fleet_x")]
    pub x: f64,
    /// The named DVPP the fleet belongs to.
    pub dvpp: Option<String>,
    /// Start values of every unit; the power-valued ones (`P_avail0`, `avail.dP`) are the
    /// fleet's totals, split equally.
    #[serde(default)]
    pub start: Table,
}

fn grid_forming() -> grid_model::DerKind {
    grid_model::DerKind::GridForming
}

fn fleet_r() -> f64 {
    0.01
}

fn fleet_x() -> f64 {
    0.10
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Experiment {
    #[serde(default)]
    pub start: f64,
    pub stop: f64,
    /// Communication step, s.
    pub step: f64,
    /// The `component.variable` patterns `cosim` records by default (the SSP's record
    /// annotation); absent: [`RECORD`].
    pub record: Option<Vec<String>>,
}

/// What a scenario's result records unless the scenario or the user says otherwise: what the
/// case-study figures and tables plot and measure (PCC and POC quantities, the units' powers,
/// currents, dc links and set points, the machines' powers, the operator's gains and desired
/// response, the units' own frequencies for their coherency with the PCC). A pattern may match
/// nothing in a given system: the system is written with those that match (the master refuses
/// a record pattern that matches no output).
pub const RECORD: [&str; 18] = [
    "grid.pcc*",
    "grid.energized",
    "*.synchronized",
    "grid.poc[*]*",
    "grid.coi.f",
    "grid.der[*].p",
    "grid.der[*].q",
    "grid.sg[*].p",
    "grid.sg[*].in_service",
    "grid.sys.*",
    "grid.area.*",
    "*.v_dc",
    "*.i_ac",
    "*.i_limit",
    "*.p_set",
    "*.p_rot",
    "*.df",
    "operator*",
];

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// A built-in case of the grid FMU.
    pub case: Option<String>,
    /// Or a case file, relative to the scenario file.
    pub case_file: Option<PathBuf>,
    /// The PCC frequency measurement's time constant, s (overrides the case's).
    pub pcc_f_filter_t: Option<f64>,
    /// Events appended to the case's own (the grid FMU's `[[model.event]]`).
    #[serde(default)]
    pub event: Vec<Table>,
    /// Start values of grid variables (e.g. `"event[1].enabled" = false`).
    #[serde(default)]
    pub start: Table,
    /// false: the case's own DER slots are left out (and its `[pcc]` sums the fleets' slots
    /// instead), for a DVPP made of fleets only; `[[der]]` must then be empty.
    #[serde(default = "yes")]
    pub case_slots: bool,
}

fn yes() -> bool {
    true
}

impl Default for GridSpec {
    /// No case (an EMT plant of its own); `case_slots` as the file's default.
    fn default() -> Self {
        GridSpec {
            case: None,
            case_file: None,
            pcc_f_filter_t: None,
            event: Vec::new(),
            start: Table::new(),
            case_slots: true,
        }
    }
}

impl GridSpec {
    /// Whether a grid case is given.
    pub fn has_case(&self) -> bool {
        self.case.is_some() || self.case_file.is_some()
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DvppSpec {
    /// DVPP base, MVA.
    #[serde(rename = "S_dvpp")]
    pub s_dvpp: f64,
    /// `T_pf = 1/(H s + D)` and `T_qv = Dq`, on `S_dvpp`.
    #[serde(rename = "H")]
    pub h: f64,
    #[serde(rename = "D")]
    pub d: f64,
    #[serde(rename = "Dq")]
    pub dq: f64,
    /// Hybrid DVPP (case study II): every unit is split into a grid-forming part of rating
    /// `eps · S` and a grid-following part of rating `(1 - eps) · S`, each with its share of the
    /// availability, dispatch and participation; 1 (or absent): grid-forming units only as the
    /// case has them, 0: grid-following only.
    #[serde(default)]
    pub eps: Option<f64>,
    /// With `eps`: the units' converter ratings times this (their dispatch and the primary
    /// sources' availability stay), for severe events (the paper's outage).
    #[serde(default)]
    pub rating_scale: Option<f64>,
    /// Rotational power control (case study III): the R/X ratio of the DVPP area's lines, set
    /// as every DER's `rot.rx` and, with a grid case that has points of coupling, as the
    /// operator's `rot.rx` (the POC powers rotated alike); 0 (or absent): classical p-f control.
    #[serde(default)]
    pub rot_rx: Option<f64>,
    /// A named DVPP's PCC bus (default: the bus of its first unit), where its operator measures
    /// the frequency; its power is the sum of its units' slots.
    #[serde(default)]
    pub pcc_bus: Option<u32>,
}

#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct StartOnly {
    #[serde(default)]
    pub start: Table,
}

/// One DER: the component name, the DER FMU's preset, its start values.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DerSpec {
    pub name: String,
    pub preset: Option<String>,
    /// The named DVPP the unit belongs to (scenarios with `[dvpp.<name>]` tables).
    pub dvpp: Option<String>,
    #[serde(default)]
    pub start: Table,
}

impl Scenario {
    pub fn read(path: &Path) -> Result<Scenario, String> {
        let at = |e: String| format!("{}: {e}", path.display());
        let text = std::fs::read_to_string(path).map_err(|e| at(e.to_string()))?;
        let mut sc: Scenario = toml::from_str(&text).map_err(|e| at(e.to_string()))?;
        sc.resolve_dvpps().map_err(at)?;
        Ok(sc)
    }

    /// `[dvpp]` as one DVPP (it has `S_dvpp`) or as named DVPPs (`[dvpp.<name>]`).
    fn resolve_dvpps(&mut self) -> Result<(), String> {
        let Some(table) = self.dvpp_table.take() else {
            return Ok(());
        };
        let spec = |what: &str, t: Table| -> Result<DvppSpec, String> {
            Value::Table(t)
                .try_into()
                .map_err(|e| format!("{what}: {e}"))
        };
        if table.contains_key("S_dvpp") {
            let one = spec("[dvpp]", table)?;
            if one.pcc_bus.is_some() {
                return Err("[dvpp] pcc_bus: only a named DVPP ([dvpp.<name>]) has a PCC of its own; one DVPP uses the case's [pcc]".into());
            }
            self.dvpp = Some(one);
            return Ok(());
        }
        for (name, v) in table {
            let Value::Table(t) = v else {
                return Err(format!(
                    "[dvpp]: '{name}' is neither a field of one DVPP (S_dvpp, H, D, Dq, ...) nor a named DVPP's table [dvpp.{name}]"
                ));
            };
            if !plain_name(&name) {
                return Err(format!(
                    "[dvpp.{name}]: a DVPP's name is made of letters, digits and _"
                ));
            }
            let d = spec(&format!("[dvpp.{name}]"), t)?;
            if d.eps.is_some() || d.rating_scale.is_some() {
                return Err(format!(
                    "[dvpp.{name}]: eps and rating_scale (a hybrid DVPP) need a single [dvpp]"
                ));
            }
            self.dvpps.push((name, d));
        }
        if self.dvpps.is_empty() {
            return Err("[dvpp]: empty; give S_dvpp, H, D, Dq or named DVPPs [dvpp.<name>]".into());
        }
        Ok(())
    }

    /// The fleets expanded into DERs (appended to `[[der]]`), after checking them.
    pub(super) fn expand_fleets(&mut self) -> Result<(), String> {
        for f in &self.fleet {
            let at = format!("[[fleet]] '{}'", f.name);
            if f.count == 0 {
                return Err(format!("{at}: count = 0, a fleet has at least one unit"));
            }
            if f.buses.is_empty() {
                return Err(format!("{at}: buses is empty"));
            }
            if !(f.rating_mva > 0.0 && f.rating_mva.is_finite()) {
                return Err(format!(
                    "{at}: rating_mva = {}: the fleet's total rating is > 0",
                    f.rating_mva
                ));
            }
            for (what, x) in [
                ("p_mw", f.p_mw),
                ("q_mvar", f.q_mvar),
                ("r", f.r),
                ("x", f.x),
            ] {
                if !x.is_finite() {
                    return Err(format!("{at}: {what} = {x} is not finite"));
                }
            }
            let n = f.count as f64;
            for k in 1..=f.count {
                let mut start = f.start.clone();
                for key in SPLIT_POWERS {
                    if let Some(x) = start.get(key).and_then(|v| v.as_float()) {
                        start.insert(key.into(), real(x / n));
                    }
                }
                self.der.push(DerSpec {
                    name: format!("{}{k}", f.name),
                    preset: f.preset.clone(),
                    dvpp: f.dvpp.clone(),
                    start,
                });
            }
        }
        Ok(())
    }

    /// The DER slots of the fleets, in the order of [`Scenario::expand_fleets`]'s DERs.
    pub(super) fn fleet_slots(
        &self,
        case: &grid_model::Case,
    ) -> Result<Vec<grid_model::DerSlot>, String> {
        let mut slots = Vec::new();
        for f in &self.fleet {
            if let Some(b) = f
                .buses
                .iter()
                .find(|b| !case.buses.iter().any(|x| x.id == **b))
            {
                return Err(format!(
                    "[[fleet]] '{}': bus {b} is not a bus of the grid case",
                    f.name
                ));
            }
            let n = f.count as f64;
            for k in 1..=f.count {
                slots.push(grid_model::DerSlot {
                    name: Some(format!("{}{k}", f.name)),
                    kind: f.kind,
                    bus: f.buses[(k - 1) % f.buses.len()],
                    rating_mva: f.rating_mva / n,
                    r: f.r,
                    x: Some(f.x),
                    p_mw: f.p_mw / n,
                    q_mvar: f.q_mvar / n,
                });
            }
        }
        Ok(slots)
    }

    /// Which DVPP each DER belongs to: indices into [`Scenario::dvpps`] (named DVPPs), or all
    /// `None` (one DVPP, or none).
    pub(super) fn membership(&self) -> Result<Vec<Option<usize>>, String> {
        self.der
            .iter()
            .map(|d| match (&d.dvpp, self.dvpps.is_empty()) {
                (None, true) => Ok(None),
                (Some(n), true) => Err(format!(
                    "DER '{}': dvpp = \"{n}\", but the scenario has no named DVPPs ([dvpp.{n}])",
                    d.name
                )),
                (None, false) => Err(format!(
                    "DER '{}': with named DVPPs every DER names its DVPP (dvpp = \"{}\", ...)",
                    d.name, self.dvpps[0].0
                )),
                (Some(n), false) => self
                    .dvpps
                    .iter()
                    .position(|(x, _)| x == n)
                    .map(Some)
                    .ok_or_else(|| {
                        let known: Vec<&str> = self.dvpps.iter().map(|(x, _)| x.as_str()).collect();
                        format!(
                            "DER '{}': unknown DVPP '{n}' (the scenario's DVPPs: {})",
                            d.name,
                            known.join(", ")
                        )
                    }),
            })
            .collect()
    }
}
