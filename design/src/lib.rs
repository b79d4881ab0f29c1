//! Design-time synthesis of option B, the grid-forming converter's LPV H∞ matching controller, by semidefinite programming.
//!
//! The controller replaces the v-q cascade of option A (the PI on the reactive power, the
//! capacitor-voltage and the converter-current loops) by one state feedback `u = K(μ) x` on the
//! filter's states, the applied converter voltage, the local reactive reference model's state and
//! two integrals, scheduled on the unit's reactive dc gain μ. [`plant`] builds the linearized,
//! augmented model, [`synthesis`] the LMI problem that [`sdp`] hands to clarabel, [`checks`]
//! verifies the result without the solver, and [`generate`] writes the gains as Rust source into
//! `dvpp-control`, so that the FMUs carry them without linking the solver. `docs/hinf.md` has
//! the design and its measured figures.

// Link OpenBLAS (clarabel's `sdp-openblas` feature leaves the choice of the BLAS crate to us).
extern crate openblas_src;

pub mod checks;
pub mod generate;
pub mod plant;
pub mod sdp;
pub mod synthesis;
