//! The host-conformance test of the EMT-level unit: reference trajectories of `EmtUnit` in closed loop with the EMT plant's circuit (stiff grid, weak grid, island; options A and B grid-forming, grid-following on the stiff and the weak grid), replayed through `EmtUnit` bit for bit; and the unit's contracts with a host (its state saved and restored, parameters refused by name, retuning).
//!
//! Each case's trajectory (tests/conformance/NAME.txt, format in
//! `dvpp_controllers::emt::trajectory`) holds every input the unit received and every output it
//! returned. `DVPP_BLESS=1 cargo test -p dvpp-controllers --test conformance` regenerates them
//! from the closed loop with the plant (`emt-plant-model`, in process); without it the test
//! replays each trajectory's inputs through `EmtUnit` and requires every output bit for bit.
//! The same files are replayed through the `dvpp_der_emt` FMU on linux64 and win64
//! (tests/tests/emt_conformance.rs, tests/tests/win64.rs).

mod support;
use dvpp_control::converter::Abc;
use dvpp_controllers::emt::trajectory::{Trajectory, N_OUT, OUTPUTS};
use dvpp_controllers::emt::{EmtCommand, EmtMeasurement, EmtParams, EmtUnit, InnerKind};
use dvpp_controllers::{AdpfKind, Mode};
use fmi_export::Status;
use std::path::PathBuf;
use support::{command, measure, plant_for, unit_params, GAINS};

/// The step of every case (s).
const H: f64 = 50e-6;
/// Steps recorded per case: 0.1 s.
const RECORDED: usize = 2000;
/// Steps run when blessing, to check that the case is stable (3 s).
const CHECKED: usize = 60000;
/// When the case's disturbance acts (s).
const T_EVENT: f64 = 0.02;

/// The grid the unit is connected to (through its filter and transformer, in the plant).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Grid {
    /// A Thevenin source of short-circuit ratio 55 on the unit's rating; the source's phase
    /// jumps by 0.05 rad at `T_EVENT`.
    Stiff,
    /// A Thevenin source of short-circuit ratio 2.5; a load of 0.1 pu on S_base switches on at
    /// `T_EVENT`.
    Weak,
    /// The plant's built-in island (the unit alone on its R-L load); a load of 0.06 pu switches
    /// on at `T_EVENT`.
    Island,
}

struct Case {
    name: &'static str,
    grid: Grid,
    mode: Mode,
    kind: InnerKind,
}

/// Option A and option B grid-forming on every grid; grid-following (its current loop is
/// option A's) on the stiff and the weak grid (an island has no voltage to follow).
const CASES: [Case; 8] = [
    Case {
        name: "stiff_gfm_a",
        grid: Grid::Stiff,
        mode: Mode::GridForming,
        kind: InnerKind::OptionA,
    },
    Case {
        name: "weak_gfm_a",
        grid: Grid::Weak,
        mode: Mode::GridForming,
        kind: InnerKind::OptionA,
    },
    Case {
        name: "island_gfm_a",
        grid: Grid::Island,
        mode: Mode::GridForming,
        kind: InnerKind::OptionA,
    },
    Case {
        name: "stiff_gfm_b",
        grid: Grid::Stiff,
        mode: Mode::GridForming,
        kind: InnerKind::OptionB,
    },
    Case {
        name: "island_gfm_b",
        grid: Grid::Island,
        mode: Mode::GridForming,
        kind: InnerKind::OptionB,
    },
    Case {
        name: "weak_gfm_b",
        grid: Grid::Weak,
        mode: Mode::GridForming,
        kind: InnerKind::OptionB,
    },
    Case {
        name: "stiff_gfl",
        grid: Grid::Stiff,
        mode: Mode::GridFollowing,
        kind: InnerKind::OptionA,
    },
    Case {
        name: "weak_gfl",
        grid: Grid::Weak,
        mode: Mode::GridFollowing,
        kind: InnerKind::OptionA,
    },
];

impl Case {
    fn params(&self) -> EmtParams {
        unit_params(self.mode, self.kind)
    }

    fn comments(&self) -> Vec<&'static str> {
        vec![
            match self.grid {
                Grid::Stiff => "stiff grid: Thevenin X = 0.03, R = 0.003 pu on S_base = 100 MVA (SCR 55 on the 60 MVA unit), E = 1.02; its phase jumps by 0.05 rad at t = 0.02 s",
                Grid::Weak => "weak grid: Thevenin X = 0.667, R = 0.0667 pu on S_base = 100 MVA (SCR 2.5 on the 60 MVA unit), E = 1.02; a load of 0.1 + j0.02 pu switches on at t = 0.02 s",
                Grid::Island => "island: the EMT plant's built-in case island (the unit alone on 0.3 + j0.06 pu); 0.06 + j0.012 pu more at t = 0.02 s",
            },
            "plant: emt-plant-model with the unit's filter R_f L_f C_f, transformer R_t L_t, dc link C_dc G_dc tau_dc; master: the plant steps [t, t+h) with the command the unit returned at t - h",
        ]
    }

    /// The plant's `config.toml`.
    fn plant_toml(&self) -> String {
        let (thevenin, loads) = match self.grid {
            Grid::Stiff => (true, "{ name = \"base\", p = 0.3, q = 0.06 }"),
            Grid::Weak => (
                true,
                "{ name = \"base\", p = 0.3, q = 0.06 }, { name = \"step\", p = 0.1, q = 0.02, t_on = 0.02 }",
            ),
            Grid::Island => (
                false,
                "{ name = \"base\", p = 0.3, q = 0.06 }, { name = \"step\", p = 0.06, q = 0.012, t_on = 0.02 }",
            ),
        };
        format!(
            "[model]\ncase = \"island\"\nthevenin = {thevenin}\nunits = [{{ name = \"unit\", s_rated = 60.0, tau_dc = 0.2, p0 = {} }}]\nloads = [{loads}]\n",
            if thevenin { 0.3 } else { 0.0 }
        )
    }
}

/// The unit in closed loop with the plant for `n` steps: its initialization and every step
/// (measurement, step, command).
#[allow(clippy::type_complexity)]
fn closed_loop(
    case: &Case,
    n: usize,
) -> (
    (EmtMeasurement, EmtCommand),
    Vec<(EmtMeasurement, f64, EmtCommand)>,
) {
    closed_loop_with(case, &case.params(), n)
}

/// [`closed_loop`] with the unit's parameters `params` instead of the case's.
#[allow(clippy::type_complexity)]
fn closed_loop_with(
    case: &Case,
    params: &EmtParams,
    n: usize,
) -> (
    (EmtMeasurement, EmtCommand),
    Vec<(EmtMeasurement, f64, EmtCommand)>,
) {
    let params = *params;
    let mut plant = plant_for(&case.plant_toml(), &params);
    match case.grid {
        Grid::Stiff => {
            plant.set("thevenin.X", 0.03);
            plant.set("thevenin.R", 0.003);
            plant.set("thevenin.jump", 0.05);
            plant.set("thevenin.jump_t", T_EVENT);
        }
        Grid::Weak => {
            plant.set("thevenin.X", 0.667);
            plant.set("thevenin.R", 0.0667);
        }
        Grid::Island => {}
    }
    assert_eq!(plant.enter_initialization_mode(), Status::Ok);
    assert_eq!(plant.exit_initialization_mode(), Status::Ok);
    let m0 = measure(&mut plant, 0.0);
    let (mut unit, mut cmd) =
        EmtUnit::initialize(&params, &m0, &GAINS).unwrap_or_else(|e| panic!("{}: {e}", case.name));
    let init = (m0, cmd.clone());
    let mut steps = Vec::with_capacity(n);
    for k in 0..n {
        let t = k as f64 * H;
        command(&mut plant, &cmd);
        let m = measure(&mut plant, t);
        let next = unit
            .step(&m, &GAINS, H)
            .unwrap_or_else(|e| panic!("{}: t = {t}: {e}", case.name));
        assert_eq!(
            plant.do_step(t, H),
            Status::Ok,
            "{}: plant at {t}",
            case.name
        );
        steps.push((m, H, next.clone()));
        cmd = next;
    }
    (init, steps)
}

fn path(case: &Case) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("conformance")
        .join(format!("{}.txt", case.name))
}

/// The unit's commands for a trajectory's inputs: initialization, then every step.
fn replay(t: &Trajectory, params: &EmtParams) -> ([f64; N_OUT], Vec<[f64; N_OUT]>) {
    let (mut unit, c0) = EmtUnit::initialize(params, &t.init_measurement(), &t.gains)
        .unwrap_or_else(|e| panic!("{}: initialize: {e}", t.case));
    let steps = (1..=t.steps.len())
        .map(|k| {
            let c = unit
                .step(&t.measurement(k), &t.gains, t.steps[k - 1].h)
                .unwrap_or_else(|e| panic!("{}: step {k}: {e}", t.case));
            c.outputs()
        })
        .collect();
    (c0.outputs(), steps)
}

/// Regenerate a case's trajectory: the closed loop run for `CHECKED` steps must be stable (the
/// swing of its power over the last 0.5 s less than half of that over the 0.5 s after the
/// disturbance), its first `RECORDED` steps are the trajectory.
fn bless(case: &Case) {
    let (init, steps) = closed_loop(case, CHECKED);
    let swing = |from: usize| {
        let w = &steps[from..from + 10000];
        let mean = w.iter().map(|s| s.2.p).sum::<f64>() / w.len() as f64;
        w.iter().map(|s| (s.2.p - mean).abs()).fold(0.0, f64::max)
    };
    let (first, last) = (swing((T_EVENT / H) as usize), swing(CHECKED - 10000));
    println!(
        "{}: blessed; p swings by {first:.2e} pu over the 0.5 s after the disturbance, {last:.2e} over the last 0.5 s",
        case.name
    );
    assert!(
        last < 0.5 * first,
        "{}: not stable: p swings by {first} pu after the disturbance and {last} pu {} s later",
        case.name,
        CHECKED as f64 * H - 0.5
    );
    let t = Trajectory::record(
        case.name,
        &case.comments(),
        case.params().named(),
        GAINS,
        (&init.0, &init.1),
        &steps[..RECORDED],
    );
    std::fs::write(path(case), t.to_text()).expect("write the trajectory");
}

fn load(case: &Case) -> Trajectory {
    let p = path(case);
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| {
        panic!(
            "{}: {e} (DVPP_BLESS=1 cargo test -p dvpp-controllers --test conformance writes it)",
            p.display()
        )
    });
    Trajectory::parse(&text).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn trajectories_replay_through_the_unit_bit_for_bit() {
    let blessing = std::env::var_os("DVPP_BLESS").is_some_and(|v| v == "1");
    let only = std::env::var("DVPP_CASE").ok();
    for case in CASES
        .iter()
        .filter(|c| only.as_deref().is_none_or(|o| o == c.name))
    {
        if blessing {
            bless(case);
        }
        let t = load(case);
        assert_eq!(t.case, case.name);
        assert_eq!(
            t.params,
            case.params().named(),
            "{}: the file's parameters are not the case's",
            case.name
        );
        assert_eq!(t.steps.len(), RECORDED);
        let (init, steps) = replay(&t, &case.params());
        if let Err(m) = t.compare(&init, &steps) {
            panic!("{m}");
        }
        // The case exercises the unit: its disturbance moves p and q.
        let at = |name: &str| OUTPUTS.iter().position(|o| *o == name).unwrap();
        let moved = |j: usize| {
            steps
                .iter()
                .map(|o| (o[j] - init[j]).abs())
                .fold(0.0, f64::max)
        };
        let (dp, dq) = (moved(at("p")), moved(at("q")));
        println!(
            "{}: {} steps bit for bit; largest |p - p0| {dp:.2e}, |q - q0| {dq:.2e} pu",
            case.name, RECORDED
        );
        assert!(
            dp > 1e-3 || dq > 1e-3,
            "{}: the disturbance did not move the unit",
            case.name
        );
    }
}

/// A replay that differs is reported at its first differing step, with the output.
#[test]
fn a_differing_replay_names_the_step_and_the_output() {
    let case = &CASES[0];
    let t = load(case);
    let (init, mut steps) = replay(&t, &case.params());
    for (k, j) in [(3, 7), (700, 9), (RECORDED - 1, 0)] {
        let saved = steps[k - 1][j];
        steps[k - 1][j] = f64::from_bits(saved.to_bits() ^ 1);
        let m = t.compare(&init, &steps).expect_err("one bit flipped");
        assert_eq!(m.step, k);
        assert!(m.signals.contains(&OUTPUTS[j].to_string()), "{m}");
        println!("{m}");
        steps[k - 1][j] = saved;
    }
    let mut bad = init;
    bad[11] += 1e-12;
    let m = t.compare(&bad, &steps).expect_err("init differs");
    assert_eq!((m.step, m.signals.as_slice()), (0, &["E".to_string()][..]));
    assert!(t.compare(&init, &steps).is_ok());
}

/// The text format reads back what it wrote.
#[test]
fn a_trajectory_reads_back_as_written() {
    let t = load(&CASES[2]);
    assert_eq!(Trajectory::parse(&t.to_text()), Ok(t));
}

/// The unit's state saved mid-run (serialized, as an FMU state is) and restored continues bit
/// for bit as the unit that was not saved.
#[test]
fn the_unit_saved_and_restored_continues_bit_for_bit() {
    let case = &CASES[3];
    let t = load(case);
    let (mut unit, _) =
        EmtUnit::initialize(&case.params(), &t.init_measurement(), &t.gains).expect("initialize");
    for k in 1..=1000 {
        unit.step(&t.measurement(k), &t.gains, H).expect("step");
    }
    let bytes = postcard::to_stdvec(&unit).expect("serialize");
    let mut restored: EmtUnit = postcard::from_bytes(&bytes).expect("deserialize");
    let mut cloned = unit.clone();
    for k in 1001..=t.steps.len() {
        let want = unit.step(&t.measurement(k), &t.gains, H).expect("step");
        for other in [&mut restored, &mut cloned] {
            let got = other.step(&t.measurement(k), &t.gains, H).expect("step");
            assert_eq!(
                got.outputs().map(f64::to_bits),
                want.outputs().map(f64::to_bits),
                "step {k}"
            );
        }
    }
}

/// Parameters are refused with the FMU's name of the one at fault.
#[test]
fn parameters_are_refused_by_name() {
    let m = load(&CASES[0]).init_measurement();
    let refused = |change: &dyn Fn(&mut EmtParams)| {
        let mut p = unit_params(Mode::GridForming, InnerKind::OptionA);
        change(&mut p);
        EmtUnit::initialize(&p, &m, &GAINS)
            .map(drop)
            .expect_err("refused")
            .to_string()
    };
    assert_eq!(refused(&|p| p.filter.l_f = 0.0), "'L_f' = 0: must be > 0");
    assert_eq!(
        refused(&|p| p.inner.i_max = -1.0),
        "'I_max' = -1: must be > 0"
    );
    assert_eq!(
        refused(&|p| {
            p.adpf_p.kind = AdpfKind::LowPass;
            p.adpf_p.tau = 0.0;
        }),
        "'adpf.p.tau' = 0: must be > 0"
    );
    assert!(refused(&|p| p.tdes.d = 0.0).starts_with("'Tdes.D' = 0"));
    assert!(refused(&|p| p.pll.tau = f64::NAN).starts_with("'pll.tau' = NaN"));
    assert!(refused(&|p| {
        p.mode = Mode::GridFollowing;
        p.inner_kind = InnerKind::OptionB;
    })
    .starts_with("'inner.kind' = 1 (option B"));
    assert_eq!(
        InnerKind::from_code(2).unwrap_err().to_string(),
        "'inner.kind' = 2: must be 0 or 1"
    );
    // A measurement of no voltage: the unit starts from a running converter.
    let mut dead = m;
    dead.v_c = Abc::default();
    let e = EmtUnit::initialize(
        &unit_params(Mode::GridForming, InnerKind::OptionA),
        &dead,
        &GAINS,
    )
    .map(drop)
    .expect_err("no voltage");
    assert_eq!(e.field, None);
    assert!(e.message.contains("capacitor voltage"), "{e}");
}

/// `retune` takes the tunable parameters (the inner loops are redesigned at the next step, with
/// an event) and keeps the fixed ones; a design of no bandwidth is refused by name.
#[test]
fn retune_takes_the_tunable_parameters_only() {
    let t = load(&CASES[0]);
    let p = unit_params(Mode::GridForming, InnerKind::OptionA);
    let (mut unit, _) = EmtUnit::initialize(&p, &t.init_measurement(), &t.gains).expect("init");
    let mut new = p;
    new.inner.current_hz = 600.0;
    new.filter.r_f = 0.5;
    new.source.deload = 0.5;
    unit.retune(&new).expect("retune");
    assert_eq!(unit.params().inner.current_hz, 600.0);
    assert_eq!(unit.params().source.deload, 0.5);
    assert_eq!(unit.params().filter.r_f, p.filter.r_f, "R_f is fixed");
    let c = unit.step(&t.measurement(1), &t.gains, H).expect("step");
    assert!(
        matches!(c.notices.as_slice(), [dvpp_controllers::Notice::Event(e)] if e.contains("retuned")),
        "{:?}",
        c.notices
    );
    let c = unit.step(&t.measurement(2), &t.gains, H).expect("step");
    assert!(c.notices.is_empty());
    new.inner.voltage_hz = 0.0;
    assert_eq!(
        unit.retune(&new).unwrap_err().to_string(),
        "'inner.voltage_hz' = 0: must be > 0"
    );
}

/// `limit.source` is what any host sees: the converter draws more power from its dc side than
/// the primary source can deliver. On the weak grid the load step takes the unit's power up (by
/// 0.12 pu of its rating beyond the range below); with an availability just above its dispatch
/// (0.34 pu on S_base, 0.567 of its rating, against 0.5 exported plus the link's 0.05 of losses)
/// the flag is off before the step and on wherever the power exported and the link's losses
/// alone exceed the range; with the default availability (1 pu of its rating) it never rises.
#[test]
fn limit_source_flags_power_the_source_cannot_deliver() {
    let case = &CASES[1];
    assert_eq!(case.grid, Grid::Weak);
    let mut tight = case.params();
    tight.source.p_avail0 = 0.34;
    let to_rated = tight.rating.s_base / tight.rating.s_rated;
    let (_, steps) = closed_loop_with(case, &tight, 2000);
    let event = (T_EVENT / H).round() as usize;
    assert!(
        steps[..event].iter().all(|(_, _, c)| !c.limit_source),
        "the flag before the load step, where the unit draws less than the source has"
    );
    let beyond: Vec<_> = steps[event..]
        .iter()
        .filter(|(m, _, c)| c.p * to_rated + tight.dc.g_dc * m.v_dc * m.v_dc > c.p_src_max + 0.05)
        .collect();
    assert!(
        !beyond.is_empty(),
        "the load step should carry the exported power beyond the source's range"
    );
    assert!(
        beyond.iter().all(|(_, _, c)| c.limit_source),
        "the flag must be on wherever the power exported and the link's losses alone exceed the source's range by 0.05 pu"
    );
    let (_, steps) = closed_loop(case, 2000);
    assert!(
        steps.iter().all(|(_, _, c)| !c.limit_source),
        "with 1 pu of its rating available the source is never short"
    );
}
