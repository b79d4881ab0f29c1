//! Co-simulation master: loads FMI 2.0 Co-Simulation FMUs, reads and writes SSP 1.0 systems and
//! runs them headless.
//!
//! [`fmu`] loads one FMU (unzip, dlopen once per distinct binary, the 34 functions, a C-variadic
//! logger); [`ssp`] is the SSP data model, reader and writer; [`master`] couples the units of a
//! system with an [`master::Algorithm`] (on one thread or several) and hands each communication
//! point to [`master::Observer`]s; [`table`] holds results and the master's clock; [`interrupt`]
//! turns SIGINT/SIGTERM/SIGHUP into a clean stop; [`tmp`] makes the private temporary
//! directories FMUs and SSPs are unpacked into. The `cosim` binary is the command-line front end.

mod archive;
mod dl;
pub mod federate;
pub mod fmu;
pub mod interrupt;
mod listen;
pub mod master;
pub mod ssp;
pub mod table;
pub mod tmp;

pub use fmu::{Fmu, Instance, LogRecord, Status};
pub use table::Table;
