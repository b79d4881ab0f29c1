//! Checks of a synthesis that do not trust the solver: LMI residuals, closed-loop eigenvalues (continuous and sampled with the delay), and the H∞ norm by a frequency sweep.

use crate::plant::{Adpf, DesignSpec, Frame, Grid, Measurements, OperatingPoint, Plant, N_STATES};
use crate::synthesis::{brl_matrix, Design};
use dvpp_control::converter::Lcl;
use dvpp_control::ss::expm;
use nalgebra::linalg::Schur;
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

/// The grids the checks use: the design's box at its corners, the middles of its edges and its
/// centre (the stiff grid alone for a stiff design).
pub fn grid_points(spec: &DesignSpec) -> Vec<Grid> {
    let mut out: Vec<Grid> = Vec::new();
    for i in 0..3 {
        for j in 0..3 {
            let g = Grid {
                theta: 1.0 - (1.0 - spec.theta_min) * i as f64 / 2.0,
                phi: spec.phi_max * j as f64 / 2.0,
            };
            if !out.contains(&g) {
                out.push(g);
            }
        }
    }
    out
}

/// Every `(μ, grid)` the grid checks visit: [`mu_grid`] × [`grid_points`].
pub fn cases(design: &Design) -> Vec<(f64, Grid)> {
    let grids = grid_points(&design.spec);
    mu_grid(design)
        .into_iter()
        .flat_map(|mu| grids.iter().map(move |&g| (mu, g)))
        .collect()
}

/// The largest eigenvalue of each vertex's bounded-real-lemma matrix at the solution (must be
/// negative): `(μ, grid, eigenvalue)` at every corner of the design's box.
pub fn lmi_residuals(design: &Design) -> Vec<(f64, Grid, f64)> {
    let mut out = Vec::new();
    for k in 0..2 {
        for g in design.spec.grid_corners() {
            let plant = Plant::at(&design.spec, design.mu[k], g);
            let m = brl_matrix(&plant, design.gamma, &design.lyapunov, &design.w[k]);
            out.push((design.mu[k], g, m.symmetric_eigen().eigenvalues.max()));
        }
    }
    out
}

/// The closed loop `A + B2 K(μ)`, `C1 + D12 K(μ)` in pu time on `grid`.
pub fn closed_loop(
    design: &Design,
    mu: f64,
    grid: Grid,
) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
    let p = Plant::at(&design.spec, mu, grid);
    let k = design.gain(mu);
    (&p.a + &p.b2 * &k, p.b1, &p.c1 + &p.d12 * &k)
}

/// The largest real part (rad/s) of the continuous closed loop's eigenvalues at `mu` on `grid`.
pub fn continuous_abscissa(design: &Design, mu: f64, grid: Grid) -> f64 {
    let (a, _, _) = closed_loop(design, mu, grid);
    let wb = design.spec.omega_b();
    eigenvalues(&a)
        .iter()
        .map(|l| l.re * wb)
        .fold(f64::NEG_INFINITY, f64::max)
}

/// The closed loop as the controller runs it, one sample to the next: the filter sampled
/// exactly at `spec.h` against `grid` (the source behind it held), the converter voltage the
/// command of the previous sample (one sample of computation delay), the reference model sampled
/// exactly with `Δ|v|` held (`v` the grid-voltage estimate with the transformer's `L_t di_g/dt`
/// over the last sample), the integrals by the forward rule; the gain's delay-lag states fed
/// with that previous command. State `[x_filter (6), u_prev (2), Δq_ref, ξ_q, ξ_w, v_c,prev (2),
/// i_g,prev (2)]`.
pub fn sampled_closed_loop(design: &Design, mu: f64, grid: Grid) -> DMatrix<f64> {
    let spec: &DesignSpec = &design.spec;
    let wb = spec.omega_b();
    let h = spec.h;
    let (a, b) = Lcl::continuous(&grid.series(&spec.data), wb, 1.0);
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
    // exact relation is left of the states, behind an impedance the divider's share too.
    let ar = dvpp_math::exp(-h / spec.tau_q);
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

/// The frame's swing with the gains closed (continuous): the rightmost eigenvalue of the
/// closed loop with the p-f reference model's frame ([`Plant::with_frame`]; the gains act on
/// the design's states, not on the frame's), as (real part in rad/s, frequency in Hz). The
/// design model holds the frame fixed; this is what its gains do to it.
pub fn frame_mode(design: &Design, mu: f64, grid: Grid, frame: &Frame) -> (f64, f64) {
    let p = Plant::with_frame(&design.spec, mu, grid, frame);
    let mut k = DMatrix::zeros(p.b2.ncols(), p.a.nrows());
    k.view_mut((0, 0), (p.b2.ncols(), N_STATES))
        .copy_from(&design.gain(mu));
    let wb = design.spec.omega_b();
    eigenvalues(&(&p.a + &p.b2 * k))
        .iter()
        .map(|l| (l.re * wb, l.im.abs() * wb / (2.0 * std::f64::consts::PI)))
        .fold(
            (f64::NEG_INFINITY, 0.0),
            |a, b| if b.0 > a.0 { b } else { a },
        )
}

/// The units the frame check visits (name, frame): the generic unit (60 MVA in 96) with static
/// p-f dc gains from 1 down to the grid-forming floor `MU_MIN_GFM` = 0.05, and case study I's
/// BESS (60 MVA) with the complement of the wind's and the PV's low-pass shares. Units with a
/// low-pass ADPF are not in it: there the model and EMT disagree (docs/hinf.md §8).
pub fn frame_units() -> Vec<(String, Frame)> {
    let mut out = Vec::new();
    for mu in [1.0, 0.6, 0.3, 0.2, 0.1, 0.05] {
        out.push((
            format!("static mu_p {mu}"),
            Frame::unit(60.0, 96.0, Adpf::Static(mu)),
        ));
    }
    for (mw, mp) in [(0.38, 0.62), (0.1, 0.1), (0.5, 0.5)] {
        out.push((
            format!("BESS, complement of wind {mw} and PV {mp}"),
            Frame::unit(60.0, 96.0, Adpf::Complement(vec![(mw, 1.5), (mp, 0.6)])),
        ));
    }
    out
}

/// The frame's worst swing over the grids of [`grid_points`] and the island's load, the units
/// of [`frame_units`] and 11 values of μ: (real part in rad/s, frequency in Hz, μ, grid, unit).
pub fn worst_frame(design: &Design) -> (f64, f64, f64, Grid, String) {
    let spec = &design.spec;
    let mut grids = grid_points(spec);
    grids.push(Grid::behind(spec.data.l_t, 1.923, 0.385));
    let mut worst = (f64::NEG_INFINITY, 0.0, 0.0, Grid::STIFF, String::new());
    for (name, frame) in frame_units() {
        for &g in &grids {
            for i in 0..11 {
                let mu = design.mu[0] + (design.mu[1] - design.mu[0]) * i as f64 / 10.0;
                let (re, hz) = frame_mode(design, mu, g, &frame);
                if re > worst.0 {
                    worst = (re, hz, mu, g, name.clone());
                }
            }
        }
    }
    worst
}

/// The eigenvalues of `m`, by the real Schur form with a bounded number of iterations.
///
/// nalgebra's `complex_eigenvalues` iterates without bound at machine precision, and its QR
/// iteration (no exceptional shifts) can cycle without converging: it did, for ever, on a sampled
/// closed loop of a fresh synthesis with OpenBLAS's Prescott kernel and one thread, at every
/// tolerance. Here each attempt stops after 10 000 iterations; the next takes the same
/// eigenvalues from the transpose, then from `D m D⁻¹` with `D` powers of two (exact), which
/// start the iteration elsewhere, and deflates at a looser tolerance (at most 1e-12 relative to
/// the neighbouring diagonal entries, far below the checks' margins).
pub fn eigenvalues(m: &DMatrix<f64>) -> Vec<Complex<f64>> {
    let n = m.nrows();
    let scaled = DMatrix::from_fn(n, n, |i, j| {
        m[(i, j)] * dvpp_math::powi(2.0, (i % 3) as i32 - (j % 3) as i32)
    });
    for eps in [f64::EPSILON, 1e-14, 1e-12] {
        for candidate in [m, &m.transpose(), &scaled] {
            if let Some(s) = Schur::try_new(candidate.clone(), eps, 10_000) {
                return s.complex_eigenvalues().iter().copied().collect();
            }
        }
    }
    panic!("the Schur iteration does not converge on a {n}×{n} matrix")
}

/// The largest eigenvalue magnitude of [`sampled_closed_loop`] at `mu` on `grid`.
pub fn sampled_radius(design: &Design, mu: f64, grid: Grid) -> f64 {
    eigenvalues(&sampled_closed_loop(design, mu, grid))
        .iter()
        .map(|&l| dvpp_math::cabs(l))
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

/// The H∞ norm of the closed loop at `mu` on `grid` by a frequency sweep: `σ_max` on a
/// logarithmic grid of 2000 frequencies from 1e-5 to 1e3 pu of `ω_b` (5e-4 Hz to 50 kHz at
/// 50 Hz), then refined by golden-section search around the grid's peak. Returns the peak and its frequency (pu).
pub fn hinf_sweep(design: &Design, mu: f64, grid: Grid) -> (f64, f64) {
    let (a, b, c) = closed_loop(design, mu, grid);
    sweep_peak(&a, &b, &c)
}

/// The largest `σ_max(C (jωI - A)⁻¹ B)` over frequency, as [`hinf_sweep`] finds it, and where.
pub fn sweep_peak(a: &DMatrix<f64>, b: &DMatrix<f64>, c: &DMatrix<f64>) -> (f64, f64) {
    let f = |w: f64| sigma_max(a, b, c, w);
    let (lo, hi, n) = (-5.0f64, 3.0f64, 2000);
    let at = |i: usize| dvpp_math::pow(10f64, lo + (hi - lo) * i as f64 / (n - 1) as f64);
    let mut best = (0, f64::NEG_INFINITY);
    for i in 0..n {
        let v = f(at(i));
        if v > best.1 {
            best = (i, v);
        }
    }
    // Golden section on log ω between the neighbours of the grid's peak.
    let (mut a_, mut b_) = (
        dvpp_math::log(at(best.0.saturating_sub(1))),
        dvpp_math::log(at((best.0 + 1).min(n - 1))),
    );
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let mut peak = (best.1, at(best.0));
    for _ in 0..60 {
        let (x1, x2) = (b_ - g * (b_ - a_), a_ + g * (b_ - a_));
        let (f1, f2) = (f(dvpp_math::exp(x1)), f(dvpp_math::exp(x2)));
        if f1 > peak.0 {
            peak = (f1, dvpp_math::exp(x1));
        }
        if f2 > peak.0 {
            peak = (f2, dvpp_math::exp(x2));
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
/// loop with its delay stays stable at every `(μ, grid)` of [`cases`]: the loop's gain margins,
/// measured on 400 factors spaced logarithmically from 0.01 to 100 (the ends mean "at least").
pub fn gain_margins(design: &Design) -> (f64, f64) {
    let cases = cases(design);
    let stable = |g: f64| {
        let mut d = design.clone();
        for k in &mut d.gains {
            *k *= g;
        }
        cases
            .iter()
            .all(|&(mu, grid)| sampled_radius(&d, mu, grid) < 1.0)
    };
    let factor = |i: i32| dvpp_math::pow(10f64, i as f64 / 100.0);
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
    /// Largest eigenvalue of each corner's bounded-real-lemma matrix at the solution.
    pub residuals: Vec<(f64, Grid, f64)>,
    /// Largest real part (rad/s) of the continuous closed loop over [`cases`], and where.
    pub worst_real_part: (f64, f64, Grid),
    /// Largest eigenvalue magnitude (rad/s) of the continuous closed loop over [`cases`].
    pub fastest_pole: f64,
    /// Largest eigenvalue magnitude of the sampled closed loop with the delay over [`cases`].
    pub worst_sampled_radius: (f64, f64, Grid),
    /// Largest swept H∞ norm over [`cases`]: (norm, μ, grid, frequency in Hz).
    pub worst_sweep: (f64, f64, Grid, f64),
    /// The sampled loop's gain margins ([`gain_margins`]).
    pub gain_margins: (f64, f64),
    /// The frame's worst swing ([`worst_frame`]).
    pub worst_frame: (f64, f64, f64, Grid, String),
    /// The swept norm at each `(μ, grid)` of [`cases`].
    pub sweep: Vec<(f64, Grid, f64)>,
}

impl Report {
    /// Run all checks on `design`.
    pub fn of(design: &Design) -> Report {
        let cases = cases(design);
        let worst = |f: &dyn Fn(f64, Grid) -> f64| {
            cases.iter().map(|&(mu, g)| (f(mu, g), mu, g)).fold(
                (f64::NEG_INFINITY, 0.0, Grid::STIFF),
                |a, b| {
                    if b.0 > a.0 {
                        b
                    } else {
                        a
                    }
                },
            )
        };
        let sweep: Vec<(f64, Grid, f64)> = cases
            .iter()
            .map(|&(mu, g)| (mu, g, hinf_sweep(design, mu, g).0))
            .collect();
        let (mut ws, mut wmu, mut wg) = (f64::NEG_INFINITY, 0.0, Grid::STIFF);
        for &(mu, g, s) in &sweep {
            if s > ws {
                (ws, wmu, wg) = (s, mu, g);
            }
        }
        let w_hz = hinf_sweep(design, wmu, wg).1 * design.spec.f_nom;
        Report {
            gamma: design.gamma,
            residuals: lmi_residuals(design),
            worst_real_part: worst(&|mu, g| continuous_abscissa(design, mu, g)),
            fastest_pole: worst(&|mu, g| {
                let (a, _, _) = closed_loop(design, mu, g);
                eigenvalues(&a)
                    .iter()
                    .map(|&l| dvpp_math::cabs(l) * design.spec.omega_b())
                    .fold(0.0, f64::max)
            })
            .0,
            worst_sampled_radius: worst(&|mu, g| sampled_radius(design, mu, g)),
            worst_sweep: (ws, wmu, wg, w_hz),
            gain_margins: gain_margins(design),
            worst_frame: worst_frame(design),
            sweep,
        }
    }

    /// Whether every check passes: residuals below zero, both closed loops stable at every
    /// `(μ, grid)` of [`cases`], the swept norm within 1 % of γ, the frame's swing damped.
    pub fn passes(&self) -> bool {
        self.worst_frame.0 < 0.0
            && self.residuals.iter().all(|r| r.2 < 0.0)
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
