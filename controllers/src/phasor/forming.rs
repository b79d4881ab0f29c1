//! The grid-forming step: `Δf = -T_pf/m Δp` sets the angle, a PI on `E` makes `q` track its reference.

use super::common::{Common, Outcome, StepPoint};
use super::{limits, Held, PhasorMeasurement, PhasorParams, Priority};
use crate::{layer, Error};
use dvpp_control::{Complex, GfmPfModel};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The grid-forming controller state.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Forming {
    pub(crate) pf: GfmPfModel,
    /// Integral part of the PI matching controller on `E`.
    pub(crate) e_int: f64,
    /// The internal voltage node `E∠θ` the controls set; the converter imposes it unless a
    /// limit acts.
    pub(crate) e: f64,
    pub(crate) theta: f64,
    /// The angle's increment over the last step and its mean over `ANGLE_MEAN_TAU` (the part
    /// the grid frequency explains): their difference is the angle move the next measured
    /// power does not yet show (the current-limited mode's delay compensation).
    pub(crate) dtheta: f64,
    pub(crate) dtheta_mean: f64,
}

/// Grid-forming delay compensation: the fraction of the limited power's change that the
/// angle's last move makes (at the measured bus voltage) which the controls add to the measured
/// power. The loop through the feedthrough of T_pf/m, with gain `g_net` per step through the
/// network and `c` = this fraction of its gain at a fixed bus voltage, has the characteristic
/// `z² - (1 - c) z + (g_net - c)` (without the compensation `z² - z + g_net`, roots of modulus
/// `√g_net`: 0.97 for case study I's wind). For that wind (`c` = 0.58) both roots stay within
/// 0.8 for `g_net` from 0.3 to 1.2.
/// The default of the parameter `delay.c`.
pub const DELAY_COMPENSATION: f64 = 0.5;

/// Time constant of the mean angle increment (s).
const ANGLE_MEAN_TAU: f64 = 0.02;

impl Forming {
    /// The grid-forming controls over one step: angle, voltage magnitude and the limits of the
    /// converter's output stage.
    pub(crate) fn step(
        &mut self,
        rt: &mut Common,
        p: &PhasorParams,
        m: &PhasorMeasurement,
        out: &mut Held,
        at: &StepPoint,
    ) -> Result<Outcome, Error> {
        let f = self;
        let StepPoint {
            h,
            dv,
            to_dvpp,
            to_rated,
            p_set,
            lpf,
            mu_p,
            ..
        } = *at;
        let n_lpf = p.adpf_p.n_lpf();
        layer::set_p_gains(&mut f.pf, p.adpf_p.kind, mu_p, &lpf[..n_lpf])?;
        // The controls see the power the internal voltage delivers: the measurement
        // plus what the limits withheld, plus the change of the (limited) power that the
        // node's last move of angle makes and the measurement does not show yet: the measurement reflects the angle sent one communication
        // step earlier, and through the direct feedthrough of T_pf/m (a low-pass unit's
        // τ/(μ H)) that loop has a gain per step near 1 (2π f_nom h |D| (S_base/S_dvpp)
        // E V/|Z| = 1.16 for case study I's wind at a fixed bus voltage; about 0.94
        // through the network, from its ringing after case study I's load step, which
        // decays by 0.97 per step). With the delay that is a 60°-per-step mode at the edge of
        // stability, which the limiter, switching between limited and free from one step
        // to the next, kept going. Half of the move's effect (`DELAY_COMPENSATION`),
        // computed with the limiter at the measured bus voltage (nothing while the dc
        // budget holds the power), keeps the loop damped over its range of gains. The
        // grid frequency's share of the move (its mean over `ANGLE_MEAN_TAU`) moves the
        // bus too and is left out. It acts at all times, not only while a limit acts: on the
        // paper's nine-bus grid, with the PV held at its current limit, the wind's loop
        // gain through the network exceeded 1 and the mode grew (step-to-step current
        // changes of 0.32 pu in a 150 MW load step) before the wind reached its own limit.
        // Rotational control: both channels see p', q' and the set point rotated (the
        // identity at rot.rx = 0).
        let compensation = f.delay_compensation(rt, p, m, out.e, to_rated);
        let (p_fb, q_fb) = rt
            .rot
            .rotate(m.p + rt.withheld.0 + compensation, m.q + rt.withheld.1);
        let (p_set_rot, q_set_rot) = rt.rot.rotate(p_set, rt.q0);
        let dp = (p_fb - p_set_rot) * to_dvpp;
        out.p_ref = p_set;
        let (df, dtheta) = layer::forming_angle(&mut f.pf, dp, h, p.rating.f_nom);
        out.df = df;
        f.dtheta = dtheta;
        f.theta += f.dtheta;
        f.dtheta_mean += -dvpp_math::expm1(-h / ANGLE_MEAN_TAU) * (f.dtheta - f.dtheta_mean);
        // PI matching controller on E: q tracks the reference held over the step.
        // E within [0, E_max]; the integrator stops while the limit holds (anti-windup).
        f.e = layer::voltage_matching(
            &mut f.e_int,
            rt.q_ref,
            q_fb,
            rt.e0,
            p.qpi.kp,
            p.qpi.ki,
            p.qpi.e_max,
            h,
        );
        rt.q_ref = q_set_rot + rt.vq.step(dv, h) / to_dvpp;
        // Reported as the q at which q' meets its reference at the measured p'.
        out.q_ref = rt.rot.unrotate(p_fb, rt.q_ref).1;
        Ok(f.output_stage(rt, p, out, at))
    }

    /// What the converter imposes: the internal voltage within the modulation limit, its
    /// current within the output stage's limits; what those hold back is withheld.
    fn output_stage(
        &self,
        rt: &mut Common,
        p: &PhasorParams,
        out: &mut Held,
        at: &StepPoint,
    ) -> Outcome {
        let f = self;
        let StepPoint {
            h,
            to_dvpp,
            to_rated,
            v,
            v_angle,
            budget,
            i_max,
            ..
        } = *at;
        // The converter imposes the internal voltage, within the modulation limit; its
        // output stage holds the current within I_max and the active power within the
        // dc link's budget (enforced in the network solution, `i_limit`, `p_min`,
        // `p_max`). What the limits hold back, estimated at the measured bus voltage,
        // is added to the measurements the controls see.
        // Behind the virtual resistance, the output is the divider between the internal
        // voltage and the bus (the identity at vi.r = 0).
        let e_cap = p.qpi.e_max * rt.dc.v_dc();
        let (r, x) = p.slot_impedance();
        let z = Complex::new(r, x);
        let bus = dvpp_math::cpolar(v, v_angle);
        let r_v = p.virtual_resistance();
        // The source's magnitude and angle, the angle continuous with the internal one; at
        // vi.r = 0 the internal voltage itself, not a round trip through rectangular
        // coordinates (which moves the last bit: a flat start would not stay flat).
        let (e_source, theta_out) = if r_v == 0.0 {
            (f.e, f.theta)
        } else {
            let source = behind_virtual(dvpp_math::cpolar(f.e, f.theta), bus, z, r_v);
            (
                dvpp_math::cabs(source),
                f.theta + dvpp_math::carg(source * dvpp_math::cpolar(1.0, -f.theta)),
            )
        };
        let mut modulation = e_source > e_cap;
        let mut e_out = e_source.min(e_cap);
        let mut theta_out = theta_out;
        let wanted = (dvpp_math::cpolar(e_out, theta_out) - bus) / z;
        let u = if v > limits::V_FLOOR {
            bus / v
        } else {
            dvpp_math::cpolar(1.0, f.theta)
        };
        let request = dvpp_math::cabs(wanted * to_rated) / i_max;
        // Reactive current in dips (`limit.priority` = 1): beyond I_max the request turns to
        // the virtual impedance's direction on the voltage across the internal node, and the
        // converter imposes the voltage that asks for it (the slot holds it at I_max in the
        // network solution); what that holds back is counted against the untouched request.
        let sent = if p.stage.priority == Priority::Reactive && request > 1.0 {
            let ev = dvpp_math::cpolar(f.e, f.theta) - bus;
            let turned = limits::turn_reactive(wanted, request, ev);
            let source = bus + turned * z;
            modulation = dvpp_math::cabs(source) > e_cap;
            e_out = dvpp_math::cabs(source).min(e_cap);
            theta_out = f.theta + dvpp_math::carg(source * dvpp_math::cpolar(1.0, -f.theta));
            (dvpp_math::cpolar(e_out, theta_out) - bus) / z
        } else {
            wanted
        };
        let lim = limits::saturate_forming(sent * to_rated, u, v, i_max, budget);
        // Its gain: the feedback closes a loop through the direct feedthrough `D` of
        // T_pf/m whose gain over one step, 2π f_nom h |D| (S_base/S_dvpp) E V/|Z|, can
        // exceed 1 (a low-pass unit, τ/(μ H)); the gain is cut to keep that loop at 0.5.
        rt.withheld = if lim.current_limit || lim.dc_limit {
            let held = bus * (wanted - lim.current / to_rated).conj();
            let feedthrough = f.pf.simulator().system().d()[0].abs();
            let loop_gain = 2.0 * PI * p.rating.f_nom * h * feedthrough * to_dvpp * e_out * v
                / dvpp_math::cabs(z);
            let kappa = (0.5 / loop_gain).min(1.0);
            (kappa * held.re, kappa * held.im)
        } else {
            (0.0, 0.0)
        };
        out.e = e_out;
        out.theta = theta_out;
        Outcome {
            current_limit: lim.current_limit,
            dc_limit: lim.dc_limit,
            request,
            modulation,
        }
    }

    /// The change of the (limited) power that the node's last move of angle makes and the
    /// measurement does not show yet, times `delay.c`; `e_held` is the magnitude the converter
    /// imposed over the last step.
    fn delay_compensation(
        &self,
        rt: &Common,
        p: &PhasorParams,
        m: &PhasorMeasurement,
        e_held: f64,
        to_rated: f64,
    ) -> f64 {
        let f = self;
        // The limited power at the measured bus voltage, from the node E∠θ.
        let (r, x) = p.slot_impedance();
        let z = Complex::new(r, x);
        let bus = dvpp_math::cpolar(m.v, m.v_angle);
        let u = if m.v > limits::V_FLOOR {
            bus / m.v
        } else {
            dvpp_math::cpolar(1.0, f.theta)
        };
        let budget = rt.dc.ac_budget();
        let r_v = p.virtual_resistance();
        let limited = |theta: f64| {
            let source = if r_v == 0.0 {
                dvpp_math::cpolar(e_held, theta)
            } else {
                behind_virtual(dvpp_math::cpolar(f.e, theta), bus, z, r_v)
            };
            let wanted = (source - bus) / z;
            let i =
                limits::saturate_forming(wanted * to_rated, u, m.v, p.stage.i_max, budget).current;
            (bus * (i / to_rated).conj()).re
        };
        let moved = f.dtheta - f.dtheta_mean;
        p.stage.delay_c * (limited(f.theta) - limited(f.theta - moved))
    }
}

/// The output voltage of a source `internal` behind the lossless virtual resistance `r_v` and
/// the slot impedance `z` into `bus`: the current is `(internal - bus)/(z + r_v)`.
fn behind_virtual(
    internal: Complex<f64>,
    bus: Complex<f64>,
    z: Complex<f64>,
    r_v: f64,
) -> Complex<f64> {
    (internal * z + bus * r_v) / (z + r_v)
}
