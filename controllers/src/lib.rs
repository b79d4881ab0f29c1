//! The DVPP controllers as host-independent library objects: typed parameters (validated, an
//! error names the field), typed measurements and commands, `initialize` and `step`; the FMUs
//! and any other host are adapters around them.

pub mod operator;
