//! The DVPP control design as a library shared by the FMUs and the tests.

pub mod phasor;
