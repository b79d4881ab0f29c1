//! Co-simulation master: loads FMI 2.0 Co-Simulation FMUs from `.fmu` archives and drives them.

pub mod fmu;
pub mod run;

pub use fmu::{Fmu, Instance, LogRecord, Status};
