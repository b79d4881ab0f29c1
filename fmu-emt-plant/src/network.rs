//! The plant's linear circuit in the stationary αβ frame: state layout, the PCC voltage
//! eliminated from KCL, and the exact discretization (transition matrix and energy integrals)
//! cached per step size and topology.
//!
//! The augmented state is `z = [x_α, x_β, e_α, e_β, u_α,1, u_β,1, …]`: the circuit states of each
//! axis (`i_f`, `v_c`, `i_g` per unit, one current per load, the Thevenin current), the Thevenin
//! source as an undamped oscillator at `ω_b`, and each unit's converter voltage, held over the
//! step (`u' = 0`) or, with the rotating hold, turning at `ω_b` (`u' = ω_b J u`). Over a step
//! `z(t+h) = Φ z(t)` with `Φ = exp(M h)`; the energy integrals `∫ zᵀ Q z dt` over the step are
//! `z(t)ᵀ W z(t)` with `W = ∫₀ʰ exp(Mᵀs) Q exp(M s) ds` (Van Loan's block exponential).

use dvpp_control::ss::expm;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// One unit's power stage, pu on its rating (`l_*`, `c_f` as reactance and susceptance at `ω_b`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct UnitData {
    /// Rating, MVA.
    pub s: f64,
    pub r_f: f64,
    pub l_f: f64,
    pub c_f: f64,
    pub r_t: f64,
    pub l_t: f64,
}

/// A series R-L branch, pu on `S_base` (`l` as reactance at `ω_b`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Branch {
    pub r: f64,
    pub l: f64,
}

/// Which branches are connected during a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Topology {
    /// Bit `j`: load `j` is connected.
    pub loads: u64,
    /// The Thevenin source is connected.
    pub thevenin: bool,
    /// The converter voltage turns at `ω_b` over a step instead of being held.
    pub rotating_hold: bool,
}

impl Topology {
    pub fn load(&self, j: usize) -> bool {
        self.loads >> j & 1 == 1
    }
}

/// The circuit's data, fixed at initialization.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Network {
    pub units: Vec<UnitData>,
    pub loads: Vec<Branch>,
    /// Thevenin impedance, `None` if no Thevenin source is declared.
    pub thevenin: Option<Branch>,
    pub s_base: f64,
    pub omega_b: f64,
}

/// Indices of the energy forms in [`Discrete::forms`] after the `N` converter forms.
pub const FORM_AC_LOSS: usize = 0;
pub const FORM_THEVENIN: usize = 1;
pub const FORM_LOADS: usize = 2;

impl Network {
    /// Circuit states per axis.
    pub fn nc(&self) -> usize {
        3 * self.units.len() + self.loads.len() + usize::from(self.thevenin.is_some())
    }
    /// Size of the augmented state.
    pub fn n(&self) -> usize {
        2 * self.nc() + 2 + 2 * self.units.len()
    }
    pub fn i_f(&self, k: usize) -> usize {
        3 * k
    }
    pub fn v_c(&self, k: usize) -> usize {
        3 * k + 1
    }
    pub fn i_g(&self, k: usize) -> usize {
        3 * k + 2
    }
    pub fn i_load(&self, j: usize) -> usize {
        3 * self.units.len() + j
    }
    /// Index of the Thevenin current (if declared).
    pub fn i_th(&self) -> usize {
        3 * self.units.len() + self.loads.len()
    }
    /// Index of `e_α` in the augmented state (`e_β` follows).
    pub fn e(&self) -> usize {
        2 * self.nc()
    }
    /// Index of unit `k`'s `u_α` in the augmented state (`u_β` follows).
    pub fn u(&self, k: usize) -> usize {
        2 * self.nc() + 2 + 2 * k
    }

    /// Unit `k`'s rating over `S_base`: its currents in system pu are `c_k` times its own.
    pub fn c(&self, k: usize) -> f64 {
        self.units[k].s / self.s_base
    }

    /// `v_pcc = Σ g_i x_i + g_e e` on one axis: KCL's derivative with the inductive branches'
    /// equations, `v Y = Σ_k c_k (v_c - R_t i_g)/L_t + (e - R_s i_s)/L_s + Σ_j R_j i_j/L_j`,
    /// `Y = Σ_k c_k/L_t + 1/L_s + Σ_j 1/L_j` over the connected branches.
    pub fn vpcc_coefficients(&self, topo: &Topology) -> (Vec<f64>, f64) {
        let mut g = vec![0.0; self.nc()];
        let mut ge = 0.0;
        let mut y = 0.0;
        for (k, u) in self.units.iter().enumerate() {
            let a = self.c(k) / u.l_t;
            y += a;
            g[self.v_c(k)] += a;
            g[self.i_g(k)] -= a * u.r_t;
        }
        for (j, l) in self.loads.iter().enumerate() {
            if topo.load(j) {
                y += 1.0 / l.l;
                g[self.i_load(j)] += l.r / l.l;
            }
        }
        if let (Some(th), true) = (self.thevenin, topo.thevenin) {
            y += 1.0 / th.l;
            ge = 1.0 / th.l;
            g[self.i_th()] -= th.r / th.l;
        }
        for x in &mut g {
            *x /= y;
        }
        (g, ge / y)
    }

    /// The PCC voltage (α, β) of an augmented state.
    pub fn vpcc(&self, topo: &Topology, z: &DVector<f64>) -> [f64; 2] {
        let (g, ge) = self.vpcc_coefficients(topo);
        let nc = self.nc();
        let mut v = [ge * z[self.e()], ge * z[self.e() + 1]];
        for (i, gi) in g.iter().enumerate() {
            v[0] += gi * z[i];
            v[1] += gi * z[nc + i];
        }
        v
    }

    /// The augmented continuous-time matrix `M`, `z' = M z`.
    pub fn continuous(&self, topo: &Topology) -> DMatrix<f64> {
        let (nc, n, wb) = (self.nc(), self.n(), self.omega_b);
        let (g, ge) = self.vpcc_coefficients(topo);
        // One axis: A (nc × nc), b_e (nc), B_u (nc × N).
        let mut a = DMatrix::zeros(nc, nc);
        let mut be = DVector::zeros(nc);
        let mut bu = DMatrix::zeros(nc, self.units.len());
        // Subtract the PCC voltage from row `r` with weight `w`.
        let minus_v = |a: &mut DMatrix<f64>, be: &mut DVector<f64>, r: usize, w: f64| {
            for (i, gi) in g.iter().enumerate() {
                a[(r, i)] -= w * gi;
            }
            be[r] -= w * ge;
        };
        for (k, u) in self.units.iter().enumerate() {
            let (f, c, t) = (self.i_f(k), self.v_c(k), self.i_g(k));
            let kf = wb / u.l_f;
            a[(f, f)] = -kf * u.r_f;
            a[(f, c)] = -kf;
            bu[(f, k)] = kf;
            let kc = wb / u.c_f;
            a[(c, f)] = kc;
            a[(c, t)] = -kc;
            let kt = wb / u.l_t;
            a[(t, c)] += kt;
            a[(t, t)] -= kt * u.r_t;
            minus_v(&mut a, &mut be, t, kt);
        }
        for (j, l) in self.loads.iter().enumerate() {
            if topo.load(j) {
                let r = self.i_load(j);
                let kl = wb / l.l;
                // i_j' = (v - R i_j) ω_b/L: the PCC voltage enters with a plus sign.
                minus_v(&mut a, &mut be, r, -kl);
                a[(r, r)] -= kl * l.r;
            }
        }
        if let (Some(th), true) = (self.thevenin, topo.thevenin) {
            let r = self.i_th();
            let ks = wb / th.l;
            be[r] += ks;
            a[(r, r)] -= ks * th.r;
            minus_v(&mut a, &mut be, r, ks);
        }
        let mut m = DMatrix::zeros(n, n);
        for axis in 0..2 {
            let o = axis * nc;
            m.view_mut((o, o), (nc, nc)).copy_from(&a);
            for i in 0..nc {
                m[(o + i, self.e() + axis)] = be[i];
                for k in 0..self.units.len() {
                    m[(o + i, self.u(k) + axis)] = bu[(i, k)];
                }
            }
        }
        // The oscillators: (α + jβ)' = jω_b (α + jβ).
        let mut rotate = |i: usize| {
            m[(i, i + 1)] = -wb;
            m[(i + 1, i)] = wb;
        };
        rotate(self.e());
        if topo.rotating_hold {
            for k in 0..self.units.len() {
                rotate(self.u(k));
            }
        }
        m
    }

    /// The symmetric matrices of the quadratic energy rates (MW): each unit's converter power
    /// `u·i_f S_k`, then the resistive losses of filters, transformers and Thevenin impedance,
    /// the Thevenin source's power `e·i_s S_base`, and the loads' power `Σ R_j i_j² S_base`.
    pub fn energy_rates(&self, topo: &Topology) -> Vec<DMatrix<f64>> {
        let (nc, n) = (self.nc(), self.n());
        let mut out = Vec::new();
        let sym = |q: &mut DMatrix<f64>, i: usize, j: usize, w: f64| {
            q[(i, j)] += w / 2.0;
            q[(j, i)] += w / 2.0;
        };
        for (k, u) in self.units.iter().enumerate() {
            let mut q = DMatrix::zeros(n, n);
            for axis in 0..2 {
                sym(&mut q, self.u(k) + axis, axis * nc + self.i_f(k), u.s);
            }
            out.push(q);
        }
        let (mut loss, mut th_q, mut loads) = (
            DMatrix::zeros(n, n),
            DMatrix::zeros(n, n),
            DMatrix::zeros(n, n),
        );
        for axis in 0..2 {
            let o = axis * nc;
            for (k, u) in self.units.iter().enumerate() {
                sym(&mut loss, o + self.i_f(k), o + self.i_f(k), u.s * u.r_f);
                sym(&mut loss, o + self.i_g(k), o + self.i_g(k), u.s * u.r_t);
            }
            if let (Some(th), true) = (self.thevenin, topo.thevenin) {
                let i = o + self.i_th();
                sym(&mut loss, i, i, self.s_base * th.r);
                sym(&mut th_q, self.e() + axis, i, self.s_base);
            }
            for (j, l) in self.loads.iter().enumerate() {
                if topo.load(j) {
                    let i = o + self.i_load(j);
                    sym(&mut loads, i, i, self.s_base * l.r);
                }
            }
        }
        out.extend([loss, th_q, loads]);
        out
    }

    /// Magnetic and electric energy stored in the ac circuit, MJ.
    pub fn stored(&self, z: &DVector<f64>) -> f64 {
        let nc = self.nc();
        let sq = |i: usize| z[i] * z[i] + z[nc + i] * z[nc + i];
        let mut w = 0.0;
        for (k, u) in self.units.iter().enumerate() {
            w +=
                u.s * (u.l_f * sq(self.i_f(k)) + u.c_f * sq(self.v_c(k)) + u.l_t * sq(self.i_g(k)));
        }
        for (j, l) in self.loads.iter().enumerate() {
            w += self.s_base * l.l * sq(self.i_load(j));
        }
        if let Some(th) = self.thevenin {
            w += self.s_base * th.l * sq(self.i_th());
        }
        w / (2.0 * self.omega_b)
    }

    /// The exact discretization at step `h` for `topo`; refused when `M h` is not finite or so
    /// large (a step of many time constants of the fastest mode, or extreme parameters) that
    /// the scaling and squaring of the exponential would lose all accuracy.
    pub fn discretize(&self, topo: &Topology, h: f64) -> Result<Discrete, String> {
        let (phi, forms) = exact_discretization(
            self.continuous(topo) * h,
            self.energy_rates(topo),
            h,
        )
        .map_err(|norm| {
            format!(
                "the circuit cannot be discretized at h = {h} s: |M h| = {norm:e} (the step spans too many time constants of the fastest mode, or a parameter is extreme)"
            )
        })?;
        Ok(Discrete {
            h,
            topo: *topo,
            phi,
            forms,
        })
    }
}

/// Largest 1-norm of `M h` accepted (2^20: twenty squarings).
const MAX_NORM: f64 = 1_048_576.0;

/// The exact discretization of `dx/dt = M x` over one step, from `mh` = `M h`: the transition
/// `Φ = exp(M h)` and, per energy rate `x' Q x`, the symmetric form `W` with
/// `x₀' W x₀ = ∫₀ʰ x' Q x dt` (Van Loan: `exp([[-Mᵀ, Q], [0, M]] h) = [[·, F12], [0, Φ]]`,
/// `∫ = Φᵀ F12`). Refused with the 1-norm of `M h` when it is not finite or beyond
/// [`MAX_NORM`], where scaling and squaring would lose all accuracy.
pub(crate) fn exact_discretization(
    mh: DMatrix<f64>,
    rates: Vec<DMatrix<f64>>,
    h: f64,
) -> Result<(DMatrix<f64>, Vec<DMatrix<f64>>), f64> {
    let n = mh.nrows();
    let norm = (0..n)
        .map(|j| mh.column(j).iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0f64, f64::max);
    if !(norm.is_finite() && norm <= MAX_NORM) {
        return Err(norm);
    }
    let phi = expm(&mh);
    let forms = rates
        .into_iter()
        .map(|q| {
            let mut c = DMatrix::zeros(2 * n, 2 * n);
            c.view_mut((0, 0), (n, n)).copy_from(&(-mh.transpose()));
            c.view_mut((0, n), (n, n)).copy_from(&(q * h));
            c.view_mut((n, n), (n, n)).copy_from(&mh);
            let f = expm(&c);
            let w = f.view((n, n), (n, n)).transpose() * f.view((0, n), (n, n));
            (&w + w.transpose()) * 0.5
        })
        .collect();
    Ok((phi, forms))
}

/// The circuit sampled at one step for one topology.
#[derive(Debug, Clone)]
pub struct Discrete {
    pub h: f64,
    pub topo: Topology,
    /// `Φ = exp(M h)`.
    pub phi: DMatrix<f64>,
    /// `W` of each energy rate of [`Network::energy_rates`]: the energy over the step, MJ, is
    /// `zᵀ W z` at the step's start.
    pub forms: Vec<DMatrix<f64>>,
}

/// The discretizations in use, most recent first (a master may alternate a few step sizes).
#[derive(Debug, Clone, Default)]
pub struct Cache {
    entries: Vec<Discrete>,
}

/// Discretizations kept.
const CACHE_SIZE: usize = 6;

impl Cache {
    /// The discretization for `(h, topo)`, computed if not cached.
    pub fn get(&mut self, net: &Network, topo: &Topology, h: f64) -> Result<&Discrete, String> {
        match self
            .entries
            .iter()
            .position(|d| d.h == h && d.topo == *topo)
        {
            Some(i) => {
                let d = self.entries.remove(i);
                self.entries.insert(0, d);
            }
            None => {
                self.entries.insert(0, net.discretize(topo, h)?);
                self.entries.truncate(CACHE_SIZE);
            }
        }
        Ok(&self.entries[0])
    }

    /// Forget every discretization (the circuit's data changed).
    pub fn clear(&mut self) {
        self.entries.clear();
    }
}

/// Quadratic form `zᵀ W z`.
pub fn quadratic(w: &DMatrix<f64>, z: &DVector<f64>) -> f64 {
    (w * z).dot(z)
}
