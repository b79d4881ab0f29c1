//! The DVPP layer every DER controller runs, the phasor outer loop and the converter at EMT level (`crate::emt`): reference models, dc gains, set point, grid-forming angle and voltage matching.
//!
//! Written once here so that a unit behaves the same at both levels of modelling; each
//! controller adds only what its level needs (the phasor one its output-stage limits and dc-link
//! model, the EMT one its dq frame, inner loops and dc-voltage command).

use crate::adpf::AdpfParams;
use crate::{positive, AdpfKind, Error, Mode, Notice, MAX_LPF};
use dvpp_control::{Adpf, GflFpModel, GfmPfModel, TDes, VqModel};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The unit's desired behaviour `T_des` (`Tdes.H`, `Tdes.D`, `Tdes.Dq`, `Tdes.tau_q`): `T_pf =
/// 1/(H s + D)`, `T_qv = Dq` rolled off by `1/(tau_q s + 1)` in its inverse.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TDesParams {
    pub h: f64,
    pub d: f64,
    pub dq: f64,
    pub tau_q: f64,
}

impl TDesParams {
    /// `T_des`, checked; an error names the parameter at fault.
    pub fn build(&self) -> Result<TDes, Error> {
        let (h, d) = (self.h, self.d);
        if h < 0.0 {
            return Err(Error::field(
                "Tdes.H",
                format!("= {h}: T_pf = 1/(H s + D) is unstable"),
            ));
        }
        if h != 0.0 && !h.is_normal() {
            return Err(Error::field(
                "Tdes.H",
                format!(
                    "= {h:e}: must be 0 or at least {:e} (a subnormal inertia overflows T_pf = 1/(H s + D))",
                    f64::MIN_POSITIVE
                ),
            ));
        }
        if d <= 0.0 {
            return Err(Error::field(
                "Tdes.D",
                format!("= {d}: T_pf = 1/(H s + D) is not stable (needs D > 0)"),
            ));
        }
        let dq = positive(self.dq, "Tdes.Dq")?;
        let tau_q = positive(self.tau_q, "Tdes.tau_q")?;
        TDes::inertia_droop(h, d, dq, tau_q).map_err(|e| Error::field("Tdes", e))
    }
}

/// The p-f reference model of the unit's mode.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub enum PfReference {
    /// Grid-forming: `Δf = -(T_pf/m) Δp` (on S_dvpp).
    Forming(GfmPfModel),
    /// Grid-following: `Δp = -m T_pf⁻¹ Δf`, rolled off behind the PLL.
    Following(GflFpModel),
}

/// What the reference models are built from.
pub struct ReferenceSpec<'a> {
    pub mode: Mode,
    pub tdes: &'a TDes,
    pub adpf_p: &'a Adpf,
    pub adpf_q: &'a Adpf,
    /// Their parameters (the names in errors, the kinds).
    pub params_p: &'a AdpfParams,
    pub params_q: &'a AdpfParams,
    pub s_rated: f64,
    pub s_dvpp: f64,
    /// Grid-following roll-off `1/(τ_pll s + 1)^d`.
    pub pll_tau: f64,
    pub pll_order: u32,
}

/// The unit's local reference models `m⁻¹ T_pf` (or `m T_pf⁻¹`) and `m T_vq`, checked stable.
pub fn reference_models(spec: &ReferenceSpec) -> Result<(PfReference, VqModel), Error> {
    let order_name = spec.params_p.name("order");
    match spec.mode {
        Mode::GridForming => {
            // A grid-forming unit cannot have (near) zero p-f participation: its floor
            // bounds its p-f stiffness on its own rating (the operator's floor alike).
            let mu_min = dvpp_control::mu_min_gfm(spec.s_rated, spec.s_dvpp);
            let adpf = match spec.adpf_p {
                Adpf::LowPass(low) if low.mu < mu_min => {
                    spec.adpf_p.with_mu(mu_min).expect("valid gain")
                }
                a => a.clone(),
            };
            let pf = GfmPfModel::with_floor(spec.tdes, &adpf, mu_min).map_err(|e| {
                Error::field(
                    &order_name,
                    format!("the grid-forming reference T_pf/m is not realizable: {e}"),
                )
            })?;
            pf.check_stability()
                .map_err(|e| Error::field(&spec.params_p.name("kind"), e))?;
            let vq = VqModel::grid_forming_shaped(spec.tdes, spec.adpf_q)
                .map_err(|e| Error::field(&spec.params_q.name("kind"), e))?;
            Ok((PfReference::Forming(pf), vq))
        }
        Mode::GridFollowing => {
            let fp = GflFpModel::new(spec.tdes, spec.adpf_p, spec.pll_tau, spec.pll_order)
                .map_err(|e| {
                    Error::field(
                        "pll.order",
                        format!("the grid-following reference m T_pf^-1/(tau_pll s + 1)^d is not proper: {e}"),
                    )
                })?;
            fp.check_stability()
                .map_err(|e| Error::field(&spec.params_p.name("kind"), e))?;
            // The v-q reference keeps a first-order roll-off: more lag in that loop (gain
            // X_th/Dq) would destabilize it; its dominant lag is `vq.tau`.
            let vq = VqModel::grid_following_shaped(spec.tdes, spec.adpf_q, spec.pll_tau, 1)
                .map_err(|e| Error::field(&spec.params_q.name("kind"), e))?;
            Ok((PfReference::Following(fp), vq))
        }
    }
}

/// The dc gains a complement unit closes, scaled down when they sum above its share (the
/// participation condition), with one warning per episode (`warned`) to `notice`.
pub fn closed_gains(
    lpf: [f64; MAX_LPF],
    n: usize,
    share: f64,
    warned: &mut bool,
    notice: &mut dyn FnMut(Notice),
) -> [f64; MAX_LPF] {
    let sum: f64 = lpf[..n].iter().sum();
    let mut g = lpf;
    if sum > share + 1e-9 {
        if !*warned {
            *warned = true;
            notice(Notice::Warning(format!(
                "mu_p_lpf sums to {sum} > share {share}: scaled down to keep the participation condition"
            )));
        }
        for x in &mut g[..n] {
            *x *= share / sum;
        }
    }
    g
}

/// The operator's dc gains at this step: `mu_q` into the v-q reference model (if its shape has
/// a dc gain), and the closed units' gains a complement unit reads (scaled by
/// [`closed_gains`]); returns the p-f gains for [`set_p_gains`].
#[allow(clippy::too_many_arguments)]
pub fn operator_gains(
    vq: &mut VqModel,
    q_kind: AdpfKind,
    mu_q: f64,
    p_kind: AdpfKind,
    lpf: [f64; MAX_LPF],
    n_lpf: usize,
    share: f64,
    warned: &mut bool,
    notice: &mut dyn FnMut(Notice),
) -> Result<[f64; MAX_LPF], Error> {
    if q_kind.has_dc_gain() {
        vq.set_mu(mu_q).map_err(|e| Error::field("mu_q", e))?;
    }
    Ok(if p_kind == AdpfKind::Complement {
        closed_gains(lpf, n_lpf, share, warned, notice)
    } else {
        lpf
    })
}

/// A p-f reference model that takes the operator's dc gains.
pub trait PfGains {
    fn set_mu(&mut self, mu: f64) -> dvpp_control::Result<f64>;
    fn set_lpf_gains(&mut self, mus: &[f64]) -> dvpp_control::Result<()>;
}

impl PfGains for GfmPfModel {
    fn set_mu(&mut self, mu: f64) -> dvpp_control::Result<f64> {
        GfmPfModel::set_mu(self, mu)
    }
    fn set_lpf_gains(&mut self, mus: &[f64]) -> dvpp_control::Result<()> {
        GfmPfModel::set_lpf_gains(self, mus)
    }
}

impl PfGains for GflFpModel {
    fn set_mu(&mut self, mu: f64) -> dvpp_control::Result<f64> {
        GflFpModel::set_mu(self, mu)
    }
    fn set_lpf_gains(&mut self, mus: &[f64]) -> dvpp_control::Result<()> {
        GflFpModel::set_lpf_gains(self, mus)
    }
}

/// The operator's dc gains into a p-f reference model: `mu_p` (static, low-pass) or the closed
/// units' gains (complement); high- and band-pass shapes have none.
pub fn set_p_gains(
    model: &mut impl PfGains,
    kind: AdpfKind,
    mu_p: f64,
    lpf: &[f64],
) -> Result<(), Error> {
    match kind {
        AdpfKind::Static | AdpfKind::LowPass => model
            .set_mu(mu_p)
            .map(drop)
            .map_err(|e| Error::field("mu_p", e)),
        AdpfKind::Complement => model
            .set_lpf_gains(lpf)
            .map_err(|e| Error::field("mu_p_lpf", e)),
        // No dc gain: the shape is all there is.
        AdpfKind::HighPass | AdpfKind::BandPass => Ok(()),
    }
}

/// The grid-forming frequency channel over a step of `h`: `Δf = -(T_pf/m) Δp` with `Δp` on
/// S_dvpp; returns `Δf` (pu) and the angle the frame turns beyond `2π f_nom h` (rad).
pub fn forming_angle(pf: &mut GfmPfModel, dp: f64, h: f64, f_nom: f64) -> (f64, f64) {
    let (df, df_int) = pf.step_with_integral(dp, h);
    (df, 2.0 * PI * f_nom * df_int)
}

/// The grid-forming PI matching controller (option A) on the voltage magnitude: `q` tracks
/// `q_ref`; the output `e0 + k_p (q_ref - q) + ∫k_i (q_ref - q)` stays within `[0, e_max]` and
/// the integral `e_int` stops while it is held there (anti-windup).
#[allow(clippy::too_many_arguments)]
pub fn voltage_matching(
    e_int: &mut f64,
    q_ref: f64,
    q: f64,
    e0: f64,
    kp: f64,
    ki: f64,
    e_max: f64,
    h: f64,
) -> f64 {
    let e = q_ref - q;
    let integral = *e_int + ki * e * h;
    let unclamped = e0 + kp * e + integral;
    let out = unclamped.clamp(0.0, e_max);
    if unclamped == out {
        *e_int = integral;
    }
    out
}

/// The primary source's availability at `t`: `P_avail0`, stepped by `dp` from `t_step` on, never
/// below zero (pu on S_base).
pub fn availability(p_avail0: f64, t_step: f64, dp: f64, t: f64) -> f64 {
    let step = if t >= t_step { dp } else { 0.0 };
    (p_avail0 + step).max(0.0)
}
