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

/// A parameter's value as a host sets it by name (the FMU's types: Real, Integer, Boolean).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum ParamValue {
    Real(f64),
    Integer(i32),
    Boolean(bool),
}

impl EmtParams {
    /// Every parameter with the name the `dvpp_der_emt` FMU gives it, in the FMU's order of
    /// declaration: what a host sets to run the FMU as this unit.
    pub fn named(&self) -> Vec<(String, ParamValue)> {
        use ParamValue::{Boolean, Integer, Real};
        let mut out: Vec<(String, ParamValue)> = Vec::new();
        let mut put = |name: &str, v: ParamValue| out.push((name.to_string(), v));
        let r = &self.rating;
        put("S_rated", Real(r.s_rated));
        put("S_base", Real(r.s_base));
        put("S_dvpp", Real(r.s_dvpp));
        put("f_nom", Real(r.f_nom));
        put("mode", Integer(self.mode.code()));
        put("Tdes.H", Real(self.tdes.h));
        put("Tdes.D", Real(self.tdes.d));
        put("Tdes.Dq", Real(self.tdes.dq));
        put("Tdes.tau_q", Real(self.tdes.tau_q));
        for a in [&self.adpf_p, &self.adpf_q] {
            let n = |field: &str| a.name(field);
            put(&n("kind"), Integer(a.kind.code()));
            put(&n("tau"), Real(a.tau));
            put(&n("tau2"), Real(a.tau2));
            put(&n("order"), Integer(a.order as i32));
            put(&n("order2"), Integer(a.order2 as i32));
            if let Some(c) = &a.complement {
                put(&n("share"), Real(c.share));
                put(&n("n_lpf"), Integer(c.n_lpf as i32));
                for k in 0..c.lpf_tau.len() {
                    put(&n(&format!("lpf[{}].tau", k + 1)), Real(c.lpf_tau[k]));
                    put(
                        &n(&format!("lpf[{}].order", k + 1)),
                        Integer(c.lpf_order[k] as i32),
                    );
                }
            }
        }
        put("pll.kp", Real(self.pll.kp));
        put("pll.ki", Real(self.pll.ki));
        put("pll.tau", Real(self.pll.tau));
        put("pll.order", Integer(self.pll.order as i32));
        put("qpi.kp", Real(self.qpi.kp));
        put("qpi.ki", Real(self.qpi.ki));
        put("E_max", Real(self.qpi.e_max));
        put("vq.tau", Real(self.vq_tau));
        let f = &self.filter;
        put("R_f", Real(f.r_f));
        put("L_f", Real(f.l_f));
        put("C_f", Real(f.c_f));
        put("R_t", Real(f.r_t));
        put("L_t", Real(f.l_t));
        put("vdc_ratio", Real(self.vdc_ratio));
        put("vi.r", Real(self.vi_r));
        put("inner.current_hz", Real(self.inner.current_hz));
        put("inner.voltage_hz", Real(self.inner.voltage_hz));
        put("inner.zero_ratio", Real(self.inner.zero_ratio));
        put("I_max", Real(self.inner.i_max));
        put("t_s", Real(self.t_s));
        let d = &self.dc;
        put("tau_dc", Real(d.tau_dc));
        put("C_dc", Real(d.c_dc));
        put("G_dc", Real(d.g_dc));
        put("k_dc", Real(d.k_dc));
        put("dc.zeta", Real(d.zeta));
        let s = &self.source;
        put("storage", Boolean(s.storage));
        put("deload", Real(s.deload));
        put("P_avail0", Real(s.p_avail0));
        put("avail.t_step", Real(s.avail_t));
        put("avail.dP", Real(s.avail_dp));
        put("inner.kind", Integer(self.inner_kind.code()));
        out
    }
}
