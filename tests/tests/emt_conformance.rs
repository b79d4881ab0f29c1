//! The EMT unit's host-conformance trajectories (controllers/tests/conformance/) replayed through the bundled `dvpp_der_emt` FMU on linux64: every output of every step bit for bit as `EmtUnit` gave it (the win64 DLL under wine: tests/tests/win64.rs).

use dvpp_e2e::conformance::{replay, trajectories};
use dvpp_e2e::load;

#[test]
fn conformance_trajectories_replay_through_the_fmu_bit_for_bit() {
    let fmu = load("dvpp_der_emt");
    let md = fmu.description.clone();
    for (path, t) in trajectories() {
        let mut i = fmu
            .instantiate(&t.case)
            .unwrap_or_else(|e| panic!("{}: {e}", t.case));
        let (init, steps) = replay(&mut i, &md, &t);
        if let Err(m) = t.compare(&init, &steps) {
            panic!("{} through dvpp_der_emt.fmu (linux64): {m}", path.display());
        }
        eprintln!(
            "{}: {} steps through dvpp_der_emt.fmu bit for bit",
            t.case,
            t.steps.len()
        );
    }
}
