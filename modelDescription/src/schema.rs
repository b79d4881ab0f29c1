//! The FMI 2.0 modelDescription schema as serde types (attributes are `@`-prefixed for quick-xml).

use serde::{Deserialize, Serialize};

/// `<fmiModelDescription>`: the root element.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelDescription {
    #[serde(rename = "@fmiVersion")]
    pub fmi_version: String,
    #[serde(rename = "@modelName")]
    pub model_name: String,
    #[serde(rename = "@guid")]
    pub guid: String,
    #[serde(
        rename = "@description",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub description: Option<String>,
    #[serde(rename = "@author", default, skip_serializing_if = "Option::is_none")]
    pub author: Option<String>,
    #[serde(rename = "@version", default, skip_serializing_if = "Option::is_none")]
    pub version: Option<String>,
    #[serde(rename = "@license", default, skip_serializing_if = "Option::is_none")]
    pub license: Option<String>,
    #[serde(
        rename = "@generationTool",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub generation_tool: Option<String>,
    #[serde(
        rename = "@generationDateAndTime",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub generation_date_and_time: Option<String>,
    #[serde(
        rename = "@variableNamingConvention",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub variable_naming_convention: Option<String>,
    #[serde(
        rename = "@numberOfEventIndicators",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub number_of_event_indicators: Option<u32>,
    #[serde(
        rename = "ModelExchange",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub model_exchange: Option<ModelExchange>,
    #[serde(
        rename = "CoSimulation",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub co_simulation: Option<CoSimulation>,
    #[serde(
        rename = "UnitDefinitions",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub unit_definitions: Option<UnitDefinitions>,
    #[serde(
        rename = "LogCategories",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub log_categories: Option<LogCategories>,
    #[serde(
        rename = "DefaultExperiment",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub default_experiment: Option<DefaultExperiment>,
    #[serde(rename = "ModelVariables")]
    pub model_variables: ModelVariables,
    #[serde(rename = "ModelStructure")]
    pub model_structure: ModelStructure,
}

/// `<ModelExchange>`: read only so that foreign descriptions parse; we never export ME.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelExchange {
    #[serde(rename = "@modelIdentifier")]
    pub model_identifier: String,
}

/// `<CoSimulation>`: the capability flags of a co-simulation FMU.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct CoSimulation {
    #[serde(rename = "@modelIdentifier")]
    pub model_identifier: String,
    #[serde(rename = "@needsExecutionTool", default)]
    pub needs_execution_tool: bool,
    #[serde(rename = "@canHandleVariableCommunicationStepSize", default)]
    pub can_handle_variable_communication_step_size: bool,
    #[serde(rename = "@canInterpolateInputs", default)]
    pub can_interpolate_inputs: bool,
    #[serde(rename = "@maxOutputDerivativeOrder", default)]
    pub max_output_derivative_order: u32,
    #[serde(rename = "@canRunAsynchronuously", default)]
    pub can_run_asynchronuously: bool,
    #[serde(rename = "@canBeInstantiatedOnlyOncePerProcess", default)]
    pub can_be_instantiated_only_once_per_process: bool,
    #[serde(rename = "@canNotUseMemoryManagementFunctions", default)]
    pub can_not_use_memory_management_functions: bool,
    #[serde(rename = "@canGetAndSetFMUstate", default)]
    pub can_get_and_set_fmu_state: bool,
    #[serde(rename = "@canSerializeFMUstate", default)]
    pub can_serialize_fmu_state: bool,
    #[serde(rename = "@providesDirectionalDerivative", default)]
    pub provides_directional_derivative: bool,
}

/// `<UnitDefinitions>`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct UnitDefinitions {
    #[serde(rename = "Unit", default)]
    pub units: Vec<Unit>,
}

/// `<Unit>` with its optional SI decomposition.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Unit {
    #[serde(rename = "@name")]
    pub name: String,
    #[serde(rename = "BaseUnit", default, skip_serializing_if = "Option::is_none")]
    pub base_unit: Option<BaseUnit>,
}

/// `<BaseUnit>`: exponents of the SI base units, a factor and an offset.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct BaseUnit {
    #[serde(rename = "@kg", default, skip_serializing_if = "Option::is_none")]
    pub kg: Option<i32>,
    #[serde(rename = "@m", default, skip_serializing_if = "Option::is_none")]
    pub m: Option<i32>,
    #[serde(rename = "@s", default, skip_serializing_if = "Option::is_none")]
    pub s: Option<i32>,
    #[serde(rename = "@A", default, skip_serializing_if = "Option::is_none")]
    pub a: Option<i32>,
    #[serde(rename = "@rad", default, skip_serializing_if = "Option::is_none")]
    pub rad: Option<i32>,
    #[serde(rename = "@factor", default, skip_serializing_if = "Option::is_none")]
    pub factor: Option<f64>,
}

/// `<LogCategories>`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct LogCategories {
    #[serde(rename = "Category", default)]
    pub categories: Vec<Category>,
}

/// `<Category>`: a log category a master may enable with `fmi2SetDebugLogging`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Category {
    #[serde(rename = "@name")]
    pub name: String,
    #[serde(
        rename = "@description",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub description: Option<String>,
}

/// `<DefaultExperiment>`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct DefaultExperiment {
    #[serde(
        rename = "@startTime",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub start_time: Option<f64>,
    #[serde(rename = "@stopTime", default, skip_serializing_if = "Option::is_none")]
    pub stop_time: Option<f64>,
    #[serde(
        rename = "@tolerance",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub tolerance: Option<f64>,
    #[serde(rename = "@stepSize", default, skip_serializing_if = "Option::is_none")]
    pub step_size: Option<f64>,
}

/// `<ModelVariables>`: the variables in index order (index = position + 1).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ModelVariables {
    #[serde(rename = "ScalarVariable", default)]
    pub variables: Vec<ScalarVariable>,
}

/// `causality` of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub enum Causality {
    Parameter,
    CalculatedParameter,
    Input,
    Output,
    #[default]
    Local,
    Independent,
}

/// `variability` of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub enum Variability {
    Constant,
    Fixed,
    Tunable,
    Discrete,
    #[default]
    Continuous,
}

/// `initial` of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub enum Initial {
    Exact,
    Approx,
    Calculated,
}

/// `<ScalarVariable>`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScalarVariable {
    #[serde(rename = "@name")]
    pub name: String,
    #[serde(rename = "@valueReference")]
    pub value_reference: u32,
    #[serde(
        rename = "@description",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub description: Option<String>,
    #[serde(
        rename = "@causality",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub causality: Option<Causality>,
    #[serde(
        rename = "@variability",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub variability: Option<Variability>,
    #[serde(rename = "@initial", default, skip_serializing_if = "Option::is_none")]
    pub initial: Option<Initial>,
    #[serde(rename = "$value")]
    pub kind: VariableKind,
}

impl ScalarVariable {
    /// Causality with the FMI default (`local`) applied.
    pub fn causality(&self) -> Causality {
        self.causality.unwrap_or_default()
    }

    /// Variability with the FMI default (`continuous`) applied.
    pub fn variability(&self) -> Variability {
        self.variability.unwrap_or_default()
    }

    /// The base type of the variable.
    pub fn base_type(&self) -> BaseType {
        match self.kind {
            VariableKind::Real(_) => BaseType::Real,
            VariableKind::Integer(_) | VariableKind::Enumeration(_) => BaseType::Integer,
            VariableKind::Boolean(_) => BaseType::Boolean,
            VariableKind::String(_) => BaseType::String,
        }
    }

    /// The start value as text, if one is declared.
    pub fn start_text(&self) -> Option<String> {
        match &self.kind {
            VariableKind::Real(r) => r.start.map(|v| v.to_string()),
            VariableKind::Integer(i) => i.start.map(|v| v.to_string()),
            VariableKind::Enumeration(i) => i.start.map(|v| v.to_string()),
            VariableKind::Boolean(b) => b.start.map(|v| v.to_string()),
            VariableKind::String(s) => s.start.clone(),
        }
    }
}

/// The four FMI base types (enumerations travel as integers).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BaseType {
    Real,
    Integer,
    Boolean,
    String,
}

impl std::fmt::Display for BaseType {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            BaseType::Real => "Real",
            BaseType::Integer => "Integer",
            BaseType::Boolean => "Boolean",
            BaseType::String => "String",
        })
    }
}

/// The type element inside `<ScalarVariable>`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum VariableKind {
    Real(RealType),
    Integer(IntegerType),
    Boolean(BooleanType),
    String(StringType),
    Enumeration(IntegerType),
}

/// `<Real>`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RealType {
    #[serde(
        rename = "@declaredType",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub declared_type: Option<String>,
    #[serde(rename = "@unit", default, skip_serializing_if = "Option::is_none")]
    pub unit: Option<String>,
    #[serde(rename = "@min", default, skip_serializing_if = "Option::is_none")]
    pub min: Option<f64>,
    #[serde(rename = "@max", default, skip_serializing_if = "Option::is_none")]
    pub max: Option<f64>,
    #[serde(rename = "@nominal", default, skip_serializing_if = "Option::is_none")]
    pub nominal: Option<f64>,
    #[serde(rename = "@start", default, skip_serializing_if = "Option::is_none")]
    pub start: Option<f64>,
}

/// `<Integer>` (and `<Enumeration>`, read only).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct IntegerType {
    #[serde(
        rename = "@declaredType",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub declared_type: Option<String>,
    #[serde(rename = "@min", default, skip_serializing_if = "Option::is_none")]
    pub min: Option<i32>,
    #[serde(rename = "@max", default, skip_serializing_if = "Option::is_none")]
    pub max: Option<i32>,
    #[serde(rename = "@start", default, skip_serializing_if = "Option::is_none")]
    pub start: Option<i32>,
}

/// `<Boolean>`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct BooleanType {
    #[serde(
        rename = "@declaredType",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub declared_type: Option<String>,
    #[serde(rename = "@start", default, skip_serializing_if = "Option::is_none")]
    pub start: Option<bool>,
}

/// `<String>`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct StringType {
    #[serde(
        rename = "@declaredType",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub declared_type: Option<String>,
    #[serde(rename = "@start", default, skip_serializing_if = "Option::is_none")]
    pub start: Option<String>,
}

/// `<ModelStructure>`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ModelStructure {
    #[serde(rename = "Outputs", default, skip_serializing_if = "Option::is_none")]
    pub outputs: Option<Unknowns>,
    #[serde(
        rename = "Derivatives",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub derivatives: Option<Unknowns>,
    #[serde(
        rename = "InitialUnknowns",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub initial_unknowns: Option<Unknowns>,
}

/// A list of `<Unknown>` elements.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Unknowns {
    #[serde(rename = "Unknown", default)]
    pub unknowns: Vec<Unknown>,
}

/// `<Unknown>`: a variable (1-based `index` into ModelVariables) and what it depends on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Unknown {
    #[serde(rename = "@index")]
    pub index: u32,
    /// Space-separated 1-based indices; `Some("")` = depends on nothing, `None` = on everything.
    #[serde(
        rename = "@dependencies",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub dependencies: Option<String>,
    #[serde(
        rename = "@dependenciesKind",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub dependencies_kind: Option<String>,
}

impl Unknown {
    /// The dependencies as indices: `None` when the attribute is absent (depends on everything).
    pub fn dependency_indices(&self) -> Option<Result<Vec<u32>, String>> {
        self.dependencies.as_ref().map(|d| {
            d.split_whitespace()
                .map(|s| {
                    s.parse::<u32>().map_err(|_| {
                        format!("dependency '{s}' of unknown {} is no index", self.index)
                    })
                })
                .collect()
        })
    }
}

impl ModelStructure {
    /// The `<Outputs>` unknowns (empty when absent).
    pub fn outputs(&self) -> &[Unknown] {
        self.outputs.as_ref().map_or(&[], |u| &u.unknowns)
    }

    /// The `<InitialUnknowns>` (empty when absent).
    pub fn initial_unknowns(&self) -> &[Unknown] {
        self.initial_unknowns.as_ref().map_or(&[], |u| &u.unknowns)
    }
}
