//! The DER matching controller at EMT level (the `dvpp_der_emt` FMU; its binary is `emt/`): the DVPP layer over the paper's cascaded inner loops, sampled every 20-50 µs on instantaneous three-phase measurements.
//!
//! One DVPP unit with the paper's converter interface ("Converter Interface of DERs"): an
//! averaged two-level VSC with a dc link fed by a lagged primary source, an RLC filter
//! (`R_f`, `L_f`, `C_f`) and an LV/MV transformer (`R_t`, `L_t`). The EMT tool computes that
//! circuit; this controller measures it and returns the modulation and the dc-source command.
//!
//! * **Measurements** (inputs, instantaneous, pu on the unit's rating): filter-capacitor
//!   voltage `v_a..c` (of the rated phase-to-neutral peak `v_r`), converter-side current
//!   `i_a..c` and grid-side (transformer) current `ig_a..c` (of the rated peak current), dc-link
//!   voltage `v_dc` (of its nominal `v_dc*`).
//! * **Commands** (outputs): modulation indices `m_a..c` (the converter's phase voltage is
//!   `m_x · v_dc · v_dc*/(2 v_r)`, so with `vdc_ratio = v_dc*/v_r = 3` a modulation of 2/3 gives
//!   1 pu at nominal dc voltage) and the dc source's current command `i_dc_ref` (pu of
//!   `S_rated/v_dc*`).
//! * **DVPP layer** (the same code as the phasor DER, `crate::layer`): the powers `p`, `q` and
//!   the voltage `v` at the MV side of the transformer (the paper's grid-side measurement,
//!   computed from `v_c` and `i_g` through `R_t + jX_t`) feed the unit's reference models with
//!   the operator's dc gains. Grid-forming (`mode` = 1): the dq frame turns at
//!   `ω_b (1 + Δf)` with `Δf = -(T_pf/m) Δp` (the frame's angle from `m⁻¹ T_pf`), and the PI
//!   matching controller sets the magnitude `E` of the capacitor-voltage reference `(E, 0)` so
//!   that `q` tracks `q₀ - T_vq Δv`. Grid-following (`mode` = 2): an SRF-PLL on the grid-side
//!   voltage orients the frame and measures `Δf`; the references `p₀ - T_fp Δf` and
//!   `q₀ - T_vq Δv` become a grid-side current reference.
//! * **Inner loops** (option A, [`dvpp_control::converter::InnerLoops`]): the capacitor-voltage
//!   PI loop gives the converter-current reference (limited to `I_max`), the current PI loop
//!   the converter voltage (limited by the modulation), with decoupling and feed-forward; gains
//!   from the filter data for the bandwidths `inner.current_hz` and `inner.voltage_hz`.
//!   Grid-following units run the current loop alone.
//! * **Dc side**: the command holds `v_dc` at 1 through the source, as the phasor DER's dc model
//!   does (`k_dc` on the stored energy, a damping term on the capacitor's power for `dc.zeta`,
//!   feed-forward of the converter power and the link losses) into the source's lag; the source
//!   itself stays within what it has (`[0, P_avail]`, or `±P_avail` for storage, output as
//!   `p_src_min`, `p_src_max` for the host's source model), as the phasor DER's does: the
//!   command is not clamped, the source is. The set point is the dispatch curtailed to
//!   `deload · P_avail - G_dc`.
//!
//! Timing: the output computed at the end of a step is meant to be held over the next step (a
//! zero-order hold, as an averaged converter model applies a modulation), so the dq-to-abc
//! transform advances the angle by 1.5 steps (one step of computation delay and half a step
//! of hold). At initialization the output is prepared for a first step of `t_s`.

mod control;
mod variables;

use crate::{DerConfig, MAX_LPF};
use control::Runtime;
use fmi_export::{Boolean, Context, Integer, Model, ModelError, Real, Store, Variables};
use serde::{Deserialize, Serialize};

/// The EMT-level controller's variable handles and, after initialization, its state.
#[derive(Clone, Serialize, Deserialize)]
pub struct DerEmt {
    mode: Integer,
    s_rated: Real,
    s_base: Real,
    s_dvpp: Real,
    f_nom: Real,
    h: Real,
    d: Real,
    dq: Real,
    tau_q: Real,
    adpf_p: crate::adpf::AdpfVars,
    adpf_q: crate::adpf::AdpfVars,
    pll_kp: Real,
    pll_ki: Real,
    pll_tau: Real,
    pll_order: Integer,
    qpi_kp: Real,
    qpi_ki: Real,
    e_max: Real,
    vq_tau: Real,
    r_f: Real,
    l_f: Real,
    c_f: Real,
    r_t: Real,
    l_t: Real,
    vdc_ratio: Real,
    vi_r: Real,
    current_hz: Real,
    voltage_hz: Real,
    zero_ratio: Real,
    i_max: Real,
    t_s: Real,
    tau_dc: Real,
    c_dc: Real,
    g_dc: Real,
    k_dc: Real,
    dc_zeta: Real,
    storage: Boolean,
    deload: Real,
    p_avail0: Real,
    avail_t: Real,
    avail_dp: Real,
    v_abc: [Real; 3],
    i_abc: [Real; 3],
    ig_abc: [Real; 3],
    v_dc: Real,
    mu_p: Real,
    mu_q: Real,
    mu_p_lpf: Vec<Real>,
    m_abc: [Real; 3],
    i_dc_ref: Real,
    p_src: [Real; 2],
    p: Real,
    q: Real,
    v: Real,
    df: Real,
    theta: Real,
    e: Real,
    p_set: Real,
    q_ref: Real,
    p_avail: Real,
    i_ac: Real,
    /// Option A (0) or B (1) for the grid-forming v-q matching.
    inner_kind: Integer,
    limit_current: Boolean,
    limit_modulation: Boolean,
    limit_source: Boolean,
}

impl DerEmt {
    fn lpf_gains(&self, s: &Store) -> [f64; MAX_LPF] {
        let mut out = [0.0; MAX_LPF];
        for (o, &r) in out.iter_mut().zip(&self.mu_p_lpf) {
            *o = s[r];
        }
        out
    }
}

impl Model for DerEmt {
    type Config = DerConfig;
    type State = Runtime;
    const IDENTIFIER: &'static str = "dvpp_der_emt";
    const NAME: &'static str = "DVPP DER matching controller, EMT level";
    const DESCRIPTION: &'static str = "DVPP unit at EMT level: the DVPP layer (T_des, ADPFs, dc gains) over cascaded capacitor-voltage and converter-current PI loops (option A) and the dc-voltage control, on instantaneous three-phase measurements";
    /// EMT steps are 20 to 50 µs, and one call costs the same at any step (no inner
    /// integration); 0.1 s still admits fmpy's `simulate_fmu` on the default experiment, whose
    /// automatic output interval steps by 16 ms, and refuses what has no meaning here.
    const MAX_STEP: f64 = 0.1;

    fn declare(
        config: &DerConfig,
        _: Option<&std::path::Path>,
        v: &mut Variables,
    ) -> Result<Self, String> {
        DerEmt::declare_variables(config, v)
    }

    fn initialize(
        &self,
        _: Option<&Runtime>,
        s: &mut Store,
        ctx: &mut Context,
    ) -> Result<Runtime, ModelError> {
        self.build(s, ctx)
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
        fmi_export::assert_golden::<super::DerEmt>(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/emt/modelDescription.xml"
        ));
    }
}
