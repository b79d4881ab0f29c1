//! DER matching controller FMU: one DVPP unit, grid-forming or grid-following, that realizes
//! its local reference model with adaptive dynamic participation factors.
//!
//! * Grid-forming (`mode` = 1): `Δf = -T_i^pf Δp` with `T_i^pf = T_pf/m_i^p` (Δp from the measured
//!   `p`, converted to the DVPP base `S_dvpp`), and the imposed angle
//!   `θ = θ₀ + 2π f_nom ∫Δf dt` (integrated exactly over each step). The voltage magnitude `E`
//!   comes from a PI matching controller (option A) making `q` track
//!   `q_ref = q₀ - T_i^vq Δv`. `E∠θ` starts behind the transformer impedance at the
//!   measured operating point, so a coupled run starts flat.
//! * Grid-following (`mode` = 2): a PLL on `v_angle` measures `Δf`; the converter injects
//!   `p_ref = p₀ - T_i^fp Δf` and `q_ref = q₀ - T_i^vq Δv`, limited to the rating circle.
//!
//! The set point `p₀` is the dispatch at initialization, curtailed to what the primary source
//! allows with its reserve: `p₀(t) = min(p_dispatch, deload · P_avail(t) - G_dc)` (a cloud that
//! cuts a PV plant's availability lowers its set point; the DVPP answers that deficit like a
//! load step).
//!
//! The primary source and dc side: an availability profile `P_avail(t)`, a dc source that follows
//! its command with the lag `τ_dc` within `[0, P_avail]`, and a dc link (`C_dc`, `G_dc`) whose
//! voltage `v_dc` a proportional controller (`k_dc`) holds. The control math is `dvpp_control`.

pub mod ports;
mod preset;

pub use preset::{Preset, UnitDefaults};

use dvpp_control::phasor::internal_voltage;
use dvpp_control::{
    Adpf, GflFpModel, GfmPfModel, Hold, LowPassSpec, LtiSimulator, StateSpace, TDes, VqModel,
};
use fmi_export::{Boolean, Context, Integer, Model, ModelError, Real, Spec, Store, Variables};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Most low-pass units a complement unit can close (`mu_p_lpf[1..8]`).
pub const MAX_LPF: usize = 8;

/// `mode` values.
pub const GRID_FORMING: i32 = 1;
/// `mode` value of a grid-following unit.
pub const GRID_FOLLOWING: i32 = 2;

/// `adpf.*.kind` values.
pub mod kind {
    /// `m = μ`.
    pub const STATIC: i32 = 0;
    /// `m = μ/(τ s + 1)^d`.
    pub const LOW_PASS: i32 = 1;
    /// `m = τ s/(τ s + 1)^d`.
    pub const HIGH_PASS: i32 = 2;
    /// `m = (τ₁ - τ₂) s/((τ₁ s + 1)^d₁ (τ₂ s + 1)^d₂)`.
    pub const BAND_PASS: i32 = 3;
    /// `m = c - Σ_j μ_j/(τ_j s + 1)^d_j`.
    pub const COMPLEMENT: i32 = 4;
}

/// Handles of one channel's ADPF shape parameters (`adpf.p.*` or `adpf.q.*`).
#[derive(Clone, Serialize, Deserialize)]
struct AdpfParams {
    prefix: String,
    kind: Integer,
    tau: Real,
    tau2: Real,
    order: Integer,
    order2: Integer,
    /// Complement only (p channel): share, number of closed units, their time constants, orders.
    share: Option<Real>,
    n_lpf: Option<Integer>,
    lpf_tau: Vec<Real>,
    lpf_order: Vec<Integer>,
}

/// The grid-forming controller state.
#[derive(Clone, Serialize, Deserialize)]
struct Forming {
    pf: GfmPfModel,
    /// Integral part of the PI matching controller on `E`.
    e_int: f64,
}

/// The grid-following controller state.
#[derive(Clone, Serialize, Deserialize)]
struct Following {
    fp: GflFpModel,
    /// PLL: states `[∫e, θ_pll]`, input `v_angle`, outputs `[Δf_pll, θ_pll]`.
    pll: LtiSimulator,
}

#[derive(Clone, Serialize, Deserialize)]
enum Channel {
    Forming(Box<Forming>),
    Following(Box<Following>),
}

/// Everything `initialize` builds from the parameters.
#[derive(Clone, Serialize, Deserialize)]
struct Runtime {
    channel: Channel,
    vq: VqModel,
    /// dc side: states `[p_dc - G_dc, v_dc - 1]` (pu on `S_rated`), input `p_ac`.
    dc: LtiSimulator,
    /// Kind of the p-f ADPF (which gains the inputs set).
    p_kind: i32,
    n_lpf: usize,
    q_kind: i32,
    p0: f64,
    q0: f64,
    v0: f64,
    e0: f64,
    theta0: f64,
    /// Grid-following: the PLL frequency held over the next step.
    df_held: f64,
    /// Grid-forming: the reactive reference held over the next step.
    q_ref: f64,
    /// Warnings already given in this episode (each once).
    warned_rating: bool,
    warned_dc: bool,
    warned_gains: bool,
}

/// The DER's variable handles and, after initialization, its controller.
#[derive(Clone, Serialize, Deserialize)]
pub struct Der {
    mode: Integer,
    s_rated: Real,
    s_base: Real,
    s_dvpp: Real,
    f_nom: Real,
    h: Real,
    d: Real,
    dq: Real,
    tau_q: Real,
    r_f: Real,
    x_f: Real,
    adpf_p: AdpfParams,
    adpf_q: AdpfParams,
    pll_kp: Real,
    pll_ki: Real,
    pll_tau: Real,
    pll_order: Integer,
    qpi_kp: Real,
    qpi_ki: Real,
    e_max: Real,
    tau_dc: Real,
    c_dc: Real,
    g_dc: Real,
    storage: Boolean,
    deload: Real,
    k_dc: Real,
    p_avail0: Real,
    avail_t: Real,
    avail_dp: Real,
    p: Real,
    q: Real,
    v: Real,
    v_angle: Real,
    mu_p: Real,
    mu_q: Real,
    mu_p_lpf: Vec<Real>,
    theta: Real,
    e: Real,
    df: Real,
    p_ref: Real,
    p_set: Real,
    q_ref: Real,
    p_avail: Real,
    v_dc: Real,
    p_dc: Real,
    rt: Option<Runtime>,
}

/// Structure of the DER: which of the paper's units it is.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DerConfig {
    /// `"wind"`, `"pv"` or `"bess"`: the case-study unit whose ratings, `τ_dc`, ADPF shapes and
    /// dc gains become the start values; none: a generic unit with a static ADPF.
    #[serde(default)]
    pub preset: Option<Preset>,
}

/// An error naming the parameter (or input) at fault: `'name' = value: why` or `'name': why`.
fn err(name: &str, message: impl std::fmt::Display) -> ModelError {
    let message = message.to_string();
    let sep = if message.starts_with('=') { " " } else { ": " };
    ModelError(format!("'{name}'{sep}{message}"))
}

fn positive(s: &Store, r: Real, name: &str) -> Result<f64, ModelError> {
    let x = s[r];
    if x > 0.0 && x.is_finite() {
        Ok(x)
    } else {
        Err(err(name, format!("= {x}: must be > 0")))
    }
}

impl AdpfParams {
    fn declare(v: &mut Variables, ch: &str, d: &preset::AdpfDefaults, complement: bool) -> Self {
        let prefix = format!("adpf.{ch}");
        let what = if ch == "p" { "p-f" } else { "v-q" };
        let kinds = if complement {
            "0 static, 1 low-pass, 2 high-pass, 3 band-pass, 4 complement of low-pass units"
        } else {
            "0 static, 1 low-pass, 2 high-pass, 3 band-pass"
        };
        let kind = v.integer(
            Spec::parameter(
                &format!("{prefix}.kind"),
                d.kind,
                "",
                &format!("ADPF shape of the {what} channel: {kinds}"),
            )
            .range(0.0, if complement { 4.0 } else { 3.0 }),
        );
        let tau = v.real(
            Spec::parameter(
                &format!("{prefix}.tau"),
                d.tau,
                "s",
                &format!("{what} ADPF time constant (low-pass, high-pass; slow one of band-pass)"),
            )
            .min(0.0),
        );
        let tau2 = v.real(
            Spec::parameter(
                &format!("{prefix}.tau2"),
                d.tau2,
                "s",
                &format!("{what} ADPF fast time constant of a band-pass (< tau)"),
            )
            .min(0.0),
        );
        let order = v.integer(
            Spec::parameter(
                &format!("{prefix}.order"),
                d.order,
                "",
                &format!("{what} ADPF order d (of the tau factor)"),
            )
            .range(1.0, 8.0),
        );
        let order2 = v.integer(
            Spec::parameter(
                &format!("{prefix}.order2"),
                d.order2,
                "",
                &format!("{what} ADPF order of the tau2 factor of a band-pass"),
            )
            .range(1.0, 8.0),
        );
        let (mut share, mut n_lpf, mut lpf_tau, mut lpf_order) = (None, None, vec![], vec![]);
        if complement {
            share = Some(
                v.real(
                    Spec::parameter(
                        &format!("{prefix}.share"),
                        1.0,
                        "1",
                        "complement: total participation c it closes, m = c - sum of the low-pass factors",
                    )
                    .range(0.0, 1.0),
                ),
            );
            n_lpf = Some(
                v.integer(
                    Spec::parameter(
                        &format!("{prefix}.n_lpf"),
                        d.lpf_tau.len() as i32,
                        "",
                        "complement: number of low-pass units it closes (gains from mu_p_lpf[k])",
                    )
                    .range(0.0, MAX_LPF as f64),
                ),
            );
            for k in 1..=MAX_LPF {
                lpf_tau.push(
                    v.real(
                        Spec::parameter(
                            &format!("{prefix}.lpf[{k}].tau"),
                            d.lpf_tau.get(k - 1).copied().unwrap_or(1.0),
                            "s",
                            &format!("complement: time constant of low-pass unit {k}"),
                        )
                        .min(0.0),
                    ),
                );
                lpf_order.push(
                    v.integer(
                        Spec::parameter(
                            &format!("{prefix}.lpf[{k}].order"),
                            1,
                            "",
                            &format!("complement: order of low-pass unit {k}"),
                        )
                        .range(1.0, 8.0),
                    ),
                );
            }
        }
        AdpfParams {
            prefix,
            kind,
            tau,
            tau2,
            order,
            order2,
            share,
            n_lpf,
            lpf_tau,
            lpf_order,
        }
    }

    fn name(&self, field: &str) -> String {
        format!("{}.{field}", self.prefix)
    }

    /// The ADPF these parameters describe, with dc gain `mu` (static, low-pass) or the closed
    /// units' gains `lpf_mu` (complement).
    fn build(&self, s: &Store, mu: f64, lpf_mu: &[f64]) -> Result<Adpf, ModelError> {
        let order = |i: Integer| s[i] as u32;
        let wrap = |field: &str| {
            let name = self.name(field);
            move |e: dvpp_control::DvppError| err(&name, e)
        };
        match s[self.kind] {
            kind::STATIC => Adpf::static_gain(mu).map_err(wrap("kind")),
            kind::LOW_PASS => {
                let tau = positive(s, self.tau, &self.name("tau"))?;
                Adpf::low_pass(mu, tau, order(self.order)).map_err(wrap("tau"))
            }
            kind::HIGH_PASS => {
                let tau = positive(s, self.tau, &self.name("tau"))?;
                Adpf::high_pass(tau, order(self.order)).map_err(wrap("tau"))
            }
            kind::BAND_PASS => {
                let tau = positive(s, self.tau, &self.name("tau"))?;
                let tau2 = positive(s, self.tau2, &self.name("tau2"))?;
                if tau2 >= tau {
                    return Err(err(
                        &self.name("tau2"),
                        format!("= {tau2}: a band-pass needs tau2 < tau = {tau}"),
                    ));
                }
                Adpf::band_pass(tau, tau2, order(self.order), order(self.order2))
                    .map_err(wrap("tau2"))
            }
            kind::COMPLEMENT if self.share.is_some() => {
                let share = s[self.share.expect("complement parameters")];
                if share <= 0.0 {
                    return Err(err(&self.name("share"), format!("= {share}: must be > 0")));
                }
                let n = s[self.n_lpf.expect("complement parameters")] as usize;
                let mut specs = Vec::with_capacity(n);
                for (k, (&mu, (&tau, &ord))) in lpf_mu
                    .iter()
                    .zip(self.lpf_tau.iter().zip(&self.lpf_order))
                    .take(n)
                    .enumerate()
                {
                    let name = format!("{}.lpf[{}].tau", self.prefix, k + 1);
                    let tau = positive(s, tau, &name)?;
                    specs.push(LowPassSpec {
                        mu,
                        tau,
                        order: order(ord),
                    });
                }
                let sum: f64 = lpf_mu[..n].iter().sum();
                if sum > share + 1e-9 {
                    return Err(err(
                        "mu_p_lpf",
                        format!("the closed units' dc gains sum to {sum} > share {share}"),
                    ));
                }
                Adpf::complement_of_specs(share, specs).map_err(wrap("n_lpf"))
            }
            k => Err(err(
                &self.name("kind"),
                format!("= {k} is not supported here"),
            )),
        }
    }
}

/// Exact ZOH model of the PLL: `e = v_angle - θ_pll`, `Δω = k_p e + k_i ∫e`, `θ_pll' = Δω`;
/// outputs `Δf_pll = Δω/(2π f_nom)` (pu) and `θ_pll`.
fn pll_model(kp: f64, ki: f64, f_nom: f64) -> StateSpace {
    let w = 2.0 * PI * f_nom;
    StateSpace::new(
        DMatrix::from_row_slice(2, 2, &[0.0, -1.0, ki, -kp]),
        DVector::from_column_slice(&[1.0, kp]),
        DMatrix::from_row_slice(2, 2, &[ki / w, -kp / w, 0.0, 1.0]),
        DVector::from_column_slice(&[kp / w, 0.0]),
    )
    .expect("PLL realization")
}

/// dc side around `v_dc = 1`: states `r = p_dc - G_dc`, `w = v_dc - 1`, input `p_ac`:
/// `τ_dc r' = p_ac + (G_dc - k_dc) w - r` (command: ac power, link losses and the proportional
/// voltage control), `C_dc w' = r - p_ac - G_dc w`.
fn dc_model(tau: f64, c: f64, g: f64, k: f64) -> StateSpace {
    StateSpace::new(
        DMatrix::from_row_slice(2, 2, &[-1.0 / tau, (g - k) / tau, 1.0 / c, -g / c]),
        DVector::from_column_slice(&[1.0 / tau, -1.0 / c]),
        DMatrix::identity(2, 2),
        DVector::zeros(2),
    )
    .expect("dc realization")
}

impl Der {
    fn lpf_gains(&self, s: &Store) -> [f64; MAX_LPF] {
        let mut out = [0.0; MAX_LPF];
        for (o, &r) in out.iter_mut().zip(&self.mu_p_lpf) {
            *o = s[r];
        }
        out
    }

    fn available(&self, s: &Store, t: f64) -> f64 {
        let step = if t >= s[self.avail_t] {
            s[self.avail_dp]
        } else {
            0.0
        };
        (s[self.p_avail0] + step).max(0.0)
    }

    fn build(
        &self,
        s: &mut Store,
        ctx: &mut Context,
        warned_rating: bool,
        warned_dc: bool,
        warned_gains: bool,
    ) -> Result<Runtime, ModelError> {
        let mode = s[self.mode];
        for (r, name) in [
            (self.s_rated, "S_rated"),
            (self.s_base, "S_base"),
            (self.s_dvpp, "S_dvpp"),
            (self.f_nom, "f_nom"),
            (self.x_f, "X_f"),
        ] {
            positive(s, r, name)?;
        }
        let (h, d) = (s[self.h], s[self.d]);
        if h < 0.0 {
            return Err(err(
                "Tdes.H",
                format!("= {h}: T_pf = 1/(H s + D) is unstable"),
            ));
        }
        if d <= 0.0 {
            return Err(err(
                "Tdes.D",
                format!("= {d}: T_pf = 1/(H s + D) is not stable (needs D > 0)"),
            ));
        }
        let dq = positive(s, self.dq, "Tdes.Dq")?;
        let tau_q = positive(s, self.tau_q, "Tdes.tau_q")?;
        let tdes = TDes::inertia_droop(h, d, dq, tau_q).map_err(|e| err("Tdes", e))?;

        let lpf = self.lpf_gains(s);
        let adpf_p = self.adpf_p.build(s, s[self.mu_p], &lpf)?;
        let adpf_q = self.adpf_q.build(s, s[self.mu_q], &[])?;
        let p_kind = s[self.adpf_p.kind];
        let order_name = self.adpf_p.name("order");

        let pll_tau = positive(s, self.pll_tau, "pll.tau")?;
        let pll_order = s[self.pll_order] as u32;
        let (channel, vq) = match mode {
            GRID_FORMING => {
                let adpf = match &adpf_p {
                    // A grid-forming unit cannot have (near) zero p-f participation.
                    Adpf::LowPass(spec) if spec.mu < dvpp_control::MU_MIN_GFM => adpf_p
                        .with_mu(dvpp_control::MU_MIN_GFM)
                        .expect("valid gain"),
                    a => a.clone(),
                };
                let pf = GfmPfModel::new(&tdes, &adpf).map_err(|e| {
                    err(
                        &order_name,
                        format!("the grid-forming reference T_pf/m is not realizable: {e}"),
                    )
                })?;
                pf.check_stability()
                    .map_err(|e| err(&self.adpf_p.name("kind"), e))?;
                let vq = VqModel::grid_forming_shaped(&tdes, &adpf_q)
                    .map_err(|e| err(&self.adpf_q.name("kind"), e))?;
                (Channel::Forming(Box::new(Forming { pf, e_int: 0.0 })), vq)
            }
            GRID_FOLLOWING => {
                let fp = GflFpModel::new(&tdes, &adpf_p, pll_tau, pll_order).map_err(|e| {
                    err(
                        "pll.order",
                        format!("the grid-following reference m T_pf^-1/(tau_pll s + 1)^d is not proper: {e}"),
                    )
                })?;
                fp.check_stability()
                    .map_err(|e| err(&self.adpf_p.name("kind"), e))?;
                let vq = VqModel::grid_following_shaped(&tdes, &adpf_q, pll_tau, pll_order)
                    .map_err(|e| err(&self.adpf_q.name("kind"), e))?;
                let (kp, ki) = (s[self.pll_kp], s[self.pll_ki]);
                if !(kp > 0.0 && ki > 0.0) {
                    return Err(err(
                        "pll.kp",
                        format!("PLL gains kp = {kp}, ki = {ki} must be > 0"),
                    ));
                }
                let mut pll = LtiSimulator::new(pll_model(kp, ki, s[self.f_nom]), Hold::Zero);
                pll.set_state(
                    DVector::from_column_slice(&[0.0, s[self.v_angle]]),
                    s[self.v_angle],
                )
                .expect("PLL state");
                (Channel::Following(Box::new(Following { fp, pll })), vq)
            }
            m => {
                return Err(err(
                    "mode",
                    format!("= {m}: 1 grid-forming, 2 grid-following"),
                ))
            }
        };

        let tau_dc = positive(s, self.tau_dc, "tau_dc")?;
        let c_dc = positive(s, self.c_dc, "C_dc")?;
        let (g_dc, k_dc) = (s[self.g_dc], s[self.k_dc]);
        let mut dc = LtiSimulator::new(dc_model(tau_dc, c_dc, g_dc, k_dc), Hold::Zero);

        // Operating point and the internal voltage behind the transformer (the slot impedance).
        let (s_base, s_rated) = (s[self.s_base], s[self.s_rated]);
        let zbase = s_base / s_rated;
        let (r, x) = (s[self.r_f] * zbase, s[self.x_f] * zbase);
        let (p, q, v) = (s[self.p], s[self.q], s[self.v]);
        if v <= 0.0 {
            return Err(err(
                "v",
                format!(
                    "= {v}: the operating point at initialization needs a terminal voltage > 0"
                ),
            ));
        }
        let (e0, theta0) = internal_voltage(p, q, v, s[self.v_angle], r, x);
        let p_ac = p * s_base / s_rated;
        dc.set_state(DVector::from_column_slice(&[p_ac, 0.0]), p_ac)
            .expect("dc state");

        let mut rt = Runtime {
            channel,
            vq,
            dc,
            p_kind,
            n_lpf: self.adpf_p.n_lpf.map_or(0, |n| s[n] as usize),
            q_kind: s[self.adpf_q.kind],
            p0: p,
            q0: q,
            v0: v,
            e0,
            theta0,
            df_held: 0.0,
            q_ref: q,
            warned_rating,
            warned_dc,
            warned_gains,
        };
        s[self.theta] = match &rt.channel {
            Channel::Forming(_) => theta0,
            Channel::Following(_) => s[self.v_angle],
        };
        s[self.e] = e0;
        s[self.df] = 0.0;
        s[self.p_ref] = p;
        s[self.p_set] = p;
        s[self.q_ref] = q;
        s[self.p_avail] = self.available(s, 0.0);
        s[self.v_dc] = 1.0;
        s[self.p_dc] = (p_ac + g_dc) * s_rated / s_base;
        let limit = self.headroom_limit(s, 0.0);
        if p > limit + 1e-12 && !rt.warned_dc {
            ctx.warn(format!(
                "dispatch p = {p:.4} pu is above deload * P_avail - G_dc = {limit:.4} pu: the set point is curtailed from the first step"
            ));
        }
        self.check_limits(s, &mut rt, ctx);
        Ok(rt)
    }

    /// The highest set point the primary source allows at `t`: `deload · P_avail - G_dc`, on S_base.
    fn headroom_limit(&self, s: &Store, t: f64) -> f64 {
        s[self.deload] * self.available(s, t) - s[self.g_dc] * s[self.s_rated] / s[self.s_base]
    }

    /// Apparent power against the rating and the dc source against its availability.
    fn check_limits(&self, s: &mut Store, rt: &mut Runtime, ctx: &mut Context) {
        let s_max = s[self.s_rated] / s[self.s_base];
        let apparent = s[self.p].hypot(s[self.q]);
        if apparent > s_max * (1.0 + 1e-9) && !rt.warned_rating {
            rt.warned_rating = true;
            ctx.warn(format!(
                "converter rating reached: |p + jq| = {apparent:.4} pu > S_rated/S_base = {s_max:.4} pu"
            ));
        }
        let (g_dc, to_rated) = (s[self.g_dc], s[self.s_base] / s[self.s_rated]);
        let cap = s[self.p_avail] * to_rated;
        let x = rt.dc.state();
        let p_dc = x[0] + g_dc;
        let floor = if s[self.storage] { -cap } else { 0.0 };
        let limited = p_dc.clamp(floor, cap);
        let mut w = x[1];
        if w < -1.0 {
            w = -1.0;
        }
        if limited != p_dc || w != x[1] {
            let u = p_dc;
            rt.dc
                .set_state(DVector::from_column_slice(&[limited - g_dc, w]), u)
                .expect("dc state");
            if !rt.warned_dc {
                rt.warned_dc = true;
                ctx.warn(format!(
                    "dc source limited: command {:.4} pu outside [{floor:.4}, P_avail = {cap:.4}] pu on S_rated",
                    p_dc
                ));
            }
        }
        let x = rt.dc.state();
        s[self.v_dc] = 1.0 + x[1];
        s[self.p_dc] = (x[0] + g_dc) / to_rated;
    }
}

impl Model for Der {
    type Config = DerConfig;
    const IDENTIFIER: &'static str = "dvpp_der";
    const NAME: &'static str = "DVPP DER matching controller";
    const DESCRIPTION: &'static str = "DVPP unit, grid-forming (df = -T_pf/m_p dp) or grid-following (dp = -m_p T_pf^-1 df), with ADPFs, dc side and rating limits";

    fn declare(
        config: &DerConfig,
        _: Option<&std::path::Path>,
        v: &mut Variables,
    ) -> Result<Self, String> {
        let u = UnitDefaults::of(config.preset);
        let io = [ports::P, ports::Q, ports::V, ports::V_ANGLE];
        let par = |v: &mut Variables, name: &str, start: f64, unit: &str, desc: &str, min: f64| {
            v.real(Spec::parameter(name, start, unit, desc).min(min))
        };
        let s_rated = par(
            v,
            ports::S_RATED,
            u.s_rated,
            "MVA",
            "converter rating",
            1e-3,
        );
        let s_base = par(v, "S_base", 100.0, "MVA", "system base power", 1e-3);
        let s_dvpp = par(
            v,
            ports::S_DVPP,
            96.0,
            "MVA",
            "DVPP base power T_des is specified on",
            1e-3,
        );
        let f_nom = par(v, "f_nom", 50.0, "Hz", "nominal frequency", 1e-3);
        let mode = v.integer(
            Spec::parameter(
                ports::MODE,
                u.mode,
                "",
                "1 = grid-forming, 2 = grid-following",
            )
            .range(1.0, 2.0),
        );
        let h = par(
            v,
            ports::TDES_H,
            5.55,
            "s",
            "virtual inertia of T_pf = 1/(H s + D)",
            0.0,
        );
        let d = par(
            v,
            ports::TDES_D,
            33.33,
            "pu",
            "damping (droop gain) of T_pf = 1/(H s + D)",
            0.0,
        );
        let dq = par(
            v,
            ports::TDES_DQ,
            0.01,
            "pu",
            "q-v droop of T_qv = Dq (dv = -Dq dq)",
            0.0,
        );
        let tau_q = par(
            v,
            "Tdes.tau_q",
            0.01,
            "s",
            "roll-off 1/(tau_q s + 1) of the inverse q-v reference",
            0.0,
        );
        let r_f = par(
            v,
            ports::R_F,
            0.01,
            "pu",
            "grid-forming: resistance between the imposed voltage (the regulated filter-capacitor voltage) and the terminal bus, the LV/MV transformer, on S_rated",
            0.0,
        );
        let x_f = par(
            v,
            ports::X_F,
            0.10,
            "pu",
            "grid-forming: reactance between the imposed voltage and the terminal bus, the LV/MV transformer, on S_rated",
            1e-6,
        );
        let adpf_p = AdpfParams::declare(v, "p", &u.adpf_p, true);
        let adpf_q = AdpfParams::declare(v, "q", &u.adpf_q, false);
        let pll_kp = par(
            v,
            "pll.kp",
            60.0,
            "1/s",
            "PLL proportional gain (grid-following)",
            0.0,
        );
        let pll_ki = par(
            v,
            "pll.ki",
            240.0,
            "1/s2",
            "PLL integral gain (grid-following)",
            0.0,
        );
        let pll_tau = par(
            v,
            "pll.tau",
            1.0 / 60.0,
            "s",
            "roll-off time constant tau_pll of the grid-following references",
            0.0,
        );
        let pll_order = v.integer(
            Spec::parameter(
                "pll.order",
                1,
                "",
                "order d of the grid-following roll-off 1/(tau_pll s + 1)^d",
            )
            .range(0.0, 4.0),
        );
        let qpi_kp = par(
            v,
            "qpi.kp",
            0.05,
            "pu",
            "grid-forming PI matching controller: proportional gain from q error to E",
            0.0,
        );
        let e_max = v.real(
            Spec::parameter(
                "E_max",
                1.5,
                "pu",
                "grid-forming: largest internal voltage magnitude the converter can impose (E in [0, E_max])",
            )
            .min(0.0),
        );
        let qpi_ki = par(
            v,
            "qpi.ki",
            5.0,
            "1/s",
            "grid-forming PI matching controller: integral gain from q error to E",
            0.0,
        );
        let tau_dc = par(
            v,
            "tau_dc",
            u.tau_dc,
            "s",
            "time constant of the dc source following its command",
            0.0,
        );
        let c_dc = par(
            v,
            "C_dc",
            0.096,
            "pu",
            "dc-link capacitance on S_rated",
            0.0,
        );
        let g_dc = par(
            v,
            "G_dc",
            0.05,
            "pu",
            "dc-link conductance (losses) on S_rated",
            0.0,
        );
        let k_dc = par(v, "k_dc", 100.0, "pu", "dc-voltage control gain", 0.0);
        let storage = v.boolean(Spec::parameter(
            "storage",
            u.storage,
            "",
            "the primary source can absorb power (a battery): dc source within [-P_avail, P_avail] instead of [0, P_avail]",
        ));
        let deload = v.real(
            Spec::parameter(
                "deload",
                1.0,
                "1",
                "deloading: the set point stays at or below deload * P_avail - G_dc (reserve for participation)",
            )
            .range(1e-3, 1.0),
        );
        let p_avail0 = par(
            v,
            ports::P_AVAIL0,
            u.p_avail0,
            "pu",
            "available active power of the primary source, on S_base",
            0.0,
        );
        let avail_t = v.real(Spec::parameter(
            "avail.t_step",
            1.0,
            "s",
            "time of the availability step (a cloud, a wind drop)",
        ));
        let avail_dp = v.real(Spec::parameter(
            "avail.dP",
            0.0,
            "pu",
            "availability step on S_base (negative = less available power)",
        ));
        let p = v.real(Spec::input(
            ports::P,
            u.p,
            "pu",
            "measured active power injected at the terminal, on S_base",
        ));
        let q = v.real(Spec::input(
            ports::Q,
            0.0,
            "pu",
            "measured reactive power injected at the terminal, on S_base",
        ));
        let vv = v.real(
            Spec::input(
                ports::V,
                1.0,
                "pu",
                "voltage magnitude at the regulated point",
            )
            .min(0.0),
        );
        let v_angle = v.real(Spec::input(
            ports::V_ANGLE,
            0.0,
            "rad",
            "voltage angle at the regulated point, rotating frame at f_nom",
        ));
        let mu_p = v.real(
            Spec::input(
                ports::MU_P,
                u.mu_p,
                "1",
                "ADPF dc gain of the p-f channel from the operator (static, low-pass)",
            )
            .range(0.0, 1.0),
        );
        let mu_q = v.real(
            Spec::input(
                ports::MU_Q,
                u.mu_q,
                "1",
                "ADPF dc gain of the v-q channel from the operator (static, low-pass)",
            )
            .range(0.0, 1.0),
        );
        let mu_p_lpf = (1..=MAX_LPF)
            .map(|k| {
                v.real(
                    Spec::input(
                        &ports::mu_p_lpf(k),
                        u.mu_p_lpf.get(k - 1).copied().unwrap_or(0.0),
                        "1",
                        &format!("complement unit: dc gain of low-pass unit {k} it closes"),
                    )
                    .range(0.0, 1.0),
                )
            })
            .collect();
        let out = |v: &mut Variables, name: &str, unit: &str, desc: &str| {
            v.real(Spec::output(name, unit, desc).initial_dependencies(&io))
        };
        Ok(Der {
            mode,
            s_rated,
            s_base,
            s_dvpp,
            f_nom,
            h,
            d,
            dq,
            tau_q,
            r_f,
            x_f,
            adpf_p,
            adpf_q,
            pll_kp,
            pll_ki,
            pll_tau,
            pll_order,
            qpi_kp,
            qpi_ki,
            e_max,
            tau_dc,
            c_dc,
            g_dc,
            storage,
            deload,
            k_dc,
            p_avail0,
            avail_t,
            avail_dp,
            p,
            q,
            v: vv,
            v_angle,
            mu_p,
            mu_q,
            mu_p_lpf,
            theta: out(
                v,
                ports::THETA,
                "rad",
                "grid-forming: internal voltage angle the converter imposes; grid-following: PLL angle",
            ),
            e: out(
                v,
                ports::E,
                "pu",
                "grid-forming: internal voltage magnitude the converter imposes (held in grid-following)",
            ),
            df: v.real(Spec::output(
                "df",
                "pu",
                "the unit's frequency deviation, pu of f_nom (grid-forming: imposed; grid-following: PLL)",
            )),
            p_ref: out(
                v,
                ports::P_REF,
                "pu",
                "grid-following: active power reference on S_base; grid-forming: the active set point (dispatch curtailed to P_avail)",
            ),
            p_set: out(
                v,
                ports::P_SET,
                "pu",
                "the unit's active set point on S_base: the dispatch, curtailed to what the primary source allows (deload * P_avail - G_dc); the operator measures the DVPP's response against the sum of these",
            ),
            q_ref: out(
                v,
                ports::Q_REF,
                "pu",
                "reactive power reference q_0 - T_i^vq dv on S_base (grid-forming: tracked by E)",
            ),
            p_avail: v.real(Spec::output(
                ports::P_AVAIL,
                "pu",
                "available active power of the primary source, on S_base",
            )),
            v_dc: v.real(Spec::output("v_dc", "pu", "dc-link voltage")),
            p_dc: out(v, "p_dc", "pu", "power of the dc source, on S_base"),
            rt: None,
        })
    }

    fn initialize(&mut self, s: &mut Store, ctx: &mut Context) -> Result<(), ModelError> {
        // Initialization may run several times in initialization mode; a warning already given
        // in this episode is not repeated (a reset starts a new episode with `rt` = None).
        let warned = self
            .rt
            .take()
            .map(|rt| (rt.warned_rating, rt.warned_dc, rt.warned_gains));
        let (wr, wd, wg) = warned.unwrap_or_default();
        self.rt = Some(self.build(s, ctx, wr, wd, wg)?);
        Ok(())
    }

    fn do_step(
        &mut self,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        let mut rt = self.rt.take().ok_or("the DER is not initialized")?;
        let result = self.step(&mut rt, s, t, h, ctx);
        self.rt = Some(rt);
        result
    }
}

impl Der {
    fn step(
        &self,
        rt: &mut Runtime,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        let to_dvpp = s[self.s_base] / s[self.s_dvpp];
        let dv = s[self.v] - rt.v0;
        let lpf = self.lpf_gains(s);
        // Dc gains from the operator (the participation bank identity holds while they move).
        if rt.q_kind <= kind::LOW_PASS {
            rt.vq.set_mu(s[self.mu_q]).map_err(|e| err("mu_q", e))?;
        }
        let lpf = if rt.p_kind == kind::COMPLEMENT {
            let share = s[self.adpf_p.share.expect("complement parameters")];
            let n = rt.n_lpf;
            let sum: f64 = lpf[..n].iter().sum();
            let mut g = lpf;
            if sum > share + 1e-9 {
                if !rt.warned_gains {
                    rt.warned_gains = true;
                    ctx.warn(format!(
                        "mu_p_lpf sums to {sum} > share {share}: scaled down to keep the participation condition"
                    ));
                }
                for x in &mut g[..n] {
                    *x *= share / sum;
                }
            }
            g
        } else {
            lpf
        };
        let s_max = s[self.s_rated] / s[self.s_base];
        // The set point: the dispatch, curtailed to what the primary source allows (a cloud lowers it).
        let p_set = rt.p0.min(self.headroom_limit(s, t));
        s[self.p_set] = p_set;
        match &mut rt.channel {
            Channel::Forming(f) => {
                match rt.p_kind {
                    kind::STATIC | kind::LOW_PASS => {
                        f.pf.set_mu(s[self.mu_p]).map_err(|e| err("mu_p", e))?;
                    }
                    kind::COMPLEMENT => {
                        f.pf.set_lpf_gains(&lpf[..rt.n_lpf])
                            .map_err(|e| err("mu_p_lpf", e))?;
                    }
                    _ => {}
                }
                let dp = (s[self.p] - p_set) * to_dvpp;
                s[self.p_ref] = p_set;
                let (df, df_int) = f.pf.step_with_integral(dp, h);
                s[self.df] = df;
                s[self.theta] += 2.0 * PI * s[self.f_nom] * df_int;
                // PI matching controller on E: q tracks the reference held over the step.
                // E within [0, E_max]; the integrator stops while the limit holds (anti-windup).
                let e = rt.q_ref - s[self.q];
                let e_max = s[self.e_max];
                let integral = f.e_int + s[self.qpi_ki] * e * h;
                let unclamped = rt.e0 + s[self.qpi_kp] * e + integral;
                s[self.e] = unclamped.clamp(0.0, e_max);
                if unclamped == s[self.e] {
                    f.e_int = integral;
                }
                rt.q_ref = rt.q0 + rt.vq.step(dv, h) / to_dvpp;
                s[self.q_ref] = rt.q_ref;
            }
            Channel::Following(g) => {
                match rt.p_kind {
                    kind::STATIC | kind::LOW_PASS => {
                        g.fp.set_mu(s[self.mu_p]).map_err(|e| err("mu_p", e))?;
                    }
                    kind::COMPLEMENT => {
                        g.fp.set_lpf_gains(&lpf[..rt.n_lpf])
                            .map_err(|e| err("mu_p_lpf", e))?;
                    }
                    _ => {}
                }
                let dp = g.fp.step(rt.df_held, h) / to_dvpp;
                let dq = rt.vq.step(dv, h) / to_dvpp;
                let mut p_ref = p_set + dp;
                let mut q_ref = rt.q0 + dq;
                if p_ref.hypot(q_ref) > s_max {
                    p_ref = p_ref.clamp(-s_max, s_max);
                    let q_max = (s_max * s_max - p_ref * p_ref).max(0.0).sqrt();
                    q_ref = q_ref.clamp(-q_max, q_max);
                    if !rt.warned_rating {
                        rt.warned_rating = true;
                        ctx.warn(format!(
                            "converter rating reached at t = {t}: references limited to |p + jq| <= {s_max:.4} pu"
                        ));
                    }
                }
                s[self.p_ref] = p_ref;
                s[self.q_ref] = q_ref;
                let y = g.pll.step_all(s[self.v_angle], h);
                rt.df_held = y[0];
                s[self.df] = y[0];
                s[self.theta] = y[1];
            }
        }
        // Primary source and dc side.
        s[self.p_avail] = self.available(s, t + h);
        let p_ac = s[self.p] * s[self.s_base] / s[self.s_rated];
        rt.dc.step(p_ac, h);
        self.check_limits(s, rt, ctx);
        Ok(())
    }
}

fmi_export::export_fmu!(Der);

#[cfg(test)]
mod golden {
    #[test]
    fn model_description_matches_the_golden_copy() {
        fmi_export::assert_golden::<super::Der>(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/modelDescription.xml"
        ));
    }
}
