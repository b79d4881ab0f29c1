//! Excitation-system models: case data, validation, states, initialization and derivatives.
//!
//! Every model is one variant of [`Exciter`]; all that the grid needs of it (state count,
//! initialization, field voltage, derivatives, limits, time constants) is in this file, so a new
//! model is added here alone. Voltages are in pu, the field voltage on the machine's E_fd base.
//! A stabilizer's output `vs` adds to every model's voltage error `vref − vt`.

use crate::error::{check_range, nonneg, pos, CaseError};
use crate::numerics::{limited, TimeConstant};
use serde::{Deserialize, Serialize};

/// Excitation system (voltage regulator), on the machine's field-voltage pu.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Exciter {
    /// Simplified exciter: lead-lag (ta_tb·t_b s + 1)/(t_b s + 1), then k/(t_e s + 1), limited.
    Sexs {
        k: f64,
        ta_tb: f64,
        t_b: f64,
        t_e: f64,
        #[serde(default = "default_emin")]
        e_min: f64,
        #[serde(default = "default_emax")]
        e_max: f64,
    },
    /// IEEE type 1 (DC exciter with rate feedback); saturation S_E = se_a·exp(se_b·E_fd).
    IeeeT1 {
        ka: f64,
        ta: f64,
        ke: f64,
        te: f64,
        kf: f64,
        tf: f64,
        #[serde(default)]
        se_a: f64,
        #[serde(default)]
        se_b: f64,
        #[serde(default = "default_emin")]
        vr_min: f64,
        #[serde(default = "default_emax")]
        vr_max: f64,
    },
    /// IEEE 421.5 ST1A static exciter (potential-source, controlled rectifier), with K_C = 0 and
    /// no field-current limiter: transducer 1/(t_r s + 1); error vref − V_m + V_s − V_F limited to
    /// [vi_min, vi_max]; lead-lags (t_c s + 1)/(t_b s + 1) and (t_c1 s + 1)/(t_b1 s + 1); gain
    /// k_a/(t_a s + 1) limited to [va_min, va_max]; field voltage limited to
    /// [V_t vr_min, V_t vr_max]; rate feedback V_F = k_f s/(t_f s + 1) E_fd. A lead-lag with
    /// t_b = 0 (t_b1 = 0) is bypassed, t_a = 0 makes the gain algebraic (then k_f must be 0).
    St1a {
        tr: f64,
        #[serde(default)]
        tc: f64,
        #[serde(default)]
        tb: f64,
        #[serde(default)]
        tc1: f64,
        #[serde(default)]
        tb1: f64,
        ka: f64,
        #[serde(default)]
        ta: f64,
        #[serde(default)]
        kf: f64,
        #[serde(default = "default_tf")]
        tf: f64,
        #[serde(default = "default_emin")]
        vi_min: f64,
        #[serde(default = "default_emax")]
        vi_max: f64,
        #[serde(default = "default_emin")]
        va_min: f64,
        #[serde(default = "default_emax")]
        va_max: f64,
        #[serde(default = "default_emin")]
        vr_min: f64,
        #[serde(default = "default_emax")]
        vr_max: f64,
    },
}

fn default_tf() -> f64 {
    1.0
}

fn default_emin() -> f64 {
    -10.0
}
fn default_emax() -> f64 {
    10.0
}

/// States of `sexs`, relative to the exciter's first state.
mod sexs {
    /// Lag state of the lead-lag.
    pub const LEAD_LAG: usize = 0;
    /// Field voltage, limited.
    pub const EFD: usize = 1;
    pub const N: usize = 2;
}

/// States of `ieee_t1`, relative to the exciter's first state.
mod ieee_t1 {
    /// Field voltage (exciter output).
    pub const EFD: usize = 0;
    /// Regulator output, limited.
    pub const VR: usize = 1;
    /// Rate-feedback state.
    pub const RF: usize = 2;
    pub const N: usize = 3;
}

/// States of `st1a`, relative to the exciter's first state. A state whose block is bypassed
/// (time constant 0) stays at rest.
mod st1a {
    /// Transducer output V_m.
    pub const VM: usize = 0;
    /// Lag state of the first lead-lag.
    pub const LL1: usize = 1;
    /// Lag state of the second lead-lag.
    pub const LL2: usize = 2;
    /// Regulator output V_A, limited.
    pub const VA: usize = 3;
    /// Rate-feedback lag state.
    pub const RF: usize = 4;
    pub const N: usize = 5;
}

/// ST1A's internal signals at one point (see `Exciter::st1a_signals`).
#[derive(Clone, Copy, Debug, Default)]
struct St1aSignals {
    err: f64,
    y1: f64,
    y2: f64,
    va: f64,
    efd: f64,
}

/// Output of the lead-lag (t_c s + 1)/(t_b s + 1) with lag state `z` and input `u`
/// (`u` itself when t_b = 0: bypassed).
fn lead_lag(u: f64, z: f64, tc: f64, tb: f64) -> f64 {
    if tb > 0.0 {
        z + tc / tb * (u - z)
    } else {
        u
    }
}

/// Derivative of a lead-lag's lag state (0 when bypassed).
fn lead_lag_deriv(u: f64, z: f64, tb: f64) -> f64 {
    if tb > 0.0 {
        (u - z) / tb
    } else {
        0.0
    }
}

impl Exciter {
    /// Number of states the model keeps.
    pub(crate) fn n_states(&self) -> usize {
        match self {
            Exciter::Sexs { .. } => sexs::N,
            Exciter::IeeeT1 { .. } => ieee_t1::N,
            Exciter::St1a { .. } => st1a::N,
        }
    }

    /// ST1A's signals for reference `vref`, terminal voltage `vt`, stabilizer output `vs` and
    /// states `x`: the limited error and the two lead-lags' outputs, V_A and E_fd.
    fn st1a_signals(&self, vref: f64, vt: f64, vs: f64, x: &[f64]) -> St1aSignals {
        let Exciter::St1a {
            tc,
            tb,
            tc1,
            tb1,
            ka,
            ta,
            kf,
            tf,
            vi_min,
            vi_max,
            va_min,
            va_max,
            vr_min,
            vr_max,
            ..
        } = *self
        else {
            return St1aSignals::default();
        };
        let field = |va: f64| va.clamp(vt * vr_min, vt * vr_max);
        // With t_a > 0, V_A is a state and E_fd (hence the rate feedback) follows from it.
        let vf_of = |efd: f64| kf / tf * (efd - x[st1a::RF]);
        let vf = if ta > 0.0 {
            vf_of(field(x[st1a::VA]))
        } else {
            0.0
        };
        let err = (vref - x[st1a::VM] + vs - vf).clamp(vi_min, vi_max);
        let y1 = lead_lag(err, x[st1a::LL1], tc, tb);
        let y2 = lead_lag(y1, x[st1a::LL2], tc1, tb1);
        let va = if ta > 0.0 {
            x[st1a::VA]
        } else {
            (ka * y2).clamp(va_min, va_max)
        };
        St1aSignals {
            err,
            y1,
            y2,
            va,
            efd: field(va),
        }
    }

    /// Check the parameters; `el` names the machine in errors.
    pub(crate) fn validate(&self, el: &str) -> Result<(), CaseError> {
        match self {
            Exciter::Sexs {
                k,
                ta_tb,
                t_b,
                t_e,
                e_min,
                e_max,
            } => {
                pos(el, "exciter.k", *k)?;
                nonneg(el, "exciter.ta_tb", *ta_tb)?;
                pos(el, "exciter.t_b", *t_b)?;
                pos(el, "exciter.t_e", *t_e)?;
                check_range(el, "exciter.e_max", *e_max, e_max > e_min, "> e_min")
            }
            Exciter::IeeeT1 {
                ka,
                ta,
                ke,
                te,
                kf,
                tf,
                se_a,
                se_b,
                vr_min,
                vr_max,
            } => {
                pos(el, "exciter.ka", *ka)?;
                pos(el, "exciter.ta", *ta)?;
                nonneg(el, "exciter.ke", *ke)?;
                pos(el, "exciter.te", *te)?;
                nonneg(el, "exciter.kf", *kf)?;
                pos(el, "exciter.tf", *tf)?;
                nonneg(el, "exciter.se_a", *se_a)?;
                nonneg(el, "exciter.se_b", *se_b)?;
                check_range(el, "exciter.vr_max", *vr_max, vr_max > vr_min, "> vr_min")
            }
            Exciter::St1a {
                tr,
                tc,
                tb,
                tc1,
                tb1,
                ka,
                ta,
                kf,
                tf,
                vi_min,
                vi_max,
                va_min,
                va_max,
                vr_min,
                vr_max,
            } => {
                pos(el, "exciter.tr", *tr)?;
                for (name, v) in [
                    ("tc", tc),
                    ("tb", tb),
                    ("tc1", tc1),
                    ("tb1", tb1),
                    ("ta", ta),
                ] {
                    nonneg(el, &format!("exciter.{name}"), *v)?;
                }
                pos(el, "exciter.ka", *ka)?;
                nonneg(el, "exciter.kf", *kf)?;
                pos(el, "exciter.tf", *tf)?;
                let bypassed = |tc: f64, tb: f64| tb > 0.0 || tc == 0.0;
                check_range(el, "exciter.tc", *tc, bypassed(*tc, *tb), "0 when tb = 0")?;
                check_range(
                    el,
                    "exciter.tc1",
                    *tc1,
                    bypassed(*tc1, *tb1),
                    "0 when tb1 = 0",
                )?;
                check_range(
                    el,
                    "exciter.kf",
                    *kf,
                    *ta > 0.0 || *kf == 0.0,
                    "0 when ta = 0",
                )?;
                check_range(el, "exciter.vi_max", *vi_max, vi_max > vi_min, "> vi_min")?;
                check_range(el, "exciter.va_max", *va_max, va_max > va_min, "> va_min")?;
                check_range(el, "exciter.vr_max", *vr_max, vr_max > vr_min, "> vr_min")
            }
        }
    }

    /// The time constants of the model's states (what the integration step must resolve);
    /// `prefix` names the machine, e.g. `machine[2]`.
    pub(crate) fn time_constants(&self, prefix: &str) -> Vec<TimeConstant> {
        let tc = |p: &str, v: f64| TimeConstant::new(format!("{prefix}.exciter.{p}"), v);
        match self {
            Exciter::Sexs { t_b, t_e, .. } => vec![tc("t_b", *t_b), tc("t_e", *t_e)],
            Exciter::IeeeT1 { ta, te, tf, .. } => vec![tc("ta", *ta), tc("te", *te), tc("tf", *tf)],
            Exciter::St1a {
                tr,
                tb,
                tb1,
                ta,
                kf,
                tf,
                ..
            } => {
                let mut out = vec![tc("tr", *tr)];
                for (name, v) in [("tb", tb), ("tb1", tb1), ("ta", ta)] {
                    if *v > 0.0 {
                        out.push(tc(name, *v));
                    }
                }
                if *kf > 0.0 {
                    out.push(tc("tf", *tf));
                }
                out
            }
        }
    }

    /// Initialize the states `x` for the steady field voltage `efd` at terminal voltage `vt`
    /// and return the voltage reference that holds it.
    pub(crate) fn init(&self, efd: f64, vt: f64, x: &mut [f64]) -> Result<f64, String> {
        match self {
            Exciter::Sexs {
                k, e_min, e_max, ..
            } => {
                if efd > *e_max || efd < *e_min {
                    return Err(format!(
                        "initial field voltage {efd:.4} outside exciter limits"
                    ));
                }
                let u0 = efd / k;
                x[sexs::LEAD_LAG] = u0;
                x[sexs::EFD] = efd;
                Ok(vt + u0)
            }
            Exciter::IeeeT1 {
                ka,
                ke,
                kf,
                tf,
                se_a,
                se_b,
                vr_min,
                vr_max,
                ..
            } => {
                let se = se_a * dvpp_math::exp(se_b * efd);
                let vr = (ke + se) * efd;
                if vr > *vr_max || vr < *vr_min {
                    return Err(format!("initial regulator output {vr:.4} outside limits"));
                }
                x[ieee_t1::EFD] = efd;
                x[ieee_t1::VR] = vr;
                x[ieee_t1::RF] = kf / tf * efd;
                Ok(vt + vr / ka)
            }
            Exciter::St1a {
                ka,
                vi_min,
                vi_max,
                va_min,
                va_max,
                vr_min,
                vr_max,
                ..
            } => {
                if efd > vt * vr_max || efd < vt * vr_min {
                    return Err(format!(
                        "initial field voltage {efd:.4} outside the ST1A's limits \
                         [{:.4}, {:.4}] (vt times vr_min, vr_max)",
                        vt * vr_min,
                        vt * vr_max
                    ));
                }
                if efd > *va_max || efd < *va_min {
                    return Err(format!(
                        "initial regulator output {efd:.4} outside va limits"
                    ));
                }
                // At rest every lead-lag passes its input and the rate feedback is 0.
                let err = efd / ka;
                if err > *vi_max || err < *vi_min {
                    return Err(format!("initial voltage error {err:.4} outside vi limits"));
                }
                x[st1a::VM] = vt;
                x[st1a::LL1] = err;
                x[st1a::LL2] = err;
                x[st1a::VA] = efd;
                x[st1a::RF] = efd;
                Ok(vt + err)
            }
        }
    }

    /// Field voltage for reference `vref`, terminal voltage `vt` and stabilizer output `vs`
    /// (the ST1A's field limits scale with `vt`; its gain may be algebraic).
    pub(crate) fn efd(&self, vref: f64, vt: f64, vs: f64, x: &[f64]) -> f64 {
        match self {
            Exciter::Sexs { .. } => x[sexs::EFD],
            Exciter::IeeeT1 { .. } => x[ieee_t1::EFD],
            Exciter::St1a { .. } => self.st1a_signals(vref, vt, vs, x).efd,
        }
    }

    /// Derivatives `dx` of the states `x` for reference `vref`, terminal voltage `vt` and
    /// stabilizer output `vs`.
    pub(crate) fn deriv(&self, vref: f64, vt: f64, vs: f64, x: &[f64], dx: &mut [f64]) {
        match self {
            Exciter::Sexs {
                k,
                ta_tb,
                t_b,
                t_e,
                e_min,
                e_max,
            } => {
                let (ll, efd) = (x[sexs::LEAD_LAG], x[sexs::EFD]);
                let e = vref - vt + vs;
                dx[sexs::LEAD_LAG] = (e - ll) / t_b;
                let u = ll + ta_tb * (e - ll);
                dx[sexs::EFD] = limited((k * u - efd) / t_e, efd, *e_min, *e_max);
            }
            Exciter::IeeeT1 {
                ka,
                ta,
                ke,
                te,
                kf,
                tf,
                se_a,
                se_b,
                vr_min,
                vr_max,
            } => {
                let (efd, vr, rf) = (x[ieee_t1::EFD], x[ieee_t1::VR], x[ieee_t1::RF]);
                let se = se_a * dvpp_math::exp(se_b * efd);
                dx[ieee_t1::EFD] = (-(ke + se) * efd + vr) / te;
                let dvr = (-vr + ka * rf - ka * kf / tf * efd + ka * (vref - vt + vs)) / ta;
                dx[ieee_t1::VR] = limited(dvr, vr, *vr_min, *vr_max);
                dx[ieee_t1::RF] = (-rf + kf / tf * efd) / tf;
            }
            Exciter::St1a {
                tr,
                tb,
                tb1,
                ka,
                ta,
                kf,
                tf,
                va_min,
                va_max,
                ..
            } => {
                let sg = self.st1a_signals(vref, vt, vs, x);
                dx[st1a::VM] = (vt - x[st1a::VM]) / tr;
                dx[st1a::LL1] = lead_lag_deriv(sg.err, x[st1a::LL1], *tb);
                dx[st1a::LL2] = lead_lag_deriv(sg.y1, x[st1a::LL2], *tb1);
                dx[st1a::VA] = if *ta > 0.0 {
                    limited((ka * sg.y2 - sg.va) / ta, sg.va, *va_min, *va_max)
                } else {
                    0.0
                };
                dx[st1a::RF] = if *kf > 0.0 {
                    (sg.efd - x[st1a::RF]) / tf
                } else {
                    0.0
                };
            }
        }
    }

    /// Hold the limited states inside their limits (after an integration step).
    pub(crate) fn clamp(&self, x: &mut [f64]) {
        match self {
            Exciter::Sexs { e_min, e_max, .. } => x[sexs::EFD] = x[sexs::EFD].clamp(*e_min, *e_max),
            Exciter::IeeeT1 { vr_min, vr_max, .. } => {
                x[ieee_t1::VR] = x[ieee_t1::VR].clamp(*vr_min, *vr_max)
            }
            Exciter::St1a { va_min, va_max, .. } => {
                x[st1a::VA] = x[st1a::VA].clamp(*va_min, *va_max)
            }
        }
    }
}
