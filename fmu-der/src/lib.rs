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
//! * Rotational power control (`rot.rx` = R/X of the lossy lines around the unit, > 0): both
//!   channels work on the rotated powers `p' = (p - r q)/√(1+r²)`, `q' = (r p + q)/√(1+r²)`
//!   ([`dvpp_control::Rotation`]) instead of `p`, `q`. Grid-forming: `Δf = -T_i^pf Δp'` and the
//!   PI on `E` makes `q'` track `q'₀ - T_i^vq Δv`; grid-following: the references are
//!   `p'₀ - T_i^fp Δf` and `q'₀ - T_i^vq Δv`, rotated back to `p_ref`, `q_ref`. The set point
//!   `(p₀, q₀)` is rotated the same way; limits act on `p`, `q`. `rot.rx` = 0 is the classical
//!   control, bit for bit. Outputs `p_rot`, `q_rot` are the measured `p'`, `q'`.
//!
//! The set point `p₀` is the dispatch at initialization, curtailed to what the primary source
//! allows with its reserve: `p₀(t) = min(p_dispatch, deload · P_avail(t) - G_dc)` (a cloud that
//! cuts a PV plant's availability lowers its set point; the DVPP answers that deficit like a
//! load step).
//!
//! The primary source and dc side: an availability profile `P_avail(t)`, a dc source that follows
//! its command with the lag `τ_dc` within `[0, P_avail]`, and a dc link (`C_dc`, `G_dc`) whose
//! voltage `v_dc` a proportional controller (`k_dc`) holds. The control math is `dvpp_control`.

mod dc;
mod limits;
pub mod ports;
mod preset;

pub use limits::priority;
pub use preset::{Preset, UnitDefaults};

use dc::{DcParams, DcSide};
use dvpp_control::phasor::internal_voltage;
use dvpp_control::{
    Adpf, Complex, GflFpModel, GfmPfModel, Hold, LowPassSpec, LtiSimulator, Rotation, StateSpace,
    TDes, VqModel,
};
use fmi_export::{Boolean, Context, Integer, Model, ModelError, Real, Spec, Store, Variables};
use limits::Episode;
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
    /// The internal voltage node `E∠θ` the controls set; the converter imposes it unless a
    /// limit acts.
    e: f64,
    theta: f64,
    /// The angle's increment over the last step and its mean over `ANGLE_MEAN_TAU` (the part
    /// the grid frequency explains): their difference is the angle move the next measured
    /// power does not yet show (the current-limited mode's delay compensation).
    dtheta: f64,
    dtheta_mean: f64,
}

/// The grid-following controller state.
#[derive(Clone, Serialize, Deserialize)]
struct Following {
    fp: GflFpModel,
    /// PLL: states `[∫e, θ_pll]`, input `v_angle`, outputs `[Δf_pll, θ_pll]`.
    pll: LtiSimulator,
    /// The converter's active and reactive currents (pu of the rated current), following
    /// their commands with the lag `current.tau`.
    current: (f64, f64),
    /// The voltage deviation the v-q droop sees, through the lag `vq.tau`.
    dv: f64,
    /// The PLL gains its model was built with (tunable: rebuilt when they change).
    gains: (f64, f64),
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
    dc: DcSide,
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
    /// Grid-forming: the reactive reference held over the next step, rotated (`q'`; `q` when
    /// `rot.rx` = 0).
    q_ref: f64,
    /// `(p, q) ↔ (p', q')` for the lines' R/X (`rot.rx`; the identity at 0).
    rot: Rotation,
    /// Power the limits withheld at the last step (what the internal voltage would have
    /// delivered minus what the converter imposed), on S_base: the controls see the unlimited
    /// power, so the internal node stays synchronized while limited.
    withheld: (f64, f64),
    /// Waiting for the terminal voltage (a start from zero voltage); `None` once synchronized.
    startup: Option<Startup>,
    /// Time of synchronization after a start from zero voltage (the set point ramps from there).
    t_sync: Option<f64>,
    limit: LimitEpisodes,
    /// Warning already given in this episode.
    warned_gains: bool,
}

/// A unit waiting for the voltage to appear.
#[derive(Clone, Serialize, Deserialize)]
struct Startup {
    /// Since when the voltage has been above `startup.v_sync` and steady.
    ok_since: Option<f64>,
    v_last: f64,
}

/// Below this terminal voltage (pu) a grid-following unit's PLL has no angle to lock to: the
/// unit loses synchronism and blocks (a grid-forming unit keeps forming its voltage).
const PLL_V_MIN: f64 = 0.05;

/// Grid-forming, current-limited mode: the fraction of the limited power's change that the
/// angle's last move makes (at the measured bus voltage) which the controls add to the measured
/// power. The loop through the feedthrough of T_pf/m, with gain `g_net` per step through the
/// network and `c` = this fraction of its gain at a fixed bus voltage, has the characteristic
/// `z² - (1 - c) z + (g_net - c)` (without the compensation `z² - z + g_net`, roots of modulus
/// `√g_net`: 0.97 for case study I's wind). For that wind (`c` = 0.58) both roots stay within
/// 0.8 for `g_net` from 0.3 to 1.2.
const DELAY_COMPENSATION: f64 = 0.5;

/// Time constant of the mean angle increment (s).
const ANGLE_MEAN_TAU: f64 = 0.02;

/// The episodes of each limit (the `limit.*` outputs).
#[derive(Clone, Default, Serialize, Deserialize)]
struct LimitEpisodes {
    current: Episode,
    dc: Episode,
    source: Episode,
    modulation: Episode,
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
    dc_zeta: Real,
    v_dc_min: Real,
    v_dc_max: Real,
    t_budget: Real,
    i_max: Real,
    priority: Integer,
    current_tau: Real,
    vq_tau: Real,
    v_sync: Real,
    t_hold: Real,
    ramp: Real,
    p_avail0: Real,
    avail_t: Real,
    avail_dp: Real,
    redispatch: Real,
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
    i_ac: Real,
    i_limit: Real,
    p_min: Real,
    p_max: Real,
    e_src: Real,
    e_ac: Real,
    e_loss: Real,
    w_dc: Real,
    limit_current: Boolean,
    limit_dc: Boolean,
    limit_source: Boolean,
    limit_modulation: Boolean,
    synchronized: Boolean,
    rot_rx: Real,
    p_rot: Real,
    q_rot: Real,
    /// Boxed: each step takes it out and puts it back, which moves only the pointer.
    rt: Option<Box<Runtime>>,
}

/// Structure of the DER: which of the paper's units it is.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DerConfig {
    /// `"wind"`, `"pv"` or `"bess"`: the case-study unit whose ratings, `τ_dc`, ADPF shapes and
    /// dc gains become the start values; none: a generic unit with a static ADPF.
    #[serde(default)]
    pub preset: Option<Preset>,
    /// The unit's rating in MVA when it differs from the preset's (a resized or split unit):
    /// the preset's available power and dispatch scale with it.
    #[serde(default)]
    pub rating: Option<f64>,
}

/// An error naming the parameter (or input) at fault: `'name' = value: why` or `'name': why`.
fn err(name: &str, message: impl std::fmt::Display) -> ModelError {
    let message = message.to_string();
    let sep = if message.starts_with('=') { " " } else { ": " };
    ModelError(format!("'{name}'{sep}{message}"))
}

fn positive(s: &Store, r: Real, name: &str) -> Result<f64, ModelError> {
    let x = s[r];
    if x > 0.0 && x.is_finite() && x.is_normal() {
        Ok(x)
    } else if x > 0.0 && x.is_finite() {
        Err(err(
            name,
            format!(
                "= {x:e}: must be > 0 and not subnormal (at least {:e})",
                f64::MIN_POSITIVE
            ),
        ))
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
        again: Option<bool>,
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
        if h != 0.0 && !h.is_normal() {
            return Err(err(
                "Tdes.H",
                format!(
                    "= {h:e}: must be 0 or at least {:e} (a subnormal inertia overflows T_pf = 1/(H s + D))",
                    f64::MIN_POSITIVE
                ),
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
                // A grid-forming unit cannot have (near) zero p-f participation: its floor
                // bounds its p-f stiffness on its own rating (the operator's floor alike).
                let mu_min = dvpp_control::mu_min_gfm(s[self.s_rated], s[self.s_dvpp]);
                let adpf = match &adpf_p {
                    Adpf::LowPass(spec) if spec.mu < mu_min => {
                        adpf_p.with_mu(mu_min).expect("valid gain")
                    }
                    a => a.clone(),
                };
                let pf = GfmPfModel::with_floor(&tdes, &adpf, mu_min).map_err(|e| {
                    err(
                        &order_name,
                        format!("the grid-forming reference T_pf/m is not realizable: {e}"),
                    )
                })?;
                pf.check_stability()
                    .map_err(|e| err(&self.adpf_p.name("kind"), e))?;
                let vq = VqModel::grid_forming_shaped(&tdes, &adpf_q)
                    .map_err(|e| err(&self.adpf_q.name("kind"), e))?;
                let forming = Forming {
                    pf,
                    e_int: 0.0,
                    e: 0.0,
                    theta: 0.0,
                    dtheta: 0.0,
                    dtheta_mean: 0.0,
                };
                (Channel::Forming(Box::new(forming)), vq)
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
                // The v-q reference keeps a first-order roll-off: more lag in that loop (gain
                // X_th/Dq) would destabilize it; its dominant lag is `vq.tau`.
                let vq = VqModel::grid_following_shaped(&tdes, &adpf_q, pll_tau, 1)
                    .map_err(|e| err(&self.adpf_q.name("kind"), e))?;
                let (kp, ki) = (s[self.pll_kp], s[self.pll_ki]);
                if !(kp > 0.0 && ki > 0.0) {
                    return Err(err(
                        "pll.kp",
                        format!("PLL gains kp = {kp}, ki = {ki} must be > 0"),
                    ));
                }
                let mut pll = LtiSimulator::new(pll_model(kp, ki, s[self.f_nom]), Hold::Zero);
                pll.set_state(&[0.0, s[self.v_angle]], s[self.v_angle])
                    .expect("PLL state");
                let following = Following {
                    fp,
                    pll,
                    current: (0.0, 0.0),
                    dv: 0.0,
                    gains: (kp, ki),
                };
                (Channel::Following(Box::new(following)), vq)
            }
            m => {
                return Err(err(
                    "mode",
                    format!("= {m}: 1 grid-forming, 2 grid-following"),
                ))
            }
        };

        let dc = self.dc_params(s)?;
        if again.is_none() {
            ctx.event(format!(
                "dc-voltage control: damping ratio {:.3} without the capacitor-power term, {:.3} with k_d = {:.3}",
                dc.damping(0.0),
                dc.damping(dc.k_d()),
                dc.k_d()
            ));
        }
        positive(s, self.i_max, "I_max")?;
        positive(s, self.e_max, "E_max")?;

        // Operating point and the internal voltage behind the transformer (the slot impedance).
        let (r, x) = self.slot_impedance(s);
        let (p, q, v) = (s[self.p], s[self.q], s[self.v]);
        // Below `startup.v_sync` the unit waits for the voltage (a start from zero voltage).
        let waiting = v < s[self.v_sync];
        let (e0, theta0) = if waiting {
            (v, s[self.v_angle])
        } else {
            internal_voltage(p, q, v, s[self.v_angle], r, x)
        };
        let p_ac = if waiting {
            0.0
        } else {
            self.converter_power(s, r)
        };
        let rot = Rotation::from_rx(s[self.rot_rx]).map_err(|e| err("rot.rx", e))?;
        let mut rt = Runtime {
            channel,
            vq,
            dc: DcSide::new(dc, p_ac),
            p_kind,
            n_lpf: self.adpf_p.n_lpf.map_or(0, |n| s[n] as usize),
            q_kind: s[self.adpf_q.kind],
            p0: p,
            q0: if waiting { 0.0 } else { q },
            v0: v,
            e0,
            theta0,
            df_held: 0.0,
            q_ref: if waiting { 0.0 } else { rot.rotate(p, q).1 },
            rot,
            withheld: (0.0, 0.0),
            startup: waiting.then_some(Startup {
                ok_since: None,
                v_last: v,
            }),
            t_sync: None,
            limit: LimitEpisodes::default(),
            warned_gains: again.unwrap_or(false),
        };
        match &mut rt.channel {
            Channel::Forming(f) => {
                f.e = e0;
                f.theta = theta0;
            }
            Channel::Following(g) if !waiting => {
                let to_rated = s[self.s_base] / s[self.s_rated];
                g.current = (p * to_rated / v, q * to_rated / v);
            }
            Channel::Following(_) => {}
        }
        s[self.theta] = match &rt.channel {
            Channel::Forming(_) => theta0,
            Channel::Following(_) => s[self.v_angle],
        };
        s[self.e] = e0;
        s[self.df] = 0.0;
        s[self.p_ref] = if waiting { 0.0 } else { p };
        s[self.p_set] = s[self.p_ref];
        s[self.q_ref] = if waiting { 0.0 } else { q };
        s[self.p_avail] = self.available(s, 0.0);
        s[self.synchronized] = !waiting;
        if waiting && again.is_none() {
            ctx.event(format!(
                "v = {v:.4} pu < startup.v_sync = {:.4} pu: waiting for the terminal voltage",
                s[self.v_sync]
            ));
        }
        let limit = self.headroom_limit(s, 0.0);
        if p > limit + 1e-12 && again.is_none() {
            ctx.warn(format!(
                "dispatch p = {p:.4} pu is above deload * P_avail - G_dc = {limit:.4} pu: the set point is curtailed from the first step"
            ));
        }
        self.write_dc(s, &rt);
        self.write_limits(s, &rt);
        self.write_rotated(s, &rt);
        Ok(rt)
    }

    /// The dc side's parameters, checked.
    fn dc_params(&self, s: &Store) -> Result<DcParams, ModelError> {
        let tau = positive(s, self.tau_dc, "tau_dc")?;
        let c = positive(s, self.c_dc, "C_dc")?;
        let t_budget = positive(s, self.t_budget, "dc.t_budget")?;
        let (v_min, v_max) = (s[self.v_dc_min], s[self.v_dc_max]);
        if !((0.0..1.0).contains(&v_min) && v_max > 1.0) {
            return Err(err(
                "v_dc_min",
                format!("= {v_min} with v_dc_max = {v_max}: needs 0 <= v_dc_min < 1 < v_dc_max"),
            ));
        }
        Ok(DcParams {
            tau,
            c,
            g: s[self.g_dc],
            k_dc: s[self.k_dc],
            zeta: s[self.dc_zeta],
            storage: s[self.storage],
            v_min,
            v_max,
            t_budget,
        })
    }

    /// The slot impedance `R_f + j X_f` on S_base.
    fn slot_impedance(&self, s: &Store) -> (f64, f64) {
        let zbase = s[self.s_base] / s[self.s_rated];
        (s[self.r_f] * zbase, s[self.x_f] * zbase)
    }

    /// The power the converter's ac side draws from its dc link, pu on S_rated: the measured
    /// terminal power and, for a grid-forming unit, the loss in `R_f` between them.
    fn converter_power(&self, s: &Store, r: f64) -> f64 {
        let (p, q, v) = (s[self.p], s[self.q], s[self.v]);
        let r_loss = if s[self.mode] == GRID_FORMING && v > 0.0 {
            r * (p * p + q * q) / (v * v)
        } else {
            0.0
        };
        (p + r_loss) * s[self.s_base] / s[self.s_rated]
    }

    /// The dc side's outputs.
    fn write_dc(&self, s: &mut Store, rt: &Runtime) {
        let (s_base, s_rated) = (s[self.s_base], s[self.s_rated]);
        s[self.v_dc] = rt.dc.v_dc();
        s[self.p_dc] = rt.dc.p_src() * s_rated / s_base;
        // Energies in MJ: pu·s on S_rated times S_rated in MVA.
        s[self.e_src] = rt.dc.e_src * s_rated;
        s[self.e_ac] = rt.dc.e_ac * s_rated;
        s[self.e_loss] = rt.dc.e_loss * s_rated;
        s[self.w_dc] = rt.dc.energy() * s_rated;
        let (p, q, v) = (s[self.p], s[self.q], s[self.v]);
        // At a dead bus no power flows: inputs that say otherwise are start values, not a current.
        s[self.i_ac] = if v < limits::V_FLOOR {
            0.0
        } else {
            p.hypot(q) / v * s_base / s_rated
        };
        // The dc budget at the terminal: less the R_f loss at the present current.
        let (r, _) = self.slot_impedance(s);
        let r_loss = if s[self.mode] == GRID_FORMING {
            r * (p * p + q * q) / v.max(limits::V_FLOOR).powi(2)
        } else {
            0.0
        };
        let (lo, hi) = rt.dc.ac_budget();
        s[self.p_min] = lo * s_rated / s_base - r_loss;
        s[self.p_max] = hi * s_rated / s_base - r_loss;
        s[self.i_limit] = s[self.i_max];
    }

    /// The measured rotated powers `p'`, `q'` (outputs `p_rot`, `q_rot`).
    fn write_rotated(&self, s: &mut Store, rt: &Runtime) {
        let (p_rot, q_rot) = rt.rot.rotate(s[self.p], s[self.q]);
        s[self.p_rot] = p_rot;
        s[self.q_rot] = q_rot;
    }

    /// The limit flags.
    fn write_limits(&self, s: &mut Store, rt: &Runtime) {
        s[self.limit_current] = rt.limit.current.active();
        s[self.limit_dc] = rt.limit.dc.active();
        s[self.limit_source] = rt.limit.source.active();
        s[self.limit_modulation] = rt.limit.modulation.active();
    }

    /// The highest set point the primary source allows at `t`: `deload · P_avail - G_dc`, on S_base.
    fn headroom_limit(&self, s: &Store, t: f64) -> f64 {
        s[self.deload] * self.available(s, t) - s[self.g_dc] * s[self.s_rated] / s[self.s_base]
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
        let u = UnitDefaults::of(config.preset).resized(config.rating)?;
        let io = [ports::P, ports::Q, ports::V, ports::V_ANGLE];
        let par = |v: &mut Variables, name: &str, start: f64, unit: &str, desc: &str, min: f64| {
            v.real(Spec::parameter(name, start, unit, desc).min(min))
        };
        // Gains, limits and set points a host may retune between steps; structure stays fixed.
        let tun = |v: &mut Variables, name: &str, start: f64, unit: &str, desc: &str, min: f64| {
            v.real(Spec::parameter(name, start, unit, desc).min(min).tunable())
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
        let pll_kp = tun(
            v,
            "pll.kp",
            60.0,
            "1/s",
            "PLL proportional gain (grid-following)",
            1e-6,
        );
        let pll_ki = tun(
            v,
            "pll.ki",
            240.0,
            "1/s2",
            "PLL integral gain (grid-following)",
            1e-6,
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
                2,
                "",
                "order d of the grid-following p-f roll-off 1/(tau_pll s + 1)^d (the v-q reference has order 1); 2 makes m T_pf^-1 strictly proper for every ADPF, so the PLL's proportional path does not reach the current at the gain H/tau_pll of a first-order roll-off",
            )
            .range(0.0, 4.0),
        );
        let qpi_kp = tun(
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
                "grid-forming: modulation limit, the largest voltage magnitude the converter can impose at the nominal dc voltage (E <= E_max * v_dc)",
            )
            .min(0.0)
            .tunable(),
        );
        let qpi_ki = tun(
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
        let k_dc = par(
            v,
            "k_dc",
            100.0,
            "pu",
            "dc-voltage control gain (source power per pu of v_dc deviation)",
            0.0,
        );
        let dc_zeta = v.real(
            Spec::parameter(
                "dc.zeta",
                0.7,
                "1",
                "damping ratio the dc-voltage control's capacitor-power term gives the k_dc, C_dc, tau_dc loop (0: no damping term)",
            )
            .range(0.0, 2.0),
        );
        let v_dc_min = v.real(
            Spec::parameter(
                "v_dc_min",
                0.8,
                "pu",
                "lowest dc-link voltage the ac side may draw the link down to (below it the ac power is held to what the source gives)",
            )
            .range(0.0, 1.0),
        );
        let v_dc_max = v.real(
            Spec::parameter(
                "v_dc_max",
                1.2,
                "pu",
                "highest dc-link voltage the ac side may charge the link to",
            )
            .min(1.0),
        );
        let t_budget = par(
            v,
            "dc.t_budget",
            0.02,
            "s",
            "the ac side may draw the link's usable energy (above v_dc_min) at most at the rate usable energy / t_budget beyond the source's power",
            0.0,
        );
        let i_max = tun(
            v,
            "I_max",
            1.2,
            "pu",
            "current limit, pu of the rated current (S_rated at 1 pu voltage)",
            1e-3,
        );
        let priority = v.integer(
            Spec::parameter(
                "limit.priority",
                limits::priority::ACTIVE,
                "",
                "grid-following at I_max: 0 active current kept first, 1 reactive current kept first",
            )
            .range(0.0, 1.0)
            .tunable(),
        );
        let current_tau = tun(
            v,
            "current.tau",
            0.02,
            "s",
            "grid-following: time constant of the converter's current response to its references (inner current control and plant, as the WECC REGC_A model's Tg); 0 = immediate",
            0.0,
        );
        let vq_tau = tun(
            v,
            "vq.tau",
            0.5,
            "s",
            "grid-following: time constant of the plant's voltage control ahead of the v-q droop (a current-injecting unit's droop 1/Dq through the grid's impedance needs a dominant lag); 0 = none",
            0.0,
        );
        let v_sync = v.real(
            Spec::parameter(
                "startup.v_sync",
                0.5,
                "pu",
                "a unit initialized below this terminal voltage waits (zero current) until the voltage is above it and steady, then synchronizes",
            )
            .range(0.0, 1.0),
        );
        let t_hold = par(
            v,
            "startup.t_hold",
            0.05,
            "s",
            "how long the voltage must be above startup.v_sync and steady (|dv/dt| < 0.5 pu/s) before the unit synchronizes",
            0.0,
        );
        let ramp = par(
            v,
            "startup.ramp",
            1.0,
            "s",
            "after a start from zero voltage, the set point ramps from 0 to the dispatch over this time",
            0.0,
        );
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
            .range(1e-3, 1.0)
            .tunable(),
        );
        let p_avail0 = tun(
            v,
            ports::P_AVAIL0,
            u.p_avail0,
            "pu",
            "available active power of the primary source, on S_base",
            0.0,
        );
        let avail_t = v.real(
            Spec::parameter(
                "avail.t_step",
                1.0,
                "s",
                "time of the availability step (a cloud, a wind drop)",
            )
            .tunable(),
        );
        let avail_dp = v.real(
            Spec::parameter(
                "avail.dP",
                0.0,
                "pu",
                "availability step on S_base (negative = less available power)",
            )
            .tunable(),
        );
        let redispatch = v.real(
            Spec::parameter(
                "dispatch.dP",
                0.0,
                "pu",
                "change of the dispatch on S_base (the dispatch is the power-flow point at initialization; a host redispatches the unit with this)",
            )
            .tunable(),
        );
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
            dc_zeta,
            v_dc_min,
            v_dc_max,
            t_budget,
            i_max,
            priority,
            current_tau,
            vq_tau,
            v_sync,
            t_hold,
            ramp,
            p_avail0,
            avail_t,
            avail_dp,
            redispatch,
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
            v_dc: v.real(Spec::output(ports::V_DC, "pu", "dc-link voltage")),
            p_dc: out(v, "p_dc", "pu", "power of the dc source, on S_base"),
            i_ac: out(
                v,
                ports::I_AC,
                "pu",
                "magnitude of the ac current at the terminal, pu of the rated current",
            ),
            i_limit: v.real(Spec::output(
                ports::I_LIMIT,
                "pu",
                "the current limit I_max, for the grid's slot (the output stage holds it in every network solution)",
            )),
            p_min: v.real(Spec::output(
                ports::P_MIN,
                "pu",
                "grid-forming: lowest active power at the terminal the dc link can take now, on S_base (for the grid's slot)",
            )),
            p_max: v.real(Spec::output(
                ports::P_MAX,
                "pu",
                "grid-forming: highest active power at the terminal the dc link can give now, on S_base (for the grid's slot)",
            )),
            e_src: v.real(Spec::output(
                ports::ENERGY_SOURCE,
                "MJ",
                "energy the primary source delivered since initialization",
            )),
            e_ac: v.real(Spec::output(
                ports::ENERGY_AC,
                "MJ",
                "energy the ac side drew from the dc link since initialization (terminal power and, grid-forming, the R_f loss)",
            )),
            e_loss: v.real(Spec::output(
                ports::ENERGY_LOSS,
                "MJ",
                "energy lost in the dc link (G_dc) since initialization",
            )),
            w_dc: v.real(Spec::output(
                ports::ENERGY_STORED,
                "MJ",
                "energy stored in the dc link, C_dc v_dc^2 / 2 (source - ac - loss = change of this)",
            )),
            limit_current: v.boolean(Spec::boolean_output(
                "limit.current",
                "the current limit I_max acts (on until 1 s after it last acted; the same for the other limit flags)",
            )),
            limit_dc: v.boolean(Spec::boolean_output(
                "limit.dc",
                "the dc link's power budget limits the active current (link near v_dc_min or v_dc_max)",
            )),
            limit_source: v.boolean(Spec::boolean_output(
                "limit.source",
                "the primary source sits at its availability (or its floor)",
            )),
            limit_modulation: v.boolean(Spec::boolean_output(
                "limit.modulation",
                "grid-forming: the imposed voltage is cut to E_max * v_dc",
            )),
            synchronized: v.boolean(Spec::boolean_output(
                ports::SYNCHRONIZED,
                "the unit is synchronized (false while it waits for the terminal voltage after a start from zero voltage, and for a grid-following unit that lost its terminal voltage)",
            )),
            // Declared last, so the variables above keep their value references.
            rot_rx: v.real(
                Spec::parameter(
                    ports::ROT_RX,
                    0.0,
                    "1",
                    "rotational power control: R/X of the lines around the unit; the p-f channel shapes p' = (p - rx q)/sqrt(1 + rx^2) and the v-q channel controls q' = (rx p + q)/sqrt(1 + rx^2) instead of p and q (0 = classical p-f and q-v control)",
                )
                .min(0.0),
            ),
            p_rot: v.real(
                Spec::output(
                    ports::P_ROT,
                    "pu",
                    "measured rotated active power p' = (p - rx q)/sqrt(1 + rx^2) on S_base (rx = rot.rx; p when 0)",
                )
                .initial_dependencies(&[ports::P, ports::Q]),
            ),
            q_rot: v.real(
                Spec::output(
                    ports::Q_ROT,
                    "pu",
                    "measured rotated reactive power q' = (rx p + q)/sqrt(1 + rx^2) on S_base (rx = rot.rx; q when 0)",
                )
                .initial_dependencies(&[ports::P, ports::Q]),
            ),
            rt: None,
        })
    }

    fn initialize(&mut self, s: &mut Store, ctx: &mut Context) -> Result<(), ModelError> {
        // Initialization may run several times in initialization mode; a warning already given
        // in this episode is not repeated (a reset starts a new episode with `rt` = None).
        let again = self.rt.take().map(|rt| rt.warned_gains);
        self.rt = Some(Box::new(self.build(s, ctx, again)?));
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
        let following = matches!(rt.channel, Channel::Following(_));
        if following && rt.startup.is_none() && s[self.v] < PLL_V_MIN {
            // The PLL has no voltage to lock to: the unit has lost synchronism. It blocks its
            // current and waits for the voltage as at a start from zero voltage.
            rt.startup = Some(Startup {
                ok_since: None,
                v_last: s[self.v],
            });
            s[self.synchronized] = false;
            ctx.warn(format!(
                "t = {t:.4} s: terminal voltage {:.4} pu: the PLL has no voltage to lock to; lost synchronism, the current is blocked until the voltage returns above startup.v_sync",
                s[self.v]
            ));
        }
        if rt.startup.is_some() && !self.wait_for_voltage(rt, s, t, h, ctx) {
            self.step_dc(rt, s, t, h, ctx);
            return Ok(());
        }
        let to_dvpp = s[self.s_base] / s[self.s_dvpp];
        let to_rated = s[self.s_base] / s[self.s_rated];
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
        // The set point: the dispatch (ramped in after a start from zero voltage), curtailed to
        // what the primary source allows (a cloud lowers it).
        let ramp = rt.t_sync.map_or(1.0, |t0| {
            let r = s[self.ramp];
            if r > 0.0 {
                ((t + h - t0) / r).min(1.0)
            } else {
                1.0
            }
        });
        let dispatch = rt.p0 + s[self.redispatch];
        let p_set = (dispatch * ramp).min(self.headroom_limit(s, t));
        s[self.p_set] = p_set;
        let (v, v_angle) = (s[self.v], s[self.v_angle]);
        let budget = rt.dc.ac_budget();
        let i_max = s[self.i_max];
        let mut modulation = false;
        let (current_limit, dc_limit, request) = match &mut rt.channel {
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
                // The controls see the power the internal voltage delivers: the measurement
                // plus what the limits withheld. While a current or dc limit episode is on (the
                // current-limited mode, left 1 s after the limit last acted) also the change of
                // the limited power that the node's last move of angle makes and the measurement
                // does not show yet: the measurement reflects the angle sent one communication
                // step earlier, and through the direct feedthrough of T_pf/m (a low-pass unit's
                // τ/(μ H)) that loop has a gain per step near 1 (2π f_nom h |D| (S_base/S_dvpp)
                // E V/|Z| = 1.16 for case study I's wind at a fixed bus voltage; about 0.94
                // through the network, from its ringing after case study I's load step, which
                // decays by 0.97 per step). With the delay that is a 60°-per-step mode at the edge of
                // stability, which the limiter, switching between limited and free from one step
                // to the next, kept going. Half of the move's effect (`DELAY_COMPENSATION`),
                // computed with the limiter at the measured bus voltage (nothing while the dc
                // budget holds the power), keeps the loop damped over its range of gains. The
                // grid frequency's share of the move (its mean over `ANGLE_MEAN_TAU`) moves the
                // bus too and is left out. Below the limits nothing changes.
                // Rotational control: both channels see p', q' and the set point rotated (the
                // identity at rot.rx = 0).
                let compensation = if rt.limit.current.active() || rt.limit.dc.active() {
                    // The limited power at the measured bus voltage, from the node E∠θ.
                    let (r, x) = self.slot_impedance(s);
                    let z = Complex::new(r, x);
                    let bus = Complex::from_polar(s[self.v], s[self.v_angle]);
                    let u = if s[self.v] > limits::V_FLOOR {
                        bus / s[self.v]
                    } else {
                        Complex::from_polar(1.0, f.theta)
                    };
                    let budget = rt.dc.ac_budget();
                    let limited = |theta: f64| {
                        let wanted = (Complex::from_polar(s[self.e], theta) - bus) / z;
                        let i = limits::saturate_forming(
                            wanted * to_rated,
                            u,
                            s[self.v],
                            s[self.i_max],
                            budget,
                        )
                        .current;
                        (bus * (i / to_rated).conj()).re
                    };
                    let moved = f.dtheta - f.dtheta_mean;
                    DELAY_COMPENSATION * (limited(f.theta) - limited(f.theta - moved))
                } else {
                    0.0
                };
                let (p_fb, q_fb) = rt.rot.rotate(
                    s[self.p] + rt.withheld.0 + compensation,
                    s[self.q] + rt.withheld.1,
                );
                let (p_set_rot, q_set_rot) = rt.rot.rotate(p_set, rt.q0);
                let dp = (p_fb - p_set_rot) * to_dvpp;
                s[self.p_ref] = p_set;
                let (df, df_int) = f.pf.step_with_integral(dp, h);
                s[self.df] = df;
                f.dtheta = 2.0 * PI * s[self.f_nom] * df_int;
                f.theta += f.dtheta;
                f.dtheta_mean += -(-h / ANGLE_MEAN_TAU).exp_m1() * (f.dtheta - f.dtheta_mean);
                // PI matching controller on E: q tracks the reference held over the step.
                // E within [0, E_max]; the integrator stops while the limit holds (anti-windup).
                let e = rt.q_ref - q_fb;
                let e_max = s[self.e_max];
                let integral = f.e_int + s[self.qpi_ki] * e * h;
                let unclamped = rt.e0 + s[self.qpi_kp] * e + integral;
                f.e = unclamped.clamp(0.0, e_max);
                if unclamped == f.e {
                    f.e_int = integral;
                }
                rt.q_ref = q_set_rot + rt.vq.step(dv, h) / to_dvpp;
                // Reported as the q at which q' meets its reference at the measured p'.
                s[self.q_ref] = rt.rot.unrotate(p_fb, rt.q_ref).1;
                // The converter imposes the internal voltage, within the modulation limit; its
                // output stage holds the current within I_max and the active power within the
                // dc link's budget (enforced in the network solution, `i_limit`, `p_min`,
                // `p_max`). What the limits hold back, estimated at the measured bus voltage,
                // is added to the measurements the controls see.
                let e_cap = s[self.e_max] * rt.dc.v_dc();
                modulation = f.e > e_cap;
                let e_out = f.e.min(e_cap);
                let (r, x) = self.slot_impedance(s);
                let z = Complex::new(r, x);
                let bus = Complex::from_polar(v, v_angle);
                let wanted = (Complex::from_polar(e_out, f.theta) - bus) / z;
                let u = if v > limits::V_FLOOR {
                    bus / v
                } else {
                    Complex::from_polar(1.0, f.theta)
                };
                let lim = limits::saturate_forming(wanted * to_rated, u, v, i_max, budget);
                // Its gain: the feedback closes a loop through the direct feedthrough `D` of
                // T_pf/m whose gain over one step, 2π f_nom h |D| (S_base/S_dvpp) E V/|Z|, can
                // exceed 1 (a low-pass unit, τ/(μ H)); the gain is cut to keep that loop at 0.5.
                rt.withheld = if lim.current_limit || lim.dc_limit {
                    let held = bus * (wanted - lim.current / to_rated).conj();
                    let feedthrough = f.pf.simulator().system().d()[0].abs();
                    let loop_gain =
                        2.0 * PI * s[self.f_nom] * h * feedthrough * to_dvpp * e_out * v / z.norm();
                    let kappa = (0.5 / loop_gain).min(1.0);
                    (kappa * held.re, kappa * held.im)
                } else {
                    (0.0, 0.0)
                };
                s[self.e] = e_out;
                s[self.theta] = f.theta;
                let request = (wanted * to_rated).norm() / i_max;
                (lim.current_limit, lim.dc_limit, request)
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
                // The v-q droop of a current-injecting unit is a loop through the grid's
                // impedance with gain X_th/Dq (about 10 at bus 2 for Dq = 0.01): stable only
                // behind a dominant lag, the plant's voltage control (`vq.tau`).
                let tau_v = s[self.vq_tau];
                let kv = if tau_v > 0.0 {
                    -(-h / tau_v).exp_m1()
                } else {
                    1.0
                };
                g.dv += kv * (dv - g.dv);
                let dq = rt.vq.step(g.dv, h) / to_dvpp;
                // Rotational control: dp, dq are changes of p', q' about the rotated set point;
                // the converter's references are their back-rotation (the identity at rot.rx = 0).
                let (p_set_rot, q_set_rot) = rt.rot.rotate(p_set, rt.q0);
                let (p_cmd, q_cmd) = rt.rot.unrotate(p_set_rot + dp, q_set_rot + dq);
                // References as currents at the measured voltage, limited, and back.
                let vm = v.max(limits::V_FLOOR) / to_rated;
                let wanted = (p_cmd / vm, q_cmd / vm);
                let ((ip, iq), cur, dcl) =
                    limits::saturate_following(wanted, v, i_max, budget, s[self.priority]);
                // The converter's currents follow their commands with the lag `current.tau`
                // (its inner current control and the plant's response): an injection that moved
                // at once would close a loop through the bus angle and the PLL, and through the
                // bus voltage and the v-q droop, that a one-step exchange delay makes oscillate
                // from one step to the next.
                let tau = s[self.current_tau];
                let k = if tau > 0.0 { -(-h / tau).exp_m1() } else { 1.0 };
                g.current.0 += k * (ip - g.current.0);
                g.current.1 += k * (iq - g.current.1);
                // The limits hold for the current itself, also while it follows its command.
                let (held, _, _) =
                    limits::saturate_following(g.current, v, i_max, budget, s[self.priority]);
                g.current = held;
                s[self.p_ref] = g.current.0 * vm;
                s[self.q_ref] = g.current.1 * vm;
                let gains = (s[self.pll_kp], s[self.pll_ki]);
                if gains != g.gains {
                    g.pll
                        .set_system(pll_model(gains.0, gains.1, s[self.f_nom]))
                        .expect("PLL order");
                    g.gains = gains;
                    ctx.event(format!(
                        "PLL gains retuned at t = {t}: kp = {}, ki = {}",
                        gains.0, gains.1
                    ));
                }
                let y = g.pll.step_all(v_angle, h);
                rt.df_held = y[0];
                s[self.df] = y[0];
                s[self.theta] = y[1];
                (cur, dcl, wanted.0.hypot(wanted.1) / i_max)
            }
        };
        let lim = &mut rt.limit;
        let t1 = t + h;
        lim.current
            .record(t1, current_limit, request, || "current limit I_max", ctx);
        let (lo, hi) = budget;
        lim.dc.record(
            t1,
            dc_limit,
            rt.dc.v_dc(),
            || format!("dc-link power budget [{lo:.3}, {hi:.3}] pu (v_dc)"),
            ctx,
        );
        lim.modulation.record(
            t1,
            modulation,
            s[self.e_max] * rt.dc.v_dc(),
            || "modulation limit E_max * v_dc",
            ctx,
        );
        self.step_dc(rt, s, t, h, ctx);
        Ok(())
    }

    /// The primary source and the dc link over the step, and the outputs that report them.
    fn step_dc(&self, rt: &mut Runtime, s: &mut Store, t: f64, h: f64, ctx: &mut Context) {
        s[self.p_avail] = self.available(s, t + h);
        let to_rated = s[self.s_base] / s[self.s_rated];
        let (r, _) = self.slot_impedance(s);
        let p_ac = self.converter_power(s, r);
        let cap = s[self.p_avail] * to_rated;
        let dc = rt.dc.step(p_ac, h, cap);
        rt.dc.update_reserve(rt.limit.dc.active(), cap);
        rt.limit.source.record(
            t + h,
            dc.source,
            rt.dc.p_src(),
            || format!("primary source at its limit (P_avail = {cap:.4} pu on S_rated)"),
            ctx,
        );
        self.write_dc(s, rt);
        self.write_limits(s, rt);
        self.write_rotated(s, rt);
    }

    /// A unit started below `startup.v_sync`: zero current until the voltage has been above
    /// it and steady for `startup.t_hold`; then it takes the measured voltage as its operating
    /// point and synchronizes (returns true from that step on).
    fn wait_for_voltage(
        &self,
        rt: &mut Runtime,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) -> bool {
        let (v, v_angle) = (s[self.v], s[self.v_angle]);
        let st = rt.startup.as_mut().expect("waiting");
        let steady = h > 0.0 && ((v - st.v_last) / h).abs() < 0.5;
        st.v_last = v;
        if v >= s[self.v_sync] && steady {
            let since = *st.ok_since.get_or_insert(t);
            if t + h - since >= s[self.t_hold] {
                rt.startup = None;
                rt.t_sync = Some(t);
                rt.v0 = v;
                rt.theta0 = v_angle;
                rt.e0 = v;
                match &mut rt.channel {
                    Channel::Forming(f) => {
                        f.e = v;
                        f.theta = v_angle;
                    }
                    Channel::Following(g) => {
                        g.pll
                            .set_state(&[0.0, v_angle], v_angle)
                            .expect("PLL state");
                        g.current = (0.0, 0.0);
                    }
                }
                s[self.synchronized] = true;
                ctx.event(format!(
                    "synchronized at t = {t:.4} s to v = {v:.4} pu; the set point ramps to {:.4} pu over {} s",
                    rt.p0,
                    s[self.ramp]
                ));
                return true;
            }
        } else {
            st.ok_since = None;
        }
        // Zero current: the converter follows the terminal voltage (grid-forming) or injects
        // nothing (grid-following).
        s[self.e] = v;
        s[self.theta] = v_angle;
        s[self.df] = 0.0;
        s[self.p_ref] = 0.0;
        s[self.q_ref] = 0.0;
        s[self.p_set] = 0.0;
        false
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
