//! Synchronous machines: case data, validation, states, initialization, stator and derivatives.
//!
//! A machine's states are its own (rotor angle δ, speed ω, transient EMFs E'q, E'd; see
//! `state`) followed by those of its governor and exciter, which it drives through
//! [`Governor`] and [`Exciter`]. `Layout` records where they sit in the grid's state vector.

use crate::error::GridError;
use crate::error::{check_range, nonneg, pos, CaseError};
use crate::exciter::Exciter;
use crate::governor::Governor;
use crate::numerics::TimeConstant;
use crate::numerics::C64;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Synchronous-machine model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MachineModel {
    /// Two-axis (flux-decay in d and q) model: states δ, ω, E'q, E'd.
    TwoAxis,
    /// Classical model: constant E' behind x'd, states δ, ω (E'q, E'd held constant).
    Classical,
}

/// The base the machine's H, D and reactances are given on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ParamBase {
    /// System base `base_mva`.
    #[default]
    System,
    /// The machine's own `rating_mva`.
    Machine,
}

/// Synchronous machine with optional governor and exciter. The fields a model does not use
/// may be left out: a classical machine needs only `h`, `xd_p` (and optionally `d`, `ra`);
/// a two-axis machine also needs `xd`, `xq`, `xq_p`, `td0_p` and `tq0_p`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Machine {
    #[serde(default)]
    pub name: Option<String>,
    pub bus: u32,
    pub model: MachineModel,
    pub rating_mva: f64,
    /// Base of `h`, `d`, `ra` and the reactances.
    #[serde(default)]
    pub base: ParamBase,
    pub h: f64,
    #[serde(default)]
    pub d: f64,
    #[serde(default)]
    pub ra: f64,
    #[serde(default)]
    pub xd: Option<f64>,
    pub xd_p: f64,
    #[serde(default)]
    pub xq: Option<f64>,
    #[serde(default)]
    pub xq_p: Option<f64>,
    #[serde(default)]
    pub td0_p: Option<f64>,
    #[serde(default)]
    pub tq0_p: Option<f64>,
    /// Active-power dispatch (ignored at the slack bus).
    #[serde(default)]
    pub p_mw: f64,
    /// Reactive dispatch, used only if the machine sits on a PQ bus.
    #[serde(default)]
    pub q_mvar: f64,
    #[serde(default)]
    pub governor: Option<Governor>,
    #[serde(default)]
    pub exciter: Option<Exciter>,
}

impl Machine {
    /// Check the machine's own parameters and those of its controls; `el` names it in errors.
    pub(crate) fn validate(&self, el: &str) -> Result<(), CaseError> {
        pos(el, "rating_mva", self.rating_mva)?;
        pos(el, "h", self.h)?;
        nonneg(el, "d", self.d)?;
        nonneg(el, "ra", self.ra)?;
        pos(el, "xd_p", self.xd_p)?;
        check_range(el, "p_mw", self.p_mw, true, "finite")?;
        let needs = |name: &str, v: Option<f64>| {
            v.ok_or_else(|| {
                CaseError::Inconsistent(format!("{el}: the two_axis model needs `{name}`"))
            })
        };
        match self.model {
            MachineModel::TwoAxis => {
                let xd = needs("xd", self.xd)?;
                check_range(el, "xd", xd, xd >= self.xd_p, ">= xd_p")?;
                for (name, v) in [
                    ("xq", self.xq),
                    ("xq_p", self.xq_p),
                    ("td0_p", self.td0_p),
                    ("tq0_p", self.tq0_p),
                ] {
                    pos(el, name, needs(name, v)?)?;
                }
                let (xq, xq_p) = (needs("xq", self.xq)?, needs("xq_p", self.xq_p)?);
                check_range(el, "xq", xq, xq >= xq_p, ">= xq_p")?;
            }
            MachineModel::Classical => {
                // xd and the q-axis data are unused; checked only for consistency if given
                if let Some(xd) = self.xd {
                    check_range(el, "xd", xd, xd >= self.xd_p, ">= xd_p")?;
                }
                if self.exciter.is_some() {
                    return Err(CaseError::Inconsistent(format!(
                        "{el}: a classical machine has constant E' and cannot take an exciter"
                    )));
                }
            }
        }
        if let Some(g) = &self.governor {
            g.validate(el)?;
        }
        if let Some(e) = &self.exciter {
            e.validate(el)?;
        }
        Ok(())
    }
}

/// The machine's own states, relative to its first state.
pub(crate) mod state {
    /// Rotor angle, rad, frame rotating at f_nom.
    pub const DELTA: usize = 0;
    /// Rotor speed, pu.
    pub const OMEGA: usize = 1;
    /// Transient EMF behind x'_d (q axis), pu.
    pub const EQ_P: usize = 2;
    /// Transient EMF behind x'_q (d axis), pu.
    pub const ED_P: usize = 3;
    pub const N: usize = 4;
}

/// Where one machine's states sit in the grid's state vector: its own, its governor's, its
/// exciter's (each range empty when there is no such control).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct Layout {
    pub machine: usize,
    pub governor: usize,
    pub exciter: usize,
    pub end: usize,
}

impl Layout {
    fn after(start: usize, governor: Option<&Governor>, exciter: Option<&Exciter>) -> Layout {
        let gov = start + state::N;
        let exc = gov + governor.map_or(0, Governor::n_states);
        let end = exc + exciter.map_or(0, Exciter::n_states);
        Layout {
            machine: start,
            governor: gov,
            exciter: exc,
            end,
        }
    }
}

/// A machine as the simulation uses it: parameters on the system base, references, layout.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct MachineRt {
    pub bus: usize,
    pub model: MachineModel,
    pub rating: f64,
    pub h: f64,
    pub d: f64,
    pub ra: f64,
    pub xd: f64,
    pub xd_p: f64,
    pub xq: f64,
    pub xq_p: f64,
    pub td0_p: f64,
    pub tq0_p: f64,
    pub governor: Option<Governor>,
    pub exciter: Option<Exciter>,
    /// Governor reference, machine base.
    pub pref: f64,
    /// Mechanical power without governor, system base.
    pub pm0: f64,
    /// Exciter voltage reference.
    pub vref: f64,
    /// Field voltage without exciter.
    pub efd0: f64,
    pub in_service: bool,
    pub at: Layout,
}

/// Algebraic machine quantities for one network solution.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct MachAlg {
    pub id: f64,
    pub iq: f64,
    pub vd: f64,
    pub vq: f64,
}

/// Rotation from the network frame to the dq frame of a rotor at angle `delta`.
pub(crate) fn rot(delta: f64) -> C64 {
    // network -> dq: multiply by e^{-j(δ - π/2)}
    C64::from_polar(1.0, -(delta - PI / 2.0))
}

impl MachineRt {
    /// Build machine `j` of the case (0-based) at its power-flow point: terminal voltage `vt`,
    /// injection `p + jq` (system base). Its states are appended to `x`.
    pub(crate) fn init(
        m: &Machine,
        j: usize,
        bus: usize,
        sb: f64,
        vt: C64,
        (p, q): (f64, f64),
        x: &mut Vec<f64>,
    ) -> Result<MachineRt, GridError> {
        let zb = match m.base {
            ParamBase::System => 1.0,
            ParamBase::Machine => sb / m.rating_mva,
        };
        let hb = 1.0 / zb; // power-like quantities scale inversely
        let missing = |name: &str| GridError::Init(format!("machine {}: no `{name}`", j + 1));
        let (xd, xq, xq_p, td0_p, tq0_p) = match m.model {
            MachineModel::TwoAxis => (
                m.xd.ok_or_else(|| missing("xd"))?,
                m.xq.ok_or_else(|| missing("xq"))?,
                m.xq_p.ok_or_else(|| missing("xq_p"))?,
                m.td0_p.ok_or_else(|| missing("td0_p"))?,
                m.tq0_p.ok_or_else(|| missing("tq0_p"))?,
            ),
            MachineModel::Classical => (m.xd_p, m.xd_p, m.xd_p, 1.0, 1.0),
        };
        let at = Layout::after(x.len(), m.governor.as_ref(), m.exciter.as_ref());
        x.resize(at.end, 0.0);
        let mut mr = MachineRt {
            bus,
            model: m.model,
            rating: m.rating_mva,
            h: m.h * hb,
            d: m.d * hb,
            ra: m.ra * zb,
            xd: xd * zb,
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
            at,
        };
        let it = (C64::new(p, q) / vt).conj();
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
        let xm = &mut x[at.machine..at.governor];
        xm[state::DELTA] = delta;
        xm[state::OMEGA] = 1.0;
        xm[state::EQ_P] = eqp;
        xm[state::ED_P] = edp;
        mr.pm0 = pe;
        mr.efd0 = efd;
        let name = format!("machine {}", j + 1);
        if let Some(g) = &mr.governor {
            let pm_mach = pe * sb / mr.rating;
            mr.pref = g
                .init(pm_mach, &mut x[at.governor..at.exciter])
                .map_err(|e| GridError::Init(format!("{name}: {e}")))?;
        }
        if let Some(e) = &mr.exciter {
            mr.vref = e
                .init(efd, vt.norm(), &mut x[at.exciter..at.end])
                .map_err(|e| GridError::Init(format!("{name}: {e}")))?;
        }
        Ok(mr)
    }

    /// The machine's own states in the full state vector `x`.
    pub(crate) fn own<'a>(&self, x: &'a [f64]) -> &'a [f64] {
        &x[self.at.machine..self.at.governor]
    }

    /// Stator currents for terminal voltage `vt` and the machine's own states `xm` (solving the
    /// two algebraic stator equations of the two-axis model); `r` is `rot(δ)`.
    pub(crate) fn stator(&self, xm: &[f64], vt: C64, r: C64) -> MachAlg {
        let (eqp, edp) = (xm[state::EQ_P], xm[state::ED_P]);
        let vdq = vt * r;
        let (vd, vq) = (vdq.re, vdq.im);
        // vd = edp - ra id + xq' iq ; vq = eqp - ra iq - xd' id
        let (a, b, c, d) = (-self.ra, self.xq_p, -self.xd_p, -self.ra);
        let (r1, r2) = (vd - edp, vq - eqp);
        let det = a * d - b * c;
        let id = (r1 * d - b * r2) / det;
        let iq = (a * r2 - c * r1) / det;
        MachAlg { id, iq, vd, vq }
    }

    /// Air-gap power for a stator solution, system base.
    pub(crate) fn pe(&self, a: &MachAlg) -> f64 {
        a.vd * a.id + a.vq * a.iq + self.ra * (a.id * a.id + a.iq * a.iq)
    }

    /// Mechanical power, system base: the governor's, or the dispatch held constant without
    /// one. A tripped machine's turbine is tripped with it (its stop valves close, as unit
    /// protection does on a breaker trip): no power.
    pub(crate) fn pm_sys(&self, x: &[f64], sb: f64) -> f64 {
        let base = self.rating / sb;
        match &self.governor {
            _ if !self.in_service => 0.0,
            Some(g) => base * g.pm(&x[self.at.governor..self.at.exciter]),
            None => self.pm0,
        }
    }

    /// Field voltage: the exciter's, or the initial one held constant without one.
    pub(crate) fn efd(&self, x: &[f64]) -> f64 {
        match &self.exciter {
            Some(e) => e.efd(&x[self.at.exciter..self.at.end]),
            None => self.efd0,
        }
    }

    /// Write the derivatives of all the machine's states (own, governor, exciter) into `dx`,
    /// given the full state `x`, its stator solution `a` and terminal voltage magnitude `vt`.
    ///
    /// A tripped machine is disconnected and its turbine tripped: no electrical or mechanical
    /// power, the rotor coasts down through its damping `D` (its speed stays a live state), and
    /// its governor, flux and exciter states are frozen.
    pub(crate) fn deriv(&self, x: &[f64], a: &MachAlg, vt: f64, wb: f64, sb: f64, dx: &mut [f64]) {
        let at = self.at;
        let xm = self.own(x);
        let dw = xm[state::OMEGA] - 1.0;
        let pe = if self.in_service { self.pe(a) } else { 0.0 };
        let pm = self.pm_sys(x, sb);
        let dxm = &mut dx[at.machine..at.governor];
        dxm[state::DELTA] = wb * dw;
        dxm[state::OMEGA] = (pm - pe - self.d * dw) / (2.0 * self.h);
        if !self.in_service {
            return;
        }
        if let Some(g) = &self.governor {
            let (xg, dxg) = (
                &x[at.governor..at.exciter],
                &mut dx[at.governor..at.exciter],
            );
            g.deriv(self.pref, dw, xg, dxg);
        }
        if self.model == MachineModel::TwoAxis {
            let efd = self.efd(x);
            let dxm = &mut dx[at.machine..at.governor];
            dxm[state::EQ_P] = (efd - xm[state::EQ_P] - (self.xd - self.xd_p) * a.id) / self.td0_p;
            dxm[state::ED_P] = (-xm[state::ED_P] + (self.xq - self.xq_p) * a.iq) / self.tq0_p;
        }
        if let Some(e) = &self.exciter {
            let (xe, dxe) = (&x[at.exciter..at.end], &mut dx[at.exciter..at.end]);
            e.deriv(self.vref, vt, xe, dxe);
        }
    }

    /// Hold the limited control states inside their limits.
    pub(crate) fn clamp(&self, x: &mut [f64]) {
        let at = self.at;
        if let Some(g) = &self.governor {
            g.clamp(&mut x[at.governor..at.exciter]);
        }
        if let Some(e) = &self.exciter {
            e.clamp(&mut x[at.exciter..at.end]);
        }
    }

    /// Time constants the integration must resolve; `j` is the 0-based machine number and
    /// `wb` the base angular frequency.
    ///
    /// Besides the control time constants: the transient time constants at a terminal short
    /// circuit (T'd0·x'd/xd and T'q0·x'q/xq, the fastest the flux states get), and the swing
    /// mode against a stiff bus through x'd, 1/ω_s = √(2 H x'd / ω_b).
    pub(crate) fn time_constants(&self, j: usize, wb: f64) -> Vec<TimeConstant> {
        let prefix = format!("machine[{}]", j + 1);
        let swing = (2.0 * self.h * self.xd_p / wb).sqrt();
        let mut out = vec![TimeConstant::new(format!("{prefix}.h"), self.h)
            .effective(swing, "swing mode sqrt(2 h xd_p / omega_b), s")];
        if self.model == MachineModel::TwoAxis {
            out.push(
                TimeConstant::new(format!("{prefix}.td0_p"), self.td0_p).effective(
                    self.td0_p * self.xd_p / self.xd,
                    "short-circuit td0_p xd_p / xd",
                ),
            );
            out.push(
                TimeConstant::new(format!("{prefix}.tq0_p"), self.tq0_p).effective(
                    self.tq0_p * self.xq_p / self.xq,
                    "short-circuit tq0_p xq_p / xq",
                ),
            );
        }
        if let Some(g) = &self.governor {
            out.extend(g.time_constants(&prefix));
        }
        if let Some(e) = &self.exciter {
            out.extend(e.time_constants(&prefix));
        }
        out
    }
}
