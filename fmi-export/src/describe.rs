//! From a model's declaration to its modelDescription.xml, and the resource file that shapes both.

use crate::instance::shown;
use crate::log::CATEGORIES;
use crate::model::{Declared, Model, Value, Variables};
use model_description as md;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// Name of the file in `resources/` that carries a scenario's configuration of one FMU.
pub const CONFIG_FILE: &str = "config.toml";

/// `resources/config.toml`: model structure, start values and default experiment of one FMU.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config<C> {
    /// The model's own structure (`Model::Config`).
    #[serde(default)]
    pub model: C,
    /// Start values that replace the declared ones: parameter or input name → value.
    #[serde(default)]
    pub start: BTreeMap<String, toml::Value>,
    /// The FMU's `DefaultExperiment`.
    #[serde(default)]
    pub experiment: Experiment,
}

impl<C: Default> Default for Config<C> {
    fn default() -> Self {
        Config {
            model: C::default(),
            start: BTreeMap::new(),
            experiment: Experiment::default(),
        }
    }
}

/// Start, stop and communication step of the default experiment.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Experiment {
    pub start: f64,
    pub stop: f64,
    pub step: f64,
}

impl Default for Experiment {
    fn default() -> Self {
        Experiment {
            start: 0.0,
            stop: 10.0,
            step: 1e-3,
        }
    }
}

impl<C: serde::de::DeserializeOwned + Default> Config<C> {
    /// Parse a config file's text.
    pub fn from_toml(text: &str) -> Result<Self, String> {
        toml::from_str(text).map_err(|e| format!("{CONFIG_FILE}: {e}"))
    }

    /// Read `dir/config.toml`; a missing file, or one beyond [`MAX_RESOURCE_BYTES`], is an
    /// error that names the path.
    pub fn load(dir: &Path) -> Result<Self, String> {
        let text = read_resource(&dir.join(CONFIG_FILE))?;
        Self::from_toml(&text)
    }
}

/// Largest resource file an FMU reads, bytes (16 MiB). The largest file the models read, a grid
/// case, is a few kB (a thousand-bus case would still be under 1 MiB), and the file is read
/// whole into memory at `fmi2Instantiate`: the limit keeps a wrong or hostile file from taking
/// the host's memory (and minutes of parsing) before it is refused.
pub const MAX_RESOURCE_BYTES: u64 = 16 << 20;

/// The text of the resource file `path`, read up to [`MAX_RESOURCE_BYTES`]: every FMU reads its
/// resources through this. A missing, unreadable, non-UTF-8 or larger file is an error naming
/// the path (and the limit).
pub fn read_resource(path: &Path) -> Result<String, String> {
    use std::io::Read;
    let too_large = || {
        format!(
            "resource file {} is larger than the limit of {} MiB ({MAX_RESOURCE_BYTES} bytes) \
             an FMU reads; refused",
            path.display(),
            MAX_RESOURCE_BYTES >> 20
        )
    };
    let file = std::fs::File::open(path)
        .map_err(|e| format!("missing resource file {}: {e}", path.display()))?;
    // The length on disk refuses a large file at once; reading at most one byte beyond the
    // limit also catches a file that grows meanwhile or reports no length (a pipe, a device).
    if file.metadata().is_ok_and(|m| m.len() > MAX_RESOURCE_BYTES) {
        return Err(too_large());
    }
    let mut bytes = Vec::new();
    file.take(MAX_RESOURCE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("cannot read resource file {}: {e}", path.display()))?;
    if bytes.len() as u64 > MAX_RESOURCE_BYTES {
        return Err(too_large());
    }
    String::from_utf8(bytes)
        .map_err(|e| format!("resource file {} is not UTF-8: {e}", path.display()))
}

fn start_override(d: &mut Declared, v: &toml::Value) -> Result<(), String> {
    let name = &d.spec.name;
    if !matches!(
        d.spec.causality,
        md::Causality::Parameter | md::Causality::Input
    ) {
        return Err(format!("[start] '{name}' is not a parameter or input"));
    }
    let new = match (&d.spec.start, v) {
        (Value::Real(_), toml::Value::Float(x)) => Value::Real(*x),
        (Value::Real(_), toml::Value::Integer(x)) => Value::Real(*x as f64),
        (Value::Integer(_), toml::Value::Integer(x)) => Value::Integer(
            i32::try_from(*x)
                .map_err(|_| format!("[start] '{name}' = {x} does not fit an Integer"))?,
        ),
        (Value::Boolean(_), toml::Value::Boolean(x)) => Value::Boolean(*x),
        (Value::String(_), toml::Value::String(x)) => Value::String(x.clone()),
        (start, _) => {
            return Err(format!(
                "[start] '{name}' = {v} is not a {}",
                start.base_type()
            ))
        }
    };
    let number = match &new {
        Value::Real(x) => Some(*x),
        Value::Integer(i) => Some(*i as f64),
        _ => None,
    };
    if let Some(x) = number {
        let (lo, hi) = d.spec.accepted_range();
        if !(lo..=hi).contains(&x) {
            return Err(format!(
                "[start] '{name}' = {} is outside its range [{}, {}]",
                shown(x),
                shown(lo),
                shown(hi)
            ));
        }
    }
    d.spec.start = new;
    Ok(())
}

/// Declare the model for `config` and apply its start values.
pub fn declare<M: Model>(
    config: &Config<M::Config>,
    resources: Option<&Path>,
) -> Result<(M, Variables), String> {
    let step = config.experiment.step;
    if !(step > 0.0 && step <= M::MAX_STEP) {
        return Err(format!(
            "[experiment] step = {step} s is outside (0, {}] s, the communication steps {} accepts",
            M::MAX_STEP,
            M::IDENTIFIER
        ));
    }
    let mut vars = Variables::default();
    let model = M::declare(&config.model, resources, &mut vars)?;
    for (name, v) in &config.start {
        let d = vars
            .find_mut(name)
            .ok_or_else(|| format!("[start] names no variable: '{name}'"))?;
        start_override(d, v)?;
    }
    Ok((model, vars))
}

/// SI decomposition of the units our models use.
fn unit_definition(name: &str) -> md::Unit {
    let base = |kg, m, s, rad, factor| md::BaseUnit {
        kg,
        m,
        s,
        rad,
        factor,
        ..Default::default()
    };
    let base_unit = match name {
        "s" => Some(base(None, None, Some(1), None, None)),
        "Hz" | "1/s" => Some(base(None, None, Some(-1), None, None)),
        "rad" => Some(base(None, None, None, Some(1), None)),
        "rad/s" => Some(base(None, None, Some(-1), Some(1), None)),
        "MW" | "MVA" | "Mvar" => Some(base(Some(1), Some(2), Some(-3), None, Some(1e6))),
        _ => None,
    };
    md::Unit {
        name: name.to_owned(),
        base_unit,
    }
}

/// The model description of `M` under `config`, with its content GUID.
pub fn describe<M: Model>(
    config: &Config<M::Config>,
    resources: Option<&Path>,
) -> Result<md::ModelDescription, String> {
    let (_, vars) = declare::<M>(config, resources)?;
    description_of::<M>(&vars, &config.experiment)
}

pub(crate) fn description_of<M: Model>(
    vars: &Variables,
    experiment: &Experiment,
) -> Result<md::ModelDescription, String> {
    let list = vars.declared();
    let index_of: BTreeMap<&str, u32> = list
        .iter()
        .enumerate()
        .map(|(i, d)| (d.spec.name.as_str(), i as u32 + 1))
        .collect();
    let deps = |names: &[String], owner: &str| -> Result<String, String> {
        let mut idx = names
            .iter()
            .map(|n| {
                index_of
                    .get(n.as_str())
                    .copied()
                    .ok_or_else(|| format!("'{owner}' depends on undeclared '{n}'"))
            })
            .collect::<Result<Vec<_>, _>>()?;
        idx.sort_unstable();
        idx.dedup();
        Ok(idx.iter().map(u32::to_string).collect::<Vec<_>>().join(" "))
    };
    let mut units: Vec<String> = list.iter().filter_map(|d| d.spec.unit.clone()).collect();
    units.sort();
    units.dedup();

    let mut variables = Vec::with_capacity(list.len());
    let (mut outputs, mut initial_unknowns) = (Vec::new(), Vec::new());
    for (i, d) in list.iter().enumerate() {
        let s = &d.spec;
        let start = s.has_start.then_some(&s.start);
        let kind = match &s.start {
            Value::Real(_) => md::VariableKind::Real(md::RealType {
                unit: s.unit.clone(),
                min: s.min,
                max: s.max,
                start: start.map(|v| match v {
                    Value::Real(x) => *x,
                    _ => unreachable!(),
                }),
                ..Default::default()
            }),
            Value::Integer(x) => md::VariableKind::Integer(md::IntegerType {
                min: s.min.map(|v| v as i32),
                max: s.max.map(|v| v as i32),
                start: start.map(|_| *x),
                ..Default::default()
            }),
            Value::Boolean(x) => md::VariableKind::Boolean(md::BooleanType {
                start: start.map(|_| *x),
                ..Default::default()
            }),
            Value::String(x) => md::VariableKind::String(md::StringType {
                start: start.map(|_| x.clone()),
                ..Default::default()
            }),
        };
        let description = if s.description.is_empty() {
            None
        } else {
            Some(s.description.clone())
        };
        variables.push(md::ScalarVariable {
            name: s.name.clone(),
            value_reference: d.vr,
            description,
            causality: Some(s.causality),
            variability: Some(s.variability),
            initial: s.initial,
            kind,
        });
        if s.causality == md::Causality::Output {
            let index = i as u32 + 1;
            outputs.push(md::Unknown {
                index,
                dependencies: Some(deps(&s.feedthrough, &s.name)?),
                dependencies_kind: None,
            });
            initial_unknowns.push(md::Unknown {
                index,
                dependencies: Some(deps(&s.initial_dependencies, &s.name)?),
                dependencies_kind: None,
            });
        }
    }
    let nonempty = |u: Vec<md::Unknown>| (!u.is_empty()).then_some(md::Unknowns { unknowns: u });
    let description = md::ModelDescription {
        fmi_version: "2.0".into(),
        model_name: M::NAME.into(),
        guid: String::new(),
        description: Some(M::DESCRIPTION.into()),
        author: None,
        version: Some(env!("CARGO_PKG_VERSION").into()),
        license: None,
        generation_tool: Some(concat!("dvpp-fmu fmi-export ", env!("CARGO_PKG_VERSION")).into()),
        generation_date_and_time: None,
        variable_naming_convention: Some("structured".into()),
        number_of_event_indicators: Some(0),
        model_exchange: None,
        co_simulation: Some(md::CoSimulation {
            model_identifier: M::IDENTIFIER.into(),
            can_handle_variable_communication_step_size: true,
            can_get_and_set_fmu_state: true,
            can_serialize_fmu_state: true,
            can_not_use_memory_management_functions: true,
            ..Default::default()
        }),
        unit_definitions: (!units.is_empty()).then(|| md::UnitDefinitions {
            units: units.iter().map(|u| unit_definition(u)).collect(),
        }),
        log_categories: Some(md::LogCategories {
            categories: CATEGORIES
                .iter()
                .map(|(n, d)| md::Category {
                    name: (*n).into(),
                    description: Some((*d).into()),
                })
                .collect(),
        }),
        default_experiment: Some(md::DefaultExperiment {
            start_time: Some(experiment.start),
            stop_time: Some(experiment.stop),
            tolerance: None,
            step_size: Some(experiment.step),
        }),
        model_variables: md::ModelVariables { variables },
        model_structure: md::ModelStructure {
            outputs: nonempty(outputs),
            derivatives: None,
            initial_unknowns: nonempty(initial_unknowns),
        },
    };
    let problems = md::check(&description);
    if !problems.is_empty() {
        return Err(md::Error::Invalid(problems).to_string());
    }
    description.with_content_guid().map_err(|e| e.to_string())
}

/// Entry point of each FMU crate's `describe` binary: print modelDescription.xml for the
/// `config.toml` in the resources directory given as the only argument (defaults without one).
pub fn describe_main<M: Model>() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = match args.as_slice() {
        [dir] if !dir.starts_with('-') => Some(Path::new(dir)),
        _ => None,
    };
    let result = match args.as_slice() {
        [] => Ok(Config::<M::Config>::default()),
        [dir] if !dir.starts_with('-') => Config::load(Path::new(dir)),
        _ => Err(format!(
            "usage: {}-describe [RESOURCES_DIR]\nprints the modelDescription.xml of {} for RESOURCES_DIR/{CONFIG_FILE}",
            M::IDENTIFIER,
            M::IDENTIFIER
        )),
    }
    .and_then(|c| describe::<M>(&c, dir))
    .and_then(|d| d.to_xml().map_err(|e| e.to_string()));
    match result {
        Ok(xml) => print!("{xml}"),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    }
}

/// Test helper: the default description of `M` must equal the committed golden copy at `path`
/// (run with `UPDATE_GOLDEN=1` to rewrite it after an intended interface change).
pub fn assert_golden<M: Model>(path: &str) {
    let xml = describe::<M>(&Config::default(), None)
        .and_then(|d| d.to_xml().map_err(|e| e.to_string()))
        .unwrap_or_else(|e| panic!("{e}"));
    if std::env::var_os("UPDATE_GOLDEN").is_some() {
        std::fs::write(path, &xml).unwrap_or_else(|e| panic!("{path}: {e}"));
        return;
    }
    let golden = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    if golden != xml {
        let line = golden
            .lines()
            .zip(xml.lines())
            .position(|(a, b)| a != b)
            .unwrap_or(0);
        panic!(
            "{} drifted from its golden modelDescription.xml {path} at line {}:\n  golden:    {}\n  generated: {}\n\
             (if the change is intended: UPDATE_GOLDEN=1 cargo test, and commit the file)",
            M::IDENTIFIER,
            line + 1,
            golden.lines().nth(line).unwrap_or(""),
            xml.lines().nth(line).unwrap_or("")
        );
    }
}
