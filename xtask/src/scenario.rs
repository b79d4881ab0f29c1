//! Scenarios: one TOML file per study (grid case, `T_des`, DERs, events, experiment) bundled into
//! `dist/<scenario>/`: one FMU per component with the scenario's values as start values, and an
//! SSP system `<scenario>.ssp` that wires them by the interface contract.

use dvpp_cosim::ssp;
use model_description::{BaseType, Causality, ModelDescription};
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
    /// The DVPP's desired behaviour, given to the operator and every DER.
    pub dvpp: Option<DvppSpec>,
    /// Present: the system has a DVPP operator serving the DERs.
    pub operator: Option<StartOnly>,
    #[serde(default)]
    pub der: Vec<DerSpec>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Experiment {
    #[serde(default)]
    pub start: f64,
    pub stop: f64,
    /// Communication step, s.
    pub step: f64,
}

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
    #[serde(default)]
    pub start: Table,
}

impl Scenario {
    pub fn read(path: &Path) -> Result<Scenario, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        toml::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
    }
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

/// The operator role of a DER from its p-f ADPF kind (`adpf.p.kind`).
fn role_of(md: &ModelDescription, der: &str) -> Result<&'static str, String> {
    let kind = start_of(md, "adpf.p.kind").ok_or(format!("DER '{der}': no adpf.p.kind"))?;
    Ok(match kind as i64 {
        0 | 1 => "low_pass",
        2 => "high_pass",
        3 => "band_pass",
        4 => "complement",
        k => return Err(format!("DER '{der}': unknown adpf.p.kind {k}")),
    })
}

/// Bundle the scenario at `path` into `out_dir` and write `<name>.ssp` there.
pub fn bundle(path: &Path, out_dir: &Path, bundle_one: &mut Bundler) -> Result<PathBuf, String> {
    let name = name_of(path)?;
    let sc = Scenario::read(path)?;
    let here = |e: String| format!("{}: {e}", path.display());
    std::fs::create_dir_all(out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    for d in &sc.der {
        if ["grid", "operator"].contains(&d.name.as_str())
            || sc.der.iter().filter(|x| x.name == d.name).count() > 1
            || d.name.is_empty()
            || !d
                .name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_')
        {
            return Err(here(format!(
                "DER name '{}' must be unique, not 'grid' or 'operator', and made of letters, digits and _",
                d.name
            )));
        }
    }

    // The grid: its configuration, and the power-flow point the other units start from.
    let mut grid_model = Table::new();
    let mut files = Vec::new();
    match (&sc.grid.case, &sc.grid.case_file) {
        (Some(c), None) => {
            grid_model.insert("case".into(), Value::String(c.clone()));
        }
        (None, Some(f)) => {
            let file = path.parent().unwrap_or(Path::new(".")).join(f);
            let base = file
                .file_name()
                .and_then(|s| s.to_str())
                .ok_or(here(format!("case_file {}: not a file", f.display())))?;
            grid_model.insert("case_file".into(), Value::String(base.into()));
            files.push(file);
        }
        _ => return Err(here("[grid] needs one of `case` or `case_file`".into())),
    }
    if let Some(t) = sc.grid.pcc_f_filter_t {
        grid_model.insert("pcc_f_filter_t".into(), real(t));
    }
    if !sc.grid.event.is_empty() {
        let events = sc.grid.event.iter().cloned().map(Value::Table).collect();
        grid_model.insert("event".into(), Value::Array(events));
    }
    let staging = out_dir.join(".grid-resources");
    let _ = std::fs::remove_dir_all(&staging);
    std::fs::create_dir_all(&staging).map_err(|e| e.to_string())?;
    for f in &files {
        std::fs::copy(f, staging.join(f.file_name().expect("file")))
            .map_err(|e| here(format!("case_file {}: {e}", f.display())))?;
    }
    let grid_config: fmu_grid::GridConfig = Value::Table(grid_model.clone())
        .try_into()
        .map_err(|e| here(format!("[grid]: {e}")))?;
    let case = grid_config.load_case(Some(&staging)).map_err(here)?;
    let _ = std::fs::remove_dir_all(&staging);
    let pf = fmu_grid::Grid::new(&case)
        .map_err(|e| here(format!("grid: {e}")))?
        .outputs();
    if case.ders.len() != sc.der.len() {
        return Err(here(format!(
            "the grid case has {} DER slots but the scenario lists {} DERs",
            case.ders.len(),
            sc.der.len()
        )));
    }
    let grid_md = bundle_one(&Build {
        package: "fmu-grid",
        id: "dvpp_grid",
        staging: format!("{name}-grid"),
        config: config_text(&sc.description, grid_model, &sc.grid.start)?,
        files,
        out: out_dir.join("grid.fmu"),
    })?;

    // T_des, shared by the operator and the DERs.
    let mut tdes = Table::new();
    if let Some(d) = &sc.dvpp {
        tdes.insert("S_dvpp".into(), real(d.s_dvpp));
        tdes.insert("Tdes.H".into(), real(d.h));
        tdes.insert("Tdes.D".into(), real(d.d));
        tdes.insert("Tdes.Dq".into(), real(d.dq));
    }

    // The DERs: preset, mode from the slot kind, the power-flow point as input start values.
    let mut ders: Vec<(Table, Table)> = Vec::new();
    for (k, d) in sc.der.iter().enumerate() {
        let mut model = Table::new();
        if let Some(p) = &d.preset {
            model.insert("preset".into(), Value::String(p.clone()));
        }
        let mut start = tdes.clone();
        let slot = &case.ders[k];
        let forming = slot.kind == fmu_grid::DerKind::GridForming;
        start.insert("mode".into(), Value::Integer(if forming { 1 } else { 2 }));
        // The slot's rating and impedance, so that E∠θ starts behind the grid's own impedance.
        let o = &pf.der[k];
        for (n, x) in [
            ("S_rated", slot.rating_mva),
            ("R_f", slot.r),
            ("X_f", slot.x),
            ("p", o.p),
            ("q", o.q),
            ("v", o.v),
            ("v_angle", o.v_angle),
        ] {
            start.insert(n.into(), real(x));
        }
        start.extend(d.start.clone());
        ders.push((model, start));
    }
    let bundle_der = |k: usize, (model, start): &(Table, Table), b: &mut Bundler| {
        b(&Build {
            package: "fmu-der",
            id: "dvpp_der",
            staging: format!("{name}-{}", sc.der[k].name),
            config: config_text(&sc.description, model.clone(), start)?,
            files: Vec::new(),
            out: out_dir.join(format!("{}.fmu", sc.der[k].name)),
        })
    };
    let mut mds = Vec::with_capacity(ders.len());
    for (k, d) in ders.iter().enumerate() {
        mds.push(bundle_der(k, d, bundle_one)?);
    }
    let roles: Vec<&str> = (0..ders.len())
        .map(|k| role_of(&mds[k], &sc.der[k].name))
        .collect::<Result<_, _>>()?;
    // A complement unit closes the low-pass units of this scenario: their time constants.
    let lpf: Vec<usize> = (0..ders.len())
        .filter(|&k| roles[k] == "low_pass")
        .collect();
    for k in 0..ders.len() {
        if roles[k] != "complement" {
            continue;
        }
        let mut extra = Table::new();
        extra.insert("adpf.p.n_lpf".into(), Value::Integer(lpf.len() as i64));
        for (j, &l) in lpf.iter().enumerate() {
            let md = &mds[l];
            let tau = start_of(md, "adpf.p.tau").unwrap_or(0.0);
            let order = start_of(md, "adpf.p.order").unwrap_or(1.0);
            extra.insert(format!("adpf.p.lpf[{}].tau", j + 1), real(tau));
            extra.insert(
                format!("adpf.p.lpf[{}].order", j + 1),
                Value::Integer(order as i64),
            );
        }
        // The scenario's own values win.
        for (key, v) in extra {
            ders[k].1.entry(key).or_insert(v);
        }
        mds[k] = bundle_der(k, &ders[k], bundle_one)?;
    }

    let mut components = vec![component("grid", &grid_md, &sc.grid.start)?];
    let mut connections = Vec::new();
    let link = |a: &str, x: &str, b: &str, y: String| ssp::Connection {
        start_element: a.into(),
        start_connector: x.into(),
        end_element: b.into(),
        end_connector: y,
        transformation: None,
    };
    for (k, d) in sc.der.iter().enumerate() {
        let slot = k + 1;
        components.push(component(&d.name, &mds[k], &ders[k].1)?);
        for v in ["p", "q", "v", "v_angle"] {
            connections.push(link("grid", &format!("der[{slot}].{v}"), &d.name, v.into()));
        }
        let drive: [&str; 2] = if case.ders[k].kind == fmu_grid::DerKind::GridForming {
            ["theta", "E"]
        } else {
            ["p_ref", "q_ref"]
        };
        for v in drive {
            connections.push(link(&d.name, v, "grid", format!("der[{slot}].{v}")));
        }
    }

    if let Some(op) = &sc.operator {
        let mut entries = Vec::new();
        let mut start = tdes.clone();
        for (k, d) in sc.der.iter().enumerate() {
            let md = &mds[k];
            let mut e = Table::new();
            e.insert("name".into(), Value::String(d.name.clone()));
            e.insert("role".into(), Value::String(roles[k].into()));
            let form = if case.ders[k].kind == fmu_grid::DerKind::GridForming {
                "grid_forming"
            } else {
                "grid_following"
            };
            e.insert("form".into(), Value::String(form.into()));
            let s_rated = start_of(md, "S_rated").ok_or(format!("DER '{}': no S_rated", d.name))?;
            e.insert("s_rated".into(), real(s_rated));
            entries.push(Value::Table(e));
            let slot = k + 1;
            let avail = start_of(md, "P_avail0").unwrap_or(0.0);
            start.insert(format!("der[{slot}].P_avail"), real(avail));
            start.insert(format!("der[{slot}].p"), real(pf.der[k].p));
            start.insert(format!("der[{slot}].q"), real(pf.der[k].q));
        }
        for (n, x) in [
            ("pcc.p", pf.pcc.p),
            ("pcc.q", pf.pcc.q),
            ("pcc.f", pf.pcc.f),
            ("pcc.v", pf.pcc.v),
        ] {
            start.insert(n.into(), real(x));
        }
        start.extend(op.start.clone());
        let mut model = Table::new();
        model.insert("ders".into(), Value::Array(entries));
        let md = bundle_one(&Build {
            package: "fmu-operator",
            id: "dvpp_operator",
            staging: format!("{name}-operator"),
            config: config_text(&sc.description, model, &start)?,
            files: Vec::new(),
            out: out_dir.join("operator.fmu"),
        })?;
        components.push(component("operator", &md, &start)?);
        for (k, d) in sc.der.iter().enumerate() {
            let slot = k + 1;
            connections.push(link(
                &d.name,
                "P_avail",
                "operator",
                format!("der[{slot}].P_avail"),
            ));
            for v in ["p", "q"] {
                connections.push(link(
                    "grid",
                    &format!("der[{slot}].{v}"),
                    "operator",
                    format!("der[{slot}].{v}"),
                ));
            }
            connections.push(link(
                "operator",
                &format!("der[{slot}].mu_q"),
                &d.name,
                "mu_q".into(),
            ));
            match roles[k] {
                "low_pass" => connections.push(link(
                    "operator",
                    &format!("der[{slot}].mu_p"),
                    &d.name,
                    "mu_p".into(),
                )),
                "complement" => {
                    for j in 1..=lpf.len() {
                        connections.push(link(
                            "operator",
                            &format!("der[{slot}].mu_p_lpf[{j}]"),
                            &d.name,
                            format!("mu_p_lpf[{j}]"),
                        ));
                    }
                }
                _ => {}
            }
        }
        for v in ["p", "q", "f", "v"] {
            connections.push(link(
                "grid",
                &format!("pcc.{v}"),
                "operator",
                format!("pcc.{v}"),
            ));
        }
    }

    // Declare the connected inputs on their components.
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
    let system = ssp::System {
        name: name.clone(),
        description: Some(sc.description.clone()),
        components,
        connections,
        start_time: sc.experiment.start,
        stop_time: Some(sc.experiment.stop),
        step_size: Some(sc.experiment.step),
    };
    let fmus: Vec<(String, PathBuf)> = system
        .components
        .iter()
        .map(|c| (c.source.clone(), out_dir.join(format!("{}.fmu", c.name))))
        .collect();
    let out = out_dir.join(format!("{name}.ssp"));
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
