//! The DVPP control design as a library shared by the FMUs and the tests.
//!
//! The method is that of Häberle, Tayyebi, He, Prieto-Araujo and Dörfler, "Grid-Forming and
//! Spatially Distributed Control Design of Dynamic Virtual Power Plants", arXiv:2202.02939
//! ("the paper" in this crate; `docs/references.md`); the equations as implemented are in
//! `docs/control.md`.
//!
//! Grid-forming and hybrid dynamic virtual power plant (DVPP) control: `T_des`, adaptive
//! dynamic participation factors (ADPFs), participation/aggregation checks, the local
//! reference models each DER realizes, with exact sampled-data simulation for FMI
//! co-simulation (communication steps 1e-4 … 1e-2 s), and phasor relations.
//!
//! Conventions: per-unit deviations on the DVPP base; `p`, `q` injected (generator convention);
//! `Δf = −T_pf Δp`, `Δv = −T_qv Δq`. Transfer-function coefficients are in **ascending** powers
//! of `s`. Every runtime type is `Clone + Serialize + Deserialize` (FMU state snapshots).

#![deny(missing_docs)]

pub mod adaptation;
pub mod adpf;
pub mod bank;
pub mod checks;
pub mod converter;
pub mod error;
pub mod fleet;
pub mod local;
pub mod phasor;
pub mod presets;
pub mod rotation;
pub mod ss;
pub mod tdes;
pub mod tf;

pub use adaptation::{
    active_gains, reactive_capacity, reactive_gains, renormalize_with_floor,
    renormalize_with_floors,
};
pub use adpf::{
    design_grid, eval_set, log_grid, max_participation_error, participation_error, Adpf,
    LowPassSpec,
};
pub use bank::ParticipationBank;
pub use checks::{
    check_gfm_aggregation, check_hybrid_aggregation, check_participation,
    check_voltage_aggregation, validate_design, DesignReport, HybridReport,
};
pub use error::{DvppError, Result};
pub use fleet::{DerKind, Fleet};
pub use local::{
    floor_scale, mu_min_gfm, GflFpModel, GfmPfModel, ShapedModel, VqModel, MU_FLOOR_KAPPA,
    MU_MIN_GFM,
};
pub use nalgebra::Complex;
pub use presets::CaseStudyI;
pub use rotation::Rotation;
pub use ss::{expm, Discretization, Hold, LtiSimulator, StateSpace};
pub use tdes::TDes;
pub use tf::TransferFunction;
