//! The phasor-level unit's parameters as plain values, named and checked as the `dvpp_der` FMU names them.

use super::dc::DcParams;
use crate::layer::TDesParams;
use crate::{positive, AdpfParams, DcLinkParams, Error, Mode, PllParams, Rating, SourceParams};
use serde::{Deserialize, Serialize};

/// Which current a unit keeps first at `I_max` (`limit.priority`). Grid-following: the component
/// kept first. Grid-forming: `Active` keeps the request's direction (the active current the
/// voltage behind the virtual resistance asks for in a dip), `Reactive` turns a request beyond
/// `I_max` to the direction of a virtual impedance (`limits::turn_reactive`): reactive current
/// in dips (the phasor counterpart of a virtual-impedance current limit).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Priority {
    /// `limit.priority` = 0: the active current (frequency support).
    Active,
    /// `limit.priority` = 1: the reactive current (voltage support, as fault ride-through codes
    /// ask).
    Reactive,
}

impl Priority {
    /// The `limit.priority` parameter's value.
    pub const fn code(self) -> i32 {
        match self {
            Priority::Active => 0,
            Priority::Reactive => 1,
        }
    }

    /// The priority of a `limit.priority` value, or the error naming it.
    pub fn from_code(code: i32) -> Result<Priority, Error> {
        match code {
            0 => Ok(Priority::Active),
            1 => Ok(Priority::Reactive),
            k => Err(Error::field(
                "limit.priority",
                format!("= {k}: 0 active current first, 1 reactive current first"),
            )),
        }
    }
}

/// The impedance between the imposed voltage and the terminal bus, the LV/MV transformer
/// (`R_f`, `X_f`, pu on `S_rated`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SlotImpedance {
    pub r_f: f64,
    pub x_f: f64,
}

/// The grid-forming PI matching controller on `E` (option A): `qpi.kp`, `qpi.ki`, and the
/// modulation limit `E_max` (all tunable).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct QPiParams {
    pub kp: f64,
    pub ki: f64,
    pub e_max: f64,
}

/// The range the ac side may move the dc link in (`v_dc_min`, `v_dc_max`, pu) and the time
/// `dc.t_budget` (s) over which it may draw the link's usable energy.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DcRange {
    pub v_min: f64,
    pub v_max: f64,
    pub t_budget: f64,
}

/// The converter's output stage (all tunable): the current limit `I_max` (pu of the rated
/// current), `limit.priority`, the grid-forming delay compensation `delay.c`, and the
/// grid-following lags `current.tau` and `vq.tau` (s; 0 = none).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OutputStage {
    pub i_max: f64,
    pub priority: Priority,
    pub delay_c: f64,
    pub current_tau: f64,
    pub vq_tau: f64,
}

/// A start from zero voltage (`startup.*`): the voltage `v_sync` (pu) the terminal must hold
/// steadily for `t_hold` (s) before the unit synchronizes, and the set point's ramp `ramp` (s).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StartupParams {
    pub v_sync: f64,
    pub t_hold: f64,
    pub ramp: f64,
}

/// Every parameter of the phasor-level unit. Those marked *tunable* may change while it runs
/// ([`super::PhasorUnit::retune`]); the others are fixed at initialization.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PhasorParams {
    /// `S_rated`, `S_base`, `S_dvpp`, `f_nom`.
    pub rating: Rating,
    /// `mode`.
    pub mode: Mode,
    /// `Tdes.*`.
    pub tdes: TDesParams,
    /// `R_f`, `X_f`.
    pub slot: SlotImpedance,
    /// `adpf.p.*`, `adpf.q.*`.
    pub adpf_p: AdpfParams,
    pub adpf_q: AdpfParams,
    /// `pll.*` (`kp`, `ki` tunable).
    pub pll: PllParams,
    /// `qpi.kp`, `qpi.ki`, `E_max` (tunable).
    pub qpi: QPiParams,
    /// `tau_dc`, `C_dc`, `G_dc`, `k_dc`, `dc.zeta`.
    pub dc: DcLinkParams,
    /// `v_dc_min`, `v_dc_max`, `dc.t_budget`.
    pub dc_range: DcRange,
    /// `storage`; `deload`, `P_avail0`, `avail.t_step`, `avail.dP` (tunable).
    pub source: SourceParams,
    /// `I_max`, `limit.priority`, `delay.c`, `current.tau`, `vq.tau` (tunable).
    pub stage: OutputStage,
    /// `vi.r`: grid-forming virtual resistance on `S_rated`.
    pub vi_r: f64,
    /// `startup.v_sync`, `startup.t_hold`, `startup.ramp`.
    pub startup: StartupParams,
    /// `rot.rx`: R/X of the lines the rotational power control compensates (0 = classical).
    pub rot_rx: f64,
    /// `dispatch.dP` (tunable): change of the dispatch on `S_base`.
    pub redispatch: f64,
}

impl PhasorParams {
    /// The bases and the slot reactance, which must be positive, checked in this order.
    pub(crate) fn validate_bases(&self) -> Result<(), Error> {
        let r = &self.rating;
        for (x, name) in [
            (r.s_rated, "S_rated"),
            (r.s_base, "S_base"),
            (r.s_dvpp, "S_dvpp"),
            (r.f_nom, "f_nom"),
            (self.slot.x_f, "X_f"),
        ] {
            positive(x, name)?;
        }
        Ok(())
    }

    /// The dc side's parameters, checked.
    pub(crate) fn dc_params(&self) -> Result<DcParams, Error> {
        let tau = positive(self.dc.tau_dc, "tau_dc")?;
        let c = positive(self.dc.c_dc, "C_dc")?;
        let t_budget = positive(self.dc_range.t_budget, "dc.t_budget")?;
        let (v_min, v_max) = (self.dc_range.v_min, self.dc_range.v_max);
        if !((0.0..1.0).contains(&v_min) && v_max > 1.0) {
            return Err(Error::field(
                "v_dc_min",
                format!("= {v_min} with v_dc_max = {v_max}: needs 0 <= v_dc_min < 1 < v_dc_max"),
            ));
        }
        Ok(DcParams {
            tau,
            c,
            g: self.dc.g_dc,
            k_dc: self.dc.k_dc,
            zeta: self.dc.zeta,
            storage: self.source.storage,
            v_min,
            v_max,
            t_budget,
        })
    }

    /// These parameters with the tunable ones of `new`.
    pub(crate) fn tuned(&self, new: &PhasorParams) -> PhasorParams {
        let mut p = *self;
        p.pll.kp = new.pll.kp;
        p.pll.ki = new.pll.ki;
        p.qpi = new.qpi;
        p.stage = new.stage;
        p.source.deload = new.source.deload;
        p.source.p_avail0 = new.source.p_avail0;
        p.source.avail_t = new.source.avail_t;
        p.source.avail_dp = new.source.avail_dp;
        p.redispatch = new.redispatch;
        p
    }

    /// The slot impedance `R_f + j X_f` on S_base.
    pub(crate) fn slot_impedance(&self) -> (f64, f64) {
        let zbase = self.rating.s_base / self.rating.s_rated;
        (self.slot.r_f * zbase, self.slot.x_f * zbase)
    }

    /// A grid-forming unit's virtual resistance `vi.r`, pu on the system base.
    pub(crate) fn virtual_resistance(&self) -> f64 {
        self.vi_r * self.rating.s_base / self.rating.s_rated
    }

    /// The highest set point the primary source allows at `t`: `deload · P_avail - G_dc`, on S_base.
    pub(crate) fn headroom_limit(&self, t: f64) -> f64 {
        self.source.deload * self.source.available(t)
            - self.dc.g_dc * self.rating.s_rated / self.rating.s_base
    }
}
