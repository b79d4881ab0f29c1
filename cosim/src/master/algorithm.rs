//! Co-simulation algorithms: how the units advance over one communication step.

use super::{Error, System};
use crate::fmu::SavedState;

/// Advances every unit of a system over one communication step and leaves the connections
/// exchanged, so that the outputs recorded afterwards belong to the step's end.
pub trait Algorithm {
    /// A short name for messages.
    fn name(&self) -> &str;
    /// Once, after initialization: refuse a system the algorithm cannot run.
    fn start(&mut self, _system: &mut Coupling<'_>) -> Result<(), Error> {
        Ok(())
    }
    /// Step every unit from `t` by `h` (integer nanoseconds).
    fn step(&mut self, system: &mut Coupling<'_>, t: i64, h: i64) -> Result<(), Error>;
    /// Once, however the run ended: release what `start` took; a line to report, if any.
    fn finish(&mut self, _system: &mut Coupling<'_>) -> Option<String> {
        None
    }
}

/// What an [`Algorithm`] may do with a loaded system during a communication step.
pub struct Coupling<'a> {
    system: &'a mut System,
}

impl<'a> Coupling<'a> {
    pub(super) fn new(system: &'a mut System) -> Coupling<'a> {
        Coupling { system }
    }
}

impl Coupling<'_> {
    /// The number of units.
    pub fn units(&self) -> usize {
        self.system.units()
    }

    /// `fmi2DoStep` of unit `k` from `t` by `h` (ticks); its outputs are read again when needed.
    pub fn do_step(&mut self, k: usize, t: i64, h: i64) -> Result<(), Error> {
        self.system.core_mut().do_step(k, t, h)
    }

    /// `fmi2DoStep` of every unit from `t` by `h` (ticks), all from the inputs they hold, each
    /// followed by the reading of the unit's outputs, on the system's threads (see
    /// [`super::Builder::threads`]). Every unit is stepped; then the statuses are checked in
    /// SSD order (the first failing unit is reported, the logs handled in that order), so the
    /// results, messages and warnings do not depend on the number of threads.
    pub fn step_all(&mut self, t: i64, h: i64) -> Result<(), Error> {
        self.system.core_mut().step_all(t, h)
    }

    /// Threads [`Coupling::step_all`] steps the units on.
    pub fn threads(&self) -> usize {
        self.system.core().threads()
    }

    /// Move every connection's value (dependency order) and set the changed inputs.
    pub fn exchange(&mut self) -> Result<(), Error> {
        self.system.exchange()
    }

    /// The units in dependency order: a unit after the units feeding it, cycles in SSD order.
    pub fn dependency_order(&self) -> &[usize] {
        self.system.unit_order()
    }

    /// The value each connection carried at its last exchange, in SSD order, into `out`.
    pub fn connection_values(&self, out: &mut Vec<f64>) {
        self.system.core().connection_values(out);
    }

    /// The components whose FMU cannot save and restore its state
    /// (`canGetAndSetFMUstate` false).
    pub fn without_state(&self) -> Vec<&str> {
        self.system
            .core()
            .units()
            .iter()
            .filter(|u| !u.can_save_state())
            .map(|u| u.name())
            .collect()
    }

    /// Save every unit's state into `states` (made on the first call, overwritten after).
    pub fn save(&mut self, states: &mut Vec<SavedState>) -> Result<(), Error> {
        self.system.core_mut().save(states)
    }

    /// Restore every unit from `states` (as saved by [`Coupling::save`]) and mark every
    /// connection unsent, so that the next exchange sets every input again (a restored FMU holds
    /// the inputs it had when saved).
    pub fn restore(&mut self, states: &[SavedState]) -> Result<(), Error> {
        self.system.core_mut().restore(states)
    }

    /// Set every connection's destination input to `values` (in SSD order, as
    /// [`Coupling::connection_values`] gives them) without reading any output.
    pub fn set_inputs(&mut self, values: &[f64]) -> Result<(), Error> {
        self.system.core_mut().set_inputs(values)
    }

    /// Free the states saved by [`Coupling::save`].
    pub fn free(&mut self, states: &mut Vec<SavedState>) {
        self.system.core_mut().free(states);
    }
}

/// All units step from the same exchanged inputs (on the system's threads, see
/// [`super::Builder::threads`]), then one exchange.
#[derive(Debug, Default, Clone, Copy)]
pub struct Jacobi;

impl Algorithm for Jacobi {
    fn name(&self) -> &str {
        "jacobi"
    }

    fn step(&mut self, system: &mut Coupling<'_>, t: i64, h: i64) -> Result<(), Error> {
        system.step_all(t, h)?;
        system.exchange()
    }
}

/// Units step one after the other in dependency order, each seeing the outputs of those
/// stepped before it (an exchange after each).
#[derive(Debug, Default, Clone, Copy)]
pub struct GaussSeidel;

impl Algorithm for GaussSeidel {
    fn name(&self) -> &str {
        "gauss-seidel"
    }

    fn step(&mut self, system: &mut Coupling<'_>, t: i64, h: i64) -> Result<(), Error> {
        for k in 0..system.units() {
            let unit = system.dependency_order()[k];
            system.do_step(unit, t, h)?;
            system.exchange()?;
        }
        Ok(())
    }
}

/// Iterative coupling with rollback: each communication step is taken as a Jacobi step, then
/// repeated from the saved FMU states with the inputs set to the outputs the last attempt gave
/// at the step's end, until those inputs no longer change (each connection within
/// `atol + rtol·|value|`) or `max_iterations` attempts were made. A converged step has no
/// exchange delay: every unit stepped with the inputs the others reach at the step's end. A step
/// where nothing moves converges at the first attempt, without a rollback. Each further attempt
/// starts from `used + ω·(obtained - used)`, ω adapted by Aitken's Δ² rule (dynamic
/// relaxation, as partitioned fluid-structure solvers use it).
#[derive(Default)]
pub struct Iterative {
    pub rtol: f64,
    pub atol: f64,
    pub max_iterations: u32,
    /// The second attempt's inputs are `used + relaxation·(obtained - used)`, `relaxation` in
    /// (0, 1]; later attempts adapt the factor (Aitken).
    pub relaxation: f64,
    residual: Vec<f64>,
    factor: f64,
    states: Vec<SavedState>,
    used: Vec<f64>,
    got: Vec<f64>,
    steps: u64,
    iterations: u64,
    unconverged: u64,
    worst: Option<(f64, f64)>,
}

impl Iterative {
    /// Tolerances 1e-2 (relative) and 1e-5 (absolute), first relaxation 1, at most 30 attempts
    /// per step. On case study I at a 1 ms step this takes about 8 attempts per step and matches
    /// a 0.1 ms Jacobi run; tighter tolerances cost many more attempts (the fixed-point
    /// iteration through the grid's and the units' voltage loops contracts slowly) for no
    /// visible gain. Without the Aitken factor the attempts oscillate and do not converge.
    pub fn new() -> Iterative {
        Iterative {
            rtol: 1e-2,
            atol: 1e-5,
            max_iterations: 30,
            relaxation: 1.0,
            ..Iterative::default()
        }
    }

    /// Steps taken, attempts made, steps that did not converge.
    pub fn counts(&self) -> (u64, u64, u64) {
        (self.steps, self.iterations, self.unconverged)
    }

    /// The largest change of a connection between the inputs used and the values obtained,
    /// relative to its tolerance (≤ 1: converged).
    fn misfit(&self) -> f64 {
        self.used
            .iter()
            .zip(&self.got)
            .map(|(u, g)| (g - u).abs() / (self.atol + self.rtol * g.abs()))
            .fold(0.0, f64::max)
    }
}

impl Algorithm for Iterative {
    fn name(&self) -> &str {
        "iterative"
    }

    fn start(&mut self, system: &mut Coupling<'_>) -> Result<(), Error> {
        let without = system.without_state();
        if !without.is_empty() {
            return Err(Error::Algorithm(format!(
                "the iterative algorithm rolls steps back with fmi2GetFMUstate/fmi2SetFMUstate, \
                 which {} cannot do (canGetAndSetFMUstate is false); use jacobi or gauss-seidel",
                without.join(", ")
            )));
        }
        if !(self.rtol >= 0.0 && self.atol >= 0.0 && self.rtol + self.atol > 0.0) {
            return Err(Error::Algorithm(format!(
                "iterative algorithm: tolerances rtol = {}, atol = {} must be non-negative and not both 0",
                self.rtol, self.atol
            )));
        }
        if self.max_iterations == 0 {
            return Err(Error::Algorithm(
                "iterative algorithm: at least one iteration".into(),
            ));
        }
        if !(self.relaxation > 0.0 && self.relaxation <= 1.0) {
            return Err(Error::Algorithm(format!(
                "iterative algorithm: relaxation {} must be in (0, 1]",
                self.relaxation
            )));
        }
        Ok(())
    }

    fn step(&mut self, system: &mut Coupling<'_>, t: i64, h: i64) -> Result<(), Error> {
        system.save(&mut self.states)?;
        system.connection_values(&mut self.used);
        self.residual.clear();
        self.residual.resize(self.used.len(), 0.0);
        self.steps += 1;
        let mut attempts = 0;
        loop {
            system.step_all(t, h)?;
            system.exchange()?;
            attempts += 1;
            system.connection_values(&mut self.got);
            let misfit = self.misfit();
            if misfit <= 1.0 {
                break;
            }
            if attempts == self.max_iterations {
                self.unconverged += 1;
                let at = crate::table::seconds(t);
                if self.worst.is_none_or(|(m, _)| misfit > m) {
                    self.worst = Some((misfit, at));
                }
                break;
            }
            system.restore(&self.states)?;
            // The residual r = obtained - used. After the first attempt the factor is
            // `relaxation`; then Aitken's Δ² rule adapts it from the last two residuals,
            // ω_k = -ω_{k-1} r_{k-1}·(r_k - r_{k-1}) / |r_k - r_{k-1}|², within [0.01, 1].
            let (mut num, mut den) = (0.0, 0.0);
            for k in 0..self.used.len() {
                let r = self.got[k] - self.used[k];
                let dr = r - self.residual[k];
                num += self.residual[k] * dr;
                den += dr * dr;
                self.residual[k] = r;
            }
            self.factor = if attempts == 1 || den == 0.0 {
                self.relaxation
            } else {
                (-self.factor * num / den).clamp(0.01, 1.0)
            };
            for (u, r) in self.used.iter_mut().zip(&self.residual) {
                *u += self.factor * r;
            }
            system.set_inputs(&self.used)?;
        }
        self.iterations += u64::from(attempts);
        Ok(())
    }

    fn finish(&mut self, system: &mut Coupling<'_>) -> Option<String> {
        system.free(&mut self.states);
        if self.steps == 0 {
            return None;
        }
        let mut line = format!(
            "iterative coupling: {} steps, {:.2} attempts per step on average, {} not converged within {} attempts",
            self.steps,
            self.iterations as f64 / self.steps as f64,
            self.unconverged,
            self.max_iterations
        );
        if let Some((misfit, at)) = self.worst {
            line.push_str(&format!(
                " (worst at t = {at} s: {misfit:.1}x the tolerance)"
            ));
        }
        Some(line)
    }
}
