//! Case description of the reduced grid: the TOML file format, its serde types and validation.
//!
//! A case holds everything needed to build a [`crate::Grid`]: the network (buses, π-model lines,
//! transformers, shunts, loads), the synchronous machines with their governors and exciters, the
//! power-flow set points, the DER slots the DVPP controllers plug into, the PCC definition, the
//! points of coupling of a DVPP area, the lines whose R/X ratio a run may change and the
//! scheduled events. Validation happens in [`Case::validate`], which [`Case::from_toml_str`] calls.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

mod validate;

pub use crate::error::CaseError;
pub(crate) use crate::error::{check_range, nonneg, pos};

/// Power-flow type of a bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BusKind {
    Slack,
    Pv,
    Pq,
}

fn default_pq() -> BusKind {
    BusKind::Pq
}
fn one() -> f64 {
    1.0
}
fn yes() -> bool {
    true
}

/// A bus. `v_set` is the voltage set point of a PV or slack bus, `angle_deg` the slack angle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Bus {
    pub id: u32,
    #[serde(default)]
    pub name: Option<String>,
    #[serde(default = "default_pq")]
    pub kind: BusKind,
    #[serde(default = "one")]
    pub v_set: f64,
    #[serde(default)]
    pub angle_deg: f64,
    /// Nominal voltage, informational only.
    #[serde(default)]
    pub base_kv: Option<f64>,
}

/// π-model line, r, x, b in pu on the system base (b = total charging susceptance).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Line {
    #[serde(default)]
    pub name: Option<String>,
    pub from: u32,
    pub to: u32,
    #[serde(default)]
    pub r: f64,
    pub x: f64,
    #[serde(default)]
    pub b: f64,
    #[serde(default = "yes")]
    pub in_service: bool,
    /// R/X ratio imposed on this line, keeping |r + jx| of the data above (None: r, x as given;
    /// for a line of the `[mv]` group, None takes the group's `rx`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rx: Option<f64>,
}

/// Two-winding transformer, series r, x in pu on the system base; `tap` is the off-nominal ratio
/// on the `from` side (ratio tap:1).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Transformer {
    #[serde(default)]
    pub name: Option<String>,
    pub from: u32,
    pub to: u32,
    #[serde(default)]
    pub r: f64,
    pub x: f64,
    #[serde(default)]
    pub tap: Option<f64>,
    #[serde(default = "yes")]
    pub in_service: bool,
}

/// Fixed shunt admittance g + jb in pu on the system base at 1 pu voltage (b > 0: capacitive).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Shunt {
    pub bus: u32,
    #[serde(default)]
    pub g: f64,
    #[serde(default)]
    pub b: f64,
}

/// Load model used in the dynamic simulation (the power flow always treats loads as P + jQ).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LoadModel {
    /// Admittance fixed from the power-flow voltage (default).
    #[default]
    ConstantImpedance,
    /// Constant P + jQ; turns into a constant impedance below 0.7 pu voltage.
    ConstantPower,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Load {
    pub bus: u32,
    pub p_mw: f64,
    #[serde(default)]
    pub q_mvar: f64,
    #[serde(default)]
    pub model: LoadModel,
}

pub use crate::exciter::Exciter;
pub use crate::governor::Governor;
pub use crate::machine::{Machine, MachineModel, ParamBase};
pub use crate::pss::Pss;

/// DER slot kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DerKind {
    /// Voltage source E∠θ behind the slot impedance.
    GridForming,
    /// P/Q current injection at the bus.
    GridFollowing,
}

/// A DER slot: where a DER FMU plugs into the grid.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DerSlot {
    #[serde(default)]
    pub name: Option<String>,
    pub kind: DerKind,
    pub bus: u32,
    pub rating_mva: f64,
    /// Series resistance between the slot's source and its bus (for a grid-forming converter:
    /// the transformer behind its regulated filter-capacitor voltage), pu on the slot rating.
    #[serde(default)]
    pub r: f64,
    /// Series reactance between the slot's source and its bus, pu on the slot rating. Needed
    /// by a grid-forming slot; informational (may be left out) for a grid-following one.
    #[serde(default)]
    pub x: Option<f64>,
    /// Active dispatch, MW (at a slack bus the slack power is shared by rating instead).
    #[serde(default)]
    pub p_mw: f64,
    /// Reactive dispatch, Mvar; only used on a PQ bus (on PV/slack buses Q is shared by rating).
    #[serde(default)]
    pub q_mvar: f64,
}

/// A branch whose flow counts towards the PCC power (flow leaving `at_bus` into the branch).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PccBranch {
    pub branch: String,
    pub at_bus: u32,
}

fn default_tf() -> f64 {
    0.02
}

/// Point of common coupling: which slots and branch flows are summed into `pcc.p`, `pcc.q`, and
/// the bus whose voltage and frequency are reported.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pcc {
    pub bus: u32,
    /// 1-based DER slot indices.
    #[serde(default)]
    pub slots: Vec<usize>,
    #[serde(default)]
    pub branches: Vec<PccBranch>,
    /// Time constant of the first-order filter on the angle derivative, s.
    #[serde(default = "default_tf")]
    pub f_filter_t: f64,
}

/// Where a POC's powers are measured on its branches.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PocSide {
    /// What the branches deliver into the POC bus (after their own losses).
    #[default]
    Grid,
    /// What the branches take from their far (area-side) ends: the area's export before the
    /// coupling transformers, where the MV lines' rotated power `p'` is conserved.
    Area,
}

impl PocSide {
    fn is_grid(&self) -> bool {
        *self == PocSide::Grid
    }
}

/// A point of coupling (POC) of an area (e.g. an MV distribution grid hosting DVPP units) with the
/// rest of the grid: the transmission bus where it is measured and the branches through which
/// the area's power arrives there. `poc[k].p`, `q` are the powers those branches carry from the
/// area to `bus` (positive: the area feeds the grid, as `pcc.p`), measured at the side `side`;
/// `v`, `f` are measured at `bus`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Poc {
    #[serde(default)]
    pub name: Option<String>,
    pub bus: u32,
    /// Names of the branches (lines or transformers) joining `bus` to the area; each must touch
    /// `bus`.
    pub branches: Vec<String>,
    /// Which end of the branches the powers are measured at (default `grid`: at `bus`).
    #[serde(default, skip_serializing_if = "PocSide::is_grid")]
    pub side: PocSide,
    /// Time constant of the first-order filter on the angle derivative, s (as `[pcc]`).
    #[serde(default = "default_tf")]
    pub f_filter_t: f64,
}

/// The PCC of one DVPP of several sharing the grid (`[[dvpp_pcc]]`, written by the bundler for a
/// scenario with named DVPPs): the summed injection of the DVPP's slots and the voltage and
/// frequency at `bus`, measured as `[pcc]` is (outputs `pcc_<name>.p`, `.q`, `.v`, `.f`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DvppPcc {
    /// The DVPP's name: letters, digits and `_`.
    pub name: String,
    pub bus: u32,
    /// 1-based DER slot indices of the DVPP's units.
    pub slots: Vec<usize>,
    /// Time constant of the first-order filter on the angle derivative, s (as `[pcc]`).
    #[serde(default = "default_tf")]
    pub f_filter_t: f64,
}

/// The lines whose R/X ratio is a run parameter (`mv.rx`, `mv.line[k].rx` in the FMU), e.g. the
/// lines of an MV distribution grid. Every line listed gets R/X = `rx` with its |r + jx| kept,
/// unless the line sets its own `rx`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MvLines {
    #[serde(default = "one")]
    pub rx: f64,
    /// Line names (`name`, or the default `L<from>-<to>`), in the order of `mv.line[k]`.
    pub lines: Vec<String>,
}

/// Largest admissible R/X ratio of a line.
pub const RX_MAX: f64 = 20.0;

/// Series r, x with |r + jx| kept and r/x = `rx`.
pub fn with_rx(r: f64, x: f64, rx: f64) -> (f64, f64) {
    let z = dvpp_math::hypot(r, x);
    let x_new = z / dvpp_math::hypot(rx, 1.0);
    (rx * x_new, x_new)
}

/// Scheduled event.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Event {
    /// Load change at `bus`: dP + j dQ at the pre-event bus voltage (positive = more load).
    LoadStep {
        time: f64,
        bus: u32,
        dp_mw: f64,
        #[serde(default)]
        dq_mvar: f64,
        #[serde(default)]
        model: LoadModel,
    },
    /// Disconnect machine number `machine` (1-based).
    GeneratorTrip { time: f64, machine: usize },
    /// Open branch `branch` (line or transformer name).
    LineTrip { time: f64, branch: String },
}

impl Event {
    pub fn time(&self) -> f64 {
        match self {
            Event::LoadStep { time, .. }
            | Event::GeneratorTrip { time, .. }
            | Event::LineTrip { time, .. } => *time,
        }
    }
}

/// A complete case.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Case {
    #[serde(default)]
    pub name: String,
    /// Where the data come from (free text).
    #[serde(default)]
    pub source: String,
    pub base_mva: f64,
    pub f_nom: f64,
    #[serde(rename = "bus")]
    pub buses: Vec<Bus>,
    #[serde(rename = "line", default)]
    pub lines: Vec<Line>,
    #[serde(rename = "transformer", default)]
    pub transformers: Vec<Transformer>,
    #[serde(rename = "shunt", default)]
    pub shunts: Vec<Shunt>,
    #[serde(rename = "load", default)]
    pub loads: Vec<Load>,
    #[serde(rename = "machine", default)]
    pub machines: Vec<Machine>,
    #[serde(rename = "der", default)]
    pub ders: Vec<DerSlot>,
    #[serde(default)]
    pub pcc: Option<Pcc>,
    /// Points of coupling of a DVPP area (outputs `poc[k].p/q/v/f`).
    #[serde(rename = "poc", default, skip_serializing_if = "Vec::is_empty")]
    pub pocs: Vec<Poc>,
    /// One PCC per DVPP when several DVPPs share the grid (outputs `pcc_<name>.p/q/v/f`).
    #[serde(rename = "dvpp_pcc", default, skip_serializing_if = "Vec::is_empty")]
    pub dvpp_pccs: Vec<DvppPcc>,
    /// Lines whose R/X ratio is a parameter of the run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mv: Option<MvLines>,
    #[serde(rename = "event", default)]
    pub events: Vec<Event>,
    /// Under-frequency load shedding, stage by stage.
    #[serde(rename = "ufls", default, skip_serializing_if = "Vec::is_empty")]
    pub ufls: Vec<UflsStage>,
}

/// One stage of under-frequency load shedding: once the centre-of-inertia frequency has been
/// below `f_hz` for `delay` seconds, every load is reduced by `shed` of its initial value
/// (constant-impedance and constant-power parts alike). Each stage acts once.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UflsStage {
    pub f_hz: f64,
    pub shed: f64,
    #[serde(default)]
    pub delay: f64,
}

/// Branch as seen by the network code: lines and transformers in one list (lines first).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BranchData {
    pub name: String,
    pub from: usize,
    pub to: usize,
    pub r: f64,
    pub x: f64,
    pub b: f64,
    pub tap: f64,
    pub in_service: bool,
}

/// Series impedance admissible: r ≥ 0, x > 0, both finite.
pub(crate) fn impedance_ok(r: f64, x: f64) -> bool {
    r.is_finite() && x.is_finite() && r >= 0.0 && x > 0.0
}

impl Case {
    /// Parse and validate a case.
    pub fn from_toml_str(s: &str) -> Result<Case, CaseError> {
        let case: Case = toml::from_str(s).map_err(|e| CaseError::Parse(e.to_string()))?;
        case.validate()?;
        Ok(case)
    }

    /// Built-in case by name: `ieee9`, `ieee9_af`, `ieee9_dvpp`, `ieee9_hybrid`, `ieee9_mv`,
    /// `thevenin_dvpp`.
    pub fn builtin(name: &str) -> Option<Case> {
        let text = builtin_text(name)?;
        Some(Case::from_toml_str(text).expect("built-in case is valid"))
    }

    /// Names of the built-in cases.
    pub fn builtin_names() -> &'static [&'static str] {
        &[
            "ieee9",
            "ieee9_af",
            "ieee9_dvpp",
            "ieee9_hybrid",
            "ieee9_mv",
            "thevenin_dvpp",
        ]
    }

    /// Map from bus id to 0-based index.
    pub fn bus_index(&self) -> BTreeMap<u32, usize> {
        self.buses
            .iter()
            .enumerate()
            .map(|(i, b)| (b.id, i))
            .collect()
    }

    /// Name of a line: its `name`, or `L<from>-<to>`.
    pub fn line_name(&self, l: &Line) -> String {
        l.name
            .clone()
            .unwrap_or_else(|| format!("L{}-{}", l.from, l.to))
    }

    /// The R/X ratio imposed on line `l` named `name`: its own `rx`, else the `[mv]` group's
    /// when it is listed there, else None (r, x as given).
    fn line_rx(&self, l: &Line, name: &str) -> Option<f64> {
        l.rx.or_else(|| {
            self.mv
                .as_ref()
                .filter(|mv| mv.lines.iter().any(|n| n == name))
                .map(|mv| mv.rx)
        })
    }

    /// Indices (into `lines`) of the `[mv]` group's lines, in the group's order.
    pub fn mv_line_indices(&self) -> Vec<usize> {
        let Some(mv) = &self.mv else {
            return Vec::new();
        };
        mv.lines
            .iter()
            .filter_map(|n| self.lines.iter().position(|l| &self.line_name(l) == n))
            .collect()
    }

    /// All branches (lines, then transformers) with bus indices and default names.
    pub fn branches(&self) -> Vec<BranchData> {
        let idx = self.bus_index();
        let mut out = Vec::new();
        for l in &self.lines {
            let name = self.line_name(l);
            let (r, x) = match self.line_rx(l, &name) {
                Some(rx) => with_rx(l.r, l.x, rx),
                None => (l.r, l.x),
            };
            out.push(BranchData {
                name,
                from: idx[&l.from],
                to: idx[&l.to],
                r,
                x,
                b: l.b,
                tap: 1.0,
                in_service: l.in_service,
            });
        }
        for t in &self.transformers {
            out.push(BranchData {
                name: t
                    .name
                    .clone()
                    .unwrap_or_else(|| format!("T{}-{}", t.from, t.to)),
                from: idx[&t.from],
                to: idx[&t.to],
                r: t.r,
                x: t.x,
                b: 0.0,
                tap: t.tap.unwrap_or(1.0),
                in_service: t.in_service,
            });
        }
        out
    }
}

/// Text of a built-in case.
pub fn builtin_text(name: &str) -> Option<&'static str> {
    match name {
        "ieee9" => Some(include_str!("../../cases/ieee9.toml")),
        "ieee9_af" => Some(include_str!("../../cases/ieee9_af.toml")),
        "ieee9_dvpp" => Some(include_str!("../../cases/ieee9_dvpp.toml")),
        "ieee9_hybrid" => Some(include_str!("../../cases/ieee9_hybrid.toml")),
        "ieee9_mv" => Some(include_str!("../../cases/ieee9_mv.toml")),
        "thevenin_dvpp" => Some(include_str!("../../cases/thevenin_dvpp.toml")),
        _ => None,
    }
}
