//! Co-simulation master: loads FMI 2.0 Co-Simulation FMUs from `.fmu` archives and drives them.

pub mod casestudy;
pub mod fmu;
pub mod master;
pub mod plot;
pub mod run;
pub mod ssp;

pub use fmu::{Fmu, Instance, LogRecord, Status};
