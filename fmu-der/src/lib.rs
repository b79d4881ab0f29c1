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
use dvpp_controllers::phasor::{PhasorCommand, PhasorParams, PhasorUnit};
use fmi_export::{Context, Model, ModelError, Real, Store, Variables};
use serde::{Deserialize, Serialize};
use unit_vars::{DcVars, GainVars, PllVars, QPiVars, SourceVars, UnitVars};
use variables::{
    DcRangeVars, EnergyOutputs, LimitFlags, LinkOutputs, MeasuredVars, Outputs, RotationVars,
    SlotVars, StageVars, StartupVars,
};

/// The DER's variable handles, in groups; its running state (`Model::State`) is the [`PhasorUnit`].
#[derive(Clone, Serialize, Deserialize)]
pub struct Der {
    /// Rating and bases, mode, `T_des`.
    unit: UnitVars,
    slot: SlotVars,
    adpf_p: AdpfVars,
    adpf_q: AdpfVars,
    pll: PllVars,
    qpi: QPiVars,
    dc: DcVars,
    dc_range: DcRangeVars,
    /// The output stage and `vi.r`.
    stage: StageVars,
    startup: StartupVars,
    source: SourceVars,
    /// `dispatch.dP`.
    redispatch: Real,
    /// The measured bus quantities.
    measured: MeasuredVars,
    /// The operator's dc gains.
    gains: GainVars,
    out: Outputs,
    link: LinkOutputs,
    energy: EnergyOutputs,
    flags: LimitFlags,
    /// Rotational power control (declared last).
    rot: RotationVars,
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
            slot: self.slot.read(s),
            adpf_p: self.adpf_p.read(s)?,
            adpf_q: self.adpf_q.read(s)?,
            pll: self.pll.read(s),
            qpi: self.qpi.read_phasor(s),
            dc: self.dc.read(s),
            dc_range: self.dc_range.read(s),
            source: self.source.read(s),
            stage: self.stage.read(s)?,
            vi_r: s[self.stage.vi_r],
            startup: self.startup.read(s),
            rot_rx: s[self.rot.rx],
            redispatch: s[self.redispatch],
        })
    }

    /// The tunable parameters into the running unit.
    fn retune(&self, unit: &mut PhasorUnit, s: &Store) -> Result<(), ModelError> {
        let (pll, source) = (self.pll.read(s), self.source.read(s));
        unit.set_pll_gains(pll.kp, pll.ki);
        unit.set_voltage_matching(self.qpi.read_phasor(s));
        unit.set_output_stage(self.stage.read(s)?);
        unit.set_availability(
            source.deload,
            source.p_avail0,
            source.avail_t,
            source.avail_dp,
        );
        unit.set_redispatch(s[self.redispatch]);
        Ok(())
    }

    /// The command into the outputs, its notices into the log.
    fn write(&self, s: &mut Store, c: PhasorCommand, ctx: &mut Context) {
        let (o, link, energy, flags) = (&self.out, &self.link, &self.energy, &self.flags);
        for (r, x) in [
            (o.theta, c.theta),
            (o.e, c.e),
            (o.df, c.df),
            (o.p_ref, c.p_ref),
            (o.p_set, c.p_set),
            (o.q_ref, c.q_ref),
            (o.p_avail, c.p_avail),
            (link.v_dc, c.v_dc),
            (link.p_dc, c.p_dc),
            (link.i_ac, c.i_ac),
            (link.i_limit, c.i_limit),
            (link.p_min, c.p_min),
            (link.p_max, c.p_max),
            (energy.source, c.energy_source),
            (energy.ac, c.energy_ac),
            (energy.loss, c.energy_loss),
            (energy.stored, c.energy_stored),
            (self.rot.p_rot, c.p_rot),
            (self.rot.q_rot, c.q_rot),
        ] {
            s[r] = x;
        }
        for (r, x) in [
            (flags.current, c.limit_current),
            (flags.dc, c.limit_dc),
            (flags.source, c.limit_source),
            (flags.modulation, c.limit_modulation),
            (flags.synchronized, c.synchronized),
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
        let m = self.measured.read(s, 0.0);
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
        if ctx.tuned() {
            self.retune(unit, s)?;
        }
        let command = unit.step(&self.measured.read(s, t), &self.gains.read(s), h)?;
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
