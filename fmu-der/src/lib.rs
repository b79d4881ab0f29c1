//! DER matching controller model (the `dvpp_der` FMU; its binary is `fmu/`): one DVPP unit,
//! grid-forming or grid-following, that realizes its local reference model with adaptive dynamic
//! participation factors.
//!
//! The controller is [`dvpp_controllers::phasor::PhasorUnit`] (its module documents the control:
//! `Δf = -T_i^pf Δp` or `Δp = -T_i^fp Δf`, the PI matching controller on `E`, rotational power
//! control, the set point curtailed to the primary source, the dc side and the output stage's
//! limits). This crate is its FMU adapter: it declares the variables (`variables`), reads them
//! into the unit's typed parameters, measurement and operator's gains, and writes its command
//! back to the outputs and its notices to the log.

mod adpf;
pub mod emt;
pub mod ports;
mod preset;
mod unit_vars;
mod variables;

pub use dvpp_controllers::phasor::Priority;
pub use dvpp_controllers::{AdpfKind, Mode, MAX_LPF};
pub use preset::{Preset, Shape, UnitDefaults, PRESETS};

use adpf::AdpfVars;
use dvpp_controllers::phasor::{
    DcRange, OutputStage, PhasorCommand, PhasorMeasurement, PhasorParams, PhasorUnit, QPiParams,
    SlotImpedance, StartupParams,
};
use fmi_export::{Boolean, Context, Integer, Model, ModelError, Real, Store, Variables};
use serde::{Deserialize, Serialize};
use unit_vars::{DcVars, GainVars, PllVars, SourceVars, UnitVars};

/// The DER's variable handles; its running state (`Model::State`) is the [`PhasorUnit`].
#[derive(Clone, Serialize, Deserialize)]
pub struct Der {
    /// Rating and bases, mode, `T_des`.
    unit: UnitVars,
    r_f: Real,
    x_f: Real,
    adpf_p: AdpfVars,
    adpf_q: AdpfVars,
    pll: PllVars,
    qpi_kp: Real,
    qpi_ki: Real,
    e_max: Real,
    dc: DcVars,
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
    source: SourceVars,
    redispatch: Real,
    p: Real,
    q: Real,
    v: Real,
    v_angle: Real,
    /// The operator's dc gains.
    gains: GainVars,
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

/// A controller's warning or event into the FMU's log.
fn log(ctx: &mut Context, notice: dvpp_controllers::Notice) {
    match notice {
        dvpp_controllers::Notice::Warning(w) => ctx.warn(w),
        dvpp_controllers::Notice::Event(e) => ctx.event(e),
    }
}

impl Der {
    /// The parameters as they are now; an unknown code (`mode`, `adpf.*.kind`,
    /// `limit.priority`) is refused by name.
    fn params(&self, s: &Store) -> Result<PhasorParams, ModelError> {
        Ok(PhasorParams {
            rating: self.unit.rating(s),
            mode: self.unit.mode(s)?,
            tdes: self.unit.tdes(s),
            slot: SlotImpedance {
                r_f: s[self.r_f],
                x_f: s[self.x_f],
            },
            adpf_p: self.adpf_p.read(s)?,
            adpf_q: self.adpf_q.read(s)?,
            pll: self.pll.read(s),
            qpi: self.qpi(s),
            dc: self.dc.read(s),
            dc_range: DcRange {
                v_min: s[self.v_dc_min],
                v_max: s[self.v_dc_max],
                t_budget: s[self.t_budget],
            },
            source: self.source.read(s),
            stage: self.stage(s)?,
            vi_r: s[self.vi_r],
            startup: StartupParams {
                v_sync: s[self.v_sync],
                t_hold: s[self.t_hold],
                ramp: s[self.ramp],
            },
            rot_rx: s[self.rot_rx],
            redispatch: s[self.redispatch],
        })
    }

    fn qpi(&self, s: &Store) -> QPiParams {
        QPiParams {
            kp: s[self.qpi_kp],
            ki: s[self.qpi_ki],
            e_max: s[self.e_max],
        }
    }

    fn stage(&self, s: &Store) -> Result<OutputStage, ModelError> {
        Ok(OutputStage {
            i_max: s[self.i_max],
            priority: Priority::from_code(s[self.priority])?,
            delay_c: s[self.delay_c],
            current_tau: s[self.current_tau],
            vq_tau: s[self.vq_tau],
        })
    }

    /// The tunable parameters into the running unit.
    fn retune(&self, unit: &mut PhasorUnit, s: &Store) -> Result<(), ModelError> {
        let (pll, source) = (self.pll.read(s), self.source.read(s));
        unit.set_pll_gains(pll.kp, pll.ki);
        unit.set_voltage_matching(self.qpi(s));
        unit.set_output_stage(self.stage(s)?);
        unit.set_availability(
            source.deload,
            source.p_avail0,
            source.avail_t,
            source.avail_dp,
        );
        unit.set_redispatch(s[self.redispatch]);
        Ok(())
    }

    fn measurement(&self, s: &Store, t: f64) -> PhasorMeasurement {
        PhasorMeasurement {
            t,
            p: s[self.p],
            q: s[self.q],
            v: s[self.v],
            v_angle: s[self.v_angle],
        }
    }

    /// The command into the outputs, its notices into the log.
    fn write(&self, s: &mut Store, c: PhasorCommand, ctx: &mut Context) {
        for (r, x) in [
            (self.theta, c.theta),
            (self.e, c.e),
            (self.df, c.df),
            (self.p_ref, c.p_ref),
            (self.p_set, c.p_set),
            (self.q_ref, c.q_ref),
            (self.p_avail, c.p_avail),
            (self.v_dc, c.v_dc),
            (self.p_dc, c.p_dc),
            (self.i_ac, c.i_ac),
            (self.i_limit, c.i_limit),
            (self.p_min, c.p_min),
            (self.p_max, c.p_max),
            (self.e_src, c.energy_source),
            (self.e_ac, c.energy_ac),
            (self.e_loss, c.energy_loss),
            (self.w_dc, c.energy_stored),
            (self.p_rot, c.p_rot),
            (self.q_rot, c.q_rot),
        ] {
            s[r] = x;
        }
        for (r, x) in [
            (self.limit_current, c.limit_current),
            (self.limit_dc, c.limit_dc),
            (self.limit_source, c.limit_source),
            (self.limit_modulation, c.limit_modulation),
            (self.synchronized, c.synchronized),
        ] {
            s[r] = x;
        }
        for n in c.notices {
            log(ctx, n);
        }
    }
}

impl Model for Der {
    type Config = DerConfig;
    type State = PhasorUnit;
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

    /// The unit at the measured operating point; the availability profile is read at t = 0.
    /// Initialization may run several times in initialization mode; what `previous` already
    /// reported is not repeated.
    fn initialize(
        &self,
        previous: Option<&PhasorUnit>,
        s: &mut Store,
        ctx: &mut Context,
    ) -> Result<PhasorUnit, ModelError> {
        let m = self.measurement(s, 0.0);
        let (unit, command) =
            PhasorUnit::initialize(&self.params(s)?, &m, &self.gains.read(s), previous)?;
        self.write(s, command, ctx);
        Ok(unit)
    }

    fn do_step(
        &self,
        unit: &mut PhasorUnit,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        self.retune(unit, s)?;
        let command = unit.step(&self.measurement(s, t), &self.gains.read(s), h)?;
        self.write(s, command, ctx);
        Ok(())
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
