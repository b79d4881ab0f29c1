//! The algebraic network: admittance matrix, its factorization and the per-stage network solve.
//!
//! Complex bus admittance matrix in the frame rotating at `f_nom` (π lines, transformers,
//! shunts, constant-impedance loads, machine Norton admittances 1/(r_a + j x'_d), grid-forming
//! slot admittances). It is LU-factorized once and the factorization is reused until the topology
//! or a load changes. Sources enter as current injections. The saliency of two-axis machines
//! (x'_q ≠ x'_d) is solved exactly per network solution through a small real system in the
//! machines' q-axis currents (using the impedance columns of the machine buses, cached with the
//! factorization); grid-following injections and constant-power loads are handled by a
//! fixed-point iteration on the factorized network (tolerance 1e-12 pu on every bus voltage).

use crate::case::{BranchData, DerKind};
use crate::error::GridError;
use crate::grid::{DerInput, Grid, SlotLimit};
use crate::machine::{rot, state, MachAlg};
use crate::numerics::{wrap, C64};
use crate::powerflow;
use nalgebra::DVector;

pub use crate::numerics::CONST_POWER_V_MIN;

const NET_TOL: f64 = 1e-12;
const NET_MAX_ITER: usize = 500;
/// A solution whose last update is below this (pu) after `NET_MAX_ITER` iterations is taken:
/// a slot at its limit can make the fixed-point iteration creep at a contraction near 1 (a
/// 1e-8 pu voltage error is a 1 W power error on 100 MVA; the balance output shows the rest).
const NET_ACCEPT: f64 = 1e-8;

/// Work buffers reused by every network solve and RK4 stage, so that a step allocates nothing.
#[derive(Clone, Debug, Default)]
pub(crate) struct Work {
    /// Bus current injections and the bus voltages they give.
    pub cur: Vec<C64>,
    pub vn: Vec<C64>,
    /// Per machine in service: its saliency terms.
    pub sal: Vec<Sal>,
    /// `I - M` (row-major) and a copy the elimination consumes; the right-hand side.
    pub i_m: Vec<f64>,
    pub lu: Vec<f64>,
    pub rhs: Vec<f64>,
    /// Stator solution of every machine at the last solve.
    pub alg: Vec<MachAlg>,
    /// RK4 stages: start state and voltages, stage states and derivatives, stage voltages.
    pub x0: Vec<f64>,
    pub v0: Vec<C64>,
    pub xs: Vec<f64>,
    pub vs: Vec<C64>,
    pub k: [Vec<f64>; 4],
}

/// A machine's saliency terms in a network solve: its q-axis current is the affine function
/// `kd v_d + kq v_q + off` of its terminal voltage (in its rotor frame `rot`), and `c` is the
/// saliency injection per unit of that current.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sal {
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
pub(crate) struct Network {
    z: Vec<Option<DVector<C64>>>,
    sources: Vec<(usize, DVector<C64>)>,
}

/// The bus with the lowest finite voltage magnitude: (index, magnitude); (0, NaN) if none.
fn lowest_voltage<'a>(v: impl Iterator<Item = &'a C64>) -> (usize, f64) {
    v.map(|v| v.norm())
        .enumerate()
        .filter(|(_, m)| m.is_finite())
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((0, f64::NAN))
}

impl Grid {
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

    pub(crate) fn ensure_lu(&mut self) -> Result<(), GridError> {
        if self.net.is_none() {
            self.net = Some(self.build_network()?);
        }
        Ok(())
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
    pub(crate) fn solve_net(
        &self,
        x: &[f64],
        v: &mut [C64],
        w: &mut Work,
    ) -> Result<(), GridError> {
        if !self.energized() {
            // Nothing holds a voltage: current injections alone define no angle (a grid-
            // following unit follows the voltage it measures), so the network is dead.
            v.fill(C64::new(0.0, 0.0));
            return Ok(());
        }
        let net = self.net.as_ref().ok_or(GridError::SingularNetwork)?;
        let n = self.n;
        let iterate = self
            .ders
            .iter()
            .any(|d| d.kind == DerKind::GridFollowing || d.limit != SlotLimit::NONE)
            || self.load_s.iter().any(|s| s.norm_sqr() > 0.0);
        w.sal.clear();
        for (j, m) in self.machines.iter().enumerate() {
            if !m.in_service {
                continue;
            }
            let xm = m.own(x);
            let det = m.ra * m.ra + m.xq_p * m.xd_p;
            let r = rot(xm[state::DELTA]);
            w.sal.push(Sal {
                j,
                bus: m.bus,
                rot: r,
                kd: m.xd_p / det,
                kq: -m.ra / det,
                off: (m.ra * xm[state::EQ_P] - m.xd_p * xm[state::ED_P]) / det,
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
        // The weakest bus (index, voltage magnitude) of the last two iterates, for the error.
        let mut weakest = (0, f64::NAN);
        // The bus whose voltage moved most in the last iteration.
        let mut worst = 0;
        for it in 0..NET_MAX_ITER {
            w.cur.clear();
            w.cur.resize(n, C64::new(0.0, 0.0));
            let cur = &mut w.cur;
            for sm in &w.sal {
                let m = &self.machines[sm.j];
                let xm = m.own(x);
                // E'' in the network frame (rot is a unit phasor), through the Norton admittance.
                let e2 = C64::new(xm[state::ED_P], xm[state::EQ_P]) * sm.rot.conj();
                cur[m.bus] += e2 / C64::new(m.ra, m.xd_p);
            }
            for d in &self.ders {
                match d.input {
                    DerInput::GridForming { theta, e } => {
                        // The Norton source (its admittance is in the matrix) and, when a limit
                        // acts, the current it holds back at the present iterate.
                        let norton = d.y * C64::from_polar(e, theta);
                        cur[d.bus] += norton;
                        if d.limit != SlotLimit::NONE {
                            let vb = v[d.bus];
                            cur[d.bus] += d.current(vb) - (norton - d.y * vb);
                        }
                    }
                    DerInput::GridFollowing { p_ref, q_ref } => {
                        cur[d.bus] += if d.limit == SlotLimit::NONE {
                            (C64::new(p_ref, q_ref) / v[d.bus]).conj()
                        } else {
                            d.current(v[d.bus])
                        }
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
            if !residual.is_finite() {
                weakest = lowest_voltage(v.iter());
                worst = (0..n)
                    .find(|&i| !(vn[i] - v[i]).norm().is_finite())
                    .unwrap_or(0);
                break;
            }
            if it + 1 == NET_MAX_ITER {
                worst = (0..n)
                    .max_by(|&a, &b| (vn[a] - v[a]).norm().total_cmp(&(vn[b] - v[b]).norm()))
                    .unwrap_or(0);
                // a fixed-point iteration that did not settle may oscillate between two iterates
                weakest = lowest_voltage(v.iter().zip(vn.iter()).map(|(a, b)| {
                    if b.norm() < a.norm() {
                        b
                    } else {
                        a
                    }
                }));
            }
            v.copy_from_slice(vn);
            let settled = residual < NET_TOL || (it + 1 == NET_MAX_ITER && residual < NET_ACCEPT);
            if !iterate || settled {
                // Stator solutions, with the rotations of the machines in service from `sal`.
                w.alg.clear();
                let mut sal = w.sal.iter().peekable();
                for (j, m) in self.machines.iter().enumerate() {
                    let xm = m.own(x);
                    let r = match sal.next_if(|sm| sm.j == j) {
                        Some(sm) => sm.rot,
                        None => rot(xm[state::DELTA]),
                    };
                    w.alg.push(m.stator(xm, v[m.bus], r));
                }
                return Ok(());
            }
        }
        let (i_min, v_min) = weakest;
        let id = |i: usize| self.case.buses.get(i).map_or(0, |b| b.id);
        Err(GridError::NetworkNotConverged {
            t: self.t,
            residual,
            bus: id(i_min),
            v_min,
            mismatch_bus: id(worst),
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

    pub(crate) fn update_angles(&mut self) {
        for (k, d) in self.ders.iter().enumerate() {
            let a = self.v[d.bus].arg();
            self.der_angle[k] += wrap(a - self.der_angle[k]);
        }
        let a = self.v[self.pcc_bus].arg();
        self.pcc_angle += wrap(a - self.pcc_angle);
        for (k, p) in self.pocs.iter().enumerate() {
            let a = self.v[p.bus].arg();
            self.poc_angle[k] += wrap(a - self.poc_angle[k]);
        }
    }

    /// Complex powers entering a branch at its `from` and `to` ends (current bus voltages).
    pub(crate) fn branch_flows(&self, br: &BranchData) -> (C64, C64) {
        let ys = C64::new(1.0, 0.0) / C64::new(br.r, br.x);
        let hb = C64::new(0.0, br.b / 2.0);
        let (vf, vt) = (self.v[br.from], self.v[br.to]);
        let t = br.tap;
        let i_f = (ys / (t * t) + hb) * vf - ys / t * vt;
        let i_t = (ys + hb) * vt - ys / t * vf;
        (vf * i_f.conj(), vt * i_t.conj())
    }
}
