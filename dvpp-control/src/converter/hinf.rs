//! Option B's runtime: the LPV H∞ state feedback with the generated vertex gains, scheduled on the unit's reactive dc gain, in place of the v-q cascade.
//!
//! Each sample, with `Δ` the deviation from the operating point the loop was started at:
//!
//! ```text
//! x = [Δi_f, Δv_c, Δi_g, Δv_m,prev, Δq_ref, ξ_q, ξ_w]          (the order of hinf_gains::STATES)
//! v_m = v_m0 + K(μ) x,   limited to |v_m| ≤ v_m,max
//! ξ_q += ω_b h (Δq - Δq_ref),   ξ_w += ω_b h (Δw_q - k_a Δf)     (held while the limit acts)
//! ```
//!
//! `v_m,prev` is the command of the previous sample, which the plant applies now (it stands in
//! for the design model's delay lag); `Δq_ref` the local reactive reference model's output and
//! `Δq` the measured reactive power, both pu on the converter's rating; `w_q` the q axis of the
//! voltage behind the virtual resistance, `v_c + r_v i_g`; `Δf` the frame's frequency deviation
//! and `k_a` the frame stabilizer ([`STABILIZER`](super::hinf_gains::STABILIZER) for a frame
//! with inertia), which lets that voltage lead the frame while the frame swings against the grid
//! (the design model holds the frame fixed). `K(μ)` interpolates the vertex gains linearly in the
//! equivalent dc gain `μ k_q/K_Q`, where `k_q = S_dvpp/(S_rated D_q)` is this unit's reference
//! gain and [`K_Q`] the design's: the reference model's input gain `k_q μ` is what the design
//! scheduled on. Docs: `docs/hinf.md`.

use super::filter::ConverterData;
use super::frame::Dq;
use super::hinf_gains::{K_MU_MAX, K_MU_MIN, K_Q, MU_MAX, MU_MIN, N_INPUTS, N_STATES};
use super::inner::FilterMeasurement;
use serde::{Deserialize, Serialize};

/// The places of the two integrals `ξ_q`, `ξ_w` in the state.
const XI_Q: usize = 9;
const XI_W: usize = 10;

/// `K(μ)`: the vertex gains interpolated linearly, `mu` clamped to the design's range.
pub fn gain(mu: f64) -> [[f64; N_STATES]; N_INPUTS] {
    let l = ((mu - MU_MIN) / (MU_MAX - MU_MIN)).clamp(0.0, 1.0);
    let mut k = K_MU_MIN;
    for (row, hi) in k.iter_mut().zip(K_MU_MAX) {
        for (v, b) in row.iter_mut().zip(hi) {
            *v += l * (b - *v);
        }
    }
    k
}

/// The loop's runtime: the operating point it regulates about, the integrals, the last command.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HinfLoop {
    x0: FilterMeasurement,
    v_m0: Dq,
    w_q0: f64,
    r_v: f64,
    k_a: f64,
    k_ratio: f64,
    xi_q: f64,
    xi_w: f64,
    v_m: Dq,
    modulation_limited: bool,
    mu: f64,
}

impl HinfLoop {
    /// A loop started in the steady state `m` with the converter voltage `v_m`, for a unit with
    /// virtual resistance `r_v` and reference gain `k_q = S_dvpp/(S_rated D_q)`, with the frame
    /// stabilizer `k_a` ([`STABILIZER`](super::hinf_gains::STABILIZER) for a frame with inertia,
    /// 0 for one that follows the unit's power at once).
    pub fn new(m: &FilterMeasurement, v_m: Dq, r_v: f64, k_q: f64, k_a: f64) -> HinfLoop {
        HinfLoop {
            x0: *m,
            v_m0: v_m,
            w_q0: m.v_c.q + r_v * m.i_g.q,
            r_v,
            k_a,
            k_ratio: k_q / K_Q,
            xi_q: 0.0,
            xi_w: 0.0,
            v_m,
            modulation_limited: false,
            mu: 0.0,
        }
    }

    /// The steady-state converter voltage of the filter `data` at `m` (frame at `omega` pu):
    /// `v_c + (R_f + jωL_f) i_f`.
    pub fn steady_voltage(data: &ConverterData, m: &FilterMeasurement, omega: f64) -> Dq {
        m.v_c + m.i_f * data.r_f + m.i_f.rot90() * (omega * data.l_f)
    }

    /// The equivalent dc gain the last sample scheduled on.
    pub fn mu(&self) -> f64 {
        self.mu
    }

    /// Whether the last sample limited the converter voltage.
    pub fn modulation_limited(&self) -> bool {
        self.modulation_limited
    }

    /// Take over again, bumplessly, from a controller that ran in its place (option B's
    /// current-limited mode, docs/hinf.md §8.5): the operating point stays, `v_m` (the command
    /// of the previous sample, which the plant applies now) becomes the loop's previous command,
    /// and the two integrals are set so that the next [`HinfLoop::step`] with the same `m`,
    /// `dq_ref` and `mu_q` returns `v_m` again: `K_ξ ξ = v_m - v_m0 - K_x x`, `K_ξ` the gain's
    /// 2×2 block on the integrals (invertible over the design's range: its determinant is 0.90
    /// at `MU_MIN` and 1.35 at `MU_MAX`). Those are the integrals the loop would hold in a
    /// steady state at this point, so the loop resumes from where the other controller left
    /// the converter rather than from where it handed over.
    pub fn resume(&mut self, m: &FilterMeasurement, v_m: Dq, dq_ref: f64, mu_q: f64) {
        self.v_m = v_m;
        self.xi_q = 0.0;
        self.xi_w = 0.0;
        let x = self.state(m, dq_ref);
        let k = gain(mu_q * self.k_ratio);
        let dot = |row: &[f64; N_STATES]| row.iter().zip(&x).map(|(a, b)| a * b).sum::<f64>();
        let r = v_m
            - self.v_m0
            - Dq {
                d: dot(&k[0]),
                q: dot(&k[1]),
            };
        let (a, b, c, d) = (k[0][XI_Q], k[0][XI_W], k[1][XI_Q], k[1][XI_W]);
        let det = a * d - b * c;
        self.xi_q = (d * r.d - b * r.q) / det;
        self.xi_w = (a * r.q - c * r.d) / det;
    }

    /// The design's state `x` (the order of [`STATES`](super::hinf_gains::STATES)) at `m`.
    fn state(&self, m: &FilterMeasurement, dq_ref: f64) -> [f64; N_STATES] {
        let (di_f, dv_c, di_g) = (
            m.i_f - self.x0.i_f,
            m.v_c - self.x0.v_c,
            m.i_g - self.x0.i_g,
        );
        let du = self.v_m - self.v_m0;
        [
            di_f.d, di_f.q, dv_c.d, dv_c.q, di_g.d, di_g.q, du.d, du.q, dq_ref, self.xi_q,
            self.xi_w,
        ]
    }

    /// The converter voltage for this sample: `m` the filter measurement, `dq` and `dq_ref` the
    /// reactive power's and its reference's deviations (pu on the rating), `mu_q` the unit's
    /// reactive dc gain, `df` the frame's frequency deviation (pu), `v_m_max` the largest
    /// converter voltage, `omega_b` (rad/s), `h` (s).
    #[allow(clippy::too_many_arguments)]
    pub fn step(
        &mut self,
        m: &FilterMeasurement,
        dq: f64,
        dq_ref: f64,
        mu_q: f64,
        df: f64,
        v_m_max: f64,
        omega_b: f64,
        h: f64,
    ) -> Dq {
        let x = self.state(m, dq_ref);
        self.mu = mu_q * self.k_ratio;
        let k = gain(self.mu);
        let dot = |row: &[f64; N_STATES]| row.iter().zip(&x).map(|(a, b)| a * b).sum::<f64>();
        let raw = self.v_m0
            + Dq {
                d: dot(&k[0]),
                q: dot(&k[1]),
            };
        let n = raw.norm();
        self.modulation_limited = n > v_m_max;
        self.v_m = if self.modulation_limited {
            raw * (v_m_max / n)
        } else {
            let w_q = m.v_c.q + self.r_v * m.i_g.q;
            self.xi_q += omega_b * h * (dq - dq_ref);
            self.xi_w += omega_b * h * (w_q - self.w_q0 - self.k_a * df);
            raw
        };
        self.v_m
    }
}

#[cfg(test)]
mod tests {
    use super::super::filter::{Lcl, LclState};
    use super::super::hinf_gains::{I_F0, I_G0, STABILIZER, V_C0, V_M0};
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn the_gain_interpolates_the_vertices() {
        // At the ends exactly the vertices, to rounding (`a + (b - a)` need not be `b`).
        let close = |k: [[f64; N_STATES]; N_INPUTS], want: [[f64; N_STATES]; N_INPUTS]| {
            k.iter()
                .flatten()
                .zip(want.iter().flatten())
                .all(|(a, b)| (a - b).abs() <= 1e-15 * b.abs().max(1.0))
        };
        assert_eq!(gain(MU_MIN), K_MU_MIN);
        assert!(close(gain(MU_MAX), K_MU_MAX));
        assert!(close(gain(MU_MAX + 5.0), K_MU_MAX));
        let mid = gain(0.5 * (MU_MIN + MU_MAX));
        assert!((mid[1][3] - 0.5 * (K_MU_MIN[1][3] + K_MU_MAX[1][3])).abs() < 1e-15);
    }

    /// After [`HinfLoop::resume`] the next sample's command is the one given, to rounding, at
    /// either end of μ and in between, wherever the converter was left; and the integrals
    /// resumed at the operating point itself are zero.
    #[test]
    fn resuming_repeats_the_command_given() {
        use super::super::hinf_gains::STATES;
        assert_eq!((STATES[XI_Q], STATES[XI_W]), ("xi_q", "xi_w"));
        let dq = |v: [f64; 2]| Dq { d: v[0], q: v[1] };
        let m0 = FilterMeasurement {
            v_c: dq(V_C0),
            i_f: dq(I_F0),
            i_g: dq(I_G0),
        };
        let mut hl = HinfLoop::new(&m0, dq(V_M0), 0.3, K_Q, STABILIZER);
        hl.resume(&m0, dq(V_M0), 0.0, 0.7);
        assert_eq!((hl.xi_q, hl.xi_w), (0.0, 0.0));
        // A converter left at 1.2 pu of current, a lower voltage, a turned command.
        let m = FilterMeasurement {
            v_c: dq([0.82, -0.11]),
            i_f: dq([0.95, 0.73]),
            i_g: dq([0.97, 0.64]),
        };
        let v_m = dq([0.91, 0.17]);
        for mu_q in [0.0, 0.37, 1.0] {
            hl.resume(&m, v_m, 0.31, mu_q);
            let out = hl.step(&m, 0.05, 0.31, mu_q, 0.0, 1.5, 2.0 * PI * 50.0, 50e-6);
            let err = (out - v_m).norm();
            assert!(err < 1e-14, "mu_q {mu_q}: {err:e}");
        }
    }

    /// The loop on the sampled filter against a stiff grid, at the design's operating point,
    /// with one sample of computation delay: started in the steady state it stays there, and
    /// after a 1 % dip of the grid voltage q follows a fixed reference change and `w_q` returns
    /// to zero (the integrals).
    #[test]
    fn tracks_a_reactive_reference_on_the_sampled_filter() {
        let (wb, h) = (2.0 * PI * 50.0, 50e-6);
        let data = ConverterData::PAPER;
        let lcl = Lcl::discretize(&data, wb, 1.0, h);
        let dq = |v: [f64; 2]| Dq { d: v[0], q: v[1] };
        let mut x = LclState {
            i_f: dq(I_F0),
            v_c: dq(V_C0),
            i_g: dq(I_G0),
        };
        let meas = |x: &LclState| FilterMeasurement {
            v_c: x.v_c,
            i_f: x.i_f,
            i_g: x.i_g,
        };
        let v_g0 = x.v_c - x.i_g * data.r_t - x.i_g.rot90() * data.l_t;
        let q_of = |x: &LclState| {
            let vg = x.v_c - x.i_g * data.r_t - x.i_g.rot90() * data.l_t;
            vg.q(x.i_g)
        };
        let q0 = q_of(&x);
        let mut hl = HinfLoop::new(&meas(&x), dq(V_M0), 0.3, K_Q, STABILIZER);
        let mut v_m = dq(V_M0);
        let (mut worst_flat, mut err) = (0.0f64, Vec::new());
        for k in 0..20_000 {
            let v_g = if k >= 2000 { v_g0 * 0.99 } else { v_g0 };
            let dq_ref = if k >= 2000 { 0.2 } else { 0.0 };
            let next = hl.step(&meas(&x), q_of(&x) - q0, dq_ref, 0.5, 0.0, 1.5, wb, h);
            x = lcl.step(&x, v_m, v_g);
            v_m = next;
            if k < 2000 {
                worst_flat = worst_flat.max((q_of(&x) - q0).abs());
            } else {
                err.push(q_of(&x) - q0 - dq_ref);
            }
        }
        assert!(worst_flat < 1e-12, "{worst_flat}");
        let last = *err.last().unwrap();
        let settle = err.iter().rposition(|e| e.abs() > 0.01 * 0.2).unwrap() as f64 * h;
        eprintln!("q error at the end {last:.2e} pu, within 1 % of the step after {settle:.4} s");
        assert!(last.abs() < 1e-4, "{last}");
        assert!(settle < 0.1, "{settle}");
        let w = hl.w_q0 - (x.v_c.q + 0.3 * x.i_g.q);
        assert!(w.abs() < 1e-4, "{w}");
        assert!(!hl.modulation_limited());
    }
}
