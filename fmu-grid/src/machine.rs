//! Synchronous machines: case data, validation, states, initialization, stator and derivatives.
//!
//! A machine's states are its own (rotor angle δ, speed ω, transient EMFs E'q, E'd and, in the
//! sub-transient model, the damper fluxes ψ1d, ψ2q; see `state`) followed by those of its
//! governor, exciter and stabilizer, which it drives through [`Governor`], [`Exciter`] and
//! [`Pss`]. `Layout` records where they sit in the grid's state vector.
//!
//! The network sees every machine as an EMF behind its stator reactances (x'd, x'q for the
//! two-axis and classical models; x''d, x''q for the sub-transient model): see
//! `MachineRt::emf`.

use crate::error::GridError;
use crate::error::{check_range, nonneg, pos, CaseError};
use crate::exciter::Exciter;
use crate::governor::Governor;
use crate::numerics::TimeConstant;
use crate::numerics::C64;
use crate::pss::Pss;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Synchronous-machine model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MachineModel {
    /// Sub-transient (6th-order) model of Sauer & Pai, without saturation: states δ, ω, E'q,
    /// E'd and the damper fluxes ψ1d, ψ2q; the stator sits behind x''d, x''q. With
    /// x''d = x''q it is PSS/E's and ANDES's GENROU without saturation.
    SubTransient,
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

/// Synchronous machine with optional governor, exciter and stabilizer. The fields a model does
/// not use may be left out: a classical machine needs only `h`, `xd_p` (and optionally `d`,
/// `ra`); a two-axis machine also needs `xd`, `xq`, `xq_p`, `td0_p` and `tq0_p`; a
/// sub-transient machine also `xd_pp`, `xl`, `td0_pp`, `tq0_pp` (and `xq_pp`, default `xd_pp`).
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
    /// Sub-transient reactances, leakage reactance and open-circuit sub-transient time
    /// constants (sub-transient model only).
    #[serde(default)]
    pub xd_pp: Option<f64>,
    #[serde(default)]
    pub xq_pp: Option<f64>,
    #[serde(default)]
    pub xl: Option<f64>,
    #[serde(default)]
    pub td0_pp: Option<f64>,
    #[serde(default)]
    pub tq0_pp: Option<f64>,
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
    /// Power system stabilizer: its output adds to the exciter's voltage error.
    #[serde(default)]
    pub pss: Option<Pss>,
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
        let model = match self.model {
            MachineModel::SubTransient => "sub_transient",
            MachineModel::TwoAxis => "two_axis",
            MachineModel::Classical => "classical",
        };
        let needs = |name: &str, v: Option<f64>| {
            v.ok_or_else(|| {
                CaseError::Inconsistent(format!("{el}: the {model} model needs `{name}`"))
            })
        };
        match self.model {
            MachineModel::SubTransient | MachineModel::TwoAxis => {
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
                if self.model == MachineModel::SubTransient {
                    let xd_pp = needs("xd_pp", self.xd_pp)?;
                    let xq_pp = self.xq_pp.unwrap_or(xd_pp);
                    let xl = needs("xl", self.xl)?;
                    nonneg(el, "xl", xl)?;
                    check_range(
                        el,
                        "xd_pp",
                        xd_pp,
                        xd_pp > xl && xd_pp <= self.xd_p,
                        "> xl and <= xd_p",
                    )?;
                    check_range(
                        el,
                        "xq_pp",
                        xq_pp,
                        xq_pp > xl && xq_pp <= xq_p,
                        "> xl and <= xq_p",
                    )?;
                    pos(el, "td0_pp", needs("td0_pp", self.td0_pp)?)?;
                    pos(el, "tq0_pp", needs("tq0_pp", self.tq0_pp)?)?;
                }
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
        if let Some(p) = &self.pss {
            if self.exciter.is_none() {
                return Err(CaseError::Inconsistent(format!(
                    "{el}: a stabilizer acts through the exciter; add `[machine.exciter]`"
                )));
            }
            p.validate(el)?;
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
    /// Damper-winding flux of the d axis, ψ1d (sub-transient model), pu.
    pub const PSI_1D: usize = 4;
    /// Damper-winding flux of the q axis, ψ2q (sub-transient model), pu.
    pub const PSI_2Q: usize = 5;
    /// States of the two-axis and classical models.
    pub const N_TRANSIENT: usize = 4;
    /// States of the sub-transient model.
    pub const N_SUB_TRANSIENT: usize = 6;
}

/// Where one machine's states sit in the grid's state vector: its own, its governor's, its
/// exciter's, its stabilizer's (each range empty when there is no such control).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct Layout {
    pub machine: usize,
    pub governor: usize,
    pub exciter: usize,
    pub pss: usize,
    pub end: usize,
}

impl Layout {
    fn after(start: usize, m: &Machine) -> Layout {
        let own = match m.model {
            MachineModel::SubTransient => state::N_SUB_TRANSIENT,
            MachineModel::TwoAxis | MachineModel::Classical => state::N_TRANSIENT,
        };
        let gov = start + own;
        let exc = gov + m.governor.as_ref().map_or(0, Governor::n_states);
        let pss = exc + m.exciter.as_ref().map_or(0, Exciter::n_states);
        let end = pss + m.pss.as_ref().map_or(0, Pss::n_states);
        Layout {
            machine: start,
            governor: gov,
            exciter: exc,
            pss,
            end,
        }
    }
}

/// Sub-transient data of a machine, system base.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct SubTransient {
    pub xd_pp: f64,
    pub xq_pp: f64,
    pub xl: f64,
    pub td0_pp: f64,
    pub tq0_pp: f64,
}

impl SubTransient {
    /// The weights of E'q and ψ1d in ψ''d, and of E'd and ψ2q in ψ''q.
    fn weights(&self, xd_p: f64, xq_p: f64) -> [f64; 4] {
        let (dd, dq) = (xd_p - self.xl, xq_p - self.xl);
        [
            (self.xd_pp - self.xl) / dd,
            (xd_p - self.xd_pp) / dd,
            (self.xq_pp - self.xl) / dq,
            (xq_p - self.xq_pp) / dq,
        ]
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
    /// Sub-transient data (sub-transient model only).
    pub sub: Option<SubTransient>,
    /// The stator reactances the network sees the EMF behind: x'' (sub-transient model) or x'.
    pub xs_d: f64,
    pub xs_q: f64,
    pub governor: Option<Governor>,
    pub exciter: Option<Exciter>,
    pub pss: Option<Pss>,
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
    dvpp_math::cpolar(1.0, -(delta - PI / 2.0))
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
            MachineModel::SubTransient | MachineModel::TwoAxis => (
                m.xd.ok_or_else(|| missing("xd"))?,
                m.xq.ok_or_else(|| missing("xq"))?,
                m.xq_p.ok_or_else(|| missing("xq_p"))?,
                m.td0_p.ok_or_else(|| missing("td0_p"))?,
                m.tq0_p.ok_or_else(|| missing("tq0_p"))?,
            ),
            MachineModel::Classical => (m.xd_p, m.xd_p, m.xd_p, 1.0, 1.0),
        };
        let sub = match m.model {
            MachineModel::SubTransient => {
                let xd_pp = m.xd_pp.ok_or_else(|| missing("xd_pp"))?;
                Some(SubTransient {
                    xd_pp: xd_pp * zb,
                    xq_pp: m.xq_pp.unwrap_or(xd_pp) * zb,
                    xl: m.xl.ok_or_else(|| missing("xl"))? * zb,
                    td0_pp: m.td0_pp.ok_or_else(|| missing("td0_pp"))?,
                    tq0_pp: m.tq0_pp.ok_or_else(|| missing("tq0_pp"))?,
                })
            }
            MachineModel::TwoAxis | MachineModel::Classical => None,
        };
        let at = Layout::after(x.len(), m);
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
            sub,
            xs_d: sub.map_or(m.xd_p * zb, |s| s.xd_pp),
            xs_q: sub.map_or(xq_p * zb, |s| s.xq_pp),
            governor: m.governor.clone(),
            exciter: m.exciter.clone(),
            pss: m.pss.clone(),
            pref: 0.0,
            pm0: 0.0,
            vref: 0.0,
            efd0: 0.0,
            in_service: true,
            at,
        };
        let it = (C64::new(p, q) / vt).conj();
        // The machine's rotor axis lies along the voltage behind r_a + j x_q (two-axis,
        // sub-transient) or behind the transient reactance (classical); Park-transform terminal
        // V and I to it.
        let x_axis = match m.model {
            MachineModel::SubTransient | MachineModel::TwoAxis => mr.xq,
            MachineModel::Classical => mr.xd_p,
        };
        let e_axis = vt + C64::new(mr.ra, x_axis) * it;
        let delta = dvpp_math::carg(e_axis);
        let (vdq, idq) = (vt * rot(delta), it * rot(delta));
        let (vd, vq, id, iq) = (vdq.re, vdq.im, idq.re, idq.im);
        let (edp, eqp, efd) = match m.model {
            MachineModel::SubTransient | MachineModel::TwoAxis => {
                let eqp = vq + mr.ra * iq + mr.xd_p * id;
                (
                    vd + mr.ra * id - mr.xq_p * iq,
                    eqp,
                    eqp + (mr.xd - mr.xd_p) * id,
                )
            }
            MachineModel::Classical => (0.0, dvpp_math::cabs(e_axis), dvpp_math::cabs(e_axis)),
        };
        let pe = vd * id + vq * iq + mr.ra * (id * id + iq * iq);
        let xm = &mut x[at.machine..at.governor];
        xm[state::DELTA] = delta;
        xm[state::OMEGA] = 1.0;
        xm[state::EQ_P] = eqp;
        xm[state::ED_P] = edp;
        if let Some(s) = &mr.sub {
            // Damper fluxes at rest: ψ1d = E'q − (x'd − xl) id, ψ2q = −E'd − (x'q − xl) iq.
            xm[state::PSI_1D] = eqp - (mr.xd_p - s.xl) * id;
            xm[state::PSI_2Q] = -edp - (mr.xq_p - s.xl) * iq;
        }
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
                .init(efd, dvpp_math::cabs(vt), &mut x[at.exciter..at.pss])
                .map_err(|e| GridError::Init(format!("{name}: {e}")))?;
        }
        // A stabilizer starts at rest (Δω = 0): its states are zero.
        Ok(mr)
    }

    /// The machine's own states in the full state vector `x`.
    pub(crate) fn own<'a>(&self, x: &'a [f64]) -> &'a [f64] {
        &x[self.at.machine..self.at.governor]
    }

    /// The EMF (E_d, E_q) the stator sees behind `xs_d`, `xs_q`: (E'd, E'q) for the two-axis
    /// and classical models, (−ψ''q, ψ''d) for the sub-transient model.
    pub(crate) fn emf(&self, xm: &[f64]) -> (f64, f64) {
        let (eqp, edp) = (xm[state::EQ_P], xm[state::ED_P]);
        match &self.sub {
            None => (edp, eqp),
            Some(s) => {
                let [a, b, c, d] = s.weights(self.xd_p, self.xq_p);
                let psi_d = a * eqp + b * xm[state::PSI_1D];
                let psi_q = -c * edp + d * xm[state::PSI_2Q];
                (-psi_q, psi_d)
            }
        }
    }

    /// Stator currents for terminal voltage `vt` and the machine's own states `xm` (solving the
    /// two algebraic stator equations); `r` is `rot(δ)`.
    pub(crate) fn stator(&self, xm: &[f64], vt: C64, r: C64) -> MachAlg {
        let (edp, eqp) = self.emf(xm);
        let vdq = vt * r;
        let (vd, vq) = (vdq.re, vdq.im);
        // vd = E_d - ra id + xs_q iq ; vq = E_q - ra iq - xs_d id
        let (a, b, c, d) = (-self.ra, self.xs_q, -self.xs_d, -self.ra);
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

    /// Field voltage at terminal voltage `vt`: the exciter's, or the initial one held constant
    /// without one.
    pub(crate) fn efd(&self, x: &[f64], vt: f64) -> f64 {
        match &self.exciter {
            Some(e) => e.efd(self.vref, vt, self.vs(x), &x[self.at.exciter..self.at.pss]),
            None => self.efd0,
        }
    }

    /// The stabilizer's output (0 without one).
    fn vs(&self, x: &[f64]) -> f64 {
        let dw = self.own(x)[state::OMEGA] - 1.0;
        self.pss
            .as_ref()
            .map_or(0.0, |p| p.output(dw, &x[self.at.pss..self.at.end]))
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
        let efd = self.efd(x, vt);
        let dxm = &mut dx[at.machine..at.governor];
        let (eqp, edp) = (xm[state::EQ_P], xm[state::ED_P]);
        match (self.model, &self.sub) {
            (MachineModel::TwoAxis, _) => {
                dxm[state::EQ_P] = (efd - eqp - (self.xd - self.xd_p) * a.id) / self.td0_p;
                dxm[state::ED_P] = (-edp + (self.xq - self.xq_p) * a.iq) / self.tq0_p;
            }
            (MachineModel::SubTransient, Some(s)) => {
                // Sauer & Pai's sub-transient model: the damper windings (ψ1d, ψ2q) between the
                // field (E'q), the q-axis rotor circuit (E'd) and the stator.
                let (psi1d, psi2q) = (xm[state::PSI_1D], xm[state::PSI_2Q]);
                let (dd, dq) = (self.xd_p - s.xl, self.xq_p - s.xl);
                let kd = (self.xd_p - s.xd_pp) / (dd * dd);
                let kq = (self.xq_p - s.xq_pp) / (dq * dq);
                let id_eff = a.id - kd * (psi1d + dd * a.id - eqp);
                let iq_eff = a.iq - kq * (psi2q + dq * a.iq + edp);
                dxm[state::EQ_P] = (efd - eqp - (self.xd - self.xd_p) * id_eff) / self.td0_p;
                dxm[state::ED_P] = (-edp + (self.xq - self.xq_p) * iq_eff) / self.tq0_p;
                dxm[state::PSI_1D] = (-psi1d + eqp - dd * a.id) / s.td0_pp;
                dxm[state::PSI_2Q] = (-psi2q - edp - dq * a.iq) / s.tq0_pp;
            }
            _ => {}
        }
        if let Some(e) = &self.exciter {
            let vs = self.vs(x);
            let (xe, dxe) = (&x[at.exciter..at.pss], &mut dx[at.exciter..at.pss]);
            e.deriv(self.vref, vt, vs, xe, dxe);
        }
        if let Some(p) = &self.pss {
            let (xp, dxp) = (&x[at.pss..at.end], &mut dx[at.pss..at.end]);
            p.deriv(dw, xp, dxp);
        }
    }

    /// Hold the limited control states inside their limits.
    pub(crate) fn clamp(&self, x: &mut [f64]) {
        let at = self.at;
        if let Some(g) = &self.governor {
            g.clamp(&mut x[at.governor..at.exciter]);
        }
        if let Some(e) = &self.exciter {
            e.clamp(&mut x[at.exciter..at.pss]);
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
        if let Some(s) = &self.sub {
            out.push(
                TimeConstant::new(format!("{prefix}.td0_pp"), s.td0_pp).effective(
                    s.td0_pp * s.xd_pp / self.xd_p,
                    "short-circuit td0_pp xd_pp / xd_p",
                ),
            );
            out.push(
                TimeConstant::new(format!("{prefix}.tq0_pp"), s.tq0_pp).effective(
                    s.tq0_pp * s.xq_pp / self.xq_p,
                    "short-circuit tq0_pp xq_pp / xq_p",
                ),
            );
        }
        if self.model != MachineModel::Classical {
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
        if let Some(p) = &self.pss {
            out.extend(p.time_constants(&prefix));
        }
        out
    }
}
