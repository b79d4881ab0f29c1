//! The grid FMU in-process (through `fmi_export::harness`): what a master sees of a case whose
//! time constants need a smaller internal step, and of a generator trip.

use fmi_export::harness::Harness;
use fmi_export::Status;
use grid_model::GridFmu;
use std::path::PathBuf;

/// A resources directory holding `case.toml` (ieee9 with SG2's governor `t_ch` set to `t_ch`)
/// and a config that selects it, with `events` appended to `[model]`.
fn resources(name: &str, t_ch: f64, events: &str) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("fmu-grid-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let case = grid_model::case::builtin_text("ieee9").expect("the built-in ieee9");
    let at = case.find("name = \"SG2\"").expect("SG2");
    let ch = at + case[at..].find("t_ch = 0.5").expect("SG2's t_ch");
    let case = format!(
        "{}t_ch = {t_ch}{}",
        &case[..ch],
        &case[ch + "t_ch = 0.5".len()..]
    );
    std::fs::write(dir.join("case.toml"), case).unwrap();
    std::fs::write(
        dir.join("config.toml"),
        format!("[model]\ncase_file = \"case.toml\"\n{events}"),
    )
    .unwrap();
    dir
}

#[test]
fn a_fast_governor_is_integrated_with_a_smaller_step_and_said_so_once() {
    let dir = resources("fast", 0.3e-3, "");
    let mut h = Harness::<GridFmu>::with_resources(&dir);
    assert_eq!(h.init(), Status::Warning, "{:?}", h.log());
    let said: Vec<_> = h.warnings();
    assert_eq!(said.len(), 1, "{said:?}");
    assert!(
        said[0].contains("t_ch") && said[0].contains("0.0003"),
        "{said:?}"
    );
    for _ in 0..3000 {
        h.step(1e-3);
    }
    let f = h.get("coi.f");
    assert!(
        f.is_finite() && (f - 1.0).abs() < 1e-6,
        "coi.f {f} after 3 s of a flat start"
    );
    assert_eq!(h.warnings().len(), 1, "no further warnings while stepping");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_governor_too_fast_for_any_step_is_refused_naming_it() {
    let dir = resources("too-fast", 1e-6, "");
    let location = format!("file://{}", dir.display());
    let made = Harness::<GridFmu>::instantiate(
        "grid",
        fmi_export::ffi::FMI2_COSIMULATION,
        Some(""),
        Some(&location),
        true,
    );
    match made {
        Ok(_) => panic!("a 1 us governor time constant was accepted"),
        Err(log) => {
            let text: Vec<_> = log.iter().map(|r| r.message.clone()).collect();
            assert!(text.iter().any(|m| m.contains("t_ch")), "{text:?}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_tripped_generator_is_out_of_service_in_the_outputs() {
    let trip = "[[model.event]]\ntype = \"generator_trip\"\ntime = 0.5\nmachine = 3\n";
    let dir = resources("trip", 0.5, trip);
    let mut h = Harness::<GridFmu>::with_resources(&dir);
    assert_eq!(h.init(), Status::Ok, "{:?}", h.log());
    assert!(h.get_bool("sg[3].in_service"));
    for _ in 0..1000 {
        h.step(1e-3);
    }
    assert!(!h.get_bool("sg[3].in_service"));
    assert!(h.get_bool("sg[1].in_service") && h.get_bool("sg[2].in_service"));
    assert_eq!(h.get("sg[3].p"), 0.0);
    assert_eq!(h.get("sg[3].pm"), 0.0);
    assert!(h.get("coi.f") < 1.0, "the grid lost a generator");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_machine_that_loses_synchronism_ends_the_step_with_an_error_naming_it() {
    // SG3 dispatched at 150 MW, then line 5–6 trips: it slips a pole in the first swing.
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("fmu-grid-slip-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let case = grid_model::case::builtin_text("ieee9_af").expect("the built-in ieee9");
    let case = case.replacen("p_mw = 85.0", "p_mw = 150.0", 1);
    std::fs::write(dir.join("case.toml"), case).unwrap();
    std::fs::write(
        dir.join("config.toml"),
        "[model]\ncase_file = \"case.toml\"\n[[model.event]]\ntype = \"line_trip\"\n\
         time = 1.0\nbranch = \"L5-6\"\n",
    )
    .unwrap();
    let mut h = Harness::<GridFmu>::with_resources(&dir);
    assert_eq!(h.init(), Status::Ok, "{:?}", h.log());
    let mut status = Status::Ok;
    for _ in 0..500 {
        status = h.do_step(h.time(), 0.01);
        if status != Status::Ok {
            break;
        }
    }
    assert_eq!(status, Status::Error, "{:?}", h.log());
    assert!(
        h.logged(Status::Error, "machine SG3 lost synchronism"),
        "{:?}",
        h.log()
    );
    assert!(h.time() > 1.0 && h.time() < 2.5, "t = {}", h.time());
    let _ = std::fs::remove_dir_all(&dir);
}
