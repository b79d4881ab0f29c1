//! What a model implements (`Model`) and the one table it declares its variables in.

use crate::log::Logger;
use crate::Status;
use model_description::{Causality, Initial, Variability};
use serde::{de::DeserializeOwned, Deserialize, Serialize};
use std::fmt;

/// A model that the export layer turns into an FMI 2.0 Co-Simulation FMU.
///
/// The model is two things kept apart: its variables, which live in a [`Store`] the layer owns
/// and which the model addresses by the typed handles [`Model::declare`] returns (the model
/// value itself holds only those handles and what its configuration fixes), and its running
/// state ([`Model::State`]), which initialization builds and each step advances. The layer keeps
/// the state beside the store, so an FMU state (`fmi2GetFMUstate`, serialization) saves exactly
/// the variables and the running state, never handles; everything a master can see (names,
/// units, causality, start values, dependencies) comes from the one declaration.
pub trait Model: Sized + Send + 'static {
    /// Structure that the variables depend on (read from `resources/config.toml`, `[model]`).
    type Config: Default + Clone + Serialize + DeserializeOwned;
    /// What initialization builds from the parameters and the measured operating point, and
    /// each step advances: the part of the model an FMU state saves beside the variables.
    type State: Clone + Send + Serialize + DeserializeOwned + 'static;
    /// `modelIdentifier`: the binary's name and a C identifier.
    const IDENTIFIER: &'static str;
    /// `modelName`.
    const NAME: &'static str;
    /// `description`.
    const DESCRIPTION: &'static str;
    /// Longest communication step `fmi2DoStep` accepts, s: generous against the steps the model
    /// is designed for, short enough that one call returns promptly. A longer step is refused
    /// with `fmi2Error` (state unchanged) instead of being integrated for minutes.
    const MAX_STEP: f64;

    /// Declare every variable and return the model holding their handles. `resources` is the
    /// FMU's `resources/` directory (for data files the config names); `None` when describing
    /// the built-in defaults.
    fn declare(
        config: &Self::Config,
        resources: Option<&std::path::Path>,
        vars: &mut Variables,
    ) -> Result<Self, String>;

    /// Build the running state and the initial outputs from parameters and inputs. Called in
    /// initialization mode whenever a value was set since the last call, and on leaving it;
    /// must be idempotent. `previous` is the state an earlier call of the same initialization
    /// mode built (none on the first call and after a reset), for what must not repeat, such
    /// as a warning already given.
    fn initialize(
        &self,
        previous: Option<&Self::State>,
        s: &mut Store,
        ctx: &mut Context,
    ) -> Result<Self::State, ModelError>;

    /// Advance `state` from `t` to `t + h` with the inputs in `s`; write outputs to `s`.
    fn do_step(
        &self,
        state: &mut Self::State,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError>;
}

/// A failure the model reports; the call returns `fmi2Error` with this message logged.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelError(pub String);

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl<T: Into<String>> From<T> for ModelError {
    fn from(m: T) -> Self {
        ModelError(m.into())
    }
}

/// Handle of a Real variable (its value reference).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Real(pub u32);
/// Handle of an Integer variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Integer(pub u32);
/// Handle of a Boolean variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Boolean(pub u32);

/// Largest magnitude a Real or Integer parameter or input accepts where its declaration states
/// no bound: no physical quantity of these models (pu, s, Hz, MVA, rad) comes near it, and
/// products of a few such values stay far from overflowing to infinity (about 1e308), so
/// `1e308` is refused by name at the setter instead of turning into inf/NaN, or a panic, deep
/// inside the model.
pub const MAX_MAGNITUDE: f64 = 1e12;

/// The accepted range for declared bounds `min`, `max`: [`MAX_MAGNITUDE`] stands in for a
/// missing one.
pub fn accepted_range(min: Option<f64>, max: Option<f64>) -> (f64, f64) {
    (min.unwrap_or(-MAX_MAGNITUDE), max.unwrap_or(MAX_MAGNITUDE))
}

/// A start value, which also fixes the variable's base type.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Value {
    Real(f64),
    Integer(i32),
    Boolean(bool),
    String(String),
}

impl Value {
    pub(crate) fn base_type(&self) -> model_description::BaseType {
        use model_description::BaseType as B;
        match self {
            Value::Real(_) => B::Real,
            Value::Integer(_) => B::Integer,
            Value::Boolean(_) => B::Boolean,
            Value::String(_) => B::String,
        }
    }
}

/// The declaration of one variable.
#[derive(Debug, Clone)]
pub struct Spec {
    pub name: String,
    pub description: String,
    pub causality: Causality,
    pub variability: Variability,
    pub initial: Option<Initial>,
    /// Start value; for outputs without one, the value's kind only fixes the type.
    pub start: Value,
    pub has_start: bool,
    pub unit: Option<String>,
    pub min: Option<f64>,
    pub max: Option<f64>,
    /// Inputs an output depends on directly within a step (none: computed in `do_step` only).
    pub feedthrough: Vec<String>,
    /// Inputs and parameters an output depends on in initialization mode.
    pub initial_dependencies: Vec<String>,
}

impl Spec {
    fn new(name: &str, start: Value, unit: &str, description: &str, causality: Causality) -> Self {
        Spec {
            name: name.to_owned(),
            description: description.to_owned(),
            causality,
            variability: if matches!(start, Value::Real(_)) {
                Variability::Continuous
            } else {
                Variability::Discrete
            },
            initial: None,
            start,
            has_start: true,
            unit: (!unit.is_empty()).then(|| unit.to_owned()),
            min: None,
            max: None,
            feedthrough: Vec::new(),
            initial_dependencies: Vec::new(),
        }
    }

    /// A fixed parameter (set before initialization).
    pub fn parameter(name: &str, start: impl Into<Value>, unit: &str, description: &str) -> Self {
        let mut s = Spec::new(name, start.into(), unit, description, Causality::Parameter);
        s.variability = Variability::Fixed;
        s
    }

    /// An input with the value it holds until a master sets it.
    pub fn input(name: &str, start: impl Into<Value>, unit: &str, description: &str) -> Self {
        Spec::new(name, start.into(), unit, description, Causality::Input)
    }

    /// A Real output, calculated by the model.
    pub fn output(name: &str, unit: &str, description: &str) -> Self {
        let mut s = Spec::new(name, Value::Real(0.0), unit, description, Causality::Output);
        s.has_start = false;
        s
    }

    /// A Boolean output (discrete: it changes at communication points only).
    pub fn boolean_output(name: &str, description: &str) -> Self {
        let mut s = Spec::output(name, "", description);
        s.start = Value::Boolean(false);
        s.variability = Variability::Discrete;
        s
    }

    /// A parameter that may also change between steps.
    pub fn tunable(mut self) -> Self {
        self.variability = Variability::Tunable;
        self
    }

    /// Accepted range; a value outside it is refused with `fmi2Error` naming the variable.
    pub fn range(mut self, min: f64, max: f64) -> Self {
        self.min = Some(min);
        self.max = Some(max);
        self
    }

    /// Lower bound only (the upper one is [`MAX_MAGNITUDE`]).
    pub fn min(mut self, min: f64) -> Self {
        self.min = Some(min);
        self
    }

    /// Upper bound only (the lower one is -[`MAX_MAGNITUDE`]).
    pub fn max(mut self, max: f64) -> Self {
        self.max = Some(max);
        self
    }

    /// The values `fmi2Set*` and `[start]` accept: the declared bounds, and ±[`MAX_MAGNITUDE`]
    /// where none is declared.
    pub fn accepted_range(&self) -> (f64, f64) {
        accepted_range(self.min, self.max)
    }

    /// Names of the inputs this output depends on in initialization mode.
    pub fn initial_dependencies(mut self, names: &[&str]) -> Self {
        self.initial_dependencies = names.iter().map(|n| n.to_string()).collect();
        self
    }

    /// Names of the inputs this output depends on directly (direct feedthrough).
    pub fn feedthrough(mut self, names: &[&str]) -> Self {
        self.feedthrough = names.iter().map(|n| n.to_string()).collect();
        self
    }
}

impl From<f64> for Value {
    fn from(v: f64) -> Self {
        Value::Real(v)
    }
}
impl From<i32> for Value {
    fn from(v: i32) -> Self {
        Value::Integer(v)
    }
}
impl From<bool> for Value {
    fn from(v: bool) -> Self {
        Value::Boolean(v)
    }
}
impl From<&str> for Value {
    fn from(v: &str) -> Self {
        Value::String(v.to_owned())
    }
}

/// A declared variable: its spec and its value reference.
#[derive(Debug, Clone)]
pub struct Declared {
    pub spec: Spec,
    pub vr: u32,
}

/// The variable table a model fills in [`Model::declare`]; value references are dense per type.
#[derive(Debug, Clone, Default)]
pub struct Variables {
    pub(crate) list: Vec<Declared>,
    counts: [u32; 4],
}

impl Variables {
    fn add(&mut self, spec: Spec) -> u32 {
        let t = spec.start.base_type() as usize;
        let vr = self.counts[t];
        self.counts[t] += 1;
        self.list.push(Declared { spec, vr });
        vr
    }

    /// Declare a Real variable.
    pub fn real(&mut self, spec: Spec) -> Real {
        assert!(
            matches!(spec.start, Value::Real(_)),
            "'{}' is not Real",
            spec.name
        );
        Real(self.add(spec))
    }

    /// Declare an Integer variable.
    pub fn integer(&mut self, spec: Spec) -> Integer {
        assert!(
            matches!(spec.start, Value::Integer(_)),
            "'{}' is not Integer",
            spec.name
        );
        Integer(self.add(spec))
    }

    /// Declare a Boolean variable.
    pub fn boolean(&mut self, spec: Spec) -> Boolean {
        assert!(
            matches!(spec.start, Value::Boolean(_)),
            "'{}' is not Boolean",
            spec.name
        );
        Boolean(self.add(spec))
    }

    /// The declared variables in declaration (index) order.
    pub fn declared(&self) -> &[Declared] {
        &self.list
    }

    pub(crate) fn find_mut(&mut self, name: &str) -> Option<&mut Declared> {
        self.list.iter_mut().find(|d| d.spec.name == name)
    }

    /// A store holding every start value (zero where none is declared).
    pub fn start_store(&self) -> Store {
        let mut s = Store {
            reals: vec![0.0; self.counts[0] as usize],
            integers: vec![0; self.counts[1] as usize],
            booleans: vec![false; self.counts[2] as usize],
            strings: vec![String::new(); self.counts[3] as usize],
        };
        for d in &self.list {
            let i = d.vr as usize;
            match &d.spec.start {
                Value::Real(v) => s.reals[i] = *v,
                Value::Integer(v) => s.integers[i] = *v,
                Value::Boolean(v) => s.booleans[i] = *v,
                Value::String(v) => s.strings[i] = v.clone(),
            }
        }
        s
    }
}

/// The values of all variables, indexed by value reference per base type.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Store {
    pub reals: Vec<f64>,
    pub integers: Vec<i32>,
    pub booleans: Vec<bool>,
    pub strings: Vec<String>,
}

impl std::ops::Index<Real> for Store {
    type Output = f64;
    fn index(&self, r: Real) -> &f64 {
        &self.reals[r.0 as usize]
    }
}
impl std::ops::IndexMut<Real> for Store {
    fn index_mut(&mut self, r: Real) -> &mut f64 {
        &mut self.reals[r.0 as usize]
    }
}
impl std::ops::Index<Integer> for Store {
    type Output = i32;
    fn index(&self, r: Integer) -> &i32 {
        &self.integers[r.0 as usize]
    }
}
impl std::ops::IndexMut<Integer> for Store {
    fn index_mut(&mut self, r: Integer) -> &mut i32 {
        &mut self.integers[r.0 as usize]
    }
}
impl std::ops::Index<Boolean> for Store {
    type Output = bool;
    fn index(&self, r: Boolean) -> &bool {
        &self.booleans[r.0 as usize]
    }
}
impl std::ops::IndexMut<Boolean> for Store {
    fn index_mut(&mut self, r: Boolean) -> &mut bool {
        &mut self.booleans[r.0 as usize]
    }
}

/// What a model may do besides computing: log through the master's logger.
pub struct Context<'a> {
    logger: Option<&'a Logger>,
    pub(crate) status: Status,
    pub(crate) tuned: bool,
}

impl<'a> Context<'a> {
    pub(crate) fn new(logger: Option<&'a Logger>) -> Self {
        Context {
            logger,
            status: Status::Ok,
            tuned: false,
        }
    }

    /// A context for a host other than the FMI layer (the IEEE/Cigré real-code DLLs of
    /// `dvpp-realcode`): messages go to `logger`; `tuned` as [`Context::tuned`] reports it.
    pub fn for_host(logger: Option<&'a Logger>, tuned: bool) -> Self {
        Context {
            logger,
            status: Status::Ok,
            tuned,
        }
    }

    /// The worst status a message of this call gave (a warning: [`Status::Warning`]).
    pub fn status(&self) -> Status {
        self.status
    }

    /// In `do_step`: a parameter was set since the model initialized or last stepped (between
    /// steps only tunable ones can be), so the model re-reads its tunable parameters; otherwise
    /// they hold the values the running state was built or last retuned with.
    pub fn tuned(&self) -> bool {
        self.tuned
    }

    /// Log a warning; the call that is running returns `fmi2Warning` (unless worse).
    pub fn warn(&mut self, message: impl fmt::Display) {
        self.status = self.status.max(Status::Warning);
        if let Some(l) = self.logger {
            l.log(Status::Warning, &message.to_string());
        }
    }

    /// Log an event (category `logEvents`, shown when debug logging is on).
    pub fn event(&mut self, message: impl fmt::Display) {
        if let Some(l) = self.logger {
            l.log(Status::Ok, &message.to_string());
        }
    }
}
