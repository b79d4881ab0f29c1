//! The per-instance runtime state: what `initialize` builds from the parameters, and its outputs.

use crate::common::{pll_model, Common, LimitEpisodes, Startup};
use crate::dc::{DcParams, DcSide};
use crate::following::Following;
use crate::forming::Forming;
use crate::layer::{self, PfReference};
use crate::limits;
use crate::{err, positive, Der, Mode, MAX_LPF};
use dvpp_control::phasor::internal_voltage;
use dvpp_control::{Hold, LtiSimulator, Rotation};
use fmi_export::{Context, ModelError, Store};
use serde::{Deserialize, Serialize};

#[derive(Clone, Serialize, Deserialize)]
pub(crate) enum Channel {
    Forming(Box<Forming>),
    Following(Box<Following>),
}

/// Everything `initialize` builds from the parameters.
#[derive(Clone, Serialize, Deserialize)]
pub struct Runtime {
    pub(crate) channel: Channel,
    pub(crate) common: Common,
}

impl Channel {
    /// The mode the channel realizes.
    pub(crate) fn mode(&self) -> Mode {
        match self {
            Channel::Forming(_) => Mode::GridForming,
            Channel::Following(_) => Mode::GridFollowing,
        }
    }
}

impl Der {
    pub(crate) fn lpf_gains(&self, s: &Store) -> [f64; MAX_LPF] {
        let mut out = [0.0; MAX_LPF];
        for (o, &r) in out.iter_mut().zip(&self.mu_p_lpf) {
            *o = s[r];
        }
        out
    }

    pub(crate) fn available(&self, s: &Store, t: f64) -> f64 {
        layer::availability(s[self.p_avail0], s[self.avail_t], s[self.avail_dp], t)
    }

    pub(crate) fn build(
        &self,
        s: &mut Store,
        ctx: &mut Context,
        again: Option<bool>,
    ) -> Result<Runtime, ModelError> {
        for (r, name) in [
            (self.s_rated, "S_rated"),
            (self.s_base, "S_base"),
            (self.s_dvpp, "S_dvpp"),
            (self.f_nom, "f_nom"),
            (self.x_f, "X_f"),
        ] {
            positive(s, r, name)?;
        }
        let tdes = crate::unit_vars::tdes(s, self.h, self.d, self.dq, self.tau_q)?;

        let lpf = self.lpf_gains(s);
        let adpf_p = self.adpf_p.build(s, s[self.mu_p], &lpf)?;
        let adpf_q = self.adpf_q.build(s, s[self.mu_q], &[])?;
        let p_kind = self.adpf_p.kind(s)?;

        let pll_tau = positive(s, self.pll_tau, "pll.tau")?;
        let pll_order = s[self.pll_order] as u32;
        let mode = Mode::from_code(s[self.mode]).map_err(|e| err("mode", e))?;
        let (reference, vq) = layer::reference_models(&layer::ReferenceSpec {
            mode,
            tdes: &tdes,
            adpf_p: &adpf_p,
            adpf_q: &adpf_q,
            params_p: &self.adpf_p.read(s)?,
            params_q: &self.adpf_q.read(s)?,
            s_rated: s[self.s_rated],
            s_dvpp: s[self.s_dvpp],
            pll_tau,
            pll_order,
        })?;
        let channel = match reference {
            PfReference::Forming(pf) => Channel::Forming(Box::new(Forming {
                pf,
                e_int: 0.0,
                e: 0.0,
                theta: 0.0,
                dtheta: 0.0,
                dtheta_mean: 0.0,
            })),
            PfReference::Following(fp) => {
                let (kp, ki) = (s[self.pll_kp], s[self.pll_ki]);
                if !(kp > 0.0 && ki > 0.0) {
                    return Err(err(
                        "pll.kp",
                        format!("PLL gains kp = {kp}, ki = {ki} must be > 0"),
                    ));
                }
                let mut pll = LtiSimulator::new(pll_model(kp, ki, s[self.f_nom]), Hold::Zero);
                pll.set_state(&[0.0, s[self.v_angle]], s[self.v_angle])
                    .expect("PLL state");
                Channel::Following(Box::new(Following {
                    fp,
                    pll,
                    current: (0.0, 0.0),
                    dv: 0.0,
                    gains: (kp, ki),
                }))
            }
        };

        let dc = self.dc_params(s)?;
        if again.is_none() {
            ctx.event(format!(
                "dc-voltage control: damping ratio {:.3} without the capacitor-power term, {:.3} with k_d = {:.3}",
                dc.damping(0.0),
                dc.damping(dc.k_d()),
                dc.k_d()
            ));
        }
        positive(s, self.i_max, "I_max")?;
        positive(s, self.e_max, "E_max")?;

        // Operating point and the internal voltage behind the transformer (the slot impedance).
        let (r, x) = self.slot_impedance(s);
        let (p, q, v) = (s[self.p], s[self.q], s[self.v]);
        // Below `startup.v_sync` the unit waits for the voltage (a start from zero voltage).
        let waiting = v < s[self.v_sync];
        // A grid-forming unit's controls set the voltage behind its virtual resistance too.
        let r_v = match mode {
            Mode::GridForming => self.virtual_resistance(s),
            Mode::GridFollowing => 0.0,
        };
        let (e0, theta0) = if waiting {
            (v, s[self.v_angle])
        } else {
            internal_voltage(p, q, v, s[self.v_angle], r + r_v, x)
        };
        let (e_out, theta_out) = if waiting || r_v == 0.0 {
            (e0, theta0)
        } else {
            internal_voltage(p, q, v, s[self.v_angle], r, x)
        };
        let p_ac = if waiting {
            0.0
        } else {
            self.converter_power(s, r, mode)
        };
        let rot = Rotation::from_rx(s[self.rot_rx]).map_err(|e| err("rot.rx", e))?;
        let common = Common {
            vq,
            dc: DcSide::new(dc, p_ac),
            p_kind,
            n_lpf: self.adpf_p.n_lpf.map_or(0, |n| s[n] as usize),
            q_kind: self.adpf_q.kind(s)?,
            p0: p,
            q0: if waiting { 0.0 } else { q },
            v0: v,
            e0,
            theta0,
            df_held: 0.0,
            q_ref: if waiting { 0.0 } else { rot.rotate(p, q).1 },
            rot,
            withheld: (0.0, 0.0),
            startup: waiting.then_some(Startup {
                ok_since: None,
                v_last: v,
            }),
            t_sync: None,
            limit: LimitEpisodes::default(),
            warned_gains: again.unwrap_or(false),
        };
        let mut rt = Runtime { channel, common };
        match &mut rt.channel {
            Channel::Forming(f) => {
                f.e = e0;
                f.theta = theta0;
            }
            Channel::Following(g) if !waiting => {
                let to_rated = s[self.s_base] / s[self.s_rated];
                g.current = (p * to_rated / v, q * to_rated / v);
            }
            Channel::Following(_) => {}
        }
        s[self.theta] = match &rt.channel {
            Channel::Forming(_) => theta_out,
            Channel::Following(_) => s[self.v_angle],
        };
        s[self.e] = e_out;
        s[self.df] = 0.0;
        s[self.p_ref] = if waiting { 0.0 } else { p };
        s[self.p_set] = s[self.p_ref];
        s[self.q_ref] = if waiting { 0.0 } else { q };
        s[self.p_avail] = self.available(s, 0.0);
        s[self.synchronized] = !waiting;
        if waiting && again.is_none() {
            ctx.event(format!(
                "v = {v:.4} pu < startup.v_sync = {:.4} pu: waiting for the terminal voltage",
                s[self.v_sync]
            ));
        }
        let limit = self.headroom_limit(s, 0.0);
        if p > limit + 1e-12 && again.is_none() {
            ctx.warn(format!(
                "dispatch p = {p:.4} pu is above deload * P_avail - G_dc = {limit:.4} pu: the set point is curtailed from the first step"
            ));
        }
        self.write_dc(s, &rt);
        self.write_limits(s, &rt);
        self.write_rotated(s, &rt);
        Ok(rt)
    }

    /// The dc side's parameters, checked.
    pub(crate) fn dc_params(&self, s: &Store) -> Result<DcParams, ModelError> {
        let tau = positive(s, self.tau_dc, "tau_dc")?;
        let c = positive(s, self.c_dc, "C_dc")?;
        let t_budget = positive(s, self.t_budget, "dc.t_budget")?;
        let (v_min, v_max) = (s[self.v_dc_min], s[self.v_dc_max]);
        if !((0.0..1.0).contains(&v_min) && v_max > 1.0) {
            return Err(err(
                "v_dc_min",
                format!("= {v_min} with v_dc_max = {v_max}: needs 0 <= v_dc_min < 1 < v_dc_max"),
            ));
        }
        Ok(DcParams {
            tau,
            c,
            g: s[self.g_dc],
            k_dc: s[self.k_dc],
            zeta: s[self.dc_zeta],
            storage: s[self.storage],
            v_min,
            v_max,
            t_budget,
        })
    }

    /// The slot impedance `R_f + j X_f` on S_base.
    pub(crate) fn slot_impedance(&self, s: &Store) -> (f64, f64) {
        let zbase = s[self.s_base] / s[self.s_rated];
        (s[self.r_f] * zbase, s[self.x_f] * zbase)
    }

    /// A grid-forming unit's virtual resistance `vi.r`, pu on the system base.
    pub(crate) fn virtual_resistance(&self, s: &Store) -> f64 {
        s[self.vi_r] * s[self.s_base] / s[self.s_rated]
    }

    /// The power the converter's ac side draws from its dc link, pu on S_rated: the measured
    /// terminal power and, for a grid-forming unit, the loss in `R_f` between them.
    pub(crate) fn converter_power(&self, s: &Store, r: f64, mode: Mode) -> f64 {
        let (p, q, v) = (s[self.p], s[self.q], s[self.v]);
        let r_loss = if mode == Mode::GridForming && v > 0.0 {
            r * (p * p + q * q) / (v * v)
        } else {
            0.0
        };
        (p + r_loss) * s[self.s_base] / s[self.s_rated]
    }

    /// The dc side's outputs.
    pub(crate) fn write_dc(&self, s: &mut Store, rt: &Runtime) {
        let (s_base, s_rated) = (s[self.s_base], s[self.s_rated]);
        s[self.v_dc] = rt.common.dc.v_dc();
        s[self.p_dc] = rt.common.dc.p_src() * s_rated / s_base;
        // Energies in MJ: pu·s on S_rated times S_rated in MVA.
        s[self.e_src] = rt.common.dc.e_src * s_rated;
        s[self.e_ac] = rt.common.dc.e_ac * s_rated;
        s[self.e_loss] = rt.common.dc.e_loss * s_rated;
        s[self.w_dc] = rt.common.dc.energy() * s_rated;
        let (p, q, v) = (s[self.p], s[self.q], s[self.v]);
        // At a dead bus no power flows: inputs that say otherwise are start values, not a current.
        s[self.i_ac] = if v < limits::V_FLOOR {
            0.0
        } else {
            dvpp_math::hypot(p, q) / v * s_base / s_rated
        };
        // The dc budget at the terminal: less the R_f loss at the present current.
        let (r, _) = self.slot_impedance(s);
        let r_loss = if rt.channel.mode() == Mode::GridForming {
            r * (p * p + q * q) / dvpp_math::powi(v.max(limits::V_FLOOR), 2)
        } else {
            0.0
        };
        let (lo, hi) = rt.common.dc.ac_budget();
        s[self.p_min] = lo * s_rated / s_base - r_loss;
        s[self.p_max] = hi * s_rated / s_base - r_loss;
        s[self.i_limit] = s[self.i_max];
    }

    /// The measured rotated powers `p'`, `q'` (outputs `p_rot`, `q_rot`).
    pub(crate) fn write_rotated(&self, s: &mut Store, rt: &Runtime) {
        let (p_rot, q_rot) = rt.common.rot.rotate(s[self.p], s[self.q]);
        s[self.p_rot] = p_rot;
        s[self.q_rot] = q_rot;
    }

    /// The limit flags.
    pub(crate) fn write_limits(&self, s: &mut Store, rt: &Runtime) {
        s[self.limit_current] = rt.common.limit.current.active();
        s[self.limit_dc] = rt.common.limit.dc.active();
        s[self.limit_source] = rt.common.limit.source.active();
        s[self.limit_modulation] = rt.common.limit.modulation.active();
    }

    /// The highest set point the primary source allows at `t`: `deload · P_avail - G_dc`, on S_base.
    pub(crate) fn headroom_limit(&self, s: &Store, t: f64) -> f64 {
        s[self.deload] * self.available(s, t) - s[self.g_dc] * s[self.s_rated] / s[self.s_base]
    }
}
