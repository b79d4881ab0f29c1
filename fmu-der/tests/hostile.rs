//! Hostile inputs against the DER FMUs in-process (phasor and EMT): every settable Real at 1e308,
//! -1e308, NaN, +inf and the ends of its range, and steps beyond each one's bound; each refused
//! by name with `fmi2Error`, never a panic.

use der_model::emt::DerEmt;
use der_model::Der;
use fmi_export::harness::Harness;
use fmi_export::Status;

#[test]
fn every_settable_real_of_the_phasor_der_is_refused_by_name_or_stepped_finite() {
    for mode in [1, 2] {
        let found = Harness::hostile_sweep(|| {
            let mut h = Harness::<Der>::new();
            h.set("mode", mode);
            h
        });
        assert!(found.is_empty(), "mode {mode}:\n{}", found.join("\n"));
    }
}

#[test]
fn every_settable_real_of_the_emt_der_is_refused_by_name_or_stepped_finite() {
    let found = Harness::hostile_sweep(Harness::<DerEmt>::new);
    assert!(found.is_empty(), "{}", found.join("\n"));
}

#[test]
fn dc_parameters_at_1e308_are_refused_by_name_at_the_setter() {
    for name in ["tau_dc", "G_dc", "k_dc"] {
        let mut h = Harness::<Der>::new();
        assert_eq!(h.try_set(name, 1e308), Status::Error, "{name}");
        assert!(
            h.logged(Status::Error, &format!("'{name}'")),
            "{:#?}",
            h.log()
        );
    }
}

#[test]
fn steps_beyond_the_bounds_are_refused_with_the_time_unchanged() {
    let mut h = Harness::<Der>::new();
    h.init();
    assert_eq!(h.do_step(0.0, 1.5), Status::Error);
    assert!(h.logged(Status::Error, "longest step dvpp_der accepts, 1 s"));
    assert_eq!(h.time(), 0.0);
    let mut h = Harness::<DerEmt>::new();
    h.init();
    assert_eq!(h.do_step(0.0, 0.2), Status::Error);
    assert!(h.logged(Status::Error, "accepts, 0.1 s"), "{:#?}", h.log());
    assert_eq!(h.time(), 0.0);
    // The bound itself is accepted.
    let mut h = Harness::<DerEmt>::new();
    h.init();
    h.step(0.1);
}
