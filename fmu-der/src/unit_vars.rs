//! The variables both DER controllers declare alike (the phasor `Der` and the EMT-level `DerEmt`): rating and bases, mode and `T_des`, the PLL, the dc side, the primary source, the operator's dc gains.

use crate::{err, ports, Mode, UnitDefaults, MAX_LPF};
use dvpp_controllers::layer::TDesParams;
use dvpp_controllers::{DcLinkParams, OperatorGains, PllParams, Rating, SourceParams};
use fmi_export::{Boolean, Integer, Real, Spec, Variables};
use fmi_export::{ModelError, Store};
use serde::{Deserialize, Serialize};

pub(crate) fn par(
    v: &mut Variables,
    name: &str,
    start: f64,
    unit: &str,
    desc: &str,
    min: f64,
) -> Real {
    v.real(Spec::parameter(name, start, unit, desc).min(min))
}

/// A parameter a host may retune between steps (gains, limits, set points; structure stays fixed).
pub(crate) fn tun(
    v: &mut Variables,
    name: &str,
    start: f64,
    unit: &str,
    desc: &str,
    min: f64,
) -> Real {
    v.real(Spec::parameter(name, start, unit, desc).min(min).tunable())
}

/// Rating, bases, mode and `T_des`.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub(crate) struct UnitVars {
    pub(crate) s_rated: Real,
    pub(crate) s_base: Real,
    pub(crate) s_dvpp: Real,
    pub(crate) f_nom: Real,
    pub(crate) mode: Integer,
    pub(crate) h: Real,
    pub(crate) d: Real,
    pub(crate) dq: Real,
    pub(crate) tau_q: Real,
}

impl UnitVars {
    pub(crate) fn declare(v: &mut Variables, u: &UnitDefaults) -> Self {
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
                u.mode.code(),
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
        UnitVars {
            s_rated,
            s_base,
            s_dvpp,
            f_nom,
            mode,
            h,
            d,
            dq,
            tau_q,
        }
    }

    pub(crate) fn rating(&self, s: &Store) -> Rating {
        Rating {
            s_rated: s[self.s_rated],
            s_base: s[self.s_base],
            s_dvpp: s[self.s_dvpp],
            f_nom: s[self.f_nom],
        }
    }

    /// The `mode` code's mode, or the error naming it.
    pub(crate) fn mode(&self, s: &Store) -> Result<Mode, ModelError> {
        Mode::from_code(s[self.mode]).map_err(|e| err("mode", e))
    }

    pub(crate) fn tdes(&self, s: &Store) -> TDesParams {
        TDesParams {
            h: s[self.h],
            d: s[self.d],
            dq: s[self.dq],
            tau_q: s[self.tau_q],
        }
    }
}

/// The PLL's gains and the grid-following references' roll-off.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub(crate) struct PllVars {
    pub(crate) kp: Real,
    pub(crate) ki: Real,
    pub(crate) tau: Real,
    pub(crate) order: Integer,
}

impl PllVars {
    pub(crate) fn declare(v: &mut Variables) -> Self {
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
        PllVars {
            kp: pll_kp,
            ki: pll_ki,
            tau: pll_tau,
            order: pll_order,
        }
    }

    pub(crate) fn read(&self, s: &Store) -> PllParams {
        PllParams {
            kp: s[self.kp],
            ki: s[self.ki],
            tau: s[self.tau],
            order: s[self.order] as u32,
        }
    }
}

/// The dc side: source lag, link, dc-voltage control.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub(crate) struct DcVars {
    pub(crate) tau_dc: Real,
    pub(crate) c_dc: Real,
    pub(crate) g_dc: Real,
    pub(crate) k_dc: Real,
    pub(crate) zeta: Real,
}

impl DcVars {
    pub(crate) fn declare(v: &mut Variables, u: &UnitDefaults) -> Self {
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
        DcVars {
            tau_dc,
            c_dc,
            g_dc,
            k_dc,
            zeta: dc_zeta,
        }
    }

    pub(crate) fn read(&self, s: &Store) -> DcLinkParams {
        DcLinkParams {
            tau_dc: s[self.tau_dc],
            c_dc: s[self.c_dc],
            g_dc: s[self.g_dc],
            k_dc: s[self.k_dc],
            zeta: s[self.zeta],
        }
    }
}

/// The primary source: storage or not, deloading, availability and its step.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub(crate) struct SourceVars {
    pub(crate) storage: Boolean,
    pub(crate) deload: Real,
    pub(crate) p_avail0: Real,
    pub(crate) avail_t: Real,
    pub(crate) avail_dp: Real,
}

impl SourceVars {
    pub(crate) fn declare(v: &mut Variables, u: &UnitDefaults) -> Self {
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
        SourceVars {
            storage,
            deload,
            p_avail0,
            avail_t,
            avail_dp,
        }
    }

    pub(crate) fn read(&self, s: &Store) -> SourceParams {
        SourceParams {
            storage: s[self.storage],
            deload: s[self.deload],
            p_avail0: s[self.p_avail0],
            avail_t: s[self.avail_t],
            avail_dp: s[self.avail_dp],
        }
    }
}

/// The operator's dc gains (inputs).
#[derive(Clone, Serialize, Deserialize)]
pub(crate) struct GainVars {
    pub(crate) mu_p: Real,
    pub(crate) mu_q: Real,
    pub(crate) mu_p_lpf: Vec<Real>,
}

impl GainVars {
    pub(crate) fn declare(v: &mut Variables, u: &UnitDefaults) -> Self {
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
        GainVars {
            mu_p,
            mu_q,
            mu_p_lpf,
        }
    }

    pub(crate) fn read(&self, s: &Store) -> OperatorGains {
        let mut mu_p_lpf = [0.0; MAX_LPF];
        for (o, &r) in mu_p_lpf.iter_mut().zip(&self.mu_p_lpf) {
            *o = s[r];
        }
        OperatorGains {
            mu_p: s[self.mu_p],
            mu_q: s[self.mu_q],
            mu_p_lpf,
        }
    }
}
