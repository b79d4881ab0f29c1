//! The algebraic network: admittance matrix, its factorization and the per-stage network solve.
//!
//! Complex bus admittance matrix in the frame rotating at `f_nom` (π lines, transformers,
//! shunts, constant-impedance loads, machine Norton admittances 1/(r_a + j x_d), x_d being x''_d or x'_d, grid-forming
//! slot admittances). It is LU-factorized once and the factorization is reused until the topology
//! or a load changes. Sources enter as current injections. The saliency of the machines
//! (x'_q ≠ x'_d, or x''_q ≠ x''_d) is solved exactly per network solution through a small real system in the
//! machines' q-axis currents (using the impedance columns of the machine buses, cached with the
//! factorization); grid-following injections and constant-power loads are handled by a
//! fixed-point iteration on the factorized network (tolerance 1e-12 pu on every bus voltage).

use crate::case::{BranchData, Case, DerKind};
use crate::der::{DerInput, DerRt, SlotLimit};
use crate::error::GridError;
use crate::machine::{rot, state, MachAlg, MachineRt};
use crate::numerics::C64;
use crate::powerflow;
use nalgebra::DVector;

pub use crate::numerics::CONST_POWER_V_MIN;

const NET_TOL: f64 = 1e-12;
const NET_MAX_ITER: usize = 500;
/// A solution whose last update is below this (pu) after `NET_MAX_ITER` iterations is taken:
/// a slot at its limit can make the fixed-point iteration creep at a contraction near 1 (a
/// 1e-8 pu voltage error is a 1 W power error on 100 MVA; the balance output shows the rest).
const NET_ACCEPT: f64 = 1e-8;

/// A network solution: the bus voltages (also the starting guess of the next solve) and the
/// stator solution of every machine.
#[derive(Clone, Debug, Default)]
pub struct Solution {
    pub(crate) v: Vec<C64>,
    pub(crate) alg: Vec<MachAlg>,
}

/// Work buffers reused by every network solve, so that a solve allocates nothing.
#[derive(Clone, Debug, Default)]
pub struct Scratch {
    /// Bus current injections and the bus voltages they give.
    cur: Vec<C64>,
    vn: Vec<C64>,
    /// Per machine in service: its saliency terms.
    sal: Vec<Sal>,
    /// `I - M` (row-major) and a copy the elimination consumes; the right-hand side.
    i_m: Vec<f64>,
    lu: Vec<f64>,
    rhs: Vec<f64>,
}

/// What injects into the network: the machines (states in `x`), the DER slots and the
/// constant-power loads (pu on S_base, per bus).
#[derive(Clone, Copy)]
pub(crate) struct Injections<'a> {
    pub machines: &'a [MachineRt],
    pub ders: &'a [DerRt],
    pub load_s: &'a [C64],
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
    n: usize,
    /// Bus ids of the case, for messages.
    bus_ids: Vec<u32>,
    z: Vec<Option<DVector<C64>>>,
    sources: Vec<(usize, DVector<C64>)>,
}

/// The bus with the lowest finite voltage magnitude: (index, magnitude); (0, NaN) if none.
fn lowest_voltage<'a>(v: impl Iterator<Item = &'a C64>) -> (usize, f64) {
    v.map(|&v| dvpp_math::cabs(v))
        .enumerate()
        .filter(|(_, m)| m.is_finite())
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((0, f64::NAN))
}

impl Network {
    /// Build and factorize the admittance matrix of the in-service `branches` with the case's
    /// shunts, the constant-impedance loads `load_y`, the Norton admittances of the machines in
    /// service and of the grid-forming slots, a bus fault's shunt admittance `fault` (bus index,
    /// admittance) while it is on, and the impedance columns of the source buses.
    pub(crate) fn build(
        case: &Case,
        branches: &[BranchData],
        load_y: &[C64],
        fault: Option<(usize, C64)>,
        inj: &Injections,
    ) -> Result<Network, GridError> {
        let n = case.buses.len();
        let mut y = powerflow::ybus(case, branches);
        for i in 0..n {
            y[(i, i)] += load_y[i];
        }
        for m in inj.machines.iter().filter(|m| m.in_service) {
            y[(m.bus, m.bus)] += C64::new(1.0, 0.0) / C64::new(m.ra, m.xs_d);
        }
        for d in inj.ders.iter().filter(|d| d.kind == DerKind::GridForming) {
            y[(d.bus, d.bus)] += d.y;
        }
        if let Some((bus, yf)) = fault {
            y[(bus, bus)] += yf;
        }
        let lu = y.lu();
        if !lu.is_invertible() {
            return Err(GridError::SingularNetwork);
        }
        // also reject numerically singular matrices
        let u = lu.u();
        let (mx, mn) = (0..n).fold((0.0f64, f64::INFINITY), |(a, b), i| {
            let d = dvpp_math::cabs(u[(i, i)]);
            (a.max(d), b.min(d))
        });
        if mn < 1e-12 * mx {
            return Err(GridError::SingularNetwork);
        }
        let column = |bus: usize| {
            let mut e = DVector::from_element(n, C64::new(0.0, 0.0));
            e[bus] = C64::new(1.0, 0.0);
            lu.solve(&e).ok_or(GridError::SingularNetwork)
        };
        let mut z = Vec::with_capacity(inj.machines.len());
        for m in inj.machines {
            z.push(if m.in_service {
                Some(column(m.bus)?)
            } else {
                None
            });
        }
        let mut buses: Vec<usize> = inj
            .machines
            .iter()
            .filter(|m| m.in_service)
            .map(|m| m.bus)
            .chain(inj.ders.iter().map(|d| d.bus))
            .chain((0..n).filter(|&i| inj.load_s[i].norm_sqr() > 0.0))
            .collect();
        buses.sort_unstable();
        buses.dedup();
        let sources = buses
            .into_iter()
            .map(|b| Ok((b, column(b)?)))
            .collect::<Result<_, GridError>>()?;
        Ok(Network {
            n,
            bus_ids: case.buses.iter().map(|b| b.id).collect(),
            z,
            sources,
        })
    }

    /// Network solution for states `x` at time `t` (for messages): `sol.v` holds the starting
    /// guess and receives the bus voltages, `sol.alg` the machines' stator solutions.
    ///
    /// The saliency of the machines (x'_q ≠ x'_d, x''_q ≠ x''_d) makes each machine's current
    /// real-linear but not complex-linear in its terminal voltage. It is solved exactly: with
    /// `s_j` the q-axis current of machine j, its saliency injection is `s_j c_j` at its bus, so
    /// `V = V_0 + Σ_j s_j c_j z_j` (`z_j` the impedance column of its bus), and the stator
    /// equations `s_j = i_q,j(V)` form a small real linear system in `s`. Only the voltage-
    /// dependent injections (grid-following slots, constant-power loads) need the fixed-point
    /// iteration on `V`.
    pub(crate) fn solve(
        &self,
        inj: &Injections,
        x: &[f64],
        sol: &mut Solution,
        w: &mut Scratch,
        t: f64,
    ) -> Result<(), GridError> {
        let net = self;
        let v = &mut sol.v[..];
        let n = self.n;
        let iterate = inj
            .ders
            .iter()
            .any(|d| d.kind == DerKind::GridFollowing || d.limit != SlotLimit::NONE)
            || inj.load_s.iter().any(|s| s.norm_sqr() > 0.0);
        w.sal.clear();
        for (j, m) in inj.machines.iter().enumerate() {
            if !m.in_service {
                continue;
            }
            let xm = m.own(x);
            let det = m.ra * m.ra + m.xs_q * m.xs_d;
            let r = rot(xm[state::DELTA]);
            let (ed, eq) = m.emf(xm);
            w.sal.push(Sal {
                j,
                bus: m.bus,
                rot: r,
                kd: m.xs_d / det,
                kq: -m.ra / det,
                off: (m.ra * eq - m.xs_d * ed) / det,
                c: C64::new(m.xs_q - m.xs_d, 0.0) / (r * C64::new(m.ra, m.xs_d)),
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
                let m = &inj.machines[sm.j];
                let xm = m.own(x);
                // E'' in the network frame (rot is a unit phasor), through the Norton admittance.
                let (ed, eq) = m.emf(xm);
                let e2 = C64::new(ed, eq) * sm.rot.conj();
                cur[m.bus] += e2 / C64::new(m.ra, m.xs_d);
            }
            for d in inj.ders {
                match d.input {
                    DerInput::GridForming { theta, e } => {
                        // The Norton source (its admittance is in the matrix) and, when a limit
                        // acts, the current it holds back at the present iterate.
                        let norton = d.y * dvpp_math::cpolar(e, theta);
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
                let s = inj.load_s[i];
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
                    .find(|&i| !dvpp_math::cabs(vn[i] - v[i]).is_finite())
                    .unwrap_or(0);
                break;
            }
            if it + 1 == NET_MAX_ITER {
                worst = (0..n)
                    .max_by(|&a, &b| {
                        dvpp_math::cabs(vn[a] - v[a]).total_cmp(&dvpp_math::cabs(vn[b] - v[b]))
                    })
                    .unwrap_or(0);
                // a fixed-point iteration that did not settle may oscillate between two iterates
                weakest = lowest_voltage(v.iter().zip(vn.iter()).map(|(a, b)| {
                    if dvpp_math::cabs(*b) < dvpp_math::cabs(*a) {
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
                sol.alg.clear();
                let mut sal = w.sal.iter().peekable();
                for (j, m) in inj.machines.iter().enumerate() {
                    let xm = m.own(x);
                    let r = match sal.next_if(|sm| sm.j == j) {
                        Some(sm) => sm.rot,
                        None => rot(xm[state::DELTA]),
                    };
                    sol.alg.push(m.stator(xm, v[m.bus], r));
                }
                return Ok(());
            }
        }
        let (i_min, v_min) = weakest;
        let id = |i: usize| self.bus_ids.get(i).copied().unwrap_or(0);
        Err(GridError::NetworkNotConverged {
            t,
            residual,
            bus: id(i_min),
            v_min,
            mismatch_bus: id(worst),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::der::DerSetpoint;

    /// Two buses joined by a line (r + jx, no charging): a grid-forming slot at bus 1 behind
    /// j0.1 pu, a load at bus 2.
    fn two_bus() -> (Case, Vec<BranchData>) {
        let case: Case = toml::from_str(
            "base_mva = 100.0\nf_nom = 50.0\n\
             [[bus]]\nid = 1\nkind = \"slack\"\n[[bus]]\nid = 2\n\
             [[line]]\nfrom = 1\nto = 2\nr = 0.01\nx = 0.05\n",
        )
        .unwrap();
        let branches = case.branches();
        (case, branches)
    }

    fn slot(e: f64, theta: f64) -> DerRt {
        DerRt {
            kind: DerKind::GridForming,
            bus: 0,
            y: C64::new(1.0, 0.0) / C64::new(0.0, 0.1),
            input: DerInput::GridForming { theta, e },
            initial: DerSetpoint::GridForming {
                theta0: theta,
                e0: e,
            },
            rating: 1.0,
            limit: SlotLimit::NONE,
        }
    }

    #[test]
    fn linear_network_is_a_voltage_divider() {
        let (case, branches) = two_bus();
        let ders = [slot(1.05, 0.2)];
        let y_load = C64::new(0.8, -0.3);
        let load_y = [C64::new(0.0, 0.0), y_load];
        let load_s = [C64::new(0.0, 0.0); 2];
        let inj = Injections {
            machines: &[],
            ders: &ders,
            load_s: &load_s,
        };
        let net = Network::build(&case, &branches, &load_y, None, &inj).unwrap();
        let mut sol = Solution {
            v: vec![C64::new(1.0, 0.0); 2],
            alg: Vec::new(),
        };
        let mut w = Scratch::default();
        net.solve(&inj, &[], &mut sol, &mut w, 0.0).unwrap();
        let e = dvpp_math::cpolar(1.05, 0.2);
        let (zs, zl, zload) = (C64::new(0.0, 0.1), C64::new(0.01, 0.05), 1.0 / y_load);
        let v2 = e * zload / (zs + zl + zload);
        let v1 = e * (zl + zload) / (zs + zl + zload);
        assert!(
            dvpp_math::cabs(sol.v[0] - v1) < 1e-12,
            "{:?} vs {v1}",
            sol.v[0]
        );
        assert!(
            dvpp_math::cabs(sol.v[1] - v2) < 1e-12,
            "{:?} vs {v2}",
            sol.v[1]
        );
    }

    #[test]
    fn constant_power_load_draws_its_power() {
        let (case, branches) = two_bus();
        let ders = [slot(1.0, 0.0)];
        let load_y = [C64::new(0.0, 0.0); 2];
        let s = C64::new(0.5, 0.2);
        let load_s = [C64::new(0.0, 0.0), s];
        let inj = Injections {
            machines: &[],
            ders: &ders,
            load_s: &load_s,
        };
        let net = Network::build(&case, &branches, &load_y, None, &inj).unwrap();
        let mut sol = Solution {
            v: vec![C64::new(1.0, 0.0); 2],
            alg: Vec::new(),
        };
        net.solve(&inj, &[], &mut sol, &mut Scratch::default(), 0.0)
            .unwrap();
        // The current through the line is the load's: V2 conj(I) = S.
        let i = (sol.v[0] - sol.v[1]) / C64::new(0.01, 0.05);
        let drawn = sol.v[1] * i.conj();
        assert!(dvpp_math::cabs(drawn - s) < 1e-10, "{drawn}");
        assert!(dvpp_math::cabs(sol.v[1]) > CONST_POWER_V_MIN);
    }

    #[test]
    fn floating_network_is_singular() {
        let (case, branches) = two_bus();
        let zero = [C64::new(0.0, 0.0); 2];
        let inj = Injections {
            machines: &[],
            ders: &[],
            load_s: &zero,
        };
        assert!(matches!(
            Network::build(&case, &branches, &zero, None, &inj),
            Err(GridError::SingularNetwork)
        ));
    }
}
