//! The coupling core, written once for the in-process master and a HELICS federate:
//! initialization, the exchange of the connections' values, stepping and sampling of the units
//! that run on this side, with the transport of values between sides left to a [`Transport`].
//!
//! An exchange walks the connections in dependency order as [`Event`]s grouped in rounds. The
//! master walks every connection whole in one round ([`Event::Local`], values copied directly);
//! a federate walks the same order split into rounds, a connection between two components read
//! at its source in one round and set at its destination in a later one, the value travelling
//! through its [`Transport`]. Either way every unit sees the same calls in the same order with
//! the same values, which is what keeps their results bit for bit the same.

use super::graph::Link;
use super::pool::Pool;
use super::unit::Phase;
use super::unit::{Unit, Var};
use super::Error;
use crate::fmu::SavedState;
use crate::ssp::Value;
use crate::table::seconds;
use std::time::Duration;

/// One event of an exchange: connection `i` walked whole on one side (both ends run there),
/// read at its source, or set at its destination.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Event {
    Local(usize),
    Produce(usize),
    Consume(usize),
}

/// The rounds of an exchange of each phase ([`Phase`] as index): the events of each round in
/// the master's order.
pub(crate) type Plans = [Vec<Vec<Event>>; 2];

/// How the value of a connection travels from its source to its destination when they are
/// walked apart ([`Event::Produce`], [`Event::Consume`]), and how the sides agree that
/// initialization settled.
pub(crate) trait Transport {
    /// Round `round` of an exchange in `phase` begins (round 0 begins the exchange): the
    /// values produced elsewhere for this round arrive.
    fn begin_round(&mut self, phase: Phase, round: usize) -> Result<(), Error>;
    /// Connection `i`'s value `raw` as read at its source (which runs here).
    fn carry(&mut self, i: usize, link: &Link, raw: f64);
    /// Connection `i`'s value at its source, for its destination (which runs here).
    fn deliver(&mut self, i: usize, link: &Link) -> Result<f64, Error>;
    /// The round's events are done: send what this side produced.
    fn end_round(&mut self) -> Result<(), Error>;
    /// An initialization exchange changed `changed` inputs here: whether no input changed on
    /// any side.
    fn settled(&mut self, changed: usize) -> Result<bool, Error>;
}

/// The in-process transport: every unit runs here, a value produced is copied to its
/// destination directly.
#[derive(Default)]
pub(crate) struct Direct {
    values: Vec<f64>,
}

impl Transport for Direct {
    fn begin_round(&mut self, _: Phase, _: usize) -> Result<(), Error> {
        Ok(())
    }

    fn carry(&mut self, i: usize, _: &Link, raw: f64) {
        if self.values.len() <= i {
            self.values.resize(i + 1, f64::NAN);
        }
        self.values[i] = raw;
    }

    fn deliver(&mut self, i: usize, link: &Link) -> Result<f64, Error> {
        self.values.get(i).copied().ok_or_else(|| {
            Error::Run(format!(
                "connection {} set before it was read",
                link.label()
            ))
        })
    }

    fn end_round(&mut self) -> Result<(), Error> {
        Ok(())
    }

    fn settled(&mut self, changed: usize) -> Result<bool, Error> {
        Ok(changed == 0)
    }
}

/// The plan of the in-process master: every connection walked whole in `order`, one round.
pub(crate) fn direct_plan(order: &[usize]) -> Vec<Vec<Event>> {
    vec![order.iter().map(|&i| Event::Local(i)).collect()]
}

/// A parameter binding, resolved: the unit, the parameter's name, its variable and value.
pub(crate) struct Parameter {
    unit: usize,
    name: String,
    var: Var,
    value: Value,
}

impl Parameter {
    pub(crate) fn new(unit: usize, name: String, var: Var, value: Value) -> Parameter {
        Parameter {
            unit,
            name,
            var,
            value,
        }
    }
}

/// The most exchanges initialization repeats before it gives up.
const MAX_PASSES: usize = 100;

/// The units and connections of a system, and what a run of its local units keeps.
pub(crate) struct Core {
    units: Vec<Unit>,
    links: Vec<Link>,
    parameters: Vec<Parameter>,
    /// The current communication point: time, then every local unit's recorded outputs.
    row: Vec<f64>,
    /// Warnings so far (loops, FMU warnings).
    warnings: Vec<String>,
    /// The threads stepping the units of a round, when more than the caller's.
    pool: Option<Pool>,
    /// Wall time spent in [`Core::step_all`] during the run.
    step_time: Duration,
}

impl Core {
    pub(crate) fn new(
        units: Vec<Unit>,
        links: Vec<Link>,
        parameters: Vec<Parameter>,
        warnings: Vec<String>,
    ) -> Core {
        Core {
            units,
            links,
            parameters,
            row: Vec::new(),
            warnings,
            pool: None,
            step_time: Duration::ZERO,
        }
    }

    pub(crate) fn units(&self) -> &[Unit] {
        &self.units
    }

    pub(crate) fn links(&self) -> &[Link] {
        &self.links
    }

    pub(crate) fn warnings(&self) -> &[String] {
        &self.warnings
    }

    pub(crate) fn take_warnings(&mut self) -> Vec<String> {
        std::mem::take(&mut self.warnings)
    }

    /// The current communication point (see [`Core::sample`]).
    pub(crate) fn row(&self) -> &[f64] {
        &self.row
    }

    /// Run only the units `local[k]` (every unit is loaded; the others run elsewhere).
    pub(crate) fn set_local(&mut self, local: &[bool]) {
        for (u, &l) in self.units.iter_mut().zip(local) {
            u.set_local(l);
        }
    }

    /// Keep the units' warnings without printing them.
    pub(crate) fn quiet(&mut self) {
        for u in &mut self.units {
            u.set_quiet();
        }
    }

    /// `time`, then `component.variable` of every recorded output of the local units.
    pub(crate) fn columns(&self) -> Vec<String> {
        let mut columns = vec!["time".to_owned()];
        for u in self.units.iter().filter(|u| u.is_local()) {
            u.columns(&mut columns);
        }
        columns
    }

    /// Step the units of [`Core::step_all`] on `pool`'s threads (`None`: the caller's).
    pub(crate) fn set_pool(&mut self, pool: Option<Pool>) {
        self.pool = pool;
        self.step_time = Duration::ZERO;
    }

    /// Threads [`Core::step_all`] steps the units on.
    pub(crate) fn threads(&self) -> usize {
        self.pool.as_ref().map_or(1, Pool::threads)
    }

    pub(crate) fn step_time(&self) -> Duration {
        self.step_time
    }

    /// Experiment, parameters, then exchange until nothing changes on any side; ends in step
    /// mode with the connections exchanged.
    pub(crate) fn initialize(
        &mut self,
        start: i64,
        stop: i64,
        plans: &Plans,
        transport: &mut dyn Transport,
    ) -> Result<(), Error> {
        let warnings = &mut self.warnings;
        for u in self.units.iter_mut().filter(|u| u.is_local()) {
            u.setup_experiment(seconds(start), seconds(stop), warnings)?;
        }
        for p in &self.parameters {
            let u = &mut self.units[p.unit];
            if u.is_local() {
                u.set_parameter(&p.name, &p.var, &p.value, warnings)?;
            }
        }
        for u in self.units.iter_mut().filter(|u| u.is_local()) {
            u.enter_initialization(warnings)?;
        }
        let mut passes = 0;
        loop {
            let changed = self.exchange(Phase::Init, &plans[Phase::Init as usize], transport)?;
            if transport.settled(changed)? {
                break;
            }
            passes += 1;
            if passes == MAX_PASSES {
                return Err(Error::Run(format!(
                    "initialization did not settle after {MAX_PASSES} exchanges (an algebraic loop that does not converge?)"
                )));
            }
        }
        let warnings = &mut self.warnings;
        for u in self.units.iter_mut().filter(|u| u.is_local()) {
            u.exit_initialization(warnings)?;
        }
        self.exchange(Phase::Step, &plans[Phase::Step as usize], transport)?;
        Ok(())
    }

    /// One exchange in `rounds`: every connection's value moved (dependency order) and the
    /// changed inputs of the local units set; returns how many of them changed.
    pub(crate) fn exchange(
        &mut self,
        phase: Phase,
        rounds: &[Vec<Event>],
        transport: &mut dyn Transport,
    ) -> Result<usize, Error> {
        let mut changed = 0;
        for (j, events) in rounds.iter().enumerate() {
            transport.begin_round(phase, j)?;
            for &e in events {
                match e {
                    Event::Local(i) => {
                        let (src, dst) = (self.links[i].src(), self.links[i].dst());
                        if !self.units[src].is_local() {
                            continue;
                        }
                        let raw = self.read(src, self.links[i].slot())?;
                        let link = &mut self.links[i];
                        let v = link.transform(raw);
                        changed += link.carry(v, &mut self.units[dst], phase) as usize;
                    }
                    Event::Produce(i) => {
                        let src = self.links[i].src();
                        if !self.units[src].is_local() {
                            continue;
                        }
                        let raw = self.read(src, self.links[i].slot())?;
                        transport.carry(i, &self.links[i], raw);
                    }
                    Event::Consume(i) => {
                        let dst = self.links[i].dst();
                        if !self.units[dst].is_local() {
                            continue;
                        }
                        let raw = transport.deliver(i, &self.links[i])?;
                        let link = &mut self.links[i];
                        let v = link.transform(raw);
                        changed += link.carry(v, &mut self.units[dst], phase) as usize;
                    }
                }
            }
            transport.end_round()?;
        }
        let warnings = &mut self.warnings;
        for u in self.units.iter_mut().filter(|u| u.is_local()) {
            u.flush(warnings)?;
        }
        Ok(changed)
    }

    /// Output `slot` of unit `k`, read first if stale.
    fn read(&mut self, k: usize, slot: usize) -> Result<f64, Error> {
        let u = &mut self.units[k];
        u.refresh(&mut self.warnings)?;
        Ok(u.values()[slot])
    }

    /// `fmi2DoStep` of every local unit from `t` by `h` (ticks), all from the inputs they
    /// hold, each followed by the reading of the unit's outputs, on the pool's threads. Every
    /// unit is stepped; then the statuses are checked in SSD order (the first failing unit is
    /// reported, the logs handled in that order), so the results, messages and warnings do not
    /// depend on the number of threads.
    pub(crate) fn step_all(&mut self, t: i64, h: i64) -> Result<(), Error> {
        let started = std::time::Instant::now();
        let (ts, hs) = (seconds(t), seconds(h));
        // Each unit's outputs are read right after its step (by the thread that stepped it),
        // while its state is in that core's cache; the exchange and the sample would read them
        // next in turn: the same values, as no input changed in between. One thread or many,
        // every instance sees the same calls in the same order.
        let step = |u: &mut Unit| {
            if u.is_local() {
                u.step_round(ts, hs);
            }
        };
        match &self.pool {
            Some(pool) => pool.for_each(&mut self.units, step),
            None => self.units.iter_mut().for_each(step),
        }
        let result = self.check_round(ts, hs);
        for u in &mut self.units {
            u.end_round();
        }
        self.step_time += started.elapsed();
        result
    }

    /// The statuses of a [`Core::step_all`] round, in unit order: every step, then every read
    /// (the order in which the steps and then the exchange would meet them).
    fn check_round(&mut self, ts: f64, hs: f64) -> Result<(), Error> {
        let warnings = &mut self.warnings;
        for u in self.units.iter_mut() {
            u.check_round_step(ts, hs, warnings)?;
        }
        for u in self.units.iter_mut() {
            u.check_round_reads(warnings)?;
        }
        Ok(())
    }

    /// `fmi2DoStep` of unit `k` alone from `t` by `h` (ticks).
    pub(crate) fn do_step(&mut self, k: usize, t: i64, h: i64) -> Result<(), Error> {
        self.units[k].do_step(seconds(t), seconds(h), &mut self.warnings)
    }

    /// Read every local unit's recorded outputs into the row (time first).
    pub(crate) fn sample(&mut self, t: i64) -> Result<(), Error> {
        self.row.clear();
        self.row.push(seconds(t));
        for u in self.units.iter_mut().filter(|u| u.is_local()) {
            u.refresh(&mut self.warnings)?;
            u.trace_sample(seconds(t));
            self.row.extend_from_slice(u.values());
        }
        Ok(())
    }

    /// Flush every unit's trace (`--trace`): the first error writing one.
    pub(crate) fn finish_traces(&mut self) -> Result<(), Error> {
        let mut first = Ok(());
        for u in &mut self.units {
            let r = u.finish_trace();
            if first.is_ok() {
                first = r;
            }
        }
        first
    }

    /// `fmi2Terminate` of every local unit.
    pub(crate) fn terminate(&mut self) -> Result<(), Error> {
        let warnings = &mut self.warnings;
        for u in self.units.iter_mut().filter(|u| u.is_local()) {
            u.terminate(warnings)?;
        }
        Ok(())
    }

    /// The value each connection carried at its last exchange, in SSD order, into `out`.
    pub(crate) fn connection_values(&self, out: &mut Vec<f64>) {
        out.clear();
        out.extend(self.links.iter().map(|l| l.last().unwrap_or(f64::NAN)));
    }

    /// Save every unit's state into `states` (made on the first call, overwritten after).
    pub(crate) fn save(&mut self, states: &mut Vec<SavedState>) -> Result<(), Error> {
        let warnings = &mut self.warnings;
        for (k, u) in self.units.iter_mut().enumerate() {
            u.save_state(states, k, warnings)?;
        }
        Ok(())
    }

    /// Restore every unit from `states` and mark every connection unsent.
    pub(crate) fn restore(&mut self, states: &[SavedState]) -> Result<(), Error> {
        let warnings = &mut self.warnings;
        for (u, saved) in self.units.iter_mut().zip(states) {
            u.restore_state(saved, warnings)?;
        }
        for l in &mut self.links {
            l.forget();
        }
        Ok(())
    }

    /// Set every connection's destination input to `values` (in SSD order) without reading
    /// any output.
    pub(crate) fn set_inputs(&mut self, values: &[f64]) -> Result<(), Error> {
        for (link, &v) in self.links.iter_mut().zip(values) {
            let dst = link.dst();
            link.set(v, &mut self.units[dst], Phase::Step);
        }
        let warnings = &mut self.warnings;
        for u in &mut self.units {
            u.flush(warnings)?;
        }
        Ok(())
    }

    /// Free the states saved by [`Core::save`].
    pub(crate) fn free(&mut self, states: &mut Vec<SavedState>) {
        for (u, saved) in self.units.iter_mut().zip(states.drain(..)) {
            u.free_state(saved);
        }
    }
}
