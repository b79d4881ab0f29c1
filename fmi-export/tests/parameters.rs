//! Parameter values a model cannot use are refused by name at `fmi2SetReal`, and a panic still
//! contained in initialization names the parameters the model ran with.

use fmi_export::harness::Harness;
use fmi_export::{Context, Model, ModelError, Real, Spec, Status, Store, Variables};
use serde::{Deserialize, Serialize};

#[derive(Clone, Serialize, Deserialize)]
struct Lag {
    tau: Real,
    k: Real,
    y: Real,
}

impl Model for Lag {
    type Config = ();
    const IDENTIFIER: &'static str = "lag";
    const NAME: &'static str = "lag";
    const DESCRIPTION: &'static str = "k/(tau s + 1); panics on a zero tau";

    fn declare(_: &(), _: Option<&std::path::Path>, v: &mut Variables) -> Result<Self, String> {
        Ok(Lag {
            tau: v.real(Spec::parameter("tau", 1.0, "s", "time constant").min(0.0)),
            k: v.real(Spec::parameter("k", 1.0, "", "gain")),
            y: v.real(Spec::output("y", "", "output")),
        })
    }

    fn initialize(&mut self, s: &mut Store, _: &mut Context) -> Result<(), ModelError> {
        let pole = -1.0 / s[self.tau];
        assert!(pole.is_finite(), "realization: pole {pole} is not finite");
        s[self.y] = 0.0;
        Ok(())
    }

    fn do_step(
        &mut self,
        _: &mut Store,
        _: f64,
        _: f64,
        _: &mut Context,
    ) -> Result<(), ModelError> {
        Ok(())
    }
}

fn messages(h: &Harness<Lag>) -> Vec<String> {
    h.log().into_iter().map(|r| r.message).collect()
}

#[test]
fn a_subnormal_parameter_is_refused_by_name() {
    for x in [4.9e-324, -1e-310, 2.2e-308] {
        let mut h = Harness::<Lag>::new();
        assert_eq!(h.try_set("tau", x), Status::Error, "tau = {x:e}");
        let log = messages(&h);
        assert!(
            log.iter()
                .any(|m| m.contains("parameter 'tau'") && m.contains("subnormal")),
            "{log:?}"
        );
    }
    // Normal values and zero stay accepted.
    let mut h = Harness::<Lag>::new();
    assert_eq!(h.try_set("k", 0.0), Status::Ok);
    assert_eq!(h.try_set("k", f64::MIN_POSITIVE), Status::Ok);
    assert_eq!(h.try_set("tau", 1e-300), Status::Ok);
}

#[test]
fn a_contained_panic_in_initialization_names_the_parameters_set() {
    let mut h = Harness::<Lag>::new();
    h.set("tau", 0.0);
    assert_eq!(h.setup_experiment(0.0, None), Status::Ok);
    assert_eq!(h.enter_initialization_mode(), Status::Ok);
    assert_eq!(h.exit_initialization_mode(), Status::Fatal);
    let log = messages(&h);
    let fatal = log
        .iter()
        .find(|m| m.contains("internal error contained"))
        .unwrap_or_else(|| panic!("no contained panic logged: {log:?}"));
    assert!(fatal.contains("'tau' = 0"), "{fatal}");
    assert!(!fatal.contains("'k'"), "k kept its start value: {fatal}");
}
