//! `cargo xtask qualify`: the grid-forming qualification suite (the grid codes' published tests on each preset unit alone and on case study I's DVPP, at EMT level in our master with the EMT plant's test bench), judged from measurements against each criterion's bound or the subject's own reference model, with a self-contained HTML report and the matrix of docs/qualification.md.
//!
//! Subjects: each preset unit (wind 46 MVA, PV 73 MVA, BESS 60 MVA) alone on the plant's
//! Thevenin source (`studies/scenarios/qualify_<unit>.toml`: a DVPP of one on its own rating,
//! `S_dvpp = S_rated`, static ADPFs of dc gain 1, so its reference model is `T_i = T_des/m_i`
//! with `m_i = 1` on its rating), and case study I's DVPP (`emt_thevenin`, option B
//! `emt_thevenin_hinf`: three units and the operator, judged at the PCC against `T_des` on
//! `S_dvpp` = 96 MVA), each grid-forming with option A and B and grid-following where the test
//! applies. The grid is the plant's stiff Thevenin source at SCR 3 on the subject's rating
//! (X/R 10) unless the test says otherwise; every event at [`T_EVENT`], every run to [`T_END`].

use crate::ride_through::{at, file_name, set, stopped, Control};
use dvpp_cosim::master::{self, Options, Record, Scheme};
use dvpp_cosim::ssp::{self, Value};
use dvpp_cosim::table::csv_field;
use dvpp_cosim::Table;
use dvpp_report::plot::{Figure, Panel, Style};
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::Path;

/// When the event starts and when a run ends, s.
pub const T_EVENT: f64 = 1.0;
pub const T_END: f64 = 3.5;
/// The short-circuit ratio on the subject's rating (ERCOT's phase-jump test is at SCR 3).
pub const SCR: f64 = 3.0;
/// The SCR step: from `SCR_STEP.0` to `SCR_STEP.1` (AEMO's SCR step down with a fault).
pub const SCR_STEP: (f64, f64) = (10.0, 2.0);
/// Synchronism kept: the subject's frequency within this of the grid's over the last `TAIL` s, Hz.
pub const SYNC_HZ: f64 = 0.05;
pub const TAIL: f64 = 0.5;
/// How far a phase current may pass `I_max` (fraction): the current loop's tracking error at a
/// fault's edges (the ride-through test's tolerance, docs/emt-unit.md §6).
pub const I_TOLERANCE: f64 = 0.05;
/// ERCOT: at least this active power (pu of the rating) for a 10° phase jump at SCR 3.
pub const JUMP_POWER: f64 = 0.2;
/// ERCOT: an inertia constant of at least this (s, on the rating) where configured inertial.
pub const H_MIN: f64 = 2.5;
/// Fast fault current: reactive current at least `K_FFC (Δv - 0.1)` pu of the rated current, at
/// most 1 pu asked (VDE-AR-N 4120's default k-factor 2 and dead band 0.1; GB ECP.A.3.9 asks for
/// fast fault current without a number).
pub const K_FFC: f64 = 2.0;
/// The reactive current may fall short of the k-factor's by this (pu of the rated current:
/// VDE-AR-N 4120's tolerance band, -10 %).
pub const FFC_TOLERANCE: f64 = 0.1;
/// Post-fault swing: damping ratio at least this (ours: the sources ask for positive damping
/// without a number); swings below `SWING_FLOOR` (pu of the rating) are not counted.
pub const ZETA_MIN: f64 = 0.1;
pub const SWING_FLOOR: f64 = 0.01;
/// The swing is read from this long after the clearing (s): the first 100 ms are the
/// current loops' and the voltage's recovery, not the swing of the frames.
pub const SWING_AFTER: f64 = 0.1;
/// Loss of the grid: the PCC voltage within this band over the last `TAIL` s (pu).
pub const ISLAND_V: (f64, f64) = (0.9, 1.1);

/// The units' current limit (pu of their rated peak current: the FMU's default `I_max`).
const I_MAX: f64 = 1.2;
const S_BASE: f64 = 100.0;
const F_NOM: f64 = 50.0;
/// The DVPP's `T_des` (case study I, every scenario of the suite): `T_pf = 1/(H s + D)`,
/// `T_qv = Dq` rolled off by `τ_q` (pu on `S_dvpp`).
pub const TDES_H: f64 = 5.55;
pub const TDES_D: f64 = 33.33;
pub const TDES_DQ: f64 = 0.01;
pub const TDES_TAU_Q: f64 = 0.01;
/// Dips and faults last this long; a frequency ramp of the ride-through this long, s.
const DURATION: f64 = 0.15;
const RAMP: f64 = 0.4;
/// The inertia test's energy is counted this long after the ramp (s): the grid-forming frame
/// follows the grid with a lag of about 0.1 s and delivers part of the energy after the ramp.
pub const ENERGY_AFTER: f64 = 1.0;
/// A subject whose power moves by more than this before the event (pu of the rating) is
/// flagged as not steady before it.
pub const UNSTEADY: f64 = 0.02;
/// The ERCOT inertia test's ramp: 1 Hz/s for 0.5 s (falling: the subject delivers energy).
const ROCOF1: (f64, f64) = (-1.0, 0.5);
/// The voltage magnitude step of the source, pu.
const V_STEP: f64 = -0.05;
/// A fault's impedance per phase, pu of the subject's rating (R = X; for the DVPP 0.01 pu on
/// `S_base`, as the ride-through study's).
const Z_FAULT: f64 = 0.0096;
/// Loss of the grid: the local load and the dispatch before (pu of the rating).
const ISLAND_LOAD: f64 = 0.4;
const ISLAND_DISCHARGING: f64 = 0.6;
const ISLAND_DISCHARGING_BESS: f64 = 0.8;
const ISLAND_CHARGING: f64 = -0.8;

/// Envelope tolerances (the tunnel around the reference model's response): half-width
/// `abs + rel·|expected| + widen·A·exp(-(t - t_event)/tau)`, `A` the expected response's largest
/// deviation: wide at the event, narrowing to `abs + rel·|expected|`.
#[derive(Debug, Clone, Copy)]
pub struct Tunnel {
    pub abs: f64,
    pub rel: f64,
    pub widen: f64,
    pub tau: f64,
}

/// The reactive response to the voltage step (pu of the rating): 0.02 + 10 %, widened by the
/// step's response over the matching PI's 0.5 s.
pub const TUNNEL_Q: Tunnel = Tunnel {
    abs: 0.02,
    rel: 0.1,
    widen: 1.0,
    tau: 0.5,
};
/// The island's frequency (pu of `f_nom`): 0.002 (0.1 Hz) + 10 %, widened by half the expected
/// deviation over 0.3 s.
pub const TUNNEL_F: Tunnel = Tunnel {
    abs: 0.002,
    rel: 0.1,
    widen: 0.5,
    tau: 0.3,
};
/// The island's frequency is judged from this long after the breaker opens (s): the PCC
/// voltage's angle jumps as the source's current stops, which any PLL reads as a spike of
/// frequency for a few tens of milliseconds.
pub const ISLAND_GRACE: f64 = 0.05;
/// The power through the 1 Hz/s ramp (pu of the rating), drawn with the inertia test.
pub const TUNNEL_P: Tunnel = Tunnel {
    abs: 0.02,
    rel: 0.1,
    widen: 0.5,
    tau: 0.2,
};

/// What is qualified: a preset unit alone, or the DVPP.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Subject {
    Wind,
    Pv,
    Bess,
    Dvpp,
}

impl Subject {
    pub const ALL: [Subject; 4] = [Subject::Wind, Subject::Pv, Subject::Bess, Subject::Dvpp];

    pub fn name(self) -> &'static str {
        match self {
            Subject::Wind => "wind",
            Subject::Pv => "PV",
            Subject::Bess => "BESS",
            Subject::Dvpp => "DVPP",
        }
    }

    /// Its rating, MVA (the DVPP's `S_dvpp`).
    pub fn rating(self) -> f64 {
        match self {
            Subject::Wind => 46.0,
            Subject::Pv => 73.0,
            Subject::Bess => 60.0,
            Subject::Dvpp => 96.0,
        }
    }

    /// The units (DER components) of its system, in the plant's order.
    pub fn units(self) -> &'static [&'static str] {
        match self {
            Subject::Wind => &["wind"],
            Subject::Pv => &["pv"],
            Subject::Bess => &["bess"],
            Subject::Dvpp => &["wind", "pv", "bess"],
        }
    }

    /// Its units' ratings, MVA (the weights of its frequency).
    fn unit_ratings(self) -> &'static [f64] {
        match self {
            Subject::Wind => &[46.0],
            Subject::Pv => &[73.0],
            Subject::Bess => &[60.0],
            Subject::Dvpp => &[46.0, 73.0, 60.0],
        }
    }

    /// The bundled system it runs on.
    pub fn system(self, control: Control) -> &'static str {
        match (self, control) {
            (Subject::Wind, _) => "qualify_wind",
            (Subject::Pv, _) => "qualify_pv",
            (Subject::Bess, _) => "qualify_bess",
            (Subject::Dvpp, Control::FormingB) => "emt_thevenin_hinf",
            (Subject::Dvpp, _) => "emt_thevenin",
        }
    }

    /// Its primary source can absorb power.
    fn storage(self) -> bool {
        self == Subject::Bess
    }
}

/// The short name of a control, for the matrix's columns.
pub fn control_short(c: Control) -> &'static str {
    match c {
        Control::FormingA => "A",
        Control::FormingB => "B",
        Control::Following => "GFL",
    }
}

/// One test of the suite.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Test {
    /// ERCOT: a 10° phase jump at SCR 3, at least 0.2 pu active power.
    Jump10,
    /// IEEE 2800-2022, MISO: a 25° phase jump ridden through (sign: direction).
    Jump25(f64),
    /// ERCOT: 1 Hz/s for 0.5 s, the energy delivered against the declared inertia.
    Rocof1,
    /// IEEE 2800-2022: 5 Hz/s ridden through, up and down (sign).
    Rocof5(f64),
    /// A voltage magnitude step of the source: the reactive response against `T_vq`.
    VoltageStep,
    /// A balanced dip to `retained` pu for 150 ms with fast fault current.
    Dip(f64),
    /// Unbalanced faults at the PCC for 150 ms: 2 phase a to ground, 3 phases b-c.
    Unbalanced(i64),
    /// AEMO: the SCR steps from 10 to 2 with a three-phase fault (the parallel line trips at
    /// the clearing).
    ScrStep,
    /// AEMO, ERCOT: loss of the last synchronous machine (the source's breaker opens), the
    /// subject charging or discharging before.
    Island { charging: bool },
    /// GB ECP.A.3.9 active damping: the post-fault swing's damping ratio (a three-phase fault).
    Damping,
}

impl Test {
    pub const ALL: [Test; 15] = [
        Test::Jump10,
        Test::Jump25(1.0),
        Test::Jump25(-1.0),
        Test::Rocof1,
        Test::Rocof5(1.0),
        Test::Rocof5(-1.0),
        Test::VoltageStep,
        Test::Dip(0.5),
        Test::Dip(0.1),
        Test::Unbalanced(2),
        Test::Unbalanced(3),
        Test::ScrStep,
        Test::Island { charging: false },
        Test::Island { charging: true },
        Test::Damping,
    ];

    /// Its name in the matrix.
    pub fn name(self) -> String {
        match self {
            Test::Jump10 => "1. phase jump +10°, SCR 3".into(),
            Test::Jump25(s) => format!("1. phase jump {}25°, SCR 3", sign(s)),
            Test::Rocof1 => "2. -1 Hz/s for 0.5 s (inertia)".into(),
            Test::Rocof5(s) => format!("2. {}5 Hz/s for {RAMP} s", sign(s)),
            Test::VoltageStep => format!("3. voltage step {V_STEP:+} pu"),
            Test::Dip(r) => format!("4. dip to {r} pu, 150 ms"),
            Test::Unbalanced(2) => "4. phase a to ground, 150 ms".into(),
            Test::Unbalanced(_) => "4. phases b-c, 150 ms".into(),
            Test::ScrStep => "5. SCR 10 → 2 with a fault".into(),
            Test::Island { charging: false } => "6. loss of the grid, discharging".into(),
            Test::Island { charging: true } => "6. loss of the grid, charging".into(),
            Test::Damping => "7. post-fault swing damping".into(),
        }
    }

    /// A short identifier (anchors, file names).
    pub fn id(self) -> String {
        match self {
            Test::Jump10 => "jump10".into(),
            Test::Jump25(s) => format!("jump25{}", if s > 0.0 { "up" } else { "down" }),
            Test::Rocof1 => "rocof1".into(),
            Test::Rocof5(s) => format!("rocof5{}", if s > 0.0 { "up" } else { "down" }),
            Test::VoltageStep => "vstep".into(),
            Test::Dip(r) => format!("dip{}", (r * 10.0) as i64),
            Test::Unbalanced(2) => "slg".into(),
            Test::Unbalanced(_) => "ll".into(),
            Test::ScrStep => "scrstep".into(),
            Test::Island { charging } => {
                format!(
                    "island{}",
                    if charging { "charging" } else { "discharging" }
                )
            }
            Test::Damping => "damping".into(),
        }
    }

    /// Where its criterion comes from.
    pub fn source(self) -> &'static str {
        match self {
            Test::Jump10 => "ERCOT advanced grid support (NOGRR 245): at least 0.2 pu active power for a 10° phase jump at SCR 3",
            Test::Jump25(_) => "IEEE 2800-2022 §7.3.2.4 and MISO: ride through a 25° phase angle jump",
            Test::Rocof1 => "ERCOT advanced grid support: the energy delivered through a 1 Hz/s event lasting 0.5 s; an inertia constant of at least 2.5 s",
            Test::Rocof5(_) => "IEEE 2800-2022 §7.3.2.5: ride through 5 Hz/s",
            Test::VoltageStep => "RTE's envelope method (no number in the sources): the reactive response against the subject's own reference T_vq",
            Test::Dip(_) | Test::Unbalanced(_) => "GB ECP.A.3.9 and IEEE 2800-2022: fault ride-through with fast fault current (k-factor 2 and dead band 0.1 from VDE-AR-N 4120)",
            Test::ScrStep => "AEMO's core grid-forming tests: SCR step down with a fault",
            Test::Island { .. } => "AEMO's core grid-forming tests and ERCOT: loss of the last synchronous machine, charging and discharging",
            Test::Damping => "GB ECP.A.3.9 active damping (positive damping, no number: ours ζ ≥ 0.1)",
        }
    }

    /// Its criterion, as judged.
    pub fn criterion(self) -> String {
        match self {
            Test::Jump10 => format!("largest |Δp| in the first 100 ms ≥ {JUMP_POWER} pu of the rating, and synchronism kept"),
            Test::Jump25(_) | Test::Rocof5(_) | Test::ScrStep => format!(
                "the run completes and the subject's frequency is within {SYNC_HZ} Hz of the grid's over the last {TAIL} s"
            ),
            Test::Rocof1 => format!(
                "H = (E - D a (T²/2 + T·{ENERGY_AFTER} s))/(2 a T) ≥ {H_MIN} s: E the energy delivered from the ramp's start to {ENERGY_AFTER} s after its end (pu·s of the rating; the frame follows the grid with a lag, so part of the inertial energy comes after the ramp; the figure in brackets counts the ramp alone), a = 1 Hz/s / f_nom, T = 0.5 s, D = T_des's droop; T_des declares H = {:.3} s",
                TDES_H / 2.0
            ),
            Test::VoltageStep => format!(
                "Δq within the tunnel around the reference -T_vq Δv (T_vq = 1/(Dq (τ_q s + 1)), Δv the PCC voltage's measured deviation), tolerance {}",
                tunnel_text(TUNNEL_Q)
            ),
            Test::Dip(_) => format!(
                "rides through, and the mean reactive current from 50 ms to the clearing ≥ min({K_FFC} (Δv - 0.1), 1) - {FFC_TOLERANCE} pu of the rated current (Δv the PCC voltage's drop)"
            ),
            Test::Unbalanced(_) => format!(
                "rides through, and every phase's converter current ≤ (1 + {I_TOLERANCE}) I_max"
            ),
            Test::Island { .. } => format!(
                "the run completes, the PCC voltage within {}-{} pu over the last {TAIL} s, and the PCC frequency (the plant's PLL, judged from {ISLAND_GRACE} s after the opening: the voltage's angle jumps as the source's current stops) within the tunnel around T_pf's response to the measured power change at the PCC (Δf = -Δp/(H s + D)), tolerance {}",
                ISLAND_V.0,
                ISLAND_V.1,
                tunnel_text(TUNNEL_F)
            ),
            Test::Damping => format!(
                "the active power's swing from {SWING_AFTER} s after clearing a 150 ms three-phase fault at SCR {SCR}: damping ratio from the decrement of successive half-cycle peaks ≥ {ZETA_MIN} (swings below {SWING_FLOOR} pu of the rating not counted: no swing)"
            ),
        }
    }

    /// Whether the test applies to `subject` under `control`: the grid-forming criteria
    /// (the 10° jump's power, the inertia, the voltage-step envelope, the island) not to
    /// grid-following; charging only to storage; the DVPP's island discharging only.
    pub fn applies(self, subject: Subject, control: Control) -> bool {
        let forming = control != Control::Following;
        match self {
            Test::Jump10 | Test::Rocof1 | Test::VoltageStep => forming,
            Test::Island { charging } => forming && (!charging || subject.storage()),
            _ => true,
        }
    }

    /// When the event is over (s).
    fn end(self) -> f64 {
        match self {
            Test::Dip(_) | Test::Unbalanced(_) | Test::ScrStep | Test::Damping => {
                T_EVENT + DURATION
            }
            Test::Rocof1 => T_EVENT + ROCOF1.1,
            Test::Rocof5(_) => T_EVENT + RAMP,
            _ => T_EVENT,
        }
    }

    fn has_grid_at_end(self) -> bool {
        !matches!(self, Test::Island { .. })
    }
}

fn sign(s: f64) -> &'static str {
    if s > 0.0 {
        "+"
    } else {
        "-"
    }
}

fn tunnel_text(t: Tunnel) -> String {
    format!(
        "±({} + {}·|expected| + {}·A·exp(-(t - {T_EVENT} s)/{} s)), A the expected response's largest deviation",
        t.abs, t.rel, t.widen, t.tau
    )
}

/// One run.
#[derive(Debug, Clone, Copy)]
pub struct Job {
    pub subject: Subject,
    pub control: Control,
    pub test: Test,
}

impl Job {
    pub fn name(&self) -> String {
        format!(
            "{}, {}, {}",
            self.test.name(),
            self.subject.name(),
            self.control.name()
        )
    }
}

/// Every run of the suite: each test on each subject and control where it applies.
pub fn jobs() -> Vec<Job> {
    let mut out = Vec::new();
    for test in Test::ALL {
        for subject in Subject::ALL {
            for control in Control::ALL {
                if test.applies(subject, control) {
                    out.push(Job {
                        subject,
                        control,
                        test,
                    });
                }
            }
        }
    }
    out
}

/// Traces every 1 ms, for the figures and the envelopes.
#[derive(Debug, Clone, Default)]
pub struct Traces {
    pub t: Vec<f64>,
    /// The subject's active and reactive power (pu of its rating) and the PCC voltage (pu).
    pub p: Vec<f64>,
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    /// The grid's frequency, the PCC's (the plant's PLL) and each unit's, Hz.
    pub f_grid: Vec<f64>,
    pub f_pcc: Vec<f64>,
    pub f_units: Vec<Vec<f64>>,
    /// The subject's frequency: its unit's (grid-forming: the frame's), for the DVPP the
    /// rating-weighted mean of its units' (the centre of inertia), Hz.
    pub f_subject: Vec<f64>,
    /// The largest converter current of any unit per phase over each millisecond, of `I_max`.
    pub i_phase: [Vec<f64>; 3],
}

/// What one run measured (NaN where not measured).
#[derive(Debug, Clone)]
pub struct Row {
    pub job: Job,
    /// Why the run stopped, if it did.
    pub error: Option<String>,
    /// The largest unit's frequency offset from the grid's over the last `TAIL` s, Hz.
    pub sync_hz: f64,
    /// The largest converter current per phase of any unit, of `I_max`.
    pub i_peak: [f64; 3],
    /// Before the event (mean over the last 100 ms): active, reactive power (pu of the
    /// rating), PCC voltage.
    pub p0: f64,
    pub q0: f64,
    pub v0: f64,
    /// The largest |p - p0| in the first 100 ms after the event.
    pub dp_100ms: f64,
    /// The energy delivered above `p0` from the event to `ENERGY_AFTER` s after its end, and
    /// over the event alone (pu·s of the rating).
    pub energy: f64,
    pub energy_event: f64,
    /// The largest |p - p0| from 0.2 s to the event: a subject not steady before the event.
    pub unsteady: f64,
    /// While the voltage is held down (50 ms after the event to the clearing): mean reactive
    /// current and PCC voltage drop.
    pub i_reactive: f64,
    pub dv: f64,
    /// The PCC voltage's range over the last `TAIL` s.
    pub v_tail: (f64, f64),
    pub traces: Traces,
}

/// The source's impedance (R, X on `S_base`) for `scr` on `rating`, X/R 10.
fn impedance(scr: f64, rating: f64) -> (f64, f64) {
    let z = S_BASE / (scr * rating);
    let k = 101f64.sqrt();
    (z / k, 10.0 * z / k)
}

/// The plant's start values for the event of `test` on `subject`.
fn event_values(test: Test, subject: Subject) -> Vec<(String, Value)> {
    let r = |x: f64| Value::Real(x);
    let zf = Z_FAULT * S_BASE / subject.rating();
    let fault = |kind: i64| {
        vec![
            ("fault.type".to_string(), Value::Integer(kind)),
            ("fault.location".into(), Value::Integer(1)),
            ("fault.R".into(), r(zf)),
            ("fault.X".into(), r(zf)),
            ("fault.t".into(), r(T_EVENT)),
            ("fault.duration".into(), r(DURATION)),
        ]
    };
    match test {
        Test::Jump10 => vec![
            ("thevenin.jump".into(), r(10f64.to_radians())),
            ("thevenin.jump_t".into(), r(T_EVENT)),
        ],
        Test::Jump25(s) => vec![
            ("thevenin.jump".into(), r((25.0 * s).to_radians())),
            ("thevenin.jump_t".into(), r(T_EVENT)),
        ],
        Test::Rocof1 => vec![
            ("thevenin.rocof".into(), r(ROCOF1.0)),
            ("thevenin.rocof_t".into(), r(T_EVENT)),
            ("thevenin.rocof_duration".into(), r(ROCOF1.1)),
        ],
        Test::Rocof5(s) => vec![
            ("thevenin.rocof".into(), r(5.0 * s)),
            ("thevenin.rocof_t".into(), r(T_EVENT)),
            ("thevenin.rocof_duration".into(), r(RAMP)),
        ],
        Test::VoltageStep => vec![
            ("thevenin.step".into(), r(V_STEP)),
            ("thevenin.step_t".into(), r(T_EVENT)),
        ],
        Test::Dip(retained) => vec![
            ("thevenin.dip".into(), r(1.0 - retained)),
            ("thevenin.dip_t".into(), r(T_EVENT)),
            ("thevenin.dip_duration".into(), r(DURATION)),
        ],
        Test::Unbalanced(kind) => fault(kind),
        Test::Damping => fault(1),
        Test::ScrStep => {
            let (rp, xp) = impedance(SCR_STEP.0 - SCR_STEP.1, subject.rating());
            let mut v = fault(1);
            v.extend([
                ("parallel.R".to_string(), r(rp)),
                ("parallel.X".into(), r(xp)),
                ("parallel.t_on".into(), r(0.0)),
                ("parallel.t_off".into(), r(T_EVENT + DURATION)),
            ]);
            v
        }
        Test::Island { .. } => vec![("thevenin.t_open".into(), r(T_EVENT))],
    }
}

/// The system of `job` from its bundled base.
pub fn prepare(base: &ssp::Package, job: &Job) -> Result<ssp::Package, String> {
    let mut pkg = base.with_system(base.system.clone());
    let s = job.subject;
    let scr = if job.test == Test::ScrStep {
        SCR_STEP.1
    } else {
        SCR
    };
    let (r, x) = impedance(scr, s.rating());
    let mut plant: Vec<(String, Value)> = vec![
        ("thevenin.H".into(), Value::Real(0.0)),
        ("thevenin.D".into(), Value::Real(0.0)),
        ("thevenin.R".into(), Value::Real(r)),
        ("thevenin.X".into(), Value::Real(x)),
    ];
    if s == Subject::Dvpp {
        // emt_thevenin's 28 MW step stays off; its base load stays on (the island's load).
        plant.push(("load[2].enabled".into(), Value::Boolean(false)));
    } else if let Test::Island { charging } = job.test {
        let dispatch = match (charging, s) {
            (true, _) => ISLAND_CHARGING,
            (false, Subject::Bess) => ISLAND_DISCHARGING_BESS,
            (false, _) => ISLAND_DISCHARGING,
        };
        // The source's voltage for a PCC at 1 pu before the event: the grid takes
        // `P + jQ` (the unit's dispatch less the load, on S_base) at `V` = 1, so
        // `E = V - (R + jX) (P - jQ)`.
        let k = s.rating() / S_BASE;
        let (pg, qg) = ((dispatch - ISLAND_LOAD) * k, -0.1 * ISLAND_LOAD * k);
        let e = dvpp_math::hypot(1.0 - r * pg - x * qg, r * qg - x * pg);
        plant.push(("load[1].enabled".into(), Value::Boolean(true)));
        plant.push(("der[1].p0".into(), Value::Real(dispatch * k)));
        plant.push(("thevenin.E".into(), Value::Real(e)));
    }
    plant.extend(event_values(job.test, s));
    for (name, value) in plant {
        set(&mut pkg, "plant", &name, value)?;
    }
    for u in s.units() {
        match job.control {
            Control::FormingA => {}
            Control::FormingB => set(&mut pkg, u, "inner.kind", Value::Integer(1))?,
            Control::Following => {
                set(&mut pkg, u, "mode", Value::Integer(2))?;
                set(&mut pkg, u, "vq.tau", Value::Real(2.0))?;
            }
        }
    }
    Ok(pkg)
}

fn record(subject: Subject) -> Record {
    let mut patterns = vec![
        "plant.der[*].i_a".to_string(),
        "plant.der[*].i_b".into(),
        "plant.der[*].i_c".into(),
        "plant.der[*].p".into(),
        "plant.der[*].q".into(),
        "plant.pcc.v".into(),
        "plant.pcc.df".into(),
        "plant.thevenin.f".into(),
    ];
    patterns.extend(subject.units().iter().map(|u| format!("{u}.df")));
    Record {
        patterns: Some(patterns),
        interval: None,
    }
}

fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len().max(1) as f64
}

/// The measurements of one run from its recorded table.
pub fn measure(job: Job, table: Result<Table, String>) -> Row {
    let mut row = Row {
        job,
        error: None,
        sync_hz: f64::NAN,
        i_peak: [f64::NAN; 3],
        p0: f64::NAN,
        q0: f64::NAN,
        v0: f64::NAN,
        dp_100ms: f64::NAN,
        energy: f64::NAN,
        energy_event: f64::NAN,
        unsteady: f64::NAN,
        i_reactive: f64::NAN,
        dv: f64::NAN,
        v_tail: (f64::NAN, f64::NAN),
        traces: Traces::default(),
    };
    let s = job.subject;
    let measured = table.and_then(|t| {
        let col = |n: &str| t.column(n).ok_or(format!("no column {n}"));
        let time = col("time")?;
        let n = time.len();
        if n < 2 || time[n - 1] < T_END - 1e-6 {
            return Err(format!(
                "the run ended at {:.4} s",
                time.last().copied().unwrap_or(0.0)
            ));
        }
        let to_rating = S_BASE / s.rating();
        let f_grid: Vec<f64> = col("plant.thevenin.f")?.iter().map(|f| f * F_NOM).collect();
        let f_pcc: Vec<f64> = col("plant.pcc.df")?
            .iter()
            .map(|d| (1.0 + d) * F_NOM)
            .collect();
        let v = col("plant.pcc.v")?;
        let (mut p, mut q) = (vec![0.0; n], vec![0.0; n]);
        let mut f_units = Vec::new();
        let mut i_abs: [Vec<f64>; 3] = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        for (k, u) in s.units().iter().enumerate() {
            let df = col(&format!("{u}.df"))?;
            f_units.push(df.iter().map(|d| (1.0 + d) * F_NOM).collect::<Vec<_>>());
            for (ph, name) in ["a", "b", "c"].iter().enumerate() {
                let i = col(&format!("plant.der[{}].i_{name}", k + 1))?;
                for (m, x) in i_abs[ph].iter_mut().zip(&i) {
                    *m = m.max(x.abs() / I_MAX);
                }
            }
            for (sum, name) in [(&mut p, "p"), (&mut q, "q")] {
                for (acc, x) in sum
                    .iter_mut()
                    .zip(col(&format!("plant.der[{}].{name}", k + 1))?)
                {
                    *acc += x * to_rating;
                }
            }
        }
        let weights = s.unit_ratings();
        let total: f64 = weights.iter().sum();
        let f_subject: Vec<f64> = (0..n)
            .map(|k| {
                f_units
                    .iter()
                    .zip(weights)
                    .map(|(f, w)| f[k] * w)
                    .sum::<f64>()
                    / total
            })
            .collect();
        for (peak, abs) in row.i_peak.iter_mut().zip(&i_abs) {
            *peak = abs.iter().fold(0.0, |m: f64, x| m.max(*x));
        }
        let (pre, ev) = (at(&time, T_EVENT - 0.1), at(&time, T_EVENT));
        row.p0 = mean(&p[pre..ev]);
        row.q0 = mean(&q[pre..ev]);
        row.v0 = mean(&v[pre..ev]);
        let e100 = at(&time, T_EVENT + 0.1);
        row.dp_100ms = (ev..e100)
            .map(|k| (p[k] - row.p0).abs())
            .fold(0.0, f64::max);
        let end = at(&time, job.test.end());
        let dt = time[1] - time[0];
        let energy = |to: usize| {
            (ev..to.max(ev + 1))
                .map(|k| (p[k] - row.p0) * dt)
                .sum::<f64>()
        };
        row.energy_event = energy(end);
        row.energy = energy(at(&time, job.test.end() + ENERGY_AFTER));
        row.unsteady = (at(&time, 0.2)..ev)
            .map(|k| (p[k] - row.p0).abs())
            .fold(0.0, f64::max);
        if matches!(
            job.test,
            Test::Dip(_) | Test::Unbalanced(_) | Test::ScrStep | Test::Damping
        ) {
            let a = at(&time, T_EVENT + 0.05);
            let m = (end - a).max(1) as f64;
            row.i_reactive = (a..end).map(|k| q[k] / v[k].max(1e-3)).sum::<f64>() / m;
            row.dv = row.v0 - (a..end).map(|k| v[k]).sum::<f64>() / m;
        }
        let tail = at(&time, T_END - TAIL);
        row.v_tail = (
            v[tail..].iter().copied().fold(f64::INFINITY, f64::min),
            v[tail..].iter().copied().fold(f64::NEG_INFINITY, f64::max),
        );
        row.sync_hz = f_units
            .iter()
            .map(|f| {
                (tail..n)
                    .map(|k| (f[k] - f_grid[k]).abs())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        let every = at(&time, 1e-3).max(1);
        let pick = |x: &[f64]| x.iter().step_by(every).copied().collect::<Vec<_>>();
        let window_max = |x: &[f64]| {
            x.chunks(every)
                .map(|c| c.iter().copied().fold(0.0, f64::max))
                .collect::<Vec<_>>()
        };
        row.traces = Traces {
            t: pick(&time),
            p: pick(&p),
            q: pick(&q),
            v: pick(&v),
            f_grid: pick(&f_grid),
            f_pcc: pick(&f_pcc),
            f_units: f_units.iter().map(|f| pick(f)).collect(),
            f_subject: pick(&f_subject),
            i_phase: [
                window_max(&i_abs[0]),
                window_max(&i_abs[1]),
                window_max(&i_abs[2]),
            ],
        };
        Ok(())
    });
    row.error = measured.err();
    row
}

/// The expected response and the measured one against it, over the traces after the event.
#[derive(Debug, Clone, Default)]
pub struct Envelope {
    pub t: Vec<f64>,
    pub measured: Vec<f64>,
    pub expected: Vec<f64>,
    pub lo: Vec<f64>,
    pub hi: Vec<f64>,
    /// The largest `|measured - expected|` over the tunnel's half-width (≤ 1: inside).
    pub excursion: f64,
}

/// The envelope from the event on; samples within `grace` s of the event are drawn, not judged.
fn envelope(t: &[f64], measured: &[f64], expected: &[f64], tunnel: Tunnel, grace: f64) -> Envelope {
    let from = at(t, T_EVENT);
    let amplitude = expected[from..].iter().fold(0.0_f64, |m, e| m.max(e.abs()));
    let mut env = Envelope::default();
    for ((&tk, &m), &e) in t.iter().zip(measured).zip(expected).skip(from) {
        let w = tunnel.abs
            + tunnel.rel * e.abs()
            + tunnel.widen * amplitude * dvpp_math::exp(-(tk - T_EVENT) / tunnel.tau);
        env.t.push(tk);
        env.measured.push(m);
        env.expected.push(e);
        env.lo.push(e - w);
        env.hi.push(e + w);
        if tk >= T_EVENT + grace - 1e-9 {
            env.excursion = env.excursion.max((m - e).abs() / w);
        }
    }
    env
}

/// The subject's reference model's response in the envelope tests (deviations from before
/// the event, pu of the rating or of `f_nom`): the measured deviation and the expected one.
pub fn reference(row: &Row) -> Option<Envelope> {
    let tr = &row.traces;
    if tr.t.len() < 2 || row.error.is_some() {
        return None;
    }
    let dt = tr.t[1] - tr.t[0];
    let ev = at(&tr.t, T_EVENT);
    match row.job.test {
        Test::VoltageStep => {
            // q = q0 - T_vq Δv, T_vq = 1/(Dq (τ_q s + 1)).
            let mut lag = 0.0;
            let expected: Vec<f64> =
                tr.v.iter()
                    .map(|v| {
                        lag += (v - row.v0 - lag) * dt / TDES_TAU_Q.max(dt);
                        -lag / TDES_DQ
                    })
                    .collect();
            let measured: Vec<f64> = tr.q.iter().map(|q| q - row.q0).collect();
            Some(envelope(&tr.t, &measured, &expected, TUNNEL_Q, 0.0))
        }
        Test::Island { .. } => {
            // H dΔf/dt + D Δf = -Δp (pu of S_dvpp = the rating), from the event on.
            let f0 = mean(&tr.f_pcc[at(&tr.t, T_EVENT - 0.1)..ev]);
            let mut df = 0.0;
            let expected: Vec<f64> = (0..tr.t.len())
                .map(|k| {
                    let out = df;
                    if k >= ev {
                        df += dt / TDES_H * (-(tr.p[k] - row.p0) - TDES_D * df);
                    }
                    out
                })
                .collect();
            let measured: Vec<f64> = tr.f_pcc.iter().map(|f| (f - f0) / F_NOM).collect();
            Some(envelope(
                &tr.t,
                &measured,
                &expected,
                TUNNEL_F,
                ISLAND_GRACE,
            ))
        }
        Test::Rocof1 => {
            // Δp = -(H d/dt + D) Δf_grid.
            let fg: Vec<f64> = tr.f_grid.iter().map(|f| f / F_NOM - 1.0).collect();
            let expected: Vec<f64> = (0..fg.len())
                .map(|k| {
                    let d = if k == 0 {
                        0.0
                    } else {
                        (fg[k] - fg[k - 1]) / dt
                    };
                    -(TDES_H * d + TDES_D * fg[k])
                })
                .collect();
            let measured: Vec<f64> = tr.p.iter().map(|p| p - row.p0).collect();
            Some(envelope(&tr.t, &measured, &expected, TUNNEL_P, 0.0))
        }
        _ => None,
    }
}

/// The post-fault swing of the active power: damping ratio and frequency from the peaks of
/// successive half-cycles (the signal's deviation from its mean over the last 0.3 s, through a
/// 10 ms moving average, split at its zero crossings); `None` when fewer than two half-cycles
/// reach `SWING_FLOOR` (no swing to speak of).
pub fn swing(row: &Row) -> Option<(f64, f64)> {
    let tr = &row.traces;
    if tr.t.len() < 20 {
        return None;
    }
    let from = at(&tr.t, T_EVENT + DURATION + SWING_AFTER);
    let last = at(&tr.t, T_END - 0.3);
    let p_end = mean(&tr.p[last..]);
    let x: Vec<f64> = (from..tr.t.len())
        .map(|k| {
            let a = k.saturating_sub(9).max(from);
            mean(&tr.p[a..=k]) - p_end
        })
        .collect();
    let mut peaks: Vec<(f64, f64)> = Vec::new();
    let mut best = (0.0_f64, 0.0_f64);
    for (j, &xj) in x.iter().enumerate() {
        if j > 0 && (xj > 0.0) != (x[j - 1] > 0.0) {
            peaks.push(best);
            best = (0.0, 0.0);
        }
        if xj.abs() > best.0 {
            best = (xj.abs(), tr.t[from + j]);
        }
    }
    let peaks: Vec<(f64, f64)> = peaks.into_iter().filter(|p| p.0 >= SWING_FLOOR).collect();
    if peaks.len() < 2 {
        return None;
    }
    let pairs = (peaks.len() - 1).min(3);
    let delta = 2.0
        * (0..pairs)
            .map(|k| dvpp_math::log(peaks[k].0 / peaks[k + 1].0))
            .sum::<f64>()
        / pairs as f64;
    let half = (peaks[pairs].1 - peaks[0].1) / pairs as f64;
    let zeta = delta / (4.0 * PI * PI + delta * delta).sqrt();
    Some((zeta, 1.0 / (2.0 * half)))
}

/// The inertia constant the energy through the 1 Hz/s ramp shows (s, on the rating): the
/// energy of `Δp = (2H d/dt + D) Δf` for a ramp `Δf = -a t` over `T`, then held at `-a T`,
/// counted to `W = T + ENERGY_AFTER`: `E = 2 H a T + D a (T²/2 + T (W - T))`.
pub fn inertia(row: &Row) -> f64 {
    let (a, t) = (-ROCOF1.0 / F_NOM, ROCOF1.1);
    (row.energy - TDES_D * a * (t * t / 2.0 + t * ENERGY_AFTER)) / (2.0 * a * t)
}

/// The same over the ramp alone (`W = T`).
pub fn inertia_over_ramp(row: &Row) -> f64 {
    let (a, t) = (-ROCOF1.0 / F_NOM, ROCOF1.1);
    (row.energy_event - TDES_D * a * t * t / 2.0) / (2.0 * a * t)
}

/// One cell of the matrix: the verdict, the measured figure and its bound.
#[derive(Debug, Clone)]
pub struct Cell {
    pub pass: bool,
    /// The measured figure judged, and the bound it is judged against, as text.
    pub figure: String,
    pub bound: String,
    /// What made it fail, when it did.
    pub why: String,
}

impl Cell {
    /// The matrix's text: `pass` or `fail`, then the figure.
    pub fn text(&self) -> String {
        format!(
            "{} {}",
            if self.pass { "pass" } else { "fail" },
            self.figure
        )
    }
}

/// The design limit a failure of `job` is known to come from (docs/qualification.md, "Why
/// cells fail"), if its class has one: the report names it beside the failure.
pub fn known_limit(job: &Job) -> Option<&'static str> {
    match (job.test, job.control, job.subject) {
        (Test::Rocof1, _, _) => Some(
            "T_des declares H/2 = 2.78 s, 11 % above the bound, and the response lags the reference by about 40 ms (the frame's synchronization), which the energy method counts against the inertia (D τ/2 ≈ 0.7 s)",
        ),
        (Test::Rocof5(_) | Test::Jump25(_), Control::FormingB, _) => Some(
            "option B's current-limited mode does not keep synchronism through it (the ride-through study's open cases, docs/emt-unit.md §6)",
        ),
        (Test::Rocof5(_), Control::FormingA, Subject::Dvpp) => Some(
            "T_des asks the DVPP beyond I_max through -5 Hz/s at SCR 3 (the ride-through study's open case, docs/emt-unit.md §6)",
        ),
        (Test::Rocof5(s), Control::Following, _) if s > 0.0 => Some(
            "a grid-following unit carrying T_des alone is driven to zero active current at +5 Hz/s and loses synchronism (docs/emt.md §9, not fixed)",
        ),
        _ => None,
    }
}

/// The verdict of one run, from its measurements.
pub fn judge(row: &Row) -> Cell {
    let test = row.job.test;
    if let Some(e) = &row.error {
        return Cell {
            pass: false,
            figure: "(stopped)".into(),
            bound: "the run completes".into(),
            why: stopped(e),
        };
    }
    let synced = !test.has_grid_at_end() || row.sync_hz <= SYNC_HZ;
    let lost = format!(
        "{:.3} Hz from the grid over the last {TAIL} s (synchronism lost)",
        row.sync_hz
    );
    let unsteady = if row.unsteady > UNSTEADY {
        format!(
            " (not steady before the event: p moves by {:.2} pu from 0.2 s on)",
            row.unsteady
        )
    } else {
        String::new()
    };
    let cell = |pass: bool, figure: String, bound: String, why: String| Cell {
        pass,
        figure,
        bound,
        why: if pass {
            String::new()
        } else {
            let known =
                known_limit(&row.job).map_or(String::new(), |k| format!("; known limit: {k}"));
            why + &unsteady + &known
        },
    };
    match test {
        Test::Jump10 => {
            let ok = row.dp_100ms >= JUMP_POWER;
            cell(
                ok && synced,
                format!("{:.2} pu", row.dp_100ms),
                format!("≥ {JUMP_POWER} pu"),
                if ok {
                    lost
                } else {
                    "too little active power".into()
                },
            )
        }
        Test::Jump25(_) | Test::Rocof5(_) | Test::ScrStep => cell(
            synced,
            format!("{:.3} Hz", row.sync_hz),
            format!("≤ {SYNC_HZ} Hz"),
            lost,
        ),
        Test::Rocof1 => {
            let h = inertia(row);
            let ok = h >= H_MIN;
            cell(
                ok && synced,
                format!("H {h:.2} s ({:.2} over the ramp)", inertia_over_ramp(row)),
                format!("≥ {H_MIN} s"),
                if ok {
                    lost
                } else {
                    format!(
                        "energy {:.4} pu·s against T_des's {:.4}",
                        row.energy,
                        expected_energy()
                    )
                },
            )
        }
        Test::VoltageStep | Test::Island { .. } => {
            let Some(env) = reference(row) else {
                return cell(false, "-".into(), "".into(), "no traces".into());
            };
            let inside = env.excursion <= 1.0;
            let v_ok = matches!(test, Test::VoltageStep)
                || (row.v_tail.0 >= ISLAND_V.0 && row.v_tail.1 <= ISLAND_V.1);
            cell(
                inside && v_ok && synced,
                format!("{:.2} of the tunnel", env.excursion),
                "≤ 1".into(),
                if !inside {
                    "leaves the reference model's tunnel".into()
                } else if !v_ok {
                    format!(
                        "PCC voltage {:.3}-{:.3} pu at the end",
                        row.v_tail.0, row.v_tail.1
                    )
                } else {
                    lost
                },
            )
        }
        Test::Dip(_) => {
            let need = (K_FFC * (row.dv - 0.1)).clamp(0.0, 1.0) - FFC_TOLERANCE;
            let ok = row.i_reactive >= need;
            cell(
                ok && synced,
                format!("i_q {:.2} pu", row.i_reactive),
                format!("≥ {need:.2} pu (Δv {:.2})", row.dv),
                if ok {
                    lost
                } else {
                    "too little reactive current".into()
                },
            )
        }
        Test::Unbalanced(_) => {
            let worst = row.i_peak.iter().copied().fold(0.0, f64::max);
            let ok = worst <= 1.0 + I_TOLERANCE;
            cell(
                ok && synced,
                format!(
                    "{:.2}/{:.2}/{:.2} I_max",
                    row.i_peak[0], row.i_peak[1], row.i_peak[2]
                ),
                format!("≤ {:.2} I_max per phase", 1.0 + I_TOLERANCE),
                if ok {
                    lost
                } else {
                    "phase current beyond the limit".into()
                },
            )
        }
        Test::Damping => match swing(row) {
            None => cell(synced, "no swing".into(), format!("ζ ≥ {ZETA_MIN}"), lost),
            Some((zeta, f)) => cell(
                zeta >= ZETA_MIN && synced,
                format!("ζ {zeta:.2} at {f:.2} Hz"),
                format!("ζ ≥ {ZETA_MIN}"),
                if zeta >= ZETA_MIN {
                    lost
                } else {
                    "poorly damped swing".into()
                },
            ),
        },
    }
}

/// The energy `T_des` delivers through the 1 Hz/s ramp and `ENERGY_AFTER` s after it, pu·s
/// of the rating.
pub fn expected_energy() -> f64 {
    let (a, t) = (-ROCOF1.0 / F_NOM, ROCOF1.1);
    TDES_H * a * t + TDES_D * a * (t * t / 2.0 + t * ENERGY_AFTER)
}

/// Run `jobs` on `workers` threads with progress, from the bundled systems under `root/dist/`;
/// rows in job order.
pub fn run_all(root: &Path, jobs: Vec<Job>, workers: usize) -> Result<Vec<Row>, String> {
    let mut names: Vec<&str> = jobs.iter().map(|j| j.subject.system(j.control)).collect();
    names.sort_unstable();
    names.dedup();
    let mut bases = Vec::new();
    for name in names {
        let path = root.join("dist").join(name).join(format!("{name}.ssp"));
        bases.push((
            name,
            ssp::read(&path)
                .map_err(|e| format!("{}: {e} (run `cargo xtask bundle`)", path.display()))?,
        ));
    }
    crate::parallel::in_order("qualify", jobs, workers, 10, |job: Job| {
        let name = job.subject.system(job.control);
        let base = &bases.iter().find(|b| b.0 == name).expect("read above").1;
        let opts = Options {
            stop: Some(T_END),
            step: None,
            algorithm: Scheme::Jacobi,
        };
        let table = prepare(base, &job).and_then(|pkg| {
            master::System::builder(&pkg)
                .load()
                .and_then(|mut s| {
                    s.quiet();
                    s.simulate_recording(&opts, record(job.subject))
                })
                .map_err(|e| e.to_string())
        });
        measure(job, table)
    })
}

/// The matrix's columns: each subject under each control.
pub fn columns() -> Vec<(Subject, Control)> {
    Subject::ALL
        .iter()
        .flat_map(|&s| Control::ALL.iter().map(move |&c| (s, c)))
        .collect()
}

/// The summary matrix as Markdown: a row per test, a column per subject and control; each
/// cell `pass` or `fail` and the figure, `n/a` where the test does not apply, `-` where it
/// was not run.
pub fn matrix(rows: &[Row]) -> String {
    let cols = columns();
    let mut out = String::from("| test |");
    for (s, c) in &cols {
        let _ = write!(out, " {} {} |", s.name(), control_short(*c));
    }
    out.push_str("\n|---|");
    out.push_str(&"---|".repeat(cols.len()));
    out.push('\n');
    for test in Test::ALL {
        if !rows.iter().any(|r| r.job.test == test) {
            continue;
        }
        let _ = write!(out, "| {} |", test.name());
        for &(s, c) in &cols {
            let text = if !test.applies(s, c) {
                "n/a".to_string()
            } else {
                rows.iter()
                    .find(|r| r.job.test == test && r.job.subject == s && r.job.control == c)
                    .map_or("-".into(), |r| judge(r).text())
            };
            let _ = write!(out, " {text} |");
        }
        out.push('\n');
    }
    out
}

/// The failures, one line each: the run, the figure against its bound and why.
pub fn failures(rows: &[Row]) -> Vec<String> {
    rows.iter()
        .filter_map(|r| {
            let c = judge(r);
            (!c.pass).then(|| format!("{}: {} ({}): {}", r.job.name(), c.figure, c.bound, c.why))
        })
        .collect()
}

fn write_csv(path: &Path, rows: &[Row]) -> Result<(), String> {
    let mut text = String::from(
        "test,subject,control,verdict,figure,bound,why,sync_Hz,i_peak_a,i_peak_b,i_peak_c,p0,q0,v0,dp_100ms,energy,energy_event,unsteady,i_reactive,dv,error\n",
    );
    for r in rows {
        let c = judge(r);
        let _ = writeln!(
            text,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            csv_field(&r.job.test.name()),
            r.job.subject.name(),
            csv_field(r.job.control.name()),
            if c.pass { "pass" } else { "fail" },
            csv_field(&c.figure),
            csv_field(&c.bound),
            csv_field(&c.why),
            r.sync_hz,
            r.i_peak[0],
            r.i_peak[1],
            r.i_peak[2],
            r.p0,
            r.q0,
            r.v0,
            r.dp_100ms,
            r.energy,
            r.energy_event,
            r.unsteady,
            r.i_reactive,
            r.dv,
            csv_field(r.error.as_deref().unwrap_or(""))
        );
    }
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))
}

const STYLES: [Style; 3] = [Style::Solid, Style::Dashed, Style::Dotted];

/// The figure of one test: a panel per subject with each control's trace; for the envelope
/// tests a panel per subject and grid-forming option with the measured response, the expected
/// one and the tunnel.
pub fn figure(test: Test, rows: &[Row]) -> Figure {
    let mine: Vec<&Row> = rows
        .iter()
        .filter(|r| r.job.test == test && !r.traces.t.is_empty())
        .collect();
    let mut fig = Figure::new(format!("{}: {}", test.name(), test.criterion_short()));
    let envelope_test = matches!(test, Test::VoltageStep | Test::Island { .. } | Test::Rocof1);
    if envelope_test {
        let (what, unit) = match test {
            Test::VoltageStep => ("Δq", "pu of the rating"),
            Test::Rocof1 => ("Δp", "pu of the rating"),
            _ => ("Δf", "pu of f_nom"),
        };
        for r in &mine {
            let Some(env) = reference(r) else { continue };
            let panel = Panel::new(
                format!("{}, {}", r.job.subject.name(), r.job.control.name()),
                "t (s)",
                format!("{what} ({unit})"),
            )
            .series("measured", &env.t, &env.measured, Style::Solid)
            .series("reference model", &env.t, &env.expected, Style::Dashed)
            .series("tunnel", &env.t, &env.lo, Style::Dotted)
            .series("", &env.t, &env.hi, Style::Dotted);
            fig = fig.panel(panel);
        }
        return fig.columns(2);
    }
    for subject in Subject::ALL {
        let (y_label, pick): (&str, fn(&Traces) -> Vec<f64>) = match test {
            Test::Jump10 | Test::Jump25(_) | Test::Damping | Test::ScrStep => {
                ("p (pu of the rating)", |tr| tr.p.clone())
            }
            Test::Rocof5(_) => ("f - f_grid (Hz)", |tr| {
                (0..tr.t.len())
                    .map(|k| {
                        tr.f_units
                            .iter()
                            .map(|f| f[k] - tr.f_grid[k])
                            .fold(0.0, |m: f64, d| if d.abs() > m.abs() { d } else { m })
                    })
                    .collect()
            }),
            Test::Dip(_) => ("q (pu of the rating)", |tr| tr.q.clone()),
            Test::Unbalanced(_) => ("largest phase current (of I_max)", |tr| {
                (0..tr.i_phase[0].len())
                    .map(|k| tr.i_phase.iter().map(|i| i[k]).fold(0.0, f64::max))
                    .collect()
            }),
            _ => ("p (pu of the rating)", |tr| tr.p.clone()),
        };
        let mut panel = Panel::new(subject.name(), "t (s)", y_label);
        for (control, style) in Control::ALL.iter().zip(STYLES) {
            if let Some(r) = mine
                .iter()
                .find(|r| r.job.subject == subject && r.job.control == *control)
            {
                let y = pick(&r.traces);
                let n = y.len().min(r.traces.t.len());
                panel = panel.series(control.name(), &r.traces.t[..n], &y[..n], style);
            }
        }
        fig = fig.panel(panel);
    }
    fig.columns(2)
}

impl Test {
    fn criterion_short(self) -> &'static str {
        match self {
            Test::Jump10 => "active power after the jump",
            Test::Jump25(_) | Test::ScrStep => "active power through the event",
            Test::Rocof1 => "power against T_des's (H s + D) Δf_grid",
            Test::Rocof5(_) => "frequency against the grid's",
            Test::VoltageStep => "reactive response against T_vq",
            Test::Dip(_) => "reactive power through the dip",
            Test::Unbalanced(_) => "phase currents",
            Test::Island { .. } => "frequency against T_pf",
            Test::Damping => "post-fault swing",
        }
    }
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The versions the report names: the workspace's version and the git commit it was run from.
fn versions(root: &Path) -> String {
    let commit = std::process::Command::new("git")
        .arg("-C")
        .arg(root)
        .args(["describe", "--always", "--dirty"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
        .unwrap_or_else(|| "unknown".into());
    format!(
        "dvpp-studies {} at commit {commit}; FMUs from dist/ (cargo xtask bundle)",
        env!("CARGO_PKG_VERSION")
    )
}

/// The self-contained HTML report: the matrix, then a section per test with its figure,
/// criterion, source and the verdict of each run; the versions and parameters.
pub fn html(rows: &[Row], versions: &str, wall: f64) -> String {
    let mut h = String::from(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>Grid-forming qualification</title>\n<style>\nbody{font-family:DejaVu Sans,Arial,sans-serif;margin:1.5em;color:#222;max-width:1400px}\ntable{border-collapse:collapse;font-size:12px}\ntd,th{border:1px solid #bbb;padding:3px 5px;vertical-align:top}\ntd.pass{background:#e3f4e3}td.fail{background:#f8dede}td.na{color:#999}\nfigure{margin:1em 0}svg{max-width:100%;height:auto}\n</style>\n</head>\n<body>\n<h1>Grid-forming qualification suite</h1>\n",
    );
    let _ = writeln!(
        h,
        "<p>Each preset unit alone on its own rating and case study I's DVPP at the PCC, at EMT level in our master with the EMT plant's test bench (<code>cargo xtask qualify</code>). {} runs, {wall:.0} s wall time. Each cell begins with <b>pass</b> or <b>fail</b>, then the measured figure; n/a: the test does not apply (a grid-forming criterion, or charging without storage).</p>",
        rows.len()
    );
    h.push_str("<h2 id=\"matrix\">Summary matrix</h2>\n<table>\n<tr><th>test</th>");
    let cols = columns();
    for (s, c) in &cols {
        let _ = write!(h, "<th>{} {}</th>", s.name(), control_short(*c));
    }
    h.push_str("</tr>\n");
    for test in Test::ALL {
        if !rows.iter().any(|r| r.job.test == test) {
            continue;
        }
        let _ = write!(
            h,
            "<tr><td><a href=\"#{}\">{}</a></td>",
            test.id(),
            esc(&test.name())
        );
        for &(s, c) in &cols {
            if !test.applies(s, c) {
                h.push_str("<td class=\"na\">n/a</td>");
                continue;
            }
            match rows
                .iter()
                .find(|r| r.job.test == test && r.job.subject == s && r.job.control == c)
            {
                Some(r) => {
                    let cell = judge(r);
                    let _ = write!(
                        h,
                        "<td class=\"{}\" title=\"{}\">{}</td>",
                        if cell.pass { "pass" } else { "fail" },
                        esc(&format!("{} {}", cell.bound, cell.why)),
                        esc(&cell.text())
                    );
                }
                None => h.push_str("<td class=\"na\">-</td>"),
            }
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
    let failed = failures(rows);
    let _ = writeln!(
        h,
        "<h2 id=\"failures\">Failures</h2>\n<p>{} of {} cells fail; each with its measured figure, its bound and why (a known limit of the design where one is known; docs/qualification.md, \"Why cells fail\").</p>\n<ul>",
        failed.len(),
        rows.len()
    );
    for f in &failed {
        let _ = writeln!(h, "<li>{}</li>", esc(f));
    }
    h.push_str("</ul>\n");
    for test in Test::ALL {
        let mine: Vec<&Row> = rows.iter().filter(|r| r.job.test == test).collect();
        if mine.is_empty() {
            continue;
        }
        let _ = writeln!(
            h,
            "<section id=\"{}\">\n<h2>{}</h2>\n<p><b>Criterion:</b> {}</p>\n<p><b>Source:</b> {}</p>",
            test.id(),
            esc(&test.name()),
            esc(&test.criterion()),
            esc(test.source())
        );
        let _ = writeln!(h, "<figure>\n{}\n</figure>", figure(test, rows).to_svg());
        h.push_str("<table>\n<tr><th>subject</th><th>control</th><th>verdict</th><th>figure</th><th>bound</th><th>why it fails</th></tr>\n");
        for r in mine {
            let c = judge(r);
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td>{}</td><td class=\"{}\">{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                r.job.subject.name(),
                r.job.control.name(),
                if c.pass { "pass" } else { "fail" },
                if c.pass { "pass" } else { "fail" },
                esc(&c.figure),
                esc(&c.bound),
                esc(&c.why)
            );
        }
        h.push_str("</table>\n</section>\n");
    }
    let _ = writeln!(
        h,
        "<h2 id=\"parameters\">Versions and parameters</h2>\n<p>{}</p>\n<ul>\n<li>T_des (case study I): T_pf = 1/(H s + D), H = {TDES_H} (an inertia constant H/2 = {:.3} s in the swing equation's sense), D = {TDES_D}; T_qv = Dq = {TDES_DQ}, τ_q = {TDES_TAU_Q} s; pu on the subject's rating (a unit alone is a DVPP of one, S_dvpp = S_rated, static ADPFs of gain 1; the DVPP on S_dvpp = 96 MVA with its operator)</li>\n<li>grid: the plant's Thevenin source, stiff, SCR {SCR} on the subject's rating (X/R 10); SCR step {} → {} by a parallel line tripped at the clearing</li>\n<li>events at {T_EVENT} s, runs to {T_END} s at 50 µs (Jacobi); dips and faults {DURATION} s (faults R = X = {Z_FAULT} pu of the rating per phase at the PCC, cleared pole by pole at current zero); 5 Hz/s for {RAMP} s; 1 Hz/s for {} s; voltage step {V_STEP} pu</li>\n<li>loss of the grid: the source's breaker opens with a local load of {ISLAND_LOAD} pu of the rating (power factor 0.995), the source's voltage set for a PCC at 1 pu before, the unit dispatched at {ISLAND_DISCHARGING} pu (BESS {ISLAND_DISCHARGING_BESS}) discharging, {ISLAND_CHARGING} pu charging; the DVPP with emt_thevenin's base load</li>\n<li>grid-following: mode 2, vq.tau 2 s on every unit; option B: inner.kind 1; I_max {I_MAX} pu</li>\n<li>tunnels: voltage step {}; island {}; 1 Hz/s (drawn) {}</li>\n</ul>\n</body>\n</html>",
        esc(versions),
        TDES_H / 2.0,
        SCR_STEP.0,
        SCR_STEP.1,
        ROCOF1.1,
        esc(&tunnel_text(TUNNEL_Q)),
        esc(&tunnel_text(TUNNEL_F)),
        esc(&tunnel_text(TUNNEL_P)),
    );
    h
}

/// A run's traces (every 1 ms) as CSV.
fn write_traces(path: &Path, r: &Row) -> Result<(), String> {
    let tr = &r.traces;
    let mut text = String::from("t,p,q,v,f_grid,f_pcc,f_subject,i_a,i_b,i_c\n");
    for k in 0..tr.t.len().min(tr.i_phase[0].len()) {
        let _ = writeln!(
            text,
            "{},{},{},{},{},{},{},{},{},{}",
            tr.t[k],
            tr.p[k],
            tr.q[k],
            tr.v[k],
            tr.f_grid[k],
            tr.f_pcc[k],
            tr.f_subject[k],
            tr.i_phase[0][k],
            tr.i_phase[1][k],
            tr.i_phase[2][k]
        );
    }
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))
}

/// The tests whose figures go to tests/figures/ (`qualify_<id>.svg`) for the docs.
pub const ENVELOPE_FIGURES: [Test; 3] = [
    Test::VoltageStep,
    Test::Island { charging: false },
    Test::Rocof1,
];

/// `cargo xtask qualify [--only TEXT]`: every run on all cores, `results/qualification.html`,
/// `results/qualification.csv`, the envelope figures `tests/figures/qualify_<test>.svg` and the
/// matrix between `qualify:begin` and `qualify:end` in
/// docs/qualification.md; with `--only`, the runs whose name (test, subject, control) contains
/// TEXT, the matrix printed and each run's traces in `results/qualify/`.
pub fn qualify(root: &Path, args: &[String]) -> Result<(), String> {
    let (all, only) = crate::parallel::only("qualify", args, jobs(), Job::name)?;
    let workers = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!(
        "qualify: {} runs of {T_END} s at 50 µs on {workers} threads",
        all.len()
    );
    let started = std::time::Instant::now();
    let rows = run_all(root, all, workers)?;
    let wall = started.elapsed().as_secs_f64();
    let matrix = matrix(&rows);
    print!("{matrix}");
    for f in failures(&rows) {
        println!("fail: {f}");
    }
    println!("qualify: {} runs in {wall:.0} s", rows.len());
    let dir = root.join("results");
    if only.is_some() {
        let runs = dir.join("qualify");
        std::fs::create_dir_all(&runs).map_err(|e| format!("{}: {e}", runs.display()))?;
        for r in &rows {
            write_traces(&runs.join(format!("{}.csv", file_name(&r.job.name()))), r)?;
        }
        println!(
            "qualify: each run's traces (every 1 ms) in {}",
            runs.display()
        );
        return Ok(());
    }
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    write_csv(&dir.join("qualification.csv"), &rows)?;
    let page = dir.join("qualification.html");
    std::fs::write(&page, html(&rows, &versions(root), wall))
        .map_err(|e| format!("{}: {e}", page.display()))?;
    // The envelope tests' figures for docs/qualification.md (one per kind of envelope).
    for test in ENVELOPE_FIGURES {
        crate::sweep::save_figure(
            root,
            &figure(test, &rows),
            &format!("qualify_{}.svg", test.id()),
        )?;
    }
    crate::docs::update_between(
        root,
        "docs/qualification.md",
        "<!-- qualify:begin -->",
        "<!-- qualify:end -->",
        &matrix,
    )?;
    println!("qualify: results/qualification.html, results/qualification.csv, tests/figures/qualify_*.svg and the matrix in docs/qualification.md");
    Ok(())
}
