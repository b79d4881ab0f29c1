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
//! * **DVPP layer** (the same code as the phasor DER, `dvpp_controllers::layer`): the powers `p`, `q` and
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
//! The controller is `dvpp_controllers::emt::EmtUnit`; this FMU is its adapter: it reads the
//! parameters, measurements and gains into their typed values, calls the unit and writes its
//! command back (docs/emt.md, "For a host author").
//!
//! Timing: the output computed at the end of a step is meant to be held over the next step (a
//! zero-order hold, as an averaged converter model applies a modulation), so the dq-to-abc
//! transform advances the angle by 1.5 steps (one step of computation delay and half a step
//! of hold). At initialization the output is prepared for a first step of `t_s`.

mod variables;

use crate::adpf::AdpfVars;
use crate::unit_vars::{DcVars, GainVars, PllVars, SourceVars, UnitVars};
use crate::{log, DerConfig};
use dvpp_control::converter::{Abc, InnerDesign};
use dvpp_controllers::emt::{
    EmtCommand, EmtMeasurement, EmtParams, EmtUnit, FilterParams, InnerKind, QPiParams,
};
use fmi_export::{Boolean, Context, Integer, Model, ModelError, Real, Store, Variables};

/// The EMT-level controller's variable handles (its running state is the unit, `EmtUnit`).
pub struct DerEmt {
    unit: UnitVars,
    adpf_p: AdpfVars,
    adpf_q: AdpfVars,
    pll: PllVars,
    /// `qpi.kp`, `qpi.ki`, `E_max`.
    qpi: [Real; 3],
    vq_tau: Real,
    /// `R_f`, `L_f`, `C_f`, `R_t`, `L_t`.
    filter: [Real; 5],
    vdc_ratio: Real,
    vi_r: Real,
    /// `inner.current_hz`, `inner.voltage_hz`, `inner.zero_ratio`, `I_max`.
    inner: [Real; 4],
    t_s: Real,
    dc: DcVars,
    source: SourceVars,
    v_abc: [Real; 3],
    i_abc: [Real; 3],
    ig_abc: [Real; 3],
    v_dc: Real,
    gains: GainVars,
    out: Outputs,
    /// Option A (0) or B (1) for the grid-forming v-q matching.
    inner_kind: Integer,
}

/// The command's variables.
struct Outputs {
    m_abc: [Real; 3],
    i_dc_ref: Real,
    /// `p_src_min`, `p_src_max`.
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
    /// `limit.current`, `limit.modulation`, `limit.source`.
    limit: [Boolean; 3],
}

/// The three phases of an input.
fn abc(s: &Store, r: &[Real; 3]) -> Abc {
    Abc {
        a: s[r[0]],
        b: s[r[1]],
        c: s[r[2]],
    }
}

impl DerEmt {
    /// The parameters as they are now; an unknown code (`mode`, `adpf.*.kind`, `inner.kind`)
    /// is refused by name.
    fn params(&self, s: &Store) -> Result<EmtParams, ModelError> {
        let [qpi_kp, qpi_ki, e_max] = self.qpi;
        let [r_f, l_f, c_f, r_t, l_t] = self.filter;
        let [current_hz, voltage_hz, zero_ratio, i_max] = self.inner;
        Ok(EmtParams {
            rating: self.unit.rating(s),
            mode: self.unit.mode(s)?,
            tdes: self.unit.tdes(s),
            adpf_p: self.adpf_p.read(s)?,
            adpf_q: self.adpf_q.read(s)?,
            pll: self.pll.read(s),
            qpi: QPiParams {
                kp: s[qpi_kp],
                ki: s[qpi_ki],
                e_max: s[e_max],
            },
            vq_tau: s[self.vq_tau],
            filter: FilterParams {
                r_f: s[r_f],
                l_f: s[l_f],
                c_f: s[c_f],
                r_t: s[r_t],
                l_t: s[l_t],
            },
            vdc_ratio: s[self.vdc_ratio],
            vi_r: s[self.vi_r],
            inner: InnerDesign {
                current_hz: s[current_hz],
                voltage_hz: s[voltage_hz],
                zero_ratio: s[zero_ratio],
                i_max: s[i_max],
            },
            inner_kind: InnerKind::from_code(s[self.inner_kind])?,
            t_s: s[self.t_s],
            dc: self.dc.read(s),
            source: self.source.read(s),
        })
    }

    fn measurement(&self, s: &Store, t: f64) -> EmtMeasurement {
        EmtMeasurement {
            t,
            v_c: abc(s, &self.v_abc),
            i_f: abc(s, &self.i_abc),
            i_g: abc(s, &self.ig_abc),
            v_dc: s[self.v_dc],
        }
    }

    /// The command into the outputs, its notices into the log.
    fn write(&self, s: &mut Store, c: EmtCommand, ctx: &mut Context) {
        let o = &self.out;
        for (&r, x) in o.m_abc.iter().zip(c.m_abc) {
            s[r] = x;
        }
        for (r, x) in [
            (o.i_dc_ref, c.i_dc_ref),
            (o.p_src[0], c.p_src_min),
            (o.p_src[1], c.p_src_max),
            (o.p, c.p),
            (o.q, c.q),
            (o.v, c.v),
            (o.df, c.df),
            (o.theta, c.theta),
            (o.e, c.e),
            (o.p_set, c.p_set),
            (o.q_ref, c.q_ref),
            (o.p_avail, c.p_avail),
            (o.i_ac, c.i_ac),
        ] {
            s[r] = x;
        }
        for (&r, x) in o
            .limit
            .iter()
            .zip([c.limit_current, c.limit_modulation, c.limit_source])
        {
            s[r] = x;
        }
        for n in c.notices {
            log(ctx, n);
        }
    }
}

impl Model for DerEmt {
    type Config = DerConfig;
    type State = EmtUnit;
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

    /// The unit at the measured operating point; the availability profile is read at t = 0.
    fn initialize(
        &self,
        _: Option<&EmtUnit>,
        s: &mut Store,
        ctx: &mut Context,
    ) -> Result<EmtUnit, ModelError> {
        let m = self.measurement(s, 0.0);
        let (unit, command) = EmtUnit::initialize(&self.params(s)?, &m, &self.gains.read(s))?;
        self.write(s, command, ctx);
        Ok(unit)
    }

    /// The tunable parameters as they are now, then one sample.
    fn do_step(
        &self,
        unit: &mut EmtUnit,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        unit.retune(&self.params(s)?)?;
        let command = unit.step(&self.measurement(s, t), &self.gains.read(s), h)?;
        self.write(s, command, ctx);
        Ok(())
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
