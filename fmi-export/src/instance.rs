//! One FMU instance: the FMI 2.0 Co-Simulation state machine around a model, in safe Rust.

use crate::describe::{declare, description_of, Config};
use crate::log::Logger;
use crate::model::{accepted_range, Context, Model, Store, Value, Variables};
use crate::Status;
use model_description::{fnv1a_128, BaseType, Causality, Variability};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Where an instance is in the FMI 2.0 Co-Simulation state machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Phase {
    Instantiated,
    InitializationMode,
    StepComplete,
    Terminated,
    Error,
    Fatal,
}

/// The FMI functions that take an instance, for the state masks and the log lines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Call {
    SetDebugLogging,
    FreeInstance,
    SetupExperiment,
    EnterInitializationMode,
    ExitInitializationMode,
    Terminate,
    Reset,
    Get(BaseType),
    Set(BaseType),
    FmuState,
    GetDirectionalDerivative,
    SetRealInputDerivatives,
    GetRealOutputDerivatives,
    DoStep,
    CancelStep,
    GetStatus,
}

impl Call {
    /// The FMI function name, for log lines.
    pub fn name(self) -> String {
        match self {
            Call::Get(t) => format!("fmi2Get{t}"),
            Call::Set(t) => format!("fmi2Set{t}"),
            Call::FmuState => "fmi2 FMU state functions".into(),
            other => format!("fmi2{other:?}"),
        }
    }

    /// Whether the FMI 2.0 CS state machine allows this call in `phase`.
    pub fn allowed_in(self, phase: Phase) -> bool {
        use Phase::*;
        match self {
            Call::SetDebugLogging | Call::FreeInstance | Call::Reset | Call::FmuState => {
                phase != Fatal
            }
            Call::SetupExperiment | Call::EnterInitializationMode => phase == Instantiated,
            Call::ExitInitializationMode => phase == InitializationMode,
            Call::Terminate | Call::DoStep => phase == StepComplete,
            Call::Get(_) | Call::GetDirectionalDerivative => {
                matches!(
                    phase,
                    InitializationMode | StepComplete | Terminated | Error
                )
            }
            Call::Set(_) | Call::SetRealInputDerivatives => {
                matches!(phase, Instantiated | InitializationMode | StepComplete)
            }
            Call::GetRealOutputDerivatives => matches!(phase, StepComplete | Terminated | Error),
            Call::CancelStep => false,
            Call::GetStatus => matches!(phase, StepComplete | Terminated),
        }
    }
}

/// Everything an FMU state snapshot holds: the part of an instance that evolves (`S`: the
/// model's [`Model::State`]).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Core<S> {
    pub phase: Phase,
    pub time: f64,
    pub stop_time: Option<f64>,
    /// A value was set in initialization mode since the model last initialized.
    pub dirty: bool,
    /// A parameter was set since the model last initialized or stepped (in step mode only
    /// tunable ones can be): the next step re-reads them ([`Context::tuned`]).
    pub tuned: bool,
    pub store: Store,
    /// The model's running state: none until the model first initializes.
    pub state: Option<S>,
}

/// What the layer knows of each variable to police `fmi2Set*`.
struct Meta {
    name: String,
    causality: Causality,
    variability: Variability,
    min: Option<f64>,
    max: Option<f64>,
}

/// An FMU instance.
pub struct Instance<M: Model> {
    pub(crate) tag: u64,
    pub name: String,
    pub guid: String,
    pub logger: Logger,
    pub resources: Option<PathBuf>,
    config: Config<M::Config>,
    meta: [Vec<Meta>; 4],
    /// The model: its variables' handles.
    pub model: M,
    pub core: Core<M::State>,
    fresh: Core<M::State>,
    /// Keeps the strings `fmi2GetString` handed out alive until the next call.
    pub(crate) string_buffer: Vec<std::ffi::CString>,
    /// The values of the `fmi2Set*` call in progress (kept to reuse its allocation).
    pub(crate) set_buffer: Vec<Value>,
}

/// Marks memory that holds an `Instance<M>` or a `Snapshot<M>` of this model.
pub(crate) fn model_tag<M: Model>() -> u64 {
    fnv1a_128(M::IDENTIFIER.as_bytes()) as u64
}

/// How the error of a step that left a value non-finite ends.
pub const NOT_FINITE: &str = "the model cannot continue";

/// Header of serialized FMU states.
const MAGIC: &[u8; 8] = b"DVPPFMU\x02";
const STATE_FORMAT: u16 = 2;

impl<M: Model> Instance<M> {
    /// Build an instance for `config`; `expected_guid` must match the description it implies.
    pub fn new(
        name: &str,
        expected_guid: &str,
        resources: Option<PathBuf>,
        config: Config<M::Config>,
        logger: Logger,
    ) -> Result<Self, String> {
        let (model, vars) = declare::<M>(&config, resources.as_deref())?;
        let description = description_of::<M>(&vars, &config.experiment)?;
        if description.guid != expected_guid {
            return Err(format!(
                "GUID mismatch: the modelDescription.xml says {expected_guid}, but this binary with \
                 these resources implements {} (rebuild the FMU with `cargo xtask bundle`)",
                description.guid
            ));
        }
        let core = Core {
            phase: Phase::Instantiated,
            time: config.experiment.start,
            stop_time: None,
            dirty: true,
            tuned: false,
            store: vars.start_store(),
            state: None,
        };
        Ok(Instance {
            tag: model_tag::<M>(),
            name: name.to_owned(),
            guid: description.guid,
            logger,
            resources,
            meta: meta_of(&vars),
            model,
            fresh: core.clone(),
            core,
            config,
            string_buffer: Vec::new(),
            set_buffer: Vec::new(),
        })
    }

    /// Log an error and return `fmi2Error`.
    pub fn error(&self, message: impl AsRef<str>) -> Status {
        self.logger.log(Status::Error, message.as_ref());
        Status::Error
    }

    /// The configuration this instance was built from.
    pub fn config(&self) -> &Config<M::Config> {
        &self.config
    }

    /// The base type and value reference of the variable called `name`.
    pub fn variable(&self, name: &str) -> Option<(BaseType, u32)> {
        [
            BaseType::Real,
            BaseType::Integer,
            BaseType::Boolean,
            BaseType::String,
        ]
        .into_iter()
        .find_map(|t| {
            self.meta[t as usize]
                .iter()
                .position(|m| m.name == name)
                .map(|vr| (t, vr as u32))
        })
    }

    pub fn setup_experiment(&mut self, start: f64, stop: Option<f64>) -> Status {
        if !start.is_finite() || stop.is_some_and(|s| !s.is_finite() || s < start) {
            return self.error(format!(
                "fmi2SetupExperiment: bad times start={start} stop={stop:?}"
            ));
        }
        self.core.time = start;
        self.core.stop_time = stop;
        Status::Ok
    }

    pub fn enter_initialization_mode(&mut self) -> Status {
        self.core.phase = Phase::InitializationMode;
        self.core.dirty = true;
        Status::Ok
    }

    fn initialize_if_dirty(&mut self) -> Status {
        if !self.core.dirty {
            return Status::Ok;
        }
        let mut ctx = Context::new(Some(&self.logger));
        let core = &mut self.core;
        match self
            .model
            .initialize(core.state.as_ref(), &mut core.store, &mut ctx)
        {
            Ok(state) => {
                core.state = Some(state);
                core.dirty = false;
                core.tuned = false;
                ctx.status
            }
            Err(e) => {
                let status = self.error(format!("initialization failed: {e}"));
                status.max(ctx.status)
            }
        }
    }

    pub fn exit_initialization_mode(&mut self) -> Status {
        let status = self.initialize_if_dirty();
        if status < Status::Error {
            self.core.phase = Phase::StepComplete;
        }
        status
    }

    pub fn terminate(&mut self) -> Status {
        self.core.phase = Phase::Terminated;
        Status::Ok
    }

    pub fn reset(&mut self) -> Status {
        self.core = self.fresh.clone();
        Status::Ok
    }

    /// Outputs are current after every call except in initialization mode, where they are
    /// computed on demand.
    pub fn before_get(&mut self) -> Status {
        if self.core.phase == Phase::InitializationMode {
            self.initialize_if_dirty()
        } else {
            Status::Ok
        }
    }

    /// Every Real variable `fmi2SetReal` may set before initialization: name, value reference,
    /// whether it may also be set between steps (an input or a tunable parameter), and the
    /// values it accepts.
    pub fn settable_reals(&self) -> Vec<(String, u32, bool, (f64, f64))> {
        let settable = |m: &Meta| match (m.causality, m.variability) {
            (Causality::Input, _) | (Causality::Parameter, Variability::Tunable) => Some(true),
            (Causality::Parameter, _) => Some(false),
            _ => None,
        };
        self.meta[BaseType::Real as usize]
            .iter()
            .enumerate()
            .filter_map(|(vr, m)| {
                settable(m).map(|later| {
                    let range = accepted_range(m.min, m.max);
                    (m.name.clone(), vr as u32, later, range)
                })
            })
            .collect()
    }

    /// Check that every value reference exists for `t`; the first unknown one is reported.
    pub fn check_refs(&self, t: BaseType, vrs: &[u32]) -> Result<(), String> {
        match vrs
            .iter()
            .find(|&&vr| vr as usize >= self.meta[t as usize].len())
        {
            Some(vr) => Err(format!("unknown {t} value reference {vr}")),
            None => Ok(()),
        }
    }

    /// Check that `fmi2Set{t}` may set every variable in `vrs` now and that every value is
    /// acceptable; nothing is applied unless all are.
    pub fn check_set(&self, t: BaseType, vrs: &[u32], values: &[Value]) -> Result<(), String> {
        self.check_refs(t, vrs)?;
        let phase = self.core.phase;
        for (&vr, value) in vrs.iter().zip(values) {
            let m = &self.meta[t as usize][vr as usize];
            let settable = match (m.causality, m.variability) {
                (Causality::Input, _) => true,
                (Causality::Parameter, Variability::Tunable) => true,
                (Causality::Parameter, _) => phase != Phase::StepComplete,
                _ => false,
            };
            if !settable {
                return Err(format!(
                    "'{}' ({:?}, {:?}) cannot be set in state {phase:?}",
                    m.name, m.causality, m.variability
                ));
            }
            let x = match value {
                Value::Real(x) => *x,
                Value::Integer(i) => *i as f64,
                _ => continue,
            };
            if !x.is_finite() {
                return Err(format!(
                    "value {x} for '{}' is not finite; rejected",
                    m.name
                ));
            }
            // No physical parameter is closer to zero than the smallest normal f64; dividing by
            // one overflows (a time constant, an inertia), so they are refused here, by name.
            if m.causality == Causality::Parameter && x != 0.0 && !x.is_normal() {
                return Err(format!(
                    "value {x:e} for parameter '{}' is subnormal (nonzero but below {:e} in magnitude); rejected",
                    m.name,
                    f64::MIN_POSITIVE
                ));
            }
            let (lo, hi) = accepted_range(m.min, m.max);
            if !(lo..=hi).contains(&x) {
                return Err(format!(
                    "value {} for '{}' is outside its range [{}, {}]; rejected",
                    shown(x),
                    m.name,
                    shown(lo),
                    shown(hi)
                ));
            }
        }
        Ok(())
    }

    /// The parameters whose values differ from their start values, as `'name' = value` (at most
    /// `limit`, then `…`): what a contained panic in initialization or a step most likely comes
    /// from.
    pub fn changed_parameters(&self, limit: usize) -> Vec<String> {
        let (now, start) = (&self.core.store, &self.fresh.store);
        let mut out = Vec::new();
        for (t, metas) in self.meta.iter().enumerate() {
            for (i, m) in metas.iter().enumerate() {
                if m.causality != Causality::Parameter {
                    continue;
                }
                let changed =
                    match t {
                        0 => (now.reals[i] != start.reals[i]).then(|| shown(now.reals[i])),
                        1 => (now.integers[i] != start.integers[i])
                            .then(|| now.integers[i].to_string()),
                        2 => (now.booleans[i] != start.booleans[i])
                            .then(|| now.booleans[i].to_string()),
                        _ => (now.strings[i] != start.strings[i])
                            .then(|| format!("{:?}", now.strings[i])),
                    };
                if let Some(v) = changed {
                    if out.len() == limit {
                        out.push("…".into());
                        return out;
                    }
                    out.push(format!("'{}' = {v}", m.name));
                }
            }
        }
        out
    }

    /// Store checked values.
    pub fn apply_set(&mut self, vrs: &[u32], values: &mut Vec<Value>) {
        let s = &mut self.core.store;
        for (&vr, v) in vrs.iter().zip(values.drain(..)) {
            let i = vr as usize;
            if self.meta[v.base_type() as usize][i].causality == Causality::Parameter {
                self.core.tuned = true;
            }
            match v {
                Value::Real(x) => s.reals[i] = x,
                Value::Integer(x) => s.integers[i] = x,
                Value::Boolean(x) => s.booleans[i] = x,
                Value::String(x) => s.strings[i] = x,
            }
        }
        if self.core.phase != Phase::StepComplete {
            self.core.dirty = true;
        }
    }

    pub fn do_step(&mut self, t: f64, h: f64) -> Status {
        let now = self.core.time;
        if !(h > 0.0 && h.is_finite()) {
            return self.error(format!(
                "fmi2DoStep: communicationStepSize = {h} s must be positive and finite; refused"
            ));
        }
        if h > M::MAX_STEP {
            return self.error(format!(
                "fmi2DoStep: communicationStepSize = {h} s exceeds the longest step {} accepts, \
                 {} s; refused (take several shorter steps)",
                M::IDENTIFIER,
                M::MAX_STEP
            ));
        }
        let tol = 1e-9 * now.abs().max(1.0);
        if !t.is_finite() || (t - now).abs() > tol {
            return self.error(format!(
                "fmi2DoStep: currentCommunicationPoint {t} does not match the FMU's time {now}"
            ));
        }
        if let Some(stop) = self.core.stop_time {
            if t + h > stop + tol {
                return self.error(format!(
                    "fmi2DoStep: step to {} passes the stop time {stop}",
                    t + h
                ));
            }
        }
        let mut ctx = Context::new(Some(&self.logger));
        ctx.tuned = self.core.tuned;
        let core = &mut self.core;
        let Some(state) = core.state.as_mut() else {
            return self.error(format!(
                "fmi2DoStep at t = {t}: the model has not initialized"
            ));
        };
        if let Err(e) = self.model.do_step(state, &mut core.store, t, h, &mut ctx) {
            let status = ctx.status;
            return self
                .error(format!("fmi2DoStep at t = {t}: {e}"))
                .max(status);
        }
        let status = ctx.status;
        // One pass without early exit (which vectorizes) tells whether any value went
        // non-finite; only then is it looked for.
        let reals = &self.core.store.reals;
        let any_bad = reals.iter().fold(false, |bad, x| bad | !x.is_finite());
        if let Some((vr, x)) = reals
            .iter()
            .enumerate()
            .find(|(_, x)| any_bad && !x.is_finite())
        {
            return self.error(format!(
                "fmi2DoStep at t = {t}: '{}' became {x}; {NOT_FINITE}",
                self.meta[0][vr].name
            ));
        }
        self.core.time = t + h;
        self.core.tuned = false;
        status
    }

    /// Serialize a snapshot: magic, format version, GUID, payload length, payload, checksum.
    pub fn serialize(&self, core: &Core<M::State>) -> Result<Vec<u8>, String> {
        let payload =
            postcard::to_stdvec(core).map_err(|e| format!("cannot serialize FMU state: {e}"))?;
        let mut out = Vec::with_capacity(payload.len() + 64);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&STATE_FORMAT.to_le_bytes());
        out.extend_from_slice(&(self.guid.len() as u16).to_le_bytes());
        out.extend_from_slice(self.guid.as_bytes());
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(&payload);
        let sum = fnv1a_128(&out) as u64;
        out.extend_from_slice(&sum.to_le_bytes());
        Ok(out)
    }

    /// Read bytes written by [`Self::serialize`] (in this or another process); anything
    /// truncated, corrupted, of another format version or of another model is refused.
    pub fn deserialize(&self, bytes: &[u8]) -> Result<Core<M::State>, String> {
        let bad = |what: &str| format!("serialized FMU state refused: {what}");
        if bytes.len() < MAGIC.len() + 2 + 2 + 8 + 8 {
            return Err(bad("too short"));
        }
        let (body, sum) = bytes.split_at(bytes.len() - 8);
        if fnv1a_128(body) as u64 != u64::from_le_bytes(sum.try_into().unwrap()) {
            return Err(bad("checksum mismatch (truncated or corrupted)"));
        }
        let (magic, rest) = body.split_at(MAGIC.len());
        if magic != MAGIC {
            return Err(bad("not an FMU state of this project"));
        }
        let (format, rest) = rest.split_at(2);
        let format = u16::from_le_bytes(format.try_into().unwrap());
        if format != STATE_FORMAT {
            return Err(bad(&format!(
                "format version {format}, this FMU reads {STATE_FORMAT}"
            )));
        }
        let (glen, rest) = rest.split_at(2);
        let glen = u16::from_le_bytes(glen.try_into().unwrap()) as usize;
        if rest.len() < glen + 8 {
            return Err(bad("header truncated"));
        }
        let (guid, rest) = rest.split_at(glen);
        if guid != self.guid.as_bytes() {
            return Err(bad(&format!(
                "it belongs to GUID {}, this instance is {}",
                String::from_utf8_lossy(guid),
                self.guid
            )));
        }
        let (len, payload) = rest.split_at(8);
        if u64::from_le_bytes(len.try_into().unwrap()) as usize != payload.len() {
            return Err(bad("payload length mismatch"));
        }
        let core: Core<M::State> =
            postcard::from_bytes(payload).map_err(|e| bad(&e.to_string()))?;
        let s = &core.store;
        let sizes = [
            s.reals.len(),
            s.integers.len(),
            s.booleans.len(),
            s.strings.len(),
        ];
        if sizes.iter().zip(&self.meta).any(|(n, m)| *n != m.len()) {
            return Err(bad("variable counts differ from this model's"));
        }
        Ok(core)
    }
}

fn meta_of(vars: &Variables) -> [Vec<Meta>; 4] {
    let mut meta: [Vec<Meta>; 4] = Default::default();
    let mut list: Vec<_> = vars.declared().iter().collect();
    list.sort_by_key(|d| d.vr);
    for d in list {
        meta[d.spec.start.base_type() as usize].push(Meta {
            name: d.spec.name.clone(),
            causality: d.spec.causality,
            variability: d.spec.variability,
            min: d.spec.min,
            max: d.spec.max,
        });
    }
    meta
}

/// What `fmi2GetFMUstate` hands out: a tagged copy of the evolving part of an instance.
pub struct Snapshot<M: Model> {
    pub(crate) tag: u64,
    pub(crate) core: Core<M::State>,
}

/// A value as log lines show it: plain, or in exponent form when very large or small.
pub(crate) fn shown(x: f64) -> String {
    if x == 0.0 || (1e-6..1e9).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}
