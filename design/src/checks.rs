//! Checks of a synthesis that do not trust the solver: LMI residuals, closed-loop eigenvalues (continuous and sampled with the delay), and the H∞ norm by a frequency sweep.

use crate::plant::{DesignSpec, Measurements, OperatingPoint, Plant, N_STATES};
use crate::synthesis::{brl_matrix, Design};
use dvpp_control::converter::Lcl;
use dvpp_control::ss::expm;
use nalgebra::{Complex, DMatrix};

/// Number of values of μ the grid checks use.
pub const GRID: usize = 50;

/// The values of μ of the grid checks: `GRID` evenly spaced over the range, ends included.
pub fn mu_grid(design: &Design) -> Vec<f64> {
    let [a, b] = design.mu;
    (0..GRID)
        .map(|i| a + (b - a) * i as f64 / (GRID - 1) as f64)
        .collect()
}

/// The largest eigenvalue of each vertex's bounded-real-lemma matrix at the solution (must be
/// negative).
pub fn lmi_residuals(design: &Design) -> [f64; 2] {
    let f = |k: usize| {
        let plant = Plant::at(&design.spec, design.mu[k]);
        let m = brl_matrix(&plant, design.gamma, &design.lyapunov, &design.w[k]);
        m.symmetric_eigen().eigenvalues.max()
    };
    [f(0), f(1)]
}

/// The closed loop `A + B2 K(μ)`, `C1 + D12 K(μ)` in pu time.
pub fn closed_loop(design: &Design, mu: f64) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
    let p = Plant::at(&design.spec, mu);
    let k = design.gain(mu);
    (&p.a + &p.b2 * &k, p.b1, &p.c1 + &p.d12 * &k)
}

/// The largest real part (rad/s) of the continuous closed loop's eigenvalues at `mu`.
pub fn continuous_abscissa(design: &Design, mu: f64) -> f64 {
    let (a, _, _) = closed_loop(design, mu);
    let wb = design.spec.omega_b();
    a.complex_eigenvalues()
        .iter()
        .map(|l| l.re * wb)
        .fold(f64::NEG_INFINITY, f64::max)
}

/// The closed loop as the controller runs it, one sample to the next: the filter sampled
/// exactly at `spec.h` against a stiff grid, the converter voltage the command of the previous
/// sample (one sample of computation delay), the reference model sampled exactly with `Δ|v|`
/// held (`v` the grid-voltage estimate with the transformer's `L_t di_g/dt` over the last
/// sample), the integrals by the forward rule; the gain's delay-lag states fed with that
/// previous command. State `[x_filter (6), u_prev (2), Δq_ref, ξ_q, ξ_w, v_c,prev (2),
/// i_g,prev (2)]`.
pub fn sampled_closed_loop(design: &Design, mu: f64) -> DMatrix<f64> {
    let spec: &DesignSpec = &design.spec;
    let wb = spec.omega_b();
    let h = spec.h;
    let (a, b) = Lcl::continuous(&spec.data, wb, 1.0);
    let mut m = DMatrix::zeros(8, 8);
    m.view_mut((0, 0), (6, 6)).copy_from(&(a * h));
    m.view_mut((0, 6), (6, 2))
        .copy_from(&(b.view((0, 0), (6, 2)) * h));
    let e = expm(&m);
    let meas = Measurements::of(spec, &OperatingPoint::of(spec));
    let k = design.gain(mu);
    let n = N_STATES;
    let mut phi = DMatrix::zeros(n + 4, n + 4);
    // Filter driven by the previous command.
    phi.view_mut((0, 0), (6, 8))
        .copy_from(&e.view((0, 0), (6, 8)));
    // The new command from the state now.
    phi.view_mut((6, 0), (2, n)).copy_from(&k);
    // Reference model: x_r+ = a x_r + (1 - a)(-k_q μ Δ|v|), with `v` the grid-voltage estimate
    // the controller computes between the last two samples, `(v̂_g + v̂_g,prev)/2 -
    // L_t (i_g - i_g,prev)/(ω_b h)`: on a stiff grid only its error against the transformer's
    // exact relation is left of the states.
    let ar = (-h / spec.tau_q).exp();
    let c = spec.data.l_t / (wb * h);
    let op = OperatingPoint::of(spec);
    let dir = op.v_g * (1.0 / op.v_g.norm());
    // Δ|v| over [x_filter now, v_c,prev, i_g,prev].
    let mut dv = DMatrix::zeros(1, n + 4);
    for j in 0..6 {
        dv[(0, j)] = 0.5 * meas.dv[j];
    }
    for (j, col) in [(2, n), (3, n + 1), (4, n + 2), (5, n + 3)] {
        dv[(0, col)] = 0.5 * meas.dv[j];
    }
    for (j, col, d) in [(4, n + 2, dir.d), (5, n + 3, dir.q)] {
        dv[(0, j)] -= c * d;
        dv[(0, col)] += c * d;
    }
    phi[(8, 8)] = ar;
    for col in 0..n + 4 {
        phi[(8, col)] += -(1.0 - ar) * spec.k_q * mu * dv[(0, col)];
    }
    for j in 0..6 {
        phi[(9, j)] = wb * h * meas.dq[j];
        phi[(10, j)] = wb * h * meas.dwq[j];
    }
    phi[(9, 8)] = -wb * h;
    phi[(9, 9)] = 1.0;
    phi[(10, 10)] = 1.0;
    // The capacitor voltage and the grid-side current of the previous sample.
    for (j, col) in [(2, n), (3, n + 1), (4, n + 2), (5, n + 3)] {
        phi[(col, j)] = 1.0;
    }
    phi
}

/// The largest eigenvalue magnitude of [`sampled_closed_loop`] at `mu`.
pub fn sampled_radius(design: &Design, mu: f64) -> f64 {
    sampled_closed_loop(design, mu)
        .complex_eigenvalues()
        .iter()
        .map(|l| l.norm())
        .fold(0.0, f64::max)
}

/// The largest singular value of `C (jω I - A)⁻¹ B` (ω in pu of `ω_b`).
pub fn sigma_max(a: &DMatrix<f64>, b: &DMatrix<f64>, c: &DMatrix<f64>, omega: f64) -> f64 {
    let n = a.nrows();
    let jw = DMatrix::<Complex<f64>>::from_diagonal_element(n, n, Complex::new(0.0, omega));
    let m = jw - a.map(|v| Complex::new(v, 0.0));
    let x = m
        .lu()
        .solve(&b.map(|v| Complex::new(v, 0.0)))
        .expect("jω is no eigenvalue of a stable closed loop");
    let g = c.map(|v| Complex::new(v, 0.0)) * x;
    let gg = g.adjoint() * &g;
    // Hermitian: the eigenvalues of its real embedding are its eigenvalues, each twice.
    let r = gg.nrows();
    let mut emb = DMatrix::zeros(2 * r, 2 * r);
    for i in 0..r {
        for j in 0..r {
            let z = gg[(i, j)];
            emb[(i, j)] = z.re;
            emb[(i + r, j + r)] = z.re;
            emb[(i, j + r)] = -z.im;
            emb[(i + r, j)] = z.im;
        }
    }
    emb.symmetric_eigen().eigenvalues.max().max(0.0).sqrt()
}

/// The H∞ norm of the closed loop at `mu` by a frequency sweep: `σ_max` on a logarithmic grid of
/// 2000 frequencies from 1e-5 to 1e3 pu of `ω_b` (5e-4 Hz to 50 kHz at 50 Hz), then refined
/// by golden-section search around the grid's peak. Returns the peak and its frequency (pu).
pub fn hinf_sweep(design: &Design, mu: f64) -> (f64, f64) {
    let (a, b, c) = closed_loop(design, mu);
    sweep_peak(&a, &b, &c)
}

/// The largest `σ_max(C (jωI - A)⁻¹ B)` over frequency, as [`hinf_sweep`] finds it, and where.
pub fn sweep_peak(a: &DMatrix<f64>, b: &DMatrix<f64>, c: &DMatrix<f64>) -> (f64, f64) {
    let f = |w: f64| sigma_max(a, b, c, w);
    let (lo, hi, n) = (-5.0f64, 3.0f64, 2000);
    let at = |i: usize| 10f64.powf(lo + (hi - lo) * i as f64 / (n - 1) as f64);
    let mut best = (0, f64::NEG_INFINITY);
    for i in 0..n {
        let v = f(at(i));
        if v > best.1 {
            best = (i, v);
        }
    }
    // Golden section on log ω between the neighbours of the grid's peak.
    let (mut a_, mut b_) = (
        at(best.0.saturating_sub(1)).ln(),
        at((best.0 + 1).min(n - 1)).ln(),
    );
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let mut peak = (best.1, at(best.0));
    for _ in 0..60 {
        let (x1, x2) = (b_ - g * (b_ - a_), a_ + g * (b_ - a_));
        let (f1, f2) = (f(x1.exp()), f(x2.exp()));
        if f1 > peak.0 {
            peak = (f1, x1.exp());
        }
        if f2 > peak.0 {
            peak = (f2, x2.exp());
        }
        if f1 > f2 {
            b_ = x2;
        } else {
            a_ = x1;
        }
    }
    // The static gain too (ω → 0), which the grid's lowest frequency approaches.
    let dc = f(0.0);
    if dc > peak.0 {
        peak = (dc, 0.0);
    }
    peak
}

/// The range of factors `[g_lo, g_hi]` on the whole gain `K(μ)` for which the sampled closed
/// loop with its delay stays stable at every μ of the grid: the loop's gain margins, measured on
/// 400 factors spaced logarithmically from 0.01 to 100 (the ends mean "at least").
pub fn gain_margins(design: &Design) -> (f64, f64) {
    let grid = mu_grid(design);
    let stable = |g: f64| {
        let mut d = design.clone();
        for k in &mut d.gains {
            *k *= g;
        }
        grid.iter().all(|&mu| sampled_radius(&d, mu) < 1.0)
    };
    let factor = |i: i32| 10f64.powf(i as f64 / 100.0);
    let (mut lo, mut hi) = (0, 0);
    while lo > -200 && stable(factor(lo - 1)) {
        lo -= 1;
    }
    while hi < 200 && stable(factor(hi + 1)) {
        hi += 1;
    }
    (factor(lo), factor(hi))
}

/// All checks, as figures.
#[derive(Debug, Clone)]
pub struct Report {
    /// The achieved bound.
    pub gamma: f64,
    /// Largest eigenvalue of each vertex LMI at the solution.
    pub residuals: [f64; 2],
    /// Largest real part (rad/s) of the continuous closed loop over the μ grid, and where.
    pub worst_real_part: (f64, f64),
    /// Largest eigenvalue magnitude (rad/s) of the continuous closed loop over the grid.
    pub fastest_pole: f64,
    /// Largest eigenvalue magnitude of the sampled closed loop with the delay over the grid.
    pub worst_sampled_radius: (f64, f64),
    /// Largest swept H∞ norm over the grid: (norm, μ, frequency in Hz).
    pub worst_sweep: (f64, f64, f64),
    /// The sampled loop's gain margins ([`gain_margins`]).
    pub gain_margins: (f64, f64),
    /// The swept norm at each μ of the grid.
    pub sweep: Vec<(f64, f64)>,
}

impl Report {
    /// Run all checks on `design`.
    pub fn of(design: &Design) -> Report {
        let grid = mu_grid(design);
        let worst = |f: &dyn Fn(f64) -> f64| {
            grid.iter()
                .map(|&mu| (f(mu), mu))
                .fold(
                    (f64::NEG_INFINITY, 0.0),
                    |a, b| if b.0 > a.0 { b } else { a },
                )
        };
        let sweep: Vec<(f64, f64)> = grid
            .iter()
            .map(|&mu| (mu, hinf_sweep(design, mu).0))
            .collect();
        let (mut ws, mut wmu) = (f64::NEG_INFINITY, 0.0);
        for &(mu, s) in &sweep {
            if s > ws {
                (ws, wmu) = (s, mu);
            }
        }
        let w_hz = hinf_sweep(design, wmu).1 * design.spec.f_nom;
        Report {
            gamma: design.gamma,
            residuals: lmi_residuals(design),
            worst_real_part: worst(&|mu| continuous_abscissa(design, mu)),
            fastest_pole: worst(&|mu| {
                let (a, _, _) = closed_loop(design, mu);
                a.complex_eigenvalues()
                    .iter()
                    .map(|l| l.norm() * design.spec.omega_b())
                    .fold(0.0, f64::max)
            })
            .0,
            worst_sampled_radius: worst(&|mu| sampled_radius(design, mu)),
            worst_sweep: (ws, wmu, w_hz),
            gain_margins: gain_margins(design),
            sweep,
        }
    }

    /// Whether every check passes: residuals below zero, both closed loops stable at every μ of
    /// the grid, the swept norm within 1 % of γ.
    pub fn passes(&self) -> bool {
        self.residuals.iter().all(|r| *r < 0.0)
            && self.worst_real_part.0 < 0.0
            && self.worst_sampled_radius.0 < 1.0
            && self.worst_sweep.0 <= 1.01 * self.gamma
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A lightly damped second-order system `ω_n²/(s² + 2ζω_n s + ω_n²)` peaks at
    /// `1/(2ζ√(1-ζ²))` at `ω_n √(1-2ζ²)`.
    #[test]
    fn sweep_finds_a_resonant_peak() {
        let (wn, z) = (3.7, 0.02);
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -wn * wn, -2.0 * z * wn]);
        let b = DMatrix::from_column_slice(2, 1, &[0.0, wn * wn]);
        let c = DMatrix::from_row_slice(1, 2, &[1.0, 0.0]);
        let (peak, w) = sweep_peak(&a, &b, &c);
        let exact = 1.0 / (2.0 * z * (1.0 - z * z).sqrt());
        assert!((peak / exact - 1.0).abs() < 1e-9, "{peak} {exact}");
        assert!(
            (w / (wn * (1.0 - 2.0 * z * z).sqrt()) - 1.0).abs() < 1e-4,
            "{w}"
        );
    }

    /// Two outputs: `σ_max` of a static 2×1 gain is its Euclidean norm, reached at dc.
    #[test]
    fn sigma_max_of_a_vector_gain() {
        let a = DMatrix::from_row_slice(1, 1, &[-1.0]);
        let b = DMatrix::from_row_slice(1, 1, &[1.0]);
        let c = DMatrix::from_column_slice(2, 1, &[3.0, 4.0]);
        assert!((sigma_max(&a, &b, &c, 0.0) - 5.0).abs() < 1e-12);
        assert!((sigma_max(&a, &b, &c, 1.0) - 5.0 / 2f64.sqrt()).abs() < 1e-12);
    }
}
