//! The cascaded filter-voltage and converter-current loops of option A, designed from the filter data.
//!
//! In the unit's dq frame (turning at `ω` pu), per sample:
//!
//! ```text
//! i_ref = i_g + jω C_f v_c + k_pv (v_ref - v_c) + k_iv ∫(v_ref - v_c)      limited to |i_ref| ≤ I_max
//! v_m   = v_c + jω L_f i_f + k_pi (i_ref - i_f) + k_ii ∫(i_ref - i_f)      limited to |v_m| ≤ v_m,max
//! ```
//!
//! The feed-forward of the grid current and the decoupling terms cancel what the filter
//! equations ([`super::filter`]) couple in, so each loop sees an integrator-like plant:
//! `(L_f/ω_b) s + R_f` for the current, `(C_f/ω_b) s` for the voltage. The gains place the
//! current loop at `ω_cc`: `k_pi = ω_cc L_f/ω_b`, `k_ii = ω_cc R_f` (the PI zero cancels the
//! filter pole, the loop is `ω_cc/s`); the voltage loop crosses over at `ω_vc` with
//! `k_pv = ω_vc C_f/ω_b` and the PI zero a factor `zero_ratio` below, `k_iv = k_pv ω_vc/zero_ratio`.
//! While a limit holds, that loop's integral stops (no wind-up); the current limit acts on
//! the inner loop's reference, so a fault or overload is met by the current loop holding
//! `I_max` while the voltage sags.
//!
//! Grid-forming ([`InnerLoops::step`]): while the reference is limited, the voltage `E - v_c`
//! across the virtual impedance is kept for the frame ([`InnerLoops::limit_error`]), weighted
//! in as the unlimited reference goes [`LIMIT_BAND`] beyond `I_max` (zero where the limit
//! starts to act), so that the frame's synchronizing term it feeds is continuous there.

use super::filter::ConverterData;
use super::frame::Dq;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// How far beyond `I_max` (fraction) the unlimited grid-forming reference goes before
/// [`InnerLoops::limit_error`] carries the whole voltage across the virtual impedance (about
/// 0.3 pu of voltage error with the default voltage loop's `k_pv`).
pub const LIMIT_BAND: f64 = 0.05;

/// The loops' bandwidths and limits, from which [`InnerDesign::gains`] follow.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct InnerDesign {
    /// Current-loop bandwidth (Hz).
    pub current_hz: f64,
    /// Voltage-loop crossover (Hz).
    pub voltage_hz: f64,
    /// How far below the voltage crossover the voltage PI's zero lies.
    pub zero_ratio: f64,
    /// Current limit `I_max` (pu peak of the rated current).
    pub i_max: f64,
}

impl Default for InnerDesign {
    /// 800 Hz current loop (a decade below a 20 kHz sampling, above the 710 Hz LCL resonance so
    /// that the loop damps it), 100 Hz voltage loop (8× slower), zero a factor 4 below,
    /// `I_max` = 1.2 pu.
    fn default() -> Self {
        InnerDesign {
            current_hz: 800.0,
            voltage_hz: 100.0,
            zero_ratio: 4.0,
            i_max: 1.2,
        }
    }
}

/// The gains of both loops.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct InnerGains {
    /// Current loop proportional gain (pu voltage per pu current).
    pub kp_i: f64,
    /// Current loop integral gain (per second).
    pub ki_i: f64,
    /// Voltage loop proportional gain (pu current per pu voltage).
    pub kp_v: f64,
    /// Voltage loop integral gain (per second).
    pub ki_v: f64,
}

impl InnerDesign {
    /// The gains for the filter `data` at base frequency `omega_b` (rad/s).
    pub fn gains(&self, data: &ConverterData, omega_b: f64) -> InnerGains {
        let (w_cc, w_vc) = (2.0 * PI * self.current_hz, 2.0 * PI * self.voltage_hz);
        let kp_v = w_vc * data.c_f / omega_b;
        InnerGains {
            kp_i: w_cc * data.l_f / omega_b,
            ki_i: w_cc * data.r_f,
            kp_v,
            ki_v: kp_v * w_vc / self.zero_ratio,
        }
    }
}

/// What the inner loops measure, in the unit's dq frame.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct FilterMeasurement {
    /// Filter-capacitor voltage `v_c`.
    pub v_c: Dq,
    /// Converter-side current `i_f`.
    pub i_f: Dq,
    /// Grid-side current `i_g`.
    pub i_g: Dq,
}

/// The loops' runtime: gains, the filter data the decoupling uses, integrals and limit flags.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InnerLoops {
    gains: InnerGains,
    data: ConverterData,
    i_max: f64,
    xi_v: Dq,
    xi_i: Dq,
    i_ref: Dq,
    /// The voltage error `v_ref - v_c` of the last sample if its reference was limited (zero
    /// otherwise).
    limit_error: Dq,
    current_limited: bool,
    modulation_limited: bool,
}

impl InnerLoops {
    /// Loops designed by `design` for the filter `data` at `omega_b` (rad/s), integrals at zero.
    pub fn new(design: &InnerDesign, data: ConverterData, omega_b: f64) -> InnerLoops {
        InnerLoops {
            gains: design.gains(&data, omega_b),
            data,
            i_max: design.i_max,
            xi_v: Dq::default(),
            xi_i: Dq::default(),
            i_ref: Dq::default(),
            limit_error: Dq::default(),
            current_limited: false,
            modulation_limited: false,
        }
    }

    /// The gains in use.
    pub fn gains(&self) -> &InnerGains {
        &self.gains
    }

    /// The current reference of the last sample (after the limit).
    pub fn i_ref(&self) -> Dq {
        self.i_ref
    }

    /// Grid-forming: the voltage `E - v_c` across the virtual impedance in the last sample if
    /// its current reference was limited (weighted in over [`LIMIT_BAND`]), zero otherwise.
    pub fn limit_error(&self) -> Dq {
        self.limit_error
    }

    /// Whether the last sample limited the current reference.
    pub fn current_limited(&self) -> bool {
        self.current_limited
    }

    /// Whether the last sample limited the converter voltage (the modulation).
    pub fn modulation_limited(&self) -> bool {
        self.modulation_limited
    }

    /// Start in the steady state of `m` with the converter voltage `v_m` (integrals set so
    /// that the first sample repeats it).
    pub fn settle(&mut self, m: &FilterMeasurement, v_m: Dq, omega: f64) {
        let jw_c = m.v_c.rot90() * (omega * self.data.c_f);
        self.xi_v = m.i_f - (m.i_g + jw_c);
        let jw_l = m.i_f.rot90() * (omega * self.data.l_f);
        self.xi_i = v_m - (m.v_c + jw_l);
        self.i_ref = m.i_f;
    }

    /// The converter voltage for this sample: `v_ref` the capacitor-voltage reference, `e` the
    /// voltage behind the virtual impedance it is taken from (a grid-forming unit's `E`; the
    /// limited reference's direction is taken from `e - v_c`), `omega` the frame's speed (pu),
    /// `v_m_max` the largest converter voltage the dc link allows, `h` the sampling period (s).
    #[allow(clippy::too_many_arguments)]
    pub fn step(
        &mut self,
        m: &FilterMeasurement,
        v_ref: Dq,
        e: Dq,
        omega: f64,
        v_m_max: f64,
        h: f64,
    ) -> Dq {
        let g = self.gains;
        // Voltage loop.
        let ev = v_ref - m.v_c;
        let ff = m.i_g + m.v_c.rot90() * (omega * self.data.c_f);
        let raw = ff + ev * g.kp_v + self.xi_v;
        self.limit_current(raw);
        if !self.current_limited {
            self.xi_v = self.xi_v + ev * (g.ki_v * h);
            self.limit_error = Dq::default();
        } else {
            self.limit_error = forming_limited(raw, e - m.v_c, self.i_max);
        }
        self.current_step(m, self.i_ref, omega, v_m_max, h)
    }

    /// The current loop alone (a grid-following unit's): the converter voltage that makes the
    /// converter-side current follow `i_ref`, which is limited to `I_max` first.
    pub fn current(
        &mut self,
        m: &FilterMeasurement,
        i_ref: Dq,
        omega: f64,
        v_m_max: f64,
        h: f64,
    ) -> Dq {
        self.limit_current(i_ref);
        self.current_step(m, self.i_ref, omega, v_m_max, h)
    }

    /// The current reference `raw`, its magnitude held at `I_max` (direction kept).
    fn limit_current(&mut self, raw: Dq) {
        let n = raw.norm();
        self.current_limited = n > self.i_max;
        self.i_ref = if self.current_limited {
            raw * (self.i_max / n)
        } else {
            raw
        };
    }

    fn current_step(
        &mut self,
        m: &FilterMeasurement,
        i_ref: Dq,
        omega: f64,
        v_m_max: f64,
        h: f64,
    ) -> Dq {
        let g = self.gains;
        let ei = i_ref - m.i_f;
        let ff = m.v_c + m.i_f.rot90() * (omega * self.data.l_f);
        let raw = ff + ei * g.kp_i + self.xi_i;
        let n = raw.norm();
        self.modulation_limited = n > v_m_max;
        if !self.modulation_limited {
            self.xi_i = self.xi_i + ei * (g.ki_i * h);
            raw
        } else {
            raw * (v_m_max / n)
        }
    }

    /// Retune both loops for `design` (the integrals carry on).
    pub fn redesign(&mut self, design: &InnerDesign, omega_b: f64) {
        self.gains = design.gains(&self.data, omega_b);
        self.i_max = design.i_max;
    }
}

/// The weight `w = (|raw|/I_max - 1)/LIMIT_BAND` (at most 1) of a grid-forming reference
/// `raw` beyond `I_max`, times `ev = E - v_c`: zero where the limit starts to act and the whole
/// voltage across the virtual impedance once the limit cuts [`LIMIT_BAND`] of the reference.
fn forming_limited(raw: Dq, ev: Dq, i_max: f64) -> Dq {
    let w = ((raw.norm() / i_max - 1.0) / LIMIT_BAND).min(1.0);
    ev * w
}

#[cfg(test)]
mod tests {
    use super::super::filter::{Lcl, LclState};
    use super::*;

    const WB: f64 = 2.0 * PI * 50.0;
    const H: f64 = 50e-6;

    fn measure(x: &LclState) -> FilterMeasurement {
        FilterMeasurement {
            v_c: x.v_c,
            i_f: x.i_f,
            i_g: x.i_g,
        }
    }

    /// Time (s) for `y` to reach 63 % of its final change, and the overshoot (fraction).
    fn rise(y: &[f64]) -> (f64, f64) {
        let (y0, yf) = (y[0], *y.last().unwrap());
        let k = y
            .iter()
            .position(|v| (v - y0) / (yf - y0) >= 1.0 - dvpp_math::exp(-1.0f64))
            .unwrap();
        let peak = y.iter().map(|v| (v - y0) / (yf - y0)).fold(0.0, f64::max);
        (k as f64 * H, peak - 1.0)
    }

    /// The current loop alone (its reference stepped directly) on the paper's filter against a
    /// stiff grid: a first-order response at the design bandwidth.
    #[test]
    fn current_loop_answers_at_its_bandwidth() {
        let data = ConverterData::PAPER;
        let design = InnerDesign::default();
        let mut loops = InnerLoops::new(&design, data, WB);
        let lcl = Lcl::discretize(&data, WB, 1.0, H);
        let vg = Dq { d: 1.0, q: 0.0 };
        let mut x = LclState::default();
        let mut v_m = vg;
        let g = *loops.gains();
        let mut trace = Vec::new();
        for k in 0..4000 {
            let m = measure(&x);
            let i_ref = Dq {
                d: if k >= 400 { 0.5 } else { 0.0 },
                q: 0.0,
            };
            // Drive the current loop with the reference given, as the voltage loop would.
            loops.i_ref = i_ref;
            let ei = i_ref - m.i_f;
            let ff = m.v_c + m.i_f.rot90() * data.l_f;
            let next = ff + ei * g.kp_i + loops.xi_i;
            loops.xi_i = loops.xi_i + ei * (g.ki_i * H);
            x = lcl.step(&x, v_m, vg);
            v_m = next;
            if k >= 400 {
                trace.push(x.i_f.d);
            }
        }
        let (tau, overshoot) = rise(&trace);
        eprintln!(
            "current loop: 63 % after {:.0} µs, overshoot {:.1} %",
            tau * 1e6,
            overshoot * 100.0
        );
        let design_tau = 1.0 / (2.0 * PI * design.current_hz);
        assert!(
            (tau - design_tau).abs() < 0.5 * design_tau + 2.0 * H,
            "63 % after {tau:e} s, designed {design_tau:e} s"
        );
        assert!(overshoot < 0.35, "overshoot {overshoot}");
        assert!((trace.last().unwrap() - 0.5).abs() < 1e-3);
    }

    /// Both loops, the converter feeding a resistive load through the transformer: the
    /// capacitor voltage follows a reference step with no steady-state error, and the
    /// current limit holds when the load asks for more.
    #[test]
    fn voltage_loop_tracks_and_the_current_limit_holds() {
        let design = InnerDesign::default();
        let mut data = ConverterData::PAPER;
        let r_load = 1.0;
        let plant = ConverterData {
            r_t: data.r_t + r_load,
            ..data
        };
        let lcl = Lcl::discretize(&plant, WB, 1.0, H);
        let mut loops = InnerLoops::new(&design, data, WB);
        let mut x = LclState::default();
        let mut v_m = Dq::default();
        let mut trace = Vec::new();
        for k in 0..8000 {
            let v_ref = Dq {
                d: if k >= 4000 { 1.0 } else { 0.9 },
                q: 0.0,
            };
            let next = loops.step(&measure(&x), v_ref, v_ref, 1.0, 1.5, H);
            x = lcl.step(&x, v_m, Dq::default());
            v_m = next;
            if k >= 4000 {
                trace.push(x.v_c.d);
            }
        }
        assert!(
            (x.v_c.d - 1.0).abs() < 1e-4 && x.v_c.q.abs() < 1e-4,
            "{:?}",
            x.v_c
        );
        let (tau, overshoot) = rise(&trace);
        eprintln!(
            "voltage loop: 63 % after {:.2} ms, overshoot {:.1} %",
            tau * 1e3,
            overshoot * 100.0
        );
        assert!(
            tau < 2.0 / (2.0 * PI * design.voltage_hz),
            "63 % after {tau:e} s"
        );
        assert!(overshoot < 0.3, "overshoot {overshoot}");
        // A load of 0.5 pu resistance at 1 pu voltage asks for ~2 pu current: limited to I_max.
        data.r_t += 0.5;
        let lcl = Lcl::discretize(&data, WB, 1.0, H);
        for _ in 0..8000 {
            let one = Dq { d: 1.0, q: 0.0 };
            let next = loops.step(&measure(&x), one, one, 1.0, 1.5, H);
            x = lcl.step(&x, v_m, Dq::default());
            v_m = next;
        }
        assert!(loops.current_limited());
        assert!(
            (x.i_f.norm() - design.i_max).abs() < 0.01 * design.i_max,
            "{}",
            x.i_f.norm()
        );
        assert!(
            x.v_c.norm() < 0.75,
            "the voltage sags instead: {}",
            x.v_c.norm()
        );
    }
}
