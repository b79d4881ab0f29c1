//! Parameter values a model cannot use (subnormal, absurdly large) are refused by name at
//! `fmi2SetReal`, steps beyond the model's bound by `fmi2DoStep`, oversized resource files at
//! reading, and a panic still contained in initialization names the parameters the model ran
//! with.

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
    type State = ();
    const IDENTIFIER: &'static str = "lag";
    const NAME: &'static str = "lag";
    const DESCRIPTION: &'static str = "k/(tau s + 1); panics on a zero tau";
    const MAX_STEP: f64 = 1.0;

    fn declare(_: &(), _: Option<&std::path::Path>, v: &mut Variables) -> Result<Self, String> {
        Ok(Lag {
            tau: v.real(Spec::parameter("tau", 1.0, "s", "time constant").min(0.0)),
            k: v.real(Spec::parameter("k", 1.0, "", "gain")),
            y: v.real(Spec::output("y", "", "output")),
        })
    }

    fn initialize(&self, _: Option<&()>, s: &mut Store, _: &mut Context) -> Result<(), ModelError> {
        let pole = -1.0 / s[self.tau];
        assert!(pole.is_finite(), "realization: pole {pole} is not finite");
        s[self.y] = 0.0;
        Ok(())
    }

    fn do_step(
        &self,
        _: &mut (),
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

#[test]
fn an_absurd_value_without_declared_bounds_is_refused_by_name_with_the_range() {
    for x in [1e308, -1e308, 1.0001e12] {
        let mut h = Harness::<Lag>::new();
        assert_eq!(h.try_set("k", x), Status::Error, "k = {x:e}");
        let log = messages(&h);
        assert!(
            log.iter()
                .any(|m| m.contains("'k'") && m.contains("outside its range [-1e12, 1e12]")),
            "{log:?}"
        );
        assert_eq!(h.get("k"), 1.0, "the refused value was stored");
    }
    // The cap itself is accepted, and a declared lower bound keeps the cap above it.
    let mut h = Harness::<Lag>::new();
    assert_eq!(h.try_set("k", fmi_export::MAX_MAGNITUDE), Status::Ok);
    assert_eq!(h.try_set("tau", 1e308), Status::Error);
    assert!(messages(&h).iter().any(|m| m.contains("'tau'")));
}

#[test]
fn an_absurd_start_value_in_the_config_is_refused_by_name() {
    let config = fmi_export::Config::from_toml("[start]\nk = 1e308\n").unwrap();
    let log = Harness::<Lag>::try_with_config(config, false)
        .err()
        .expect("instantiated");
    assert!(
        log.iter().any(
            |r| r.message.contains("[start] 'k' = ") && r.message.contains("outside its range")
        ),
        "{log:?}"
    );
}

#[test]
fn a_step_beyond_max_step_or_not_positive_is_refused_with_the_time_unchanged() {
    for bad in [1.5, 1e4, 0.0, -1.0, f64::NAN, f64::INFINITY] {
        let mut h = Harness::<Lag>::new();
        h.init();
        assert_eq!(h.do_step(0.0, bad), Status::Error, "h = {bad}");
        assert_eq!(h.time(), 0.0);
        assert!(
            messages(&h)
                .iter()
                .any(|m| m.contains("fmi2DoStep: communicationStepSize")),
            "{:?}",
            messages(&h)
        );
    }
    let mut h = Harness::<Lag>::new();
    h.init();
    h.step(<Lag as Model>::MAX_STEP);
}

#[test]
fn a_resource_file_over_the_limit_is_refused_naming_it_and_the_limit() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("fmi-export-resource-limit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("config.toml");
    let f = std::fs::File::create(&path).unwrap();
    // Sparse: no disk space taken.
    f.set_len(fmi_export::MAX_RESOURCE_BYTES + 1).unwrap();
    let e = fmi_export::read_resource(&path).unwrap_err();
    assert!(
        e.contains(&path.display().to_string()) && e.contains("16 MiB"),
        "{e}"
    );
    let e = fmi_export::Config::<()>::load(&dir).unwrap_err();
    assert!(e.contains("16 MiB"), "{e}");
    // At the limit it is read (and then fails to parse as TOML: NUL bytes).
    f.set_len(fmi_export::MAX_RESOURCE_BYTES).unwrap();
    assert!(fmi_export::read_resource(&path).is_ok());
    let _ = std::fs::remove_dir_all(&dir);
}
