//! The co-simulation master: runs an SSP system of FMUs in fixed communication steps (integer
//! nanoseconds) from initialization to the stop time, handing each point to its observers.
//!
//! How the units advance over a step is an [`Algorithm`] ([`Jacobi`], [`GaussSeidel`]); what
//! happens to the results is up to the [`Observer`]s ([`CsvWriter`] streams them to disk,
//! [`Progress`] reports, [`Recorder`] keeps them in memory). The loop polls
//! [`crate::interrupt::requested`] at each communication point. [`Jacobi`] and [`Iterative`]
//! step the units on [`Builder::threads`] threads (a small pool, the caller included), with
//! the results of one thread bit for bit.
//!
//! One exchange moves every connection's value from its start connector to its end connector
//! (with the SSP `LinearTransformation`), in dependency order: a connection leaving a unit with
//! direct feedthrough (`ModelStructure/Outputs` dependencies during steps, `InitialUnknowns`
//! during initialization) is read after the connections into that unit were set. A cycle of
//! such dependencies (an algebraic loop) is reported and broken at the connection of the cycle
//! that comes first in the SSD: that connection carries the value from before the exchange.
//! Initialization repeats the exchange until no value changes.
//!
//! A system is loaded by a [`Builder`] (`System::builder(path).threads(2).load()`, or `.run`
//! to load and run it). The initialization, exchange, stepping and sampling live in one
//! coupling core (`coupling`), which the HELICS federate ([`crate::federate`]) drives as well,
//! over its own components and with its values travelling through HELICS.
//!
//! The parts: `unit` (one loaded component and its FMI calls), `graph` (connections and their
//! exchange order), `coupling` (the core), `system` (loading, the builder, the experiment),
//! `run` (the run loop), [`algorithm`](Algorithm), observers and results.

mod algorithm;
mod coupling;
mod error;
mod graph;
mod observer;
mod pool;
mod results;
mod run;
mod system;
mod unit;

pub use algorithm::{Algorithm, Coupling, GaussSeidel, Iterative, Jacobi};
pub use error::Error;
pub use observer::{End, Observer, Progress, Recorder, RunInfo};
pub use results::{matches, Csv, CsvWriter, Format, Mat, MatWriter, Record, ResultWriter, Select};
pub use run::{Outcome, MAX_STEPS};
pub use system::{Builder, Source, System};

pub use crate::fmu::Sharing;

pub(crate) use coupling::{Event, Plans, Transport};
pub(crate) use graph::Link;
pub(crate) use unit::Phase;

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
            _ => Err(Error::Algorithm(format!(
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
