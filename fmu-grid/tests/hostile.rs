//! Hostile inputs against the grid FMU in-process: every settable Real at 1e308, -1e308, NaN,
//! +inf and the ends of its range, communication steps it must refuse, and a resource file over
//! the size limit; each refused by name with `fmi2Error`, never a panic.

use fmi_export::harness::Harness;
use fmi_export::{Config, Status, MAX_RESOURCE_BYTES};
use grid_model::GridFmu;
use std::time::{Duration, Instant};

/// The grid of `case` with its built-in defaults.
fn grid(case: &str) -> Harness<GridFmu> {
    Harness::from_toml(&format!("[model]\ncase = \"{case}\"\n"))
}

#[test]
fn every_settable_real_is_refused_by_name_or_stepped_finite() {
    // ieee9_dvpp: grid-forming slots; ieee9_hybrid: grid-following ones; ieee9_mv: R/X
    // parameters and POCs.
    for case in ["ieee9_dvpp", "ieee9_hybrid", "ieee9_mv"] {
        let found = Harness::hostile_sweep(|| grid(case));
        assert!(found.is_empty(), "{case}:\n{}", found.join("\n"));
    }
}

#[test]
fn a_huge_voltage_magnitude_is_refused_by_name_at_the_setter() {
    let mut h = grid("ieee9_dvpp");
    h.init();
    let before = h.instance().core.store.clone();
    assert_eq!(h.try_set("der[1].E", 1e308), Status::Error);
    assert!(h.logged(Status::Error, "'der[1].E'"), "{:#?}", h.log());
    assert!(h.logged(Status::Error, "[0, 10]"), "{:#?}", h.log());
    assert_eq!(
        h.instance().core.store,
        before,
        "the refused value was stored"
    );
}

#[test]
fn a_step_beyond_the_bound_is_refused_at_once_with_the_state_unchanged() {
    for h_step in [1e4, 1.0 + 1e-9] {
        let mut h = grid("ieee9_dvpp");
        h.init();
        let before = h.instance().core.clone();
        let t0 = Instant::now();
        assert_eq!(h.do_step(0.0, h_step), Status::Error);
        assert!(t0.elapsed() < Duration::from_secs(1), "{:?}", t0.elapsed());
        assert!(
            h.logged(Status::Error, "communicationStepSize")
                && h.logged(Status::Error, "longest step dvpp_grid accepts, 1 s"),
            "{:#?}",
            h.log()
        );
        let after = &h.instance().core;
        assert_eq!(
            (after.time, &after.store),
            (before.time, &before.store),
            "state changed"
        );
    }
    // The bound itself is accepted.
    let mut h = grid("ieee9_dvpp");
    h.init();
    h.step(1.0);
    assert_eq!(h.time(), 1.0);
}

#[test]
fn non_finite_or_non_positive_steps_are_refused_by_name() {
    for bad in [0.0, -1e-3, f64::NAN, f64::INFINITY, -f64::INFINITY] {
        let mut h = grid("ieee9_dvpp");
        h.init();
        assert_eq!(h.do_step(0.0, bad), Status::Error, "h = {bad}");
        assert!(
            h.logged(Status::Error, "communicationStepSize")
                && h.logged(Status::Error, "must be positive and finite"),
            "{:#?}",
            h.log()
        );
    }
}

#[test]
fn a_default_experiment_step_beyond_the_bound_is_refused_at_instantiation() {
    let config = Config::from_toml("[experiment]\nstart = 0.0\nstop = 10.0\nstep = 2.0\n").unwrap();
    let log = Harness::<GridFmu>::try_with_config(config, false)
        .err()
        .expect("instantiated");
    assert!(
        log.iter()
            .any(|r| r.status == Status::Error && r.message.contains("[experiment] step = 2 s")),
        "{log:#?}"
    );
}

/// A resources directory whose `name` is a sparse file of `len` bytes, beside a valid config.
fn resources_with(tag: &str, config: &str, name: &str, len: u64) -> std::path::PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("fmu-grid-hostile-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    if name != "config.toml" {
        std::fs::write(dir.join("config.toml"), config).unwrap();
    }
    let f = std::fs::File::create(dir.join(name)).unwrap();
    f.set_len(len).unwrap();
    dir
}

fn instantiate(dir: &std::path::Path) -> Result<Harness<GridFmu>, Vec<fmi_export::log::LogRecord>> {
    let location = format!("file://{}", dir.display());
    Harness::<GridFmu>::instantiate(
        "hostile",
        fmi_export::ffi::FMI2_COSIMULATION,
        Some("any"),
        Some(&location),
        false,
    )
}

#[test]
fn a_resource_file_over_the_limit_fails_instantiation_naming_it_and_the_limit() {
    let over = MAX_RESOURCE_BYTES + 1;
    for (tag, name) in [("config", "config.toml"), ("case", "case.toml")] {
        let dir = resources_with(tag, "[model]\ncase_file = \"case.toml\"\n", name, over);
        let t0 = Instant::now();
        let log = instantiate(&dir).err().expect("instantiated");
        assert!(t0.elapsed() < Duration::from_secs(2), "{:?}", t0.elapsed());
        let path = dir.join(name);
        assert!(
            log.iter().any(|r| r.status == Status::Error
                && r.message.contains(&path.display().to_string())
                && r.message.contains("16 MiB")),
            "{log:#?}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
