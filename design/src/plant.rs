//! The linearized grid-forming converter and the augmented plant the H∞ synthesis works on.
//!
//! Time is in per unit, `t̃ = ω_b t`, so that the matrices have entries of order 1-50 (in
//! seconds the filter's entries reach 3·10³ and the solver's conditioning suffers); the H∞ norm
//! does not change with the time scale, the eigenvalues and frequencies scale by `ω_b`.
//!
//! States (in this order, [`N_STATES`]):
//!
//! | index | state | what |
//! |---|---|---|
//! | 0, 1 | `Δi_f` (d, q) | converter-side filter current |
//! | 2, 3 | `Δv_c` (d, q) | filter-capacitor voltage |
//! | 4, 5 | `Δi_g` (d, q) | grid-side (transformer) current |
//! | 6, 7 | `Δv_m` (d, q) | the converter voltage actually applied: the command through the lag `T_d` that stands for the sampling's delay |
//! | 8 | `Δq_ref` | the local reactive reference model's output |
//! | 9 | `ξ_q` | integral (pu time) of the tracking error `Δq - Δq_ref` |
//! | 10 | `ξ_w` | integral (pu time) of the q-axis of the voltage behind the virtual resistance |
//!
//! Input `u`: the converter-voltage command (d, q). Disturbance `w`: the voltage `Δv_s` (d, q)
//! of the source behind the grid's impedance `R_g + jL_g` beyond the transformer ([`Grid`]: a
//! stiff grid has none, an island is a load impedance with no source). All pu on the
//! converter's rating, in the unit's dq frame at nominal speed. The reference model reads the
//! MV-side voltage's magnitude (the controller computes it with the transformer's
//! `L_t di_g/dt`, see `controllers/src/emt/mod.rs`): on a stiff grid that is `w`, behind an
//! impedance it moves with the unit's own current.

use dvpp_control::converter::{ConverterData, Dq, Lcl};
use nalgebra::{DMatrix, DVector};

/// Number of states of the augmented plant.
pub const N_STATES: usize = 11;
/// Number of control inputs (the converter voltage, d and q).
pub const N_INPUTS: usize = 2;
/// Number of disturbances (the grid voltage, d and q).
pub const N_DISTURBANCES: usize = 2;
/// Number of performance outputs.
pub const N_OUTPUTS: usize = 6;

/// Names of the states, in order (for the generated file and the docs).
pub const STATE_NAMES: [&str; N_STATES] = [
    "i_f.d", "i_f.q", "v_c.d", "v_c.q", "i_g.d", "i_g.q", "v_m.d", "v_m.q", "q_ref", "xi_q", "xi_w",
];

/// The weights of the performance outputs: the design's tuning knobs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Weights {
    /// Tracking weight `w_e`: `z_e = w_e (e + ω_e ξ_q)`, i.e. `W_e(s) = w_e (s + ω_e)/s` on the
    /// reactive tracking error `e = Δq - Δq_ref`.
    pub tracking: f64,
    /// Corner `ω_e` (pu of `ω_b`) below which the tracking weight rises as an integrator.
    pub tracking_corner: f64,
    /// Alignment weight `w_a`: the same shape on `Δw_q`, the q-axis of the voltage behind the
    /// virtual resistance, which the frame's angle is defined by.
    pub alignment: f64,
    /// Corner (pu of `ω_b`) of the alignment weight.
    pub alignment_corner: f64,
    /// Control-effort weight `w_u` on the command `Δu`.
    pub effort: f64,
    /// Roll-off weight `w_r` on `Δu - Δv_m`, the part of the command the delay has not yet
    /// passed: it grows with frequency (`w_r T_d s/(T_d s + 1)` of `Δu`), so it keeps the
    /// command's high-frequency content, and with it the loop's bandwidth, low.
    pub rolloff: f64,
}

impl Default for Weights {
    /// The weights of the committed design (docs/hinf.md says why each).
    fn default() -> Self {
        Weights {
            tracking: 0.05,
            tracking_corner: 0.5,
            alignment: 1.0,
            alignment_corner: 0.5,
            effort: 0.005,
            rolloff: 0.5,
        }
    }
}

/// The grid behind the transformer, as the plant depends on it: `θ = L_t/(L_t + L_g)` and
/// `φ = R_g/(L_t + L_g)` for a source behind `R_g + jL_g` (pu on the rating). The plant is
/// affine in `(θ, φ)`, so a design at the corners of a box of them holds inside it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// `L_t/(L_t + L_g)`: 1 for a stiff grid, towards 0 for a weak one.
    pub theta: f64,
    /// `R_g/(L_t + L_g)`.
    pub phi: f64,
}

impl Grid {
    /// The stiff grid: the MV side is the source.
    pub const STIFF: Grid = Grid {
        theta: 1.0,
        phi: 0.0,
    };

    /// The grid of a source behind `r_g + j l_g` (pu on the rating) for a transformer `l_t`.
    pub fn behind(l_t: f64, r_g: f64, l_g: f64) -> Grid {
        Grid {
            theta: l_t / (l_t + l_g),
            phi: r_g / (l_t + l_g),
        }
    }

    /// The grid's inductance `L_g` for the transformer `l_t`.
    pub fn l_g(&self, l_t: f64) -> f64 {
        l_t / self.theta - l_t
    }

    /// The grid's resistance `R_g` for the transformer `l_t`.
    pub fn r_g(&self, l_t: f64) -> f64 {
        self.phi * l_t / self.theta
    }

    /// The filter data with the grid's impedance added to the transformer's, the series path
    /// from the capacitor to the source.
    pub fn series(&self, data: &ConverterData) -> ConverterData {
        ConverterData {
            l_t: data.l_t + self.l_g(data.l_t),
            r_t: data.r_t + self.r_g(data.l_t),
            ..*data
        }
    }
}

impl std::fmt::Display for Grid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "theta {:.3}, phi {:.3}", self.theta, self.phi)
    }
}

/// What the design is made for: converter, operating point, reference model and range of μ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DesignSpec {
    /// The converter's filter and transformer.
    pub data: ConverterData,
    /// Nominal frequency (Hz).
    pub f_nom: f64,
    /// Active power at the operating point (pu on the rating, at the MV side).
    pub p0: f64,
    /// Reactive power at the operating point (pu on the rating, at the MV side).
    pub q0: f64,
    /// Voltage magnitude at the MV side at the operating point (pu).
    pub v0: f64,
    /// Virtual resistance `vi.r` (pu): the frame is aligned with `v_c + vi.r i_g`.
    pub r_v: f64,
    /// The reactive reference model's gain on the rating at μ = 1: `S_dvpp/(S_rated D_q)`.
    pub k_q: f64,
    /// The reference model's time constant `τ_q` (s).
    pub tau_q: f64,
    /// The lag `T_d` (s) that stands for the sampling's delay (1.5 samples: one of computation,
    /// half a sample of hold).
    pub t_delay: f64,
    /// The controller's sampling step (s).
    pub h: f64,
    /// The range of the scheduling parameter μ (the unit's reactive dc gain).
    pub mu_min: f64,
    /// Upper end of μ.
    pub mu_max: f64,
    /// The performance weights.
    pub weights: Weights,
    /// The grids the design holds on: the box `θ ∈ [theta_min, 1]`, `φ ∈ [0, phi_max]`
    /// ([`Grid`]); `theta_min` = 1 and `phi_max` = 0 is the stiff grid alone.
    pub theta_min: f64,
    /// Upper end of `φ`.
    pub phi_max: f64,
    /// Radius (pu of `ω_b`) of the disk about the origin that holds every closed-loop
    /// eigenvalue at every μ: it keeps the loop well below the sampling rate.
    pub pole_radius: f64,
    /// The frame stabilizer `k_a`: the alignment's integral follows `Δw_q - k_a Δf`, so that the
    /// voltage behind the virtual resistance leads the frame by `k_a Δf` while the frame swings
    /// (pu voltage per pu frequency). It is not in the design model (which holds the frame
    /// fixed); [`Plant::with_frame`] and `checks::frame_mode` have it.
    pub stabilizer: f64,
}

impl Default for DesignSpec {
    /// The EMT-level DER's defaults: the paper's converter, 50 Hz, the generic 60 MVA unit in a
    /// DVPP of 96 MVA with `D_q` = 0.01 and `τ_q` = 10 ms (so `k_q` = 160, the paper's appendix
    /// model `-100 μ/(0.01 s + 1)` on the DVPP base), `vi.r` = 0.3, sampled at 50 µs, at half
    /// load and unity power factor; μ over the whole range `[0, 1]` the operator's reactive
    /// gains `Q_cap,i/Σ Q_cap` take. The grids: from the stiff grid to a source behind
    /// `L_g` = 0.4 pu (θ = 0.2), up to φ = 0.1: `emt_thevenin`'s grid as one unit sees it
    /// (about 0.01 + j0.08 pu: θ 0.56, φ 0.06) lies inside; the island's R-L load (1.9 + j0.39 pu:
    /// θ 0.21, φ 4.0) outside in φ, which the checks measure apart (a box reaching φ = 4 has no
    /// solution: its corner θ = 1, φ = 4 is a source behind 0.4 pu of pure resistance). The
    /// frame stabilizer 9, the middle of the 6 to 11 that pass the frame check; the roll-off 0.5
    /// (docs/hinf.md §3, §8.2).
    fn default() -> Self {
        DesignSpec {
            data: ConverterData::PAPER,
            f_nom: 50.0,
            p0: 0.5,
            q0: 0.0,
            v0: 1.0,
            r_v: 0.3,
            k_q: 96.0 / (60.0 * 0.01),
            tau_q: 0.01,
            t_delay: 1.5 * 50e-6,
            h: 50e-6,
            mu_min: 0.0,
            mu_max: 1.0,
            weights: Weights::default(),
            pole_radius: 50.0,
            stabilizer: 9.0,
            theta_min: 0.2,
            phi_max: 0.1,
        }
    }
}

impl DesignSpec {
    /// `ω_b` (rad/s).
    pub fn omega_b(&self) -> f64 {
        2.0 * std::f64::consts::PI * self.f_nom
    }

    /// The corners of the box of grids (the stiff grid first).
    pub fn grid_corners(&self) -> Vec<Grid> {
        let mut out = vec![Grid::STIFF];
        for (theta, phi) in [
            (1.0, self.phi_max),
            (self.theta_min, 0.0),
            (self.theta_min, self.phi_max),
        ] {
            let g = Grid { theta, phi };
            if !out.contains(&g) {
                out.push(g);
            }
        }
        out
    }
}

/// The steady state at the operating point, in the frame aligned with `v_c + r_v i_g`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OperatingPoint {
    /// Converter-side current.
    pub i_f: Dq,
    /// Capacitor voltage.
    pub v_c: Dq,
    /// Grid-side current.
    pub i_g: Dq,
    /// Converter voltage.
    pub v_m: Dq,
    /// Grid voltage (MV side).
    pub v_g: Dq,
}

fn c_mul(a: Dq, r: f64, x: f64) -> Dq {
    // (r + jx) a
    a * r + a.rot90() * x
}

impl OperatingPoint {
    /// The phasor solution of the filter at `spec`'s p0, q0, v0 (frame at nominal speed).
    pub fn of(spec: &DesignSpec) -> OperatingPoint {
        let d = &spec.data;
        let v_g = Dq { d: spec.v0, q: 0.0 };
        // p = v_d i_d + v_q i_q, q = v_q i_d - v_d i_q with v_g on the d axis.
        let i_g = Dq {
            d: spec.p0 / spec.v0,
            q: -spec.q0 / spec.v0,
        };
        let v_c = v_g + c_mul(i_g, d.r_t, d.l_t);
        let i_f = i_g + v_c.rot90() * d.c_f;
        let v_m = v_c + c_mul(i_f, d.r_f, d.l_f);
        let w = v_c + i_g * spec.r_v;
        let angle = dvpp_math::atan2(w.q, w.d);
        let turn = |x: Dq| Dq {
            d: x.d * dvpp_math::cos(angle) + x.q * dvpp_math::sin(angle),
            q: -x.d * dvpp_math::sin(angle) + x.q * dvpp_math::cos(angle),
        };
        OperatingPoint {
            i_f: turn(i_f),
            v_c: turn(v_c),
            i_g: turn(i_g),
            v_m: turn(v_m),
            v_g: turn(v_g),
        }
    }
}

/// Rows (over the six filter states) of the linearized measurements the controller computes:
/// the grid-voltage estimate `v_c - (R_t + jL_t) i_g`, its magnitude, `q` and `w_q`.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurements {
    /// `Δ|v_g|` over the filter states.
    pub dv: DVector<f64>,
    /// `Δq` over the filter states.
    pub dq: DVector<f64>,
    /// `Δw_q = Δv_cq + r_v Δi_gq` over the filter states.
    pub dwq: DVector<f64>,
}

impl Measurements {
    /// The linearization at `op`.
    pub fn of(spec: &DesignSpec, op: &OperatingPoint) -> Measurements {
        let d = &spec.data;
        // Δv_g = Δv_c - R_t Δi_g - j L_t Δi_g: rows for d and q.
        let mut vgd = DVector::zeros(6);
        let mut vgq = DVector::zeros(6);
        vgd[2] = 1.0;
        vgd[4] = -d.r_t;
        vgd[5] = d.l_t; // -j L_t i_g: d part is +L_t i_gq
        vgq[3] = 1.0;
        vgq[5] = -d.r_t;
        vgq[4] = -d.l_t;
        let (vg, ig) = (op.v_g, op.i_g);
        let n = vg.norm();
        let dv = (&vgd * vg.d + &vgq * vg.q) / n;
        // q = v_q i_d - v_d i_q.
        let mut dq = &vgq * ig.d - &vgd * ig.q;
        dq[4] += vg.q;
        dq[5] -= vg.d;
        let mut dwq = DVector::zeros(6);
        dwq[3] = 1.0;
        dwq[5] = spec.r_v;
        Measurements { dv, dq, dwq }
    }
}

/// The augmented plant at one value of μ, pu time:
/// `x' = A x + B1 w + B2 u`, `z = C1 x + D12 u` (`D11` = 0).
#[derive(Debug, Clone, PartialEq)]
pub struct Plant {
    /// State matrix.
    pub a: DMatrix<f64>,
    /// Disturbance input (grid voltage).
    pub b1: DMatrix<f64>,
    /// Control input (converter-voltage command).
    pub b2: DMatrix<f64>,
    /// Performance outputs over the states.
    pub c1: DMatrix<f64>,
    /// Performance outputs over the control.
    pub d12: DMatrix<f64>,
}

impl Plant {
    /// The plant of `spec` at scheduling parameter `mu` on `grid`. Only the reference model's
    /// row depends on μ, linearly; the plant is multi-affine in `(μ, θ, φ)`.
    pub fn at(spec: &DesignSpec, mu: f64, grid: Grid) -> Plant {
        let wb = spec.omega_b();
        let op = OperatingPoint::of(spec);
        let meas = Measurements::of(spec, &op);
        let (a_lcl, b_lcl) = Lcl::continuous(&grid.series(&spec.data), wb, 1.0);
        let n = N_STATES;
        let mut a = DMatrix::zeros(n, n);
        let mut b1 = DMatrix::zeros(n, N_DISTURBANCES);
        let mut b2 = DMatrix::zeros(n, N_INPUTS);
        // The filter in pu time, driven by the applied converter voltage (states 6, 7).
        a.view_mut((0, 0), (6, 6)).copy_from(&(a_lcl / wb));
        let b_lcl = b_lcl / wb;
        a.view_mut((0, 6), (6, 2))
            .copy_from(&b_lcl.view((0, 0), (6, 2)));
        b1.view_mut((0, 0), (6, 2))
            .copy_from(&b_lcl.view((0, 2), (6, 2)));
        // The delay's lag: v_m' = (u - v_m)/T_d.
        let td = spec.t_delay * wb;
        for k in 0..2 {
            a[(6 + k, 6 + k)] = -1.0 / td;
            b2[(6 + k, k)] = 1.0 / td;
        }
        // The reference model τ Δq_ref' = -Δq_ref - k_q μ Δ|v_mv|, reading the MV-side voltage
        // (the controller's estimate with the transformer's L_t di_g/dt). Eliminating di_g/dt
        // with the series path's equation: v_mv = (1 - θ) v_c - (R_t (1 - θ) - L_t φ) i_g + θ v_s,
        // the divider between transformer and grid (on a stiff grid the source itself).
        let tau = spec.tau_q * wb;
        a[(8, 8)] = -1.0 / tau;
        let dir = op.v_g * (1.0 / op.v_g.norm());
        let gain = -spec.k_q * mu / tau;
        let (th, ph) = (grid.theta, grid.phi);
        let c_i = -(spec.data.r_t * (1.0 - th) - spec.data.l_t * ph);
        for (k, d) in [(0, dir.d), (1, dir.q)] {
            a[(8, 2 + k)] = gain * d * (1.0 - th);
            a[(8, 4 + k)] = gain * d * c_i;
            b1[(8, k)] = gain * d * th;
        }
        for j in 0..6 {
            // ξ_q' = Δq - Δq_ref, ξ_w' = Δw_q.
            a[(9, j)] = meas.dq[j];
            a[(10, j)] = meas.dwq[j];
        }
        a[(9, 8)] = -1.0;
        // Performance outputs.
        let w = &spec.weights;
        let mut c1 = DMatrix::zeros(N_OUTPUTS, n);
        let mut d12 = DMatrix::zeros(N_OUTPUTS, N_INPUTS);
        for j in 0..6 {
            c1[(0, j)] = w.tracking * meas.dq[j];
            c1[(1, j)] = w.alignment * meas.dwq[j];
        }
        c1[(0, 8)] = -w.tracking;
        c1[(0, 9)] = w.tracking * w.tracking_corner;
        c1[(1, 10)] = w.alignment * w.alignment_corner;
        for k in 0..2 {
            d12[(2 + k, k)] = w.effort;
            d12[(4 + k, k)] = w.rolloff;
            c1[(4 + k, 6 + k)] = -w.rolloff;
        }
        Plant { a, b1, b2, c1, d12 }
    }
}

/// A unit's p-f ADPF `m(s)`, as its frame sees it.
#[derive(Debug, Clone, PartialEq)]
pub enum Adpf {
    /// A static dc gain `μ_p`.
    Static(f64),
    /// A low-pass `μ_p/(τ s + 1)` (the wind and PV presets; `τ` in s).
    LowPass {
        /// Dc gain.
        mu: f64,
        /// Time constant (s).
        tau: f64,
    },
    /// The complement `1 - Σ μ_j/(τ_j s + 1)` of the low-pass units' shares (the BESS), the
    /// pairs `(μ_j, τ_j)`.
    Complement(Vec<(f64, f64)>),
}

/// The p-f reference model's frame, which the design model holds fixed: for the analysis of
/// [`crate::checks::frame_mode`]. The frame turns at `1 + Δf` with
/// `Δf = -T_pf(s)/m(s) Δp_dvpp`, `T_pf = 1/(H s + D)`, and the grid's source lies at the angle
/// `-δ` in it, `δ' = ω_b Δf`.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// `T_des`'s inertia `H` (s) in `T_pf = 1/(H s + D)`.
    pub h: f64,
    /// `T_des`'s damping `D`.
    pub d: f64,
    /// `S_rated/S_dvpp`: the unit's power in pu of its rating to pu of the DVPP's.
    pub ratio: f64,
    /// The unit's p-f ADPF.
    pub adpf: Adpf,
}

/// Polynomial product, coefficients in ascending powers.
fn poly_mul(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

impl Frame {
    /// A unit of `s_rated` in a DVPP of `s_dvpp` with the EMT DER's `T_des` defaults
    /// (`Tdes.H` 5.55, `Tdes.D` 33.33) and the p-f ADPF `adpf`.
    pub fn unit(s_rated: f64, s_dvpp: f64, adpf: Adpf) -> Frame {
        Frame {
            h: 5.55,
            d: 33.33,
            ratio: s_rated / s_dvpp,
            adpf,
        }
    }

    /// The stabilizer the controller gives this frame: `spec.stabilizer` for a frame with
    /// inertia, 0 for a low-pass ADPF's, whose frequency follows the unit's power at once.
    pub fn stabilizer(&self, spec: &DesignSpec) -> f64 {
        match self.adpf {
            Adpf::LowPass { .. } => 0.0,
            _ => spec.stabilizer,
        }
    }

    /// `G(s) = ratio/(m(s) (H s + D))`, from the unit's power (pu on its rating) to `-Δf`, as
    /// (numerator, denominator), ascending powers of `s` in seconds.
    fn transfer(&self) -> (Vec<f64>, Vec<f64>) {
        let t_pf = [self.d, self.h];
        match &self.adpf {
            Adpf::Static(mu) => (vec![self.ratio], vec![mu * self.d, mu * self.h]),
            Adpf::LowPass { mu, tau } => (
                vec![self.ratio, self.ratio * tau],
                vec![mu * self.d, mu * self.h],
            ),
            Adpf::Complement(shares) => {
                let mut p = vec![1.0];
                for &(_, tau) in shares {
                    p = poly_mul(&p, &[1.0, tau]);
                }
                let mut m = p.clone();
                for (j, &(mu_j, _)) in shares.iter().enumerate() {
                    let mut pj = vec![1.0];
                    for (k, &(_, tau)) in shares.iter().enumerate() {
                        if k != j {
                            pj = poly_mul(&pj, &[1.0, tau]);
                        }
                    }
                    for (c, x) in m.iter_mut().zip(&pj) {
                        *c -= mu_j * x;
                    }
                }
                let num: Vec<f64> = p.iter().map(|c| c * self.ratio).collect();
                (num, poly_mul(&m, &t_pf))
            }
        }
    }

    /// `G` in pu time (`s = ω_b s̃`) as a state space `(A, B, C, D)` in controllable canonical
    /// form: `z' = A z + B Δp`, `-Δf = C z + D Δp`.
    pub fn state_space(&self, omega_b: f64) -> (DMatrix<f64>, DVector<f64>, DVector<f64>, f64) {
        let (num, den) = self.transfer();
        let scale = |c: &[f64]| -> Vec<f64> {
            c.iter()
                .enumerate()
                .map(|(k, x)| x * dvpp_math::powi(omega_b, k as i32))
                .collect()
        };
        let (mut num, den) = (scale(&num), scale(&den));
        let n = den.len() - 1;
        let lead = den[n];
        let a_coef: Vec<f64> = den.iter().map(|x| x / lead).collect();
        num.resize(n + 1, 0.0);
        let d = num[n] / lead;
        let mut a = DMatrix::zeros(n, n);
        for i in 0..n - 1 {
            a[(i, i + 1)] = 1.0;
        }
        for k in 0..n {
            a[(n - 1, k)] = -a_coef[k];
        }
        let mut b = DVector::zeros(n);
        b[n - 1] = 1.0;
        let c = DVector::from_iterator(n, (0..n).map(|k| num[k] / lead - d * a_coef[k]));
        (a, b, c, d)
    }
}

impl Plant {
    /// The plant at `(mu, grid)` with the frame appended (and no performance outputs on it): the
    /// states of `G`, then `δ`. `Δf = -(C z + D Δp)` turns the filter's dq equations and enters
    /// the alignment's integral through the stabilizer, `δ` turns the source's voltage in the
    /// frame, and the frame follows the measured active power.
    pub fn with_frame(spec: &DesignSpec, mu: f64, grid: Grid, frame: &Frame) -> Plant {
        let p = Plant::at(spec, mu, grid);
        let wb = spec.omega_b();
        let (ag, bg, cg, dg) = frame.state_space(wb);
        let ng = ag.nrows();
        let (n, delta) = (N_STATES + ng + 1, N_STATES + ng);
        let op = OperatingPoint::of(spec);
        let d = &spec.data;
        let mut a = DMatrix::zeros(n, n);
        a.view_mut((0, 0), (N_STATES, N_STATES)).copy_from(&p.a);
        // δ: Δv_s = -j v_s0 Δδ, v_s0 the source's voltage behind the grid impedance.
        let z_i = c_mul(op.i_g, grid.r_g(d.l_t), grid.l_g(d.l_t));
        let v_s = op.v_g - z_i;
        for i in 0..N_STATES {
            a[(i, delta)] = p.b1[(i, 0)] * v_s.q - p.b1[(i, 1)] * v_s.d;
        }
        // Δp over the filter states: p = v̂_g · i_g with v̂_g = v_c - (R_t + jL_t) i_g.
        let (v, i) = (op.v_g, op.i_g);
        let dp = [
            0.0,
            0.0,
            i.d,
            i.q,
            v.d - d.r_t * i.d - d.l_t * i.q,
            v.q + d.l_t * i.d - d.r_t * i.q,
        ];
        // Δf as a row over the states: -(D Δp + C z).
        let mut df = DVector::zeros(n);
        for (j, dpj) in dp.iter().enumerate() {
            df[j] = -dg * dpj;
        }
        for k in 0..ng {
            df[N_STATES + k] = -cg[k];
        }
        // G's states follow Δp.
        a.view_mut((N_STATES, N_STATES), (ng, ng)).copy_from(&ag);
        for k in 0..ng {
            for (j, dpj) in dp.iter().enumerate() {
                a[(N_STATES + k, j)] = bg[k] * dpj;
            }
        }
        // Δf: the filter's rotation terms (affine in the frame's speed), the stabilizer in the
        // alignment's integral (ξ_w' = Δw_q - k_a Δf), and δ' = Δf.
        let series = grid.series(d);
        let (a1, _) = Lcl::continuous(&series, wb, 1.0);
        let (a2, _) = Lcl::continuous(&series, wb, 2.0);
        let x0 = DVector::from_column_slice(&[
            op.i_f.d, op.i_f.q, op.v_c.d, op.v_c.q, op.i_g.d, op.i_g.q,
        ]);
        let rot = (a2 - a1) * x0 / wb;
        // The controller's stabilizer for this frame (none for a low-pass ADPF's, §8.2).
        let k_a = frame.stabilizer(spec);
        for col in 0..n {
            for r in 0..6 {
                a[(r, col)] += rot[r] * df[col];
            }
            a[(10, col)] -= k_a * df[col];
            a[(delta, col)] += df[col];
        }
        let pad = |m: &DMatrix<f64>| {
            let mut out = DMatrix::zeros(n, m.ncols());
            out.view_mut((0, 0), (N_STATES, m.ncols())).copy_from(m);
            out
        };
        let mut c1 = DMatrix::zeros(p.c1.nrows(), n);
        c1.view_mut((0, 0), (p.c1.nrows(), N_STATES))
            .copy_from(&p.c1);
        Plant {
            a,
            b1: pad(&p.b1),
            b2: pad(&p.b2),
            c1,
            d12: p.d12,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn operating_point_is_a_steady_state_of_the_filter() {
        let spec = DesignSpec::default();
        let op = OperatingPoint::of(&spec);
        let wb = spec.omega_b();
        let (a, b) = Lcl::continuous(&spec.data, wb, 1.0);
        let x = DVector::from_column_slice(&[
            op.i_f.d, op.i_f.q, op.v_c.d, op.v_c.q, op.i_g.d, op.i_g.q,
        ]);
        let u = DVector::from_column_slice(&[op.v_m.d, op.v_m.q, op.v_g.d, op.v_g.q]);
        let dx = a * x + b * u;
        assert!(dx.amax() < 1e-9 * wb, "{dx}");
        // Aligned with the voltage behind the virtual resistance, and at the asked powers.
        assert!((op.v_c.q + spec.r_v * op.i_g.q).abs() < 1e-12);
        assert!((op.v_g.p(op.i_g) - spec.p0).abs() < 1e-12);
        assert!((op.v_g.q(op.i_g) - spec.q0).abs() < 1e-12);
    }

    #[test]
    fn linearized_q_and_v_match_finite_differences() {
        let spec = DesignSpec {
            q0: 0.2,
            ..DesignSpec::default()
        };
        let op = OperatingPoint::of(&spec);
        let m = Measurements::of(&spec, &op);
        let d = &spec.data;
        let f = |x: &[f64; 6]| {
            let v_c = Dq { d: x[2], q: x[3] };
            let i_g = Dq { d: x[4], q: x[5] };
            let vg = v_c - c_mul(i_g, d.r_t, d.l_t);
            (vg.norm(), vg.q(i_g))
        };
        let x0 = [op.i_f.d, op.i_f.q, op.v_c.d, op.v_c.q, op.i_g.d, op.i_g.q];
        let (v0, q0) = f(&x0);
        assert!((v0 - spec.v0).abs() < 1e-12 && (q0 - spec.q0).abs() < 1e-12);
        for j in 0..6 {
            let eps = 1e-6;
            let mut x = x0;
            x[j] += eps;
            let (v, q) = f(&x);
            assert!(((v - v0) / eps - m.dv[j]).abs() < 1e-5, "dv[{j}]");
            assert!(((q - q0) / eps - m.dq[j]).abs() < 1e-5, "dq[{j}]");
        }
    }

    /// The reference row reads `v_mv = v_c - R_t i_g - L_t di_g/dt̃ - j L_t i_g` with `di_g/dt̃`
    /// from the series path's own equation: the divider form in `Plant::at` is that.
    #[test]
    fn the_reference_reads_the_mv_voltage_behind_the_grid_impedance() {
        let spec = DesignSpec::default();
        let d = &spec.data;
        let grid = Grid::behind(d.l_t, 0.05, 0.3);
        let p = Plant::at(&spec, 1.0, grid);
        let op = OperatingPoint::of(&spec);
        let dir = op.v_g * (1.0 / op.v_g.norm());
        let gain = -spec.k_q / (spec.tau_q * spec.omega_b());
        // A state and a source voltage, arbitrary.
        let x = DVector::from_fn(N_STATES, |i, _| ((i * 7 + 3) % 11) as f64 / 10.0 - 0.4);
        let w = DVector::from_column_slice(&[0.3, -0.2]);
        let dx = &p.a * &x + &p.b1 * &w;
        let v_c = Dq { d: x[2], q: x[3] };
        let i_g = Dq { d: x[4], q: x[5] };
        let di = Dq { d: dx[4], q: dx[5] };
        let v_mv = v_c - c_mul(i_g, d.r_t, d.l_t) - di * d.l_t;
        let expected =
            gain * (dir.d * v_mv.d + dir.q * v_mv.q) - x[8] / (spec.tau_q * spec.omega_b());
        assert!(
            (dx[8] - expected).abs() < 1e-9 * expected.abs().max(1.0),
            "{} {expected}",
            dx[8]
        );
        // On the stiff grid the source itself.
        let s = Plant::at(&spec, 1.0, Grid::STIFF);
        for j in 0..6 {
            assert_eq!(s.a[(8, j)], 0.0);
        }
    }

    /// Multi-affine in `(μ, θ, φ)`: the plant at an inner point is the corners' combination
    /// with the weights of multilinear interpolation.
    #[test]
    fn the_plant_is_multi_affine_in_mu_theta_phi() {
        let spec = DesignSpec::default();
        let (mu, th, ph) = (0.3, 0.55, 0.07);
        let at = |m: f64, t: f64, f: f64| Plant::at(&spec, m, Grid { theta: t, phi: f });
        let (m0, m1, t0, t1, f0, f1) = (0.0, 1.0, 0.2, 1.0, 0.0, 0.1);
        let lm = (mu - m0) / (m1 - m0);
        let lt = (th - t0) / (t1 - t0);
        let lf = (ph - f0) / (f1 - f0);
        let mut a = DMatrix::zeros(N_STATES, N_STATES);
        let mut b1 = DMatrix::zeros(N_STATES, N_DISTURBANCES);
        for (m, wm) in [(m0, 1.0 - lm), (m1, lm)] {
            for (t, wt) in [(t0, 1.0 - lt), (t1, lt)] {
                for (f, wf) in [(f0, 1.0 - lf), (f1, lf)] {
                    let p = at(m, t, f);
                    a += p.a * (wm * wt * wf);
                    b1 += p.b1 * (wm * wt * wf);
                }
            }
        }
        let p = at(mu, th, ph);
        assert!(
            (&a - &p.a).amax() < 1e-9 * p.a.amax(),
            "{}",
            (&a - &p.a).amax()
        );
        assert!((&b1 - &p.b1).amax() < 1e-9 * p.b1.amax());
        assert_eq!(at(0.0, 0.2, 0.1).b2, at(1.0, 1.0, 0.0).b2);
        assert_eq!(at(0.0, 0.2, 0.1).c1, at(1.0, 1.0, 0.0).c1);
    }

    /// The frame's state follows the linearized `p = v̂_g · i_g` (finite differences), a
    /// source turned by `δ` moves the filter as the disturbance `-j v_s δ` does, and the
    /// frame's transfer function is `ratio/(m(s) (H s + D))` at a test frequency for each ADPF.
    #[test]
    fn the_frame_reads_the_linearized_power_and_turns_the_source() {
        let spec = DesignSpec::default();
        let op = OperatingPoint::of(&spec);
        let d = &spec.data;
        let frame = Frame::unit(60.0, 96.0, Adpf::Static(1.0));
        let p = Plant::with_frame(&spec, 0.5, Grid::STIFF, &frame);
        let power = |x: &[f64; 6]| {
            let v_c = Dq { d: x[2], q: x[3] };
            let i_g = Dq { d: x[4], q: x[5] };
            (v_c - c_mul(i_g, d.r_t, d.l_t)).p(i_g)
        };
        let x0 = [op.i_f.d, op.i_f.q, op.v_c.d, op.v_c.q, op.i_g.d, op.i_g.q];
        for j in 0..6 {
            let mut x = x0;
            x[j] += 1e-7;
            let fd = (power(&x) - power(&x0)) / 1e-7;
            assert!((p.a[(N_STATES, j)] - fd).abs() < 1e-5, "p row {j}");
        }
        let s = Plant::at(&spec, 0.5, Grid::STIFF);
        for i in 0..N_STATES {
            let want = s.b1[(i, 0)] * op.v_g.q - s.b1[(i, 1)] * op.v_g.d;
            assert!((p.a[(i, N_STATES + 1)] - want).abs() < 1e-12);
        }
        let wb = spec.omega_b();
        let w = 2.0 * std::f64::consts::PI * 3.0;
        let jw = nalgebra::Complex::new(0.0, w);
        let one = nalgebra::Complex::new(1.0, 0.0);
        for adpf in [
            Adpf::Static(0.4),
            Adpf::LowPass { mu: 0.38, tau: 1.5 },
            Adpf::Complement(vec![(0.38, 1.5), (0.4, 0.6)]),
        ] {
            let m = match &adpf {
                Adpf::Static(mu) => one * *mu,
                Adpf::LowPass { mu, tau } => one * *mu / (one + jw * *tau),
                Adpf::Complement(sh) => sh
                    .iter()
                    .fold(one, |acc, &(mu, tau)| acc - one * mu / (one + jw * tau)),
            };
            let f = Frame::unit(46.0, 96.0, adpf);
            let want = one * f.ratio / (m * (jw * f.h + f.d));
            let (a, b, c, dd) = f.state_space(wb);
            let n = a.nrows();
            let s_pu = nalgebra::Complex::new(0.0, w / wb);
            let mat = DMatrix::<nalgebra::Complex<f64>>::from_diagonal_element(n, n, s_pu)
                - a.map(|v| one * v);
            let x = mat.lu().solve(&b.map(|v| one * v)).unwrap();
            let got = (0..n).map(|k| x[k] * c[k]).sum::<nalgebra::Complex<f64>>() + dd;
            assert!(
                dvpp_math::cabs(got - want) < 1e-9 * dvpp_math::cabs(want),
                "{got} {want}"
            );
        }
    }

    #[test]
    fn only_the_reference_row_of_b1_depends_on_mu_and_linearly() {
        let spec = DesignSpec::default();
        let (p0, p1, ph) = (
            Plant::at(&spec, 0.0, Grid::STIFF),
            Plant::at(&spec, 1.0, Grid::STIFF),
            Plant::at(&spec, 0.5, Grid::STIFF),
        );
        let diff = &p1.b1 - &p0.b1;
        for i in 0..N_STATES {
            if i != 8 {
                assert_eq!(diff.row(i).amax(), 0.0, "row {i}");
            }
        }
        assert_eq!(p0.b1.row(8).amax(), 0.0);
        assert!(diff.row(8).amax() > 1.0);
        assert!((&ph.b1 - (&p0.b1 + &p1.b1) * 0.5).amax() < 1e-12);
        assert_eq!(p0.a, p1.a);
        assert_eq!(p0.b2, p1.b2);
        assert_eq!(p0.c1, p1.c1);
    }
}
