//! The phasor-level DER matching controller as a library object: `PhasorUnit` (typed parameters, measurement, operator's gains and command; `initialize`, `step`, `retune`), which the `dvpp_der` FMU adapts.
//!
//! * Grid-forming ([`Mode::GridForming`]): `Δf = -T_i^pf Δp` with `T_i^pf = T_pf/m_i^p` (Δp
//!   from the measured `p`, converted to the DVPP base `S_dvpp`), and the imposed angle
//!   `θ = θ₀ + 2π f_nom ∫Δf dt` (integrated exactly over each step). The voltage magnitude `E`
//!   comes from a PI matching controller (option A) making `q` track `q_ref = q₀ - T_i^vq Δv`.
//!   `E∠θ` starts behind the transformer impedance at the measured operating point, so a
//!   coupled run starts flat.
//! * Grid-following ([`Mode::GridFollowing`]): a PLL on `v_angle` measures `Δf`; the converter
//!   injects `p_ref = p₀ - T_i^fp Δf` and `q_ref = q₀ - T_i^vq Δv`, limited to the rating circle.
//! * Rotational power control (`rot.rx` > 0): both channels work on the rotated powers `p'`,
//!   `q'` ([`dvpp_control::Rotation`]); `rot.rx` = 0 is the classical control, bit for bit.
//!
//! The set point is the dispatch at initialization, curtailed to what the primary source allows
//! with its reserve (`deload · P_avail(t) - G_dc`). The primary source and dc side ([`dc`]): an
//! availability profile, a dc source that follows its command with the lag `τ_dc`, and a dc link
//! whose voltage a proportional controller holds. The output stage's limits are in [`limits`].

mod common;
pub mod dc;
mod following;
mod forming;
pub mod limits;
mod params;

pub use forming::DELAY_COMPENSATION;
pub use params::{
    DcRange, OutputStage, PhasorParams, Priority, QPiParams, SlotImpedance, StartupParams,
};

use crate::layer::{self, PfReference};
use crate::{positive, Error, Mode, Notice, OperatorGains};
use common::{pll_model, Common, LimitEpisodes, Outcome, Startup, StepPoint};
use dc::DcSide;
use dvpp_control::phasor::internal_voltage;
use dvpp_control::{Hold, LtiSimulator, Rotation};
use following::Following;
use forming::Forming;
use serde::{Deserialize, Serialize};

/// Below this terminal voltage (pu) a grid-following unit's PLL has no angle to lock to: the
/// unit loses synchronism and blocks (a grid-forming unit keeps forming its voltage).
const PLL_V_MIN: f64 = 0.05;

/// What the unit measures at its terminal at time `t` (s): the active and reactive power it
/// injects (pu on `S_base`) and the voltage at the regulated point (magnitude, pu; angle, rad in
/// the frame rotating at `f_nom`).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PhasorMeasurement {
    pub t: f64,
    pub p: f64,
    pub q: f64,
    pub v: f64,
    pub v_angle: f64,
}

/// What the unit commands for the next step, and what it reports (the `dvpp_der` FMU's
/// outputs; powers pu on `S_base` unless said otherwise).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PhasorCommand {
    /// Grid-forming: the internal voltage angle the converter imposes (rad); grid-following:
    /// the PLL angle.
    pub theta: f64,
    /// Grid-forming: the internal voltage magnitude the converter imposes (held in
    /// grid-following).
    pub e: f64,
    /// The unit's frequency deviation, pu of `f_nom`.
    pub df: f64,
    /// Grid-following: the active power reference; grid-forming: the active set point.
    pub p_ref: f64,
    /// The active set point: the dispatch curtailed to what the primary source allows.
    pub p_set: f64,
    /// The reactive power reference `q₀ - T_i^vq Δv`.
    pub q_ref: f64,
    /// The primary source's available power.
    pub p_avail: f64,
    /// The dc-link voltage, pu.
    pub v_dc: f64,
    /// The dc source's power.
    pub p_dc: f64,
    /// The magnitude of the ac current at the terminal, pu of the rated current.
    pub i_ac: f64,
    /// The current limit `I_max`, for the host's network solution.
    pub i_limit: f64,
    /// Grid-forming: the lowest and highest active power at the terminal the dc link can take
    /// and give now, for the host's network solution.
    pub p_min: f64,
    pub p_max: f64,
    /// Energies since initialization (MJ): delivered by the primary source, drawn by the ac
    /// side, lost in the link; and the energy stored in the link now.
    pub energy_source: f64,
    pub energy_ac: f64,
    pub energy_loss: f64,
    pub energy_stored: f64,
    /// The limits' episodes: current `I_max`, the dc link's budget, the primary source at its
    /// availability, the modulation limit `E_max · v_dc`.
    pub limit_current: bool,
    pub limit_dc: bool,
    pub limit_source: bool,
    pub limit_modulation: bool,
    /// The unit is synchronized (false while it waits for the terminal voltage).
    pub synchronized: bool,
    /// The measured rotated powers `p'`, `q'` (`p`, `q` at `rot.rx` = 0).
    pub p_rot: f64,
    pub q_rot: f64,
    /// Warnings and events of this call, for the host's log.
    pub notices: Vec<Notice>,
}

/// The mode's controller state.
#[derive(Debug, Clone, Serialize, Deserialize)]
enum Channel {
    Forming(Box<Forming>),
    Following(Box<Following>),
}

impl Channel {
    /// The mode the channel realizes.
    fn mode(&self) -> Mode {
        match self {
            Channel::Forming(_) => Mode::GridForming,
            Channel::Following(_) => Mode::GridFollowing,
        }
    }

    /// The mode's controller for its reference model, at the measurement `m`.
    fn new(
        reference: PfReference,
        p: &PhasorParams,
        m: &PhasorMeasurement,
    ) -> Result<Channel, Error> {
        Ok(match reference {
            PfReference::Forming(pf) => Channel::Forming(Box::new(Forming {
                pf,
                e_int: 0.0,
                e: 0.0,
                theta: 0.0,
                dtheta: 0.0,
                dtheta_mean: 0.0,
            })),
            PfReference::Following(fp) => {
                let (kp, ki) = (p.pll.kp, p.pll.ki);
                if !(kp > 0.0 && ki > 0.0) {
                    return Err(Error::field(
                        "pll.kp",
                        format!("PLL gains kp = {kp}, ki = {ki} must be > 0"),
                    ));
                }
                let mut pll = LtiSimulator::new(pll_model(kp, ki, p.rating.f_nom), Hold::Zero);
                pll.set_state(&[0.0, m.v_angle], m.v_angle)
                    .expect("PLL state");
                Channel::Following(Box::new(Following {
                    fp,
                    pll,
                    current: (0.0, 0.0),
                    dv: 0.0,
                    gains: (kp, ki),
                }))
            }
        })
    }
}

/// The outputs a step may leave as they were (held from the last step that set them).
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub(crate) struct Held {
    pub(crate) theta: f64,
    pub(crate) e: f64,
    pub(crate) df: f64,
    pub(crate) p_ref: f64,
    pub(crate) p_set: f64,
    pub(crate) q_ref: f64,
    pub(crate) p_avail: f64,
}

/// The phasor-level DER matching controller: its parameters and running state.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PhasorUnit {
    params: PhasorParams,
    channel: Channel,
    common: Common,
    out: Held,
}

/// The power the converter's ac side draws from its dc link, pu on S_rated: the measured
/// terminal power and, for a grid-forming unit, the loss in `R_f` (`r` on S_base) between them.
fn converter_power(p: &PhasorParams, m: &PhasorMeasurement, r: f64, mode: Mode) -> f64 {
    let (pw, q, v) = (m.p, m.q, m.v);
    let r_loss = if mode == Mode::GridForming && v > 0.0 {
        r * (pw * pw + q * q) / (v * v)
    } else {
        0.0
    };
    (pw + r_loss) * p.rating.s_base / p.rating.s_rated
}

/// The internal voltage `E∠θ` the controls set and the one the converter imposes, behind the
/// slot impedance (and a grid-forming unit's virtual resistance) at the operating point `m`; a
/// unit `waiting` for the voltage follows the terminal voltage.
fn internal_voltages(
    p: &PhasorParams,
    m: &PhasorMeasurement,
    waiting: bool,
) -> ((f64, f64), (f64, f64)) {
    // The internal voltage behind the transformer (the slot impedance).
    let (r, x) = p.slot_impedance();
    let (pw, q, v) = (m.p, m.q, m.v);
    // A grid-forming unit's controls set the voltage behind its virtual resistance too.
    let r_v = match p.mode {
        Mode::GridForming => p.virtual_resistance(),
        Mode::GridFollowing => 0.0,
    };
    let (e0, theta0) = if waiting {
        (v, m.v_angle)
    } else {
        internal_voltage(pw, q, v, m.v_angle, r + r_v, x)
    };
    let (e_out, theta_out) = if waiting || r_v == 0.0 {
        (e0, theta0)
    } else {
        internal_voltage(pw, q, v, m.v_angle, r, x)
    };
    ((e0, theta0), (e_out, theta_out))
}

impl PhasorUnit {
    /// The unit at the measured operating point `m`, taken as a steady state (its time `m.t` is
    /// when the availability profile is read), with the operator's gains `gains`, and its
    /// command. `previous` is the unit an earlier initialization of the same episode built (a
    /// host that initializes again as values change): what it already reported is not repeated.
    /// An error names the parameter at fault.
    pub fn initialize(
        params: &PhasorParams,
        m: &PhasorMeasurement,
        gains: &OperatorGains,
        previous: Option<&PhasorUnit>,
    ) -> Result<(PhasorUnit, PhasorCommand), Error> {
        let p = params;
        let again = previous.map(|u| u.common.warned_gains);
        p.validate_bases()?;
        let tdes = p.tdes.build()?;
        let adpf_p = p.adpf_p.build(gains.mu_p, &gains.mu_p_lpf)?;
        let adpf_q = p.adpf_q.build(gains.mu_q, &[])?;
        let pll_tau = positive(p.pll.tau, "pll.tau")?;
        let mode = p.mode;
        let (reference, vq) = layer::reference_models(&layer::ReferenceSpec {
            mode,
            tdes: &tdes,
            adpf_p: &adpf_p,
            adpf_q: &adpf_q,
            params_p: &p.adpf_p,
            params_q: &p.adpf_q,
            s_rated: p.rating.s_rated,
            s_dvpp: p.rating.s_dvpp,
            pll_tau,
            pll_order: p.pll.order,
        })?;
        let mut channel = Channel::new(reference, p, m)?;
        let dc = p.dc_params()?;
        positive(p.stage.i_max, "I_max")?;
        positive(p.qpi.e_max, "E_max")?;
        let rot = Rotation::from_rx(p.rot_rx).map_err(|e| Error::field("rot.rx", e))?;
        let mut notices = Vec::new();
        if again.is_none() {
            notices.push(Notice::Event(format!(
                "dc-voltage control: damping ratio {:.3} without the capacitor-power term, {:.3} with k_d = {:.3}",
                dc.damping(0.0),
                dc.damping(dc.k_d()),
                dc.k_d()
            )));
        }

        // Below `startup.v_sync` the unit waits for the voltage (a start from zero voltage).
        let (pw, q, v) = (m.p, m.q, m.v);
        let waiting = v < p.startup.v_sync;
        let ((e0, theta0), (e_out, theta_out)) = internal_voltages(p, m, waiting);
        let (r, _) = p.slot_impedance();
        let p_ac = if waiting {
            0.0
        } else {
            converter_power(p, m, r, mode)
        };
        let common = Common {
            vq,
            dc: DcSide::new(dc, p_ac),
            p0: pw,
            q0: if waiting { 0.0 } else { q },
            v0: v,
            e0,
            theta0,
            df_held: 0.0,
            q_ref: if waiting { 0.0 } else { rot.rotate(pw, q).1 },
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
        match &mut channel {
            Channel::Forming(f) => {
                f.e = e0;
                f.theta = theta0;
            }
            Channel::Following(g) if !waiting => {
                let to_rated = p.rating.s_base / p.rating.s_rated;
                g.current = (pw * to_rated / v, q * to_rated / v);
            }
            Channel::Following(_) => {}
        }
        let p_ref = if waiting { 0.0 } else { pw };
        let out = Held {
            theta: match &channel {
                Channel::Forming(_) => theta_out,
                Channel::Following(_) => m.v_angle,
            },
            e: e_out,
            df: 0.0,
            p_ref,
            p_set: p_ref,
            q_ref: if waiting { 0.0 } else { q },
            p_avail: p.source.available(m.t),
        };
        if waiting && again.is_none() {
            notices.push(Notice::Event(format!(
                "v = {v:.4} pu < startup.v_sync = {:.4} pu: waiting for the terminal voltage",
                p.startup.v_sync
            )));
        }
        let limit = p.headroom_limit(m.t);
        if pw > limit + 1e-12 && again.is_none() {
            notices.push(Notice::Warning(format!(
                "dispatch p = {pw:.4} pu is above deload * P_avail - G_dc = {limit:.4} pu: the set point is curtailed from the first step"
            )));
        }
        let unit = PhasorUnit {
            params: *p,
            channel,
            common,
            out,
        };
        let command = unit.command(m, notices);
        Ok((unit, command))
    }

    /// The parameters the unit runs with.
    pub fn params(&self) -> &PhasorParams {
        &self.params
    }

    /// New values of the tunable parameters (`pll.kp`, `pll.ki`, `qpi.*`, `E_max`, `I_max`,
    /// `limit.priority`, `delay.c`, `current.tau`, `vq.tau`, `deload`, `P_avail0`, `avail.*`,
    /// `dispatch.dP`), taken from `params`; the others keep their values from initialization.
    pub fn retune(&mut self, params: &PhasorParams) {
        self.params = self.params.tuned(params);
    }

    /// The PLL's gains `pll.kp`, `pll.ki`: a grid-following unit rebuilds its PLL at its next
    /// step (and reports it).
    pub fn set_pll_gains(&mut self, kp: f64, ki: f64) {
        self.params.pll.kp = kp;
        self.params.pll.ki = ki;
    }

    /// The grid-forming PI matching controller's gains and modulation limit.
    pub fn set_voltage_matching(&mut self, qpi: QPiParams) {
        self.params.qpi = qpi;
    }

    /// The output stage's limit, priority, delay compensation and lags.
    pub fn set_output_stage(&mut self, stage: OutputStage) {
        self.params.stage = stage;
    }

    /// The primary source's deloading and availability profile (`deload`, `P_avail0`,
    /// `avail.t_step`, `avail.dP`); whether it is storage stays as initialized.
    pub fn set_availability(&mut self, deload: f64, p_avail0: f64, avail_t: f64, avail_dp: f64) {
        let s = &mut self.params.source;
        (s.deload, s.p_avail0, s.avail_t, s.avail_dp) = (deload, p_avail0, avail_t, avail_dp);
    }

    /// The change of the dispatch `dispatch.dP` (pu on `S_base`), from the next step on.
    pub fn set_redispatch(&mut self, dp: f64) {
        self.params.redispatch = dp;
    }

    /// One step from `m.t` to `m.t + h`: the measurement at `m.t` and the operator's gains; the
    /// command over the step. An error names the input at fault.
    pub fn step(
        &mut self,
        m: &PhasorMeasurement,
        gains: &OperatorGains,
        h: f64,
    ) -> Result<PhasorCommand, Error> {
        let t = m.t;
        let mut notices = Vec::new();
        let following = matches!(self.channel, Channel::Following(_));
        if following && self.common.startup.is_none() && m.v < PLL_V_MIN {
            // The PLL has no voltage to lock to: the unit has lost synchronism. It blocks its
            // current and waits for the voltage as at a start from zero voltage.
            self.common.startup = Some(Startup {
                ok_since: None,
                v_last: m.v,
            });
            notices.push(Notice::Warning(format!(
                "t = {t:.4} s: terminal voltage {:.4} pu: the PLL has no voltage to lock to; lost synchronism, the current is blocked until the voltage returns above startup.v_sync",
                m.v
            )));
        }
        if self.common.startup.is_some() && !self.wait_for_voltage(m, h, &mut notices) {
            self.step_dc(m, h, &mut notices);
            return Ok(self.command(m, notices));
        }
        let p = &self.params;
        let to_dvpp = p.rating.s_base / p.rating.s_dvpp;
        let to_rated = p.rating.s_base / p.rating.s_rated;
        let dv = m.v - self.common.v0;
        // Dc gains from the operator (the participation bank identity holds while they move).
        let c = &mut self.common;
        let lpf = layer::operator_gains(
            &mut c.vq,
            p.adpf_q.kind,
            gains.mu_q,
            p.adpf_p.kind,
            gains.mu_p_lpf,
            p.adpf_p.n_lpf(),
            p.adpf_p.share(),
            &mut c.warned_gains,
            &mut |n| notices.push(n),
        )?;
        // The set point: the dispatch (ramped in after a start from zero voltage), curtailed to
        // what the primary source allows (a cloud lowers it).
        let ramp = self.common.t_sync.map_or(1.0, |t0| {
            let r = p.startup.ramp;
            if r > 0.0 {
                ((t + h - t0) / r).min(1.0)
            } else {
                1.0
            }
        });
        let dispatch = self.common.p0 + p.redispatch;
        let p_set = (dispatch * ramp).min(p.headroom_limit(t));
        self.out.p_set = p_set;
        let budget = self.common.dc.ac_budget();
        let i_max = p.stage.i_max;
        let at = StepPoint {
            t,
            h,
            dv,
            to_dvpp,
            to_rated,
            p_set,
            lpf,
            v: m.v,
            v_angle: m.v_angle,
            budget,
            i_max,
            mu_p: gains.mu_p,
        };
        let Outcome {
            current_limit,
            dc_limit,
            request,
            modulation,
        } = match &mut self.channel {
            Channel::Forming(f) => f.step(&mut self.common, p, m, &mut self.out, &at)?,
            Channel::Following(g) => {
                g.step(&mut self.common, p, &mut self.out, &at, &mut notices)?
            }
        };
        let lim = &mut self.common.limit;
        let t1 = t + h;
        lim.current.record(
            t1,
            current_limit,
            request,
            || "current limit I_max",
            &mut notices,
        );
        let (lo, hi) = budget;
        lim.dc.record(
            t1,
            dc_limit,
            self.common.dc.v_dc(),
            || format!("dc-link power budget [{lo:.3}, {hi:.3}] pu (v_dc)"),
            &mut notices,
        );
        lim.modulation.record(
            t1,
            modulation,
            p.qpi.e_max * self.common.dc.v_dc(),
            || "modulation limit E_max * v_dc",
            &mut notices,
        );
        self.step_dc(m, h, &mut notices);
        Ok(self.command(m, notices))
    }

    /// The primary source and the dc link over the step.
    fn step_dc(&mut self, m: &PhasorMeasurement, h: f64, notices: &mut Vec<Notice>) {
        let p = &self.params;
        let t = m.t;
        self.out.p_avail = p.source.available(t + h);
        let to_rated = p.rating.s_base / p.rating.s_rated;
        let (r, _) = p.slot_impedance();
        let p_ac = converter_power(p, m, r, self.channel.mode());
        let cap = self.out.p_avail * to_rated;
        let c = &mut self.common;
        let dc = c.dc.step(p_ac, h, cap);
        c.dc.update_reserve(c.limit.dc.active(), cap);
        c.limit.source.record(
            t + h,
            dc.source,
            c.dc.p_src(),
            || format!("primary source at its limit (P_avail = {cap:.4} pu on S_rated)"),
            notices,
        );
    }

    /// A unit started below `startup.v_sync`: zero current until the voltage has been above
    /// it and steady for `startup.t_hold`; then it takes the measured voltage as its operating
    /// point and synchronizes (returns true from that step on).
    fn wait_for_voltage(
        &mut self,
        m: &PhasorMeasurement,
        h: f64,
        notices: &mut Vec<Notice>,
    ) -> bool {
        let (t, v, v_angle) = (m.t, m.v, m.v_angle);
        let startup = self.params.startup;
        let c = &mut self.common;
        let st = c.startup.as_mut().expect("waiting");
        let steady = h > 0.0 && ((v - st.v_last) / h).abs() < 0.5;
        st.v_last = v;
        if v >= startup.v_sync && steady {
            let since = *st.ok_since.get_or_insert(t);
            if t + h - since >= startup.t_hold {
                c.startup = None;
                c.t_sync = Some(t);
                c.v0 = v;
                c.theta0 = v_angle;
                c.e0 = v;
                match &mut self.channel {
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
                notices.push(Notice::Event(format!(
                    "synchronized at t = {t:.4} s to v = {v:.4} pu; the set point ramps to {:.4} pu over {} s",
                    c.p0, startup.ramp
                )));
                return true;
            }
        } else {
            st.ok_since = None;
        }
        // Zero current: the converter follows the terminal voltage (grid-forming) or injects
        // nothing (grid-following).
        let o = &mut self.out;
        o.e = v;
        o.theta = v_angle;
        o.df = 0.0;
        o.p_ref = 0.0;
        o.q_ref = 0.0;
        o.p_set = 0.0;
        false
    }

    /// The command: the held outputs, the dc side's and the limits' reports at the measurement
    /// `m`, and `notices`.
    fn command(&self, m: &PhasorMeasurement, notices: Vec<Notice>) -> PhasorCommand {
        let p = &self.params;
        let c = &self.common;
        let (s_base, s_rated) = (p.rating.s_base, p.rating.s_rated);
        // At a dead bus no power flows: inputs that say otherwise are start values, not a current.
        let i_ac = if m.v < limits::V_FLOOR {
            0.0
        } else {
            dvpp_math::hypot(m.p, m.q) / m.v * s_base / s_rated
        };
        // The dc budget at the terminal: less the R_f loss at the present current.
        let (r, _) = p.slot_impedance();
        let r_loss = if self.channel.mode() == Mode::GridForming {
            r * (m.p * m.p + m.q * m.q) / dvpp_math::powi(m.v.max(limits::V_FLOOR), 2)
        } else {
            0.0
        };
        let (lo, hi) = c.dc.ac_budget();
        let (p_rot, q_rot) = c.rot.rotate(m.p, m.q);
        let o = &self.out;
        PhasorCommand {
            theta: o.theta,
            e: o.e,
            df: o.df,
            p_ref: o.p_ref,
            p_set: o.p_set,
            q_ref: o.q_ref,
            p_avail: o.p_avail,
            v_dc: c.dc.v_dc(),
            p_dc: c.dc.p_src() * s_rated / s_base,
            i_ac,
            i_limit: p.stage.i_max,
            p_min: lo * s_rated / s_base - r_loss,
            p_max: hi * s_rated / s_base - r_loss,
            // Energies in MJ: pu·s on S_rated times S_rated in MVA.
            energy_source: c.dc.e_src * s_rated,
            energy_ac: c.dc.e_ac * s_rated,
            energy_loss: c.dc.e_loss * s_rated,
            energy_stored: c.dc.energy() * s_rated,
            limit_current: c.limit.current.active(),
            limit_dc: c.limit.dc.active(),
            limit_source: c.limit.source.active(),
            limit_modulation: c.limit.modulation.active(),
            synchronized: c.startup.is_none(),
            p_rot,
            q_rot,
            notices,
        }
    }
}
