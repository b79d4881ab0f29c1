//! The grid-following step: a PLL measures `Δf`, the converter injects `p₀ - T_fp Δf` and `q₀ - T_vq Δv`.

use super::common::{pll_model, Common, Outcome, StepPoint};
use super::{limits, Held, PhasorParams};
use crate::{layer, Error, Notice};
use dvpp_control::{GflFpModel, LtiSimulator};
use serde::{Deserialize, Serialize};

/// The grid-following controller state.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Following {
    pub(crate) fp: GflFpModel,
    /// PLL: states `[∫e, θ_pll]`, input `v_angle`, outputs `[Δf_pll, θ_pll]`.
    pub(crate) pll: LtiSimulator,
    /// The converter's active and reactive currents (pu of the rated current), following
    /// their commands with the lag `current.tau`.
    pub(crate) current: (f64, f64),
    /// The voltage deviation the v-q droop sees, through the lag `vq.tau`.
    pub(crate) dv: f64,
    /// The PLL gains its model was built with (tunable: rebuilt when they change).
    pub(crate) gains: (f64, f64),
}

impl Following {
    /// The grid-following controls over one step: the references, the converter's currents
    /// within the limits, and the PLL.
    pub(crate) fn step(
        &mut self,
        rt: &mut Common,
        p: &PhasorParams,
        out: &mut Held,
        at: &StepPoint,
        notices: &mut Vec<Notice>,
    ) -> Result<Outcome, Error> {
        let g = self;
        let StepPoint {
            t,
            h,
            dv,
            to_dvpp,
            to_rated,
            p_set,
            lpf,
            v,
            v_angle,
            budget,
            i_max,
            mu_p,
        } = *at;
        let n_lpf = p.adpf_p.n_lpf();
        layer::set_p_gains(&mut g.fp, p.adpf_p.kind, mu_p, &lpf[..n_lpf])?;
        let dp = g.fp.step(rt.df_held, h) / to_dvpp;
        // The v-q droop of a current-injecting unit is a loop through the grid's
        // impedance with gain X_th/Dq (about 10 at bus 2 for Dq = 0.01): stable only
        // behind a dominant lag, the plant's voltage control (`vq.tau`).
        let tau_v = p.stage.vq_tau;
        let kv = if tau_v > 0.0 {
            -dvpp_math::expm1(-h / tau_v)
        } else {
            1.0
        };
        g.dv += kv * (dv - g.dv);
        let dq = rt.vq.step(g.dv, h) / to_dvpp;
        // Rotational control: dp, dq are changes of p', q' about the rotated set point;
        // the converter's references are their back-rotation (the identity at rot.rx = 0).
        let (p_set_rot, q_set_rot) = rt.rot.rotate(p_set, rt.q0);
        let (p_cmd, q_cmd) = rt.rot.unrotate(p_set_rot + dp, q_set_rot + dq);
        // References as currents at the measured voltage, limited, and back.
        let vm = v.max(limits::V_FLOOR) / to_rated;
        let wanted = (p_cmd / vm, q_cmd / vm);
        let ((ip, iq), cur, dcl) =
            limits::saturate_following(wanted, v, i_max, budget, p.stage.priority);
        // The converter's currents follow their commands with the lag `current.tau`
        // (its inner current control and the plant's response): an injection that moved
        // at once would close a loop through the bus angle and the PLL, and through the
        // bus voltage and the v-q droop, that a one-step exchange delay makes oscillate
        // from one step to the next.
        let tau = p.stage.current_tau;
        let k = if tau > 0.0 {
            -dvpp_math::expm1(-h / tau)
        } else {
            1.0
        };
        g.current.0 += k * (ip - g.current.0);
        g.current.1 += k * (iq - g.current.1);
        // The limits hold for the current itself, also while it follows its command.
        let (held, _, _) =
            limits::saturate_following(g.current, v, i_max, budget, p.stage.priority);
        g.current = held;
        out.p_ref = g.current.0 * vm;
        out.q_ref = g.current.1 * vm;
        let gains = (p.pll.kp, p.pll.ki);
        if gains != g.gains {
            g.pll
                .set_system(pll_model(gains.0, gains.1, p.rating.f_nom))
                .expect("PLL order");
            g.gains = gains;
            notices.push(Notice::Event(format!(
                "PLL gains retuned at t = {t}: kp = {}, ki = {}",
                gains.0, gains.1
            )));
        }
        let y = g.pll.step_all(v_angle, h);
        rt.df_held = y[0];
        out.df = y[0];
        out.theta = y[1];
        Ok(Outcome {
            current_limit: cur,
            dc_limit: dcl,
            request: dvpp_math::hypot(wanted.0, wanted.1) / i_max,
            modulation: false,
        })
    }
}
