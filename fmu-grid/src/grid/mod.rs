//! The reduced-grid model: the [`Grid`] that ties the network, machines, DER slots, PCC and
//! events together, its construction from a case and its inputs.
//!
//! Its parts are the child modules `dynamics` (network solve at its states, derivative, the
//! communication step), `outputs`, [`events`] and [`snapshot`] (serialization); the physics is
//! in the layers below, which know nothing of the grid: [`crate::network`] (admittance matrix
//! and network solve), [`crate::machine`], [`crate::governor`] and [`crate::exciter`] (the
//! dynamic models), [`crate::integration`] (internal step and RK4 over a DAE), [`crate::der`],
//! [`crate::numerics`] and [`crate::error`].

mod dynamics;
pub mod events;
pub mod fault;
mod outputs;
pub mod snapshot;

pub use crate::der::{DerInput, DerSetpoint, SlotLimit};
pub use crate::error::GridError;
pub use crate::integration::MAX_INTERNAL_STEP;
pub use crate::network::CONST_POWER_V_MIN;
use events::UflsState;
pub use events::{EventOverride, EventState};
use fault::FaultRt;
pub use fault::{BusFault, FaultOutput};
pub use outputs::{DerOutput, MachineOutput, Outputs, PccOutput};

use crate::case::{BranchData, Case, DerKind, LoadModel};
use crate::der::DerRt;
use crate::integration::choose_internal_step;
use crate::integration::Rk4;
use crate::machine::MachineRt;
use crate::network::{Network, Scratch, Solution};
use crate::numerics::TimeConstant;
use crate::powerflow::{self, PowerFlow, C64};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Angle between a machine's rotor (or a grid-forming slot's internal voltage) and the centre
/// of inertia beyond which the unit has lost synchronism, rad: π, the pole slip (the
/// electrical power it exchanges with the rest of the grid has changed sign, and a first-swing
/// stable system stays well inside it).
pub const LOSS_OF_SYNCHRONISM_ANGLE: f64 = PI;

/// The band of centre-of-inertia frequency, pu, outside which the machines' frequency
/// protection disconnects them: 47.5 to 51.5 Hz at 50 Hz, the range the European network code
/// for generators (Commission Regulation (EU) 2016/631, Table 2) asks them to ride through. A
/// grid whose frequency leaves it has no operating point left; the step ends with
/// [`GridError::FrequencyCollapse`].
pub const FREQUENCY_BAND: (f64, f64) = (0.95, 1.03);

/// A point of coupling as the simulation uses it.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct PocRt {
    /// Measurement bus (index).
    pub bus: usize,
    /// Branch indices whose flows from the area towards `bus` are summed.
    pub branches: Vec<usize>,
    /// Measured at the branches' area-side ends (else where they meet `bus`).
    pub area_side: bool,
    /// Slot indices (0-based) whose injections are summed (a DVPP's PCC, `[[dvpp_pcc]]`).
    #[serde(default)]
    pub slots: Vec<usize>,
    pub tf: f64,
}

/// The buses behind the POCs: those reached from each POC branch's far end (the end that is not
/// the POC bus) without crossing a POC branch.
fn area_buses(n: usize, branches: &[BranchData], pocs: &[PocRt]) -> Vec<usize> {
    let poc_branch = |k: usize| pocs.iter().any(|p| p.branches.contains(&k));
    let mut inside = vec![false; n];
    let mut stack: Vec<usize> = pocs
        .iter()
        .flat_map(|p| {
            p.branches.iter().map(move |&k| {
                let b = &branches[k];
                if b.from == p.bus {
                    b.to
                } else {
                    b.from
                }
            })
        })
        .collect();
    while let Some(i) = stack.pop() {
        if std::mem::replace(&mut inside[i], true) {
            continue;
        }
        for (k, b) in branches.iter().enumerate() {
            if poc_branch(k) {
                continue;
            }
            if b.from == i && !inside[b.to] {
                stack.push(b.to);
            } else if b.to == i && !inside[b.from] {
                stack.push(b.from);
            }
        }
    }
    (0..n).filter(|&i| inside[i]).collect()
}

/// The reduced-grid model.
///
/// `Serialize`/`Deserialize` go through `GridSnapshot` ([`snapshot`]): the case as TOML text plus the
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
    /// The loads at the power-flow point: what an under-frequency shedding stage takes its
    /// share of.
    load_y0: Vec<C64>,
    load_s0: Vec<C64>,
    /// Per under-frequency shedding stage of the case: its timer and whether it acted.
    ufls: Vec<UflsState>,
    machines: Vec<MachineRt>,
    ders: Vec<DerRt>,
    pcc_bus: usize,
    pcc_slots: Vec<usize>,
    /// (branch index, measured at bus index).
    pcc_branches: Vec<(usize, usize)>,
    pcc_tf: f64,
    pocs: Vec<PocRt>,
    /// Buses of the area behind the POCs (reached from the POC branches' far ends without
    /// crossing them); empty without POCs.
    area: Vec<usize>,
    /// Index in `x` of the PCC angle filter state; the POC filters follow it.
    pcc_state: usize,
    /// State vector: per machine its states (see `MachineRt::at`), then the PCC angle filter,
    /// then one angle filter per POC.
    x: Vec<f64>,
    t: f64,
    /// The network solution at the current state.
    sol: Solution,
    der_angle: Vec<f64>,
    pcc_angle: f64,
    /// Unwrapped bus angle of each POC, rad.
    poc_angle: Vec<f64>,
    events: Vec<EventState>,
    /// The balanced bus fault, when one is set ([`Grid::set_fault`]).
    fault: Option<FaultRt>,
    pf: PowerFlow,
    /// Internal integration step in use, and the largest the case's time constants allow.
    h_max: f64,
    h_limit: f64,
    /// Why `h_limit` is below [`MAX_INTERNAL_STEP`] (None when it is not).
    step_note: Option<String>,
    /// Factorized network; a cache, rebuilt on demand (not part of snapshots).
    net: Option<Network>,
    /// Work buffers of the network solves and the integrator; caches (not part of snapshots).
    work: Work,
}

/// The buffers the network solves and the integrator reuse, so that a step allocates nothing.
#[derive(Clone, Debug, Default)]
struct Work {
    spare: Solution,
    scratch: Scratch,
    rk4: Rk4<Solution>,
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
        // machines, then the PCC and POC filter states
        let mut machines = Vec::new();
        let mut x = Vec::new();
        for (j, m) in case.machines.iter().enumerate() {
            let bus = idx[&m.bus];
            let mr = MachineRt::init(m, j, bus, sb, v[bus], pf.machine_pq[j], &mut x)?;
            machines.push(mr);
        }
        let pcc_state = x.len();
        x.push(0.0);
        let mut pocs: Vec<PocRt> = case
            .pocs
            .iter()
            .map(|p| {
                let bus = idx[&p.bus];
                x.push(dvpp_math::carg(v[bus]));
                PocRt {
                    bus,
                    branches: p
                        .branches
                        .iter()
                        .map(|name| branches.iter().position(|b| &b.name == name).unwrap())
                        .collect(),
                    area_side: p.side == crate::case::PocSide::Area,
                    slots: Vec::new(),
                    tf: p.f_filter_t,
                }
            })
            .collect();
        let area = area_buses(n, &branches, &pocs);
        // The DVPPs' PCCs follow the POCs (filter states, angles), outside the area.
        for p in &case.dvpp_pccs {
            let bus = idx[&p.bus];
            x.push(dvpp_math::carg(v[bus]));
            pocs.push(PocRt {
                bus,
                branches: Vec::new(),
                area_side: false,
                slots: p.slots.iter().map(|k| k - 1).collect(),
                tf: p.f_filter_t,
            });
        }
        let poc_angle = pocs.iter().map(|p| dvpp_math::carg(v[p.bus])).collect();
        // DER slots
        let mut ders = Vec::new();
        for (k, d) in case.ders.iter().enumerate() {
            let bus = idx[&d.bus];
            let (p, q) = pf.der_pq[k];
            let zs = C64::new(d.r, d.x.unwrap_or(0.0)) * (sb / d.rating_mva);
            let y = if dvpp_math::cabs(zs) > 0.0 {
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
                            theta: dvpp_math::carg(e),
                            e: dvpp_math::cabs(e),
                        },
                        DerSetpoint::GridForming {
                            theta0: dvpp_math::carg(e),
                            e0: dvpp_math::cabs(e),
                        },
                    )
                }
                DerKind::GridFollowing => (
                    DerInput::GridFollowing { p_ref: p, q_ref: q },
                    DerSetpoint::GridFollowing { p0: p, q0: q },
                ),
            };
            ders.push(DerRt {
                rating: d.rating_mva / sb,
                limit: SlotLimit::NONE,
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
        x[pcc_state] = dvpp_math::carg(v[pcc_bus]);
        let der_angle = ders.iter().map(|d| dvpp_math::carg(v[d.bus])).collect();
        let pcc_angle = dvpp_math::carg(v[pcc_bus]);
        let events = case
            .events
            .iter()
            .map(|e| EventState {
                event: e.clone(),
                enabled: true,
                fired: false,
            })
            .collect();
        // The internal step the case's time constants allow.
        let mut tcs: Vec<TimeConstant> = machines
            .iter()
            .enumerate()
            .flat_map(|(j, m)| m.time_constants(j, wb))
            .collect();
        tcs.push(TimeConstant::new("pcc.f_filter_t".into(), pcc_tf));
        let n_poc = case.pocs.len();
        for (k, p) in pocs.iter().enumerate() {
            let name = if k < n_poc {
                format!("poc[{}].f_filter_t", k + 1)
            } else {
                format!("pcc_{}.f_filter_t", case.dvpp_pccs[k - n_poc].name)
            };
            tcs.push(TimeConstant::new(name, p.tf));
        }
        let (h_limit, step_note) = choose_internal_step(&tcs)?;
        let mut g = Grid {
            case: case.clone(),
            sb,
            wb,
            n,
            branches,
            load_y0: load_y.clone(),
            load_s0: load_s.clone(),
            ufls: vec![UflsState::default(); case.ufls.len()],
            load_y,
            load_s,
            machines,
            ders,
            pcc_bus,
            pcc_slots,
            pcc_branches,
            pcc_tf,
            pocs,
            area,
            pcc_state,
            x,
            t: 0.0,
            sol: Solution { v, alg: Vec::new() },
            der_angle,
            pcc_angle,
            poc_angle,
            events,
            fault: None,
            pf,
            h_max: h_limit,
            h_limit,
            step_note,
            net: None,
            work: Work::default(),
        };
        // A network solve from the initialized states must reproduce the power flow.
        g.resolve()?;
        let dev = g
            .sol
            .v
            .iter()
            .zip(&g.pf.v)
            .map(|(a, b)| dvpp_math::cabs(a - b))
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
    /// Largest internal step the case's time constants allow: [`MAX_INTERNAL_STEP`], or less
    /// when a time constant is shorter than 3 ms (see [`Grid::internal_step_note`]).
    pub fn max_internal_step(&self) -> f64 {
        self.h_limit
    }
    /// Why the internal step was reduced below [`MAX_INTERNAL_STEP`] (which parameter of the
    /// case needs it), or None when it was not; the FMU logs it at initialization.
    pub fn internal_step_note(&self) -> Option<&str> {
        self.step_note.as_deref()
    }
    /// Set the internal integration step (0 < h ≤ [`Grid::max_internal_step`]).
    pub fn set_internal_step(&mut self, h: f64) -> Result<(), GridError> {
        if !(h > 0.0 && h <= self.h_limit) {
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
                    Some(g) => m.rating / self.sb / g.droop(),
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

    /// Set the converter limits of slot `k` (0-based) for the next solutions: `i_max` in pu of
    /// the slot rating, `p_min`, `p_max` in pu on S_base (infinite: none).
    pub fn set_der_limit(&mut self, k: usize, limit: SlotLimit) -> Result<(), GridError> {
        let d = self.ders.get_mut(k).ok_or(GridError::BadSlot {
            index: k,
            reason: "no such slot".into(),
        })?;
        let SlotLimit {
            i_max,
            p_min,
            p_max,
        } = limit;
        if i_max.is_nan() || i_max < 0.0 || p_min.is_nan() || p_max.is_nan() || p_min > p_max {
            return Err(GridError::BadSlot {
                index: k,
                reason: format!(
                    "limits i_max = {i_max}, p_min = {p_min}, p_max = {p_max}: need i_max >= 0 (0: the converter is blocked) and p_min <= p_max"
                ),
            });
        }
        d.limit = limit;
        Ok(())
    }

    /// Converter limits of slot `k` (0-based).
    pub fn der_limit(&self, k: usize) -> Option<SlotLimit> {
        self.ders.get(k).map(|d| d.limit)
    }
}

#[allow(dead_code)]
fn _assert_traits() {
    fn ok<T: Clone + Serialize + for<'de> Deserialize<'de>>() {}
    ok::<Grid>();
    ok::<Outputs>();
    ok::<Case>();
}
