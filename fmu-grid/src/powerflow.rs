//! Newton–Raphson power flow (polar form) and the bus admittance matrix of the passive network.

use crate::case::{BranchData, BusKind, Case};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

pub use crate::numerics::C64;

/// Power-flow result: bus voltages and the P, Q each source delivers (system base, pu).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PowerFlow {
    pub v: Vec<C64>,
    pub iterations: usize,
    pub mismatch: f64,
    /// Per machine (P, Q) injected at its bus.
    pub machine_pq: Vec<(f64, f64)>,
    /// Per DER slot (P, Q) injected at its bus.
    pub der_pq: Vec<(f64, f64)>,
}

/// Add a branch's π-model stamp to `y`.
pub fn stamp_branch(y: &mut DMatrix<C64>, br: &BranchData) {
    let ys = C64::new(1.0, 0.0) / C64::new(br.r, br.x);
    let t = br.tap;
    let (f, to) = (br.from, br.to);
    let half_b = C64::new(0.0, br.b / 2.0);
    y[(f, f)] += ys / (t * t) + half_b;
    y[(to, to)] += ys + half_b;
    y[(f, to)] -= ys / t;
    y[(to, f)] -= ys / t;
}

/// Bus admittance matrix of branches and fixed shunts.
pub fn ybus(case: &Case, branches: &[BranchData]) -> DMatrix<C64> {
    let n = case.buses.len();
    let idx = case.bus_index();
    let mut y = DMatrix::from_element(n, n, C64::new(0.0, 0.0));
    for br in branches.iter().filter(|b| b.in_service) {
        stamp_branch(&mut y, br);
    }
    for s in &case.shunts {
        let i = idx[&s.bus];
        y[(i, i)] += C64::new(s.g, s.b);
    }
    y
}

/// Solve the power flow of `case`. Loads are constant P + jQ here.
pub fn solve(case: &Case, tol: f64, max_iter: usize) -> Result<PowerFlow, (usize, f64)> {
    let n = case.buses.len();
    let idx = case.bus_index();
    let sb = case.base_mva;
    let y = ybus(case, &case.branches());
    // specified injections
    let mut p_spec = vec![0.0; n];
    let mut q_spec = vec![0.0; n];
    for l in &case.loads {
        let i = idx[&l.bus];
        p_spec[i] -= l.p_mw / sb;
        q_spec[i] -= l.q_mvar / sb;
    }
    for m in &case.machines {
        let i = idx[&m.bus];
        p_spec[i] += m.p_mw / sb;
        q_spec[i] += m.q_mvar / sb;
    }
    for d in &case.ders {
        let i = idx[&d.bus];
        p_spec[i] += d.p_mw / sb;
        q_spec[i] += d.q_mvar / sb;
    }
    let kind: Vec<BusKind> = case.buses.iter().map(|b| b.kind).collect();
    let mut vm: Vec<f64> = case
        .buses
        .iter()
        .map(|b| if b.kind == BusKind::Pq { 1.0 } else { b.v_set })
        .collect();
    let mut va: Vec<f64> = case
        .buses
        .iter()
        .map(|b| {
            if b.kind == BusKind::Slack {
                b.angle_deg.to_radians()
            } else {
                0.0
            }
        })
        .collect();
    // unknowns: angles of non-slack buses, magnitudes of PQ buses
    let ang_idx: Vec<usize> = (0..n).filter(|&i| kind[i] != BusKind::Slack).collect();
    let mag_idx: Vec<usize> = (0..n).filter(|&i| kind[i] == BusKind::Pq).collect();
    let na = ang_idx.len();
    let nu = na + mag_idx.len();
    let calc = |vm: &[f64], va: &[f64]| -> (Vec<f64>, Vec<f64>) {
        let v: Vec<C64> = (0..n).map(|i| dvpp_math::cpolar(vm[i], va[i])).collect();
        let mut p = vec![0.0; n];
        let mut q = vec![0.0; n];
        for i in 0..n {
            let mut cur = C64::new(0.0, 0.0);
            for k in 0..n {
                cur += y[(i, k)] * v[k];
            }
            let s = v[i] * cur.conj();
            p[i] = s.re;
            q[i] = s.im;
        }
        (p, q)
    };
    let mut iterations = 0;
    let mut mismatch;
    loop {
        let (p, q) = calc(&vm, &va);
        let mut f = DVector::zeros(nu);
        for (r, &i) in ang_idx.iter().enumerate() {
            f[r] = p_spec[i] - p[i];
        }
        for (r, &i) in mag_idx.iter().enumerate() {
            f[na + r] = q_spec[i] - q[i];
        }
        mismatch = f.amax();
        if mismatch < tol {
            break;
        }
        if iterations >= max_iter || !mismatch.is_finite() {
            return Err((iterations, mismatch));
        }
        iterations += 1;
        // Jacobian d(P,Q)/d(θ, |V|) by analytic formulas
        let v: Vec<C64> = (0..n).map(|i| dvpp_math::cpolar(vm[i], va[i])).collect();
        let ibus: Vec<C64> = (0..n)
            .map(|i| (0..n).fold(C64::new(0.0, 0.0), |a, k| a + y[(i, k)] * v[k]))
            .collect();
        // dS/dθ and dS/d|V| (complex), standard derivation
        let mut ds_dth = DMatrix::from_element(n, n, C64::new(0.0, 0.0));
        let mut ds_dvm = DMatrix::from_element(n, n, C64::new(0.0, 0.0));
        for i in 0..n {
            for k in 0..n {
                let yv = y[(i, k)] * v[k];
                // dS_i/dθ_k = j V_i conj(Y_ik V_k) (k != i) ; diag adds j V_i conj(I_i) - ...
                ds_dth[(i, k)] = -C64::i() * v[i] * yv.conj();
                ds_dvm[(i, k)] = v[i] * (y[(i, k)] * v[k] / vm[k]).conj();
            }
            ds_dth[(i, i)] += C64::i() * v[i] * ibus[i].conj();
            ds_dvm[(i, i)] += ibus[i].conj() * v[i] / vm[i];
        }
        let mut j = DMatrix::zeros(nu, nu);
        for (r, &i) in ang_idx.iter().enumerate() {
            for (c, &k) in ang_idx.iter().enumerate() {
                j[(r, c)] = ds_dth[(i, k)].re;
            }
            for (c, &k) in mag_idx.iter().enumerate() {
                j[(r, na + c)] = ds_dvm[(i, k)].re;
            }
        }
        for (r, &i) in mag_idx.iter().enumerate() {
            for (c, &k) in ang_idx.iter().enumerate() {
                j[(na + r, c)] = ds_dth[(i, k)].im;
            }
            for (c, &k) in mag_idx.iter().enumerate() {
                j[(na + r, na + c)] = ds_dvm[(i, k)].im;
            }
        }
        let dx = match j.lu().solve(&f) {
            Some(dx) => dx,
            None => return Err((iterations, mismatch)),
        };
        for (r, &i) in ang_idx.iter().enumerate() {
            va[i] += dx[r];
        }
        for (r, &i) in mag_idx.iter().enumerate() {
            vm[i] += dx[na + r];
        }
    }
    let v: Vec<C64> = (0..n).map(|i| dvpp_math::cpolar(vm[i], va[i])).collect();
    let (p, q) = calc(&vm, &va);
    // net source injection at each bus = computed injection + load
    let mut p_src = p.clone();
    let mut q_src = q.clone();
    for l in &case.loads {
        let i = idx[&l.bus];
        p_src[i] += l.p_mw / sb;
        q_src[i] += l.q_mvar / sb;
    }
    // share among sources: fixed dispatch where specified, the balance by rating
    let mut machine_pq = vec![(0.0, 0.0); case.machines.len()];
    let mut der_pq = vec![(0.0, 0.0); case.ders.len()];
    for i in 0..n {
        let ms: Vec<usize> = (0..case.machines.len())
            .filter(|&j| idx[&case.machines[j].bus] == i)
            .collect();
        let ds: Vec<usize> = (0..case.ders.len())
            .filter(|&k| idx[&case.ders[k].bus] == i)
            .collect();
        if ms.is_empty() && ds.is_empty() {
            continue;
        }
        let rating: f64 = ms.iter().map(|&j| case.machines[j].rating_mva).sum::<f64>()
            + ds.iter().map(|&k| case.ders[k].rating_mva).sum::<f64>();
        let share_p = kind[i] == BusKind::Slack;
        let share_q = kind[i] != BusKind::Pq;
        // total source injection at the bus (network injection + load)
        let tot_p = p_src[i];
        let tot_q = q_src[i];
        for &j in &ms {
            let m = &case.machines[j];
            let w = m.rating_mva / rating;
            machine_pq[j] = (
                if share_p { tot_p * w } else { m.p_mw / sb },
                if share_q { tot_q * w } else { m.q_mvar / sb },
            );
        }
        for &k in &ds {
            let d = &case.ders[k];
            let w = d.rating_mva / rating;
            der_pq[k] = (
                if share_p { tot_p * w } else { d.p_mw / sb },
                if share_q { tot_q * w } else { d.q_mvar / sb },
            );
        }
    }
    Ok(PowerFlow {
        v,
        iterations,
        mismatch,
        machine_pq,
        der_pq,
    })
}
