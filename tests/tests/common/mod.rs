//! Shared helpers of the end-to-end tests: where the bundled FMUs are, and loading them.

#![allow(dead_code)]

use dvpp_cosim::{Fmu, Instance, Status};
use std::path::PathBuf;
use std::sync::Arc;

/// The directory with the default FMUs (`cargo xtask bundle` writes it).
pub fn dist() -> PathBuf {
    std::env::var_os("DVPP_DIST")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../dist/default"))
}

pub const IDS: [&str; 3] = ["dvpp_der", "dvpp_operator", "dvpp_grid"];

/// Path of a bundled FMU.
pub fn fmu_path(id: &str) -> PathBuf {
    let p = dist().join(format!("{id}.fmu"));
    assert!(
        p.is_file(),
        "{} is missing: run `cargo xtask bundle` (or `cargo xtask test`)",
        p.display()
    );
    p
}

/// Load a bundled FMU.
pub fn load(id: &str) -> Arc<Fmu> {
    Arc::new(Fmu::load(&fmu_path(id)).unwrap_or_else(|e| panic!("{e}")))
}

/// Instantiate, set up and initialize; returns an instance in step mode at t = 0.
pub fn initialized(fmu: &Arc<Fmu>, name: &str) -> Instance {
    let mut i = fmu.instantiate(name).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(i.setup_experiment(0.0, None), Status::Ok);
    assert_eq!(i.enter_initialization_mode(), Status::Ok);
    assert_eq!(i.exit_initialization_mode(), Status::Ok);
    i
}

/// Value references of all Real outputs, in index order.
pub fn real_outputs(fmu: &Fmu) -> Vec<u32> {
    fmu.description
        .model_variables
        .variables
        .iter()
        .filter(|v| v.causality() == model_description::Causality::Output)
        .map(|v| v.value_reference)
        .collect()
}

/// Step `n` times by `h` from `t0`, returning the outputs after each step.
pub fn run(i: &mut Instance, vrs: &[u32], t0: f64, h: f64, n: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|k| {
            let t = t0 + k as f64 * h;
            assert_eq!(
                i.do_step(t, h),
                Status::Ok,
                "step at {t}: {:?}",
                i.last_message()
            );
            let mut out = vec![0.0; vrs.len()];
            assert_eq!(i.get_real(vrs, &mut out), Status::Ok);
            out
        })
        .collect()
}
