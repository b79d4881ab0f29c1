//! EMT plant model (the `dvpp_emt_plant` FMU; its binary is `fmu/`): the power stage of N
//! grid-forming converters on one MV point of common coupling (PCC), with a Thevenin source and
//! switchable series R-L loads, for a controller FMU that closes the loop at 20-50 µs.
//!
//! # Per unit
//! - Each unit's ac quantities are pu on its own rating `S_rated` (MVA): voltages of the rated
//!   phase-to-neutral peak `v_r`, currents of the rated peak current, amplitude invariant, so
//!   `p = (2/3)(v_a i_a + v_b i_b + v_c i_c) = v_α i_α + v_β i_β` pu on `S_rated`.
//! - Dc side: `v_dc` pu of its nominal `v_dc* = 3 v_r`; `i_src` pu of `S_rated/v_dc*`. The
//!   averaged two-level converter makes `v_conv,x = (3/2) m_x v_dc` (pu of `v_r`), `m_x` the
//!   modulation index of phase x, clamped to [-1, 1] (`der[k].m_clamped` then true). The
//!   modulation's zero sequence drives no current (three-wire) and is dropped.
//! - The network (PCC, Thevenin source, loads) is pu on `S_base` at the MV nominal voltage
//!   (peak phase-neutral base). The transformer is an ideal ratio plus `R_t`, `L_t`: voltages
//!   carry over unchanged, currents scale by `S_rated/S_base`, impedances by `S_base/S_rated`.
//! - Inductances and capacitances are given as reactance and susceptance at `ω_b = 2π f_nom`
//!   (`L = X/ω_b` in pu·s). `C_dc` is the dc link's energy time constant in seconds (stored
//!   energy `C_dc v_dc²/2` pu·s on `S_rated`, as in the DER model).
//! - Energies are in MJ (pu·s times the base in MVA). Angles refer to the start of the run:
//!   the Thevenin source is `e_a(t) = E cos(ω_b (t - t_0) + angle)`, `t_0` the first
//!   communication point (`e_b`, `e_c` lag by 120° and 240°).
//!
//! # Circuit
//! Per unit: `L_f i_f' = v_conv - R_f i_f - v_c`, `C_f v_c' = i_f - i_g`,
//! `L_t i_g' = v_c - R_t i_g - v_pcc` (divided by `ω_b`); dc side `τ_dc i_src' = i_dc_ref - i_src`,
//! `C_dc v_dc v_dc' = v_dc i_src - G_dc v_dc² - p_conv` with `p_conv = v_conv · i_f`
//! (see [`dc`]). The PCC joins only inductive branches (transformers, the Thevenin `R + jX`
//! behind `e`, the loads' `R + jX`), so `v_pcc` is algebraic and eliminated: differentiating
//! KCL and inserting the branch equations gives `v_pcc` as a linear combination of branch
//! currents, capacitor voltages and `e` ([`network::Network::vpcc_coefficients`]); no shunt
//! capacitance is added. The circuit is three-wire and balanced and integrated in the
//! stationary αβ frame; outputs are converted back to abc.
//!
//! # Discretization
//! The step is exact: the Thevenin source enters as an undamped oscillator (two states), the
//! converter voltage `(3/2) m v_dc` (from `m` and `v_dc` at the step's start) as held states, and
//! `z(t+h) = exp(M h) z(t)`; the energies over the step are exact quadratic forms
//! ([`network`]). The matrix exponentials are cached per step size and topology (connected
//! loads, Thevenin on/off, hold) and recomputed when either changes. The LC filter resonates
//! near 490 Hz (`1/√(L_f C_f)` = 9.8 pu) and the LCL near 710 Hz (14.2 pu): an explicit
//! integrator would need steps well below 20 µs and still add numerical damping; the exact
//! zero-order-hold step is stable at any step and exact for the held inputs.
//!
//! `hold` = 0 (default) holds the converter voltage's abc values over the step (zero-order
//! hold, as a digital controller's PWM update does: on average a delay of `h/2`, so a
//! controller should send the modulation for the middle of the step, its angle advanced by
//! `ω h/2`, which leaves an error of second order in `h`); `hold` = 1 turns the held space
//! vector at `ω_b` over the step, which reproduces a nominal-frequency sinusoid exactly (a
//! flat start then stays flat to rounding).
//!
//! # Switching and events
//! A load connects (with zero current, as an inductor must) at the first step boundary at or
//! after `load[j].t_on` (0: from the start, negative or `load[j].enabled` = false: never);
//! masters step on a fixed grid, so the switching instant is that grid point. Loads are not
//! switched off (an inductive current cannot be interrupted without an arc model). The
//! Thevenin dip (`E (1 - dip)` during `[dip_t, dip_t + dip_duration)`), phase jump
//! (`angle + jump` from `jump_t`), voltage step (`E + step` from `step_t`) and frequency ramp
//! (`thevenin.rocof` from `rocof_t` for `rocof_duration`, then held; the oscillator's angle is set
//! at each step's start to pass the ramp's exact angle at the step's middle) act likewise at step
//! boundaries.
//!
//! # Test bench
//! Faults (balanced and unbalanced, at the PCC or the source bus), a line and a switchable
//! parallel line from the source bus, the source's breaker and grounded units change the circuit:
//! when any of them is configured the plant runs on [`mod@bench`]'s αβ0 circuit (parameters and
//! steps in `events.rs`); without them it runs on the balanced αβ circuit above, unchanged.
//!
//! # Initialization
//! The plant starts in the circuit's sinusoidal steady state. With the Thevenin source
//! connected it is the slack and unit k injects `der[k].p0 + j der[k].q0` (pu on `S_base`) at
//! the PCC (Newton's method on the PCC voltage); without it, unit 1's capacitor voltage is
//! `der[1].v0` at angle 0 and the other units inject their start powers. Loads with
//! `t_on = 0` are connected. The dc links sit at `v_dc = 1` with `i_src = p_conv + G_dc`.
//! A controller initializes from the measurements alone with the phasor relation
//! `v_conv = v_c + (R_f + jX_f) i_f` (peak phasors from the abc samples, `X_f = L_f`) and
//! `m = v_conv / (1.5 v_dc)`, `i_dc_ref = i_src`.
//!
//! The PCC frequency `pcc.df` and angle `pcc.theta` come from a measurement SRF-PLL
//! ([`meter::Pll`], `pll.kp` = 60, `pll.ki` = 240 as the paper's PLL), a meter only.

pub mod bench;
pub mod config;
pub mod dc;
mod events;
pub mod meter;
pub mod network;
pub mod steady;

use config::{Layout, PlantConfig};
use dc::{DcParams, DcState};
use fmi_export::{Boolean, Context, Integer, Model, ModelError, Real, Spec, Store, Variables};
use meter::{clarke, inverse_clarke, wrap, Pll};
use nalgebra::DVector;
use network::{Branch, Cache, Network, Topology, UnitData};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use steady::{Slack, C};

/// Handles of one unit's variables.
#[derive(Clone, Serialize, Deserialize)]
struct UnitVars {
    s_rated: Real,
    r_f: Real,
    l_f: Real,
    c_f: Real,
    r_t: Real,
    l_t: Real,
    c_dc: Real,
    g_dc: Real,
    tau_dc: Real,
    p0: Real,
    q0: Real,
    /// Unit 1 only: its capacitor voltage when it is the slack.
    v0: Option<Real>,
    m: [Real; 3],
    i_dc_ref: Real,
    /// The source's power range `[p_min, p_max]` (S_rated).
    p_src: [Real; 2],
    v: [Real; 3],
    i: [Real; 3],
    ig: [Real; 3],
    v_dc: Real,
    i_src: Real,
    p: Real,
    q: Real,
    m_clamped: Boolean,
}

impl UnitVars {
    /// The unit's modulation indices, each clamped to [-1, 1]; `m_clamped` says whether any was.
    fn modulation(&self, s: &mut Store) -> [f64; 3] {
        let mut clamped = false;
        let m = self.m.map(|r| {
            let m = s[r];
            clamped |= m.abs() > 1.0;
            m.clamp(-1.0, 1.0)
        });
        s[self.m_clamped] = clamped;
        m
    }
}

/// Handles of one load's variables.
#[derive(Clone, Serialize, Deserialize)]
struct LoadVars {
    p_set: Real,
    q_set: Real,
    t_on: Real,
    enabled: Boolean,
    p: Real,
    q: Real,
}

/// Handles of the Thevenin source's variables.
#[derive(Clone, Serialize, Deserialize)]
struct TheveninVars {
    enabled: Boolean,
    r: Real,
    x: Real,
    e: Real,
    angle: Real,
    dip: Real,
    dip_t: Real,
    dip_duration: Real,
    jump: Real,
    jump_t: Real,
    h: Real,
    d: Real,
    i: [Real; 3],
    p: Real,
    q: Real,
    df: Real,
}

/// Handles of the energy outputs.
#[derive(Clone, Serialize, Deserialize)]
struct EnergyVars {
    source: Real,
    ac: Real,
    dc_loss: Real,
    dc_stored: Real,
    ac_loss: Real,
    thevenin: Real,
    loads: Real,
    ac_stored: Real,
}

/// Energies since initialization, MJ.
#[derive(Clone, Copy, Default, Serialize, Deserialize)]
struct Energies {
    source: f64,
    ac: f64,
    dc_loss: f64,
    ac_loss: f64,
    thevenin: f64,
    loads: f64,
    /// Dissipated in the fault's impedance (test bench).
    fault: f64,
    /// Removed by breakers interrupting inductive currents (test bench).
    switching: f64,
}

/// What initialization fixed: the circuit, the dc parameters, the events.
#[derive(Clone, Serialize, Deserialize)]
struct Fixed {
    net: Network,
    dc: Vec<DcParams>,
    omega_b: f64,
    rotating_hold: bool,
    thevenin_on: bool,
    /// E, angle, dip, dip_t, dip_duration, jump, jump_t.
    source: [f64; 7],
    /// The source's swing `(H, D)` on S_base (none: stiff).
    swing: Option<(f64, f64)>,
    /// Time constant of the PCC frequency's lag after the meter's PLL, s.
    f_filter_t: f64,
    /// Per load: connected from this time on (None: never).
    t_on: Vec<Option<f64>>,
    pll_gains: (f64, f64),
    /// The source's voltage step `(ΔE, t)` and frequency ramp `(RoCoF Hz/s, t, duration)`.
    v_step: Option<(f64, f64)>,
    ramp: Option<(f64, f64, f64)>,
    f_nom: f64,
    /// The test bench's circuit and switching times, when a bench element is configured.
    bench: Option<events::BenchFixed>,
}

/// The running state.
#[derive(Clone, Serialize, Deserialize)]
struct Run {
    /// Circuit states, α axis then β axis.
    x: Vec<f64>,
    /// The Thevenin oscillator at the time of `x` (α, β).
    e: [f64; 2],
    dc: Vec<DcState>,
    pll: Pll,
    energy: Energies,
    /// First communication point (the angles' reference), once known.
    t0: Option<f64>,
    /// The topology of the last step (for the PCC voltage of the current state).
    topo: Topology,
    /// The swinging source: angle beyond `ω_b t` (rad), speed deviation (pu), mechanical power
    /// (pu on S_base, its initial electrical power).
    delta: f64,
    dw: f64,
    p_m: f64,
    /// The PCC frequency deviation after the lag `pcc.f_filter_t`.
    df_lag: f64,
    /// The test bench's topology of the last step.
    btopo: bench::BenchTopo,
    /// The fault branches' currents at the last step's start (for clearing at current zero).
    fault_last: Vec<f64>,
    /// The end of the last step (None before the first).
    t_end: Option<f64>,
}

/// The EMT plant's variables and state.
#[derive(Clone, Serialize, Deserialize)]
pub struct Plant {
    layout_units: usize,
    s_base: Real,
    f_nom: Real,
    hold: Integer,
    pll_kp: Real,
    pll_ki: Real,
    units: Vec<UnitVars>,
    loads: Vec<LoadVars>,
    thevenin: Option<TheveninVars>,
    pcc_v: [Real; 3],
    pcc_mag: Real,
    pcc_df: Real,
    pcc_theta: Real,
    pcc_p: Real,
    pcc_q: Real,
    pcc_f: Real,
    pcc_f_filter_t: Real,
    energy: EnergyVars,
    /// The test bench's parameters and outputs (declared last).
    bench: events::BenchVars,
}

/// The EMT plant's running state: what initialization fixes from the parameters, the circuit's
/// state, and the discretizations computed so far.
#[derive(Clone, Serialize, Deserialize)]
pub struct PlantState {
    fixed: Fixed,
    run: Run,
    /// Rebuilt on demand after a restore.
    #[serde(skip)]
    cache: Cache,
    #[serde(skip)]
    bench_cache: bench::BenchCache,
}

const PHASES: [&str; 3] = ["a", "b", "c"];
/// The start of a unit's source-range inputs (pu on S_rated): far beyond any converter, so a
/// host that does not wire them gets the lag alone.
const SOURCE_UNBOUNDED: f64 = 1e3;

fn positive(s: &Store, r: Real, name: &str) -> Result<f64, ModelError> {
    let x = s[r];
    if x > 0.0 && x.is_finite() {
        Ok(x)
    } else {
        Err(ModelError(format!(
            "parameter '{name}' = {x} must be positive"
        )))
    }
}

fn non_negative(s: &Store, r: Real, name: &str) -> Result<f64, ModelError> {
    let x = s[r];
    if x >= 0.0 && x.is_finite() {
        Ok(x)
    } else {
        Err(ModelError(format!(
            "parameter '{name}' = {x} must not be negative"
        )))
    }
}

fn unit_name(k: usize, what: &str) -> String {
    format!("der[{}].{what}", k + 1)
}

impl Plant {
    fn declare_unit(v: &mut Variables, k: usize, u: &config::UnitSpec) -> UnitVars {
        let n = |w: &str| unit_name(k, w);
        let who = format!("unit {} ({}, {} MVA)", k + 1, u.name, u.s_rated);
        let par = |v: &mut Variables, w: &str, start: f64, unit: &str, what: &str| {
            v.real(Spec::parameter(&n(w), start, unit, &format!("{who}: {what}")).min(0.0))
        };
        let s_rated = par(v, "S_rated", u.s_rated, "MVA", "rating S_rated");
        let r_f = par(v, "R_f", 0.01, "pu", "filter resistance, on S_rated");
        let l_f = par(
            v,
            "L_f",
            0.11,
            "pu",
            "filter inductance as reactance at f_nom, on S_rated",
        );
        let c_f = par(
            v,
            "C_f",
            0.0942,
            "pu",
            "filter capacitance as susceptance at f_nom, on S_rated",
        );
        let r_t = par(
            v,
            "R_t",
            0.01,
            "pu",
            "LV/MV transformer resistance, on S_rated",
        );
        let l_t = par(
            v,
            "L_t",
            0.1,
            "pu",
            "LV/MV transformer leakage inductance as reactance at f_nom, on S_rated",
        );
        let c_dc = par(
            v,
            "C_dc",
            0.096,
            "s",
            "dc-link capacitance as energy time constant: stored energy C_dc v_dc^2/2 pu s on S_rated",
        );
        let g_dc = par(
            v,
            "G_dc",
            0.05,
            "pu",
            "dc-link conductance (losses G_dc v_dc^2), on S_rated",
        );
        let tau_dc = par(v, "tau_dc", u.tau_dc, "s", "primary-source lag tau_dc");
        let p0 = v.real(Spec::parameter(
            &n("p0"),
            u.p0,
            "pu",
            &format!("{who}: active power injected at the PCC at initialization, on S_base (with the Thevenin source as slack)"),
        ));
        let q0 = v.real(Spec::parameter(
            &n("q0"),
            u.q0,
            "pu",
            &format!("{who}: reactive power injected at the PCC at initialization, on S_base"),
        ));
        let v0 = (k == 0).then(|| {
            par(
                v,
                "v0",
                1.0,
                "pu",
                "capacitor-voltage magnitude at initialization when this unit is the slack (Thevenin source absent or disabled), angle 0",
            )
        });
        let m = PHASES.map(|x| {
            v.real(Spec::input(
                &n(&format!("m_{x}")),
                0.0,
                "1",
                &format!("{who}: modulation index of phase {x}, v_conv = 1.5 m v_dc (clamped to [-1, 1])"),
            ))
        });
        let i_dc_ref = v.real(Spec::input(
            &n("i_dc_ref"),
            0.0,
            "pu",
            &format!("{who}: primary-source current command, pu of S_rated/v_dc*"),
        ));
        let p_src = [
            ("p_src_min", -SOURCE_UNBOUNDED, "lowest", "0 for a source that cannot absorb, -P_avail for storage"),
            ("p_src_max", SOURCE_UNBOUNDED, "highest", "the available power P_avail"),
        ]
        .map(|(name, start, which, what)| {
            v.real(Spec::input(
                &n(name),
                start,
                "pu",
                &format!(
                    "{who}: the {which} power the primary source can deliver, on S_rated ({what}; from the \
                     unit's controller; the start value leaves the source unbounded)"
                ),
            ))
        });
        let out = |v: &mut Variables, w: String, what: String| {
            v.real(Spec::output(&n(&w), "pu", &format!("{who}: {what}")))
        };
        let vc = PHASES.map(|x| {
            out(
                v,
                format!("v_{x}"),
                format!("filter-capacitor voltage, phase {x}, pu of v_r"),
            )
        });
        let i = PHASES.map(|x| {
            out(
                v,
                format!("i_{x}"),
                format!("converter-side filter current i_f, phase {x}, on S_rated"),
            )
        });
        let ig = PHASES.map(|x| {
            out(
                v,
                format!("ig_{x}"),
                format!("transformer current toward the PCC, phase {x}, on S_rated"),
            )
        });
        let v_dc = out(v, "v_dc".into(), "dc-link voltage, pu of v_dc*".into());
        let i_src = out(
            v,
            "i_src".into(),
            "primary-source current, pu of S_rated/v_dc*".into(),
        );
        let p = out(
            v,
            "p".into(),
            "active power into the PCC through the transformer, on S_base".into(),
        );
        let q = out(
            v,
            "q".into(),
            "reactive power into the PCC through the transformer, on S_base".into(),
        );
        let m_clamped = v.boolean(Spec::boolean_output(
            &n("m_clamped"),
            &format!("{who}: a modulation index was clamped to [-1, 1] in the last step"),
        ));
        UnitVars {
            s_rated,
            r_f,
            l_f,
            c_f,
            r_t,
            l_t,
            c_dc,
            g_dc,
            tau_dc,
            p0,
            q0,
            v0,
            m,
            i_dc_ref,
            p_src,
            v: vc,
            i,
            ig,
            v_dc,
            i_src,
            p,
            q,
            m_clamped,
        }
    }

    fn declare_load(v: &mut Variables, j: usize, l: &config::LoadSpec) -> LoadVars {
        let n = |w: &str| format!("load[{}].{w}", j + 1);
        let who = format!("load {} ({})", j + 1, l.name);
        LoadVars {
            p_set: v.real(
                Spec::parameter(
                    &n("P"),
                    l.p,
                    "pu",
                    &format!("{who}: active power at 1 pu voltage (series R-L), on S_base"),
                )
                .min(0.0),
            ),
            q_set: v.real(
                Spec::parameter(
                    &n("Q"),
                    l.q,
                    "pu",
                    &format!("{who}: reactive power at 1 pu voltage (series R-L, > 0), on S_base"),
                )
                .min(0.0),
            ),
            t_on: v.real(Spec::parameter(
                &n("t_on"),
                l.t_on,
                "s",
                &format!("{who}: switch-on time, at the first step boundary at or after it (0: from the start, negative: never)"),
            )),
            enabled: v.boolean(Spec::parameter(
                &n("enabled"),
                true,
                "",
                &format!("{who}: present (false: never connected)"),
            )),
            p: v.real(Spec::output(
                &n("p"),
                "pu",
                &format!("{who}: active power drawn, on S_base"),
            )),
            q: v.real(Spec::output(
                &n("q"),
                "pu",
                &format!("{who}: reactive power drawn, on S_base"),
            )),
        }
    }

    fn declare_thevenin(v: &mut Variables) -> TheveninVars {
        let par = |v: &mut Variables, n: &str, start: f64, unit: &str, what: &str| {
            v.real(Spec::parameter(n, start, unit, what))
        };
        TheveninVars {
            enabled: v.boolean(Spec::parameter(
                "thevenin.enabled",
                true,
                "",
                "Thevenin source connected (false: an island, unit 1 is the slack at initialization)",
            )),
            r: v.real(
                Spec::parameter(
                    "thevenin.R",
                    0.015,
                    "pu",
                    "Thevenin resistance, on S_base",
                )
                .min(0.0),
            ),
            x: v.real(
                Spec::parameter(
                    "thevenin.X",
                    0.15,
                    "pu",
                    "Thevenin reactance at f_nom, on S_base (0.15: short-circuit power 663 MVA, SCR 6.9 on 96 MVA)",
                )
                .min(0.0),
            ),
            e: v.real(
                Spec::parameter(
                    "thevenin.E",
                    1.02,
                    "pu",
                    "Thevenin source voltage, peak phase-neutral pu",
                )
                .min(0.0),
            ),
            angle: par(
                v,
                "thevenin.angle",
                0.0,
                "rad",
                "Thevenin source angle at the start of the run",
            ),
            dip: v.real(
                Spec::parameter(
                    "thevenin.dip",
                    0.0,
                    "1",
                    "voltage dip: the source's amplitude falls by this fraction during the dip",
                )
                .range(0.0, 1.0),
            ),
            dip_t: par(v, "thevenin.dip_t", 1.0, "s", "start of the voltage dip"),
            dip_duration: v.real(
                Spec::parameter(
                    "thevenin.dip_duration",
                    0.1,
                    "s",
                    "duration of the voltage dip",
                )
                .min(0.0),
            ),
            jump: par(
                v,
                "thevenin.jump",
                0.0,
                "rad",
                "phase jump of the source (added to its angle from thevenin.jump_t on)",
            ),
            jump_t: par(v, "thevenin.jump_t", 1.0, "s", "time of the phase jump"),
            h: v.real(
                Spec::parameter(
                    "thevenin.H",
                    0.0,
                    "s",
                    "inertia constant of the source on S_base (a grid's aggregate machines): its angle swings by 2H dw/dt = p_m - p_e - D dw; 0 = a stiff source at f_nom",
                )
                .min(0.0),
            ),
            d: v.real(
                Spec::parameter(
                    "thevenin.D",
                    0.0,
                    "pu",
                    "damping of the swinging source on S_base (power per pu of speed deviation: the aggregate droop response)",
                )
                .min(0.0),
            ),
            i: PHASES.map(|x| {
                v.real(Spec::output(
                    &format!("thevenin.i_{x}"),
                    "pu",
                    &format!("Thevenin current into the PCC, phase {x}, on S_base"),
                ))
            }),
            p: v.real(Spec::output(
                "thevenin.p",
                "pu",
                "active power the Thevenin branch delivers into the PCC, on S_base",
            )),
            q: v.real(Spec::output(
                "thevenin.q",
                "pu",
                "reactive power the Thevenin branch delivers into the PCC, on S_base",
            )),
            df: v.real(Spec::output(
                "thevenin.df",
                "pu",
                "speed deviation of the swinging source, pu of f_nom (0 when thevenin.H = 0)",
            )),
        }
    }

    /// Read and check every parameter; the circuit and what else initialization fixes.
    fn fixed(&self, s: &Store) -> Result<Fixed, ModelError> {
        let s_base = positive(s, self.s_base, "S_base")?;
        let f_nom = positive(s, self.f_nom, "f_nom")?;
        let omega_b = 2.0 * PI * f_nom;
        let hold = s[self.hold];
        if !(0..=1).contains(&hold) {
            return Err(format!("parameter 'hold' = {hold} must be 0 or 1").into());
        }
        let kp = non_negative(s, self.pll_kp, "pll.kp")?;
        let ki = non_negative(s, self.pll_ki, "pll.ki")?;
        let mut units = Vec::new();
        let mut dc = Vec::new();
        for (k, u) in self.units.iter().enumerate() {
            let n = |w: &str| unit_name(k, w);
            units.push(UnitData {
                s: positive(s, u.s_rated, &n("S_rated"))?,
                r_f: non_negative(s, u.r_f, &n("R_f"))?,
                l_f: positive(s, u.l_f, &n("L_f"))?,
                c_f: positive(s, u.c_f, &n("C_f"))?,
                r_t: non_negative(s, u.r_t, &n("R_t"))?,
                l_t: positive(s, u.l_t, &n("L_t"))?,
            });
            dc.push(DcParams {
                c: positive(s, u.c_dc, &n("C_dc"))?,
                g: non_negative(s, u.g_dc, &n("G_dc"))?,
                tau: positive(s, u.tau_dc, &n("tau_dc"))?,
            });
            if let Some(v0) = u.v0 {
                non_negative(s, v0, &n("v0"))?;
            }
        }
        let mut loads = Vec::new();
        let mut t_on = Vec::new();
        for (j, l) in self.loads.iter().enumerate() {
            let n = |w: &str| format!("load[{}].{w}", j + 1);
            let p = non_negative(s, l.p_set, &n("P"))?;
            let q = positive(s, l.q_set, &n("Q"))
                .map_err(|e| ModelError(format!("{e} (a series R-L load draws reactive power)")))?;
            // Z = V²/S* at 1 pu: R + jX = (P + jQ)/(P² + Q²).
            let d = p * p + q * q;
            let (r, x) = (p / d, q / d);
            if !(r.is_finite() && x.is_finite() && x > 0.0) {
                return Err(format!(
                    "parameters 'load[{}].P' = {p}, 'load[{}].Q' = {q} give no finite series R-L impedance",
                    j + 1,
                    j + 1
                )
                .into());
            }
            loads.push(Branch { r, l: x });
            let at = s[l.t_on];
            t_on.push((s[l.enabled] && at >= 0.0).then_some(at));
        }
        let swing = match &self.thevenin {
            Some(t) if s[t.h] > 0.0 => Some((
                positive(s, t.h, "thevenin.H")?,
                non_negative(s, t.d, "thevenin.D")?,
            )),
            _ => None,
        };
        let f_filter_t = non_negative(s, self.pcc_f_filter_t, "pcc.f_filter_t")?;
        let (thevenin, thevenin_on, source) = match &self.thevenin {
            Some(t) => {
                let r = non_negative(s, t.r, "thevenin.R")?;
                let x = positive(s, t.x, "thevenin.X")?;
                let e = non_negative(s, t.e, "thevenin.E")?;
                let dip = s[t.dip];
                if !(0.0..=1.0).contains(&dip) {
                    return Err(
                        format!("parameter 'thevenin.dip' = {dip} must be in [0, 1]").into(),
                    );
                }
                let dur = non_negative(s, t.dip_duration, "thevenin.dip_duration")?;
                (
                    Some(Branch { r, l: x }),
                    s[t.enabled],
                    [e, s[t.angle], dip, s[t.dip_t], dur, s[t.jump], s[t.jump_t]],
                )
            }
            None => (None, false, [0.0; 7]),
        };
        let (v_step, ramp) = self.source_events(s, thevenin.is_some())?;
        let bench = self.bench_fixed(s, &units, &loads, thevenin, s_base, omega_b)?;
        Ok(Fixed {
            net: Network {
                units,
                loads,
                thevenin,
                s_base,
                omega_b,
            },
            dc,
            omega_b,
            rotating_hold: hold == 1,
            thevenin_on,
            source,
            swing,
            f_filter_t,
            t_on,
            pll_gains: (kp, ki),
            v_step,
            ramp,
            f_nom,
            bench,
        })
    }
}

impl Fixed {
    /// The topology of the step that starts at `t`.
    fn topology(&self, t: f64) -> Topology {
        let tol = 1e-9 * t.abs().max(1.0);
        let mut loads = 0u64;
        for (j, on) in self.t_on.iter().enumerate() {
            if on.is_some_and(|at| t >= at - tol) {
                loads |= 1 << j;
            }
        }
        Topology {
            loads,
            thevenin: self.thevenin_on,
            rotating_hold: self.rotating_hold,
        }
    }

    /// The Thevenin source's amplitude and the phase of its oscillator at the start of the step
    /// `[t, t + h]` (`t0` the run's start, `delta` the swing's angle): with a frequency ramp the
    /// ramp's angle at the step's middle, so the oscillator, turning at `ω_b` over the step,
    /// passes through the source's exact angle there.
    fn source_phase(&self, t: f64, h: f64, t0: f64, delta: f64) -> (f64, f64) {
        let (e, angle) = self.source(t);
        let mut phase = self.omega_b * (t - t0) + angle + delta;
        if let Some(ramp) = self.ramp_angle(t + 0.5 * h) {
            phase += ramp;
        }
        (e, phase)
    }

    /// The frequency ramp's angle at `t` (rad): `2π ∫ Δf`, `Δf` rising at RoCoF from `t_r` for
    /// the duration, then held.
    fn ramp_angle(&self, t: f64) -> Option<f64> {
        let (rocof, at, dur) = self.ramp?;
        let tau = (t - at).max(0.0);
        let ramped = tau.min(dur);
        Some(2.0 * PI * rocof * (0.5 * ramped * ramped + dur * (tau - ramped).max(0.0)))
    }

    /// The frequency ramp's deviation at `t`, Hz.
    fn ramp_df(&self, t: f64) -> f64 {
        self.ramp
            .map_or(0.0, |(rocof, at, dur)| rocof * (t - at).clamp(0.0, dur))
    }

    /// The Thevenin source's amplitude and angle over the step that starts at `t`.
    fn source(&self, t: f64) -> (f64, f64) {
        let [e, angle, dip, dip_t, dur, jump, jump_t] = self.source;
        let tol = 1e-9 * t.abs().max(1.0);
        let e = match self.v_step {
            Some((de, at)) if t >= at - tol => e + de,
            _ => e,
        };
        let dipped = dip > 0.0 && t >= dip_t - tol && t < dip_t + dur - tol;
        let jumped = t >= jump_t - tol;
        (
            if dipped { e * (1.0 - dip) } else { e },
            if jumped { angle + jump } else { angle },
        )
    }
}

impl Plant {
    /// The augmented state at the start of a step (`e` and `u` filled in by the caller).
    fn augmented(fixed: &Fixed, run: &Run) -> DVector<f64> {
        let net = &fixed.net;
        let mut z = DVector::zeros(net.n());
        z.rows_mut(0, run.x.len()).copy_from_slice(&run.x);
        z[net.e()] = run.e[0];
        z[net.e() + 1] = run.e[1];
        z
    }

    /// Write every measurement of the current state.
    fn write_outputs(&self, fixed: &Fixed, run: &Run, s: &mut Store) {
        let net = &fixed.net;
        let nc = net.nc();
        let z = Self::augmented(fixed, run);
        let ab = |i: usize| [run.x[i], run.x[nc + i]];
        let vp = net.vpcc(&run.topo, &z);
        let power =
            |v: [f64; 2], i: [f64; 2]| (v[0] * i[0] + v[1] * i[1], v[1] * i[0] - v[0] * i[1]);
        let (mut p_sum, mut q_sum) = (0.0, 0.0);
        for (k, u) in self.units.iter().enumerate() {
            for (r, x) in u.v.iter().zip(inverse_clarke(ab(net.v_c(k)))) {
                s[*r] = x;
            }
            for (r, x) in u.i.iter().zip(inverse_clarke(ab(net.i_f(k)))) {
                s[*r] = x;
            }
            let ig = ab(net.i_g(k));
            for (r, x) in u.ig.iter().zip(inverse_clarke(ig)) {
                s[*r] = x;
            }
            s[u.v_dc] = run.dc[k].v(&fixed.dc[k]);
            s[u.i_src] = run.dc[k].i_src;
            let (p, q) = power(vp, ig);
            s[u.p] = p * net.c(k);
            s[u.q] = q * net.c(k);
            p_sum += s[u.p];
            q_sum += s[u.q];
        }
        s[self.pcc_p] = p_sum;
        s[self.pcc_q] = q_sum;
        s[self.pcc_f] = 1.0 + run.df_lag;
        for (j, l) in self.loads.iter().enumerate() {
            let (p, q) = power(vp, ab(net.i_load(j)));
            s[l.p] = p;
            s[l.q] = q;
        }
        if let Some(t) = &self.thevenin {
            for (r, x) in t.i.iter().zip(inverse_clarke(ab(net.i_th()))) {
                s[*r] = x;
            }
            let (p, q) = power(vp, ab(net.i_th()));
            s[t.p] = p;
            s[t.q] = q;
            s[t.df] = run.dw;
        }
        for (r, x) in self.pcc_v.iter().zip(inverse_clarke(vp)) {
            s[*r] = x;
        }
        s[self.pcc_mag] = dvpp_math::hypot(vp[0], vp[1]);
        self.write_meters_and_energies(fixed, run, s, net.stored(&z));
    }

    /// Write the PLL's measurements and the energy accounts (`ac_stored` given).
    fn write_meters_and_energies(&self, fixed: &Fixed, run: &Run, s: &mut Store, ac_stored: f64) {
        let net = &fixed.net;
        s[self.pcc_df] = run.pll.dw / fixed.omega_b;
        s[self.pcc_theta] = wrap(run.pll.theta);
        let e = &run.energy;
        let ev = &self.energy;
        s[ev.source] = e.source;
        s[ev.ac] = e.ac;
        s[ev.dc_loss] = e.dc_loss;
        s[ev.dc_stored] = run.dc.iter().zip(&net.units).map(|(d, u)| d.w * u.s).sum();
        s[ev.ac_loss] = e.ac_loss;
        s[ev.thevenin] = e.thevenin;
        s[ev.loads] = e.loads;
        s[ev.ac_stored] = ac_stored;
        s[self.bench.energy_fault] = e.fault;
        s[self.bench.energy_switching] = e.switching;
        if let Some(r) = self.bench.f_source {
            let ramp = run.t_end.map_or(0.0, |t| fixed.ramp_df(t));
            s[r] = 1.0 + run.dw + ramp / fixed.f_nom;
        }
    }
}

impl Model for Plant {
    type State = PlantState;
    type Config = PlantConfig;
    const IDENTIFIER: &'static str = "dvpp_emt_plant";
    const NAME: &'static str = "DVPP EMT plant";
    const DESCRIPTION: &'static str =
        "EMT plant: N averaged converters (dc link, source lag, LC filter, transformer) on an MV PCC with a Thevenin source and switchable R-L loads, exact zero-order-hold steps";
    /// EMT steps are 20 to 50 µs, and one call costs the same at any step (no inner
    /// integration); 0.1 s still admits fmpy's `simulate_fmu` on the default experiment, whose
    /// automatic output interval steps by 16 ms, and refuses what has no meaning here.
    const MAX_STEP: f64 = 0.1;

    fn declare(
        config: &PlantConfig,
        _: Option<&std::path::Path>,
        v: &mut Variables,
    ) -> Result<Self, String> {
        let layout: Layout = config.layout()?;
        let s_base = v.real(Spec::parameter("S_base", 100.0, "MVA", "system base power").min(0.0));
        let f_nom = v.real(Spec::parameter("f_nom", 50.0, "Hz", "nominal frequency").min(0.0));
        let hold = v.integer(
            Spec::parameter(
                "hold",
                0,
                "",
                "converter voltage over a step: 0 = held (zero-order hold of v_conv,abc), 1 = held space vector turning at f_nom",
            )
            .range(0.0, 1.0),
        );
        let pll_kp = v.real(
            Spec::parameter(
                "pll.kp",
                60.0,
                "1/s",
                "measurement PLL proportional gain (rad/s per rad)",
            )
            .min(0.0),
        );
        let pll_ki = v.real(
            Spec::parameter(
                "pll.ki",
                240.0,
                "1/s2",
                "measurement PLL integral gain (rad/s^2 per rad)",
            )
            .min(0.0),
        );
        let thevenin = layout.thevenin.then(|| Self::declare_thevenin(v));
        let units = layout
            .units
            .iter()
            .enumerate()
            .map(|(k, u)| Self::declare_unit(v, k, u))
            .collect();
        let loads = layout
            .loads
            .iter()
            .enumerate()
            .map(|(j, l)| Self::declare_load(v, j, l))
            .collect();
        let out = |v: &mut Variables, n: &str, unit: &str, what: &str| {
            v.real(Spec::output(n, unit, what))
        };
        let pcc_v = PHASES.map(|x| {
            out(
                v,
                &format!("pcc.v_{x}"),
                "pu",
                &format!("PCC voltage, phase {x}, peak phase-neutral pu of the MV base"),
            )
        });
        let pcc_mag = out(v, "pcc.v", "pu", "PCC voltage space-vector magnitude");
        let pcc_df = out(
            v,
            "pcc.df",
            "pu",
            "PCC frequency deviation from the measurement SRF-PLL, pu of f_nom",
        );
        let pcc_theta = out(
            v,
            "pcc.theta",
            "rad",
            "PCC voltage angle from the measurement SRF-PLL, wrapped to (-pi, pi]",
        );
        let pcc_f_filter_t = v.real(
            Spec::parameter(
                "pcc.f_filter_t",
                0.02,
                "s",
                "time constant of the lag after the measurement PLL that gives pcc.f (as the phasor grid's PCC frequency filter)",
            )
            .min(0.0),
        );
        let pcc_p = out(
            v,
            "pcc.p",
            "pu",
            "the units' active power into the PCC, summed, on S_base (the DVPP's power)",
        );
        let pcc_q = out(
            v,
            "pcc.q",
            "pu",
            "the units' reactive power into the PCC, summed, on S_base",
        );
        let pcc_f = out(
            v,
            "pcc.f",
            "pu",
            "PCC frequency, pu of f_nom: 1 + pcc.df through the lag pcc.f_filter_t",
        );
        let energy = EnergyVars {
            source: out(v, "energy.source", "MJ", "energy the primary sources delivered to the dc links since initialization"),
            ac: out(v, "energy.ac", "MJ", "energy the converters delivered to the ac side since initialization"),
            dc_loss: out(v, "energy.dc_loss", "MJ", "energy lost in the dc links' G_dc since initialization"),
            dc_stored: out(v, "energy.dc_stored", "MJ", "energy stored in the dc links, sum of C_dc v_dc^2/2 (source - ac - dc_loss = change of this)"),
            ac_loss: out(v, "energy.ac_loss", "MJ", "energy lost in R_f, R_t and the Thevenin resistance since initialization"),
            thevenin: out(v, "energy.thevenin", "MJ", "energy the Thevenin source e delivered since initialization"),
            loads: out(v, "energy.loads", "MJ", "energy the loads consumed since initialization"),
            ac_stored: out(v, "energy.ac_stored", "MJ", "magnetic and electric energy stored in the ac circuit (ac + thevenin - ac_loss - loads = change of this)"),
        };
        let bench = Self::declare_bench(v, &layout);
        Ok(Plant {
            layout_units: layout.units.len(),
            s_base,
            f_nom,
            hold,
            pll_kp,
            pll_ki,
            units,
            loads,
            thevenin,
            pcc_v,
            pcc_mag,
            pcc_df,
            pcc_theta,
            pcc_p,
            pcc_q,
            pcc_f,
            pcc_f_filter_t,
            energy,
            bench,
        })
    }

    fn initialize(
        &self,
        _: Option<&PlantState>,
        s: &mut Store,
        _ctx: &mut Context,
    ) -> Result<PlantState, ModelError> {
        let fixed = self.fixed(s)?;
        if fixed.bench.is_some() {
            return self.initialize_bench(fixed, s);
        }
        let net = &fixed.net;
        let topo = fixed.topology(0.0);
        let s0: Vec<C> = self
            .units
            .iter()
            .map(|u| C::new(s[u.p0], s[u.q0]))
            .collect();
        let (e_mag, angle) = fixed.source(0.0);
        let slack = if topo.thevenin {
            Slack::Thevenin(dvpp_math::cpolar(e_mag, angle))
        } else {
            let v0 = self.units[0].v0.expect("unit 1 declares v0");
            Slack::Unit(C::new(s[v0], 0.0))
        };
        let st = steady::solve(net, &topo, slack, &s0).map_err(ModelError)?;
        let nc = net.nc();
        let mut x = vec![0.0; 2 * nc];
        let mut put = |i: usize, c: C| {
            x[i] = c.re;
            x[nc + i] = c.im;
        };
        for (k, u) in st.units.iter().enumerate() {
            put(net.i_f(k), u.i_f);
            put(net.v_c(k), u.v_c);
            put(net.i_g(k), u.i_g);
        }
        for (j, i) in st.loads.iter().enumerate() {
            put(net.i_load(j), *i);
        }
        if net.thevenin.is_some() {
            put(net.i_th(), st.i_th);
        }
        let e = if topo.thevenin {
            let c = dvpp_math::cpolar(e_mag, angle);
            [c.re, c.im]
        } else {
            [0.0; 2]
        };
        let dc = st
            .units
            .iter()
            .zip(&fixed.dc)
            .map(|(u, p)| DcState::steady(p, u.p_conv()))
            .collect();
        // The swinging source's mechanical power: its electrical power at the start.
        let p_m = if topo.thevenin {
            e[0] * x[net.i_th()] + e[1] * x[nc + net.i_th()]
        } else {
            0.0
        };
        let run = Run {
            x,
            e,
            dc,
            pll: Pll::locked(dvpp_math::carg(st.v_pcc)),
            energy: Energies::default(),
            t0: None,
            topo,
            delta: 0.0,
            dw: 0.0,
            p_m,
            df_lag: 0.0,
            t_end: None,
            btopo: Default::default(),
            fault_last: Vec::new(),
        };
        for u in &self.units {
            s[u.m_clamped] = false;
        }
        self.write_outputs(&fixed, &run, s);
        Ok(PlantState {
            fixed,
            run,
            cache: Cache::default(),
            bench_cache: Default::default(),
        })
    }

    fn do_step(
        &self,
        state: &mut PlantState,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        let PlantState {
            fixed,
            run,
            cache,
            bench_cache,
        } = state;
        let t0 = *run.t0.get_or_insert(t);
        run.t_end = Some(t + h);
        if fixed.bench.is_some() {
            return self.step_bench(fixed, run, bench_cache, s, t, h, t0, ctx);
        }
        let net = &fixed.net;
        let topo = fixed.topology(t);
        // The source at the step's start, from the absolute time (an event acts here).
        if topo.thevenin {
            let (e, phase) = fixed.source_phase(t, h, t0, run.delta);
            let c = dvpp_math::cpolar(e, phase);
            run.e = [c.re, c.im];
        }
        let mut z = Self::augmented(fixed, run);
        for (k, u) in self.units.iter().enumerate() {
            let m = u.modulation(s);
            let v_dc = run.dc[k].v(&fixed.dc[k]);
            let [a, b] = clarke(m);
            z[net.u(k)] = 1.5 * v_dc * a;
            z[net.u(k) + 1] = 1.5 * v_dc * b;
        }
        if topo != run.topo {
            for j in 0..net.loads.len() {
                if topo.load(j) && !run.topo.load(j) {
                    ctx.event(format!("t = {t}: load {} connected", j + 1));
                }
            }
        }
        let d = cache.get(net, &topo, h).map_err(ModelError)?;
        self.account(fixed, run, s, &d.forms, &z, h, topo.thevenin)?;
        let z1 = &d.phi * &z;
        let nx = run.x.len();
        run.x.copy_from_slice(z1.rows(0, nx).as_slice());
        run.e = [z1[net.e()], z1[net.e() + 1]];
        run.topo = topo;
        run.meter(fixed, net.vpcc(&topo, &z1), h);
        self.write_outputs(fixed, run, s);
        Ok(())
    }
}

impl Run {
    /// The measurement PLL and the PCC frequency's lag over a step, on the PCC voltage `vp`
    /// (αβ) at its end.
    fn meter(&mut self, fixed: &Fixed, vp: [f64; 2], h: f64) {
        let (kp, ki) = fixed.pll_gains;
        self.pll.step(vp, h, fixed.omega_b, kp, ki);
        let df = self.pll.dw / fixed.omega_b;
        self.df_lag += if fixed.f_filter_t > 0.0 {
            -dvpp_math::expm1(-h / fixed.f_filter_t) * (df - self.df_lag)
        } else {
            df - self.df_lag
        };
    }
}

impl Plant {
    /// The energies over a step from the exact forms `forms` at the step's start `z`: each
    /// unit's converter energy into its dc link (which steps), the ac losses, the source's and
    /// the loads' energies; then the swinging source over the step.
    #[allow(clippy::too_many_arguments)]
    fn account(
        &self,
        fixed: &Fixed,
        run: &mut Run,
        s: &mut Store,
        forms: &[nalgebra::DMatrix<f64>],
        z: &DVector<f64>,
        h: f64,
        thevenin: bool,
    ) -> Result<(), ModelError> {
        let net = &fixed.net;
        let n_units = net.units.len();
        let energy = |i: usize| network::quadratic(&forms[i], z);
        for (k, u) in self.units.iter().enumerate() {
            let e_ac = energy(k);
            let p = &fixed.dc[k];
            let su = net.units[k].s;
            let range = [s[u.p_src[0]], s[u.p_src[1]]];
            let step = run.dc[k].step(p, s[u.i_dc_ref], e_ac / su, h, range);
            if run.dc[k].w <= 0.0 {
                return Err(format!(
                    "unit {}: the dc link is discharged (the converter drew more than the link stores); der[{}].v_dc reached 0",
                    k + 1,
                    k + 1
                )
                .into());
            }
            run.energy.ac += e_ac;
            run.energy.source += step.source * su;
            run.energy.dc_loss += step.loss * su;
        }
        run.energy.ac_loss += energy(n_units + network::FORM_AC_LOSS);
        let e_th = energy(n_units + network::FORM_THEVENIN);
        run.energy.thevenin += e_th;
        run.energy.loads += energy(n_units + network::FORM_LOADS);
        // The swinging source over the step, on its mean electrical power (exact for the linear
        // swing at that power; the angle it turns enters at the next step's start).
        if let (Some((h_th, d_th)), true) = (fixed.swing, thevenin) {
            let p_e = e_th / (h * net.s_base);
            let dw0 = run.dw;
            run.dw = if d_th > 0.0 {
                let k = dvpp_math::exp(-h * d_th / (2.0 * h_th));
                dw0 * k + (run.p_m - p_e) / d_th * (1.0 - k)
            } else {
                dw0 + h * (run.p_m - p_e) / (2.0 * h_th)
            };
            run.delta += fixed.omega_b * h * 0.5 * (dw0 + run.dw);
        }
        Ok(())
    }
}

impl Plant {
    /// Number of units this instance was declared with.
    pub fn units(&self) -> usize {
        self.layout_units
    }
}

#[cfg(test)]
mod golden {
    #[test]
    fn model_description_matches_the_golden_copy() {
        fmi_export::assert_golden::<super::Plant>(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/modelDescription.xml"
        ));
    }
}
