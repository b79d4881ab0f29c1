//! The EMT-level controller's runtime: initialization from the measured operating point, and one sample of the DVPP layer, the inner loops and the dc-voltage command.

use super::DerEmt;
use crate::layer::{self, PfReference};
use crate::{err, positive, AdpfKind, Mode};
use dvpp_control::converter::{
    hinf_gains, Abc, ConverterData, Dq, FilterMeasurement, HinfLoop, InnerDesign, InnerLoops, Pll,
};
use dvpp_control::VqModel;
use dvpp_controllers::dc::damping_gain;
use fmi_export::{Context, ModelError, Store};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The converter voltage's floor in the modulation (pu of `v_dc*`): below it the dc link is
/// taken as empty and the modulation saturates rather than divide by zero.
const V_DC_FLOOR: f64 = 0.05;

/// Option B's trip: the converter current (pu of the rated peak) beyond which a unit running the
/// H∞ state feedback, which has no current limit of its own, stops with an error, in units of
/// `I_max`.
const HINF_TRIP: f64 = 1.5;

/// Grid-following: time constant (s) of the voltages the current reference is computed from.
/// The reference `conj(S/v_g) + jωC_f v_c` taken from the instantaneous voltages closes a loop
/// through the LCL resonance (710 Hz) that the current loop's 1.5 samples of delay make
/// unstable (measured: a 50 µs, 800 Hz loop diverges from rounding noise within 30 ms); the
/// lag keeps the reference an outer-loop quantity, as the phasor DER's references are.
const REFERENCE_TAU: f64 = 1e-3;

/// Everything `initialize` builds, and the controller's state.
#[derive(Clone, Serialize, Deserialize)]
pub struct Runtime {
    mode: Mode,
    pf: PfReference,
    vq: VqModel,
    p_kind: AdpfKind,
    q_kind: AdpfKind,
    n_lpf: usize,
    inner: InnerLoops,
    design: InnerDesign,
    /// Grid-forming with `inner.kind` = 1: option B's state feedback in place of the q PI and
    /// the inner loops.
    hinf: Option<HinfLoop>,
    /// Grid-following: the PLL on the grid-side voltage.
    pll: Option<Pll>,
    /// Grid-forming: the frame's angle beyond `ω_b t` (rad).
    theta: f64,
    /// The frequency deviation of the frame (pu), held over the next step.
    df: f64,
    /// Grid-forming PI matching controller: integral, output, start value.
    e_int: f64,
    e: f64,
    e0: f64,
    /// The operating point at initialization (pu on S_base; `v0` pu).
    p0: f64,
    q0: f64,
    v0: f64,
    /// The reactive reference held over the next step (S_base).
    q_ref: f64,
    /// Grid-following: the voltage deviation through `vq.tau`.
    dv_lag: f64,
    /// Grid-following: the grid-side and capacitor voltages through `REFERENCE_TAU` (dq, PLL
    /// frame), from which the current reference is computed.
    vg_lag: Dq,
    vc_lag: Dq,
    /// The converter voltage the last output asked for (dq, pu), for the converter power.
    v_m: Dq,
    /// Option B: the grid-side current and the grid-voltage estimate of the previous sample
    /// (dq, pu, its frame), for the voltage the reactive reference model reads.
    i_g_prev: Dq,
    vg_prev: Dq,
    /// The dc source's current as the controller models it (its command through `τ_dc`).
    i_src: f64,
    k_d: f64,
    warned_gains: bool,
}

/// The three phases of an input or output.
fn abc(s: &Store, r: &[fmi_export::Real; 3]) -> Abc {
    Abc {
        a: s[r[0]],
        b: s[r[1]],
        c: s[r[2]],
    }
}

impl DerEmt {
    fn data(&self, s: &Store) -> ConverterData {
        ConverterData {
            c_dc: s[self.c_dc],
            g_dc: s[self.g_dc],
            r_f: s[self.r_f],
            l_f: s[self.l_f],
            c_f: s[self.c_f],
            r_t: s[self.r_t],
            l_t: s[self.l_t],
            kp_pll: s[self.pll_kp],
            ki_pll: s[self.pll_ki],
            k_dc: s[self.k_dc],
            v_dc_ratio: s[self.vdc_ratio],
        }
    }

    fn design(&self, s: &Store) -> InnerDesign {
        InnerDesign {
            current_hz: s[self.current_hz],
            voltage_hz: s[self.voltage_hz],
            zero_ratio: s[self.zero_ratio],
            i_max: s[self.i_max],
        }
    }

    fn omega_b(&self, s: &Store) -> f64 {
        2.0 * PI * s[self.f_nom]
    }

    /// The filter measurement in the frame at `rho`.
    fn measure(&self, s: &Store, rho: f64) -> FilterMeasurement {
        FilterMeasurement {
            v_c: abc(s, &self.v_abc).to_dq(rho),
            i_f: abc(s, &self.i_abc).to_dq(rho),
            i_g: abc(s, &self.ig_abc).to_dq(rho),
        }
    }

    /// The voltage at the MV side of the transformer, `v_c - (R_t + j ω L_t) i_g` (the
    /// phasor relation in the frame turning at `omega` pu).
    fn grid_voltage(&self, s: &Store, m: &FilterMeasurement, omega: f64) -> Dq {
        m.v_c - m.i_g * s[self.r_t] - m.i_g.rot90() * (omega * s[self.l_t])
    }

    /// The voltage behind the virtual resistance, `v_c + r_v i_g`: the grid-forming frame and
    /// `E` start on it.
    fn behind_virtual(&self, s: &Store, m: &FilterMeasurement) -> Dq {
        m.v_c + m.i_g * s[self.vi_r]
    }

    fn available(&self, s: &Store, t: f64) -> f64 {
        layer::availability(s[self.p_avail0], s[self.avail_t], s[self.avail_dp], t)
    }

    pub(crate) fn build(&self, s: &mut Store, ctx: &mut Context) -> Result<Runtime, ModelError> {
        for (r, name) in [
            (self.s_rated, "S_rated"),
            (self.s_base, "S_base"),
            (self.s_dvpp, "S_dvpp"),
            (self.f_nom, "f_nom"),
            (self.l_f, "L_f"),
            (self.c_f, "C_f"),
            (self.vdc_ratio, "vdc_ratio"),
            (self.current_hz, "inner.current_hz"),
            (self.voltage_hz, "inner.voltage_hz"),
            (self.zero_ratio, "inner.zero_ratio"),
            (self.i_max, "I_max"),
            (self.t_s, "t_s"),
            (self.tau_dc, "tau_dc"),
            (self.c_dc, "C_dc"),
        ] {
            positive(s, r, name)?;
        }
        let tdes = crate::unit_vars::tdes(s, self.h, self.d, self.dq, self.tau_q)?;
        let lpf = self.lpf_gains(s);
        let adpf_p = self.adpf_p.build(s, s[self.mu_p], &lpf)?;
        let adpf_q = self.adpf_q.build(s, s[self.mu_q], &[])?;
        let mode = Mode::from_code(s[self.mode]).map_err(|e| err("mode", e))?;
        let (pf, vq) = layer::reference_models(&layer::ReferenceSpec {
            mode,
            tdes: &tdes,
            adpf_p: &adpf_p,
            adpf_q: &adpf_q,
            params_p: &self.adpf_p.read(s)?,
            params_q: &self.adpf_q.read(s)?,
            s_rated: s[self.s_rated],
            s_dvpp: s[self.s_dvpp],
            pll_tau: positive(s, self.pll_tau, "pll.tau")?,
            pll_order: s[self.pll_order] as u32,
        })?;
        let omega_b = self.omega_b(s);
        let data = self.data(s);
        let design = self.design(s);
        let mut inner = InnerLoops::new(&design, data, omega_b);

        // The measured operating point, taken as a steady state: the frame starts on the
        // voltage behind the virtual resistance (grid-forming) or on the grid-side voltage
        // (grid-following).
        let at_zero = self.measure(s, 0.0);
        let rho = match mode {
            Mode::GridForming => {
                let w = self.behind_virtual(s, &at_zero);
                dvpp_math::atan2(w.q, w.d)
            }
            Mode::GridFollowing => {
                let vg = self.grid_voltage(s, &at_zero, 1.0);
                dvpp_math::atan2(vg.q, vg.d)
            }
        };
        let m = self.measure(s, rho);
        if m.v_c.norm() < 0.1 {
            return Err(ModelError(format!(
                "the measured capacitor voltage is {:.4} pu: the controller starts from a running converter (set the start values of v_a, v_b, v_c to the operating point)",
                m.v_c.norm()
            )));
        }
        let vg = self.grid_voltage(s, &m, 1.0);
        let to_base = s[self.s_rated] / s[self.s_base];
        let (p0, q0) = (vg.p(m.i_g) * to_base, vg.q(m.i_g) * to_base);
        let v_m = m.v_c + m.i_f * data.r_f + m.i_f.rot90() * data.l_f;
        inner.settle(&m, v_m, 1.0);
        let hinf = match (s[self.inner_kind], mode) {
            (0, _) => None,
            (1, Mode::GridForming) => Some(HinfLoop::new(
                &m,
                v_m,
                s[self.vi_r],
                s[self.s_dvpp] / (s[self.s_rated] * s[self.dq]),
                // The frame stabilizer damps a frame with inertia; a low-pass ADPF's frame
                // follows the unit's power at once and the stabilizer would feed that back
                // (docs/hinf.md §8.2).
                match self.adpf_p.kind(s)? {
                    AdpfKind::LowPass => 0.0,
                    _ => hinf_gains::STABILIZER,
                },
            )),
            (1, Mode::GridFollowing) => return Err(err(
                "inner.kind",
                "= 1 (option B, the H-infinity v-q matching) is for grid-forming units (mode = 1)",
            )),
            (k, _) => return Err(err("inner.kind", format!("= {k}: must be 0 or 1"))),
        };
        let pll = (mode == Mode::GridFollowing)
            .then(|| Pll::new(s[self.pll_kp], s[self.pll_ki], omega_b, rho));
        let v_dc = s[self.v_dc];
        let p_conv = v_m.p(m.i_f);
        let i_src = (p_conv + data.g_dc * v_dc * v_dc) / v_dc.max(V_DC_FLOOR);
        let rt = Runtime {
            mode,
            pf,
            vq,
            p_kind: self.adpf_p.kind(s)?,
            q_kind: self.adpf_q.kind(s)?,
            n_lpf: self.adpf_p.n_lpf.map_or(0, |n| s[n] as usize),
            inner,
            design,
            hinf,
            pll,
            theta: rho,
            df: 0.0,
            e_int: 0.0,
            e: self.behind_virtual(s, &m).d,
            e0: self.behind_virtual(s, &m).d,
            p0,
            q0,
            v0: vg.norm(),
            q_ref: q0,
            dv_lag: 0.0,
            vg_lag: vg,
            vc_lag: m.v_c,
            v_m,
            i_g_prev: m.i_g,
            vg_prev: vg,
            i_src,
            k_d: damping_gain(
                s[self.tau_dc],
                data.c_dc,
                data.g_dc,
                data.k_dc,
                s[self.dc_zeta],
            ),
            warned_gains: false,
        };
        let limit = self.headroom(s, 0.0);
        if p0 > limit + 1e-12 {
            ctx.warn(format!(
                "dispatch p = {p0:.4} pu is above deload * P_avail - G_dc = {limit:.4} pu: the set point is curtailed from the first step"
            ));
        }
        self.write_modulation(s, &rt, rho + 0.5 * s[self.t_s] * omega_b);
        s[self.i_dc_ref] = i_src;
        let range = self.source_range(s, 0.0);
        s[self.p_src[0]] = range[0];
        s[self.p_src[1]] = range[1];
        s[self.p] = p0;
        s[self.q] = q0;
        s[self.v] = rt.v0;
        s[self.df] = 0.0;
        s[self.theta] = rho;
        s[self.e] = rt.e;
        s[self.p_set] = p0.min(limit);
        s[self.q_ref] = q0;
        s[self.p_avail] = self.available(s, 0.0);
        s[self.i_ac] = m.i_f.norm();
        s[self.limit_current] = false;
        s[self.limit_modulation] = false;
        s[self.limit_source] = false;
        Ok(rt)
    }

    /// The highest set point the primary source allows at `t`: `deload · P_avail - G_dc`, on S_base.
    fn headroom(&self, s: &Store, t: f64) -> f64 {
        s[self.deload] * self.available(s, t) - s[self.g_dc] * s[self.s_rated] / s[self.s_base]
    }

    /// What the primary source can deliver at `t`, `[0, P_avail]` or `±P_avail` for storage, on
    /// S_rated.
    fn source_range(&self, s: &Store, t: f64) -> [f64; 2] {
        let cap = self.available(s, t) * s[self.s_base] / s[self.s_rated];
        [if s[self.storage] { -cap } else { 0.0 }, cap]
    }

    /// The modulation for the converter voltage `rt.v_m` at the frame angle `rho`.
    fn write_modulation(&self, s: &mut Store, rt: &Runtime, rho: f64) {
        let scale = 0.5 * s[self.vdc_ratio] * s[self.v_dc].max(V_DC_FLOOR);
        let v = rt.v_m.to_abc(rho);
        for (r, x) in self.m_abc.iter().zip([v.a, v.b, v.c]) {
            s[*r] = (x / scale).clamp(-1.0, 1.0);
        }
    }

    /// One sample: measurements at `t`, commands for the step that starts at `t + h`.
    pub(crate) fn step(
        &self,
        rt: &mut Runtime,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        let omega_b = self.omega_b(s);
        let design = self.design(s);
        if design != rt.design {
            rt.inner.redesign(&design, omega_b);
            rt.design = design;
            ctx.event(format!(
                "inner loops retuned at t = {t}: current {} Hz, voltage {} Hz, I_max {}",
                design.current_hz, design.voltage_hz, design.i_max
            ));
        }
        // The frame at t: grid-forming from the reference model's angle, grid-following the PLL's.
        let rho = match &rt.pll {
            Some(pll) => pll.theta(),
            None => (omega_b * t).rem_euclid(2.0 * PI) + rt.theta,
        };
        let omega = 1.0 + rt.df;
        let m = self.measure(s, rho);
        let vg = self.grid_voltage(s, &m, omega);
        let to_base = s[self.s_rated] / s[self.s_base];
        let to_dvpp = s[self.s_base] / s[self.s_dvpp];
        let (p, q, v) = (vg.p(m.i_g) * to_base, vg.q(m.i_g) * to_base, vg.norm());
        // Option B's reference model reads the MV-side voltage with the transformer's
        // L_t di_g/dt too, which the phasor estimate `vg` leaves out: over the last sample,
        // `(vg + vg_prev)/2 - L_t (i_g - i_g,prev)/(ω_b h)` (centred, so that the estimate's
        // error is of second order in h). The converter's own current does not move that
        // voltage on a stiff grid; `vg` does move with it (by L_t di_g/dt), and the fast
        // tracking of option B would close a loop through it and the frame's swing
        // (docs/hinf.md §8).
        let dv = if rt.hinf.is_some() {
            let di = (m.i_g - rt.i_g_prev) * (s[self.l_t] / (omega_b * h));
            let v_mv = (vg + rt.vg_prev) * 0.5 - di;
            rt.i_g_prev = m.i_g;
            rt.vg_prev = vg;
            v_mv.norm() - rt.v0
        } else {
            v - rt.v0
        };

        // The operator's dc gains.
        let lpf = layer::operator_gains(
            &mut rt.vq,
            rt.q_kind,
            s[self.mu_q],
            rt.p_kind,
            self.lpf_gains(s),
            rt.n_lpf,
            self.adpf_p.share.map_or(1.0, |r| s[r]),
            &mut rt.warned_gains,
            &mut |n| crate::log(ctx, n),
        )?;
        let p_set = rt.p0.min(self.headroom(s, t));
        let v_dc = s[self.v_dc];
        let v_m_max = 0.5 * s[self.vdc_ratio] * v_dc.max(0.0);
        let (v_m, df_next) = match &mut rt.pf {
            PfReference::Forming(pf) => {
                layer::set_p_gains(pf, rt.p_kind, s[self.mu_p], &lpf[..rt.n_lpf])?;
                let (df, dtheta) =
                    layer::forming_angle(pf, (p - p_set) * to_dvpp, h, s[self.f_nom]);
                // Option B: the state feedback on the reactive error of this sample; option A:
                // the q PI sets E.
                let b = match rt.hinf.as_mut() {
                    Some(hl) => {
                        // Option B has no current limit: beyond HINF_TRIP · I_max the unit trips
                        // rather than run a converter far past its rating.
                        let i_f = m.i_f.norm();
                        let trip = HINF_TRIP * s[self.i_max];
                        if i_f > trip {
                            return Err(ModelError(format!(
                                "option B (inner.kind = 1) has no current limit: the converter \
                                 current reached {i_f:.3} pu at t = {t} s, beyond {HINF_TRIP} \
                                 I_max = {trip:.3} pu; the unit trips (docs/hinf.md §8)"
                            )));
                        }
                        let v = hl.step(
                            &m,
                            (q - rt.q0) / to_base,
                            (rt.q_ref - rt.q0) / to_base,
                            rt.vq.mu_q(),
                            rt.df,
                            v_m_max,
                            omega_b,
                            h,
                        );
                        rt.e = self.behind_virtual(s, &m).d;
                        Some(v)
                    }
                    None => {
                        rt.e = layer::voltage_matching(
                            &mut rt.e_int,
                            rt.q_ref,
                            q,
                            rt.e0,
                            s[self.qpi_kp],
                            s[self.qpi_ki],
                            s[self.e_max],
                            h,
                        );
                        None
                    }
                };
                rt.q_ref = rt.q0 + rt.vq.step(dv, h) / to_dvpp;
                rt.theta += dtheta;
                let v_m = b.unwrap_or_else(|| {
                    // The capacitor-voltage reference behind the virtual resistance.
                    let v_ref = Dq { d: rt.e, q: 0.0 } - m.i_g * s[self.vi_r];
                    rt.inner.step(&m, v_ref, omega, v_m_max, h)
                });
                (v_m, df)
            }
            PfReference::Following(fp) => {
                layer::set_p_gains(fp, rt.p_kind, s[self.mu_p], &lpf[..rt.n_lpf])?;
                let dp = fp.step(rt.df, h) / to_dvpp;
                let tau_v = s[self.vq_tau];
                let kv = if tau_v > 0.0 {
                    -dvpp_math::expm1(-h / tau_v)
                } else {
                    1.0
                };
                rt.dv_lag += kv * (dv - rt.dv_lag);
                rt.q_ref = rt.q0 + rt.vq.step(rt.dv_lag, h) / to_dvpp;
                // The grid-side current for the references at the measured voltage, plus the
                // capacitor's current: the converter-side current reference.
                let k = -dvpp_math::expm1(-h / REFERENCE_TAU);
                rt.vg_lag = rt.vg_lag + (vg - rt.vg_lag) * k;
                rt.vc_lag = rt.vc_lag + (m.v_c - rt.vc_lag) * k;
                let (pr, qr) = ((p_set + dp) / to_base, rt.q_ref / to_base);
                let u = rt.vg_lag;
                let n2 = (u.d * u.d + u.q * u.q).max(1e-4);
                let i_g = Dq {
                    d: (u.d * pr + u.q * qr) / n2,
                    q: (u.q * pr - u.d * qr) / n2,
                };
                let i_ref = i_g + rt.vc_lag.rot90() * (omega * s[self.c_f]);
                let v_m = rt.inner.current(&m, i_ref, omega, v_m_max, h);
                let pll = rt.pll.as_mut().expect("grid-following PLL");
                pll.kp = s[self.pll_kp];
                pll.ki = s[self.pll_ki];
                pll.step(rt.vg_lag.to_abc(rho), h);
                (v_m, pll.delta_f())
            }
        };
        // The dc-voltage command: converter power and link losses fed forward, k_dc on the
        // stored energy, the damping term on the capacitor's power (as the phasor DER).
        let p_conv = rt.v_m.p(m.i_f);
        let (c_dc, g_dc) = (s[self.c_dc], s[self.g_dc]);
        let stored = 0.5 * c_dc * (v_dc * v_dc - 1.0);
        let charging = rt.i_src * v_dc - g_dc * v_dc * v_dc - p_conv;
        let command =
            p_conv + g_dc * v_dc * v_dc - s[self.k_dc] / c_dc * stored - rt.k_d * charging;
        // The command drives the source's lag unclamped; the source stays within its range
        // (modelled here as the host's source model does it: cut at once to a range that fell,
        // held at a bound the lag reaches).
        let range = self.source_range(s, t + h);
        let v_range = v_dc.max(V_DC_FLOOR);
        let (lo, hi) = (range[0] / v_range, range[1] / v_range);
        let i_cmd = command / v_range;
        let i0 = rt.i_src.clamp(lo, hi);
        rt.i_src = (i_cmd + (i0 - i_cmd) * dvpp_math::exp(-h / s[self.tau_dc])).clamp(lo, hi);
        let source = (rt.i_src >= hi && i_cmd > hi) || (rt.i_src <= lo && i_cmd < lo);

        rt.v_m = v_m;
        rt.df = df_next;
        let rho_out = rho + 1.5 * h * omega_b * (1.0 + df_next);
        self.write_modulation(s, rt, rho_out);
        s[self.i_dc_ref] = i_cmd;
        s[self.p_src[0]] = range[0];
        s[self.p_src[1]] = range[1];
        s[self.p] = p;
        s[self.q] = q;
        s[self.v] = v;
        s[self.df] = df_next;
        s[self.theta] = match &rt.pll {
            Some(pll) => (pll.theta() - omega_b * (t + h) + PI).rem_euclid(2.0 * PI) - PI,
            None => rt.theta,
        };
        s[self.e] = rt.e;
        s[self.p_set] = p_set;
        s[self.q_ref] = rt.q_ref;
        s[self.p_avail] = self.available(s, t + h);
        s[self.i_ac] = m.i_f.norm();
        s[self.limit_current] = match rt.hinf {
            // Option B does not limit its current: the flag says it is beyond I_max.
            Some(_) => m.i_f.norm() > s[self.i_max],
            None => rt.inner.current_limited(),
        };
        s[self.limit_modulation] = rt
            .hinf
            .as_ref()
            .map_or(rt.inner.modulation_limited(), HinfLoop::modulation_limited);
        s[self.limit_source] = source;
        Ok(())
    }
}
