//! Scenarios: one TOML file per study (grid case, `T_des`, DERs, events, experiment) bundled into
//! `dist/<scenario>/`: one FMU per component with the scenario's values as start values, and an
//! SSP system `<scenario>.ssp` that wires them by the signal contract (`docs/contract.md`).

use der_model::ports as der;
use dvpp_cosim::ssp;
use grid_model::ports as grid;
use model_description::{BaseType, Causality, ModelDescription};
use operator_model::ports as op;
use operator_model::{Form, Role};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use toml::{Table, Value};

/// A scenario file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// One line shown in the SSD and the demo.
    pub description: String,
    pub experiment: Experiment,
    pub grid: GridSpec,
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
/// response). A pattern may match nothing in a given system.
pub const RECORD: [&str; 17] = [
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

/// DER parameters in power units that a split scales with the part (pu on S_base).
const SPLIT_POWERS: [&str; 2] = [der::P_AVAIL0, "avail.dP"];

/// The parts of a unit split at `eps`: (name suffix, grid-forming, part); a part of zero is
/// left out.
fn parts(eps: f64) -> Vec<(&'static str, bool, f64)> {
    [("_gfm", true, eps), ("_gfl", false, 1.0 - eps)]
        .into_iter()
        .filter(|&(_, _, x)| x > 0.0)
        .collect()
}

/// The DERs split at `eps`, in the order of [`split_case`]'s slots: each part named after its
/// unit and form, its power-valued start values scaled, and a complement's share set to the part.
fn split_ders(ders: &[DerSpec], eps: f64) -> Vec<DerSpec> {
    parts(eps)
        .into_iter()
        .flat_map(|(suffix, _, part)| {
            ders.iter().map(move |d| {
                let mut start = d.start.clone();
                for key in SPLIT_POWERS {
                    if let Some(x) = start.get(key).and_then(|v| v.as_float()) {
                        start.insert(key.into(), real(x * part));
                    }
                }
                start.entry("adpf.p.share").or_insert_with(|| real(part));
                // The preset's dc gains split like the unit (the operator sends the actual ones
                // from the first step; these keep the initialization consistent).
                let preset = d
                    .preset
                    .as_deref()
                    .and_then(|p| der_model::Preset::named(p).ok());
                if let Some(p) = preset {
                    let u = der_model::UnitDefaults::of(Some(p));
                    let gains = [
                        (der::MU_P.to_string(), u.mu_p),
                        (der::MU_Q.to_string(), u.mu_q),
                    ]
                    .into_iter()
                    .chain(
                        u.mu_p_lpf
                            .iter()
                            .enumerate()
                            .map(|(j, &m)| (der::mu_p_lpf(j + 1), m)),
                    );
                    for (key, mu) in gains {
                        start.entry(key).or_insert_with(|| real(mu * part));
                    }
                }
                DerSpec {
                    name: format!("{}{suffix}", d.name),
                    preset: d.preset.clone(),
                    dvpp: d.dvpp.clone(),
                    start,
                }
            })
        })
        .collect()
}

/// The grid case with every DER slot split into its grid-forming and grid-following parts
/// (ratings and dispatch scaled, the PCC's slot list following).
fn split_case(case: &grid_model::Case, eps: f64, scale: f64) -> grid_model::Case {
    let mut out = case.clone();
    out.ders.clear();
    let mut new_index = vec![Vec::new(); case.ders.len()];
    for (&(suffix, forming, part), _) in parts(eps).iter().zip(0..) {
        for (k, slot) in case.ders.iter().enumerate() {
            let name = slot.name.clone().unwrap_or_else(|| format!("der{}", k + 1));
            out.ders.push(grid_model::DerSlot {
                name: Some(format!("{name}{suffix}")),
                kind: if forming {
                    grid_model::DerKind::GridForming
                } else {
                    grid_model::DerKind::GridFollowing
                },
                rating_mva: slot.rating_mva * part * scale,
                p_mw: slot.p_mw * part,
                q_mvar: slot.q_mvar * part,
                ..slot.clone()
            });
            new_index[k].push(out.ders.len());
        }
    }
    if let Some(pcc) = &mut out.pcc {
        pcc.slots = pcc
            .slots
            .iter()
            .flat_map(|&s| new_index.get(s - 1).cloned().unwrap_or_default())
            .collect();
    }
    out
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
    fn expand_fleets(&mut self) -> Result<(), String> {
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
    fn fleet_slots(&self, case: &grid_model::Case) -> Result<Vec<grid_model::DerSlot>, String> {
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
    fn membership(&self) -> Result<Vec<Option<usize>>, String> {
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

/// A component-name part: letters, digits and `_`, not empty.
fn plain_name(name: &str) -> bool {
    !name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// The scenario's name: its file stem.
pub fn name_of(path: &Path) -> Result<String, String> {
    path.file_stem()
        .and_then(|s| s.to_str())
        .filter(|s| !s.is_empty())
        .map(str::to_owned)
        .ok_or_else(|| format!("{}: not a scenario file name", path.display()))
}

/// How a component's FMU is made: package, staging name, config text, extra resource files.
pub struct Build<'a> {
    pub package: &'a str,
    pub id: &'a str,
    pub staging: String,
    pub config: String,
    pub files: Vec<PathBuf>,
    pub out: PathBuf,
}

/// Bundles one component and returns its model description (the bundler's `bundle_one`).
pub type Bundler<'a> = dyn FnMut(&Build) -> Result<ModelDescription, String> + 'a;

fn config_text(header: &str, model: Table, start: &Table) -> Result<String, String> {
    let mut doc = Table::new();
    doc.insert("model".into(), Value::Table(model));
    doc.insert("start".into(), Value::Table(start.clone()));
    let body = toml::to_string(&doc).map_err(|e| e.to_string())?;
    Ok(format!("# {header}\n{body}"))
}

fn real(x: f64) -> Value {
    Value::Float(x)
}

/// Start value of `name` in a model description, as f64.
fn start_of(md: &ModelDescription, name: &str) -> Option<f64> {
    md.variable(name)?.start_text()?.parse().ok()
}

/// The component names of the grid and the operator (a DER's is its scenario name).
const GRID: &str = "grid";
const OPERATOR: &str = "operator";

/// Package and model identifier of each FMU kind.
const GRID_FMU: (&str, &str) = ("fmu-grid", "dvpp_grid");
const DER_FMU: (&str, &str) = ("fmu-der", "dvpp_der");
const OPERATOR_FMU: (&str, &str) = ("fmu-operator", "dvpp_operator");

/// The operator role of a DER from its p-f ADPF kind (`adpf.p.kind`).
fn role_of(md: &ModelDescription, der: &str) -> Result<Role, String> {
    let kind = start_of(md, der::ADPF_P_KIND).ok_or(format!("DER '{der}': no adpf.p.kind"))?;
    let kind = der_model::AdpfKind::from_code(kind as i32)
        .map_err(|e| format!("DER '{der}': adpf.p.kind {e}"))?;
    Ok(match kind {
        der_model::AdpfKind::Static | der_model::AdpfKind::LowPass => Role::LowPass,
        der_model::AdpfKind::HighPass => Role::HighPass,
        der_model::AdpfKind::BandPass => Role::BandPass,
        der_model::AdpfKind::Complement => Role::Complement,
    })
}

/// The `[model]` of a DER's FMU: its preset, resized to the slot's rating (its available power
/// and dispatch scale with it).
fn der_model(spec: &DerSpec, rating_mva: f64) -> Table {
    let mut model = Table::new();
    if let Some(p) = &spec.preset {
        model.insert("preset".into(), Value::String(p.clone()));
        model.insert("rating".into(), real(rating_mva));
    }
    model
}

/// A value of the operator's configuration (`Role`, `Form`) as its TOML string.
fn toml_of<T: serde::Serialize>(x: T) -> Result<Value, String> {
    Value::try_from(x).map_err(|e| e.to_string())
}

/// One bundling: the scenario, where it goes, and the bundler that makes each FMU.
struct Job<'a, 'b> {
    path: &'a Path,
    name: String,
    sc: Scenario,
    /// Each DER's named DVPP (index into `sc.dvpps`), all `None` with one DVPP or none.
    member: Vec<Option<usize>>,
    out_dir: &'a Path,
    bundle_one: &'a mut Bundler<'b>,
}

/// A bundled component: its name, model description and start values.
struct Unit {
    name: String,
    md: ModelDescription,
    start: Table,
}

/// The grid step's result: the case and the power-flow point the other units start from.
struct GridUnit {
    unit: Unit,
    case: grid_model::Case,
    pf: grid_model::Outputs,
}

/// A bundled DER and what its wiring depends on.
struct DerUnit {
    unit: Unit,
    /// 1-based slot in the grid.
    slot: usize,
    /// 1-based entry in its DVPP's operator, and that operator's component name.
    entry: usize,
    operator: String,
    forming: bool,
    role: Role,
    /// A complement: the operator's low-pass gains it reads (1-based, in the operator's order).
    closes: Vec<usize>,
}

impl Job<'_, '_> {
    /// `e` prefixed with the scenario file.
    fn here(&self, e: String) -> String {
        format!("{}: {e}", self.path.display())
    }

    /// Bundle the FMU of `(package, id)` as `component` with the given `[model]` and start values.
    fn build(
        &mut self,
        (package, id): (&str, &str),
        component: &str,
        model: Table,
        start: &Table,
        files: Vec<PathBuf>,
    ) -> Result<ModelDescription, String> {
        (self.bundle_one)(&Build {
            package,
            id,
            staging: format!("{}-{component}", self.name),
            config: config_text(&self.sc.description, model, start)?,
            files,
            out: self.out_dir.join(format!("{component}.fmu")),
        })
    }

    /// DER names are component names: unique, not those of the grid or the operator, plain.
    fn check_der_names(&self) -> Result<(), String> {
        let ders = &self.sc.der;
        for d in ders {
            if [GRID, OPERATOR].contains(&d.name.as_str())
                || d.name.starts_with("operator_")
                || ders.iter().filter(|x| x.name == d.name).count() > 1
                || !plain_name(&d.name)
            {
                return Err(self.here(format!(
                    "DER name '{}' must be unique, not 'grid', 'operator' or 'operator_…', and made of letters, digits and _",
                    d.name
                )));
            }
        }
        Ok(())
    }

    /// The DVPPs: (name, operator component, DER indices); one unnamed DVPP without named ones.
    fn groups(&self) -> Vec<(Option<String>, String, Vec<usize>)> {
        if self.sc.dvpps.is_empty() {
            return vec![(None, OPERATOR.into(), (0..self.sc.der.len()).collect())];
        }
        self.sc
            .dvpps
            .iter()
            .enumerate()
            .map(|(g, (name, _))| {
                let members = (0..self.sc.der.len())
                    .filter(|&k| self.member[k] == Some(g))
                    .collect();
                (Some(name.clone()), format!("operator_{name}"), members)
            })
            .collect()
    }

    /// The spec of DVPP `g` of [`Job::groups`].
    fn dvpp_spec(&self, g: usize) -> Option<&DvppSpec> {
        if self.sc.dvpps.is_empty() {
            self.sc.dvpp.as_ref()
        } else {
            self.sc.dvpps.get(g).map(|(_, d)| d)
        }
    }

    /// The DVPP (index of [`Job::groups`]) of DER `k`.
    fn group_of(&self, k: usize) -> usize {
        self.member[k].unwrap_or(0)
    }

    /// The grid: its configuration, and the power-flow point the other units start from.
    fn grid(&mut self) -> Result<GridUnit, String> {
        let here = |e: String| self.here(e);
        let spec = &self.sc.grid;
        let mut model = Table::new();
        let mut files = Vec::new();
        match (&spec.case, &spec.case_file) {
            (Some(c), None) => {
                model.insert("case".into(), Value::String(c.clone()));
            }
            (None, Some(f)) => {
                let file = self.path.parent().unwrap_or(Path::new(".")).join(f);
                let base = file
                    .file_name()
                    .and_then(|s| s.to_str())
                    .ok_or(here(format!("case_file {}: not a file", f.display())))?;
                model.insert("case_file".into(), Value::String(base.into()));
                files.push(file);
            }
            _ => return Err(here("[grid] needs one of `case` or `case_file`".into())),
        }
        if let Some(t) = spec.pcc_f_filter_t {
            model.insert("pcc_f_filter_t".into(), real(t));
        }
        if !spec.event.is_empty() {
            let events = spec.event.iter().cloned().map(Value::Table).collect();
            model.insert("event".into(), Value::Array(events));
        }
        let staging = self.out_dir.join(".grid-resources");
        let _ = std::fs::remove_dir_all(&staging);
        std::fs::create_dir_all(&staging).map_err(|e| e.to_string())?;
        for f in &files {
            std::fs::copy(f, staging.join(f.file_name().expect("file")))
                .map_err(|e| here(format!("case_file {}: {e}", f.display())))?;
        }
        let config: grid_model::GridConfig = Value::Table(model.clone())
            .try_into()
            .map_err(|e| here(format!("[grid]: {e}")))?;
        let mut case = config.load_case(Some(&staging)).map_err(here)?;
        let _ = std::fs::remove_dir_all(&staging);
        let eps = self.sc.dvpp.as_ref().and_then(|d| d.eps);
        if let Some(eps) = eps {
            let scale = self.sc.dvpp.as_ref().and_then(|d| d.rating_scale);
            case = split_case(&case, eps, scale.unwrap_or(1.0));
        }
        let rewritten = self.extend_case(&mut case).map_err(here)?;
        if eps.is_some() || rewritten {
            // The case as the scenario makes it (split, fleets, the DVPPs' PCCs), with the
            // scenario's events and filter already in it, goes to the grid FMU as its case file.
            let file = self.out_dir.join(format!(".{}-case.toml", self.name));
            let text = toml::to_string(&case).map_err(|e| here(format!("split case: {e}")))?;
            std::fs::write(&file, text).map_err(|e| here(format!("{}: {e}", file.display())))?;
            model = Table::new();
            model.insert(
                "case_file".into(),
                Value::String(format!(".{}-case.toml", self.name)),
            );
            files = vec![file];
        }
        apply_rx_starts(&mut case, &self.sc.grid.start).map_err(here)?;
        let pf = grid_model::Grid::new(&case)
            .map_err(|e| here(format!("grid: {e}")))?
            .outputs();
        let start = self.sc.grid.start.clone();
        let md = self.build(GRID_FMU, GRID, model, &start, files.clone())?;
        if eps.is_some() || rewritten {
            let _ = std::fs::remove_file(&files[0]);
        }
        Ok(GridUnit {
            unit: Unit {
                name: GRID.into(),
                md,
                start,
            },
            case,
            pf,
        })
    }

    /// The case as the scenario extends it: without its own slots (`case_slots = false`), the
    /// fleets' slots appended (and summed into the one DVPP's `[pcc]`), one `[[dvpp_pcc]]` per
    /// named DVPP. Returns whether anything changed.
    fn extend_case(&self, case: &mut grid_model::Case) -> Result<bool, String> {
        let mut changed = false;
        if !self.sc.grid.case_slots {
            if self.sc.fleet.is_empty() {
                return Err("[grid] case_slots = false leaves no DER slot: add a [[fleet]]".into());
            }
            case.ders.clear();
            if let Some(pcc) = &mut case.pcc {
                pcc.slots.clear();
                pcc.branches.clear();
            }
            changed = true;
        }
        let fleet = self.sc.fleet_slots(case)?;
        if !fleet.is_empty() {
            let first = case.ders.len() + 1;
            let n = fleet.len();
            case.ders.extend(fleet);
            if self.sc.dvpps.is_empty() {
                if let Some(pcc) = &mut case.pcc {
                    pcc.slots.extend(first..first + n);
                }
            }
            changed = true;
        }
        if case.ders.len() != self.sc.der.len() {
            return Err(format!(
                "the grid case has {} DER slots but the scenario lists {} DERs",
                case.ders.len(),
                self.sc.der.len()
            ));
        }
        if !self.sc.dvpps.is_empty() {
            if !case.pocs.is_empty() {
                return Err(
                    "named DVPPs measure at their own PCCs; a case with points of coupling ([[poc]]) needs a single [dvpp]"
                        .into(),
                );
            }
            let f_filter_t = self
                .sc
                .grid
                .pcc_f_filter_t
                .or(case.pcc.as_ref().map(|p| p.f_filter_t))
                .unwrap_or(0.02);
            for (g, (name, members)) in self
                .groups()
                .into_iter()
                .map(|(n, _, m)| (n.expect("named"), m))
                .enumerate()
            {
                let first = members
                    .first()
                    .ok_or(format!("[dvpp.{name}]: no DER belongs to it"))?;
                let bus = self.sc.dvpps[g].1.pcc_bus.unwrap_or(case.ders[*first].bus);
                if !case.buses.iter().any(|b| b.id == bus) {
                    return Err(format!(
                        "[dvpp.{name}] pcc_bus = {bus} is not a bus of the grid case"
                    ));
                }
                case.dvpp_pccs.push(grid_model::case::DvppPcc {
                    name: name.clone(),
                    bus,
                    slots: members.iter().map(|k| k + 1).collect(),
                    f_filter_t,
                });
            }
            changed = true;
        }
        if changed {
            case.validate()
                .map_err(|e| format!("the scenario's grid case: {e}"))?;
        }
        Ok(changed)
    }

    /// The rotation's R/X of DVPP `g` from its `rot_rx` (None: classical).
    fn rot_rx(&self, g: usize) -> Result<Option<f64>, String> {
        match self.dvpp_spec(g).and_then(|d| d.rot_rx) {
            Some(rx) if !(rx.is_finite() && rx >= 0.0) => Err(self.here(format!(
                "[dvpp] rot_rx = {rx}: the R/X ratio is finite and >= 0"
            ))),
            rx => Ok(rx),
        }
    }

    /// `T_des` of DVPP `g`, shared by its operator and its DERs.
    fn tdes(&self, g: usize) -> Table {
        let mut tdes = Table::new();
        if let Some(d) = self.dvpp_spec(g) {
            tdes.insert(der::S_DVPP.into(), real(d.s_dvpp));
            tdes.insert(der::TDES_H.into(), real(d.h));
            tdes.insert(der::TDES_D.into(), real(d.d));
            tdes.insert(der::TDES_DQ.into(), real(d.dq));
        }
        tdes
    }

    /// The DERs: preset, mode from the slot kind, the power-flow point as input start values;
    /// then every complement unit again, with the time constants of the low-pass units it closes.
    fn ders(&mut self, grid: &GridUnit) -> Result<Vec<DerUnit>, String> {
        let mut ders = Vec::with_capacity(self.sc.der.len());
        let groups = self.groups();
        let mut entry = vec![0; self.sc.der.len()];
        for (_, _, members) in &groups {
            for (i, &k) in members.iter().enumerate() {
                entry[k] = i + 1;
            }
        }
        for (k, &entry) in entry.iter().enumerate() {
            let g = self.group_of(k);
            let spec = &self.sc.der[k];
            let slot = &grid.case.ders[k];
            let model = der_model(spec, slot.rating_mva);
            let mut start = self.tdes(g);
            if let Some(rx) = self.rot_rx(g)? {
                start.insert(der::ROT_RX.into(), real(rx));
            }
            let forming = slot.kind == grid_model::DerKind::GridForming;
            let mode = if forming {
                der_model::Mode::GridForming
            } else {
                der_model::Mode::GridFollowing
            };
            start.insert(der::MODE.into(), Value::Integer(mode.code().into()));
            // The slot's rating and impedance, so that E∠θ starts behind the grid's own impedance.
            let o = &grid.pf.der[k];
            for (n, x) in [
                (der::S_RATED, slot.rating_mva),
                (der::R_F, slot.r),
                (der::P, o.p),
                (der::Q, o.q),
                (der::V, o.v),
                (der::V_ANGLE, o.v_angle),
            ] {
                start.insert(n.into(), real(x));
            }
            // A grid-following slot may leave its impedance out (the unit injects current).
            if let Some(x) = slot.x {
                start.insert(der::X_F.into(), real(x));
            }
            start.extend(spec.start.clone());
            let name = spec.name.clone();
            let md = self.build(DER_FMU, &name, model, &start, Vec::new())?;
            let role = role_of(&md, &name)?;
            ders.push(DerUnit {
                unit: Unit { name, md, start },
                slot: k + 1,
                entry,
                operator: groups[g].1.clone(),
                forming,
                role,
                closes: Vec::new(),
            });
        }
        // A complement unit closes the low-pass units of its DVPP (with a complement per form,
        // a hybrid DVPP: those of its own form): their time constants, and which of its
        // operator's low-pass gains it reads.
        for (name, _, members) in &groups {
            self.close_complements(&mut ders, grid, name.as_deref(), members)?;
        }
        Ok(ders)
    }

    /// The complement units among `members` (DVPP `name`) closing that DVPP's low-pass units.
    fn close_complements(
        &mut self,
        ders: &mut [DerUnit],
        grid: &GridUnit,
        name: Option<&str>,
        members: &[usize],
    ) -> Result<(), String> {
        let lpf: Vec<(bool, f64, i64)> = members
            .iter()
            .map(|&k| &ders[k])
            .filter(|d| d.role == Role::LowPass)
            .map(|d| {
                let tau = start_of(&d.unit.md, der::ADPF_P_TAU).unwrap_or(0.0);
                let order = start_of(&d.unit.md, der::ADPF_P_ORDER).unwrap_or(1.0);
                (d.forming, tau, order as i64)
            })
            .collect();
        let per_form = members
            .iter()
            .filter(|&&k| ders[k].role == Role::Complement)
            .count()
            > 1;
        for &k in members {
            let d = &mut ders[k];
            if d.role != Role::Complement {
                continue;
            }
            let closed: Vec<(usize, f64, i64)> = lpf
                .iter()
                .enumerate()
                .filter(|(_, u)| !per_form || u.0 == d.forming)
                .map(|(j, &(_, tau, order))| (j + 1, tau, order))
                .collect();
            if closed.len() > der_model::MAX_LPF {
                return Err(self.here(format!(
                    "DER '{}' (the complement of DVPP {}) would close {} low-pass units; a complement closes at most {} (a fleet's units are best given static ADPFs, which need no complement)",
                    d.unit.name,
                    name.unwrap_or("of the scenario"),
                    closed.len(),
                    der_model::MAX_LPF
                )));
            }
            d.closes = closed.iter().map(|c| c.0).collect();
            let mut extra = Table::new();
            extra.insert(
                der::ADPF_P_N_LPF.into(),
                Value::Integer(closed.len() as i64),
            );
            for (j, &(_, tau, order)) in closed.iter().enumerate() {
                extra.insert(der::adpf_p_lpf_tau(j + 1), real(tau));
                extra.insert(der::adpf_p_lpf_order(j + 1), Value::Integer(order));
            }
            // The scenario's own values win.
            for (key, v) in extra {
                d.unit.start.entry(key).or_insert(v);
            }
            let model = der_model(&self.sc.der[k], grid.case.ders[k].rating_mva);
            d.unit.md = self.build(DER_FMU, &d.unit.name, model, &d.unit.start, Vec::new())?;
        }
        Ok(())
    }

    /// The operator of DVPP `g`: one entry per DER of it (role, form, rating), the power-flow
    /// point as start values.
    fn operator(&mut self, grid: &GridUnit, ders: &[DerUnit], g: usize) -> Result<Unit, String> {
        let (name, component, members) = self.groups().swap_remove(g);
        let mut entries = Vec::new();
        let mut start = self.tdes(g);
        for d in members.iter().map(|&k| &ders[k]) {
            let md = &d.unit.md;
            let mut e = Table::new();
            e.insert("name".into(), Value::String(d.unit.name.clone()));
            e.insert("role".into(), toml_of(d.role)?);
            let form = if d.forming {
                Form::GridForming
            } else {
                Form::GridFollowing
            };
            e.insert("form".into(), toml_of(form)?);
            let s_rated =
                start_of(md, der::S_RATED).ok_or(format!("DER '{}': no S_rated", d.unit.name))?;
            e.insert("s_rated".into(), real(s_rated));
            entries.push(Value::Table(e));
            let (k, slot) = (d.entry, d.slot);
            let avail = start_of(md, der::P_AVAIL0).unwrap_or(0.0);
            start.insert(op::der_p_avail(k), real(avail));
            start.insert(op::der_p(k), real(grid.pf.der[slot - 1].p));
            start.insert(op::der_p_set(k), real(grid.pf.der[slot - 1].p));
            start.insert(op::der_q(k), real(grid.pf.der[slot - 1].q));
        }
        let pcc = match &name {
            None => &grid.pf.pcc,
            Some(n) => grid
                .case
                .dvpp_pccs
                .iter()
                .position(|p| &p.name == n)
                .and_then(|i| grid.pf.dvpp_pcc.get(i))
                .ok_or(format!("the grid case has no [[dvpp_pcc]] '{n}'"))?,
        };
        for (n, x) in [
            (op::PCC_P, pcc.p),
            (op::PCC_Q, pcc.q),
            (op::PCC_F, pcc.f),
            (op::PCC_V, pcc.v),
        ] {
            start.insert(n.into(), real(x));
        }
        // A DVPP area with points of coupling: ref.df is matched at them, on the POC powers
        // rotated by the scenario's R/X.
        let pocs = grid.case.pocs.len();
        let rot_rx = self.rot_rx(g)?.unwrap_or(0.0);
        if pocs > 0 {
            for (k, o) in grid.pf.poc.iter().enumerate() {
                for (n, x) in [
                    (op::poc_p(k + 1), o.p),
                    (op::poc_q(k + 1), o.q),
                    (op::poc_f(k + 1), o.f),
                    (op::poc_v(k + 1), o.v),
                ] {
                    start.insert(n, real(x));
                }
            }
            start.insert(op::ROT_RX.into(), real(rot_rx));
            start.insert(op::AREA_P_LOAD.into(), real(grid.pf.area_p_load));
            start.insert(op::AREA_Q_LOAD.into(), real(grid.pf.area_q_load));
        }
        start.extend(
            self.sc
                .operator
                .as_ref()
                .map_or(Table::new(), |o| o.start.clone()),
        );
        let mut model = Table::new();
        model.insert("ders".into(), Value::Array(entries));
        if pocs > 0 {
            model.insert("pocs".into(), Value::Integer(pocs as i64));
            model.insert("rot_rx".into(), real(rot_rx));
        }
        let md = self.build(OPERATOR_FMU, &component, model, &start, Vec::new())?;
        Ok(Unit {
            name: component,
            md,
            start,
        })
    }
}

/// The grid's R/X start values (`mv.rx`, `mv.line[k].rx` > 0) applied to `case`, so that the
/// power flow the other units start from is the one the grid FMU solves at initialization.
fn apply_rx_starts(case: &mut grid_model::Case, start: &Table) -> Result<(), String> {
    let value = |key: &str| -> Result<Option<f64>, String> {
        match start.get(key) {
            None => Ok(None),
            Some(Value::Float(x)) => Ok(Some(*x)),
            Some(Value::Integer(x)) => Ok(Some(*x as f64)),
            Some(v) => Err(format!("[grid.start] '{key}' = {v}: expected a number")),
        }
    };
    let lines = case.mv_line_indices();
    if let Some(rx) = value(grid::MV_RX)? {
        case.mv
            .as_mut()
            .ok_or(format!(
                "[grid.start] '{}': the case has no [mv]",
                grid::MV_RX
            ))?
            .rx = rx;
    }
    for (k, &i) in lines.iter().enumerate() {
        if let Some(rx) = value(&grid::mv_line_rx(k + 1))? {
            case.lines[i].rx = (rx > 0.0).then_some(rx);
        }
    }
    Ok(())
}

/// One connection: from (component, output) to (component, input).
type Wire = ((String, String), (String, String));

fn wire(from: &str, output: &str, to: &str, input: &str) -> Wire {
    ((from.into(), output.into()), (to.into(), input.into()))
}

/// A wiring rule: the connections it makes for one DER.
type DerRule = fn(&DerUnit) -> Vec<Wire>;

/// Grid → DER: the measurements at the DER's slot.
fn slot_measurements(d: &DerUnit) -> Vec<Wire> {
    let (n, k) = (d.unit.name.as_str(), d.slot);
    vec![
        wire(GRID, &grid::der_p(k), n, der::P),
        wire(GRID, &grid::der_q(k), n, der::Q),
        wire(GRID, &grid::der_v(k), n, der::V),
        wire(GRID, &grid::der_v_angle(k), n, der::V_ANGLE),
    ]
}

/// DER → grid: what drives its slot (`E∠θ` grid-forming, `p_ref`, `q_ref` grid-following) and
/// its converter's limits.
fn slot_drive(d: &DerUnit) -> Vec<Wire> {
    let (n, k) = (d.unit.name.as_str(), d.slot);
    // The converter's limits go with its drive: the slot's output stage holds them.
    if d.forming {
        vec![
            wire(n, der::THETA, GRID, &grid::der_theta(k)),
            wire(n, der::E, GRID, &grid::der_e(k)),
            wire(n, der::I_LIMIT, GRID, &grid::der_i_max(k)),
            wire(n, der::P_MIN, GRID, &grid::der_p_min(k)),
            wire(n, der::P_MAX, GRID, &grid::der_p_max(k)),
        ]
    } else {
        vec![
            wire(n, der::P_REF, GRID, &grid::der_p_ref(k)),
            wire(n, der::Q_REF, GRID, &grid::der_q_ref(k)),
            wire(n, der::I_LIMIT, GRID, &grid::der_i_max(k)),
        ]
    }
}

/// DER and grid → its operator: the DER's availability and its slot's power.
fn operator_measurements(d: &DerUnit) -> Vec<Wire> {
    let (n, k, s, o) = (d.unit.name.as_str(), d.entry, d.slot, d.operator.as_str());
    vec![
        wire(n, der::P_AVAIL, o, &op::der_p_avail(k)),
        wire(n, der::P_SET, o, &op::der_p_set(k)),
        wire(GRID, &grid::der_p(s), o, &op::der_p(k)),
        wire(GRID, &grid::der_q(s), o, &op::der_q(k)),
    ]
}

/// Its operator → DER: the dc gains its role takes.
fn operator_gains(d: &DerUnit) -> Vec<Wire> {
    let (n, k, o) = (d.unit.name.as_str(), d.entry, d.operator.as_str());
    let mut wires = vec![wire(o, &op::der_mu_q(k), n, der::MU_Q)];
    match d.role {
        Role::LowPass => wires.push(wire(o, &op::der_mu_p(k), n, der::MU_P)),
        Role::Complement => wires.extend(
            d.closes
                .iter()
                .enumerate()
                .map(|(i, &j)| wire(o, &op::der_mu_p_lpf(k, j), n, &der::mu_p_lpf(i + 1))),
        ),
        Role::HighPass | Role::BandPass => {}
    }
    wires
}

/// Grid → operator: the PCC measurements (`dvpp`: a named DVPP's own PCC, `pcc_<name>.*`).
fn pcc_measurements(dvpp: Option<&str>, operator: &str) -> Vec<Wire> {
    let from: [String; 4] = match dvpp {
        None => [grid::PCC_P, grid::PCC_Q, grid::PCC_F, grid::PCC_V].map(String::from),
        Some(n) => [
            grid::dvpp_pcc_p(n),
            grid::dvpp_pcc_q(n),
            grid::dvpp_pcc_f(n),
            grid::dvpp_pcc_v(n),
        ],
    };
    from.iter()
        .zip([op::PCC_P, op::PCC_Q, op::PCC_F, op::PCC_V])
        .map(|(from, to)| wire(GRID, from, operator, to))
        .collect()
}

/// Grid → operator: each point of coupling's measurements.
fn poc_measurements(pocs: usize) -> Vec<Wire> {
    (1..=pocs)
        .flat_map(|k| {
            [
                (grid::poc_p(k), op::poc_p(k)),
                (grid::poc_q(k), op::poc_q(k)),
                (grid::poc_f(k), op::poc_f(k)),
                (grid::poc_v(k), op::poc_v(k)),
            ]
        })
        .chain(if pocs > 0 {
            vec![
                (grid::AREA_P_LOAD.to_string(), op::AREA_P_LOAD.to_string()),
                (grid::AREA_Q_LOAD.to_string(), op::AREA_Q_LOAD.to_string()),
            ]
        } else {
            Vec::new()
        })
        .map(|(from, to)| wire(GRID, &from, OPERATOR, &to))
        .collect()
}

/// Rules per DER of every system, in the order of the connections.
const DER_RULES: &[DerRule] = &[slot_measurements, slot_drive];
/// Rules per DER of a system with an operator, after those of `DER_RULES`.
const OPERATOR_RULES: &[DerRule] = &[operator_measurements, operator_gains];

/// Every connection of the system: `operators` are the DVPPs' (name, operator component) if
/// the system has operators, `pocs` the grid's points of coupling.
fn wiring(ders: &[DerUnit], operators: &[(Option<String>, String)], pocs: usize) -> Vec<Wire> {
    let per_der = |rules: &[DerRule]| -> Vec<Wire> {
        ders.iter()
            .flat_map(|d| rules.iter().flat_map(move |rule| rule(d)))
            .collect()
    };
    let mut wires = per_der(DER_RULES);
    if !operators.is_empty() {
        wires.extend(per_der(OPERATOR_RULES));
        for (name, component) in operators {
            wires.extend(pcc_measurements(name.as_deref(), component));
        }
        wires.extend(poc_measurements(pocs));
    }
    wires
}

/// The SSP system of `units` wired by `wires`, each connected input declared on its component.
fn system(
    name: &str,
    sc: &Scenario,
    units: &[Unit],
    wires: Vec<Wire>,
) -> Result<ssp::System, String> {
    let mut components = units
        .iter()
        .map(|u| component(&u.name, &u.md, &u.start))
        .collect::<Result<Vec<_>, _>>()?;
    let connections: Vec<ssp::Connection> = wires
        .into_iter()
        .map(|((a, x), (b, y))| ssp::Connection {
            start_element: a,
            start_connector: x,
            end_element: b,
            end_connector: y,
            transformation: None,
        })
        .collect();
    for c in &connections {
        let comp = components
            .iter_mut()
            .find(|x| x.name == c.end_element)
            .expect("a scenario component");
        if !comp.connectors.iter().any(|k| k.name == c.end_connector) {
            let md_ty = comp
                .connectors
                .iter()
                .find(|k| k.name == c.start_connector)
                .map(|k| k.ty)
                .unwrap_or(ssp::Type::Real);
            comp.connectors.push(ssp::Connector {
                name: c.end_connector.clone(),
                kind: ssp::Kind::Input,
                ty: md_ty,
            });
        }
    }
    Ok(ssp::System {
        name: name.into(),
        description: Some(sc.description.clone()),
        components,
        connections,
        start_time: sc.experiment.start,
        stop_time: Some(sc.experiment.stop),
        step_size: Some(sc.experiment.step),
        record: match &sc.experiment.record {
            Some(r) => r.clone(),
            None => RECORD.iter().map(|p| p.to_string()).collect(),
        },
    })
}

/// A bundler that builds nothing: the model description of `b` described in process from its
/// configuration (staged under `dir`), and an empty file in place of the FMU. Enough to compile a
/// scenario into its system (the tests and `cargo xtask fuzz`), not to run it.
pub fn described(dir: &Path, b: &Build) -> Result<ModelDescription, String> {
    use fmi_export::{describe, Config};
    let res = dir.join(&b.staging);
    std::fs::create_dir_all(&res).map_err(|e| e.to_string())?;
    std::fs::write(res.join(fmi_export::CONFIG_FILE), &b.config).map_err(|e| e.to_string())?;
    for f in &b.files {
        let name = f
            .file_name()
            .ok_or(format!("{}: not a file", f.display()))?;
        std::fs::copy(f, res.join(name)).map_err(|e| format!("{}: {e}", f.display()))?;
    }
    let md = match b.package {
        "fmu-grid" => describe::<grid_model::GridFmu>(&Config::load(&res)?, Some(&res)),
        "fmu-der" => describe::<der_model::Der>(&Config::load(&res)?, Some(&res)),
        "fmu-operator" => describe::<operator_model::Operator>(&Config::load(&res)?, Some(&res)),
        p => Err(format!("unknown package {p}")),
    }?;
    // The system only needs the file to exist.
    std::fs::write(&b.out, b"").map_err(|e| e.to_string())?;
    Ok(md)
}

/// The scenario at `path` with its DERs as the system has them: each split into its
/// grid-forming and grid-following parts by `[dvpp] eps`, and the fleets expanded.
fn resolved(path: &Path) -> Result<Scenario, String> {
    let mut sc = Scenario::read(path)?;
    if let Some(eps) = sc.dvpp.as_ref().and_then(|d| d.eps) {
        if !(0.0..=1.0).contains(&eps) {
            return Err(format!(
                "{}: [dvpp] eps = {eps}: the grid-forming share is in [0, 1]",
                path.display()
            ));
        }
        let scale = sc.dvpp.as_ref().and_then(|d| d.rating_scale).unwrap_or(1.0);
        if !(scale > 0.0 && scale.is_finite()) {
            return Err(format!(
                "{}: [dvpp] rating_scale = {scale}: must be > 0",
                path.display()
            ));
        }
        sc.der = split_ders(&sc.der, eps);
    }
    sc.expand_fleets()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(sc)
}

/// The DER units (component names) of the scenario at `path`, in the grid's slot order.
pub fn units(path: &Path) -> Result<Vec<String>, String> {
    Ok(resolved(path)?.der.into_iter().map(|d| d.name).collect())
}

/// Bundle the scenario at `path` into `out_dir` and write `<name>.ssp` there.
pub fn bundle(path: &Path, out_dir: &Path, bundle_one: &mut Bundler) -> Result<PathBuf, String> {
    let name = name_of(path)?;
    let sc = resolved(path)?;
    let member = sc
        .membership()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    std::fs::create_dir_all(out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    let mut job = Job {
        path,
        name,
        sc,
        member,
        out_dir,
        bundle_one,
    };
    job.check_der_names()?;
    let grid = job.grid()?;
    let ders = job.ders(&grid)?;
    let mut operators = Vec::new();
    let mut named = Vec::new();
    if job.sc.operator.is_some() {
        for (g, (name, component, _)) in job.groups().into_iter().enumerate() {
            operators.push(job.operator(&grid, &ders, g)?);
            named.push((name, component));
        }
    }
    let wires = wiring(&ders, &named, grid.case.pocs.len());
    let mut units = vec![grid.unit];
    units.extend(ders.into_iter().map(|d| d.unit));
    units.extend(operators);
    let system = system(&job.name, &job.sc, &units, wires)?;
    let fmus: Vec<(String, PathBuf)> = system
        .components
        .iter()
        .map(|c| (c.source.clone(), out_dir.join(format!("{}.fmu", c.name))))
        .collect();
    let out = out_dir.join(format!("{}.ssp", job.name));
    system
        .write_ssp(&fmus, &out)
        .map_err(|e| format!("{}: {e}", out.display()))?;
    Ok(out)
}

/// A component of the system: every output as a connector, the parameters among `start` bound.
fn component(name: &str, md: &ModelDescription, start: &Table) -> Result<ssp::Component, String> {
    let connectors = md
        .model_variables
        .variables
        .iter()
        .filter(|v| v.causality() == Causality::Output)
        .map(|v| ssp::Connector {
            name: v.name.clone(),
            kind: ssp::Kind::Output,
            ty: v.base_type().into(),
        })
        .collect();
    let mut parameters = Vec::new();
    for (key, value) in start {
        let v = md.variable(key).ok_or_else(|| {
            format!(
                "component '{name}': '{key}' is not a variable of {}",
                md.model_name
            )
        })?;
        if v.causality() != Causality::Parameter {
            continue;
        }
        let value = match (v.base_type(), value) {
            (BaseType::Real, Value::Float(x)) => ssp::Value::Real(*x),
            (BaseType::Real, Value::Integer(x)) => ssp::Value::Real(*x as f64),
            (BaseType::Integer, Value::Integer(x)) => ssp::Value::Integer(*x),
            (BaseType::Boolean, Value::Boolean(b)) => ssp::Value::Boolean(*b),
            (BaseType::String, Value::String(s)) => ssp::Value::String(s.clone()),
            (t, v) => {
                return Err(format!(
                    "component '{name}': '{key}' = {v} does not fit its type {t}"
                ))
            }
        };
        parameters.push(ssp::Parameter {
            name: key.clone(),
            value,
        });
    }
    Ok(ssp::Component {
        name: name.into(),
        source: format!("resources/{name}.fmu"),
        connectors,
        parameters,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    /// Bundle `scenario` with the FMUs described in process instead of built: the system, and
    /// the model description of each component.
    fn bundled(scenario: &Path) -> (ssp::System, BTreeMap<String, ModelDescription>) {
        try_bundled(scenario).unwrap()
    }

    /// [`bundled`], or the bundler's error.
    fn try_bundled(
        scenario: &Path,
    ) -> Result<(ssp::System, BTreeMap<String, ModelDescription>), String> {
        let name = name_of(scenario).unwrap();
        let tmp = dvpp_cosim::tmp::TempDir::new(&format!("xtask-scenario-{name}")).unwrap();
        let dir = tmp.path().to_path_buf();
        let mut mds = BTreeMap::new();
        let mut one = |b: &Build| -> Result<ModelDescription, String> {
            let md = described(&dir, b)?;
            let component = b.out.file_stem().unwrap().to_string_lossy().into_owned();
            mds.insert(component, md.clone());
            Ok(md)
        };
        let ssp = bundle(scenario, &dir, &mut one);
        let system = ssp.map(|ssp| ssp::read(&ssp).unwrap().system.clone());
        let _ = std::fs::remove_dir_all(&dir);
        Ok((system?, mds))
    }

    /// Every connection runs from an output to an input of the model descriptions, and every
    /// input is driven once: a connector renamed on one side only fails here.
    fn assert_wired(scenario: &Path, connections: usize) {
        let (system, mds) = bundled(scenario);
        assert_eq!(
            system.connections.len(),
            connections,
            "{}",
            scenario.display()
        );
        let mut driven = std::collections::BTreeSet::new();
        for c in &system.connections {
            let causality = |component: &str, name: &str| {
                mds[component]
                    .variable(name)
                    .unwrap_or_else(|| panic!("{component} has no variable '{name}'"))
                    .causality()
            };
            let from = (&c.start_element, &c.start_connector);
            let to = (&c.end_element, &c.end_connector);
            assert_eq!(causality(from.0, from.1), Causality::Output, "{from:?}");
            assert_eq!(causality(to.0, to.1), Causality::Input, "{to:?}");
            assert!(driven.insert(to), "{to:?} driven twice");
        }
    }

    #[test]
    fn shipped_scenarios_wire_outputs_to_inputs() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
        // Per DER: 4 measurements, 2 drives, 4 to the operator, mu_q, and the converter limits
        // (grid-forming: i_limit, p_min, p_max); mu_p of the 2 low-pass units, their 2 gains to
        // the complement; 4 PCC measurements.
        assert_wired(&dir.join("case1_load.toml"), 3 * (11 + 3) + 2 + 2 + 4);
        assert_wired(&dir.join("ieee9.toml"), 0);
        // Case study III: as case study I, and 4 measurements of each of the 2 POCs.
        for name in [
            "case3_ext_pf",
            "case3_ext_rot",
            "case3_int_pf",
            "case3_int_rot",
        ] {
            assert_wired(
                &dir.join(format!("{name}.toml")),
                3 * (11 + 3) + 2 + 2 + 4 + 2 * 4 + 2,
            );
        }
    }

    #[test]
    fn rot_rx_reaches_every_der_and_the_operator_of_a_poc_case() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
        for (name, rx) in [("case3_ext_rot", 1.0), ("case3_int_pf", 0.0)] {
            let (system, mds) = bundled(&dir.join(format!("{name}.toml")));
            let bound = |c: &str, n: &str| {
                system
                    .components
                    .iter()
                    .find(|x| x.name == c)
                    .and_then(|x| x.parameters.iter().find(|p| p.name == n))
                    .map(|p| p.value.clone())
            };
            for c in ["wind", "pv", "bess", OPERATOR] {
                assert_eq!(bound(c, "rot.rx"), Some(ssp::Value::Real(rx)), "{name} {c}");
                assert_eq!(start_of(&mds[c], "rot.rx"), Some(rx), "{name} {c}");
            }
            assert!(mds[OPERATOR].variable(&op::poc_err_df(2)).is_some());
            assert!(mds[OPERATOR].variable(&op::poc_err_df(3)).is_none());
        }
        // Without POCs the operator has none of their variables.
        let (_, mds) = bundled(&dir.join("case1_load.toml"));
        assert!(mds[OPERATOR].variable(op::ROT_RX).is_none());
    }

    #[test]
    fn hybrid_dvpp_wires_grid_following_units_and_two_complements() {
        let tmp = dvpp_cosim::tmp::TempDir::new("xtask-hybrid").unwrap();
        let dir = tmp.path().to_path_buf();
        let path = dir.join("hybrid.toml");
        let mut text = String::from(
            "description = \"hybrid\"\n[experiment]\nstop = 1.0\nstep = 1e-3\n\
             [grid]\ncase = \"ieee9_hybrid\"\n[dvpp]\nS_dvpp = 96.0\nH = 5.55\nD = 33.33\n\
             Dq = 0.01\n[operator]\n",
        );
        for (name, preset) in [
            ("wind", "wind"),
            ("pv", "pv"),
            ("bess", "bess"),
            ("wind_gfl", "wind"),
            ("pv_gfl", "pv"),
            ("bess_gfl", "bess"),
        ] {
            text += &format!("[[der]]\nname = \"{name}\"\npreset = \"{preset}\"\n");
        }
        std::fs::write(&path, text).unwrap();
        // 6 DERs of 11 connections, 3 grid-forming with 3 limits and 3 grid-following with 1;
        // 4 low-pass mu_p; 2 complements closing the 2 low-pass units of their form; 4 PCC.
        assert_wired(&path, 6 * 11 + 3 * 3 + 3 + 4 + 2 * 2 + 4);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn eps_splits_every_unit_and_its_slot() {
        let tmp = dvpp_cosim::tmp::TempDir::new("xtask-eps").unwrap();
        let dir = tmp.path().to_path_buf();
        for (eps, connections) in [
            // Both forms: as the hand-written hybrid DVPP.
            (0.25, 6 * 11 + 3 * 3 + 3 + 4 + 2 * 2 + 4),
            // One form only: three units, one complement closing both low-pass units.
            (0.0, 3 * 11 + 3 + 2 + 2 + 4),
            (1.0, 3 * (11 + 3) + 2 + 2 + 4),
        ] {
            let path = dir.join(format!("eps{}.toml", (eps * 100.0) as u32));
            let mut text = format!(
                "description = \"split\"\n[experiment]\nstop = 1.0\nstep = 1e-3\n\
                 [grid]\ncase = \"ieee9_dvpp\"\n[dvpp]\nS_dvpp = 96.0\nH = 5.55\nD = 33.33\n\
                 Dq = 0.01\neps = {eps}\n[operator]\n"
            );
            for name in ["wind", "pv", "bess"] {
                text += &format!(
                    "[[der]]\nname = \"{name}\"\npreset = \"{name}\"\n[der.start]\nP_avail0 = 0.5\n"
                );
            }
            std::fs::write(&path, text).unwrap();
            assert_wired(&path, connections);
            let (system, mds) = bundled(&path);
            let ders: Vec<&str> = system
                .components
                .iter()
                .map(|c| c.name.as_str())
                .filter(|n| n.ends_with("_gfm") || n.ends_with("_gfl"))
                .collect();
            assert_eq!(ders.len(), if eps == 0.25 { 6 } else { 3 }, "{ders:?}");
            // Each part: rating and availability times its share of the unit.
            let start = |c: &str, n: &str| {
                system
                    .components
                    .iter()
                    .find(|x| x.name == c)
                    .and_then(|x| x.parameters.iter().find(|p| p.name == n))
                    .and_then(|p| match p.value {
                        ssp::Value::Real(x) => Some(x),
                        _ => None,
                    })
                    .or_else(|| start_of(&mds[c], n))
            };
            for (suffix, part) in [("_gfm", eps), ("_gfl", 1.0 - eps)] {
                if part == 0.0 {
                    continue;
                }
                let c = format!("pv{suffix}");
                assert_eq!(start(&c, der::S_RATED), Some(73.0 * part), "{c}");
                assert_eq!(start(&c, der::P_AVAIL0), Some(0.5 * part), "{c}");
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn fleets_and_named_dvpps_wire_each_operator_to_its_own_units() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
        // Per static grid-forming fleet unit: 4 measurements, 2 drives, 3 limits, 4 to the
        // operator, mu_q and mu_p; 4 PCC measurements per operator.
        assert_wired(&dir.join("scale_fleet200.toml"), 200 * 15 + 4);
        // Case study I's DVPP as in case1_load, and 24 fleet units with their operator.
        assert_wired(
            &dir.join("scale_two_dvpps.toml"),
            3 * (11 + 3) + 2 + 2 + 4 + 24 * 15 + 4,
        );
        let (system, mds) = bundled(&dir.join("scale_two_dvpps.toml"));
        let operators: Vec<&str> = system
            .components
            .iter()
            .map(|c| c.name.as_str())
            .filter(|n| n.starts_with("operator"))
            .collect();
        assert_eq!(operators, ["operator_ci", "operator_fleet"]);
        // Each operator serves its own units, numbered from 1, with its own T_des.
        assert!(mds["operator_ci"].variable(&op::der_mu_p(3)).is_none());
        assert!(mds["operator_fleet"].variable(&op::der_mu_p(24)).is_some());
        assert_eq!(start_of(&mds["operator_fleet"], der::S_DVPP), Some(60.0));
        assert_eq!(start_of(&mds["f24"], der::S_DVPP), Some(60.0));
        assert_eq!(start_of(&mds["wind"], der::S_DVPP), Some(96.0));
        assert_eq!(start_of(&mds["f7"], der::S_RATED), Some(2.5));
        let from = |to: &str, input: &str| {
            system
                .connections
                .iter()
                .find(|c| c.end_element == to && c.end_connector == input)
                .map(|c| (c.start_element.clone(), c.start_connector.clone()))
        };
        assert_eq!(
            from("operator_fleet", op::PCC_F),
            Some((GRID.into(), grid::dvpp_pcc_f("fleet")))
        );
        assert_eq!(
            from("f3", der::MU_P),
            Some(("operator_fleet".into(), op::der_mu_p(3)))
        );
        assert_eq!(
            from("operator_fleet", &op::der_p(3)),
            Some((GRID.into(), grid::der_p(6)))
        );
        // The BESS closes the two low-pass units of its own DVPP only.
        assert_eq!(start_of(&mds["bess"], der::ADPF_P_N_LPF), Some(2.0));
    }

    /// The error bundling `text` (a scenario file body) gives.
    fn bundle_error(text: &str) -> String {
        let tmp = dvpp_cosim::tmp::TempDir::new("xtask-bad").unwrap();
        let dir = tmp.path().to_path_buf();
        let path = dir.join("bad.toml");
        std::fs::write(&path, text).unwrap();
        let mut one = |_: &Build| -> Result<ModelDescription, String> { Err("built".into()) };
        let e = bundle(&path, &dir.join("out"), &mut one).unwrap_err();
        let _ = std::fs::remove_dir_all(&dir);
        e
    }

    #[test]
    fn a_complement_closing_more_low_pass_units_than_it_can_is_refused() {
        let tmp = dvpp_cosim::tmp::TempDir::new("xtask-lpf").unwrap();
        let dir = tmp.path().to_path_buf();
        let path = dir.join("many_lpf.toml");
        let mut text = String::from(
            "description = \"many\"\n[experiment]\nstop = 1.0\nstep = 1e-3\n\
             [grid]\ncase = \"ieee9_dvpp\"\n[dvpp]\nS_dvpp = 96.0\nH = 5.55\nD = 33.33\n\
             Dq = 0.01\n[operator]\n",
        );
        for name in ["wind", "pv", "bess"] {
            text += &format!("[[der]]\nname = \"{name}\"\npreset = \"{name}\"\n");
        }
        // Seven more low-pass units: the BESS would close nine.
        text += "[[fleet]]\nname = \"w\"\npreset = \"wind\"\ncount = 7\nbuses = [5]\nrating_mva = 70.0\n";
        std::fs::write(&path, text).unwrap();
        let e = try_bundled(&path).map(|_| ()).unwrap_err();
        assert!(
            e.contains("would close 9 low-pass units") && e.contains("at most 8"),
            "{e}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn bad_fleets_and_dvpp_names_are_refused_with_clear_errors() {
        let head = "description = \"bad\"\n[experiment]\nstop = 1.0\nstep = 1e-3\n\
                    [grid]\ncase = \"ieee9_dvpp\"\ncase_slots = false\n[operator]\n";
        let one = "[dvpp]\nS_dvpp = 96.0\nH = 5.55\nD = 33.33\nDq = 0.01\n";
        let named = "[dvpp.a]\nS_dvpp = 96.0\nH = 5.55\nD = 33.33\nDq = 0.01\n";
        let fleet = |extra: &str| {
            format!(
                "[[fleet]]\nname = \"u\"\ncount = 4\nbuses = [2, 5]\nrating_mva = 10.0\n{extra}"
            )
        };
        for (text, expected) in [
            (
                format!("{head}{one}{}", fleet("").replace("count = 4", "count = 0")),
                "count = 0",
            ),
            (
                format!("{head}{one}{}", fleet("").replace("[2, 5]", "[2, 42]")),
                "bus 42 is not a bus",
            ),
            (
                format!("{head}{one}{}", fleet("").replace("[2, 5]", "[]")),
                "buses is empty",
            ),
            (
                format!("{head}{one}{}", fleet("").replace("10.0", "0.0")),
                "total rating is > 0",
            ),
            (
                format!("{head}{named}{}", fleet("dvpp = \"b\"\n")),
                "unknown DVPP 'b'",
            ),
            (
                format!("{head}{named}{}", fleet("")),
                "every DER names its DVPP",
            ),
            (
                format!("{head}{one}{}", fleet("dvpp = \"a\"\n")),
                "no named DVPPs",
            ),
            (
                format!(
                    "{head}{named}[dvpp.b]\nS_dvpp = 9.0\nH = 1.0\nD = 1.0\nDq = 0.01\n{}",
                    fleet("dvpp = \"a\"\n")
                ),
                "[dvpp.b]: no DER belongs to it",
            ),
            (
                format!("{head}{named}[dvpp.a.extra]\n{}", fleet("dvpp = \"a\"\n")),
                "extra",
            ),
            (
                format!("{head}[dvpp]\nH = 5.0\n{}", fleet("")),
                "'H' is neither",
            ),
            (
                format!(
                    "{head}{}",
                    one.replace("Dq = 0.01", "Dq = 0.01\npcc_bus = 2")
                ),
                "pcc_bus: only a named DVPP",
            ),
            (
                format!("{head}{one}"),
                "case_slots = false leaves no DER slot",
            ),
            (
                format!("{head}{one}{}", fleet("").replace("\"u\"", "\"operator_\"")),
                "must be unique",
            ),
        ] {
            let e = bundle_error(&text);
            assert!(e.contains(expected), "expected '{expected}' in: {e}");
        }
    }

    /// `units` (what the case-study checks expect) names the DER components of the compiled
    /// system, in the grid's slot order, for every shipped scenario (none for `ieee9`).
    #[test]
    fn units_are_the_der_components_in_slot_order() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
        let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        files.sort();
        assert!(files.len() > 10, "the shipped scenarios");
        for path in files {
            let (system, mds) = bundled(&path);
            let ders: Vec<String> = system
                .components
                .iter()
                .filter(|c| mds[&c.name].model_identifier() == Some("dvpp_der"))
                .map(|c| c.name.clone())
                .collect();
            assert_eq!(units(&path).unwrap(), ders, "{}", path.display());
        }
    }
}
