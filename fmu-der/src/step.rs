//! One communication step: set point, dc gains, the channel's step, limit episodes, dc side, startup.

use crate::common::{Outcome, Startup, StepPoint};
use crate::runtime::{Channel, Runtime};
use crate::{layer, Der};
use fmi_export::{Context, ModelError, Store};

/// Below this terminal voltage (pu) a grid-following unit's PLL has no angle to lock to: the
/// unit loses synchronism and blocks (a grid-forming unit keeps forming its voltage).
const PLL_V_MIN: f64 = 0.05;

impl Der {
    pub(crate) fn step(
        &self,
        rt: &mut Runtime,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        let following = matches!(rt.channel, Channel::Following(_));
        if following && rt.common.startup.is_none() && s[self.v] < PLL_V_MIN {
            // The PLL has no voltage to lock to: the unit has lost synchronism. It blocks its
            // current and waits for the voltage as at a start from zero voltage.
            rt.common.startup = Some(Startup {
                ok_since: None,
                v_last: s[self.v],
            });
            s[self.synchronized] = false;
            ctx.warn(format!(
                "t = {t:.4} s: terminal voltage {:.4} pu: the PLL has no voltage to lock to; lost synchronism, the current is blocked until the voltage returns above startup.v_sync",
                s[self.v]
            ));
        }
        if rt.common.startup.is_some() && !self.wait_for_voltage(rt, s, t, h, ctx) {
            self.step_dc(rt, s, t, h, ctx);
            return Ok(());
        }
        let to_dvpp = s[self.s_base] / s[self.s_dvpp];
        let to_rated = s[self.s_base] / s[self.s_rated];
        let dv = s[self.v] - rt.common.v0;
        let lpf = self.lpf_gains(s);
        // Dc gains from the operator (the participation bank identity holds while they move).
        let share = self.adpf_p.share.map_or(1.0, |r| s[r]);
        let c = &mut rt.common;
        let lpf = layer::operator_gains(
            &mut c.vq,
            c.q_kind,
            s[self.mu_q],
            c.p_kind,
            lpf,
            c.n_lpf,
            share,
            &mut c.warned_gains,
            &mut |n| crate::log(ctx, n),
        )?;
        // The set point: the dispatch (ramped in after a start from zero voltage), curtailed to
        // what the primary source allows (a cloud lowers it).
        let ramp = rt.common.t_sync.map_or(1.0, |t0| {
            let r = s[self.ramp];
            if r > 0.0 {
                ((t + h - t0) / r).min(1.0)
            } else {
                1.0
            }
        });
        let dispatch = rt.common.p0 + s[self.redispatch];
        let p_set = (dispatch * ramp).min(self.headroom_limit(s, t));
        s[self.p_set] = p_set;
        let (v, v_angle) = (s[self.v], s[self.v_angle]);
        let budget = rt.common.dc.ac_budget();
        let i_max = s[self.i_max];
        let at = StepPoint {
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
        };
        let Outcome {
            current_limit,
            dc_limit,
            request,
            modulation,
        } = match &mut rt.channel {
            Channel::Forming(f) => self.step_forming(f, &mut rt.common, s, &at)?,
            Channel::Following(g) => self.step_following(g, &mut rt.common, s, &at, ctx)?,
        };
        let lim = &mut rt.common.limit;
        let t1 = t + h;
        lim.current
            .record(t1, current_limit, request, || "current limit I_max", ctx);
        let (lo, hi) = budget;
        lim.dc.record(
            t1,
            dc_limit,
            rt.common.dc.v_dc(),
            || format!("dc-link power budget [{lo:.3}, {hi:.3}] pu (v_dc)"),
            ctx,
        );
        lim.modulation.record(
            t1,
            modulation,
            s[self.e_max] * rt.common.dc.v_dc(),
            || "modulation limit E_max * v_dc",
            ctx,
        );
        self.step_dc(rt, s, t, h, ctx);
        Ok(())
    }

    /// The primary source and the dc link over the step, and the outputs that report them.
    pub(crate) fn step_dc(
        &self,
        rt: &mut Runtime,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) {
        s[self.p_avail] = self.available(s, t + h);
        let to_rated = s[self.s_base] / s[self.s_rated];
        let (r, _) = self.slot_impedance(s);
        let p_ac = self.converter_power(s, r, rt.channel.mode());
        let cap = s[self.p_avail] * to_rated;
        let dc = rt.common.dc.step(p_ac, h, cap);
        rt.common
            .dc
            .update_reserve(rt.common.limit.dc.active(), cap);
        rt.common.limit.source.record(
            t + h,
            dc.source,
            rt.common.dc.p_src(),
            || format!("primary source at its limit (P_avail = {cap:.4} pu on S_rated)"),
            ctx,
        );
        self.write_dc(s, rt);
        self.write_limits(s, rt);
        self.write_rotated(s, rt);
    }

    /// A unit started below `startup.v_sync`: zero current until the voltage has been above
    /// it and steady for `startup.t_hold`; then it takes the measured voltage as its operating
    /// point and synchronizes (returns true from that step on).
    pub(crate) fn wait_for_voltage(
        &self,
        rt: &mut Runtime,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) -> bool {
        let (v, v_angle) = (s[self.v], s[self.v_angle]);
        let st = rt.common.startup.as_mut().expect("waiting");
        let steady = h > 0.0 && ((v - st.v_last) / h).abs() < 0.5;
        st.v_last = v;
        if v >= s[self.v_sync] && steady {
            let since = *st.ok_since.get_or_insert(t);
            if t + h - since >= s[self.t_hold] {
                rt.common.startup = None;
                rt.common.t_sync = Some(t);
                rt.common.v0 = v;
                rt.common.theta0 = v_angle;
                rt.common.e0 = v;
                match &mut rt.channel {
                    Channel::Forming(f) => {
                        f.e = v;
                        f.theta = v_angle;
                    }
                    Channel::Following(g) => {
                        g.pll
                            .set_state(&[0.0, v_angle], v_angle)
                            .expect("PLL state");
                        g.current = (0.0, 0.0);
                    }
                }
                s[self.synchronized] = true;
                ctx.event(format!(
                    "synchronized at t = {t:.4} s to v = {v:.4} pu; the set point ramps to {:.4} pu over {} s",
                    rt.common.p0,
                    s[self.ramp]
                ));
                return true;
            }
        } else {
            st.ok_since = None;
        }
        // Zero current: the converter follows the terminal voltage (grid-forming) or injects
        // nothing (grid-following).
        s[self.e] = v;
        s[self.theta] = v_angle;
        s[self.df] = 0.0;
        s[self.p_ref] = 0.0;
        s[self.q_ref] = 0.0;
        s[self.p_set] = 0.0;
        false
    }
}
