//! End-to-end tests of the export layer: the bundled FMUs driven through their C API as a master
//! drives them — legal and illegal call sequences, bad values, FMU state, threads.

use dvpp_cosim::fmu::Sharing;
use dvpp_cosim::fmu::FMI2_CS_FUNCTIONS;
use dvpp_cosim::{Fmu, Instance, Status};
use dvpp_e2e::*;
use std::sync::Arc;

fn assert_logged(i: &Instance, needle: &str) {
    let log = i.log();
    assert!(
        log.iter().any(|r| r.message.contains(needle)),
        "expected a log line containing '{needle}', got {:#?}",
        log.iter().map(|r| &r.message).collect::<Vec<_>>()
    );
}

#[test]
fn binaries_export_all_34_functions_and_need_only_the_c_runtime() {
    assert_eq!(FMI2_CS_FUNCTIONS.len(), 34);
    for id in IDS {
        // Its own copy of the binary, unpacked and dlopened (resolving every function or
        // failing): with the default sharing, an FMU whose binary another test of this process
        // has loaded at that moment is unpacked without `binaries/` and uses that library.
        let fmu =
            Fmu::load_with(&fmu_path(id), Sharing::Separate).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(fmu.version_and_platform(), ("2.0".into(), "default".into()));
        let so = fmu.dir.join(format!("binaries/linux64/{id}.so"));
        let out = std::process::Command::new("readelf")
            .arg("-d")
            .arg(&so)
            .output()
            .expect("readelf");
        let text = String::from_utf8_lossy(&out.stdout);
        let needed: Vec<&str> = text
            .lines()
            .filter(|l| l.contains("(NEEDED)"))
            .filter_map(|l| l.split('[').nth(1)?.split(']').next())
            .collect();
        assert!(!needed.is_empty(), "{id}: no NEEDED entries read");
        for lib in &needed {
            assert!(
                [
                    "libc.so.6",
                    "libm.so.6",
                    "libgcc_s.so.1",
                    "ld-linux-x86-64.so.2",
                    "libpthread.so.0",
                    "libdl.so.2"
                ]
                .contains(lib),
                "{id} depends on {lib}, which is not part of the C runtime"
            );
        }
    }
}

#[test]
fn illegal_call_sequences_return_error_and_reset_recovers() {
    for id in IDS {
        let fmu = load(id);
        let mut i = fmu.instantiate("illegal").unwrap();
        let outs = real_outputs(&fmu);
        let mut buf = vec![0.0; outs.len()];
        // Each call below is illegal in the state the instance is in; each must log and return
        // fmi2Error, then fmi2Reset brings the instance back to `instantiated`.
        type Call = fn(&mut Instance) -> Status;
        let cases: [(&str, Call); 4] = [
            ("fmi2DoStep before initialization", |i| i.do_step(0.0, 1e-3)),
            ("fmi2ExitInitializationMode before entering", |i| {
                i.exit_initialization_mode()
            }),
            ("fmi2Terminate before initialization", |i| i.terminate()),
            ("fmi2GetReal while instantiated", |i| {
                i.get_real(&[0], &mut [0.0])
            }),
        ];
        for (what, call) in &cases {
            assert_eq!(call(&mut i), Status::Error, "{id}: {what}");
            assert_logged(&i, "illegal call sequence");
            // In the error state only inspection, reset and state restore are allowed.
            assert_eq!(
                i.do_step(0.0, 1e-3),
                Status::Error,
                "{id}: step in error state"
            );
            assert_eq!(i.reset(), Status::Ok, "{id}: reset after {what}");
        }
        // After initialization: setup and a second initialization are illegal.
        assert_eq!(i.setup_experiment(0.0, None), Status::Ok);
        assert_eq!(i.enter_initialization_mode(), Status::Ok);
        assert_eq!(
            i.enter_initialization_mode(),
            Status::Error,
            "{id}: enter twice"
        );
        assert_eq!(i.reset(), Status::Ok);
        let mut i = initialized(&fmu, "after-init");
        assert_eq!(
            i.setup_experiment(0.0, None),
            Status::Error,
            "{id}: setup after init"
        );
        assert_eq!(i.reset(), Status::Ok);
        // The instance is fully usable again.
        assert_eq!(i.setup_experiment(0.0, None), Status::Ok);
        assert_eq!(i.enter_initialization_mode(), Status::Ok);
        assert_eq!(i.exit_initialization_mode(), Status::Ok);
        assert_eq!(i.do_step(0.0, 1e-3), Status::Ok);
        assert_eq!(i.get_real(&outs, &mut buf), Status::Ok);
        assert!(buf.iter().all(|x| x.is_finite()));
        assert_eq!(i.terminate(), Status::Ok);
        assert_eq!(
            i.do_step(1e-3, 1e-3),
            Status::Error,
            "{id}: step after terminate"
        );
    }
}

#[test]
fn bad_values_are_rejected_and_change_nothing() {
    let fmu = load("dvpp_der");
    let (p, mu, h, theta, q) = (
        fmu.vr("p").unwrap(),
        fmu.vr("mu_p").unwrap(),
        fmu.vr("Tdes.H").unwrap(),
        fmu.vr("theta").unwrap(),
        fmu.vr("q").unwrap(),
    );
    let cases: [(&str, u32, f64, &str); 5] = [
        ("NaN input", p, f64::NAN, "not finite"),
        ("infinite input", p, f64::INFINITY, "not finite"),
        ("input out of range", mu, 2.0, "outside its range"),
        (
            "fixed parameter after initialization",
            h,
            3.0,
            "cannot be set",
        ),
        ("an output", theta, 0.5, "cannot be set"),
    ];
    for (what, vr, value, message) in cases {
        let mut i = initialized(&fmu, what);
        let mut before = [0.0];
        assert_eq!(i.get_real(&[vr], &mut before), Status::Ok);
        // A batch with one bad value must not apply the good one either.
        assert_eq!(
            i.set_real(&[q, vr], &[0.123, value]),
            Status::Error,
            "{what}"
        );
        assert_logged(&i, message);
        let mut after = [0.0, 0.0];
        assert_eq!(
            i.get_real(&[vr, q], &mut after),
            Status::Ok,
            "{what}: get in error state"
        );
        assert_eq!(
            after[0].to_bits(),
            before[0].to_bits(),
            "{what}: value changed"
        );
        assert_eq!(after[1], 0.0, "{what}: partial batch applied");
    }
    let mut i = fmu.instantiate("unknown-vr").unwrap();
    assert_eq!(i.set_real(&[9999], &[1.0]), Status::Error);
    assert_logged(&i, "unknown Real value reference 9999");
    // A parameter out of range before initialization names the parameter.
    let mut i = fmu.instantiate("bad-parameter").unwrap();
    assert_eq!(i.set_real(&[h], &[-1.0]), Status::Error);
    assert_logged(&i, "'Tdes.H'");
}

#[test]
fn do_step_rejects_bad_step_sizes_and_communication_points() {
    let fmu = load("dvpp_grid");
    let cases: [(&str, f64, f64, &str); 6] = [
        ("zero step", 0.0, 0.0, "positive and finite"),
        ("negative step", 0.0, -1e-3, "positive and finite"),
        ("NaN step", 0.0, f64::NAN, "positive and finite"),
        ("wrong communication point", 0.5, 1e-3, "does not match"),
        ("beyond the stop time", 0.0, 0.75, "stop time"),
        (
            "beyond the longest step",
            0.0,
            1e4,
            "exceeds the longest step dvpp_grid accepts, 1 s",
        ),
    ];
    for (what, t, h, message) in cases {
        let mut i = fmu.instantiate(what).unwrap();
        assert_eq!(i.setup_experiment(0.0, Some(0.5)), Status::Ok);
        assert_eq!(i.enter_initialization_mode(), Status::Ok);
        assert_eq!(i.exit_initialization_mode(), Status::Ok);
        assert_eq!(i.do_step(t, h), Status::Error, "{what}");
        assert_logged(&i, message);
    }
}

#[test]
fn unsupported_optional_functions_log_and_return_error() {
    let fmu = load("dvpp_operator");
    for (name, status) in initialized(&fmu, "unsupported").call_unsupported() {
        assert_eq!(status, Status::Error, "{name}");
    }
    let mut i = initialized(&fmu, "unsupported-log");
    i.call_unsupported();
    assert_logged(&i, "is not supported");
}

#[test]
fn status_queries_report_time_and_discard_the_rest() {
    let fmu = load("dvpp_operator");
    let mut i = initialized(&fmu, "status");
    let outs = real_outputs(&fmu);
    run(&mut i, &outs, 0.0, 0.25, 4);
    assert_eq!(i.last_successful_time(), (Status::Ok, 1.0));
    assert_eq!(
        i.status_queries(),
        vec![Status::Ok, Status::Discard, Status::Ok, Status::Discard]
    );
}

#[test]
fn instantiate_refuses_wrong_guid_missing_resources_and_model_exchange() {
    let fmu = load("dvpp_der");
    let uri = fmu.resource_uri();
    let guid = fmu.description.guid.clone();
    let e = fmu
        .instantiate_with(
            "bad-guid",
            "{00000000-0000-0000-0000-000000000000}",
            &uri,
            1,
        )
        .err()
        .unwrap();
    assert!(e.0.contains("GUID mismatch"), "{e}");
    let missing = format!("file://{}/nowhere", std::env::temp_dir().display());
    let e = fmu
        .instantiate_with("no-resources", &guid, &missing, 1)
        .err()
        .unwrap();
    assert!(e.0.contains("missing resource file"), "{e}");
    let e = fmu
        .instantiate_with("model-exchange", &guid, &uri, 0)
        .err()
        .unwrap();
    assert!(e.0.contains("Co-Simulation only"), "{e}");
    let e = fmu.instantiate_with("", &guid, &uri, 1).err().unwrap();
    assert!(e.0.contains("instanceName"), "{e}");
    let e = fmu
        .instantiate_with("remote", &guid, "http://example.org/resources", 1)
        .err()
        .unwrap();
    assert!(e.0.contains("not a file URI"), "{e}");
}

#[test]
fn resource_locations_are_decoded_in_every_file_uri_form() {
    let fmu = load("dvpp_der");
    let guid = fmu.description.guid.clone();
    // A space in the path, inside a fresh private directory.
    let scratch = dvpp_cosim::tmp::TempDir::new("res").unwrap();
    let spaced = scratch.path().join("dvpp res");
    std::fs::create_dir(&spaced).unwrap();
    std::fs::copy(
        fmu.dir.join("resources/config.toml"),
        spaced.join("config.toml"),
    )
    .unwrap();
    let path = spaced.display().to_string();
    let encoded = path.replace(' ', "%20");
    for uri in [
        format!("file://{encoded}"),
        format!("file:{encoded}"),
        format!("file://localhost{encoded}/"),
        path.clone(),
    ] {
        let i = fmu.instantiate_with("uri", &guid, &uri, 1);
        assert!(i.is_ok(), "{uri}: {:?}", i.err());
    }
    drop(scratch);
}

/// Drive the DER with a power step so its state evolves.
fn der_stepped(fmu: &Arc<Fmu>, name: &str) -> (Instance, Vec<u32>) {
    // Driven open loop (the bus does not answer the unit's angle): the limits are lifted.
    let mut i = fmu.instantiate(name).unwrap();
    assert_eq!(i.setup_experiment(0.0, None), Status::Ok);
    for (n, x) in [("I_max", 1e9), ("dc.t_budget", 1e-9), ("E_max", 1e9)] {
        assert_eq!(i.set_real(&[fmu.vr(n).unwrap()], &[x]), Status::Ok);
    }
    assert_eq!(i.enter_initialization_mode(), Status::Ok);
    assert_eq!(i.exit_initialization_mode(), Status::Ok);
    let p = fmu.vr("p").unwrap();
    assert_eq!(i.set_real(&[p], &[0.4]), Status::Ok);
    (i, real_outputs(fmu))
}

#[test]
fn fmu_state_get_set_and_serialize_round_trip() {
    for id in IDS {
        let fmu = load(id);
        let (mut a, outs) = if id == "dvpp_der" {
            der_stepped(&fmu, "a")
        } else {
            let i = initialized(&fmu, "a");
            (i, real_outputs(&fmu))
        };
        run(&mut a, &outs, 0.0, 1e-3, 1500);
        let (st, saved) = a.get_state();
        assert_eq!(st, Status::Ok);
        let saved = saved.unwrap();
        let bytes = a.serialize_state(&saved).unwrap();
        let expected = run(&mut a, &outs, 1.5, 1e-3, 500);

        // Restore in the same instance.
        assert_eq!(a.set_state(&saved), Status::Ok);
        assert_eq!(
            run(&mut a, &outs, 1.5, 1e-3, 500),
            expected,
            "{id}: set_state continuation"
        );
        assert_eq!(a.free_state(saved), Status::Ok);

        // Restore the serialized bytes in a fresh instance that was never initialized.
        let mut b = fmu.instantiate("b").unwrap();
        let (st, restored) = b.deserialize_state(&bytes);
        assert_eq!(st, Status::Ok);
        assert_eq!(b.set_state(&restored.unwrap()), Status::Ok);
        assert_eq!(
            run(&mut b, &outs, 1.5, 1e-3, 500),
            expected,
            "{id}: deserialized continuation"
        );

        // Corrupted, truncated and foreign bytes are refused.
        let mut corrupt = bytes.clone();
        let mid = corrupt.len() / 2;
        corrupt[mid] ^= 0x40;
        for (what, bad) in [
            ("corrupted", corrupt),
            ("truncated", bytes[..bytes.len() - 9].to_vec()),
            ("empty", vec![]),
        ] {
            let mut c = fmu.instantiate(what).unwrap();
            let (st, s) = c.deserialize_state(&bad);
            assert_eq!(st, Status::Error, "{id}: {what} bytes accepted");
            assert!(s.is_none());
            assert_logged(&c, "refused");
        }
    }
    let der = load("dvpp_der");
    let grid = load("dvpp_grid");
    let mut g = initialized(&grid, "g");
    let (_, s) = g.get_state();
    let grid_bytes = g.serialize_state(&s.unwrap()).unwrap();
    let mut d = der.instantiate("d").unwrap();
    assert_eq!(
        d.deserialize_state(&grid_bytes).0,
        Status::Error,
        "a grid state restored into a DER"
    );
}

#[test]
fn error_state_recovers_through_set_fmu_state() {
    let fmu = load("dvpp_grid");
    let mut i = initialized(&fmu, "recover");
    let outs = real_outputs(&fmu);
    run(&mut i, &outs, 0.0, 1e-3, 100);
    let (_, saved) = i.get_state();
    let saved = saved.unwrap();
    let expected = run(&mut i, &outs, 0.1, 1e-3, 10);
    assert_eq!(i.set_state(&saved), Status::Ok);
    let theta = fmu.vr("der[1].theta").unwrap();
    assert_eq!(i.set_real(&[theta], &[f64::NAN]), Status::Error);
    assert_eq!(
        i.do_step(0.1, 1e-3),
        Status::Error,
        "stepping in the error state"
    );
    assert_eq!(i.set_state(&saved), Status::Ok);
    assert_eq!(run(&mut i, &outs, 0.1, 1e-3, 10), expected);
}

#[test]
fn instances_in_threads_match_one_alone() {
    let fmu = load("dvpp_grid");
    let outs = real_outputs(&fmu);
    let alone = run(&mut initialized(&fmu, "alone"), &outs, 0.0, 1e-3, 3000);
    let handles: Vec<_> = (0..2)
        .map(|k| {
            let (fmu, outs) = (Arc::clone(&fmu), outs.clone());
            std::thread::spawn(move || {
                run(
                    &mut initialized(&fmu, &format!("thread{k}")),
                    &outs,
                    0.0,
                    1e-3,
                    3000,
                )
            })
        })
        .collect();
    for h in handles {
        assert_eq!(h.join().unwrap(), alone);
    }
}

#[test]
fn variable_communication_steps_are_honoured_exactly() {
    // The DER's frequency channel Δf = -1/(μ (H s + D)) Δp is discretized exactly, so any
    // sequence of step sizes lands on the analytic step response.
    let fmu = load("dvpp_der");
    let (mut i, _) = der_stepped(&fmu, "variable-steps");
    let vr = |n: &str| fmu.vr(n).unwrap();
    // Open loop (the power input does not answer the angle): no delay compensation.
    assert_eq!(i.set_real(&[vr("delay.c")], &[0.0]), Status::Ok);
    let mut par = [0.0; 5];
    i.get_real(
        &[
            vr("Tdes.H"),
            vr("Tdes.D"),
            vr("S_base"),
            vr("S_dvpp"),
            vr("mu_p"),
        ],
        &mut par,
    );
    let [h_in, d, s_base, s_dvpp, mu] = par;
    let dp = (0.4 - 0.3) * s_base / s_dvpp;
    let steps = [1e-4, 1e-2, 3e-3, 1e-3, 2.5e-2, 7e-4, 1e-2];
    let mut t = 0.0;
    for k in 0..60 {
        let h = steps[k % steps.len()];
        assert_eq!(i.do_step(t, h), Status::Ok);
        t += h;
        let mut df = [0.0];
        i.get_real(&[vr("df")], &mut df);
        let analytic = -dp / (mu * d) * (1.0 - dvpp_math::exp(-d * t / h_in));
        assert!(
            (df[0] - analytic).abs() < 1e-12,
            "t = {t}: {} vs {analytic}",
            df[0]
        );
    }
}

#[test]
fn debug_logging_categories() {
    let fmu = load("dvpp_operator");
    let mut i = fmu.instantiate("logging").unwrap();
    assert_eq!(
        i.set_debug_logging(true, &["logEvents", "logStatusError"]),
        Status::Ok
    );
    assert_eq!(i.set_debug_logging(false, &[]), Status::Ok);
    assert_eq!(
        i.set_debug_logging(true, &["logNoSuchCategory"]),
        Status::Error
    );
    assert_logged(&i, "unknown log category 'logNoSuchCategory'");
}

/// Half of the cross-process test: restores a state from a file and continues (runs only when
/// the parent test starts this test binary with the file names in the environment).
#[test]
fn restore_in_child_process() {
    let (Some(state), Some(out)) = (
        std::env::var_os("DVPP_STATE_IN"),
        std::env::var_os("DVPP_OUTPUTS_OUT"),
    ) else {
        return;
    };
    let fmu = load("dvpp_grid");
    let mut i = fmu.instantiate("child").unwrap();
    let (st, s) = i.deserialize_state(&std::fs::read(state).unwrap());
    assert_eq!(st, Status::Ok);
    assert_eq!(i.set_state(&s.unwrap()), Status::Ok);
    let outs = real_outputs(&fmu);
    let values = run(&mut i, &outs, 2.0, 1e-3, 200);
    let bytes: Vec<u8> = values
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    std::fs::write(out, bytes).unwrap();
}

#[test]
fn serialized_state_restores_in_another_process() {
    let fmu = load("dvpp_grid");
    let outs = real_outputs(&fmu);
    let mut i = initialized(&fmu, "parent");
    run(&mut i, &outs, 0.0, 1e-3, 2000);
    let (_, s) = i.get_state();
    let bytes = i.serialize_state(&s.unwrap()).unwrap();
    let expected: Vec<u8> = run(&mut i, &outs, 2.0, 1e-3, 200)
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    let dir = dvpp_cosim::tmp::create_dir("state").unwrap();
    let (state_file, out_file) = (dir.join("state.bin"), dir.join("outputs.bin"));
    std::fs::write(&state_file, &bytes).unwrap();
    let status = std::process::Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "restore_in_child_process", "--test-threads", "1"])
        .env("DVPP_STATE_IN", &state_file)
        .env("DVPP_OUTPUTS_OUT", &out_file)
        .env("DVPP_DIST", dist())
        .status()
        .unwrap();
    assert!(status.success());
    assert_eq!(
        std::fs::read(&out_file).unwrap(),
        expected,
        "the other process continued differently"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
