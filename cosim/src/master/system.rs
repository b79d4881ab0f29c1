//! A loaded system: where it comes from and how it is loaded (the [`Builder`]), its units and
//! resolved connections and parameter bindings, its experiment and what is known about it.

use super::coupling::{direct_plan, Core, Parameter, Plans};
use super::graph::{order_links, order_units, Ends, Link};
use super::unit::Phase;
use super::unit::{variable, Unit};
use super::{Algorithm, Error, Options, Sharing, MAX_STEPS};
use crate::fmu::Fmu;
use crate::ssp::{self, Component, Value};
use crate::table::ticks;
use model_description::{BaseType, Causality};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// What a [`Builder`] loads: a path (an `.ssp`, a directory, an `.ssd` or one `.fmu` on its
/// own) or a package already read.
#[derive(Clone, Copy)]
pub enum Source<'a> {
    Path(&'a Path),
    Package(&'a ssp::Package),
}

impl<'a> From<&'a Path> for Source<'a> {
    fn from(p: &'a Path) -> Self {
        Source::Path(p)
    }
}

impl<'a> From<&'a PathBuf> for Source<'a> {
    fn from(p: &'a PathBuf) -> Self {
        Source::Path(p)
    }
}

impl<'a> From<&'a ssp::Package> for Source<'a> {
    fn from(p: &'a ssp::Package) -> Self {
        Source::Package(p)
    }
}

/// How to load a system and run it: `System::builder(path).threads(2).load()`, or
/// `.run(&opts, &mut observers)` to load and run it in one go.
pub struct Builder<'a> {
    source: Source<'a>,
    sharing: Sharing,
    threads: usize,
    algorithm: Option<&'a mut dyn Algorithm>,
    trace: Option<&'a Path>,
}

impl<'a> Builder<'a> {
    /// Whether components whose binaries are identical share one loaded library (the default,
    /// [`Sharing::Shared`]), each with its own unpacked resources.
    pub fn sharing(mut self, sharing: Sharing) -> Self {
        self.sharing = sharing;
        self
    }

    /// Step the units of each Jacobi step (and each iterative attempt) on `threads` threads,
    /// the caller's included (at least 1, at most one per unit; 1, the default, steps them in
    /// turn). Gauss-Seidel steps in turn whatever this says. Results do not depend on it (bit
    /// for bit): the units of one step are independent.
    pub fn threads(mut self, threads: usize) -> Self {
        self.threads = threads.max(1);
        self
    }

    /// Run with `algorithm` (e.g. an [`super::Iterative`] with its own tolerances) instead of
    /// the one [`Options::algorithm`] names.
    pub fn algorithm(mut self, algorithm: &'a mut dyn Algorithm) -> Self {
        self.algorithm = Some(algorithm);
        self
    }

    /// Record every call to each unit in `<dir>/<component>.trace` (the directory is made when
    /// missing; traces there are replaced), for replaying one unit alone in another tool: the
    /// format is in [`crate::fmu::trace`].
    pub fn trace(mut self, dir: &'a Path) -> Self {
        self.trace = Some(dir);
        self
    }

    /// The algorithm given to [`Builder::algorithm`], taken (once).
    pub(super) fn take_algorithm(&mut self) -> Option<&'a mut dyn Algorithm> {
        self.algorithm.take()
    }

    /// Load every component's FMU, resolve the connections and check the parameter bindings.
    /// One `.fmu` on its own: every output recorded, inputs held at their start values, the
    /// experiment from its `DefaultExperiment` (stop 1 s and step 1 ms where it gives none).
    pub fn load(&self) -> Result<System, Error> {
        if let Some(dir) = self.trace {
            std::fs::create_dir_all(dir).map_err(|e| {
                Error::Load(format!("--trace: cannot create {}: {e}", dir.display()))
            })?;
        }
        let trace = self.trace;
        let mut system = match self.source {
            Source::Path(path) if path.extension().is_some_and(|e| e == "fmu") => {
                System::from_fmu(path, self.sharing, trace)?
            }
            // An unpacked .ssp lives as long as its FMUs are loaded (they are unpacked again
            // each).
            Source::Path(path) => System::from_package(&ssp::read(path)?, self.sharing, trace)?,
            Source::Package(package) => System::from_package(package, self.sharing, trace)?,
        };
        system.threads = self.threads;
        Ok(system)
    }
}

/// A loaded system, ready to simulate once.
pub struct System {
    core: Core,
    /// The connections in exchange order, per [`Phase`], and the master's plan of each.
    orders: [Vec<usize>; 2],
    plans: Plans,
    unit_order: Vec<usize>,
    start: f64,
    stop: Option<f64>,
    step: Option<f64>,
    name: String,
    /// The signals recorded by default (the SSP's record annotation).
    record: Vec<String>,
    /// Threads asked for (see [`Builder::threads`]).
    threads: usize,
    /// Wall time of the last run after initialization: its steps and samples.
    advance_time: std::time::Duration,
}

impl System {
    /// How to load the system at `source` (a path or a package already read).
    pub fn builder<'a>(source: impl Into<Source<'a>>) -> Builder<'a> {
        Builder {
            source: source.into(),
            sharing: Sharing::Shared,
            threads: 1,
            algorithm: None,
            trace: None,
        }
    }

    fn from_package(
        package: &ssp::Package,
        sharing: Sharing,
        trace: Option<&Path>,
    ) -> Result<System, Error> {
        let sys = &package.system;
        let mut fmus = Vec::with_capacity(sys.components.len());
        for c in &sys.components {
            let fmu = Fmu::load_with(&package.source_path(c), sharing)
                .map_err(|e| Error::Load(format!("component '{}' ({}): {e}", c.name, c.source)))?;
            fmus.push(Arc::new(fmu));
        }
        System::assemble(sys, fmus, trace)
    }

    fn from_fmu(path: &Path, sharing: Sharing, trace: Option<&Path>) -> Result<System, Error> {
        let fmu = Fmu::load_with(path, sharing)
            .map_err(|e| Error::Load(format!("{}: {e}", path.display())))?;
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
        System::assemble(&sys, vec![fmu], trace)
    }

    /// Resolve the connections and parameter bindings of `sys` over its loaded FMUs.
    fn assemble(
        sys: &ssp::System,
        fmus: Vec<Arc<Fmu>>,
        trace: Option<&Path>,
    ) -> Result<System, Error> {
        let mut units = Vec::with_capacity(fmus.len());
        for (c, fmu) in sys.components.iter().zip(fmus) {
            units.push(Unit::load(c, fmu, trace)?);
        }
        let links = connect(sys, &mut units)?;
        let parameters = bind(sys, &units)?;
        for u in &mut units {
            u.finish_reads();
        }
        let mut warnings = Vec::new();
        let init_order = order_links(&units, &links, Phase::Init, &mut warnings);
        let step_order = order_links(&units, &links, Phase::Step, &mut warnings);
        let unit_order = order_units(units.len(), &links);
        Ok(System {
            core: Core::new(units, links, parameters, warnings),
            plans: [direct_plan(&init_order), direct_plan(&step_order)],
            orders: [init_order, step_order],
            unit_order,
            start: sys.start_time,
            stop: sys.stop_time,
            step: sys.step_size,
            name: sys.name.clone(),
            record: sys.record.clone(),
            threads: 1,
            advance_time: std::time::Duration::ZERO,
        })
    }

    /// The system's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The signals recorded by default (the SSP's record annotation).
    pub(crate) fn record(&self) -> &[String] {
        &self.record
    }

    pub(crate) fn core(&self) -> &Core {
        &self.core
    }

    pub(crate) fn core_mut(&mut self) -> &mut Core {
        &mut self.core
    }

    /// The core and the master's plans of exchange, apart.
    pub(crate) fn core_and_plans(&mut self) -> (&mut Core, &Plans) {
        (&mut self.core, &self.plans)
    }

    /// The connections in the exchange order of `phase`.
    pub(crate) fn order(&self, phase: Phase) -> &[usize] {
        &self.orders[phase as usize]
    }

    /// The units in dependency order: a unit after the units feeding it, cycles in SSD order.
    pub(crate) fn unit_order(&self) -> &[usize] {
        &self.unit_order
    }

    /// Warnings so far (loops, FMU warnings).
    pub fn warnings(&self) -> &[String] {
        self.core.warnings()
    }

    /// The threads a run of this system steps its units on.
    pub fn stepping_threads(&self) -> usize {
        self.threads.min(self.core.units().len()).max(1)
    }

    /// Wall time the last run spent stepping every unit and reading its outputs in Jacobi steps
    /// and iterative attempts ([`super::Coupling::step_all`]): the part of a run that runs on
    /// the system's threads; the rest stays on the calling thread.
    pub fn step_time(&self) -> std::time::Duration {
        self.core.step_time()
    }

    /// Wall time of the last run from the end of initialization to the last sample: what a
    /// run costs per step, loading and initialization aside.
    pub fn advance_time(&self) -> std::time::Duration {
        self.advance_time
    }

    pub(super) fn set_advance_time(&mut self, t: std::time::Duration) {
        self.advance_time = t;
    }

    /// The number of components.
    pub fn units(&self) -> usize {
        self.core.units().len()
    }

    /// The loaded FMU of the component `name`.
    pub fn fmu(&self, name: &str) -> Option<&Arc<Fmu>> {
        self.core
            .units()
            .iter()
            .find(|u| u.name() == name)
            .map(Unit::fmu)
    }

    /// How many distinct libraries (dlopen handles) the components run in.
    pub fn libraries(&self) -> usize {
        let mut seen: Vec<&Arc<crate::fmu::Library>> = Vec::new();
        for u in self.core.units() {
            let l = u.library();
            if !seen.iter().any(|s| Arc::ptr_eq(s, l)) {
                seen.push(l);
            }
        }
        seen.len()
    }

    /// `time`, then `component.variable` of every recorded output.
    pub fn columns(&self) -> Vec<String> {
        self.core.columns()
    }

    /// Keep the units' warnings (in [`System::warnings`]) without printing them.
    pub fn quiet(&mut self) {
        self.core.quiet();
    }

    /// The experiment in ticks: start, stop and step from `opts` or the system, each checked.
    pub(crate) fn experiment(&self, opts: &Options) -> Result<(i64, i64, i64), Error> {
        let name = &self.name;
        let stop_s = opts.stop.or(self.stop).ok_or_else(|| {
            Error::Experiment(format!(
                "system '{name}': no stop time (give --stop or a DefaultExperiment stopTime)"
            ))
        })?;
        let step_s = opts.step.or(self.step).ok_or_else(|| {
            Error::Experiment(format!(
                "system '{name}': no step size (give --step or the OSP FixedStepAlgorithm baseStepSize annotation)"
            ))
        })?;
        let limit = |what: &str, v: f64| {
            ticks(v).ok_or_else(|| {
                Error::Experiment(format!(
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
            return Err(Error::Experiment(format!(
                "system '{name}': step size {step_s} s must be at least 1 ns"
            )));
        }
        if stop <= start {
            return Err(Error::Experiment(format!(
                "system '{name}': stop time {stop_s} s must be after the start time {} s",
                self.start
            )));
        }
        let steps = (stop - start) / step;
        if steps > MAX_STEPS {
            return Err(Error::Experiment(format!(
                "system '{name}': {steps} communication steps from {} s to {stop_s} s by {step_s} s; a run takes at most {MAX_STEPS}",
                self.start
            )));
        }
        Ok((start, stop, step))
    }
}

/// Resolve the connections of `sys` between its `units` (each source output gets its slot).
fn connect(sys: &ssp::System, units: &mut [Unit]) -> Result<Vec<Link>, Error> {
    let index = |name: &str| {
        sys.components
            .iter()
            .position(|c| c.name == name)
            .ok_or_else(|| {
                Error::Connection(format!("connection names an unknown component '{name}'"))
            })
    };
    let mut links = Vec::with_capacity(sys.connections.len());
    for c in &sys.connections {
        let (src, dst) = (index(&c.start_element)?, index(&c.end_element)?);
        let label = format!(
            "{}.{} -> {}.{}",
            c.start_element, c.start_connector, c.end_element, c.end_connector
        );
        let (fmu_s, fmu_d) = (Arc::clone(units[src].fmu()), Arc::clone(units[dst].fmu()));
        let (from, _) = variable(&fmu_s.description, &c.start_element, &c.start_connector)
            .map_err(|e| Error::Connection(e.to_string()))?;
        let (to, causality) = variable(&fmu_d.description, &c.end_element, &c.end_connector)
            .map_err(|e| Error::Connection(e.to_string()))?;
        if from.ty() != to.ty() {
            return Err(Error::Connection(format!(
                "connection {label}: {} output to {} input",
                from.ty(),
                to.ty()
            )));
        }
        if from.ty() == BaseType::String {
            return Err(Error::Connection(format!(
                "connection {label}: String connections are not supported"
            )));
        }
        if !matches!(causality, Causality::Input | Causality::Parameter) {
            return Err(Error::Connection(format!(
                "connection {label}: the end is a {causality:?} variable, not an input"
            )));
        }
        let transformation = c
            .transformation
            .as_ref()
            .map_or((1.0, 0.0), |t| (t.factor, t.offset));
        let slot = units[src].slot(from);
        let ends = Ends {
            src,
            slot,
            dst,
            dst_var: to,
        };
        links.push(Link::new(ends, transformation, label, &units[dst]));
    }
    Ok(links)
}

/// Check the parameter bindings of `sys` against its units' variables.
fn bind(sys: &ssp::System, units: &[Unit]) -> Result<Vec<Parameter>, Error> {
    let mut parameters = Vec::new();
    for (u, c) in sys.components.iter().enumerate() {
        for p in &c.parameters {
            let md = &units[u].fmu().description;
            let (var, causality) =
                variable(md, &c.name, &p.name).map_err(|e| Error::Parameter(e.to_string()))?;
            if matches!(
                causality,
                Causality::Output | Causality::Local | Causality::CalculatedParameter
            ) && md
                .variable(&p.name)
                .is_some_and(|v| v.start_text().is_none())
            {
                return Err(Error::Parameter(format!(
                    "component '{}': parameter binding '{}': a {causality:?} variable without a start value cannot be set",
                    c.name, p.name
                )));
            }
            if let Value::Integer(v) = p.value {
                if i32::try_from(v).is_err() {
                    return Err(Error::Parameter(format!(
                        "component '{}': parameter binding '{}': {v} is outside the 32-bit range of an FMI Integer",
                        c.name, p.name
                    )));
                }
            }
            let ok = matches!(
                (&p.value, var.ty()),
                (Value::Real(_), BaseType::Real)
                    | (Value::Integer(_), BaseType::Integer)
                    | (Value::Boolean(_), BaseType::Boolean)
                    | (Value::String(_), BaseType::String)
            );
            if !ok {
                return Err(Error::Parameter(format!(
                    "component '{}': parameter binding '{}' gives {:?} to a {} variable",
                    c.name,
                    p.name,
                    p.value,
                    var.ty()
                )));
            }
            parameters.push(Parameter::new(u, p.name.clone(), var, p.value.clone()));
        }
    }
    Ok(parameters)
}
