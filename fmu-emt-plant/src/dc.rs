//! One unit's dc side: the primary source's first-order lag and the dc link as an energy store,
//! stepped as an exact energy balance (pu on the unit's rating, energies in pu·s).
//!
//! The source current follows `τ_dc i_src' = i_dc_ref - i_src` exactly (held command), within
//! what the primary source has: its power `v_dc i_src` stays in `[p_min, p_max]` (the unit's
//! availability, `[0, P_avail]` or `±P_avail` for storage, from its controller). A source above a
//! range that fell (a cloud) is cut to it at once; a lag that reaches a bound within the step
//! stays there from that instant (its charge exact). The link
//! stores `W = C_dc v_dc²/2` and `W(t+h) = W(t) + E_src - E_loss - E_ac`: `E_ac` is the exact
//! integral of the converter power over the step (from the ac circuit), `E_src = v̄ ∫ i_src`
//! and `E_loss = G_dc h (v_dc(t)² + v̂²)/2` with `v̄` the mean of `v_dc(t)` and a predicted
//! `v̂ = v_dc(t+h)`: a second-order rule whose terms sum, by construction, to the change of the
//! stored energy, so the account closes to rounding.

use serde::{Deserialize, Serialize};

/// Parameters of the dc side.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DcParams {
    /// Dc-link capacitance as the link's energy time constant: `W = C_dc v_dc²/2` pu·s.
    pub c: f64,
    /// Link conductance (losses `G_dc v_dc²`).
    pub g: f64,
    /// Source lag, s.
    pub tau: f64,
}

/// The dc side's state.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DcState {
    /// Source current, pu of `S_rated/v_dc*`.
    pub i_src: f64,
    /// Stored energy, pu·s on `S_rated`.
    pub w: f64,
}

/// Below this dc voltage (pu) the source's current range is taken at it (no division by zero).
const V_FLOOR: f64 = 0.05;

/// `∫ i_src` over `t` for the lag from `i0` toward the held `i_ref` (`exp_m1` for accuracy).
fn lag_charge(i0: f64, i_ref: f64, tau: f64, t: f64) -> f64 {
    i_ref * t - (i0 - i_ref) * tau * dvpp_math::expm1(-t / tau)
}

/// Energies over one step, pu·s.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DcStep {
    pub source: f64,
    pub loss: f64,
}

impl DcState {
    /// At `v_dc = 1` with the source covering `p_conv` and the link losses.
    pub fn steady(p: &DcParams, p_conv: f64) -> Self {
        DcState {
            i_src: p_conv + p.g,
            w: 0.5 * p.c,
        }
    }

    /// Dc voltage, pu of `v_dc*`.
    pub fn v(&self, p: &DcParams) -> f64 {
        (2.0 * self.w.max(0.0) / p.c).sqrt()
    }

    /// One step of `h` with the command `i_ref` held, the source's power within `range`
    /// (`[p_min, p_max]`, pu on S_rated), and `e_ac` drawn by the converter.
    pub fn step(&mut self, p: &DcParams, i_ref: f64, e_ac: f64, h: f64, range: [f64; 2]) -> DcStep {
        let v_range = self.v(p).max(V_FLOOR);
        let (lo, hi) = (range[0] / v_range, range[0].max(range[1]) / v_range);
        let i0 = self.i_src.clamp(lo, hi);
        // Where the lag toward i_ref would leave [lo, hi], the instant it reaches the bound.
        let bound = if i_ref > hi {
            Some(hi)
        } else if i_ref < lo {
            Some(lo)
        } else {
            None
        };
        let (charge, i1) =
            match bound.map(|b| (b, p.tau * dvpp_math::log((i0 - i_ref) / (b - i_ref)))) {
                Some((b, t_b)) if t_b < h => (lag_charge(i0, i_ref, p.tau, t_b) + b * (h - t_b), b),
                _ => (
                    lag_charge(i0, i_ref, p.tau, h),
                    i_ref + (i0 - i_ref) * dvpp_math::exp(-h / p.tau),
                ),
            };
        let v0 = self.v(p);
        let predicted = self.w + v0 * charge - p.g * v0 * v0 * h - e_ac;
        let v1 = (2.0 * predicted.max(0.0) / p.c).sqrt();
        let source = 0.5 * (v0 + v1) * charge;
        let loss = p.g * h * 0.5 * (v0 * v0 + v1 * v1);
        self.w += source - loss - e_ac;
        self.i_src = i1;
        DcStep { source, loss }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: DcParams = DcParams {
        c: 0.096,
        g: 0.05,
        tau: 0.6,
    };
    const FREE: [f64; 2] = [-1e3, 1e3];
    /// A link so large that it stays at 1 pu: the source's energy is its charge.
    const STIFF: DcParams = DcParams {
        c: 1e9,
        g: 0.0,
        tau: 0.6,
    };

    /// The source's charge over `h` by 100 000 explicit substeps of the clamped lag (the
    /// reference for the exact rule), with the link held at 1 pu.
    fn fine_charge(i0: f64, i_ref: f64, h: f64, lo: f64, hi: f64) -> (f64, f64) {
        let n = 100_000;
        let dt = h / n as f64;
        let (mut i, mut q) = (i0.clamp(lo, hi), 0.0);
        for _ in 0..n {
            let next = (i + dt * (i_ref - i) / P.tau).clamp(lo, hi);
            q += 0.5 * (i + next) * dt;
            i = next;
        }
        (q, i)
    }

    #[test]
    fn within_its_range_the_source_is_the_lag_alone() {
        let mut a = DcState {
            i_src: 0.7,
            w: 0.048,
        };
        let mut b = a;
        let sa = a.step(&P, 0.5, 0.5 * 1e-3, 1e-3, FREE);
        let sb = b.step(&P, 0.5, 0.5 * 1e-3, 1e-3, [0.0, 0.8]);
        assert_eq!(a, b);
        assert_eq!(sa.source, sb.source);
        assert!((a.i_src - (0.5 + 0.2 * dvpp_math::exp(-1e-3f64 / 0.6))).abs() < 1e-15);
    }

    #[test]
    fn a_range_that_falls_cuts_the_source_at_once_and_a_lag_stops_at_its_bound() {
        let at = |i_src| DcState { i_src, w: 0.5e9 };
        // A cloud: the source at 0.685 pu, its availability now 0.438 pu, the command above it.
        let mut d = at(0.685);
        let step = d.step(&STIFF, 0.9, 0.0, 1e-3, [0.0, 0.438]);
        assert_eq!(d.i_src, 0.438);
        assert!((step.source - 0.438e-3).abs() < 1e-15);
        // A lag rising toward a command beyond the bound reaches it within the step: the charge
        // is the lag's up to that instant and the bound's after it, as a fine integration has it.
        let (h, hi) = (0.05, 0.45);
        for (i0, i_ref) in [(0.40, 2.0), (0.05, -3.0)] {
            let mut d = at(i0);
            let step = d.step(&STIFF, i_ref, 0.0, h, [0.0, hi]);
            let (q, i) = fine_charge(i0, i_ref, h, 0.0, hi);
            assert_eq!(d.i_src, i);
            assert!((step.source - q).abs() < 1e-9, "{} vs {q}", step.source);
        }
    }

    #[test]
    fn the_energy_account_closes_at_the_bounds() {
        let mut d = DcState::steady(&P, 0.6);
        let w0 = d.w;
        let (mut src, mut loss, mut ac) = (0.0, 0.0, 0.0);
        for k in 0..20_000 {
            let t = k as f64 * 50e-6;
            let cap = if t < 0.2 { 0.8 } else { 0.44 };
            let e_ac = 0.35 * 50e-6;
            let v = d.v(&P);
            let s = d.step(&P, 5.0 * (1.0 - v) + 0.4, e_ac, 50e-6, [0.0, cap]);
            src += s.source;
            loss += s.loss;
            ac += e_ac;
            assert!(d.i_src * v <= cap + 1e-12);
        }
        assert!((src - loss - ac - (d.w - w0)).abs() < 1e-12);
    }
}
