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
//! Input `u`: the converter-voltage command (d, q). Disturbance `w`: the grid voltage `Δv_g`
//! (d, q) of a stiff grid behind the transformer. All pu on the converter's rating, in the
//! unit's dq frame at nominal speed. The reference model reads the grid voltage's magnitude
//! (the controller computes it with the transformer's `L_t di_g/dt`, see
//! `fmu-der/src/emt/control.rs`), so it is driven by `w` and not by the states.

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
            rolloff: 1.0,
        }
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
    /// Radius (pu of `ω_b`) of the disk about the origin that holds every closed-loop
    /// eigenvalue at every μ: it keeps the loop well below the sampling rate.
    pub pole_radius: f64,
}

impl Default for DesignSpec {
    /// The EMT-level DER's defaults: the paper's converter, 50 Hz, the generic 60 MVA unit in a
    /// DVPP of 96 MVA with `D_q` = 0.01 and `τ_q` = 10 ms (so `k_q` = 160, the paper's appendix
    /// model `-100 μ/(0.01 s + 1)` on the DVPP base), `vi.r` = 0.3, sampled at 50 µs, at half
    /// load and unity power factor; μ over the whole range `[0, 1]` the operator's reactive
    /// gains `Q_cap,i/Σ Q_cap` take.
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
        }
    }
}

impl DesignSpec {
    /// `ω_b` (rad/s).
    pub fn omega_b(&self) -> f64 {
        2.0 * std::f64::consts::PI * self.f_nom
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
        let angle = w.q.atan2(w.d);
        let turn = |x: Dq| Dq {
            d: x.d * angle.cos() + x.q * angle.sin(),
            q: -x.d * angle.sin() + x.q * angle.cos(),
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
    /// The plant of `spec` at scheduling parameter `mu`. Only `B1`'s reference-model row depends
    /// on μ, linearly.
    pub fn at(spec: &DesignSpec, mu: f64) -> Plant {
        let wb = spec.omega_b();
        let op = OperatingPoint::of(spec);
        let meas = Measurements::of(spec, &op);
        let (a_lcl, b_lcl) = Lcl::continuous(&spec.data, wb, 1.0);
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
        // The reference model τ Δq_ref' = -Δq_ref - k_q μ Δ|v_g|, reading the MV-side voltage
        // (the controller's estimate with the transformer's L_t di_g/dt): the disturbance.
        let tau = spec.tau_q * wb;
        a[(8, 8)] = -1.0 / tau;
        let n_g = op.v_g.norm();
        b1[(8, 0)] = -spec.k_q * mu * op.v_g.d / n_g / tau;
        b1[(8, 1)] = -spec.k_q * mu * op.v_g.q / n_g / tau;
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

    #[test]
    fn only_the_reference_row_of_b1_depends_on_mu_and_linearly() {
        let spec = DesignSpec::default();
        let (p0, p1, ph) = (
            Plant::at(&spec, 0.0),
            Plant::at(&spec, 1.0),
            Plant::at(&spec, 0.5),
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
