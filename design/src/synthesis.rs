//! The LPV H∞ state-feedback problem over the range of μ: bounded-real-lemma LMIs at the vertices with one common Lyapunov matrix.
//!
//! For `x' = A(μ) x + B1 w + B2 u`, `z = C1 x + D12 u` and `u = K(μ) x`, the closed loop's H∞
//! norm from `w` to `z` is below `γ` if there are `X = Xᵀ ≻ 0` and `W(μ)` with
//!
//! ```text
//! [ A X + X Aᵀ + B2 W + Wᵀ B2ᵀ   B1    (C1 X + D12 W)ᵀ ]
//! [ B1ᵀ                         -γ I   0               ]  ≺ 0,   K = W X⁻¹.
//! [ C1 X + D12 W                 0    -γ I             ]
//! ```
//!
//! The plant is multi-affine in `(μ, θ, φ)` (μ the reference model's input gain, `θ`, `φ` the
//! grid behind the transformer, [`Grid`]) and `B2`, `C1`, `D12` do not depend on them, so with
//! `W` affine in μ the left-hand side is multi-affine in `(μ, θ, φ)`: on the box it is a convex
//! combination of its values at the corners. Imposed at every corner with one `X`, and a `W_k`
//! per end of μ (the grid is not measured, so `W` does not depend on it), it holds on the whole
//! box with `W(μ)` the same combination of the `W_k`, and so for `K(μ) = W(μ) X⁻¹`, the linear
//! interpolation of the vertex gains `K_k = W_k X⁻¹`. Minimizing `γ` over `(γ, X, W_0, W_1)` is
//! one semidefinite program, solved by clarabel.

use crate::plant::{DesignSpec, Grid, Plant, N_DISTURBANCES, N_INPUTS, N_OUTPUTS, N_STATES};
use crate::sdp::{minimize, Lmi, Solution};
use nalgebra::DMatrix;

/// Strictness margin of the vertex LMIs and of `X ≻ 0`.
pub const MARGIN: f64 = 1e-6;

/// Where the decision variables sit in the decision vector: `γ`, the upper triangle of `X`
/// (column by column), then each vertex's `W_k` (row by row).
#[derive(Debug, Clone, Copy)]
pub struct Layout {
    n: usize,
    m: usize,
    vertices: usize,
}

impl Layout {
    fn for_plant(vertices: usize) -> Layout {
        Layout {
            n: N_STATES,
            m: N_INPUTS,
            vertices,
        }
    }

    fn n_x(&self) -> usize {
        self.n * (self.n + 1) / 2
    }

    /// Length of the decision vector.
    pub fn len(&self) -> usize {
        1 + self.n_x() + self.vertices * self.m * self.n
    }

    /// Whether the decision vector is empty (never).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// `γ`.
    pub fn gamma(&self, x: &[f64]) -> f64 {
        x[0]
    }

    /// `X`.
    pub fn lyapunov(&self, x: &[f64]) -> DMatrix<f64> {
        let mut out = DMatrix::zeros(self.n, self.n);
        let mut idx = 1;
        for col in 0..self.n {
            for row in 0..=col {
                out[(row, col)] = x[idx];
                out[(col, row)] = x[idx];
                idx += 1;
            }
        }
        out
    }

    /// `W_k`.
    pub fn w(&self, x: &[f64], k: usize) -> DMatrix<f64> {
        let start = 1 + self.n_x() + k * self.m * self.n;
        DMatrix::from_row_slice(self.m, self.n, &x[start..start + self.m * self.n])
    }
}

/// The bounded-real-lemma matrix of `plant` at `(γ, X, W)`.
pub fn brl_matrix(plant: &Plant, gamma: f64, x: &DMatrix<f64>, w: &DMatrix<f64>) -> DMatrix<f64> {
    let (n, nw, nz) = (N_STATES, N_DISTURBANCES, N_OUTPUTS);
    let mut m = DMatrix::zeros(n + nw + nz, n + nw + nz);
    let ax_bw = &plant.a * x + &plant.b2 * w;
    m.view_mut((0, 0), (n, n))
        .copy_from(&(&ax_bw + ax_bw.transpose()));
    m.view_mut((0, n), (n, nw)).copy_from(&plant.b1);
    m.view_mut((n, 0), (nw, n)).copy_from(&plant.b1.transpose());
    let cz = &plant.c1 * x + &plant.d12 * w;
    m.view_mut((n + nw, 0), (nz, n)).copy_from(&cz);
    m.view_mut((0, n + nw), (n, nz)).copy_from(&cz.transpose());
    for i in n..n + nw + nz {
        m[(i, i)] = -gamma;
    }
    m
}

/// The pole-region matrix of `plant` at `(X, W)`: `[-r X, A X + B2 W; (A X + B2 W)ᵀ, -r X] ≺ 0`
/// puts the eigenvalues of `A + B2 W X⁻¹` in the disk of radius `r` about the origin.
pub fn disk_matrix(plant: &Plant, r: f64, x: &DMatrix<f64>, w: &DMatrix<f64>) -> DMatrix<f64> {
    let n = N_STATES;
    let mut m = DMatrix::zeros(2 * n, 2 * n);
    let ax_bw = &plant.a * x + &plant.b2 * w;
    m.view_mut((0, 0), (n, n)).copy_from(&(x * -r));
    m.view_mut((n, n), (n, n)).copy_from(&(x * -r));
    m.view_mut((0, n), (n, n)).copy_from(&ax_bw);
    m.view_mut((n, 0), (n, n)).copy_from(&ax_bw.transpose());
    m
}

/// The result of a synthesis.
#[derive(Debug, Clone)]
pub struct Design {
    /// What it was designed for.
    pub spec: DesignSpec,
    /// The vertices of μ.
    pub mu: [f64; 2],
    /// The vertex gains `K_k = W_k X⁻¹` (inputs × states).
    pub gains: [DMatrix<f64>; 2],
    /// The achieved bound `γ`.
    pub gamma: f64,
    /// The common Lyapunov matrix.
    pub lyapunov: DMatrix<f64>,
    /// The vertex `W_k`.
    pub w: [DMatrix<f64>; 2],
    /// Clarabel's status.
    pub status: String,
    /// Interior-point iterations.
    pub iterations: u32,
}

impl Design {
    /// `K(μ)`: the vertex gains interpolated linearly (μ clamped to the range).
    pub fn gain(&self, mu: f64) -> DMatrix<f64> {
        let l = ((mu - self.mu[0]) / (self.mu[1] - self.mu[0])).clamp(0.0, 1.0);
        &self.gains[0] * (1.0 - l) + &self.gains[1] * l
    }

    /// `W(μ)`, interpolated as `K(μ)`.
    pub fn w_at(&self, mu: f64) -> DMatrix<f64> {
        let l = ((mu - self.mu[0]) / (self.mu[1] - self.mu[0])).clamp(0.0, 1.0);
        &self.w[0] * (1.0 - l) + &self.w[1] * l
    }
}

/// Minimize γ (the layout's first variable) subject to `lmis` and `X` positive definite.
fn minimize_gamma<'a>(layout: Layout, mut lmis: Vec<Lmi<'a>>) -> Result<Solution, String> {
    lmis.push(Lmi {
        name: "X positive definite".into(),
        f: Box::new(move |x: &[f64]| -layout.lyapunov(x)),
        margin: MARGIN,
    });
    let mut c = vec![0.0; layout.len()];
    c[0] = 1.0;
    minimize(&c, &lmis)
}

/// The plant at each end `k` of μ and each corner of the box of grids: `(k, grid, plant)`.
fn corner_plants(spec: &DesignSpec) -> Vec<(usize, Grid, Plant)> {
    let mu = [spec.mu_min, spec.mu_max];
    (0..2)
        .flat_map(|k| {
            spec.grid_corners()
                .into_iter()
                .map(move |g| (k, g, Plant::at(spec, mu[k], g)))
        })
        .collect()
}

/// Solve the LPV H∞ problem of `spec`.
pub fn synthesize(spec: &DesignSpec) -> Result<Design, String> {
    let mu = [spec.mu_min, spec.mu_max];
    let plants = corner_plants(spec);
    let layout = Layout::for_plant(2);
    let mut lmis: Vec<Lmi> = Vec::new();
    for (k, grid, plant) in plants.iter() {
        let k = *k;
        let at = format!("mu = {}, theta = {}, phi = {}", mu[k], grid.theta, grid.phi);
        lmis.push(Lmi {
            name: format!("bounded-real lemma at {at}"),
            f: Box::new(move |x: &[f64]| {
                brl_matrix(plant, layout.gamma(x), &layout.lyapunov(x), &layout.w(x, k))
            }),
            margin: MARGIN,
        });
        let r = spec.pole_radius;
        lmis.push(Lmi {
            name: format!("pole region at {at}"),
            f: Box::new(move |x: &[f64]| {
                disk_matrix(plant, r, &layout.lyapunov(x), &layout.w(x, k))
            }),
            margin: MARGIN,
        });
    }
    let sol = minimize_gamma(layout, lmis)?;
    let x = &sol.x;
    let lyap = layout.lyapunov(x);
    let inv = lyap
        .clone()
        .try_inverse()
        .ok_or("the Lyapunov matrix is singular")?;
    let w = [layout.w(x, 0), layout.w(x, 1)];
    Ok(Design {
        spec: *spec,
        mu,
        gains: [&w[0] * &inv, &w[1] * &inv],
        gamma: layout.gamma(x),
        lyapunov: lyap,
        w,
        status: sol.status,
        iterations: sol.iterations,
    })
}

/// The analysis problem for given vertex gains: the smallest `γ` that one common Lyapunov matrix
/// certifies for `K(μ)`, the linear interpolation of `gains` over `[spec.mu_min, spec.mu_max]`,
/// on the box of grids — the LMIs of [`synthesize`] with `W_k = K_k X` (affine in `(γ, X)` for
/// fixed gains). It gives gains that did not come out of this run's synthesis (the committed
/// file's) the `X` and `W_k` the LMI residuals of [`crate::checks`] need: the solver only finds
/// the certificate, the residuals verify it without the solver. The gains are not changed.
pub fn certify(spec: &DesignSpec, gains: &[DMatrix<f64>; 2]) -> Result<Design, String> {
    let mu = [spec.mu_min, spec.mu_max];
    let plants = corner_plants(spec);
    // γ and X only: no W.
    let layout = Layout::for_plant(0);
    let mut lmis: Vec<Lmi> = Vec::new();
    for (k, grid, plant) in plants.iter() {
        let gain = &gains[*k];
        let at = format!(
            "mu = {}, theta = {}, phi = {}",
            mu[*k], grid.theta, grid.phi
        );
        lmis.push(Lmi {
            name: format!("bounded-real lemma at {at}"),
            f: Box::new(move |x: &[f64]| {
                let lyap = layout.lyapunov(x);
                brl_matrix(plant, layout.gamma(x), &lyap, &(gain * &lyap))
            }),
            margin: MARGIN,
        });
        let r = spec.pole_radius;
        lmis.push(Lmi {
            name: format!("pole region at {at}"),
            f: Box::new(move |x: &[f64]| {
                let lyap = layout.lyapunov(x);
                disk_matrix(plant, r, &lyap, &(gain * &lyap))
            }),
            margin: MARGIN,
        });
    }
    let sol = minimize_gamma(layout, lmis)?;
    let lyap = layout.lyapunov(&sol.x);
    Ok(Design {
        spec: *spec,
        mu,
        gains: gains.clone(),
        gamma: layout.gamma(&sol.x),
        w: [&gains[0] * &lyap, &gains[1] * &lyap],
        lyapunov: lyap,
        status: sol.status,
        iterations: sol.iterations,
    })
}
