//! One loaded component of a system: its instance, the outputs it records, the inputs waiting
//! to be set, its direct-feedthrough dependencies and the checking of its FMI calls.

use super::Error;
use crate::fmu::{Fmu, Instance, Library, SavedState, Status, Trace};
use crate::ssp::{self, Component, Value};
use model_description::{BaseType, Causality, ModelDescription};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::sync::Arc;

/// The two phases of a run, whose direct feedthrough differs: initialization
/// (`InitialUnknowns`) and steps (`Outputs`).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(crate) enum Phase {
    Init,
    Step,
}

/// Variable index (1-based, as in `ModelStructure`) to value reference and type.
pub(crate) struct Var {
    index: u32,
    vr: u32,
    ty: BaseType,
}

impl Var {
    /// The variable's index in `ModelVariables`, 1-based.
    pub(crate) fn index(&self) -> u32 {
        self.index
    }

    pub(crate) fn vr(&self) -> u32 {
        self.vr
    }

    pub(crate) fn ty(&self) -> BaseType {
        self.ty
    }
}

/// The variable `name` of component `comp`, and its causality.
pub(crate) fn variable(
    md: &ModelDescription,
    comp: &str,
    name: &str,
) -> Result<(Var, Causality), Error> {
    let index = md
        .model_variables
        .variables
        .iter()
        .position(|v| v.name == name)
        .ok_or_else(|| {
            Error::Load(format!(
                "component '{comp}': '{name}' is not a variable of {}",
                md.model_name
            ))
        })?;
    let v = &md.model_variables.variables[index];
    Ok((
        Var {
            index: index as u32 + 1,
            vr: v.value_reference,
            ty: v.base_type(),
        },
        v.causality(),
    ))
}

/// Create `<dir>/<component>.trace` with its header (the component's name must be a plain file
/// name).
fn start_trace(dir: &Path, c: &Component, md: &ModelDescription) -> Result<Trace, Error> {
    let name = &c.name;
    if name.is_empty()
        || name.starts_with('.')
        || name.contains(['/', '\\', '\0'])
        || name.chars().any(char::is_control)
    {
        return Err(Error::Load(format!(
            "--trace: component '{name}': its name cannot be a file name"
        )));
    }
    let path = dir.join(format!("{name}.trace"));
    let header = [
        ("unit", name.as_str()),
        ("source", c.source.as_str()),
        ("model", md.model_identifier().unwrap_or(&md.model_name)),
        ("guid", md.guid.as_str()),
    ];
    Trace::create(&path, &header)
        .map_err(|e| Error::Load(format!("--trace: cannot create {}: {e}", path.display())))
}

/// Output index → input indices, from a list of unknowns (`None` dependencies = every input).
fn dependencies(
    md: &ModelDescription,
    unknowns: &[model_description::Unknown],
) -> Result<BTreeMap<u32, BTreeSet<u32>>, String> {
    let inputs: BTreeSet<u32> = md
        .model_variables
        .variables
        .iter()
        .enumerate()
        .filter(|(_, v)| v.causality() == Causality::Input)
        .map(|(i, _)| i as u32 + 1)
        .collect();
    unknowns
        .iter()
        .map(|u| {
            let deps = match u.dependency_indices() {
                Some(d) => d?.into_iter().filter(|i| inputs.contains(i)).collect(),
                None => inputs.clone(),
            };
            Ok((u.index, deps))
        })
        .collect()
}

/// One loaded component.
pub(crate) struct Unit {
    name: String,
    inst: Instance,
    /// Whether this side initializes, steps and records the unit (a federate loads every
    /// component of its system but runs only its own).
    local: bool,
    /// Keep the unit's warnings without printing them (runs of a sweep).
    quiet: bool,
    /// Variables read after a step (output connectors and connection starts), recorded.
    reads: Vec<Var>,
    values: Vec<f64>,
    /// `values` is current (no step and no input change since it was read).
    fresh: bool,
    /// Inputs to set before the next read or step: Reals (value references, values), others.
    pending_real: (Vec<u32>, Vec<f64>),
    pending_other: Vec<(u32, BaseType, f64)>,
    /// The Real, Integer and Boolean entries of `reads` (fixed at load) and buffers for them:
    /// one call per type reads them all.
    real_vrs: Vec<u32>,
    buf: Vec<f64>,
    int_vrs: Vec<u32>,
    int_buf: Vec<i32>,
    bool_vrs: Vec<u32>,
    bool_buf: Vec<bool>,
    /// Output index → input indices it depends on, during steps and during initialization.
    step_deps: BTreeMap<u32, BTreeSet<u32>>,
    init_deps: BTreeMap<u32, BTreeSet<u32>>,
    last_message: Option<String>,
    /// The status of the last `fmi2DoStep` of a stepping round, and of the reads that followed
    /// it on the same thread (checked in unit order after the round).
    stepped: Status,
    fetched: Option<(Status, &'static str)>,
}

impl Unit {
    /// Check component `c`'s connectors against its FMU and instantiate it; with `trace`, a
    /// directory, every call to the instance is recorded in `<trace>/<component>.trace`.
    pub(crate) fn load(c: &Component, fmu: Arc<Fmu>, trace: Option<&Path>) -> Result<Unit, Error> {
        let md = &fmu.description;
        let mut reads = Vec::new();
        for k in &c.connectors {
            let (var, causality) = variable(md, &c.name, &k.name)?;
            if var.ty != BaseType::from(k.ty) {
                return Err(Error::Load(format!(
                    "component '{}': connector '{}' is {:?} in the SSD but {} in {}",
                    c.name, k.name, k.ty, var.ty, md.model_name
                )));
            }
            let expected = match k.kind {
                ssp::Kind::Input => Causality::Input,
                ssp::Kind::Output => Causality::Output,
                ssp::Kind::Parameter => Causality::Parameter,
                ssp::Kind::CalculatedParameter => Causality::CalculatedParameter,
            };
            if causality != expected {
                return Err(Error::Load(format!(
                    "component '{}': connector '{}' is {:?} in the SSD but {causality:?} in {}",
                    c.name, k.name, k.kind, md.model_name
                )));
            }
            if k.kind == ssp::Kind::Output && var.ty != BaseType::String {
                reads.push(var);
            }
        }
        let step_deps = dependencies(md, md.model_structure.outputs());
        // Outputs absent from InitialUnknowns are exact: they depend on nothing.
        let init_deps = dependencies(md, md.model_structure.initial_unknowns());
        let (step_deps, init_deps) = match (step_deps, init_deps) {
            (Ok(s), Ok(i)) => (s, i),
            (Err(e), _) | (_, Err(e)) => {
                return Err(Error::Load(format!("component '{}': {e}", c.name)))
            }
        };
        let trace = match trace {
            Some(dir) => Some(start_trace(dir, c, md)?),
            None => None,
        };
        let inst = fmu
            .instantiate_traced(&c.name, trace)
            .map_err(|e| Error::Load(format!("component '{}': {e}", c.name)))?;
        Ok(Unit {
            local: true,
            quiet: false,
            name: c.name.clone(),
            inst,
            values: vec![0.0; reads.len()],
            reads,
            fresh: false,
            pending_real: (Vec::new(), Vec::new()),
            pending_other: Vec::new(),
            real_vrs: Vec::new(),
            buf: Vec::new(),
            int_vrs: Vec::new(),
            int_buf: Vec::new(),
            bool_vrs: Vec::new(),
            bool_buf: Vec::new(),
            fetched: None,
            step_deps,
            init_deps,
            last_message: None,
            stepped: Status::Ok,
        })
    }

    pub(crate) fn name(&self) -> &str {
        &self.name
    }

    pub(crate) fn fmu(&self) -> &Arc<Fmu> {
        self.inst.fmu()
    }

    pub(crate) fn library(&self) -> &Arc<Library> {
        self.inst.fmu().library()
    }

    /// The recorded outputs as last read.
    pub(crate) fn values(&self) -> &[f64] {
        &self.values
    }

    /// The `ModelVariables` index of recorded output `slot`.
    pub(crate) fn output_index(&self, slot: usize) -> u32 {
        self.reads[slot].index
    }

    /// `component.variable` of every recorded output, appended to `out`.
    pub(crate) fn columns(&self, out: &mut Vec<String>) {
        let md = &self.inst.fmu().description;
        for r in &self.reads {
            let name = &md.model_variables.variables[r.index as usize - 1].name;
            out.push(format!("{}.{name}", self.name));
        }
    }

    pub(crate) fn is_local(&self) -> bool {
        self.local
    }

    pub(crate) fn set_local(&mut self, local: bool) {
        self.local = local;
    }

    /// Keep the unit's warnings without printing them.
    pub(crate) fn set_quiet(&mut self) {
        self.quiet = true;
    }

    /// Whether the FMU can save and restore its state (`canGetAndSetFMUstate`).
    pub(crate) fn can_save_state(&self) -> bool {
        self.inst
            .fmu()
            .description
            .co_simulation
            .as_ref()
            .is_some_and(|cs| cs.can_get_and_set_fmu_state)
    }

    /// Fix the reads per type (after every connection has its slot).
    pub(crate) fn finish_reads(&mut self) {
        let vrs = |ty| -> Vec<u32> {
            self.reads
                .iter()
                .filter(|r| r.ty == ty)
                .map(|r| r.vr)
                .collect()
        };
        (self.real_vrs, self.int_vrs, self.bool_vrs) = (
            vrs(BaseType::Real),
            vrs(BaseType::Integer),
            vrs(BaseType::Boolean),
        );
        self.buf = vec![0.0; self.real_vrs.len()];
        self.int_buf = vec![0; self.int_vrs.len()];
        self.bool_buf = vec![false; self.bool_vrs.len()];
    }

    /// The slot of output `var` among the recorded outputs (added when not recorded yet).
    pub(crate) fn slot(&mut self, var: Var) -> usize {
        match self
            .reads
            .iter()
            .position(|r| r.vr == var.vr && r.ty == var.ty)
        {
            Some(i) => i,
            None => {
                self.reads.push(var);
                self.values.push(0.0);
                self.reads.len() - 1
            }
        }
    }

    /// Output index → the input indices it depends on, in `phase`.
    pub(crate) fn deps(&self, phase: Phase) -> &BTreeMap<u32, BTreeSet<u32>> {
        match phase {
            Phase::Init => &self.init_deps,
            Phase::Step => &self.step_deps,
        }
    }

    /// Whether setting input `index` can change an output of this unit now.
    pub(crate) fn feeds_through(&self, phase: Phase, index: u32) -> bool {
        self.deps(phase).values().any(|d| d.contains(&index))
    }

    /// Report an FMI call's status: `Err` (naming the unit and its last message) above warning.
    pub(crate) fn check(
        &mut self,
        what: impl FnOnce() -> String,
        s: Status,
        warnings: &mut Vec<String>,
    ) -> Result<(), Error> {
        self.drain_log(warnings);
        if s <= Status::Warning {
            return Ok(());
        }
        Err(Error::Fmu {
            unit: self.name.clone(),
            call: what(),
            status: s,
            log: self.last_message.clone(),
        })
    }

    /// Print the unit's new log messages with its name; keep warnings and the last message.
    fn drain_log(&mut self, warnings: &mut Vec<String>) {
        if !self.inst.has_log() {
            return;
        }
        for r in self.inst.take_log() {
            let line = format!(
                "[{}] {:?} {}: {}",
                self.name, r.status, r.category, r.message
            );
            if r.status >= Status::Warning {
                if !self.quiet {
                    eprintln!("{line}");
                }
                if r.status == Status::Warning {
                    warnings.push(line);
                }
            }
            self.last_message = Some(r.message);
        }
    }

    /// `fmi2SetupExperiment` from `start` to `stop`, s.
    pub(crate) fn setup_experiment(
        &mut self,
        start: f64,
        stop: f64,
        warnings: &mut Vec<String>,
    ) -> Result<(), Error> {
        let s = self.inst.setup_experiment(start, Some(stop));
        self.check(|| "fmi2SetupExperiment".into(), s, warnings)
    }

    /// Set parameter `name` (variable `var`) to `value`.
    pub(crate) fn set_parameter(
        &mut self,
        name: &str,
        var: &Var,
        value: &Value,
        warnings: &mut Vec<String>,
    ) -> Result<(), Error> {
        let s = match value {
            Value::Real(v) => self.inst.set_real(&[var.vr], &[*v]),
            // Range-checked against i32 by the SSP reader.
            Value::Integer(v) => self.inst.set_integer(&[var.vr], &[*v as i32]),
            Value::Boolean(v) => self.inst.set_boolean(&[var.vr], &[*v]),
            Value::String(v) => self.inst.set_string(&[var.vr], &[v.as_str()]),
        };
        self.check(|| format!("setting parameter '{name}'"), s, warnings)
    }

    /// `fmi2EnterInitializationMode`; the outputs are read again when needed.
    pub(crate) fn enter_initialization(&mut self, warnings: &mut Vec<String>) -> Result<(), Error> {
        let s = self.inst.enter_initialization_mode();
        self.check(|| "fmi2EnterInitializationMode".into(), s, warnings)?;
        self.fresh = false;
        Ok(())
    }

    /// `fmi2ExitInitializationMode`; the outputs are read again when needed.
    pub(crate) fn exit_initialization(&mut self, warnings: &mut Vec<String>) -> Result<(), Error> {
        let s = self.inst.exit_initialization_mode();
        self.check(|| "fmi2ExitInitializationMode".into(), s, warnings)?;
        self.fresh = false;
        Ok(())
    }

    /// `fmi2Terminate`.
    pub(crate) fn terminate(&mut self, warnings: &mut Vec<String>) -> Result<(), Error> {
        let s = self.inst.terminate();
        self.check(|| "fmi2Terminate".into(), s, warnings)
    }

    /// `fmi2DoStep` from `ts` by `hs` (s), checked; the outputs are read again when needed.
    pub(crate) fn do_step(
        &mut self,
        ts: f64,
        hs: f64,
        warnings: &mut Vec<String>,
    ) -> Result<(), Error> {
        let s = self.inst.do_step(ts, hs);
        self.fresh = false;
        self.check(|| format!("fmi2DoStep({ts}, {hs})"), s, warnings)
    }

    /// `fmi2DoStep` from `ts` by `hs` (s), then the reading of the outputs when no input waits
    /// and the step went well; the statuses are kept for [`Unit::check_round_step`] (this runs on
    /// any thread, the log is left to the checks).
    pub(crate) fn step_round(&mut self, ts: f64, hs: f64) {
        self.stepped = self.inst.do_step(ts, hs);
        self.fresh = false;
        let idle = self.pending_real.0.is_empty() && self.pending_other.is_empty();
        if self.stepped <= Status::Warning && idle {
            self.fetched = Some(self.fetch());
        }
    }

    /// The status of the step of [`Unit::step_round`], checked (and forgotten).
    pub(crate) fn check_round_step(
        &mut self,
        ts: f64,
        hs: f64,
        warnings: &mut Vec<String>,
    ) -> Result<(), Error> {
        let s = std::mem::replace(&mut self.stepped, Status::Ok);
        self.check(|| format!("fmi2DoStep({ts}, {hs})"), s, warnings)
    }

    /// The status of the reads of [`Unit::step_round`], checked: the outputs are current.
    pub(crate) fn check_round_reads(&mut self, warnings: &mut Vec<String>) -> Result<(), Error> {
        if let Some((s, what)) = self.fetched.take() {
            self.check(|| what.into(), s, warnings)?;
            self.fresh = true;
        }
        Ok(())
    }

    /// Forget the reads of a round that failed before they were checked.
    pub(crate) fn end_round(&mut self) {
        self.fetched = None;
    }

    fn set(&mut self, vr: u32, ty: BaseType, v: f64) -> Status {
        match ty {
            BaseType::Real => self.inst.set_real(&[vr], &[v]),
            BaseType::Integer => self.inst.set_integer(&[vr], &[v.round() as i32]),
            BaseType::Boolean => self.inst.set_boolean(&[vr], &[v != 0.0]),
            BaseType::String => Status::Error,
        }
    }

    /// Set the pending inputs (the Reals in one call).
    pub(crate) fn flush(&mut self, warnings: &mut Vec<String>) -> Result<(), Error> {
        if !self.pending_real.0.is_empty() {
            let s = self
                .inst
                .set_real(&self.pending_real.0, &self.pending_real.1);
            self.pending_real.0.clear();
            self.pending_real.1.clear();
            self.check(|| "fmi2SetReal".into(), s, warnings)?;
        }
        for (vr, ty, v) in std::mem::take(&mut self.pending_other) {
            let s = self.set(vr, ty, v);
            self.check(|| format!("fmi2Set{ty}"), s, warnings)?;
        }
        Ok(())
    }

    /// Queue input `vr` of type `ty` to be set to `v` (before the next read or step); when it
    /// feeds through to an output (`feeds`), the outputs are read again when needed.
    pub(crate) fn push(&mut self, vr: u32, ty: BaseType, v: f64, feeds: bool) {
        if ty == BaseType::Real {
            self.pending_real.0.push(vr);
            self.pending_real.1.push(v);
        } else {
            self.pending_other.push((vr, ty, v));
        }
        if feeds {
            self.fresh = false;
        }
    }

    /// Read every recorded variable unless they are current (after setting the pending inputs).
    pub(crate) fn refresh(&mut self, warnings: &mut Vec<String>) -> Result<(), Error> {
        if self.fresh {
            return Ok(());
        }
        self.flush(warnings)?;
        let (s, what) = self.fetch();
        self.check(|| what.into(), s, warnings)?;
        self.fresh = true;
        Ok(())
    }

    /// Get every recorded variable into `values` (one call per type), without setting inputs
    /// or looking at the log: the worst status and its call (the first above a warning stops).
    fn fetch(&mut self) -> (Status, &'static str) {
        let mut worst = (Status::Ok, "fmi2GetReal");
        let s = self.inst.get_real(&self.real_vrs, &mut self.buf);
        if s > worst.0 {
            worst = (s, "fmi2GetReal");
        }
        if !self.int_vrs.is_empty() && worst.0 <= Status::Warning {
            let s = self.inst.get_integer(&self.int_vrs, &mut self.int_buf);
            if s > worst.0 {
                worst = (s, "fmi2GetInteger");
            }
        }
        if !self.bool_vrs.is_empty() && worst.0 <= Status::Warning {
            let s = self.inst.get_boolean(&self.bool_vrs, &mut self.bool_buf);
            if s > worst.0 {
                worst = (s, "fmi2GetBoolean");
            }
        }
        if worst.0 > Status::Warning {
            return worst;
        }
        let (mut real, mut int, mut boolean) = (0, 0, 0);
        for (value, r) in self.values.iter_mut().zip(&self.reads) {
            match r.ty {
                BaseType::Real => {
                    *value = self.buf[real];
                    real += 1;
                }
                BaseType::Integer => {
                    *value = self.int_buf[int] as f64;
                    int += 1;
                }
                BaseType::Boolean => {
                    *value = self.bool_buf[boolean] as i32 as f64;
                    boolean += 1;
                }
                BaseType::String => {}
            }
        }
        worst
    }

    /// Note in the unit's trace, if any, that a communication point at `t` s was recorded with
    /// the values read last.
    pub(crate) fn trace_sample(&mut self, t: f64) {
        if let Some(trace) = self.inst.trace_mut() {
            trace.sample(t);
        }
    }

    /// Flush the unit's trace, if any.
    pub(crate) fn finish_trace(&mut self) -> Result<(), Error> {
        self.inst
            .finish_trace()
            .map_err(|e| Error::Run(format!("component '{}': {e}", self.name)))
    }

    /// Save the unit's state into `states[k]` (made and pushed when there is none yet).
    pub(crate) fn save_state(
        &mut self,
        states: &mut Vec<SavedState>,
        k: usize,
        warnings: &mut Vec<String>,
    ) -> Result<(), Error> {
        let s = match states.get_mut(k) {
            Some(saved) => self.inst.update_state(saved),
            None => {
                let (s, saved) = self.inst.get_state();
                if let Some(saved) = saved {
                    states.push(saved);
                }
                s
            }
        };
        self.check(|| "fmi2GetFMUstate".into(), s, warnings)
    }

    /// Restore the unit's state from `saved`; the outputs are read again when needed.
    pub(crate) fn restore_state(
        &mut self,
        saved: &SavedState,
        warnings: &mut Vec<String>,
    ) -> Result<(), Error> {
        let s = self.inst.set_state(saved);
        self.fresh = false;
        self.check(|| "fmi2SetFMUstate".into(), s, warnings)
    }

    /// Free a state saved by [`Unit::save_state`].
    pub(crate) fn free_state(&mut self, saved: SavedState) {
        let _ = self.inst.free_state(saved);
    }
}
