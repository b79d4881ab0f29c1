//! Phasor (RMS) dynamic simulation of the reduced grid.
//!
//! Network: complex bus admittance matrix in the frame rotating at `f_nom` (π lines, transformers,
//! shunts, constant-impedance loads, machine Norton admittances 1/(r_a + j x'_d), grid-forming
//! slot admittances). It is LU-factorized once and the factorization is reused until the topology
//! or a load changes. Sources enter as current injections. The saliency of two-axis machines
//! (x'_q ≠ x'_d) is solved exactly per network solution through a small real system in the
//! machines' q-axis currents (using the impedance columns of the machine buses, cached with the
//! factorization); grid-following injections and constant-power loads are handled by a
//! fixed-point iteration on the factorized network (tolerance 1e-12 pu on every bus voltage).
//!
//! Integration: classical fourth-order Runge–Kutta with a fixed internal step (≤ 1 ms, the
//! communication step is split into equal sub-steps), with a full algebraic network solve at every
//! stage. Events split the sub-steps so they fire exactly at their time.

use crate::case::{
    BranchData, Case, CaseError, DerKind, Event, Exciter, Governor, LoadModel, MachineModel,
    ParamBase,
};
use crate::powerflow::{self, PowerFlow, C64};
use nalgebra::DVector;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::fmt;

/// Largest internal integration step, s.
pub const MAX_INTERNAL_STEP: f64 = 1e-3;
/// Voltage below which constant-power loads turn into constant impedances, pu.
pub const CONST_POWER_V_MIN: f64 = 0.7;
const NET_TOL: f64 = 1e-12;
const NET_MAX_ITER: usize = 500;
const EVENT_EPS: f64 = 1e-9;
/// States reserved per machine: δ, ω, E'q, E'd, 3 governor, 3 exciter.
const NS_M: usize = 10;

/// Errors while building or running the grid.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum GridError {
    Case(CaseError),
    PowerFlowDiverged { iterations: usize, mismatch: f64 },
    Init(String),
    SingularNetwork,
    NetworkNotConverged { t: f64, residual: f64 },
    BadSlot { index: usize, reason: String },
    BadEvent { index: usize, reason: String },
    InvalidStep { t: f64, h: f64 },
    TimeMismatch { expected: f64, got: f64 },
    NonFinite { t: f64 },
}

impl fmt::Display for GridError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GridError::Case(e) => write!(f, "{e}"),
            GridError::PowerFlowDiverged {
                iterations,
                mismatch,
            } => write!(
                f,
                "power flow did not converge ({iterations} iterations, mismatch {mismatch:e} pu)"
            ),
            GridError::Init(m) => write!(f, "initialization failed: {m}"),
            GridError::SingularNetwork => write!(f, "network admittance matrix is singular"),
            GridError::NetworkNotConverged { t, residual } => {
                write!(
                    f,
                    "network solution did not converge at t = {t} s (residual {residual:e})"
                )
            }
            GridError::BadSlot { index, reason } => write!(f, "DER slot {index}: {reason}"),
            GridError::BadEvent { index, reason } => write!(f, "event {index}: {reason}"),
            GridError::InvalidStep { t, h } => write!(f, "invalid step t = {t}, h = {h}"),
            GridError::TimeMismatch { expected, got } => {
                write!(
                    f,
                    "step starts at t = {got} but the grid is at t = {expected}"
                )
            }
            GridError::NonFinite { t } => write!(f, "non-finite state at t = {t} s"),
        }
    }
}

impl std::error::Error for GridError {}

impl From<CaseError> for GridError {
    fn from(e: CaseError) -> Self {
        GridError::Case(e)
    }
}

/// Initial DER set points (what the DER controllers must hold for a flat start).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum DerSetpoint {
    /// Internal voltage angle (rad, frame at f_nom) and magnitude (pu).
    GridForming { theta0: f64, e0: f64 },
    /// Injected powers at the bus, pu on S_base.
    GridFollowing { p0: f64, q0: f64 },
}

/// Input of a DER slot.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum DerInput {
    GridForming { theta: f64, e: f64 },
    GridFollowing { p_ref: f64, q_ref: f64 },
}

/// Per-slot outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DerOutput {
    /// Active power injected into the bus, pu on S_base.
    pub p: f64,
    /// Reactive power injected into the bus, pu on S_base.
    pub q: f64,
    /// Voltage magnitude of the slot's bus, pu.
    pub v: f64,
    /// Voltage angle of the slot's bus, rad, frame at f_nom, continuous (unwrapped).
    pub v_angle: f64,
}

/// PCC outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PccOutput {
    /// Sum of the PCC slots' and branches' active injections, pu on S_base.
    pub p: f64,
    pub q: f64,
    /// PCC bus voltage magnitude, pu.
    pub v: f64,
    /// PCC frequency, pu (1 = f_nom): 1 + (1/ω_b) · s/(T_f s + 1) applied to the bus angle.
    pub f: f64,
    /// PCC bus angle, rad, continuous.
    pub angle: f64,
}

/// Per-machine outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MachineOutput {
    /// Rotor speed, pu.
    pub omega: f64,
    /// Electrical active power at the terminal, pu on S_base.
    pub p: f64,
    pub q: f64,
    /// Air-gap power, pu on S_base.
    pub pe: f64,
    /// Mechanical power, pu on S_base.
    pub pm: f64,
    /// Field voltage, pu.
    pub efd: f64,
    /// Rotor angle, rad, frame at f_nom.
    pub delta: f64,
    /// Terminal voltage, pu.
    pub vt: f64,
    pub in_service: bool,
}

/// All outputs at the current time.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Outputs {
    pub t: f64,
    pub der: Vec<DerOutput>,
    pub pcc: PccOutput,
    /// Inertia-weighted mean speed of the in-service machines, pu (PCC frequency if none).
    pub coi_f: f64,
    pub sg: Vec<MachineOutput>,
    /// Total generation: machine terminal powers + DER slot injections, pu on S_base.
    pub gen_p: f64,
    /// Total load: loads, event loads and shunt conductances, pu.
    pub load_p: f64,
    /// Series losses in lines and transformers, pu.
    pub loss_p: f64,
    /// gen_p − load_p − loss_p (zero up to the network tolerance).
    pub balance_p: f64,
}

/// Changes to a scheduled event (None keeps the case value).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EventOverride {
    pub enabled: Option<bool>,
    pub time: Option<f64>,
    /// Load steps only.
    pub dp_mw: Option<f64>,
    pub dq_mvar: Option<f64>,
}

/// A scheduled event and whether it has fired.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EventState {
    pub event: Event,
    pub enabled: bool,
    pub fired: bool,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
struct MachineRt {
    bus: usize,
    model: MachineModel,
    rating: f64,
    h: f64,
    d: f64,
    ra: f64,
    xd: f64,
    xd_p: f64,
    xq: f64,
    xq_p: f64,
    td0_p: f64,
    tq0_p: f64,
    governor: Option<Governor>,
    exciter: Option<Exciter>,
    /// Governor reference, machine base.
    pref: f64,
    /// Mechanical power without governor, system base.
    pm0: f64,
    /// Exciter voltage reference.
    vref: f64,
    /// Field voltage without exciter.
    efd0: f64,
    in_service: bool,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
struct DerRt {
    kind: DerKind,
    bus: usize,
    /// Series admittance on the system base (grid-forming).
    y: C64,
    input: DerInput,
    initial: DerSetpoint,
}

/// Algebraic machine quantities for one network solution.
#[derive(Clone, Copy, Debug, Default)]
struct MachAlg {
    id: f64,
    iq: f64,
    vd: f64,
    vq: f64,
}

/// The reduced-grid model.
///
/// `Serialize`/`Deserialize` go through [`GridSnapshot`]: the case as TOML text plus the
/// evolving state, so that the bytes are valid in binary formats (postcard) too; deserializing
/// rebuilds the static part from the case and restores the state bit for bit.
#[derive(Clone, Debug)]
pub struct Grid {
    case: Case,
    sb: f64,
    wb: f64,
    n: usize,
    branches: Vec<BranchData>,
    load_y: Vec<C64>,
    load_s: Vec<C64>,
    machines: Vec<MachineRt>,
    ders: Vec<DerRt>,
    pcc_bus: usize,
    pcc_slots: Vec<usize>,
    /// (branch index, measured at bus index).
    pcc_branches: Vec<(usize, usize)>,
    pcc_tf: f64,
    /// State vector: NS_M per machine, then the PCC angle-filter state.
    x: Vec<f64>,
    t: f64,
    v: Vec<C64>,
    der_angle: Vec<f64>,
    pcc_angle: f64,
    events: Vec<EventState>,
    pf: PowerFlow,
    h_max: f64,
    /// Factorized network; a cache, rebuilt on demand (not part of snapshots).
    net: Option<Network>,
    /// Work buffers of the network solves and the integrator; a cache (not part of snapshots).
    work: Work,
}

/// Work buffers reused by every network solve and RK4 stage, so that a step allocates nothing.
#[derive(Clone, Debug, Default)]
struct Work {
    /// Bus current injections and the bus voltages they give.
    cur: Vec<C64>,
    vn: Vec<C64>,
    /// Per machine in service: its saliency terms.
    sal: Vec<Sal>,
    /// `I - M` (row-major) and a copy the elimination consumes; the right-hand side.
    i_m: Vec<f64>,
    lu: Vec<f64>,
    rhs: Vec<f64>,
    /// Stator solution of every machine at the last solve.
    alg: Vec<MachAlg>,
    /// RK4 stages: start state and voltages, stage states and derivatives, stage voltages.
    x0: Vec<f64>,
    v0: Vec<C64>,
    xs: Vec<f64>,
    vs: Vec<C64>,
    k: [Vec<f64>; 4],
}

/// A machine's saliency terms in a network solve: its q-axis current is the affine function
/// `kd v_d + kq v_q + off` of its terminal voltage (in its rotor frame `rot`), and `c` is the
/// saliency injection per unit of that current.
#[derive(Clone, Copy, Debug)]
struct Sal {
    j: usize,
    bus: usize,
    rot: C64,
    kd: f64,
    kq: f64,
    off: f64,
    c: C64,
}

impl Sal {
    fn lin(&self, v: C64) -> f64 {
        let vdq = v * self.rot;
        self.kd * vdq.re + self.kq * vdq.im
    }
}

/// Solve the dense `n`×`n` row-major system `a x = b` in place (`b` becomes `x`) by Gaussian
/// elimination with partial pivoting; false if `a` is singular.
fn solve_dense(a: &mut [f64], b: &mut [f64], n: usize) -> bool {
    for c in 0..n {
        let p = (c..n)
            .max_by(|&i, &j| a[i * n + c].abs().total_cmp(&a[j * n + c].abs()))
            .unwrap_or(c);
        if a[p * n + c] == 0.0 || !a[p * n + c].is_finite() {
            return false;
        }
        if p != c {
            for k in 0..n {
                a.swap(p * n + k, c * n + k);
            }
            b.swap(p, c);
        }
        for r in c + 1..n {
            let f = a[r * n + c] / a[c * n + c];
            for k in c..n {
                a[r * n + k] -= f * a[c * n + k];
            }
            b[r] -= f * b[c];
        }
    }
    for c in (0..n).rev() {
        let mut x = b[c];
        for k in c + 1..n {
            x -= a[c * n + k] * b[k];
        }
        b[c] = x / a[c * n + c];
    }
    true
}

/// The factorized network admittance matrix and columns of its inverse `Z` (how the bus
/// voltages respond to a current injected at a bus): per machine in service at its bus, and per
/// source bus (a machine, a DER slot or a constant-power load), so that a solve is the sum of
/// a few columns instead of a full triangular solve.
#[derive(Clone, Debug)]
struct Network {
    z: Vec<Option<DVector<C64>>>,
    sources: Vec<(usize, DVector<C64>)>,
}

/// The serialized form of a [`Grid`]: the case (TOML text) and everything that evolves.
///
/// The case and event types use internally tagged enums (`type = "hygov"`), which only
/// self-describing formats can read back, so they travel as TOML text inside the snapshot.
#[derive(Serialize, Deserialize)]
struct GridSnapshot {
    case: String,
    /// The scheduled events, as TOML (`[[event]]` tables).
    events: String,
    /// (enabled, fired) per event.
    event_flags: Vec<(bool, bool)>,
    branch_in_service: Vec<bool>,
    machine_in_service: Vec<bool>,
    load_y: Vec<C64>,
    load_s: Vec<C64>,
    der_inputs: Vec<DerInput>,
    x: Vec<f64>,
    t: f64,
    v: Vec<C64>,
    der_angle: Vec<f64>,
    pcc_angle: f64,
    h_max: f64,
}

/// `[[event]]` tables of a snapshot.
#[derive(Serialize, Deserialize)]
struct EventList {
    #[serde(default)]
    event: Vec<Event>,
}

impl GridSnapshot {
    fn of(g: &Grid) -> Result<GridSnapshot, String> {
        let events = EventList {
            event: g.events.iter().map(|e| e.event.clone()).collect(),
        };
        Ok(GridSnapshot {
            case: toml::to_string(&g.case).map_err(|e| format!("case: {e}"))?,
            events: toml::to_string(&events).map_err(|e| format!("events: {e}"))?,
            event_flags: g.events.iter().map(|e| (e.enabled, e.fired)).collect(),
            branch_in_service: g.branches.iter().map(|b| b.in_service).collect(),
            machine_in_service: g.machines.iter().map(|m| m.in_service).collect(),
            load_y: g.load_y.clone(),
            load_s: g.load_s.clone(),
            der_inputs: g.ders.iter().map(|d| d.input).collect(),
            x: g.x.clone(),
            t: g.t,
            v: g.v.clone(),
            der_angle: g.der_angle.clone(),
            pcc_angle: g.pcc_angle,
            h_max: g.h_max,
        })
    }

    fn restore(self) -> Result<Grid, String> {
        let case = Case::from_toml_str(&self.case).map_err(|e| e.to_string())?;
        let mut g = Grid::new(&case).map_err(|e| e.to_string())?;
        let events: EventList = toml::from_str(&self.events).map_err(|e| e.to_string())?;
        let sizes = [
            (events.event.len(), self.event_flags.len(), "event flags"),
            (g.branches.len(), self.branch_in_service.len(), "branches"),
            (g.machines.len(), self.machine_in_service.len(), "machines"),
            (g.n, self.load_y.len(), "load admittances"),
            (g.n, self.load_s.len(), "load powers"),
            (g.n, self.v.len(), "bus voltages"),
            (g.ders.len(), self.der_inputs.len(), "DER inputs"),
            (g.ders.len(), self.der_angle.len(), "DER angles"),
            (g.x.len(), self.x.len(), "states"),
        ];
        for (want, got, what) in sizes {
            if want != got {
                return Err(format!("snapshot has {got} {what}, the case needs {want}"));
            }
        }
        g.events = events
            .event
            .into_iter()
            .zip(self.event_flags)
            .map(|(event, (enabled, fired))| EventState {
                event,
                enabled,
                fired,
            })
            .collect();
        for (b, s) in g.branches.iter_mut().zip(self.branch_in_service) {
            b.in_service = s;
        }
        for (m, s) in g.machines.iter_mut().zip(self.machine_in_service) {
            m.in_service = s;
        }
        for (k, input) in self.der_inputs.into_iter().enumerate() {
            g.set_der_input_deferred(k, input)
                .map_err(|e| e.to_string())?;
        }
        g.load_y = self.load_y;
        g.load_s = self.load_s;
        g.x = self.x;
        g.t = self.t;
        g.v = self.v;
        g.der_angle = self.der_angle;
        g.pcc_angle = self.pcc_angle;
        g.h_max = self.h_max;
        g.net = None;
        Ok(g)
    }
}

impl Serialize for Grid {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        GridSnapshot::of(self)
            .map_err(serde::ser::Error::custom)?
            .serialize(s)
    }
}

impl<'de> Deserialize<'de> for Grid {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Grid, D::Error> {
        GridSnapshot::deserialize(d)?
            .restore()
            .map_err(serde::de::Error::custom)
    }
}

fn wrap(a: f64) -> f64 {
    let mut a = a % (2.0 * PI);
    if a > PI {
        a -= 2.0 * PI;
    } else if a <= -PI {
        a += 2.0 * PI;
    }
    a
}

fn rot(delta: f64) -> C64 {
    // network -> dq: multiply by e^{-j(δ - π/2)}
    C64::from_polar(1.0, -(delta - PI / 2.0))
}

impl Grid {
    /// Power flow and consistent initialization of all dynamic states.
    pub fn new(case: &Case) -> Result<Grid, GridError> {
        case.validate()?;
        let pf = powerflow::solve(case, 1e-12, 40).map_err(|(iterations, mismatch)| {
            GridError::PowerFlowDiverged {
                iterations,
                mismatch,
            }
        })?;
        let sb = case.base_mva;
        let wb = 2.0 * PI * case.f_nom;
        let n = case.buses.len();
        let idx = case.bus_index();
        let branches = case.branches();
        let v = pf.v.clone();
        // loads
        let mut load_y = vec![C64::new(0.0, 0.0); n];
        let mut load_s = vec![C64::new(0.0, 0.0); n];
        for l in &case.loads {
            let i = idx[&l.bus];
            let s = C64::new(l.p_mw, l.q_mvar) / sb;
            match l.model {
                LoadModel::ConstantImpedance => load_y[i] += s.conj() / v[i].norm_sqr(),
                LoadModel::ConstantPower => load_s[i] += s,
            }
        }
        // machines
        let mut machines = Vec::new();
        let mut x = vec![0.0; NS_M * case.machines.len() + 1];
        for (j, m) in case.machines.iter().enumerate() {
            let zb = match m.base {
                ParamBase::System => 1.0,
                ParamBase::Machine => sb / m.rating_mva,
            };
            let hb = 1.0 / zb; // power-like quantities scale inversely
            let (xq, xq_p, td0_p, tq0_p) = match m.model {
                MachineModel::TwoAxis => (
                    m.xq.unwrap(),
                    m.xq_p.unwrap(),
                    m.td0_p.unwrap(),
                    m.tq0_p.unwrap(),
                ),
                MachineModel::Classical => (m.xd_p, m.xd_p, 1.0, 1.0),
            };
            let mut mr = MachineRt {
                bus: idx[&m.bus],
                model: m.model,
                rating: m.rating_mva,
                h: m.h * hb,
                d: m.d * hb,
                ra: m.ra * zb,
                xd: m.xd * zb,
                xd_p: m.xd_p * zb,
                xq: xq * zb,
                xq_p: xq_p * zb,
                td0_p,
                tq0_p,
                governor: m.governor.clone(),
                exciter: m.exciter.clone(),
                pref: 0.0,
                pm0: 0.0,
                vref: 0.0,
                efd0: 0.0,
                in_service: true,
            };
            let (p, q) = pf.machine_pq[j];
            let vt = v[mr.bus];
            let it = (C64::new(p, q) / vt).conj();
            let o = NS_M * j;
            // The machine's rotor axis lies along the voltage behind r_a + j x_q (two-axis) or
            // behind the transient reactance (classical); Park-transform terminal V and I to it.
            let x_axis = match m.model {
                MachineModel::TwoAxis => mr.xq,
                MachineModel::Classical => mr.xd_p,
            };
            let e_axis = vt + C64::new(mr.ra, x_axis) * it;
            let delta = e_axis.arg();
            let (vdq, idq) = (vt * rot(delta), it * rot(delta));
            let (vd, vq, id, iq) = (vdq.re, vdq.im, idq.re, idq.im);
            let (edp, eqp, efd) = match m.model {
                MachineModel::TwoAxis => {
                    let eqp = vq + mr.ra * iq + mr.xd_p * id;
                    (
                        vd + mr.ra * id - mr.xq_p * iq,
                        eqp,
                        eqp + (mr.xd - mr.xd_p) * id,
                    )
                }
                MachineModel::Classical => (0.0, e_axis.norm(), e_axis.norm()),
            };
            let pe = vd * id + vq * iq + mr.ra * (id * id + iq * iq);
            x[o] = delta;
            x[o + 1] = 1.0;
            x[o + 2] = eqp;
            x[o + 3] = edp;
            mr.pm0 = pe;
            mr.efd0 = efd;
            let pm_mach = pe * sb / mr.rating;
            let name = format!("machine {}", j + 1);
            match &mr.governor {
                Some(Governor::TgovReheat { p_max, p_min, .. }) => {
                    if pm_mach > *p_max || pm_mach < *p_min {
                        return Err(GridError::Init(format!(
                            "{name}: initial mechanical power {pm_mach:.4} pu outside governor limits"
                        )));
                    }
                    x[o + 4] = pm_mach;
                    x[o + 5] = pm_mach;
                    x[o + 6] = pm_mach;
                    mr.pref = pm_mach;
                }
                Some(Governor::Hygov { p_max, p_min, .. }) => {
                    if pm_mach > *p_max || pm_mach < *p_min {
                        return Err(GridError::Init(format!(
                            "{name}: initial gate {pm_mach:.4} pu outside governor limits"
                        )));
                    }
                    x[o + 4] = 0.0;
                    x[o + 5] = pm_mach;
                    x[o + 6] = pm_mach;
                    mr.pref = pm_mach;
                }
                None => {}
            }
            let vtm = vt.norm();
            match &mr.exciter {
                Some(Exciter::Sexs {
                    k, e_min, e_max, ..
                }) => {
                    if efd > *e_max || efd < *e_min {
                        return Err(GridError::Init(format!(
                            "{name}: initial field voltage {efd:.4} outside exciter limits"
                        )));
                    }
                    let u0 = efd / k;
                    x[o + 7] = u0;
                    x[o + 8] = efd;
                    mr.vref = vtm + u0;
                }
                Some(Exciter::IeeeT1 {
                    ka,
                    ke,
                    kf,
                    tf,
                    se_a,
                    se_b,
                    vr_min,
                    vr_max,
                    ..
                }) => {
                    let se = se_a * (se_b * efd).exp();
                    let vr = (ke + se) * efd;
                    if vr > *vr_max || vr < *vr_min {
                        return Err(GridError::Init(format!(
                            "{name}: initial regulator output {vr:.4} outside limits"
                        )));
                    }
                    x[o + 7] = efd;
                    x[o + 8] = vr;
                    x[o + 9] = kf / tf * efd;
                    mr.vref = vtm + vr / ka;
                }
                None => {}
            }
            machines.push(mr);
        }
        // DER slots
        let mut ders = Vec::new();
        for (k, d) in case.ders.iter().enumerate() {
            let bus = idx[&d.bus];
            let (p, q) = pf.der_pq[k];
            let zs = C64::new(d.r, d.x) * (sb / d.rating_mva);
            let y = if zs.norm() > 0.0 {
                C64::new(1.0, 0.0) / zs
            } else {
                C64::new(0.0, 0.0)
            };
            let (input, initial) = match d.kind {
                DerKind::GridForming => {
                    let i = (C64::new(p, q) / v[bus]).conj();
                    let e = v[bus] + zs * i;
                    (
                        DerInput::GridForming {
                            theta: e.arg(),
                            e: e.norm(),
                        },
                        DerSetpoint::GridForming {
                            theta0: e.arg(),
                            e0: e.norm(),
                        },
                    )
                }
                DerKind::GridFollowing => (
                    DerInput::GridFollowing { p_ref: p, q_ref: q },
                    DerSetpoint::GridFollowing { p0: p, q0: q },
                ),
            };
            ders.push(DerRt {
                kind: d.kind,
                bus,
                y,
                input,
                initial,
            });
        }
        // PCC
        let (pcc_bus, pcc_slots, pcc_branches, pcc_tf) = match &case.pcc {
            Some(p) => (
                idx[&p.bus],
                p.slots.iter().map(|k| k - 1).collect(),
                p.branches
                    .iter()
                    .map(|pb| {
                        (
                            branches.iter().position(|b| b.name == pb.branch).unwrap(),
                            idx[&pb.at_bus],
                        )
                    })
                    .collect(),
                p.f_filter_t,
            ),
            None => {
                let b = case.ders.first().map(|d| idx[&d.bus]).unwrap_or(0);
                ((b), (0..case.ders.len()).collect(), Vec::new(), 0.02)
            }
        };
        let nx = x.len();
        x[nx - 1] = v[pcc_bus].arg();
        let der_angle = ders.iter().map(|d| v[d.bus].arg()).collect();
        let pcc_angle = v[pcc_bus].arg();
        let events = case
            .events
            .iter()
            .map(|e| EventState {
                event: e.clone(),
                enabled: true,
                fired: false,
            })
            .collect();
        let mut g = Grid {
            case: case.clone(),
            sb,
            wb,
            n,
            branches,
            load_y,
            load_s,
            machines,
            ders,
            pcc_bus,
            pcc_slots,
            pcc_branches,
            pcc_tf,
            x,
            t: 0.0,
            v,
            der_angle,
            pcc_angle,
            events,
            pf,
            h_max: MAX_INTERNAL_STEP,
            net: None,
            work: Work::default(),
        };
        // A network solve from the initialized states must reproduce the power flow.
        g.resolve()?;
        let dev =
            g.v.iter()
                .zip(&g.pf.v)
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f64::max);
        if dev > 1e-8 {
            return Err(GridError::Init(format!(
                "network solve from the initial states deviates from the power flow by {dev:e} pu"
            )));
        }
        Ok(g)
    }

    /// The case the grid was built from.
    pub fn case(&self) -> &Case {
        &self.case
    }
    /// Current simulation time, s.
    pub fn time(&self) -> f64 {
        self.t
    }
    /// Move the clock to `t` before the first step (a run that starts at `t ≠ 0`). Event times
    /// are absolute: an event scheduled before `t` fires at the start of the first step.
    pub fn start_at(&mut self, t: f64) -> Result<(), GridError> {
        if !t.is_finite() || self.events.iter().any(|e| e.fired) {
            return Err(GridError::InvalidStep { t, h: 0.0 });
        }
        self.t = t;
        Ok(())
    }
    /// Power-flow solution used for initialization.
    pub fn power_flow(&self) -> &PowerFlow {
        &self.pf
    }
    pub fn n_der(&self) -> usize {
        self.ders.len()
    }
    pub fn n_machines(&self) -> usize {
        self.machines.len()
    }
    pub fn der_kind(&self, k: usize) -> Option<DerKind> {
        self.ders.get(k).map(|d| d.kind)
    }
    /// Internal integration step, s.
    pub fn internal_step(&self) -> f64 {
        self.h_max
    }
    /// Set the internal integration step (0 < h ≤ 1 ms).
    pub fn set_internal_step(&mut self, h: f64) -> Result<(), GridError> {
        if !(h > 0.0 && h <= MAX_INTERNAL_STEP) {
            return Err(GridError::InvalidStep { t: self.t, h });
        }
        self.h_max = h;
        Ok(())
    }
    /// Σ of (rating/S_base)/R over in-service governed machines plus their damping D: the
    /// analytic steady-state frequency stiffness, pu power per pu frequency on S_base.
    pub fn droop_stiffness(&self) -> f64 {
        self.machines
            .iter()
            .filter(|m| m.in_service)
            .map(|m| {
                let r = match &m.governor {
                    Some(Governor::TgovReheat { r, .. }) | Some(Governor::Hygov { r, .. }) => {
                        m.rating / self.sb / r
                    }
                    None => 0.0,
                };
                r + m.d
            })
            .sum()
    }
    /// Total inertia constant of in-service machines on S_base, s.
    pub fn total_inertia(&self) -> f64 {
        self.machines
            .iter()
            .filter(|m| m.in_service)
            .map(|m| m.h)
            .sum()
    }

    /// Initial set points of the DER slots (index 0-based).
    pub fn der_initial(&self) -> Vec<DerSetpoint> {
        self.ders.iter().map(|d| d.initial).collect()
    }

    /// Current input of slot `k` (0-based).
    pub fn der_input(&self, k: usize) -> Option<DerInput> {
        self.ders.get(k).map(|d| d.input)
    }

    /// Set the input of slot `k` (0-based) and re-solve the network so `outputs` reflect it.
    pub fn set_der_input(&mut self, k: usize, input: DerInput) -> Result<(), GridError> {
        self.set_der_input_deferred(k, input)?;
        self.resolve()
    }

    /// Set the input of slot `k` without re-solving the network (the next `step` or `resolve`
    /// uses it). Useful when setting many inputs at once.
    pub fn set_der_input_deferred(&mut self, k: usize, input: DerInput) -> Result<(), GridError> {
        let d = self.ders.get_mut(k).ok_or(GridError::BadSlot {
            index: k,
            reason: "no such slot".into(),
        })?;
        let ok = matches!(
            (d.kind, input),
            (DerKind::GridForming, DerInput::GridForming { .. })
                | (DerKind::GridFollowing, DerInput::GridFollowing { .. })
        );
        if !ok {
            return Err(GridError::BadSlot {
                index: k,
                reason: format!("input {input:?} does not match slot kind {:?}", d.kind),
            });
        }
        let finite = match input {
            DerInput::GridForming { theta, e } => theta.is_finite() && e.is_finite() && e >= 0.0,
            DerInput::GridFollowing { p_ref, q_ref } => p_ref.is_finite() && q_ref.is_finite(),
        };
        if !finite {
            return Err(GridError::BadSlot {
                index: k,
                reason: format!("invalid input {input:?}"),
            });
        }
        d.input = input;
        Ok(())
    }

    /// Scheduled events and their state.
    pub fn events(&self) -> &[EventState] {
        &self.events
    }

    /// Change a scheduled event (0-based index) before it fires.
    pub fn set_event_override(&mut self, i: usize, ov: EventOverride) -> Result<(), GridError> {
        let es = self.events.get_mut(i).ok_or(GridError::BadEvent {
            index: i,
            reason: "no such event".into(),
        })?;
        if es.fired {
            return Err(GridError::BadEvent {
                index: i,
                reason: "event has already fired".into(),
            });
        }
        if let Some(en) = ov.enabled {
            es.enabled = en;
        }
        if let Some(t) = ov.time {
            if !(t.is_finite() && t >= 0.0) {
                return Err(GridError::BadEvent {
                    index: i,
                    reason: format!("bad time {t}"),
                });
            }
            match &mut es.event {
                Event::LoadStep { time, .. }
                | Event::GeneratorTrip { time, .. }
                | Event::LineTrip { time, .. } => *time = t,
            }
        }
        if ov.dp_mw.is_some() || ov.dq_mvar.is_some() {
            match &mut es.event {
                Event::LoadStep { dp_mw, dq_mvar, .. } => {
                    if let Some(p) = ov.dp_mw {
                        *dp_mw = p;
                    }
                    if let Some(q) = ov.dq_mvar {
                        *dq_mvar = q;
                    }
                }
                _ => {
                    return Err(GridError::BadEvent {
                        index: i,
                        reason: "dp/dq override on an event that is not a load step".into(),
                    })
                }
            }
        }
        Ok(())
    }

    /// Disable every scheduled event.
    pub fn disable_events(&mut self) {
        for e in &mut self.events {
            e.enabled = false;
        }
    }

    /// Add an event (validated against the case).
    pub fn add_event(&mut self, ev: Event) -> Result<(), GridError> {
        let mut c = self.case.clone();
        c.events = vec![ev.clone()];
        c.validate().map_err(|e| GridError::BadEvent {
            index: self.events.len(),
            reason: e.to_string(),
        })?;
        self.events.push(EventState {
            event: ev,
            enabled: true,
            fired: false,
        });
        Ok(())
    }

    // ---------------------------------------------------------------- network

    fn build_network(&self) -> Result<Network, GridError> {
        let mut y = powerflow::ybus(&self.case, &self.branches);
        for i in 0..self.n {
            y[(i, i)] += self.load_y[i];
        }
        for m in self.machines.iter().filter(|m| m.in_service) {
            y[(m.bus, m.bus)] += C64::new(1.0, 0.0) / C64::new(m.ra, m.xd_p);
        }
        for d in self.ders.iter().filter(|d| d.kind == DerKind::GridForming) {
            y[(d.bus, d.bus)] += d.y;
        }
        let lu = y.lu();
        if !lu.is_invertible() {
            return Err(GridError::SingularNetwork);
        }
        // also reject numerically singular matrices
        let u = lu.u();
        let (mx, mn) = (0..self.n).fold((0.0f64, f64::INFINITY), |(a, b), i| {
            let d = u[(i, i)].norm();
            (a.max(d), b.min(d))
        });
        if mn < 1e-12 * mx {
            return Err(GridError::SingularNetwork);
        }
        let column = |bus: usize| {
            let mut e = DVector::from_element(self.n, C64::new(0.0, 0.0));
            e[bus] = C64::new(1.0, 0.0);
            lu.solve(&e).ok_or(GridError::SingularNetwork)
        };
        let mut z = Vec::with_capacity(self.machines.len());
        for m in &self.machines {
            z.push(if m.in_service {
                Some(column(m.bus)?)
            } else {
                None
            });
        }
        let mut buses: Vec<usize> = self
            .machines
            .iter()
            .filter(|m| m.in_service)
            .map(|m| m.bus)
            .chain(self.ders.iter().map(|d| d.bus))
            .chain((0..self.n).filter(|&i| self.load_s[i].norm_sqr() > 0.0))
            .collect();
        buses.sort_unstable();
        buses.dedup();
        let sources = buses
            .into_iter()
            .map(|b| Ok((b, column(b)?)))
            .collect::<Result<_, GridError>>()?;
        Ok(Network { z, sources })
    }

    fn ensure_lu(&mut self) -> Result<(), GridError> {
        if self.net.is_none() {
            self.net = Some(self.build_network()?);
        }
        Ok(())
    }

    /// Stator currents of machine `m` for terminal voltage `vt` and states (solving the two
    /// algebraic stator equations of the two-axis model).
    /// `r` is `rot(δ)` of the machine's rotor angle `x[0]`.
    fn stator(m: &MachineRt, x: &[f64], vt: C64, r: C64) -> MachAlg {
        let (eqp, edp) = (x[2], x[3]);
        let vdq = vt * r;
        let (vd, vq) = (vdq.re, vdq.im);
        // vd = edp - ra id + xq' iq ; vq = eqp - ra iq - xd' id
        let (a, b, c, d) = (-m.ra, m.xq_p, -m.xd_p, -m.ra);
        let (r1, r2) = (vd - edp, vq - eqp);
        let det = a * d - b * c;
        let id = (r1 * d - b * r2) / det;
        let iq = (a * r2 - c * r1) / det;
        MachAlg { id, iq, vd, vq }
    }

    /// Network solution for states `x`: `v` holds the starting guess and receives the bus
    /// voltages, `w.alg` the machines' stator solutions.
    ///
    /// The saliency of the two-axis machines (x'_q ≠ x'_d) makes each machine's current
    /// real-linear but not complex-linear in its terminal voltage. It is solved exactly: with
    /// `s_j` the q-axis current of machine j, its saliency injection is `s_j c_j` at its bus, so
    /// `V = V_0 + Σ_j s_j c_j z_j` (`z_j` the impedance column of its bus), and the stator
    /// equations `s_j = i_q,j(V)` form a small real linear system in `s`. Only the voltage-
    /// dependent injections (grid-following slots, constant-power loads) need the fixed-point
    /// iteration on `V`.
    fn solve_net(&self, x: &[f64], v: &mut [C64], w: &mut Work) -> Result<(), GridError> {
        let net = self.net.as_ref().ok_or(GridError::SingularNetwork)?;
        let n = self.n;
        let iterate = self.ders.iter().any(|d| d.kind == DerKind::GridFollowing)
            || self.load_s.iter().any(|s| s.norm_sqr() > 0.0);
        w.sal.clear();
        for (j, m) in self.machines.iter().enumerate() {
            if !m.in_service {
                continue;
            }
            let xs = &x[NS_M * j..];
            let det = m.ra * m.ra + m.xq_p * m.xd_p;
            let r = rot(xs[0]);
            w.sal.push(Sal {
                j,
                bus: m.bus,
                rot: r,
                kd: m.xd_p / det,
                kq: -m.ra / det,
                off: (m.ra * xs[2] - m.xd_p * xs[3]) / det,
                c: C64::new(m.xq_p - m.xd_p, 0.0) / (r * C64::new(m.ra, m.xd_p)),
            });
        }
        // (I - M) is constant over the iterations: M[a][b] = lin_a(c_b z_b[bus_a]).
        let ns = w.sal.len();
        w.i_m.clear();
        for (a, sa) in w.sal.iter().enumerate() {
            for (b, sb) in w.sal.iter().enumerate() {
                let zb = net.z[sb.j].as_ref().ok_or(GridError::SingularNetwork)?;
                let one = if a == b { 1.0 } else { 0.0 };
                w.i_m.push(one - sa.lin(sb.c * zb[sa.bus]));
            }
        }
        let mut residual = f64::INFINITY;
        for _ in 0..NET_MAX_ITER {
            w.cur.clear();
            w.cur.resize(n, C64::new(0.0, 0.0));
            let cur = &mut w.cur;
            for sm in &w.sal {
                let (m, xs) = (&self.machines[sm.j], &x[NS_M * sm.j..]);
                // E'' in the network frame (rot is a unit phasor), through the Norton admittance.
                let e2 = C64::new(xs[3], xs[2]) * sm.rot.conj();
                cur[m.bus] += e2 / C64::new(m.ra, m.xd_p);
            }
            for d in &self.ders {
                match d.input {
                    DerInput::GridForming { theta, e } => {
                        cur[d.bus] += d.y * C64::from_polar(e, theta)
                    }
                    DerInput::GridFollowing { p_ref, q_ref } => {
                        cur[d.bus] += (C64::new(p_ref, q_ref) / v[d.bus]).conj()
                    }
                }
            }
            for i in 0..n {
                let s = self.load_s[i];
                if s.norm_sqr() > 0.0 {
                    if v[i].norm_sqr() >= CONST_POWER_V_MIN * CONST_POWER_V_MIN {
                        cur[i] -= (s / v[i]).conj();
                    } else {
                        cur[i] -= s.conj() / (CONST_POWER_V_MIN * CONST_POWER_V_MIN) * v[i];
                    }
                }
            }
            // V = Z I, with I zero outside the source buses.
            let vn = &mut w.vn;
            vn.clear();
            vn.resize(n, C64::new(0.0, 0.0));
            for (b, zb) in &net.sources {
                let i_b = cur[*b];
                for (v_i, z_ib) in vn.iter_mut().zip(zb.iter()) {
                    *v_i += z_ib * i_b;
                }
            }
            if ns > 0 {
                w.rhs.clear();
                w.rhs.extend(w.sal.iter().map(|s| s.lin(vn[s.bus]) + s.off));
                w.lu.clone_from(&w.i_m);
                if !solve_dense(&mut w.lu, &mut w.rhs, ns) {
                    return Err(GridError::SingularNetwork);
                }
                for (sb, iq) in w.sal.iter().zip(&w.rhs) {
                    let zb = net.z[sb.j].as_ref().ok_or(GridError::SingularNetwork)?;
                    let k = sb.c * iq;
                    for i in 0..n {
                        vn[i] += k * zb[i];
                    }
                }
            }
            residual = (0..n)
                .map(|i| (vn[i] - v[i]).norm_sqr())
                .fold(0.0, f64::max)
                .sqrt();
            v.copy_from_slice(vn);
            if !residual.is_finite() {
                break;
            }
            if !iterate || residual < NET_TOL {
                // Stator solutions, with the rotations of the machines in service from `sal`.
                w.alg.clear();
                let mut sal = w.sal.iter().peekable();
                for (j, m) in self.machines.iter().enumerate() {
                    let xs = &x[NS_M * j..];
                    let r = match sal.next_if(|sm| sm.j == j) {
                        Some(sm) => sm.rot,
                        None => rot(xs[0]),
                    };
                    w.alg.push(Self::stator(m, xs, v[m.bus], r));
                }
                return Ok(());
            }
        }
        Err(GridError::NetworkNotConverged {
            t: self.t,
            residual,
        })
    }

    /// Re-solve the network at the current state (after input or topology changes).
    pub fn resolve(&mut self) -> Result<(), GridError> {
        self.ensure_lu()?;
        // Solve on a copy: a failed solve leaves the voltages as they were.
        let mut w = std::mem::take(&mut self.work);
        let mut v = std::mem::take(&mut w.vs);
        v.clone_from(&self.v);
        let solved = self.solve_net(&self.x, &mut v, &mut w);
        if solved.is_ok() {
            std::mem::swap(&mut self.v, &mut v);
        }
        w.vs = v;
        self.work = w;
        solved?;
        self.update_angles();
        Ok(())
    }

    fn update_angles(&mut self) {
        for (k, d) in self.ders.iter().enumerate() {
            let a = self.v[d.bus].arg();
            self.der_angle[k] += wrap(a - self.der_angle[k]);
        }
        let a = self.v[self.pcc_bus].arg();
        self.pcc_angle += wrap(a - self.pcc_angle);
    }

    // ---------------------------------------------------------------- dynamics

    fn pm_sys(&self, m: &MachineRt, xs: &[f64]) -> f64 {
        let base = m.rating / self.sb;
        match &m.governor {
            Some(Governor::TgovReheat { f_hp, .. }) => base * (f_hp * xs[5] + (1.0 - f_hp) * xs[6]),
            Some(Governor::Hygov { .. }) => base * (3.0 * xs[6] - 2.0 * xs[5]),
            None => m.pm0,
        }
    }

    fn efd(m: &MachineRt, xs: &[f64]) -> f64 {
        match &m.exciter {
            Some(Exciter::Sexs { .. }) => xs[8],
            Some(Exciter::IeeeT1 { .. }) => xs[7],
            None => m.efd0,
        }
    }

    /// Time derivative `dx` of the state vector at `x`, given its network solution (bus
    /// voltages `v`, stator solutions `alg`).
    fn deriv(&self, x: &[f64], v: &[C64], alg: &[MachAlg], dx: &mut Vec<f64>) {
        dx.clear();
        dx.resize(x.len(), 0.0);
        for (j, m) in self.machines.iter().enumerate() {
            if !m.in_service {
                continue;
            }
            let o = NS_M * j;
            let xs = &x[o..o + NS_M];
            let a = alg[j];
            let dw = xs[1] - 1.0;
            let pe = a.vd * a.id + a.vq * a.iq + m.ra * (a.id * a.id + a.iq * a.iq);
            let pm = self.pm_sys(m, xs);
            let efd = Self::efd(m, xs);
            dx[o] = self.wb * dw;
            dx[o + 1] = (pm - pe - m.d * dw) / (2.0 * m.h);
            if m.model == MachineModel::TwoAxis {
                dx[o + 2] = (efd - xs[2] - (m.xd - m.xd_p) * a.id) / m.td0_p;
                dx[o + 3] = (-xs[3] + (m.xq - m.xq_p) * a.iq) / m.tq0_p;
            }
            match &m.governor {
                Some(Governor::TgovReheat {
                    r,
                    t_g,
                    t_ch,
                    t_rh,
                    p_max,
                    p_min,
                    ..
                }) => {
                    let u = m.pref - dw / r;
                    dx[o + 4] = limited((u - xs[4]) / t_g, xs[4], *p_min, *p_max);
                    dx[o + 5] = (xs[4] - xs[5]) / t_ch;
                    dx[o + 6] = (xs[5] - xs[6]) / t_rh;
                }
                Some(Governor::Hygov {
                    r,
                    t_r,
                    t_2,
                    t_g,
                    t_w,
                    p_max,
                    p_min,
                }) => {
                    let u = dw / r;
                    dx[o + 4] = (u - xs[4]) / t_2;
                    let c = xs[4] + t_r / t_2 * (u - xs[4]);
                    let gref = m.pref - c;
                    dx[o + 5] = limited((gref - xs[5]) / t_g, xs[5], *p_min, *p_max);
                    dx[o + 6] = (xs[5] - xs[6]) / (0.5 * t_w);
                }
                None => {}
            }
            let vt = v[m.bus].norm();
            match &m.exciter {
                Some(Exciter::Sexs {
                    k,
                    ta_tb,
                    t_b,
                    t_e,
                    e_min,
                    e_max,
                }) => {
                    let e = m.vref - vt;
                    dx[o + 7] = (e - xs[7]) / t_b;
                    let u = xs[7] + ta_tb * (e - xs[7]);
                    dx[o + 8] = limited((k * u - xs[8]) / t_e, xs[8], *e_min, *e_max);
                }
                Some(Exciter::IeeeT1 {
                    ka,
                    ta,
                    ke,
                    te,
                    kf,
                    tf,
                    se_a,
                    se_b,
                    vr_min,
                    vr_max,
                }) => {
                    let (efd, vr, rf) = (xs[7], xs[8], xs[9]);
                    let se = se_a * (se_b * efd).exp();
                    dx[o + 7] = (-(ke + se) * efd + vr) / te;
                    let dvr = (-vr + ka * rf - ka * kf / tf * efd + ka * (m.vref - vt)) / ta;
                    dx[o + 8] = limited(dvr, vr, *vr_min, *vr_max);
                    dx[o + 9] = (-rf + kf / tf * efd) / tf;
                }
                None => {}
            }
        }
        let nx = x.len();
        let th = v[self.pcc_bus].arg();
        dx[nx - 1] = wrap(th - x[nx - 1]) / self.pcc_tf;
    }

    fn clamp_states(&mut self) {
        for (j, m) in self.machines.iter().enumerate() {
            let o = NS_M * j;
            match &m.governor {
                Some(Governor::TgovReheat { p_max, p_min, .. }) => {
                    self.x[o + 4] = self.x[o + 4].clamp(*p_min, *p_max)
                }
                Some(Governor::Hygov { p_max, p_min, .. }) => {
                    self.x[o + 5] = self.x[o + 5].clamp(*p_min, *p_max)
                }
                None => {}
            }
            match &m.exciter {
                Some(Exciter::Sexs { e_min, e_max, .. }) => {
                    self.x[o + 8] = self.x[o + 8].clamp(*e_min, *e_max)
                }
                Some(Exciter::IeeeT1 { vr_min, vr_max, .. }) => {
                    self.x[o + 8] = self.x[o + 8].clamp(*vr_min, *vr_max)
                }
                None => {}
            }
        }
        let nx = self.x.len();
        self.x[nx - 1] = wrap(self.x[nx - 1]);
    }

    /// One RK4 step of length `h` from the current state, whose network solution is the one
    /// in `self.v` and the work buffers (left there by the last solve: `resolve` at the start of
    /// a communication step, an event, or the previous sub-step's final solve).
    fn rk4(&mut self, h: f64) -> Result<(), GridError> {
        let mut w = std::mem::take(&mut self.work);
        let result = self.rk4_with(h, &mut w);
        self.work = w;
        result
    }

    fn rk4_with(&mut self, h: f64, w: &mut Work) -> Result<(), GridError> {
        let mut x0 = std::mem::take(&mut w.x0);
        let mut v0 = std::mem::take(&mut w.v0);
        let mut xs = std::mem::take(&mut w.xs);
        let mut vs = std::mem::take(&mut w.vs);
        let mut k = std::mem::take(&mut w.k);
        x0.clone_from(&self.x);
        v0.clone_from(&self.v);
        if w.alg.len() != self.machines.len() {
            self.solve_net(&x0, &mut v0, w)?;
        }
        self.deriv(&x0, &v0, &w.alg, &mut k[0]);
        vs.clone_from(&v0);
        let mut stages = || -> Result<(), GridError> {
            for (stage, c) in [(1, 0.5), (2, 0.5), (3, 1.0)] {
                xs.clear();
                xs.extend(x0.iter().zip(&k[stage - 1]).map(|(x, d)| x + c * h * d));
                self.solve_net(&xs, &mut vs, w)?;
                self.deriv(&xs, &vs, &w.alg, &mut k[stage]);
            }
            Ok(())
        };
        let staged = stages();
        let result = staged.and_then(|()| {
            for i in 0..x0.len() {
                self.x[i] = x0[i] + h / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i]);
            }
            if self.x.iter().any(|v| !v.is_finite()) {
                self.x.clone_from(&x0);
                return Err(GridError::NonFinite { t: self.t });
            }
            self.clamp_states();
            // The solution at the new state: the outputs, and the next sub-step's first stage.
            vs.clone_from(&v0);
            self.solve_net(&self.x, &mut vs, w)?;
            std::mem::swap(&mut self.v, &mut vs);
            self.update_angles();
            Ok(())
        });
        (w.x0, w.v0, w.xs, w.vs, w.k) = (x0, v0, xs, vs, k);
        result
    }

    fn fire_due_events(&mut self) -> Result<(), GridError> {
        let mut changed = false;
        for i in 0..self.events.len() {
            let es = &self.events[i];
            if !es.enabled || es.fired || es.event.time() > self.t + EVENT_EPS {
                continue;
            }
            let ev = es.event.clone();
            let idx = self.case.bus_index();
            match ev {
                Event::LoadStep {
                    bus,
                    dp_mw,
                    dq_mvar,
                    model,
                    ..
                } => {
                    let b = idx[&bus];
                    let s = C64::new(dp_mw, dq_mvar) / self.sb;
                    match model {
                        LoadModel::ConstantImpedance => {
                            self.load_y[b] += s.conj() / self.v[b].norm_sqr().max(1e-6)
                        }
                        LoadModel::ConstantPower => self.load_s[b] += s,
                    }
                }
                Event::GeneratorTrip { machine, .. } => {
                    self.machines[machine - 1].in_service = false;
                }
                Event::LineTrip { branch, .. } => {
                    let k = self.branches.iter().position(|b| b.name == branch).ok_or(
                        GridError::BadEvent {
                            index: i,
                            reason: format!("unknown branch {branch}"),
                        },
                    )?;
                    self.branches[k].in_service = false;
                }
            }
            self.events[i].fired = true;
            changed = true;
        }
        if changed {
            self.net = None;
            self.resolve()?;
        }
        Ok(())
    }

    /// Integrate from `t` to `t + h` (FMI doStep semantics). Events fire when their time is
    /// reached; the internal step is at most [`MAX_INTERNAL_STEP`].
    pub fn step(&mut self, t: f64, h: f64) -> Result<(), GridError> {
        if !(h >= 0.0 && h.is_finite() && t.is_finite()) {
            return Err(GridError::InvalidStep { t, h });
        }
        if (t - self.t).abs() > 1e-6 * t.abs().max(1.0) {
            return Err(GridError::TimeMismatch {
                expected: self.t,
                got: t,
            });
        }
        self.t = t;
        self.ensure_lu()?;
        // inputs may have been set deferred
        self.resolve()?;
        let t_end = t + h;
        loop {
            self.fire_due_events()?;
            if self.t >= t_end - EVENT_EPS {
                break;
            }
            let next_ev = self
                .events
                .iter()
                .filter(|e| e.enabled && !e.fired && e.event.time() > self.t + EVENT_EPS)
                .map(|e| e.event.time())
                .fold(f64::INFINITY, f64::min);
            let seg_end = t_end.min(next_ev);
            let span = seg_end - self.t;
            let ns = (span / self.h_max - 1e-9).ceil().max(1.0) as usize;
            let hs = span / ns as f64;
            let t0 = self.t;
            for i in 0..ns {
                self.rk4(hs)?;
                self.t = t0 + (i + 1) as f64 * hs;
            }
            self.t = seg_end;
        }
        self.t = t_end;
        Ok(())
    }

    // ---------------------------------------------------------------- outputs

    fn branch_flows(&self, br: &BranchData) -> (C64, C64) {
        let ys = C64::new(1.0, 0.0) / C64::new(br.r, br.x);
        let hb = C64::new(0.0, br.b / 2.0);
        let (vf, vt) = (self.v[br.from], self.v[br.to]);
        let t = br.tap;
        let i_f = (ys / (t * t) + hb) * vf - ys / t * vt;
        let i_t = (ys + hb) * vt - ys / t * vf;
        (vf * i_f.conj(), vt * i_t.conj())
    }

    fn der_power(&self, d: &DerRt) -> C64 {
        let vb = self.v[d.bus];
        match d.input {
            DerInput::GridForming { theta, e } => {
                let i = d.y * (C64::from_polar(e, theta) - vb);
                vb * i.conj()
            }
            DerInput::GridFollowing { p_ref, q_ref } => C64::new(p_ref, q_ref),
        }
    }

    /// All outputs at the current time (from the last network solution).
    pub fn outputs(&self) -> Outputs {
        let nx = self.x.len();
        let mut out = Outputs {
            t: self.t,
            ..Default::default()
        };
        let mut gen = 0.0;
        for (k, d) in self.ders.iter().enumerate() {
            let s = self.der_power(d);
            gen += s.re;
            out.der.push(DerOutput {
                p: s.re,
                q: s.im,
                v: self.v[d.bus].norm(),
                v_angle: self.der_angle[k],
            });
        }
        let (mut hw, mut hs) = (0.0, 0.0);
        for (j, m) in self.machines.iter().enumerate() {
            let xs = &self.x[NS_M * j..NS_M * (j + 1)];
            let vt = self.v[m.bus];
            let mut o = MachineOutput {
                omega: xs[1],
                delta: xs[0],
                vt: vt.norm(),
                in_service: m.in_service,
                ..Default::default()
            };
            if m.in_service {
                let r = rot(xs[0]);
                let a = Self::stator(m, xs, vt, r);
                let i = C64::new(a.id, a.iq) * r.conj();
                let s = vt * i.conj();
                o.p = s.re;
                o.q = s.im;
                o.pe = a.vd * a.id + a.vq * a.iq + m.ra * (a.id * a.id + a.iq * a.iq);
                o.pm = self.pm_sys(m, xs);
                o.efd = Self::efd(m, xs);
                gen += s.re;
                hw += m.h * xs[1];
                hs += m.h;
            }
            out.sg.push(o);
        }
        let mut load = 0.0;
        for i in 0..self.n {
            let vm2 = self.v[i].norm_sqr();
            load += self.load_y[i].re * vm2;
            let s = self.load_s[i];
            load += if vm2.sqrt() >= CONST_POWER_V_MIN {
                s.re
            } else {
                s.re * vm2 / (CONST_POWER_V_MIN * CONST_POWER_V_MIN)
            };
        }
        for s in &self.case.shunts {
            if let Some(i) = self.case.buses.iter().position(|b| b.id == s.bus) {
                load += s.g * self.v[i].norm_sqr();
            }
        }
        let mut loss = 0.0;
        for br in self.branches.iter().filter(|b| b.in_service) {
            let (sf, st) = self.branch_flows(br);
            loss += sf.re + st.re;
        }
        // PCC
        let mut sp = C64::new(0.0, 0.0);
        for &k in &self.pcc_slots {
            sp += self.der_power(&self.ders[k]);
        }
        for &(b, at) in &self.pcc_branches {
            let br = &self.branches[b];
            if br.in_service {
                let (sf, st) = self.branch_flows(br);
                sp += if at == br.from { sf } else { st };
            }
        }
        let th = self.v[self.pcc_bus].arg();
        let f = 1.0 + wrap(th - self.x[nx - 1]) / (self.pcc_tf * self.wb);
        out.pcc = PccOutput {
            p: sp.re,
            q: sp.im,
            v: self.v[self.pcc_bus].norm(),
            f,
            angle: self.pcc_angle,
        };
        out.coi_f = if hs > 0.0 { hw / hs } else { f };
        out.gen_p = gen;
        out.load_p = load;
        out.loss_p = loss;
        out.balance_p = gen - load - loss;
        out
    }

    /// Largest |derivative| over all states at the current point (0 at an equilibrium).
    pub fn max_derivative(&self) -> Result<f64, GridError> {
        let mut w = Work::default();
        let mut v = self.v.clone();
        self.solve_net(&self.x, &mut v, &mut w)?;
        let mut dx = Vec::new();
        self.deriv(&self.x, &v, &w.alg, &mut dx);
        Ok(dx.iter().fold(0.0, |a, d| a.max(d.abs())))
    }

    /// Current bus voltages (complex, frame at f_nom).
    pub fn bus_voltages(&self) -> Vec<(f64, f64)> {
        self.v.iter().map(|v| (v.norm(), v.arg())).collect()
    }
}

/// Non-windup limit on an integrator state: hold at the limit while pushed outward.
fn limited(dx: f64, x: f64, lo: f64, hi: f64) -> f64 {
    if (x >= hi && dx > 0.0) || (x <= lo && dx < 0.0) {
        0.0
    } else {
        dx
    }
}

#[allow(dead_code)]
fn _assert_traits() {
    fn ok<T: Clone + Serialize + for<'de> Deserialize<'de>>() {}
    ok::<Grid>();
    ok::<Outputs>();
    ok::<Case>();
}
