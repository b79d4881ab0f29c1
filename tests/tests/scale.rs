//! Scaling up (docs/scaling.md): units stepped on several threads give the results of one
//! thread bit for bit, and components with identical binaries run in one loaded library while
//! each reads its own resources.

use dvpp_cosim::master::{self, Iterative, Jacobi, Options, Recorder, Sharing, System};
use dvpp_cosim::{ssp, Table};
use dvpp_e2e::{cosim, scenario};
use std::path::Path;
use std::process::Command;

/// `case1_load` to `stop` s with `algorithm` on `threads` threads, every output in memory.
fn run(stop: f64, threads: usize, algorithm: &mut dyn master::Algorithm) -> Table {
    let opts = Options {
        stop: Some(stop),
        ..Options::default()
    };
    let mut rec = Recorder::default();
    let outcome = System::builder(&scenario("case1_load"))
        .threads(threads)
        .algorithm(algorithm)
        .run(&opts, &mut [&mut rec])
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(outcome.end, master::End::Completed);
    assert_eq!(outcome.threads, threads.min(outcome.units));
    rec.table
}

/// Every value of `a` and `b` has the same bits.
fn assert_bit_identical(a: &Table, b: &Table, what: &str) {
    assert_eq!(a.columns, b.columns, "{what}: columns");
    assert_eq!(a.rows.len(), b.rows.len(), "{what}: rows");
    for (ra, rb) in a.rows.iter().zip(&b.rows) {
        for ((x, y), name) in ra.iter().zip(rb).zip(&a.columns) {
            assert_eq!(
                x.to_bits(),
                y.to_bits(),
                "{what}: {name} at t = {}: {x} vs {y}",
                ra[0]
            );
        }
    }
}

#[test]
fn two_threads_give_the_results_of_one_bit_for_bit() {
    let one = run(20.0, 1, &mut Jacobi);
    let two = run(20.0, 2, &mut Jacobi);
    assert_eq!(one.rows.len(), 20_001);
    assert_bit_identical(&one, &two, "Jacobi, 2 threads");
    // More threads than units: one per unit.
    let many = run(2.0, 16, &mut Jacobi);
    let head = Table {
        columns: one.columns.clone(),
        rows: one.rows[..many.rows.len()].to_vec(),
    };
    assert_bit_identical(&head, &many, "Jacobi, 16 threads");
    // Iterative coupling steps its attempts on the threads too (over the load step).
    let one = run(1.05, 1, &mut Iterative::new());
    let two = run(1.05, 2, &mut Iterative::new());
    assert_bit_identical(&one, &two, "iterative, 2 threads");
}

#[test]
fn cosim_threads_flag_writes_the_same_csv() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("scale-cli");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create the directory");
    let csv = |threads: &str| {
        let out = dir.join(format!("t{threads}.csv"));
        let done = Command::new(cosim())
            .arg(scenario("case1_load"))
            .args(["--stop", "2", "--threads", threads, "--out"])
            .arg(&out)
            .output()
            .expect("run cosim");
        assert!(
            done.status.success(),
            "cosim --threads {threads}: {}",
            String::from_utf8_lossy(&done.stderr)
        );
        std::fs::read(&out).expect("read the CSV")
    };
    let one = csv("1");
    assert!(one == csv("2"), "--threads 2 wrote another CSV");
    assert!(one == csv("all"), "--threads all wrote another CSV");
    let bad = Command::new(cosim())
        .arg(scenario("case1_load"))
        .args(["--threads", "0"])
        .output()
        .expect("run cosim");
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--threads 0"));
}

#[test]
fn identical_binaries_share_one_library_each_with_its_own_resources() {
    let package = ssp::read(&scenario("case1_load")).unwrap_or_else(|e| panic!("{e}"));
    let shared = System::builder(&package)
        .load()
        .unwrap_or_else(|e| panic!("{e}"));
    let fmu = |s: &System, name: &str| s.fmu(name).expect(name).clone();
    let (wind, pv, bess) = (
        fmu(&shared, "wind"),
        fmu(&shared, "pv"),
        fmu(&shared, "bess"),
    );
    let (grid, operator) = (fmu(&shared, "grid"), fmu(&shared, "operator"));
    // The three DERs are the same dvpp_der binary: one library.
    assert!(wind.shares_library_with(&pv) && wind.shares_library_with(&bess));
    assert!(!wind.shares_library_with(&grid) && !grid.shares_library_with(&operator));
    assert_eq!(wind.library().model_identifier(), "dvpp_der");
    assert_eq!(shared.libraries(), 3);
    // Each its own unpacked resources, named in its fmi2Instantiate.
    assert_ne!(wind.dir, pv.dir);
    assert_ne!(wind.resource_uri(), pv.resource_uri());
    for f in [&wind, &pv, &bess] {
        assert!(f.dir.join("resources").join("config.toml").is_file());
    }
    drop((wind, pv, bess, grid, operator));

    // Loaded separately, every component has its own library, and the results are the same.
    let separate = System::builder(&package)
        .sharing(Sharing::Separate)
        .load()
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(separate.libraries(), 5);
    let wind_sep = fmu(&separate, "wind");
    assert!(!wind_sep.shares_library_with(&fmu(&shared, "wind")));
    drop(wind_sep);
    let opts = Options {
        stop: Some(0.5),
        ..Options::default()
    };
    let run = |mut s: System| s.simulate(&opts).unwrap_or_else(|e| panic!("{e}"));
    let (a, b) = (run(shared), run(separate));
    assert_bit_identical(&a, &b, "shared vs separate binaries");

    // Sharing the binary, each DER read its own config.toml: the wind's and the PV's start
    // values (available power 0.43 and 0.7 pu, presets wind and PV) come out.
    let at0 = |name: &str| a.column(name).expect(name)[0];
    assert_eq!(at0("wind.P_avail"), 0.43);
    assert_eq!(at0("pv.P_avail"), 0.7);
    assert_ne!(at0("wind.p_set"), at0("pv.p_set"));
    // And the same FMU file loaded twice shares too.
    let path = package.source_path(package.system.component("wind").expect("wind"));
    let (x, y) = (
        dvpp_cosim::Fmu::load(&path).expect("load"),
        dvpp_cosim::Fmu::load(&path).expect("load"),
    );
    assert!(x.shares_library_with(&y));
    let z = dvpp_cosim::Fmu::load_with(&path, Sharing::Separate).expect("load");
    assert!(!z.shares_library_with(&x));
}
