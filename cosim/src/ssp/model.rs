//! The SSD data model: systems, components, connectors, parameters and connections.

/// `ssd:Connector kind` (`inout`, meant for signal dictionaries, is not supported).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Kind {
    Input,
    Output,
    Parameter,
    CalculatedParameter,
}

impl Kind {
    /// The attribute value.
    pub fn as_str(self) -> &'static str {
        match self {
            Kind::Input => "input",
            Kind::Output => "output",
            Kind::Parameter => "parameter",
            Kind::CalculatedParameter => "calculatedParameter",
        }
    }

    pub(super) fn parse(s: &str) -> Option<Kind> {
        Some(match s {
            "input" => Kind::Input,
            "output" => Kind::Output,
            "parameter" => Kind::Parameter,
            "calculatedParameter" => Kind::CalculatedParameter,
            _ => return None,
        })
    }
}

/// Connector and parameter types (`Enumeration` and `Binary` are not supported).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Type {
    Real,
    Integer,
    Boolean,
    String,
}

impl From<model_description::BaseType> for Type {
    fn from(t: model_description::BaseType) -> Type {
        use model_description::BaseType as B;
        match t {
            B::Real => Type::Real,
            B::Integer => Type::Integer,
            B::Boolean => Type::Boolean,
            B::String => Type::String,
        }
    }
}

impl From<Type> for model_description::BaseType {
    fn from(t: Type) -> Self {
        use model_description::BaseType as B;
        match t {
            Type::Real => B::Real,
            Type::Integer => B::Integer,
            Type::Boolean => B::Boolean,
            Type::String => B::String,
        }
    }
}

impl Type {
    /// The element's local name (`ssc:Real`, `ssv:Real`, ...).
    pub fn as_str(self) -> &'static str {
        match self {
            Type::Real => "Real",
            Type::Integer => "Integer",
            Type::Boolean => "Boolean",
            Type::String => "String",
        }
    }

    pub(super) fn parse(s: &str) -> Option<Type> {
        Some(match s {
            "Real" => Type::Real,
            "Integer" => Type::Integer,
            "Boolean" => Type::Boolean,
            "String" => Type::String,
            _ => return None,
        })
    }
}

/// An `ssd:Connector` of a component: the name of an FMU variable, its kind and type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Connector {
    pub name: String,
    pub kind: Kind,
    pub ty: Type,
}

/// A parameter value.  SSP's `ssv:Integer` is an `xs:int`: keep values within `i32`.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    Real(f64),
    Integer(i64),
    Boolean(bool),
    String(String),
}

impl Value {
    pub fn ty(&self) -> Type {
        match self {
            Value::Real(_) => Type::Real,
            Value::Integer(_) => Type::Integer,
            Value::Boolean(_) => Type::Boolean,
            Value::String(_) => Type::String,
        }
    }
}

/// A start value for a component's variable.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameter {
    /// The component's variable name.
    pub name: String,
    pub value: Value,
}

/// An FMU component.
#[derive(Debug, Clone, PartialEq)]
pub struct Component {
    pub name: String,
    /// The FMU, relative to the package directory, e.g. `resources/grid.fmu`.
    pub source: String,
    pub connectors: Vec<Connector>,
    pub parameters: Vec<Parameter>,
}

impl Component {
    pub fn connector(&self, name: &str) -> Option<&Connector> {
        self.connectors.iter().find(|c| c.name == name)
    }
}

/// `end = offset + factor * start` (Real connections only).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearTransformation {
    pub factor: f64,
    pub offset: f64,
}

/// A connection from a component's output (or parameter) to another component's input.
#[derive(Debug, Clone, PartialEq)]
pub struct Connection {
    pub start_element: String,
    pub start_connector: String,
    pub end_element: String,
    pub end_connector: String,
    pub transformation: Option<LinearTransformation>,
}

/// A flat system of FMU components.
#[derive(Debug, Clone, PartialEq)]
pub struct System {
    pub name: String,
    pub description: Option<String>,
    pub components: Vec<Component>,
    pub connections: Vec<Connection>,
    pub start_time: f64,
    pub stop_time: Option<f64>,
    /// OSP `FixedStepAlgorithm baseStepSize`.
    pub step_size: Option<f64>,
    /// The `component.variable` patterns our master records unless told otherwise
    /// ([`RECORD_ANNOTATION`](super::RECORD_ANNOTATION)); empty: every output.
    pub record: Vec<String>,
}

impl System {
    pub fn component(&self, name: &str) -> Option<&Component> {
        self.components.iter().find(|c| c.name == name)
    }
}
