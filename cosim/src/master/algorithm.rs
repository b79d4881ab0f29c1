//! Co-simulation algorithms: how the units advance over one communication step.

use super::{Coupling, Error};
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

/// All units step from the same exchanged inputs (parallel in principle), then one exchange.
#[derive(Debug, Default, Clone, Copy)]
pub struct Jacobi;

impl Algorithm for Jacobi {
    fn name(&self) -> &str {
        "jacobi"
    }

    fn step(&mut self, system: &mut Coupling<'_>, t: i64, h: i64) -> Result<(), Error> {
        for unit in 0..system.units() {
            system.do_step(unit, t, h)?;
        }
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
/// starts from `used + relaxation·(obtained - used)`.
#[derive(Default)]
pub struct Iterative {
    pub rtol: f64,
    pub atol: f64,
    pub max_iterations: u32,
    /// The next attempt's inputs: `used + relaxation·(obtained - used)`, in (0, 1].
    pub relaxation: f64,
    states: Vec<SavedState>,
    used: Vec<f64>,
    got: Vec<f64>,
    steps: u64,
    iterations: u64,
    unconverged: u64,
    worst: Option<(f64, f64)>,
}

impl Iterative {
    /// Tolerances 1e-4 (relative) and 1e-7 (absolute), relaxation 0.5, at most 30 attempts per
    /// step. Without relaxation the attempts of case study I oscillate and diverge after its load
    /// step (the reactive-power loop through the grid and the units' PI controllers has a
    /// fixed-point gain beyond 1 at a 1 ms step); with 0.5 they converge in about 12-19.
    pub fn new() -> Iterative {
        Iterative {
            rtol: 1e-4,
            atol: 1e-7,
            max_iterations: 30,
            relaxation: 0.5,
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
            return Err(Error(format!(
                "the iterative algorithm rolls steps back with fmi2GetFMUstate/fmi2SetFMUstate, \
                 which {} cannot do (canGetAndSetFMUstate is false); use jacobi or gauss-seidel",
                without.join(", ")
            )));
        }
        if !(self.rtol >= 0.0 && self.atol >= 0.0 && self.rtol + self.atol > 0.0) {
            return Err(Error(format!(
                "iterative algorithm: tolerances rtol = {}, atol = {} must be non-negative and not both 0",
                self.rtol, self.atol
            )));
        }
        if self.max_iterations == 0 {
            return Err(Error("iterative algorithm: at least one iteration".into()));
        }
        if !(self.relaxation > 0.0 && self.relaxation <= 1.0) {
            return Err(Error(format!(
                "iterative algorithm: relaxation {} must be in (0, 1]",
                self.relaxation
            )));
        }
        Ok(())
    }

    fn step(&mut self, system: &mut Coupling<'_>, t: i64, h: i64) -> Result<(), Error> {
        system.save(&mut self.states)?;
        system.connection_values(&mut self.used);
        self.steps += 1;
        let mut attempts = 0;
        loop {
            for unit in 0..system.units() {
                system.do_step(unit, t, h)?;
            }
            system.exchange()?;
            attempts += 1;
            system.connection_values(&mut self.got);
            let misfit = self.misfit();
            if misfit <= 1.0 {
                break;
            }
            if attempts == self.max_iterations {
                self.unconverged += 1;
                let at = super::seconds(t);
                if self.worst.is_none_or(|(m, _)| misfit > m) {
                    self.worst = Some((misfit, at));
                }
                break;
            }
            system.restore(&self.states)?;
            let w = self.relaxation;
            for (u, g) in self.used.iter_mut().zip(&self.got) {
                *u += w * (g - *u);
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
