//! DER matching controller model (the `dvpp_der` FMU; its binary is `fmu/`): one DVPP unit,
//! grid-forming or grid-following, that realizes its local reference model with adaptive dynamic
//! participation factors.
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

mod adpf;
mod common;
mod dc;
pub mod emt;
mod following;
mod forming;
mod limits;
pub mod ports;
mod preset;
mod runtime;
mod step;
mod unit_vars;
mod variables;

pub use dvpp_controllers::{AdpfKind, Mode, MAX_LPF};
pub use limits::priority;
pub use preset::{Preset, Shape, UnitDefaults, PRESETS};

use adpf::AdpfVars;
use dvpp_controllers::layer;
use fmi_export::{Boolean, Context, Integer, Model, ModelError, Real, Store, Variables};
use runtime::Runtime;
use serde::{Deserialize, Serialize};

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
    adpf_p: AdpfVars,
    adpf_q: AdpfVars,
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
    delay_c: Real,
    vi_r: Real,
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
}

/// Structure of the DER: which of the paper's units it is.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DerConfig {
    /// The name of one of [`PRESETS`] (`"wind"`, `"pv"`, `"bess"`): the unit whose rating,
    /// `τ_dc`, ADPF shapes and dc gains become the start values; none: a generic unit with a
    /// static ADPF.
    #[serde(default)]
    pub preset: Option<&'static Preset>,
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
    dvpp_controllers::positive(s[r], name).map_err(model_error)
}

/// A controller's error as the FMU reports it (the same text).
fn model_error(e: dvpp_controllers::Error) -> ModelError {
    ModelError(e.to_string())
}

/// A controller's warning or event into the FMU's log.
fn log(ctx: &mut Context, notice: dvpp_controllers::Notice) {
    match notice {
        dvpp_controllers::Notice::Warning(w) => ctx.warn(w),
        dvpp_controllers::Notice::Event(e) => ctx.event(e),
    }
}

impl Model for Der {
    type Config = DerConfig;
    type State = Runtime;
    const IDENTIFIER: &'static str = "dvpp_der";
    const NAME: &'static str = "DVPP DER matching controller";
    const DESCRIPTION: &'static str = "DVPP unit, grid-forming (df = -T_pf/m_p dp) or grid-following (dp = -m_p T_pf^-1 df), with ADPFs, dc side and rating limits";
    /// Phasor steps are 1e-4 to 1e-2 s; 1 s (100 times the longest) keeps one call short.
    const MAX_STEP: f64 = 1.0;

    fn declare(
        config: &DerConfig,
        _: Option<&std::path::Path>,
        v: &mut Variables,
    ) -> Result<Self, String> {
        Der::declare_variables(config, v)
    }

    fn initialize(
        &self,
        previous: Option<&Runtime>,
        s: &mut Store,
        ctx: &mut Context,
    ) -> Result<Runtime, ModelError> {
        // Initialization may run several times in initialization mode; a warning already given
        // in this episode is not repeated.
        self.build(s, ctx, previous.map(|rt| rt.common.warned_gains))
    }

    fn do_step(
        &self,
        rt: &mut Runtime,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        self.step(rt, s, t, h, ctx)
    }
}

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
