//! Hostile inputs against the EMT plant FMU in-process: every settable Real at 1e308, -1e308,
//! NaN, +inf and the ends of its range, and a step beyond its bound; each refused by name with
//! `fmi2Error`, never a panic.

use emt_plant_model::Plant;
use fmi_export::harness::Harness;
use fmi_export::Status;

#[test]
fn every_settable_real_is_refused_by_name_or_stepped_finite() {
    let found = Harness::hostile_sweep(Harness::<Plant>::new);
    assert!(found.is_empty(), "{}", found.join("\n"));
}

#[test]
fn a_step_beyond_the_bound_is_refused_with_the_time_unchanged() {
    let mut h = Harness::<Plant>::new();
    h.init();
    assert_eq!(h.do_step(0.0, 0.2), Status::Error);
    assert!(
        h.logged(Status::Error, "longest step dvpp_emt_plant accepts, 0.1 s"),
        "{:#?}",
        h.log()
    );
    assert_eq!(h.time(), 0.0);
}
