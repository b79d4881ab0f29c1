//! The DER matching controller at EMT level as a host-independent object: the DVPP layer over the paper's cascaded inner loops, sampled every 20-50 µs on instantaneous three-phase measurements.
//!
//! [`EmtUnit::initialize`] takes the [`EmtParams`], the measured operating point and the
//! operator's gains and returns the unit and its first [`EmtCommand`]; [`EmtUnit::step`] takes
//! one sample's [`EmtMeasurement`] and gains and returns the command for the next step;
//! [`EmtUnit::retune`] takes new values of the tunable parameters. The unit is `Clone` and
//! serializable: a host saves and restores it as its state.
//!
//! Bases and frames (pu on the unit's rating `S_rated`): the capacitor voltage `v_c` of the
//! rated phase-to-neutral peak `v_r`, the converter-side current `i_f` and the grid-side
//! (transformer) current `i_g` toward the grid of the rated peak current, `v_dc` of its nominal
//! `v_dc*`. The converter's phase voltage is `m · v_dc · vdc_ratio/2` (pu of `v_r`). The dq frame
//! is the amplitude-invariant Park transform at the angle `ω_b t + θ` (grid-forming) or the
//! PLL's. The powers `p`, `q` (pu on `S_base`) and the voltage `v` are those at the MV side of
//! the transformer, computed from `v_c` and `i_g` through `R_t + jX_t`.
//!
//! Timing: the command computed from the measurements at `t` is meant to be held over the next
//! step `[t + h, t + 2h)` (a zero-order hold, as an averaged converter applies a modulation), so
//! the dq-to-abc transform of the modulation advances the angle by 1.5 steps (one step of
//! computation delay and half a step of hold). At initialization the command is prepared for a
//! first step of `t_s`.

mod params;
pub mod trajectory;

pub use params::{EmtParams, FilterParams, InnerKind, ParamValue, QPiParams};

use crate::dc::damping_gain;
use crate::layer::{self, PfReference};
use crate::{AdpfKind, Error, Mode, Notice, OperatorGains};
use dvpp_control::converter::{
    hinf_gains, Abc, Dq, FilterMeasurement, HinfLoop, InnerDesign, InnerLoops, Pll,
};
use dvpp_control::VqModel;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The converter voltage's floor in the modulation (pu of `v_dc*`): below it the dc link is
/// taken as empty and the modulation saturates rather than divide by zero.
const V_DC_FLOOR: f64 = 0.05;

/// Option B's current limit (docs/hinf.md §8.5): the H∞ state feedback hands over to option A's
/// current-limited cascade when the converter current, extrapolated this many samples ahead from
/// its last change, reaches `I_max`. The command computed now is applied from the next step on,
/// held over it: the current the handover can first act on is about two samples ahead (measured:
/// in a 30 % dip the current rises 0.05 pu per sample; handing over when the current itself
/// reached `I_max` let it peak at 1.30 pu, two samples ahead at 1.22 pu).
const HINF_LOOKAHEAD: f64 = 2.0;

/// Option B's current limit: how long (s) the current-limited mode must have run with no limit
/// acting (the current reference not at `I_max`, the modulation not limited, `E` within
/// `(0, E_max)`, the converter current below `I_max`) before the state feedback takes over
/// again (measured: 0.1 s left the unit in option A's mode longer and with a larger reactive
/// error at the hand-back, which made the 20° jump hand over again for a second).
const HINF_HOLD: f64 = 0.05;

/// Option B's current limit: a handover that comes within [`HINF_REARM`] s of the last hand-back
/// is a quick one; from the second quick one in a row on, the hold doubles with each (up to
/// [`HINF_HOLD_MAX`]), and a run of the state feedback longer than `HINF_REARM` starts again
/// from [`HINF_HOLD`]. Where the state feedback's transient after each hand-back takes the
/// current back to the limit (its frame's kick), the unit thus stays longer in option A's mode
/// each time instead of switching back and forth; one quick handover (the 20° jump of
/// docs/hinf.md §9) keeps the short hold.
const HINF_REARM: f64 = 1.0;
const HINF_HOLD_MAX: f64 = 1.6;

/// Option B's current limit: time constant (s) with which the reactive error left at the
/// hand-back fades from the state feedback's reference, so that the feedback takes up the
/// reference model's output over about this time instead of within its own 30 ms (the fast
/// correction kicks the frame, by 2.6 pu of p per pu of q on S_base at μ = 1, and with the
/// error taken up at once the 30 % dip handed over twice more).
const HINF_REENTRY_TAU: f64 = 0.1;

/// Grid-following: time constant (s) of the voltages the current reference is computed from.
/// The reference taken from the instantaneous voltages closes a loop through the LCL resonance
/// (710 Hz) that the current loop's 1.5 samples of delay make unstable (measured: a 50 µs,
/// 800 Hz loop diverges from rounding noise within 30 ms); the lag keeps the reference an
/// outer-loop quantity, as the phasor DER's references are.
const REFERENCE_TAU: f64 = 1e-3;

/// Grid-following: time constant (s) of the capacitor voltage the converter-side reference's
/// capacitor current `jω C_f v_c` is computed from. Fed forward from `v_c` through a lag `τ`,
/// the capacitor current leaves the grid an admittance `jω C_f τs/(τs + 1)` beside the filter
/// capacitor, whose real part at the resonance of `C_f` with the transformer's and the grid's
/// inductance (dq: about 145, 200 and 300 Hz at SCR 1.5, 3 and 10) is a negative conductance of
/// `ω C_f ω_r τ/(1 + ω_r² τ²)`: 0.046 pu at SCR 3 through [`REFERENCE_TAU`] (1 ms). The unit's
/// own active current `p/|v|` is a positive conductance `p/v²` there, which hid it at the
/// generic unit's 0.5 pu; a unit near zero active power (case study I's battery at 0.17 pu of
/// its rating) oscillated at that resonance from the start (measured 0.3-0.55 pu of power at
/// SCR 3, 1.5 and 0 pu; docs/emt.md, grid-following on weak grids). Through 10 ms the
/// conductance is 0.1 of that and the resonance keeps the grid's damping: stable from 0 pu on
/// SCR 1.5 to 500 (5 ms is not at 0 pu on SCR 1.5, 3 ms not at SCR 3).
const CAPACITOR_TAU: f64 = 0.01;

/// Grid-following fault ride-through: time constant (s) of the voltage magnitude whose
/// deviation enters the ride-through and sets the k-factor's injection (it leaves on the
/// voltage through [`REFERENCE_TAU`], within the hysteresis). That voltage carries the ringing
/// of the capacitor's resonance at a voltage step (±0.1 pu for about 50 ms after a dip's end on
/// SCR 1.5): read alone, it took the unit in and out of the ride-through at every half period,
/// freezing the p-f model's frequency and the v-q droop at values of the ringing (with the
/// capacitor current through [`CAPACITOR_TAU`], the generic unit stayed in it at 0.88 pu after a
/// 0.5 pu dip on SCR 1.5), and a 0.08 pu dip's first swing there crossed the band (3 and 4 ms
/// still did).
const FRT_DETECT_TAU: f64 = 0.005;

/// Grid-following: time constant (s) of the lag through which the p-f reference model reads
/// the PLL's frequency. The PLL's frequency `k_p e + k_i ∫e` passes the angle of the unit's own
/// voltage at the gain `k_p` up to hundreds of Hz, and the model's inertia `2H s/(τ_pll s + 1)²`
/// turns it into power: on a weak grid the loop (power, voltage angle through the grid's
/// reactance, PLL, inertia) has a gain of `X 2H k_p/(ω_b τ_pll²)` ≈ 68 at SCR 3 above 10 Hz and
/// crosses over near 650 Hz, where the reference lag, the current loop and the delay take the
/// phase past -180° (docs/emt.md, grid-following on weak grids). Through this lag it stays
/// below 1 before that; measured stable from SCR 1.5 to 500 with the whole DVPP's inertia on
/// one unit (0.05 s is not at SCR 1.5).
const FREQUENCY_TAU: f64 = 0.1;

/// Grid-following fault ride-through (docs/emt.md §9): the dead band of the voltage's deviation
/// from its value before the event (pu; VDE-AR-N 4110/4120's default ±10 %), and the band's
/// hysteresis on leaving it.
const FRT_BAND: f64 = 0.1;
const FRT_HYSTERESIS: f64 = 0.02;
/// The k-factor: the additional reactive current (pu of the rated peak current) per pu of the
/// voltage's deviation beyond the dead band, `Δi_q = K_FRT (Δv - 0.1)` (capacitive in a dip,
/// inductive above the band), within I_max, reactive first.
const K_FRT: f64 = 2.0;
/// The time constant (s) through which the injection follows the deviation: 90 % within 25 ms
/// (the grid codes' rise time, 30 ms); taken at once, the step of up to I_max closes the loop
/// injection, voltage, deviation within the current loop's bandwidth and rings on weak grids
/// (measured: loss of synchronism after a 0.5 pu dip at SCR 3 and 1.5).
const FRT_TAU: f64 = 0.01;
/// The time constant (s) of the voltage before the event (held during it).
const V_PRE_TAU: f64 = 10.0;
/// The voltage (pu) below which the PLL holds its frequency in a fault ride-through.
const PLL_HOLD: f64 = 0.3;

/// Grid-forming, option A: the virtual reactance (pu on `S_rated`) through which the voltage
/// error a limited current reference leaves is read as power by the reference model (the
/// frame's synchronizing power while limited; docs/emt.md, current limit and ride-through).
const LIMIT_X: f64 = 0.4;

/// Grid-forming, option A: the frame's damping against the grid while limited and in the
/// recovery after, `D_slip` in units of `Tdes.D` (the reference model's own damping): the
/// frame's swing against the grid after a fault at SCR 10 has ζ ≈ 0.1 without it, 0.4 with
/// (docs/emt.md, current limit and ride-through).
const SLIP_DAMPING: f64 = 1.8;

/// The time constant (s) through which the frame damping reads the frame's speed against the
/// MV voltage (the angle's derivative carries the 100 Hz ripple of unbalanced operation and the
/// steps of faults).
const SLIP_TAU: f64 = 0.02;

/// Grid-forming, option A: the threshold virtual impedance on the voltage reference (after
/// Qoria et al.'s threshold virtual impedance): it acts beyond `TVI_THRESHOLD · I_max` of the
/// converter current's magnitude (through `TVI_TAU`), `TVI_GAIN` pu of resistance per pu of
/// current beyond it, `X/R` = `TVI_X_R`: in a dip the current turns reactive (0.24 -> 0.95 pu
/// reactive in a 0.5 pu dip at SCR 10) and stays below `I_max`, where the limit on the reference
/// remains the bound.
const TVI_THRESHOLD: f64 = 1.1 / 1.2;
const TVI_GAIN: f64 = 1.0;
const TVI_X_R: f64 = 5.0;
const TVI_TAU: f64 = 2e-3;

/// How long (s) the frame damping acts after the current was last limited, and the last part
/// of it over which it fades out.
const SLIP_RECOVERY: f64 = 2.0;
const SLIP_FADE: f64 = 1.0;

/// The frame damping's largest power (pu of the unit's rating): a phase jump or a fault's
/// voltage collapse turns the measured angle by up to π within a sample.
const SLIP_MAX: f64 = 0.5;

/// Grid-forming, option A: the zero-sequence converter current (pu) from which on the unit
/// takes its star point as grounded and controls the zero sequence to zero.
const ZERO_SEQUENCE_SEEN: f64 = 1e-3;

/// One sample of the measurements (pu on `S_rated`, instantaneous), at time `t` (s).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct EmtMeasurement {
    pub t: f64,
    /// Filter-capacitor voltage, of the rated phase-to-neutral peak.
    pub v_c: Abc,
    /// Converter-side filter current, of the rated peak current.
    pub i_f: Abc,
    /// Grid-side (transformer) current toward the grid, of the rated peak current.
    pub i_g: Abc,
    /// Dc-link voltage, of its nominal `v_dc*`.
    pub v_dc: f64,
}

/// What the unit commands for the next step, and what it reports.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct EmtCommand {
    /// Modulation indices of phases a, b, c, within [-1, 1].
    pub m_abc: [f64; 3],
    /// Current command to the primary (dc) source's lag, pu of `S_rated/v_dc*`.
    pub i_dc_ref: f64,
    /// The range of power the primary source can deliver now, pu on `S_rated`, for the host's
    /// source model: `[0, P_avail]`, or `[-P_avail, P_avail]` for storage.
    pub p_src_min: f64,
    pub p_src_max: f64,
    /// Active and reactive power into the grid and the voltage magnitude at the MV side of
    /// the transformer (pu on `S_base`, pu).
    pub p: f64,
    pub q: f64,
    pub v: f64,
    /// The unit's frequency deviation (pu of `f_nom`).
    pub df: f64,
    /// The frame's angle beyond `2π f_nom t` (rad).
    pub theta: f64,
    /// Grid-forming: the capacitor-voltage reference magnitude.
    pub e: f64,
    /// The active set point and the reactive reference (pu on `S_base`).
    pub p_set: f64,
    pub q_ref: f64,
    /// The primary source's availability (pu on `S_base`).
    pub p_avail: f64,
    /// Magnitude of the converter-side current (pu of the rated current).
    pub i_ac: f64,
    /// Option A: the current reference is held at `I_max`; option B: its current-limited mode
    /// (option A's cascade) runs.
    pub limit_current: bool,
    /// The converter voltage is held at the modulation limit.
    pub limit_modulation: bool,
    /// The power the converter draws from its dc side (its ac power and the link's losses
    /// `G_dc v_dc²`) is outside the primary source's range `[p_src_min, p_src_max]`: the dc link
    /// delivers or takes the difference (in a host that models no dc link and holds `v_dc` at
    /// 1, its ideal dc supply does, beyond what the primary source has).
    pub limit_source: bool,
    /// Warnings and events of this call, for the host's log.
    pub notices: Vec<Notice>,
}

/// The EMT-level DER matching controller: its parameters and running state.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EmtUnit {
    params: EmtParams,
    /// `2π f_nom` (rad/s).
    omega_b: f64,
    pf: PfReference,
    vq: VqModel,
    inner: InnerLoops,
    /// The design the inner loops run (the tunable one may have moved since).
    design: InnerDesign,
    /// Grid-forming with option B: the state feedback in place of the q PI and the inner loops.
    hinf: Option<HinfLoop>,
    /// Option B: the current-limited mode (option A's q PI and inner loops in place of the
    /// state feedback) runs, and for how long (s) no limit has acted in it.
    hinf_limited: bool,
    hinf_clear: f64,
    /// Option B: the hold the present limited mode needs (s), how many quick handovers came in
    /// a row, and how long the state feedback has run since the last hand-back (s).
    hinf_hold: f64,
    hinf_quick: u32,
    hinf_free: f64,
    /// Option B: the converter current's magnitude at the previous sample.
    hinf_i_prev: f64,
    /// Option B: the reactive error left at the hand-back (pu on S_rated), added to the
    /// state feedback's reference and fading.
    hinf_q_offset: f64,
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
    /// Grid-following: through `REFERENCE_TAU` (dq, PLL frame), the MV voltage with the
    /// transformer's `L_t di_g/dt` (the PLL's input and the fault ride-through's voltage), its
    /// phasor estimate `v_c - (R_t + jX_t) i_g` (the current reference's magnitude); the
    /// capacitor voltage through `CAPACITOR_TAU` (the reference's capacitor current).
    vg_lag: Dq,
    vg_phasor: Dq,
    vc_lag: Dq,
    /// Grid-following: the MV voltage's magnitude through `FRT_DETECT_TAU`, which the fault
    /// ride-through's dead band reads.
    u_frt: f64,
    /// Grid-following: the PLL's frequency deviation through `FREQUENCY_TAU` (pu), which the
    /// p-f reference model reads.
    df_lag: f64,
    /// Grid-following: the last sample's reactive current reference was held at `I_max`.
    limited: bool,
    /// Grid-following fault ride-through: the voltage before the event (the estimate's
    /// magnitude through `V_PRE_TAU`, held during the event), whether the unit is in it, the
    /// voltage deviation beyond the dead band through `FRT_TAU` (pu), and the reactive
    /// grid-side current reference before the event (PLL frame, pu of the rated peak).
    v_pre: f64,
    frt: bool,
    dv_frt: f64,
    iq_pre: f64,
    /// The converter voltage the last output asked for (dq, pu), for the converter power.
    v_m: Dq,
    /// Grid-forming, option A: a zero-sequence current has been seen in the converter (its star
    /// point is grounded), and the converter's zero-sequence voltage commanded for the next
    /// step (pu), which drives that current to zero.
    zero_path: bool,
    v_m0: f64,
    /// Grid-forming, option A: the MV voltage of the last sample (dq, the frame), and the
    /// frame's speed against it through `SLIP_TAU` (pu), which the frame damping reads.
    vg_last: Dq,
    slip: f64,
    /// Grid-forming, option A: how long (s) the frame damping still acts, set to
    /// `SLIP_RECOVERY` whenever the current is limited.
    recovery: f64,
    /// Grid-forming, option A: the converter current's magnitude through `TVI_TAU` (pu), which
    /// the threshold virtual impedance reads.
    i_filt: f64,
    /// Grid-forming, option A: the virtual impedance acted in the last sample.
    tvi_active: bool,
    /// Option B: the grid-side current and the grid-voltage estimate of the previous sample
    /// (dq, pu, its frame), for the voltage the reactive reference model reads.
    i_g_prev: Dq,
    vg_prev: Dq,
    /// The dc source's current as the controller models it (its command through `τ_dc`).
    i_src: f64,
    k_d: f64,
    warned_gains: bool,
}

impl EmtMeasurement {
    /// The filter measurement in the frame at `rho`.
    fn at(&self, rho: f64) -> FilterMeasurement {
        FilterMeasurement {
            v_c: self.v_c.to_dq(rho),
            i_f: self.i_f.to_dq(rho),
            i_g: self.i_g.to_dq(rho),
        }
    }
}

impl EmtUnit {
    /// The unit at the measured operating point `m`, taken as a steady state (its time `m.t` is
    /// when the availability profile is read), with the operator's gains `gains`; and its
    /// command for a first step of `t_s`. An error names the parameter at fault.
    pub fn initialize(
        params: &EmtParams,
        m: &EmtMeasurement,
        gains: &OperatorGains,
    ) -> Result<(EmtUnit, EmtCommand), Error> {
        params.validate()?;
        let p = params;
        let tdes = p.tdes.build()?;
        let adpf_p = p.adpf_p.build(gains.mu_p, &gains.mu_p_lpf)?;
        let adpf_q = p.adpf_q.build(gains.mu_q, &[])?;
        let mode = p.mode;
        let (pf, vq) = layer::reference_models(&layer::ReferenceSpec {
            mode,
            tdes: &tdes,
            adpf_p: &adpf_p,
            adpf_q: &adpf_q,
            params_p: &p.adpf_p,
            params_q: &p.adpf_q,
            s_rated: p.rating.s_rated,
            s_dvpp: p.rating.s_dvpp,
            pll_tau: crate::positive(p.pll.tau, "pll.tau")?,
            pll_order: p.pll.order,
        })?;
        let omega_b = 2.0 * PI * p.rating.f_nom;
        let data = p.converter_data();
        let design = p.inner;
        let mut inner = InnerLoops::new(&design, data, omega_b);

        // The measured operating point, taken as a steady state: the frame starts on the
        // voltage behind the virtual resistance (grid-forming) or on the grid-side voltage
        // (grid-following).
        let at_zero = m.at(0.0);
        let rho = match mode {
            Mode::GridForming => {
                let w = behind_virtual(p, &at_zero);
                dvpp_math::atan2(w.q, w.d)
            }
            Mode::GridFollowing => {
                let vg = grid_voltage(p, &at_zero, 1.0);
                dvpp_math::atan2(vg.q, vg.d)
            }
        };
        let fm = m.at(rho);
        if fm.v_c.norm() < 0.1 {
            return Err(Error::unit(format!(
                "the measured capacitor voltage is {:.4} pu: the controller starts from a running converter (set the start values of v_a, v_b, v_c to the operating point)",
                fm.v_c.norm()
            )));
        }
        let vg = grid_voltage(p, &fm, 1.0);
        let to_base = p.rating.s_rated / p.rating.s_base;
        let (p0, q0) = (vg.p(fm.i_g) * to_base, vg.q(fm.i_g) * to_base);
        let v_m = fm.v_c + fm.i_f * data.r_f + fm.i_f.rot90() * data.l_f;
        inner.settle(&fm, v_m, 1.0);
        let hinf = match (p.inner_kind, mode) {
            (InnerKind::OptionA, _) => None,
            (InnerKind::OptionB, Mode::GridForming) => Some(HinfLoop::new(
                &fm,
                v_m,
                p.vi_r,
                p.rating.s_dvpp / (p.rating.s_rated * p.tdes.dq),
                // The frame stabilizer damps a frame with inertia; a low-pass ADPF's frame
                // follows the unit's power at once and the stabilizer would feed that back
                // (docs/hinf.md §8.2).
                match p.adpf_p.kind {
                    AdpfKind::LowPass => 0.0,
                    _ => hinf_gains::STABILIZER,
                },
            )),
            (InnerKind::OptionB, Mode::GridFollowing) => return Err(Error::field(
                "inner.kind",
                "= 1 (option B, the H-infinity v-q matching) is for grid-forming units (mode = 1)",
            )),
        };
        let pll = (mode == Mode::GridFollowing).then(|| Pll::new(p.pll.kp, p.pll.ki, omega_b, rho));
        let v_dc = m.v_dc;
        let p_conv = v_m.p(fm.i_f);
        let i_src = (p_conv + data.g_dc * v_dc * v_dc) / v_dc.max(V_DC_FLOOR);
        let e0 = behind_virtual(p, &fm).d;
        let unit = EmtUnit {
            params: *p,
            omega_b,
            pf,
            vq,
            inner,
            design,
            hinf,
            hinf_limited: false,
            hinf_clear: 0.0,
            hinf_hold: HINF_HOLD,
            hinf_quick: 0,
            hinf_free: HINF_REARM,
            hinf_i_prev: fm.i_f.norm(),
            hinf_q_offset: 0.0,
            pll,
            theta: rho,
            df: 0.0,
            e_int: 0.0,
            e: e0,
            e0,
            p0,
            q0,
            v0: vg.norm(),
            q_ref: q0,
            dv_lag: 0.0,
            vg_lag: vg,
            vg_phasor: vg,
            vc_lag: fm.v_c,
            u_frt: vg.norm(),
            df_lag: 0.0,
            limited: false,
            v_pre: vg.norm(),
            frt: false,
            dv_frt: 0.0,
            iq_pre: -q0 / to_base / vg.norm(),
            v_m,
            i_g_prev: fm.i_g,
            vg_prev: vg,
            i_src,
            k_d: damping_gain(p.dc.tau_dc, data.c_dc, data.g_dc, data.k_dc, p.dc.zeta),
            warned_gains: false,
            zero_path: false,
            v_m0: 0.0,
            vg_last: vg,
            slip: 0.0,
            recovery: 0.0,
            i_filt: fm.i_f.norm(),
            tvi_active: false,
        };
        let mut notices = Vec::new();
        let limit = unit.headroom(m.t);
        if p0 > limit + 1e-12 {
            notices.push(Notice::Warning(format!(
                "dispatch p = {p0:.4} pu is above deload * P_avail - G_dc = {limit:.4} pu: the set point is curtailed from the first step"
            )));
        }
        let range = unit.source_range(m.t);
        let command = EmtCommand {
            m_abc: unit.modulation(v_dc, rho + 0.5 * p.t_s * omega_b),
            i_dc_ref: i_src,
            p_src_min: range[0],
            p_src_max: range[1],
            p: p0,
            q: q0,
            v: unit.v0,
            df: 0.0,
            theta: rho,
            e: unit.e,
            p_set: p0.min(limit),
            q_ref: q0,
            p_avail: p.source.available(m.t),
            i_ac: fm.i_f.norm(),
            limit_current: false,
            limit_modulation: false,
            limit_source: false,
            notices,
        };
        Ok((unit, command))
    }

    /// The parameters the unit runs with.
    pub fn params(&self) -> &EmtParams {
        &self.params
    }

    /// New values of the tunable parameters (`pll.kp`, `pll.ki`, `qpi.*`, `E_max`, `vq.tau`,
    /// `vi.r`, `inner.*`, `I_max`, `deload`, `P_avail0`, `avail.*`), taken from `params`; the
    /// others keep their values from initialization. The inner loops are redesigned at the next
    /// step if their design changed. Values unchanged change nothing.
    pub fn retune(&mut self, params: &EmtParams) -> Result<(), Error> {
        params.validate_inner()?;
        self.params = self.params.tuned(params);
        Ok(())
    }

    /// The highest set point the primary source allows at `t`: `deload · P_avail - G_dc`, on S_base.
    fn headroom(&self, t: f64) -> f64 {
        let p = &self.params;
        p.source.deload * p.source.available(t) - p.dc.g_dc * p.rating.s_rated / p.rating.s_base
    }

    /// What the primary source can deliver at `t`, `[0, P_avail]` or `±P_avail` for storage, on
    /// S_rated.
    fn source_range(&self, t: f64) -> [f64; 2] {
        let p = &self.params;
        let cap = p.source.available(t) * p.rating.s_base / p.rating.s_rated;
        [if p.source.storage { -cap } else { 0.0 }, cap]
    }

    /// The modulation for the converter voltage `self.v_m` at the frame angle `rho`, with the
    /// dc voltage `v_dc`.
    fn modulation(&self, v_dc: f64, rho: f64) -> [f64; 3] {
        let scale = 0.5 * self.params.vdc_ratio * v_dc.max(V_DC_FLOOR);
        let v = self.v_m.to_abc(rho);
        if self.zero_path {
            let v0 = self.v_m0;
            [v.a + v0, v.b + v0, v.c + v0].map(|x| (x / scale).clamp(-1.0, 1.0))
        } else {
            [v.a, v.b, v.c].map(|x| (x / scale).clamp(-1.0, 1.0))
        }
    }

    /// One sample: the measurements at `m.t` and the operator's gains; the command for the
    /// step that starts at `m.t + h`.
    pub fn step(
        &mut self,
        m: &EmtMeasurement,
        gains: &OperatorGains,
        h: f64,
    ) -> Result<EmtCommand, Error> {
        let t = m.t;
        let p = self.params;
        let omega_b = self.omega_b;
        let mut notices = Vec::new();
        let design = p.inner;
        if design != self.design {
            self.inner.redesign(&design, omega_b);
            self.design = design;
            notices.push(Notice::Event(format!(
                "inner loops retuned at t = {t}: current {} Hz, voltage {} Hz, I_max {}",
                design.current_hz, design.voltage_hz, design.i_max
            )));
        }
        // The frame at t: grid-forming from the reference model's angle, grid-following the PLL's.
        let rho = match &self.pll {
            Some(pll) => pll.theta(),
            None => (omega_b * t).rem_euclid(2.0 * PI) + self.theta,
        };
        let omega = 1.0 + self.df;
        let fm = m.at(rho);
        let vg = grid_voltage(&p, &fm, omega);
        let to_base = p.rating.s_rated / p.rating.s_base;
        let to_dvpp = p.rating.s_base / p.rating.s_dvpp;
        let (pw, q, v) = (vg.p(fm.i_g) * to_base, vg.q(fm.i_g) * to_base, vg.norm());
        // Option B's reference model reads the MV-side voltage with the transformer's
        // L_t di_g/dt too, which the phasor estimate `vg` leaves out: over the last sample,
        // `(vg + vg_prev)/2 - L_t (i_g - i_g,prev)/(ω_b h)` (centred, so that the estimate's
        // error is of second order in h). The converter's own current does not move that
        // voltage on a stiff grid; `vg` does move with it (by L_t di_g/dt), and the fast
        // tracking of option B would close a loop through it and the frame's swing
        // (docs/hinf.md §8).
        let dv = if self.hinf.is_some() {
            let di = (fm.i_g - self.i_g_prev) * (p.filter.l_t / (omega_b * h));
            let v_mv = (vg + self.vg_prev) * 0.5 - di;
            self.i_g_prev = fm.i_g;
            self.vg_prev = vg;
            v_mv.norm() - self.v0
        } else {
            v - self.v0
        };

        // The operator's dc gains.
        let n_lpf = p.adpf_p.n_lpf();
        let lpf = layer::operator_gains(
            &mut self.vq,
            p.adpf_q.kind,
            gains.mu_q,
            p.adpf_p.kind,
            gains.mu_p_lpf,
            n_lpf,
            p.adpf_p.share(),
            &mut self.warned_gains,
            &mut |n| notices.push(n),
        )?;
        let p_set = self.p0.min(self.headroom(t));
        let v_dc = m.v_dc;
        let v_m_max = 0.5 * p.vdc_ratio * v_dc.max(0.0);
        let (v_m, df_next, reference_limited) = match &mut self.pf {
            PfReference::Forming(pf) => {
                layer::set_p_gains(pf, p.adpf_p.kind, gains.mu_p, &lpf[..n_lpf])?;
                // Option A: the threshold virtual impedance `k (|i_f| - I_th) (1 + j X/R)`
                // (`TVI_*`) beyond `I_th`, on the voltage reference: the current a fault drives
                // turns reactive and stays below `I_max` (the limit on the reference remains
                // the bound), and its weight `w_tvi` (0 at `I_th`, 1 at `I_th + 0.05`).
                self.i_filt += (fm.i_f.norm() - self.i_filt) * (h / TVI_TAU);
                let i_th = TVI_THRESHOLD * p.inner.i_max;
                let over = if self.hinf.is_none() {
                    (self.i_filt - i_th).max(0.0)
                } else {
                    0.0
                };
                let w_tvi = (over / 0.05).min(1.0);
                self.tvi_active = over > 0.0;
                // Option A while the last sample's current reference was limited, or the
                // virtual impedance acts: the reference model reads the delivered power plus
                // the power a virtual reactance `LIMIT_X` would carry on the voltage `E - v_c`
                // (weighted in as the limit cuts deeper or the impedance grows; the frame's
                // angle ahead of the grid's shows as `ev_q > 0`), so that the frame keeps
                // synchronized with the grid while the current, hence the power, is held.
                let limited = self.hinf.is_none() && (self.inner.current_limited() || w_tvi > 0.0);
                let p_model = if limited {
                    let ev_limit = self.inner.limit_error();
                    let ev_tvi = (Dq { d: self.e, q: 0.0 } - fm.v_c) * w_tvi;
                    let ev = if ev_tvi.norm() > ev_limit.norm() {
                        ev_tvi
                    } else {
                        ev_limit
                    };
                    pw + self.e * ev.q / LIMIT_X * to_base
                } else {
                    pw
                };
                // Option A: the frame's damping against the grid, while the current is limited
                // and over the recovery after (`SLIP_RECOVERY`, fading out over its last
                // `SLIP_FADE`). The frame's speed against the MV voltage (the slip: the angle
                // the voltage turns back in the frame per sample), through `SLIP_TAU`, read by
                // the reference model as the power `D_slip · slip` (`D_slip` = `SLIP_DAMPING ·
                // Tdes.D`, on S_dvpp, at most `SLIP_MAX` of the rating): it damps the frame's
                // swing against the grid after a fault (with the q PI's E, 1.7 Hz, ζ 0.1
                // without it). Unlimited operation is untouched (the slip is tracked, unread).
                let damping = if self.hinf.is_none() {
                    let last = self.vg_last;
                    let turn = dvpp_math::atan2(last.d * vg.q - last.q * vg.d, last.p(vg));
                    self.vg_last = vg;
                    self.slip += (-turn / (omega_b * h) - self.slip) * (h / SLIP_TAU);
                    if limited {
                        self.recovery = SLIP_RECOVERY;
                    } else {
                        self.recovery = (self.recovery - h).max(0.0);
                    }
                    let max = SLIP_MAX / to_dvpp * to_base;
                    let fade = (self.recovery / SLIP_FADE).min(1.0);
                    (self.recovery > 0.0)
                        .then(|| (fade * SLIP_DAMPING * p.tdes.d * self.slip).clamp(-max, max))
                } else {
                    None
                };
                let dp = (p_model - p_set) * to_dvpp;
                let dp = damping.map_or(dp, |d| dp + d);
                let (df, dtheta) = layer::forming_angle(pf, dp, h, p.rating.f_nom);
                // Option B: the state feedback on the reactive error of this sample; option A:
                // the q PI sets E.
                let b = match self.hinf.as_mut() {
                    Some(hl) => {
                        // Option B's current limit (docs/hinf.md §8.5): when the converter
                        // current is about to pass I_max the unit hands over to option A's
                        // current-limited cascade, the q PI at the present E and both loops'
                        // integrals at their steady-state values for the present capacitor
                        // voltage and grid current; it takes back when no limit has acted for
                        // HINF_HOLD, the state feedback's integrals set so that its first
                        // command repeats the last one.
                        let i_f = fm.i_f.norm();
                        let i_ahead = i_f + HINF_LOOKAHEAD * (i_f - self.hinf_i_prev).max(0.0);
                        self.hinf_i_prev = i_f;
                        if !self.hinf_limited && i_ahead > p.inner.i_max {
                            self.hinf_limited = true;
                            self.hinf_clear = 0.0;
                            if self.hinf_free < HINF_REARM {
                                self.hinf_quick += 1;
                            } else {
                                self.hinf_quick = 0;
                            }
                            self.hinf_hold = if self.hinf_quick >= 2 {
                                (2.0 * self.hinf_hold).min(HINF_HOLD_MAX)
                            } else {
                                HINF_HOLD
                            };
                            self.hinf_q_offset = 0.0;
                            let e = self.q_ref - q;
                            self.e_int = behind_virtual(&p, &fm).d
                                - self.e0
                                - p.qpi.kp * e
                                - p.qpi.ki * e * h;
                            // The steady state at the present v_c and i_g: i_f = i_g + jωC_f v_c
                            // (the voltage loop's integral zero) and v_m = v_c + (R_f + jωL_f) i_f
                            // (the current loop's R_f i_f). Settled to the measured i_f and the
                            // last command instead, the integrals kept the transient's
                            // C_f dv_c/dt and L_f di_f/dt: the current rose on to 1.47 pu in the
                            // 30 % dip and stayed at I_max for a second after it.
                            let data = p.converter_data();
                            let steady = FilterMeasurement {
                                i_f: fm.i_g + fm.v_c.rot90() * (omega * data.c_f),
                                ..fm
                            };
                            self.inner.settle(
                                &steady,
                                HinfLoop::steady_voltage(&data, &steady, omega),
                                omega,
                            );
                            notices.push(Notice::Event(format!(
                                "option B: the converter current reached {i_f:.3} pu \
                                 (I_max {}) at t = {t} s: current-limited mode (option A's \
                                 cascade)",
                                p.inner.i_max
                            )));
                        } else if self.hinf_limited && self.hinf_clear >= self.hinf_hold {
                            self.hinf_limited = false;
                            self.hinf_free = 0.0;
                            self.hinf_q_offset = (q - self.q_ref) / to_base;
                            hl.resume(
                                &fm,
                                self.v_m,
                                (self.q_ref - self.q0) / to_base + self.hinf_q_offset,
                                self.vq.mu_q(),
                            );
                            notices.push(Notice::Event(format!(
                                "option B: no limit for {} s at t = {t} s: the H-infinity \
                                 state feedback takes over again",
                                self.hinf_hold
                            )));
                        }
                        if self.hinf_limited {
                            self.e = layer::voltage_matching(
                                &mut self.e_int,
                                self.q_ref,
                                q,
                                self.e0,
                                p.qpi.kp,
                                p.qpi.ki,
                                p.qpi.e_max,
                                h,
                            );
                            None
                        } else {
                            // The reference, plus what is left of the error at the hand-back.
                            let mut dq_ref = (self.q_ref - self.q0) / to_base;
                            if self.hinf_q_offset != 0.0 {
                                dq_ref += self.hinf_q_offset;
                            }
                            let v = hl.step(
                                &fm,
                                (q - self.q0) / to_base,
                                dq_ref,
                                self.vq.mu_q(),
                                self.df,
                                v_m_max,
                                omega_b,
                                h,
                            );
                            self.e = behind_virtual(&p, &fm).d;
                            if self.hinf_free < HINF_REARM {
                                self.hinf_free += h;
                            }
                            if self.hinf_q_offset != 0.0 {
                                self.hinf_q_offset *= dvpp_math::exp(-h / HINF_REENTRY_TAU);
                                if self.hinf_q_offset.abs() < 1e-15 {
                                    self.hinf_q_offset = 0.0;
                                }
                            }
                            Some(v)
                        }
                    }
                    None => {
                        // While limited the q PI's integral holds (the reactive power follows
                        // the limited current, not E).
                        let held = self.e_int;
                        self.e = layer::voltage_matching(
                            &mut self.e_int,
                            self.q_ref,
                            q,
                            self.e0,
                            p.qpi.kp,
                            p.qpi.ki,
                            p.qpi.e_max,
                            h,
                        );
                        if limited {
                            self.e_int = held;
                        }
                        None
                    }
                };
                self.q_ref = self.q0 + self.vq.step(dv, h) / to_dvpp;
                self.theta += dtheta;
                let v_m = b.unwrap_or_else(|| {
                    // The capacitor-voltage reference behind the virtual resistance.
                    let mut v_ref = Dq { d: self.e, q: 0.0 } - fm.i_g * p.vi_r;
                    if over > 0.0 {
                        let k = TVI_GAIN * over;
                        v_ref = v_ref - (fm.i_g + fm.i_g.rot90() * TVI_X_R) * k;
                    }
                    let e = Dq { d: self.e, q: 0.0 };
                    self.inner.step(&fm, v_ref, e, omega, v_m_max, h)
                });
                if self.hinf_limited {
                    let clear = !(self.inner.current_limited()
                        || self.inner.modulation_limited()
                        || self.e <= 0.0
                        || self.e >= p.qpi.e_max
                        || fm.i_f.norm() > p.inner.i_max);
                    self.hinf_clear = if clear { self.hinf_clear + h } else { 0.0 };
                }
                (v_m, df, false)
            }
            PfReference::Following(fp) => {
                layer::set_p_gains(fp, p.adpf_p.kind, gains.mu_p, &lpf[..n_lpf])?;
                let dp = fp.step(self.df_lag, h) / to_dvpp;
                let tau_v = p.vq_tau;
                let kv = if tau_v > 0.0 {
                    -dvpp_math::expm1(-h / tau_v)
                } else {
                    1.0
                };
                // While the reactive current is limited, the voltage deviation's lag does not
                // move further from zero (anti-windup: the reactive reference it drives cannot
                // be delivered, and would hold the active current at zero after the voltage
                // returns); in a fault ride-through it holds (the k-factor injection is the
                // response, and the droop takes over from where it was when the voltage is back).
                let step = kv * (dv - self.dv_lag);
                let away = self.limited && step * self.dv_lag > 0.0;
                if !(away || self.frt) {
                    self.dv_lag += step;
                }
                self.q_ref = self.q0 + self.vq.step(self.dv_lag, h) / to_dvpp;
                // The grid-side current for the references at the measured voltage magnitude,
                // in the PLL's frame (the d axis on the voltage): the PLL alone places the
                // current. Taken as `conj(S/v_g)` from the voltage's dq value, the current would
                // turn with the voltage's angle through `REFERENCE_TAU`, a second synchronization
                // of about 160 Hz bandwidth that the unit's own current moves on a weak grid
                // (docs/emt.md, grid-following on weak grids).
                // The MV voltage with the transformer's `L_t di_g/dt` (centred over the last
                // sample, as option B's): the phasor relation alone, `v_c - (R_t + jX_t) i_g`,
                // reads the dc offsets of the currents after a voltage step (a 50 Hz component
                // in dq, times X_t) as a swing of the voltage's angle of tens of degrees, on which
                // the PLL swings by Hz and the current reference turns (docs/emt.md §9).
                // The current reference's magnitude `|v|` stays on the phasor estimate: taken
                // from `v_mv`, the derivative of the unit's own current closes a loop through it
                // (measured on the generic unit at SCR 10: a sustained oscillation of the PLL's
                // frequency by ±0.07 Hz and of the voltage by ±0.02 pu after a dip).
                let k = -dvpp_math::expm1(-h / REFERENCE_TAU);
                let di = (fm.i_g - self.i_g_prev) * (p.filter.l_t / (omega_b * h));
                let v_mv = (vg + self.vg_prev) * 0.5 - di;
                self.i_g_prev = fm.i_g;
                self.vg_prev = vg;
                self.vg_lag = self.vg_lag + (v_mv - self.vg_lag) * k;
                self.vg_phasor = self.vg_phasor + (vg - self.vg_phasor) * k;
                let k_c = -dvpp_math::expm1(-h / CAPACITOR_TAU);
                self.vc_lag = self.vc_lag + (fm.v_c - self.vc_lag) * k_c;
                // The active reference within what the primary source can take: a unit without
                // storage (`[0, P_avail]`) cannot absorb more than its dc link's losses, and the
                // p-f model's inertia and droop ask it to when the frequency rises (+5 Hz/s: the
                // dc link charged to 1.3 pu, the converter saturated its modulation and lost
                // synchronism).
                let p_min = self.source_range(t)[0] - p.dc.g_dc;
                let (pr, qr) = (((p_set + dp) / to_base).max(p_min), self.q_ref / to_base);
                let u = self.vg_phasor.norm().max(1e-2);
                let mut i_g = Dq {
                    d: pr / u,
                    q: -qr / u,
                };
                // Fault ride-through: beyond the dead band of the voltage before the event, the
                // reactive current is the one before it plus `K_FRT` times the deviation beyond
                // the band (through `FRT_TAU`, which also ramps it out after the event), the
                // active current `p/|v|` as before; the reactive-first limit below keeps the sum
                // within I_max.
                let u_mv = self.vg_lag.norm();
                self.u_frt += -dvpp_math::expm1(-h / FRT_DETECT_TAU) * (u_mv - self.u_frt);
                let dev = self.v_pre - u_mv;
                // Entering on the voltage through `FRT_DETECT_TAU` (not on the first swing of the
                // capacitor's ringing), leaving on the voltage itself (within the hysteresis).
                let frt = if self.frt {
                    dev.abs() > FRT_BAND - FRT_HYSTERESIS
                } else {
                    (self.v_pre - self.u_frt).abs() > FRT_BAND
                };
                self.frt = frt;
                let dev_f = self.v_pre - self.u_frt;
                let beyond = if frt {
                    dev_f - FRT_BAND * dev_f.signum()
                } else {
                    0.0
                };
                self.dv_frt += -dvpp_math::expm1(-h / FRT_TAU) * (beyond - self.dv_frt);
                if frt {
                    i_g.q = self.iq_pre;
                } else {
                    self.iq_pre = i_g.q;
                    self.v_pre += -dvpp_math::expm1(-h / V_PRE_TAU) * (u_mv - self.v_pre);
                }
                i_g.q -= K_FRT * self.dv_frt;
                // Plus the capacitor's current: the converter-side reference, limited to I_max
                // reactive current first.
                let raw = i_g + self.vc_lag.rot90() * (omega * p.filter.c_f);
                let (i_ref, limited, reactive) = reactive_first(raw, p.inner.i_max);
                self.limited = reactive;
                let v_m = self.inner.current(&fm, i_ref, omega, v_m_max, h);
                let pll = self.pll.as_mut().expect("grid-following PLL");
                pll.kp = p.pll.kp;
                pll.ki = p.pll.ki;
                // Below `PLL_HOLD` the voltage's angle is the unit's own current through the
                // fault's impedance, not the grid's: the PLL holds its frequency.
                if self.frt && u_mv < PLL_HOLD {
                    pll.hold(h);
                } else {
                    pll.step(self.vg_lag.to_abc(rho), h);
                }
                let df = pll.delta_f();
                // The p-f reference model does not read the PLL through a fault (its inertia
                // would turn the PLL's swing at the fault's edges into active power).
                if !self.frt {
                    self.df_lag += -dvpp_math::expm1(-h / FREQUENCY_TAU) * (df - self.df_lag);
                }
                (v_m, df, limited)
            }
        };
        // The dc-voltage command: converter power and link losses fed forward, k_dc on the
        // stored energy, the damping term on the capacitor's power (as the phasor DER).
        let p_conv = self.v_m.p(fm.i_f);
        let (c_dc, g_dc) = (p.dc.c_dc, p.dc.g_dc);
        let stored = 0.5 * c_dc * (v_dc * v_dc - 1.0);
        let charging = self.i_src * v_dc - g_dc * v_dc * v_dc - p_conv;
        let command = p_conv + g_dc * v_dc * v_dc - p.dc.k_dc / c_dc * stored - self.k_d * charging;
        // The command drives the source's lag unclamped; the source stays within its range
        // (modelled here as the host's source model does it: cut at once to a range that fell,
        // held at a bound the lag reaches).
        let range = self.source_range(t + h);
        let v_range = v_dc.max(V_DC_FLOOR);
        let (lo, hi) = (range[0] / v_range, range[1] / v_range);
        let i_cmd = command / v_range;
        let i0 = self.i_src.clamp(lo, hi);
        self.i_src = (i_cmd + (i0 - i_cmd) * dvpp_math::exp(-h / p.dc.tau_dc)).clamp(lo, hi);
        // The source's limit as any host sees it: the power the converter draws from its dc side
        // (its ac power and the link's losses) is outside what the source can deliver now, so
        // the dc link (or a host's ideal dc supply, where it models no link) makes up the rest.
        let drawn = p_conv + g_dc * v_dc * v_dc;
        let now = self.source_range(t);
        let source = drawn > now[1] || drawn < now[0];

        // Zero sequence (grid-forming, option A): the dq loops see none. A three-wire converter
        // carries none; once a zero-sequence current shows (a grounded star: the converter's dc
        // midpoint, the filter capacitors' star and the transformer's), the converter's
        // zero-sequence voltage follows the capacitors' and drives the current to zero at the
        // current loop's gain, so that it adds nothing to the phase currents.
        if self.hinf.is_none() && matches!(self.pf, PfReference::Forming(_)) {
            let i_0 = (m.i_f.a + m.i_f.b + m.i_f.c) / 3.0;
            if i_0.abs() > ZERO_SEQUENCE_SEEN {
                self.zero_path = true;
            }
            if self.zero_path {
                let v_c0 = (m.v_c.a + m.v_c.b + m.v_c.c) / 3.0;
                self.v_m0 = v_c0 - self.inner.gains().kp_i * i_0;
            }
        }
        self.v_m = v_m;
        self.df = df_next;
        let rho_out = rho + 1.5 * h * omega_b * (1.0 + df_next);
        let i_ac = fm.i_f.norm();
        Ok(EmtCommand {
            m_abc: self.modulation(v_dc, rho_out),
            i_dc_ref: i_cmd,
            p_src_min: range[0],
            p_src_max: range[1],
            p: pw,
            q,
            v,
            df: df_next,
            theta: match &self.pll {
                Some(pll) => (pll.theta() - omega_b * (t + h) + PI).rem_euclid(2.0 * PI) - PI,
                None => self.theta,
            },
            e: self.e,
            p_set,
            q_ref: self.q_ref,
            p_avail: p.source.available(t + h),
            i_ac,
            limit_current: match self.hinf {
                // Option B: the current-limited mode runs.
                Some(_) => self.hinf_limited,
                None => reference_limited || self.inner.current_limited() || self.tvi_active,
            },
            limit_modulation: match &self.hinf {
                Some(hl) if !self.hinf_limited => hl.modulation_limited(),
                _ => self.inner.modulation_limited(),
            },
            limit_source: source,
            notices,
        })
    }
}

/// The voltage at the MV side of the transformer, `v_c - (R_t + j ω L_t) i_g` (the phasor
/// relation in the frame turning at `omega` pu).
fn grid_voltage(p: &EmtParams, m: &FilterMeasurement, omega: f64) -> Dq {
    m.v_c - m.i_g * p.filter.r_t - m.i_g.rot90() * (omega * p.filter.l_t)
}

/// A grid-following unit's converter-current reference `raw` (dq in the PLL's frame: d active,
/// q reactive) within `I_max`, reactive current first: `|i_q| ≤ I_max`, then
/// `|i_d| ≤ √(I_max² - i_q²)`; whether it was limited, and whether its reactive current was. In
/// a dip the voltage-reactive reference keeps the current it asks for and the active current
/// yields (the priority of the reactive current in fault ride-through that grid codes ask, e.g.
/// VDE-AR-N 4120).
fn reactive_first(raw: Dq, i_max: f64) -> (Dq, bool, bool) {
    let q = raw.q.clamp(-i_max, i_max);
    let d_max = (i_max * i_max - q * q).max(0.0).sqrt();
    let d = raw.d.clamp(-d_max, d_max);
    (Dq { d, q }, d != raw.d || q != raw.q, q != raw.q)
}

/// The voltage behind the virtual resistance, `v_c + r_v i_g`: the grid-forming frame and `E`
/// start on it.
fn behind_virtual(p: &EmtParams, m: &FilterMeasurement) -> Dq {
    m.v_c + m.i_g * p.vi_r
}
