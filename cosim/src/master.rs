//! The co-simulation master: runs an SSP system of FMUs in fixed communication steps (integer
//! nanoseconds) from initialization to the stop time, handing each point to its observers.
//!
//! How the units advance over a step is an [`Algorithm`] ([`Jacobi`], [`GaussSeidel`]); what
//! happens to the results is up to the [`Observer`]s ([`CsvWriter`] streams them to disk,
//! [`Progress`] reports, [`Recorder`] keeps them in memory). The loop polls
//! [`crate::interrupt::requested`] at each communication point. [`Jacobi`] and [`Iterative`]
//! step the units on [`System::set_threads`] threads (a small pool, the caller included), with
//! the results of one thread bit for bit.
//!
//! One exchange moves every connection's value from its start connector to its end connector
//! (with the SSP `LinearTransformation`), in dependency order: a connection leaving a unit with
//! direct feedthrough (`ModelStructure/Outputs` dependencies during steps, `InitialUnknowns`
//! during initialization) is read after the connections into that unit were set. A cycle of
//! such dependencies (an algebraic loop) is reported and broken at the connection of the cycle
//! that comes first in the SSD: that connection carries the value from before the exchange.
//! Initialization repeats the exchange until no value changes.

mod algorithm;
mod observer;
mod pool;
mod results;

pub use algorithm::{Algorithm, GaussSeidel, Iterative, Jacobi};
pub use observer::{End, Observer, Progress, Recorder, RunInfo};
pub use results::{
    matches, partial_path, Csv, CsvWriter, Format, Mat, MatWriter, Record, ResultWriter, Select,
};

pub use crate::fmu::Sharing;

use crate::fmu::{Fmu, Instance, Status};
use crate::interrupt;
use crate::ssp::{self, Component, Value};
use crate::table::{seconds, ticks, Table};
use model_description::{BaseType, Causality, ModelDescription};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::path::Path;
use std::sync::Arc;

/// The built-in algorithms by name (the `--algorithm` of `cosim`); [`System::simulate_with`]
/// takes any [`Algorithm`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scheme {
    /// [`Jacobi`]: all units step from the same exchanged inputs.
    #[default]
    Jacobi,
    /// [`GaussSeidel`]: units step one after the other in dependency order.
    GaussSeidel,
    /// [`Iterative`]: each step repeated from saved states until the exchanged values settle.
    Iterative,
}

impl Scheme {
    /// The algorithm this name stands for, with the default settings.
    pub fn algorithm(self) -> Box<dyn Algorithm> {
        match self {
            Scheme::Jacobi => Box::new(Jacobi),
            Scheme::GaussSeidel => Box::new(GaussSeidel),
            Scheme::Iterative => Box::new(Iterative::new()),
        }
    }
}

impl std::str::FromStr for Scheme {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self, Error> {
        match s {
            "jacobi" => Ok(Scheme::Jacobi),
            "gauss-seidel" => Ok(Scheme::GaussSeidel),
            "iterative" => Ok(Scheme::Iterative),
            _ => Err(Error(format!(
                "unknown algorithm '{s}': jacobi, gauss-seidel or iterative"
            ))),
        }
    }
}

/// Run options; `None` takes the system's `DefaultExperiment` and OSP step size.
#[derive(Debug, Clone, Default)]
pub struct Options {
    pub stop: Option<f64>,
    pub step: Option<f64>,
    pub algorithm: Scheme,
}

/// How a run uses the machine, besides [`Options`] (which other crates build as struct
/// literals): threads stepping the units, and whether identical binaries share one library.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Execution {
    /// Threads that step the units of a Jacobi step (and of each iterative attempt), the
    /// calling thread included; 1 steps them in turn on the calling thread. Results do not
    /// depend on it (bit for bit): the units of one step are independent.
    pub threads: usize,
    pub sharing: Sharing,
}

impl Default for Execution {
    /// One thread, identical binaries shared.
    fn default() -> Self {
        Execution {
            threads: 1,
            sharing: Sharing::Shared,
        }
    }
}

impl Execution {
    /// `threads` threads (at least 1), identical binaries shared.
    pub fn threads(threads: usize) -> Execution {
        Execution {
            threads: threads.max(1),
            ..Execution::default()
        }
    }
}

/// What went wrong, naming the unit, element or file.
#[derive(Debug, Clone, PartialEq)]
pub struct Error(pub String);

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Error {}

impl From<ssp::Error> for Error {
    fn from(e: ssp::Error) -> Self {
        Error(e.to_string())
    }
}

/// How a run went: how it ended, its warnings (also printed to stderr as they happen) and
/// where the time went.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub end: End,
    pub warnings: Vec<String>,
    /// Communication points recorded (the initial one included).
    pub samples: u64,
    /// Simulated time, s.
    pub simulated: f64,
    /// Recorded outputs (columns besides `time`).
    pub columns: usize,
    /// Wall time of reading the system and loading its FMUs, and of initializing and stepping.
    pub load_time: std::time::Duration,
    pub run_time: std::time::Duration,
    /// Of `run_time`, the steps and samples after initialization ([`System::advance_time`]).
    pub advance_time: std::time::Duration,
    /// Components, and the libraries they run in (fewer when identical binaries are shared).
    pub units: usize,
    pub libraries: usize,
    /// Threads that stepped the units.
    pub threads: usize,
}

/// Load the system at `path` (an `.ssp`, a directory or an `.ssd`) and simulate it to its end,
/// keeping the results in memory (tests and short runs; [`run`] streams them instead).
pub fn simulate(path: &Path, opts: &Options) -> Result<Table, Error> {
    System::load(&ssp::read(path)?)?.simulate(opts)
}

/// Load the system at `path` (an `.ssp`, a directory, an `.ssd` or one `.fmu` on its own) and
/// simulate it, handing every communication point to `observers`.
///
/// `Err` when the system cannot be loaded or its experiment is invalid (no observer has started
/// then); a run that starts returns `Ok` with [`Outcome::end`] saying how it ended.
pub fn run(
    path: &Path,
    opts: &Options,
    observers: &mut [&mut dyn Observer],
) -> Result<Outcome, Error> {
    run_with(path, opts, &mut *opts.algorithm.algorithm(), observers)
}

/// [`run`] with an algorithm of the caller's (e.g. an [`Iterative`] with its own tolerances).
pub fn run_with(
    path: &Path,
    opts: &Options,
    algorithm: &mut dyn Algorithm,
    observers: &mut [&mut dyn Observer],
) -> Result<Outcome, Error> {
    run_on(path, opts, &Execution::default(), algorithm, observers)
}

/// [`run_with`] on the threads and with the sharing of `exec`.
pub fn run_on(
    path: &Path,
    opts: &Options,
    exec: &Execution,
    algorithm: &mut dyn Algorithm,
    observers: &mut [&mut dyn Observer],
) -> Result<Outcome, Error> {
    let started = std::time::Instant::now();
    // An unpacked .ssp lives as long as its FMUs are loaded (they are unpacked again each).
    let mut system = if path.extension().is_some_and(|e| e == "fmu") {
        System::alone_with(path, exec.sharing)?
    } else {
        System::load_with(&ssp::read(path)?, exec.sharing)?
    };
    system.set_threads(exec.threads);
    let load_time = started.elapsed();
    let columns = system.columns().len() - 1;
    let (units, libraries, threads) = (
        system.units.len(),
        system.libraries(),
        system.stepping_threads(),
    );
    let (end, samples, simulated) = system.simulate_with(opts, algorithm, observers)?;
    let advance_time = system.advance_time();
    Ok(Outcome {
        end,
        warnings: system.warnings,
        samples,
        simulated,
        columns,
        load_time,
        run_time: started.elapsed() - load_time,
        advance_time,
        units,
        libraries,
        threads,
    })
}

/// Variable index (1-based, as in `ModelStructure`) to value reference and type.
pub(crate) struct Var {
    pub(crate) index: u32,
    pub(crate) vr: u32,
    pub(crate) ty: BaseType,
}

/// One loaded component.
pub(crate) struct Unit {
    pub(crate) name: String,
    pub(crate) inst: Instance,
    /// Keep the unit's warnings without printing them (runs of a sweep).
    quiet: bool,
    /// Variables read after a step (output connectors and connection starts), recorded.
    pub(crate) reads: Vec<Var>,
    pub(crate) values: Vec<f64>,
    /// `values` is current (no step and no input change since it was read).
    pub(crate) fresh: bool,
    /// Inputs to set before the next read or step: Reals (value references, values), others.
    pub(crate) pending_real: (Vec<u32>, Vec<f64>),
    pub(crate) pending_other: Vec<(u32, BaseType, f64)>,
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
    /// The status of the last `fmi2DoStep` of [`Coupling::step_all`], and of the reads that
    /// followed it on the same thread (checked in unit order after the round).
    pub(crate) stepped: Status,
    pub(crate) fetched: Option<(Status, &'static str)>,
}

/// One connection, resolved.
pub(crate) struct Link {
    pub(crate) src: usize,
    pub(crate) slot: usize,
    pub(crate) dst: usize,
    pub(crate) dst_index: u32,
    pub(crate) dst_vr: u32,
    pub(crate) ty: BaseType,
    pub(crate) factor: f64,
    pub(crate) offset: f64,
    pub(crate) last: Option<f64>,
    pub(crate) label: String,
    /// Whether the destination input feeds through to an output of its unit, per phase
    /// (initialization, step): setting it makes the unit's outputs stale.
    pub(crate) feeds: [bool; 2],
}

#[derive(Clone, Copy, PartialEq)]
pub(crate) enum Phase {
    Init,
    Step,
}

/// A loaded system, ready to simulate once.
pub struct System {
    pub(crate) units: Vec<Unit>,
    pub(crate) links: Vec<Link>,
    pub(crate) parameters: Vec<(usize, String, Var, Value)>,
    pub(crate) init_order: Vec<usize>,
    pub(crate) step_order: Vec<usize>,
    unit_order: Vec<usize>,
    start: f64,
    stop: Option<f64>,
    step: Option<f64>,
    name: String,
    /// The signals recorded by default (the SSP's record annotation).
    record: Vec<String>,
    /// The current communication point: time, then every unit's recorded outputs.
    pub(crate) row: Vec<f64>,
    /// Warnings so far (loops, FMU warnings).
    pub warnings: Vec<String>,
    /// Threads asked for (see [`System::set_threads`]), and the pool of a run using more than 1.
    threads: usize,
    pool: Option<pool::Pool>,
    /// Wall time spent in [`Coupling::step_all`] during the last run.
    step_time: std::time::Duration,
    /// Wall time of the last run after initialization: its steps and samples.
    advance_time: std::time::Duration,
}

fn variable(md: &ModelDescription, comp: &str, name: &str) -> Result<(Var, Causality), Error> {
    let index = md
        .model_variables
        .variables
        .iter()
        .position(|v| v.name == name)
        .ok_or_else(|| {
            Error(format!(
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

impl Unit {
    fn load(c: &Component, fmu: Arc<Fmu>) -> Result<Unit, Error> {
        let md = &fmu.description;
        let mut reads = Vec::new();
        for k in &c.connectors {
            let (var, causality) = variable(md, &c.name, &k.name)?;
            if var.ty != BaseType::from(k.ty) {
                return Err(Error(format!(
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
                return Err(Error(format!(
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
            (Err(e), _) | (_, Err(e)) => return Err(Error(format!("component '{}': {e}", c.name))),
        };
        let inst = fmu
            .instantiate(&c.name)
            .map_err(|e| Error(format!("component '{}': {e}", c.name)))?;
        Ok(Unit {
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

    /// Fix the reads per type (after every connection has its slot).
    fn finish_reads(&mut self) {
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

    fn slot(&mut self, var: Var) -> usize {
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

    fn deps(&self, phase: Phase) -> &BTreeMap<u32, BTreeSet<u32>> {
        match phase {
            Phase::Init => &self.init_deps,
            Phase::Step => &self.step_deps,
        }
    }

    /// Whether setting input `index` can change an output of this unit now.
    fn feeds_through(&self, phase: Phase, index: u32) -> bool {
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
        let what = what();
        let last = self
            .last_message
            .as_deref()
            .map(|m| format!(": {m}"))
            .unwrap_or_default();
        let why = if s == Status::Discard {
            " (the master cannot repeat a rejected step)"
        } else {
            ""
        };
        Err(Error(format!(
            "component '{}': {what} returned {s:?}{why}{last}",
            self.name
        )))
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

    pub(crate) fn push(&mut self, vr: u32, ty: BaseType, v: f64) {
        if ty == BaseType::Real {
            self.pending_real.0.push(vr);
            self.pending_real.1.push(v);
        } else {
            self.pending_other.push((vr, ty, v));
        }
    }

    /// Read every recorded variable (after setting the pending inputs).
    pub(crate) fn read(&mut self, warnings: &mut Vec<String>) -> Result<(), Error> {
        self.flush(warnings)?;
        let (s, what) = self.fetch();
        self.check(|| what.into(), s, warnings)?;
        self.fresh = true;
        Ok(())
    }

    /// Get every recorded variable into `values` (one call per type), without setting inputs
    /// or looking at the log: the worst status and its call (the first above a warning stops).
    pub(crate) fn fetch(&mut self) -> (Status, &'static str) {
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
}

/// Order links so that a link leaving unit U after a dependency on one of U's inputs comes
/// after the link into that input; cycles are broken at their first link in SSD order.
fn order_links(
    units: &[Unit],
    links: &[Link],
    phase: Phase,
    warnings: &mut Vec<String>,
) -> Vec<usize> {
    let n = links.len();
    // preds[b] = links a whose end input feeds (through unit b.src) the start of b.
    let preds: Vec<Vec<usize>> = (0..n)
        .map(|b| {
            let lb = &links[b];
            let out_index = units[lb.src].reads[lb.slot].index;
            let deps = units[lb.src].deps(phase).get(&out_index);
            (0..n)
                .filter(|&a| {
                    links[a].dst == lb.src && deps.is_some_and(|d| d.contains(&links[a].dst_index))
                })
                .collect()
        })
        .collect();
    let mut done = vec![false; n];
    let mut ignored: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); n];
    let mut order = Vec::with_capacity(n);
    while order.len() < n {
        let ready = (0..n)
            .find(|&b| !done[b] && preds[b].iter().all(|&a| done[a] || ignored[b].contains(&a)));
        if let Some(b) = ready {
            done[b] = true;
            order.push(b);
            continue;
        }
        // Every remaining link waits on another: walk back from one until a link repeats.
        let mut path = vec![(0..n).find(|&b| !done[b]).expect("a remaining link")];
        let cycle = loop {
            let b = *path.last().expect("non-empty");
            let a = preds[b]
                .iter()
                .copied()
                .find(|&a| !done[a] && !ignored[b].contains(&a))
                .expect("a waiting link has a pending predecessor");
            if let Some(pos) = path.iter().position(|&x| x == a) {
                break path[pos..].to_vec();
            }
            path.push(a);
        };
        // Break at the cycle's first link in SSD order: it stops waiting on its predecessor.
        let first = *cycle.iter().min().expect("non-empty cycle");
        let pos = cycle.iter().position(|&x| x == first).expect("member");
        let pred = cycle[(pos + 1) % cycle.len()];
        ignored[first].insert(pred);
        let mut names: Vec<&str> = cycle
            .iter()
            .rev()
            .map(|&i| links[i].label.as_str())
            .collect();
        names.dedup();
        let what = match phase {
            Phase::Init => "initialization",
            Phase::Step => "steps",
        };
        let msg = format!(
            "algebraic loop (direct feedthrough cycle) during {what}: {}; broken at {} (it carries the value from before each exchange)",
            names.join(" -> "),
            links[first].label
        );
        eprintln!("cosim: warning: {msg}");
        warnings.push(msg);
    }
    order
}

/// Gauss-Seidel order of the units: a unit after the units feeding it; cycles in SSD order.
fn order_units(n: usize, links: &[Link]) -> Vec<usize> {
    let mut done = vec![false; n];
    let mut order = Vec::with_capacity(n);
    while order.len() < n {
        let ready = (0..n).find(|&u| {
            !done[u]
                && links
                    .iter()
                    .all(|l| l.dst != u || l.src == u || done[l.src])
        });
        // In a cycle the first remaining unit in SSD order goes first.
        let u = ready.unwrap_or_else(|| (0..n).find(|&u| !done[u]).expect("a remaining unit"));
        done[u] = true;
        order.push(u);
    }
    order
}

impl System {
    /// Load every component's FMU, resolve the connections and check the parameter bindings.
    /// Components whose binaries are identical share one loaded library ([`Sharing::Shared`]),
    /// each with its own unpacked resources.
    pub fn load(package: &ssp::Package) -> Result<System, Error> {
        System::load_with(package, Sharing::Shared)
    }

    /// [`System::load`] with a choice of sharing.
    pub fn load_with(package: &ssp::Package, sharing: Sharing) -> Result<System, Error> {
        let sys = &package.system;
        let mut fmus = Vec::with_capacity(sys.components.len());
        for c in &sys.components {
            let fmu = Fmu::load_with(&package.source_path(c), sharing)
                .map_err(|e| Error(format!("component '{}' ({}): {e}", c.name, c.source)))?;
            fmus.push(Arc::new(fmu));
        }
        System::assemble(sys, fmus)
    }

    /// One FMU on its own: every output recorded, inputs held at their start values, the
    /// experiment from its `DefaultExperiment` (stop 1 s and step 1 ms where it gives none).
    pub fn alone(path: &Path) -> Result<System, Error> {
        System::alone_with(path, Sharing::Shared)
    }

    /// [`System::alone`] with a choice of sharing.
    pub fn alone_with(path: &Path, sharing: Sharing) -> Result<System, Error> {
        let fmu =
            Fmu::load_with(path, sharing).map_err(|e| Error(format!("{}: {e}", path.display())))?;
        let fmu = Arc::new(fmu);
        let md = &fmu.description;
        let connectors = md
            .model_variables
            .variables
            .iter()
            .filter(|v| v.causality() == Causality::Output && v.base_type() != BaseType::String)
            .map(|v| ssp::Connector {
                name: v.name.clone(),
                kind: ssp::Kind::Output,
                ty: v.base_type().into(),
            })
            .collect();
        let name = md.model_identifier().unwrap_or(&md.model_name).to_owned();
        let de = md.default_experiment.clone().unwrap_or_default();
        let sys = ssp::System {
            name: name.clone(),
            description: None,
            components: vec![Component {
                name,
                source: path.display().to_string(),
                connectors,
                parameters: Vec::new(),
            }],
            connections: Vec::new(),
            start_time: de.start_time.unwrap_or(0.0),
            stop_time: Some(de.stop_time.unwrap_or(1.0)),
            step_size: Some(de.step_size.unwrap_or(1e-3)),
            record: Vec::new(),
        };
        System::assemble(&sys, vec![fmu])
    }

    /// Resolve the connections and parameter bindings of `sys` over its loaded FMUs.
    fn assemble(sys: &ssp::System, fmus: Vec<Arc<Fmu>>) -> Result<System, Error> {
        let mut units = Vec::with_capacity(fmus.len());
        for (c, fmu) in sys.components.iter().zip(fmus) {
            units.push(Unit::load(c, fmu)?);
        }
        let index = |name: &str| {
            sys.components
                .iter()
                .position(|c| c.name == name)
                .ok_or_else(|| Error(format!("connection names an unknown component '{name}'")))
        };
        let mut links = Vec::with_capacity(sys.connections.len());
        for c in &sys.connections {
            let (src, dst) = (index(&c.start_element)?, index(&c.end_element)?);
            let label = format!(
                "{}.{} -> {}.{}",
                c.start_element, c.start_connector, c.end_element, c.end_connector
            );
            let (fmu_s, fmu_d) = (
                Arc::clone(units[src].inst.fmu()),
                Arc::clone(units[dst].inst.fmu()),
            );
            let (from, _) = variable(&fmu_s.description, &c.start_element, &c.start_connector)?;
            let (to, causality) = variable(&fmu_d.description, &c.end_element, &c.end_connector)?;
            if from.ty != to.ty {
                return Err(Error(format!(
                    "connection {label}: {} output to {} input",
                    from.ty, to.ty
                )));
            }
            if from.ty == BaseType::String {
                return Err(Error(format!(
                    "connection {label}: String connections are not supported"
                )));
            }
            if !matches!(causality, Causality::Input | Causality::Parameter) {
                return Err(Error(format!(
                    "connection {label}: the end is a {causality:?} variable, not an input"
                )));
            }
            let (factor, offset) = c
                .transformation
                .as_ref()
                .map_or((1.0, 0.0), |t| (t.factor, t.offset));
            let (dst_index, dst_vr, ty) = (to.index, to.vr, to.ty);
            let slot = units[src].slot(from);
            let feeds = [Phase::Init, Phase::Step].map(|p| units[dst].feeds_through(p, dst_index));
            links.push(Link {
                src,
                slot,
                dst,
                dst_index,
                dst_vr,
                ty,
                factor,
                offset,
                last: None,
                label,
                feeds,
            });
        }
        let mut parameters = Vec::new();
        for (u, c) in sys.components.iter().enumerate() {
            for p in &c.parameters {
                let md = &units[u].inst.fmu().description;
                let (var, causality) = variable(md, &c.name, &p.name)?;
                if matches!(
                    causality,
                    Causality::Output | Causality::Local | Causality::CalculatedParameter
                ) && md
                    .variable(&p.name)
                    .is_some_and(|v| v.start_text().is_none())
                {
                    return Err(Error(format!(
                        "component '{}': parameter binding '{}': a {causality:?} variable without a start value cannot be set",
                        c.name, p.name
                    )));
                }
                if let Value::Integer(v) = p.value {
                    if i32::try_from(v).is_err() {
                        return Err(Error(format!(
                            "component '{}': parameter binding '{}': {v} is outside the 32-bit range of an FMI Integer",
                            c.name, p.name
                        )));
                    }
                }
                let ok = matches!(
                    (&p.value, var.ty),
                    (Value::Real(_), BaseType::Real)
                        | (Value::Integer(_), BaseType::Integer)
                        | (Value::Boolean(_), BaseType::Boolean)
                        | (Value::String(_), BaseType::String)
                );
                if !ok {
                    return Err(Error(format!(
                        "component '{}': parameter binding '{}' gives {:?} to a {} variable",
                        c.name, p.name, p.value, var.ty
                    )));
                }
                parameters.push((u, p.name.clone(), var, p.value.clone()));
            }
        }
        for u in &mut units {
            u.finish_reads();
        }
        let mut warnings = Vec::new();
        let init_order = order_links(&units, &links, Phase::Init, &mut warnings);
        let step_order = order_links(&units, &links, Phase::Step, &mut warnings);
        let unit_order = order_units(units.len(), &links);
        Ok(System {
            units,
            links,
            parameters,
            init_order,
            step_order,
            unit_order,
            start: sys.start_time,
            stop: sys.stop_time,
            step: sys.step_size,
            name: sys.name.clone(),
            record: sys.record.clone(),
            row: Vec::new(),
            warnings,
            threads: 1,
            pool: None,
            step_time: std::time::Duration::ZERO,
            advance_time: std::time::Duration::ZERO,
        })
    }

    /// Step the units of each Jacobi step (and each iterative attempt) on `threads` threads,
    /// the caller's included (at most one per unit; 1, the default, steps them in turn).
    /// Gauss-Seidel steps in turn whatever this says.
    pub fn set_threads(&mut self, threads: usize) {
        self.threads = threads.max(1);
    }

    /// The threads a run of this system steps its units on.
    pub fn stepping_threads(&self) -> usize {
        self.threads.min(self.units.len()).max(1)
    }

    /// Wall time the last run spent in [`Coupling::step_all`] (Jacobi steps, iterative
    /// attempts): stepping every unit and reading its outputs, the part of a run that runs on
    /// the system's threads; the rest stays on the calling thread.
    pub fn step_time(&self) -> std::time::Duration {
        self.step_time
    }

    /// Wall time of the last run from the end of initialization to the last sample: what a
    /// run costs per step, loading and initialization aside.
    pub fn advance_time(&self) -> std::time::Duration {
        self.advance_time
    }

    /// The loaded FMU of the component `name`.
    pub fn fmu(&self, name: &str) -> Option<&Arc<Fmu>> {
        self.units
            .iter()
            .find(|u| u.name == name)
            .map(|u| u.inst.fmu())
    }

    /// How many distinct libraries (dlopen handles) the components run in.
    pub fn libraries(&self) -> usize {
        let mut seen: Vec<&Arc<crate::fmu::Library>> = Vec::new();
        for u in &self.units {
            let l = u.inst.fmu().library();
            if !seen.iter().any(|s| Arc::ptr_eq(s, l)) {
                seen.push(l);
            }
        }
        seen.len()
    }

    /// Move every connection's value in the phase's order; returns how many inputs changed.
    fn exchange(&mut self, phase: Phase) -> Result<usize, Error> {
        let order = std::mem::take(match phase {
            Phase::Init => &mut self.init_order,
            Phase::Step => &mut self.step_order,
        });
        let result = self.exchange_in(phase, &order);
        *match phase {
            Phase::Init => &mut self.init_order,
            Phase::Step => &mut self.step_order,
        } = order;
        result
    }

    fn exchange_in(&mut self, phase: Phase, order: &[usize]) -> Result<usize, Error> {
        let mut changed = 0;
        for &i in order {
            let (src, slot, dst) = (self.links[i].src, self.links[i].slot, self.links[i].dst);
            if !self.units[src].fresh {
                self.units[src].read(&mut self.warnings)?;
            }
            let link = &mut self.links[i];
            let v = link.factor * self.units[src].values[slot] + link.offset;
            if link.last.map(f64::to_bits) == Some(v.to_bits()) {
                continue;
            }
            link.last = Some(v);
            changed += 1;
            let (vr, ty) = (link.dst_vr, link.ty);
            let feeds = link.feeds[phase as usize];
            let unit = &mut self.units[dst];
            unit.push(vr, ty, v);
            if feeds {
                unit.fresh = false;
            }
        }
        for u in &mut self.units {
            u.flush(&mut self.warnings)?;
        }
        Ok(changed)
    }

    /// Read every unit's recorded outputs into the row buffer (time first).
    pub(crate) fn sample(&mut self, t: i64) -> Result<(), Error> {
        self.row.clear();
        self.row.push(seconds(t));
        for u in &mut self.units {
            if !u.fresh {
                u.read(&mut self.warnings)?;
            }
            self.row.extend_from_slice(&u.values);
        }
        Ok(())
    }

    /// `time`, then `component.variable` of every recorded output.
    pub fn columns(&self) -> Vec<String> {
        let mut columns = vec!["time".to_owned()];
        for u in &self.units {
            let md = &u.inst.fmu().description;
            for r in &u.reads {
                let name = &md.model_variables.variables[r.index as usize - 1].name;
                columns.push(format!("{}.{name}", u.name));
            }
        }
        columns
    }

    /// The experiment in ticks: start, stop and step from `opts` or the system, each checked.
    pub(crate) fn experiment(&self, opts: &Options) -> Result<(i64, i64, i64), Error> {
        let name = &self.name;
        let stop_s = opts.stop.or(self.stop).ok_or_else(|| {
            Error(format!(
                "system '{name}': no stop time (give --stop or a DefaultExperiment stopTime)"
            ))
        })?;
        let step_s = opts.step.or(self.step).ok_or_else(|| {
            Error(format!(
                "system '{name}': no step size (give --step or the OSP FixedStepAlgorithm baseStepSize annotation)"
            ))
        })?;
        let limit = |what: &str, v: f64| {
            ticks(v).ok_or_else(|| {
                Error(format!(
                    "system '{name}': {what} {v} s is not a finite time within ±{:e} s",
                    crate::table::MAX_TIME
                ))
            })
        };
        let (start, stop, step) = (
            limit("start time", self.start)?,
            limit("stop time", stop_s)?,
            limit("step size", step_s)?,
        );
        if step <= 0 {
            return Err(Error(format!(
                "system '{name}': step size {step_s} s must be at least 1 ns"
            )));
        }
        if stop <= start {
            return Err(Error(format!(
                "system '{name}': stop time {stop_s} s must be after the start time {} s",
                self.start
            )));
        }
        let steps = (stop - start) / step;
        if steps > MAX_STEPS {
            return Err(Error(format!(
                "system '{name}': {steps} communication steps from {} s to {stop_s} s by {step_s} s; a run takes at most {MAX_STEPS}",
                self.start
            )));
        }
        Ok((start, stop, step))
    }

    /// [`System::simulate_with`] with the algorithm named in `opts`, results in memory.
    /// Keep the units' warnings (in `warnings`) without printing them.
    pub fn quiet(&mut self) {
        for u in &mut self.units {
            u.quiet = true;
        }
    }

    /// Simulate to the end keeping every output in memory.
    pub fn simulate(&mut self, opts: &Options) -> Result<Table, Error> {
        self.simulate_recording(opts, Record::parse("all"))
    }

    /// Simulate to the end keeping what `record` chooses in memory (the studies keep the
    /// system's default set, [`Record::system_default`]).
    pub fn simulate_recording(&mut self, opts: &Options, record: Record) -> Result<Table, Error> {
        let mut recorder = Select::new(Recorder::default(), record);
        let mut algorithm = opts.algorithm.algorithm();
        let (end, _, _) = self.simulate_with(opts, &mut *algorithm, &mut [&mut recorder])?;
        match end {
            End::Completed => Ok(recorder.inner.table),
            End::Interrupted { signal, at } => Err(Error(format!(
                "interrupted by signal {signal} at t = {at} s"
            ))),
            End::Failed { error, .. } => Err(Error(error)),
        }
    }

    /// Initialize, step with `algorithm` to the stop time (or until an error or a signal) and
    /// hand every communication point to `observers`; returns how the run ended, the number of
    /// communication points recorded and the simulated time, s.
    ///
    /// `Err` only when the experiment is invalid, before any observer started; an error during
    /// the run ends it as [`End::Failed`] after the observers had every point up to it.
    pub fn simulate_with(
        &mut self,
        opts: &Options,
        algorithm: &mut dyn Algorithm,
        observers: &mut [&mut dyn Observer],
    ) -> Result<(End, u64, f64), Error> {
        let (start, stop, step) = self.experiment(opts)?;
        let threads = self.stepping_threads();
        self.step_time = std::time::Duration::ZERO;
        self.advance_time = std::time::Duration::ZERO;
        self.pool = if threads > 1 {
            let pool = pool::Pool::new(threads)
                .map_err(|e| Error(format!("cannot start {threads} stepping threads: {e}")))?;
            Some(pool)
        } else {
            None
        };
        let columns = self.columns();
        let info = RunInfo {
            system: &self.name,
            columns: &columns,
            start: seconds(start),
            stop: seconds(stop),
            step: seconds(step),
            record: &self.record,
        };
        let mut started = Vec::with_capacity(observers.len());
        let mut result = Ok(None);
        for (k, o) in observers.iter_mut().enumerate() {
            if let Err(e) = o.start(&info) {
                result = Err(e);
                break;
            }
            started.push(k);
        }
        let mut tally = Tally::default();
        if result.is_ok() {
            let span = Span { start, stop, step };
            result = self.drive(span, algorithm, observers, &mut tally);
        }
        let Tally { last, samples } = tally;
        let at = last.map_or(seconds(start), seconds);
        let end = match result {
            Ok(None) => End::Completed,
            Ok(Some(signal)) => End::Interrupted { signal, at },
            Err(e) => End::Failed { at, error: e.0 },
        };
        // The workers end with the run.
        self.pool = None;
        for k in started {
            if let Err(e) = observers[k].finish(&end) {
                if end == End::Completed {
                    return Ok((End::Failed { at, error: e.0 }, samples, at - seconds(start)));
                }
                eprintln!("cosim: {e}");
            }
        }
        Ok((end, samples, at - seconds(start)))
    }

    /// The run itself: `Ok(Some(signal))` when interrupted; `tally` counts what was recorded.
    fn drive(
        &mut self,
        span: Span,
        algorithm: &mut dyn Algorithm,
        observers: &mut [&mut dyn Observer],
        tally: &mut Tally,
    ) -> Result<Option<i32>, Error> {
        if let Some(signal) = interrupt::requested() {
            return Ok(Some(signal));
        }
        self.initialize(span.start, span.stop)
            .map_err(|e| Error(format!("during initialization: {e}")))?;
        algorithm.start(&mut Coupling { system: self })?;
        let started = std::time::Instant::now();
        let result = self.advance(span, algorithm, observers, tally);
        self.advance_time = started.elapsed();
        if let Some(report) = algorithm.finish(&mut Coupling { system: self }) {
            eprintln!("cosim: {report}");
        }
        result
    }

    /// Sample, step, repeat until the stop time (or a signal).
    fn advance(
        &mut self,
        Span { start, stop, step }: Span,
        algorithm: &mut dyn Algorithm,
        observers: &mut [&mut dyn Observer],
        tally: &mut Tally,
    ) -> Result<Option<i32>, Error> {
        let mut t = start;
        loop {
            self.sample(t)?;
            for o in observers.iter_mut() {
                o.sample(&self.row)?;
            }
            tally.last = Some(t);
            tally.samples += 1;
            if t >= stop {
                break;
            }
            if let Some(signal) = interrupt::requested() {
                return Ok(Some(signal));
            }
            let h = step.min(stop - t);
            algorithm
                .step(&mut Coupling { system: self }, t, h)
                .map_err(|e| {
                    Error(format!(
                        "in the communication step from t = {} s to {} s ({}): {e}",
                        seconds(t),
                        seconds(t + h),
                        algorithm.name()
                    ))
                })?;
            t += h;
        }
        for u in &mut self.units {
            let s = u.inst.terminate();
            u.check(|| "fmi2Terminate".into(), s, &mut self.warnings)?;
        }
        Ok(None)
    }

    /// Experiment, parameters, then exchange until nothing changes; ends in step mode with the
    /// connections exchanged.
    fn initialize(&mut self, start: i64, stop: i64) -> Result<(), Error> {
        for k in 0..self.units.len() {
            let u = &mut self.units[k];
            let s = u.inst.setup_experiment(seconds(start), Some(seconds(stop)));
            u.check(|| "fmi2SetupExperiment".into(), s, &mut self.warnings)?;
        }
        for (k, name, var, value) in &self.parameters {
            let u = &mut self.units[*k];
            let s = match value {
                Value::Real(v) => u.inst.set_real(&[var.vr], &[*v]),
                // Range-checked against i32 by the SSP reader.
                Value::Integer(v) => u.inst.set_integer(&[var.vr], &[*v as i32]),
                Value::Boolean(v) => u.inst.set_boolean(&[var.vr], &[*v]),
                Value::String(v) => u.inst.set_string(&[var.vr], &[v.as_str()]),
            };
            u.check(
                || format!("setting parameter '{name}'"),
                s,
                &mut self.warnings,
            )?;
        }
        for u in &mut self.units {
            let s = u.inst.enter_initialization_mode();
            u.check(
                || "fmi2EnterInitializationMode".into(),
                s,
                &mut self.warnings,
            )?;
            u.fresh = false;
        }
        const MAX_PASSES: usize = 100;
        let mut passes = 0;
        while self.exchange(Phase::Init)? > 0 {
            passes += 1;
            if passes == MAX_PASSES {
                return Err(Error(format!(
                    "initialization did not settle after {MAX_PASSES} exchanges (an algebraic loop that does not converge?)"
                )));
            }
        }
        for u in &mut self.units {
            let s = u.inst.exit_initialization_mode();
            u.check(
                || "fmi2ExitInitializationMode".into(),
                s,
                &mut self.warnings,
            )?;
            u.fresh = false;
        }
        self.exchange(Phase::Step)?;
        Ok(())
    }
}

/// The most communication steps one run takes (a billion rows would be a CSV of tens of GB per
/// column group, and hours of stepping: a start or stop time off by orders of magnitude).
pub const MAX_STEPS: i64 = 1_000_000_000;

/// A run's start, stop and step, ticks.
#[derive(Clone, Copy)]
struct Span {
    start: i64,
    stop: i64,
    step: i64,
}

/// What a run has recorded: the last communication point, and how many.
#[derive(Default)]
struct Tally {
    last: Option<i64>,
    samples: u64,
}

/// The statuses of a [`Coupling::step_all`] round, in unit order: every step, then every read
/// (the order in which the steps and then the exchange would meet them).
pub(crate) fn checked(
    units: &mut [Unit],
    warnings: &mut Vec<String>,
    ts: f64,
    hs: f64,
) -> Result<(), Error> {
    for u in units.iter_mut() {
        let s = std::mem::replace(&mut u.stepped, Status::Ok);
        u.check(|| format!("fmi2DoStep({ts}, {hs})"), s, warnings)?;
    }
    for u in units.iter_mut() {
        if let Some((s, what)) = u.fetched.take() {
            u.check(|| what.into(), s, warnings)?;
            u.fresh = true;
        }
    }
    Ok(())
}

/// What an [`Algorithm`] may do with a loaded system during a communication step.
pub struct Coupling<'a> {
    system: &'a mut System,
}

impl Coupling<'_> {
    /// The number of units.
    pub fn units(&self) -> usize {
        self.system.units.len()
    }

    /// `fmi2DoStep` of unit `k` from `t` by `h` (ticks); its outputs are read again when needed.
    pub fn do_step(&mut self, k: usize, t: i64, h: i64) -> Result<(), Error> {
        let u = &mut self.system.units[k];
        let s = u.inst.do_step(seconds(t), seconds(h));
        u.fresh = false;
        u.check(
            || format!("fmi2DoStep({}, {})", seconds(t), seconds(h)),
            s,
            &mut self.system.warnings,
        )
    }

    /// `fmi2DoStep` of every unit from `t` by `h` (ticks), all from the inputs they hold, each
    /// followed by the reading of the unit's outputs, on the system's threads (see
    /// [`System::set_threads`]). Every unit is stepped; then the statuses are checked in SSD
    /// order (the first failing unit is reported, the logs handled in that order), so the
    /// results, messages and warnings do not depend on the number of threads.
    pub fn step_all(&mut self, t: i64, h: i64) -> Result<(), Error> {
        let started = std::time::Instant::now();
        let result = self.step_all_units(t, h);
        self.system.step_time += started.elapsed();
        result
    }

    fn step_all_units(&mut self, t: i64, h: i64) -> Result<(), Error> {
        let sys = &mut *self.system;
        let (ts, hs) = (seconds(t), seconds(h));
        // Each unit's outputs are read right after its step (by the thread that stepped it),
        // while its state is in that core's cache; the exchange and the sample would read them
        // next in turn: the same values, as no input changed in between. One thread or many,
        // every instance sees the same calls in the same order.
        let step = |u: &mut Unit| {
            u.stepped = u.inst.do_step(ts, hs);
            u.fresh = false;
            let idle = u.pending_real.0.is_empty() && u.pending_other.is_empty();
            if u.stepped <= Status::Warning && idle {
                u.fetched = Some(u.fetch());
            }
        };
        match &sys.pool {
            Some(pool) => pool.for_each(&mut sys.units, step),
            None => sys.units.iter_mut().for_each(step),
        }
        let result = checked(&mut sys.units, &mut sys.warnings, ts, hs);
        for u in &mut sys.units {
            u.fetched = None;
        }
        result
    }

    /// Threads [`Coupling::step_all`] steps the units on.
    pub fn threads(&self) -> usize {
        self.system.pool.as_ref().map_or(1, pool::Pool::threads)
    }

    /// Move every connection's value (dependency order) and set the changed inputs.
    pub fn exchange(&mut self) -> Result<(), Error> {
        self.system.exchange(Phase::Step).map(|_| ())
    }

    /// The units in dependency order: a unit after the units feeding it, cycles in SSD order.
    pub fn dependency_order(&self) -> &[usize] {
        &self.system.unit_order
    }

    /// The value each connection carried at its last exchange, in SSD order, into `out`.
    pub fn connection_values(&self, out: &mut Vec<f64>) {
        out.clear();
        out.extend(self.system.links.iter().map(|l| l.last.unwrap_or(f64::NAN)));
    }

    /// The components whose FMU cannot save and restore its state
    /// (`canGetAndSetFMUstate` false).
    pub fn without_state(&self) -> Vec<&str> {
        self.system
            .units
            .iter()
            .filter(|u| {
                !u.inst
                    .fmu()
                    .description
                    .co_simulation
                    .as_ref()
                    .is_some_and(|cs| cs.can_get_and_set_fmu_state)
            })
            .map(|u| u.name.as_str())
            .collect()
    }

    /// Save every unit's state into `states` (made on the first call, overwritten after).
    pub fn save(&mut self, states: &mut Vec<crate::fmu::SavedState>) -> Result<(), Error> {
        let sys = &mut *self.system;
        for (k, u) in sys.units.iter_mut().enumerate() {
            let s = match states.get_mut(k) {
                Some(saved) => u.inst.update_state(saved),
                None => {
                    let (s, saved) = u.inst.get_state();
                    if let Some(saved) = saved {
                        states.push(saved);
                    }
                    s
                }
            };
            u.check(|| "fmi2GetFMUstate".into(), s, &mut sys.warnings)?;
        }
        Ok(())
    }

    /// Restore every unit from `states` (as saved by [`Coupling::save`]) and mark every
    /// connection unsent, so that the next exchange sets every input again (a restored FMU holds
    /// the inputs it had when saved).
    pub fn restore(&mut self, states: &[crate::fmu::SavedState]) -> Result<(), Error> {
        let sys = &mut *self.system;
        for (u, saved) in sys.units.iter_mut().zip(states) {
            let s = u.inst.set_state(saved);
            u.fresh = false;
            u.check(|| "fmi2SetFMUstate".into(), s, &mut sys.warnings)?;
        }
        for l in &mut sys.links {
            l.last = None;
        }
        Ok(())
    }

    /// Set every connection's destination input to `values` (in SSD order, as
    /// [`Coupling::connection_values`] gives them) without reading any output.
    pub fn set_inputs(&mut self, values: &[f64]) -> Result<(), Error> {
        let sys = &mut *self.system;
        for (link, &v) in sys.links.iter_mut().zip(values) {
            link.last = Some(v);
            let unit = &mut sys.units[link.dst];
            unit.push(link.dst_vr, link.ty, v);
            if link.feeds[Phase::Step as usize] {
                unit.fresh = false;
            }
        }
        for u in &mut sys.units {
            u.flush(&mut sys.warnings)?;
        }
        Ok(())
    }

    /// Free the states saved by [`Coupling::save`].
    pub fn free(&mut self, states: &mut Vec<crate::fmu::SavedState>) {
        for (u, saved) in self.system.units.iter_mut().zip(states.drain(..)) {
            let _ = u.inst.free_state(saved);
        }
    }
}
