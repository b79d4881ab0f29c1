//! The EMT-level unit's parameters as plain values, named and checked as the `dvpp_der_emt` FMU names them.

use crate::layer::TDesParams;
use crate::{positive, AdpfParams, DcLinkParams, Error, Mode, PllParams, Rating, SourceParams};
use dvpp_control::converter::{ConverterData, InnerDesign};
use serde::{Deserialize, Serialize};

/// The grid-forming v-q matching (`inner.kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum InnerKind {
    /// `inner.kind` = 0: the q PI sets `E`, the capacitor-voltage and converter-current PI loops
    /// realize it.
    OptionA,
    /// `inner.kind` = 1 (grid-forming only): the LPV H∞ state feedback of
    /// `dvpp_control::converter::hinf_gains`, scheduled on `mu_q` (docs/hinf.md).
    OptionB,
}

impl InnerKind {
    /// The `inner.kind` parameter's value.
    pub const fn code(self) -> i32 {
        match self {
            InnerKind::OptionA => 0,
            InnerKind::OptionB => 1,
        }
    }

    /// The option of an `inner.kind` value, or the error naming it.
    pub fn from_code(code: i32) -> Result<InnerKind, Error> {
        match code {
            0 => Ok(InnerKind::OptionA),
            1 => Ok(InnerKind::OptionB),
            k => Err(Error::field("inner.kind", format!("= {k}: must be 0 or 1"))),
        }
    }
}

/// The grid-forming PI matching controller (option A): `qpi.kp`, `qpi.ki`, and the largest
/// capacitor-voltage reference `E_max`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct QPiParams {
    pub kp: f64,
    pub ki: f64,
    pub e_max: f64,
}

/// The circuit the converter drives, pu on `S_rated` at `f_nom`: the filter `R_f`, `L_f`,
/// `C_f` and the LV/MV transformer `R_t`, `L_t` (inductances and capacitance as their
/// reactance and susceptance at `f_nom`). They must be the host circuit's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FilterParams {
    pub r_f: f64,
    pub l_f: f64,
    pub c_f: f64,
    pub r_t: f64,
    pub l_t: f64,
}

/// Every parameter of the EMT-level unit. Those marked *tunable* may change while it runs
/// ([`crate::emt::EmtUnit::retune`]); the others are fixed at initialization.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EmtParams {
    pub rating: Rating,
    /// `mode`.
    pub mode: Mode,
    /// `Tdes.*`.
    pub tdes: TDesParams,
    /// `adpf.p.*`, `adpf.q.*`.
    pub adpf_p: AdpfParams,
    pub adpf_q: AdpfParams,
    /// `pll.*` (`kp`, `ki` tunable).
    pub pll: PllParams,
    /// `qpi.kp`, `qpi.ki`, `E_max` (tunable).
    pub qpi: QPiParams,
    /// `vq.tau` (tunable): grid-following, the lag of the voltage deviation ahead of the v-q droop.
    pub vq_tau: f64,
    /// `R_f`, `L_f`, `C_f`, `R_t`, `L_t`.
    pub filter: FilterParams,
    /// `vdc_ratio`: `v_dc*/v_r`, the converter's phase voltage is `m v_dc vdc_ratio/2`.
    pub vdc_ratio: f64,
    /// `vi.r` (tunable): grid-forming virtual resistance on `S_rated`.
    pub vi_r: f64,
    /// `inner.current_hz`, `inner.voltage_hz`, `inner.zero_ratio`, `I_max` (tunable).
    pub inner: InnerDesign,
    /// `inner.kind`.
    pub inner_kind: InnerKind,
    /// `t_s`: the host's step, for the output at initialization only.
    pub t_s: f64,
    /// `tau_dc`, `C_dc`, `G_dc`, `k_dc`, `dc.zeta`.
    pub dc: DcLinkParams,
    /// `storage`; `deload`, `P_avail0`, `avail.t_step`, `avail.dP` (tunable).
    pub source: SourceParams,
}

impl EmtParams {
    /// The parameters that must be positive, checked in this order; then `T_des`.
    pub fn validate(&self) -> Result<(), Error> {
        for (x, name) in [
            (self.rating.s_rated, "S_rated"),
            (self.rating.s_base, "S_base"),
            (self.rating.s_dvpp, "S_dvpp"),
            (self.rating.f_nom, "f_nom"),
            (self.filter.l_f, "L_f"),
            (self.filter.c_f, "C_f"),
            (self.vdc_ratio, "vdc_ratio"),
        ] {
            positive(x, name)?;
        }
        self.validate_inner()?;
        for (x, name) in [
            (self.t_s, "t_s"),
            (self.dc.tau_dc, "tau_dc"),
            (self.dc.c_dc, "C_dc"),
        ] {
            positive(x, name)?;
        }
        self.tdes.build().map(drop)
    }

    /// The inner-loop design's parameters, all positive.
    pub(crate) fn validate_inner(&self) -> Result<(), Error> {
        for (x, name) in [
            (self.inner.current_hz, "inner.current_hz"),
            (self.inner.voltage_hz, "inner.voltage_hz"),
            (self.inner.zero_ratio, "inner.zero_ratio"),
            (self.inner.i_max, "I_max"),
        ] {
            positive(x, name)?;
        }
        Ok(())
    }

    /// The converter data the inner loops are designed from.
    pub(crate) fn converter_data(&self) -> ConverterData {
        ConverterData {
            c_dc: self.dc.c_dc,
            g_dc: self.dc.g_dc,
            r_f: self.filter.r_f,
            l_f: self.filter.l_f,
            c_f: self.filter.c_f,
            r_t: self.filter.r_t,
            l_t: self.filter.l_t,
            kp_pll: self.pll.kp,
            ki_pll: self.pll.ki,
            k_dc: self.dc.k_dc,
            v_dc_ratio: self.vdc_ratio,
        }
    }

    /// These parameters with the tunable ones of `new`.
    pub(crate) fn tuned(&self, new: &EmtParams) -> EmtParams {
        let mut p = *self;
        p.pll.kp = new.pll.kp;
        p.pll.ki = new.pll.ki;
        p.qpi = new.qpi;
        p.vq_tau = new.vq_tau;
        p.vi_r = new.vi_r;
        p.inner = new.inner;
        p.source.deload = new.source.deload;
        p.source.p_avail0 = new.source.p_avail0;
        p.source.avail_t = new.source.avail_t;
        p.source.avail_dp = new.source.avail_dp;
        p
    }
}
