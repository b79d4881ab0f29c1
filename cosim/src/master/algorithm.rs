//! Co-simulation algorithms: how the units advance over one communication step.

use super::{Coupling, Error};

/// Advances every unit of a system over one communication step and leaves the connections
/// exchanged, so that the outputs recorded afterwards belong to the step's end.
pub trait Algorithm {
    /// A short name for messages.
    fn name(&self) -> &str;
    /// Step every unit from `t` by `h` (integer nanoseconds).
    fn step(&mut self, system: &mut Coupling<'_>, t: i64, h: i64) -> Result<(), Error>;
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
