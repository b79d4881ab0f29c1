//! The dc side of a unit: a primary source with a lag and its availability limits, the dc link as
//! an energy store the ac side draws from, and the dc-voltage control (all pu on `S_rated`).
//!
//! State (deviations from nominal, so the model is linear and integrated exactly; `r` and the
//! input are kept relative to the ac power at initialization, so a flat start stays exactly flat):
//! `r = p_src - G_dc` (source power beyond the nominal link losses) and `e = W - W*`, the stored
//! energy `W = C_dc v_dc²/2` above its nominal `W* = C_dc/2`. With `g = 2 G_dc/C_dc` the link
//! losses are `G_dc v_dc² = G_dc + g e` and
//!
//! ```text
//! e' = r - p_ac - g e                                         (energy balance of the link)
//! τ_dc r' = p_ac + g e - k_e e - k_d e' - r                   (dc-voltage control through the source lag)
//! ```
//!
//! The command is the ac-power and loss feedforward plus the proportional voltage control of the
//! converter model the paper takes its dc side from, written on the stored energy (`k_e = k_dc/C_dc`
//! equals `k_dc` on `v_dc` near 1 pu, and makes the loop linear), plus the damping term `k_d e'` on
//! the capacitor's power. Without it the loop `k_dc`–`C_dc`–`τ_dc` has `ζ = (1 + τ g)/(2√(k_e τ))`,
//! 0.02–0.04 with the case-study source lags; `k_d` places `ζ` at `dc.zeta`.
//!
//! Two more states integrate `r` and `e` so the step also yields the exact source and loss
//! energies: over any run `E_src - E_ac - E_loss = W - W(0)` to rounding.

use crate::dc::damping_gain;
use dvpp_control::{Hold, LtiSimulator, StateSpace};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Parameters of the dc side (pu on `S_rated`, seconds).
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct DcParams {
    pub tau: f64,
    pub c: f64,
    pub g: f64,
    pub k_dc: f64,
    pub zeta: f64,
    /// The source can absorb power (a battery): `p_src` within `[-P_avail, P_avail]`.
    pub storage: bool,
    pub v_min: f64,
    pub v_max: f64,
    /// Time over which the ac side may draw the link's usable energy (`W - W_min`).
    pub t_budget: f64,
}

impl DcParams {
    /// Gain of the damping term: `ζ` of the closed loop at `zeta` (0 when the loop has that
    /// much damping without it).
    pub fn k_d(&self) -> f64 {
        damping_gain(self.tau, self.c, self.g, self.k_dc, self.zeta)
    }

    /// Damping ratio of the loop with the damping gain `k_d`.
    pub fn damping(&self, k_d: f64) -> f64 {
        let k_e = self.k_dc / self.c;
        let g = 2.0 * self.g / self.c;
        (1.0 + self.tau * g + k_d) / (2.0 * (k_e * self.tau).sqrt())
    }

    fn nominal_energy(&self) -> f64 {
        0.5 * self.c
    }

    /// The free loop (`source_held` false) or the loop with the source held at a limit.
    fn model(&self, source_held: bool) -> StateSpace {
        let (tau, c, gd, k_dc) = (self.tau, self.c, self.g, self.k_dc);
        let (k_e, g, k_d) = (k_dc / c, 2.0 * gd / c, self.k_d());
        // Rows: r, e, ∫r, ∫e; input p_ac.
        let (ar, br) = if source_held {
            ([0.0; 4], 0.0)
        } else {
            (
                [-(1.0 + k_d) / tau, (g - k_e + k_d * g) / tau, 0.0, 0.0],
                (1.0 + k_d) / tau,
            )
        };
        #[rustfmt::skip]
        let a = DMatrix::from_row_slice(4, 4, &[
            ar[0], ar[1], ar[2], ar[3],
            1.0,   -g,    0.0,   0.0,
            1.0,   0.0,   0.0,   0.0,
            0.0,   1.0,   0.0,   0.0,
        ]);
        let b = DVector::from_column_slice(&[br, -1.0, 0.0, 0.0]);
        StateSpace::new(a, b, DMatrix::identity(4, 4), DVector::zeros(4)).expect("dc realization")
    }
}

/// Which dc-side limit acts.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct DcLimits {
    /// The source sits at `P_avail` (or at its floor).
    pub source: bool,
}

/// The dc side's state and its energy account.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct DcSide {
    params: DcParams,
    free: LtiSimulator,
    held: LtiSimulator,
    /// The source sat at a bound at the end of the last step.
    at_bound: bool,
    /// The ac power at initialization: the state's `r` and the input are relative to it.
    p0: f64,
    /// Energies since initialization (pu·s on `S_rated`): source, ac side, link losses.
    pub e_src: f64,
    pub e_ac: f64,
    pub e_loss: f64,
    /// Stored energy at initialization.
    pub w0: f64,
    /// The link's reserve is spent: it was run down to its floor (or up to its ceiling) and the
    /// dc limit has acted since; the budget then holds the ac side to the source (see
    /// [`DcSide::ac_budget`]).
    #[serde(default)]
    reserve_spent: Reserve,
}

/// Which side of the link's reserve is spent ([`DcSide::ac_budget`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Reserve {
    /// Run down to `v_min`: while the source is at its upper bound, the ac side may draw no
    /// more than the source gives.
    pub floor: bool,
    /// Run up to `v_max`: while the source is at its lower bound, the ac side may return no
    /// more than the source takes.
    pub ceiling: bool,
    /// The source sits at its upper (lower) bound.
    pub at_cap: bool,
    pub at_floor: bool,
}

/// The link counts as run down to its floor (up to its ceiling) within this fraction of its
/// usable energy `W* - W_min` (`W_max - W*`).
const RESERVE_SPENT: f64 = 0.05;

impl DcSide {
    /// At the nominal dc voltage, supplying `p_ac` (and the losses) in steady state.
    pub fn new(params: DcParams, p_ac: f64) -> Self {
        // Both start at the zero state (the operating point).
        let free = LtiSimulator::new(params.model(false), Hold::Zero);
        let held = LtiSimulator::new(params.model(true), Hold::Zero);
        DcSide {
            params,
            free,
            held,
            at_bound: false,
            p0: p_ac,
            e_src: 0.0,
            e_ac: 0.0,
            e_loss: 0.0,
            w0: params.nominal_energy(),
            reserve_spent: Reserve::default(),
        }
    }

    fn x(&self) -> &DVector<f64> {
        self.free.state()
    }

    /// Source power `p_src`.
    pub fn p_src(&self) -> f64 {
        self.x()[0] + self.p0 + self.params.g
    }

    /// Stored energy `W`.
    pub fn energy(&self) -> f64 {
        self.params.nominal_energy() + self.x()[1]
    }

    /// dc-link voltage `v_dc = √(2W/C)` (0 for an empty link).
    pub fn v_dc(&self) -> f64 {
        (2.0 * self.energy().max(0.0) / self.params.c).sqrt()
    }

    /// Link losses `G_dc v_dc²`.
    pub fn p_loss(&self) -> f64 {
        2.0 * self.params.g / self.params.c * self.energy()
    }

    /// The range of ac power the link can supply now: the source and losses, plus (minus) the
    /// usable stored energy above `v_min` (room below `v_max`) spread over `t_budget`. Once the
    /// reserve is spent (the link was run down to `v_min` or up to `v_max`), only the source and
    /// losses until the dc limit has been released ([`DcSide::update_reserve`]): the link then
    /// refills and stays as the reserve, where drawing it again whenever the source fell short
    /// cycled it between its floor and nominal.
    pub fn ac_budget(&self) -> (f64, f64) {
        let p = &self.params;
        let w = self.energy();
        let (w_min, w_max) = (
            0.5 * p.c * dvpp_math::powi(p.v_min, 2),
            0.5 * p.c * dvpp_math::powi(p.v_max, 2),
        );
        let net = self.p_src() - self.p_loss();
        let spent = self.reserve_spent;
        (
            net - if spent.ceiling && spent.at_floor {
                0.0
            } else {
                (w_max - w).max(0.0) / p.t_budget
            },
            net + if spent.floor && spent.at_cap {
                0.0
            } else {
                (w - w_min).max(0.0) / p.t_budget
            },
        )
    }

    /// Which side of the reserve is spent ([`DcSide::ac_budget`]).
    #[cfg(test)]
    pub fn reserve_spent(&self) -> Reserve {
        self.reserve_spent
    }

    /// After a step: the reserve is spent when the link is within `RESERVE_SPENT` of its usable
    /// energy from `v_min` or `v_max`, and available again once the dc limit's episode has ended
    /// (`dc_limit_on` false: the limit has not acted for [`super::limits::RELEASE`]).
    pub fn update_reserve(&mut self, dc_limit_on: bool, cap: f64) {
        let p = &self.params;
        let floor = if p.storage { -cap } else { 0.0 };
        let src = self.p_src();
        let (w, w_star) = (self.energy(), p.nominal_energy());
        let (w_min, w_max) = (
            0.5 * p.c * dvpp_math::powi(p.v_min, 2),
            0.5 * p.c * dvpp_math::powi(p.v_max, 2),
        );
        let spent = &mut self.reserve_spent;
        if !dc_limit_on {
            *spent = Reserve::default();
        }
        spent.floor |= w - w_min <= RESERVE_SPENT * (w_star - w_min);
        spent.ceiling |= w_max - w <= RESERVE_SPENT * (w_max - w_star);
        spent.at_cap = src >= cap;
        spent.at_floor = src <= floor;
    }

    /// Advance by `h` with the ac side drawing `p_ac` and the source within `[floor, cap]`
    /// (`cap` = `P_avail` on `S_rated`).
    pub fn step(&mut self, p_ac: f64, h: f64, cap: f64) -> DcLimits {
        let p = self.params;
        let floor = if p.storage { -cap } else { 0.0 };
        let x0: [f64; 4] = self.x().as_slice().try_into().expect("4 dc states");
        let (src0, u) = (self.p_src(), p_ac - self.p0);
        // Held at a bound while the command pushes beyond it.
        let pushes = {
            let (k_e, g, k_d) = (p.k_dc / p.c, 2.0 * p.g / p.c, p.k_d());
            let de = x0[0] - u - g * x0[1];
            let cmd = p_ac + p.g + g * x0[1] - k_e * x0[1] - k_d * de;
            (src0 >= cap && cmd > src0) || (src0 <= floor && cmd < src0)
        };
        let sim = if self.at_bound && pushes {
            &mut self.held
        } else {
            &mut self.free
        };
        sim.set_state(&x0, u).expect("dc state");
        sim.step_all(u, h);
        let mut x: [f64; 4] = sim.state().as_slice().try_into().expect("4 dc states");
        // Energy account of the step, exact for the held input.
        self.e_src += (x[2] - x0[2]) + (self.p0 + p.g) * h;
        self.e_loss += 2.0 * p.g / p.c * (x[3] - x0[3]) + p.g * h;
        self.e_ac += p_ac * h;
        // The source cannot leave its range (a lag that overshot within the step stops there).
        let src = x[0] + self.p0 + p.g;
        let limited = src.clamp(floor, cap.max(floor));
        self.at_bound = limited != src || (self.at_bound && pushes);
        if limited != src {
            x[0] = limited - self.p0 - p.g;
        }
        self.free.set_state(&x, u).expect("dc state");
        DcLimits {
            source: self.at_bound,
        }
    }

    /// `E_src - E_ac - E_loss - (W - W(0))`: zero to rounding.
    #[cfg(test)]
    pub fn energy_residual(&self) -> f64 {
        self.e_src - self.e_ac - self.e_loss - (self.energy() - self.w0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bess() -> DcParams {
        DcParams {
            tau: 0.2,
            c: 0.096,
            g: 0.05,
            k_dc: 100.0,
            zeta: 0.7,
            storage: true,
            v_min: 0.8,
            v_max: 1.2,
            t_budget: 0.02,
        }
    }

    #[test]
    fn the_damping_term_places_the_dc_mode() {
        let p = bess();
        // Without the damping term: the lightly damped mode of k_dc, C_dc and tau_dc.
        assert!((p.damping(0.0) - 0.042).abs() < 1e-3, "{}", p.damping(0.0));
        assert!((p.damping(p.k_d()) - 0.7).abs() < 1e-12);
        // A source fast enough needs none.
        let fast = DcParams { tau: 1e-4, ..p };
        assert_eq!(fast.k_d(), 0.0);
    }

    #[test]
    fn a_power_step_settles_without_ringing_and_keeps_the_energy_account() {
        let mut dc = DcSide::new(bess(), 0.2);
        // The ac side steps from 0.2 to 0.5 pu: the link dips, then comes back with at most the
        // overshoot of a ζ = 0.7 mode (4.6 % of the dip), not the ringing of ζ = 0.04 (88 %).
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        for _ in 0..3000 {
            dc.step(0.5, 1e-3, 1.0);
            lo = lo.min(dc.v_dc());
            hi = hi.max(dc.v_dc());
        }
        let overshoot = (hi - 1.0) / (1.0 - lo);
        assert!(
            overshoot < 0.06,
            "rings: overshoot {overshoot:.3} of the dip ({lo}..{hi})"
        );
        assert!(
            (dc.v_dc() - 1.0).abs() < 1e-6,
            "settles at 1 pu: {}",
            dc.v_dc()
        );
        assert!((dc.p_src() - 0.5 - dc.p_loss()).abs() < 1e-6);
        let moved = dc.e_src.abs() + dc.e_ac.abs();
        assert!(dc.energy_residual().abs() <= 1e-12 * moved);
    }

    #[test]
    fn a_source_at_its_limit_cannot_hold_the_link_and_the_budget_shrinks() {
        // A PV source capped at 0.3 pu while the ac side draws 0.5 pu.
        let p = DcParams {
            storage: false,
            ..bess()
        };
        let mut dc = DcSide::new(p, 0.2);
        let (_, hi0) = dc.ac_budget();
        let mut limits = DcLimits::default();
        for _ in 0..20 {
            limits = dc.step(0.5, 1e-3, 0.3);
        }
        assert!(limits.source);
        assert!(dc.p_src() <= 0.3 + 1e-15);
        assert!(dc.v_dc() < 1.0);
        let (_, hi) = dc.ac_budget();
        assert!(hi < hi0);
        assert!(dc.energy_residual().abs() < 1e-14);
    }

    #[test]
    fn a_spent_reserve_is_held_back_while_the_source_is_at_its_cap() {
        // A PV source capped at 0.3 pu while the ac side draws the budget's top.
        let p = DcParams {
            storage: false,
            ..bess()
        };
        let mut dc = DcSide::new(p, 0.2);
        let cap = 0.3;
        for _ in 0..2000 {
            let (_, hi) = dc.ac_budget();
            dc.step(hi.max(0.5), 1e-3, cap);
            dc.update_reserve(true, cap);
            if dc.reserve_spent().floor {
                break;
            }
        }
        let spent = dc.reserve_spent();
        assert!(spent.floor && spent.at_cap, "{spent:?}");
        assert!(dc.v_dc() < 0.82, "run down to v_dc_min: {}", dc.v_dc());
        // Only the source, less the losses, while the source is at its cap.
        let (_, hi) = dc.ac_budget();
        assert!((hi - (dc.p_src() - dc.p_loss())).abs() < 1e-12);
        // Drawing less than the source refills the link; the reserve stays held back until the
        // dc limit's episode has ended.
        for _ in 0..3000 {
            dc.step(0.1, 1e-3, cap);
            dc.update_reserve(true, cap);
        }
        assert!(dc.v_dc() > 0.99, "refilled: {}", dc.v_dc());
        assert!(dc.reserve_spent().floor);
        dc.update_reserve(false, cap);
        assert!(!dc.reserve_spent().floor);
        let (_, hi) = dc.ac_budget();
        assert!(hi > dc.p_src() - dc.p_loss() + 0.5);
        assert!(dc.energy_residual().abs() < 1e-13);
    }
}
