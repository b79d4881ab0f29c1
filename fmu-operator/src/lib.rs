//! DVPP operator model (the `dvpp_operator` FMU; its binary is `fmu/`): online ADPF dc gains for
//! every DER and the desired aggregate response.
//!
//! Centrally, at every communication step (the paper's online adaptation of the low-pass dc
//! gains, section III; as implemented: `docs/control.md` §6):
//! - active dc gains `μ_p` of the low-pass units proportional to their available power, bounded
//!   below for grid-forming units by their floor `min(mu_min, κ S_i/S_dvpp)` (a grid-forming
//!   unit cannot have zero p-f participation; the floor bounds its p-f stiffness per unit of its
//!   own rating, `dvpp_control::mu_min_gfm`) and renormalized, so `Σ μ_p = 1` over the low-pass
//!   units;
//! - reactive dc gains `μ_q` of all units proportional to their PQ-capability headroom
//!   `sqrt(S² - P²)`, so `Σ μ_q = 1`;
//! - a complement unit receives the low-pass gains it complements (`mu_p_lpf[j]`);
//! - optional rate limit and communication delay that keep both sums exact;
//! - the desired aggregate response `ref.df = -T_pf Δp_pcc`, `ref.dv = -T_qv Δq_pcc` (on the
//!   `S_dvpp` base, changes since initialization; `Δp_pcc` is taken against the DVPP's summed
//!   set point `Σ der[k].p_set`, so a set point lowered by the primary source counts as the
//!   disturbance it is) and the matching errors `err.df`, `err.dv`.
//!
//! A DER split into a grid-forming and a grid-following part (case study II) appears as two
//! entries whose `share` (ε and 1 - ε) scales its availability and its rating.
//!
//! A DVPP area with several points of coupling (case study III, `[model] pocs = n`): the desired
//! frequency deviation is matched at the POCs, `ref.df = -T_pf Σ_k Δp'_poc,k`, with `Δp'` the
//! POC power deviation rotated by the lines' R/X (parameter `rot.rx`, as the DERs'; 0: plain
//! `Δp`), and every POC reports its own matching error `poc[k].err_df`. The change of what the
//! area's own loads draw (inputs `area.p_load`, `area.q_load`) is added back to `Σ_k Δp_poc,k`:
//! a load step inside the area is a disturbance, not the DVPP's response.

pub mod ports;

use dvpp_control::adaptation::{
    reactive_capacity, renormalize_with_floor, renormalize_with_floors,
};
use dvpp_control::floor_scale;
use dvpp_control::{Hold, LtiSimulator, Rotation, TDes};
use fmi_export::{Context, Model, ModelError, Real, Spec, Store, Variables};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// The ADPF shape of a DER's p-f channel, as far as the operator cares.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// Steady-state contribution; gets an active dc gain.
    LowPass,
    /// Zero dc gain; no active dc gain to send.
    HighPass,
    /// Zero dc gain; no active dc gain to send.
    BandPass,
    /// Closes the participation condition; gets the low-pass units' gains.
    Complement,
}

/// Grid-forming or grid-following control of a DER.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Form {
    GridForming,
    GridFollowing,
}

/// One DER the operator serves.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DerEntry {
    pub name: String,
    pub role: Role,
    pub form: Form,
    /// Converter rating of the whole unit, MVA.
    pub s_rated: f64,
    /// The part of the unit this entry stands for (ε or 1 - ε in a hybrid DVPP; 1 otherwise).
    #[serde(default = "one")]
    pub share: f64,
}

fn one() -> f64 {
    1.0
}

/// The DVPP the operator serves (`[model]` in config.toml).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OperatorConfig {
    pub ders: Vec<DerEntry>,
    /// Points of coupling of a DVPP area (inputs `poc[k].p`, `.q`, `.f`, `.v`): `ref.df` is then
    /// matched at them (`-T_pf Σ_k Δp'_poc,k`); 0 (default): at the PCC.
    #[serde(default)]
    pub pocs: usize,
    /// Start value of the parameter `rot.rx` (declared with `pocs` > 0): the R/X ratio the
    /// rotation `p' = (p - rx q)/sqrt(1 + rx²)` of the POC powers compensates, as the DERs'
    /// `rot.rx` (0: classical, plain `Δp`).
    #[serde(default)]
    pub rot_rx: f64,
}

impl Default for OperatorConfig {
    /// Case study I: wind and PV low-pass, BESS the complement, all grid-forming.
    fn default() -> Self {
        let der = |name: &str, role, s_rated| DerEntry {
            name: name.into(),
            role,
            form: Form::GridForming,
            s_rated,
            share: 1.0,
        };
        OperatorConfig {
            ders: vec![
                der("wind", Role::LowPass, 46.0),
                der("pv", Role::LowPass, 73.0),
                der("bess", Role::Complement, 60.0),
            ],
            pocs: 0,
            rot_rx: 0.0,
        }
    }
}

impl OperatorConfig {
    fn check(&self) -> Result<(), String> {
        if self.ders.is_empty() {
            return Err("[model] ders: no entries, expected at least one DER".into());
        }
        for (k, d) in self.ders.iter().enumerate() {
            let at = format!("[model] ders[{}] '{}'", k + 1, d.name);
            if !(d.s_rated.is_finite() && d.s_rated > 0.0) {
                return Err(format!("{at}: s_rated = {} must be positive", d.s_rated));
            }
            if !(d.share > 0.0 && d.share <= 1.0) {
                return Err(format!("{at}: share = {} must be in (0, 1]", d.share));
            }
        }
        if !self.ders.iter().any(|d| d.role == Role::LowPass) {
            return Err("[model] ders: no low-pass unit carries the steady state".into());
        }
        if self.pocs > MAX_POCS {
            return Err(format!(
                "[model] pocs = {}: at most {MAX_POCS} points of coupling",
                self.pocs
            ));
        }
        Rotation::from_rx(self.rot_rx).map_err(|e| format!("[model] rot_rx: {e}"))?;
        if self.rot_rx != 0.0 && self.pocs == 0 {
            return Err(format!(
                "[model] rot_rx = {}: the rotation applies to the POC powers, but pocs = 0",
                self.rot_rx
            ));
        }
        Ok(())
    }
}

/// Largest number of points of coupling.
pub const MAX_POCS: usize = 16;

/// Handles of one point of coupling's variables.
#[derive(Clone, Serialize, Deserialize)]
struct PocVars {
    p: Real,
    q: Real,
    f: Real,
    err_df: Real,
}

/// The POCs of a DVPP area (`[model] pocs` > 0).
#[derive(Clone, Serialize, Deserialize)]
struct Pocs {
    vars: Vec<PocVars>,
    /// Parameter `rot.rx` and output `poc.dp`.
    rot_rx: Real,
    dp: Real,
    /// The rotation of `rot.rx`, fixed at initialization.
    rot: Rotation,
    /// Every POC's p, q at initialization.
    pq0: Vec<(f64, f64)>,
    /// Inputs `area.p_load`, `area.q_load` and their values at initialization.
    load: (Real, Real),
    load0: (f64, f64),
}

/// Handles of one DER's variables.
#[derive(Clone, Serialize, Deserialize)]
struct DerVars {
    p_avail: Real,
    p: Real,
    p_set: Real,
    s_rated: Real,
    mu_p: Option<Real>,
    mu_q: Real,
    mu_p_lpf: Vec<Real>,
}

/// Gains as sent: active for the low-pass units (in their order), reactive for all units.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Gains {
    p: Vec<f64>,
    q: Vec<f64>,
}

/// Which degenerate input a warning was given for (each is logged once per episode).
#[derive(Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
enum Degenerate {
    NoAvailability,
    NegativeAvailability(usize),
    OverRating(usize),
    NoReactiveCapacity,
}

/// Warn once per episode: `active` says whether the condition holds now, `clear` whether it has
/// ended (for a threshold, below it by a margin); an episode ends when it has been clear for
/// [`RELEASE`] seconds, so that a value hovering at a threshold is one episode, not one per
/// crossing. `warned` holds the conditions reported, each with the time it has been clear since.
/// The end of an episode is logged as an event.
fn warn_once(
    warned: &mut Vec<(Degenerate, Option<f64>)>,
    ctx: &mut Context,
    t: f64,
    what: Degenerate,
    (active, clear): (bool, bool),
    message: impl FnOnce() -> String,
) {
    match warned.iter().position(|(w, _)| *w == what) {
        None if active => {
            warned.push((what, None));
            ctx.warn(message());
        }
        None => {}
        Some(i) if clear => {
            let since = *warned[i].1.get_or_insert(t);
            if t - since >= RELEASE {
                warned.remove(i);
                ctx.event(what.ended());
            }
        }
        Some(i) => warned[i].1 = None,
    }
}

/// How long a condition must stay clear for its episode to end, s.
const RELEASE: f64 = 1.0;

/// How far below a rating a unit must come back for its over-rating episode to end.
const RATING_HYSTERESIS: f64 = 0.02;

impl Degenerate {
    /// The log line of an episode's end.
    fn ended(&self) -> String {
        match self {
            Degenerate::NoAvailability => "low-pass DERs report available power again".into(),
            Degenerate::NegativeAvailability(k) => {
                format!("DER {}'s available power is no longer negative", k + 1)
            }
            Degenerate::OverRating(k) => format!(
                "DER {} is back within its rating (below {:.0} % of it for {RELEASE} s)",
                k + 1,
                (1.0 - RATING_HYSTERESIS) * 100.0
            ),
            Degenerate::NoReactiveCapacity => "DERs have reactive capacity again".into(),
        }
    }
}

/// The operator's variables and state.
#[derive(Clone, Serialize, Deserialize)]
pub struct Operator {
    config: OperatorConfig,
    s_base: Real,
    s_dvpp: Real,
    h: Real,
    d: Real,
    dq: Real,
    mu_min: Real,
    rate_limit: Real,
    delay: Real,
    ders: Vec<DerVars>,
    pcc_p: Real,
    pcc_q: Real,
    pcc_f: Real,
    pcc_v: Real,
    ref_df: Real,
    ref_dv: Real,
    err_df: Real,
    err_dv: Real,
    sum_mu_p: Real,
    sum_mu_q: Real,
    /// Points of coupling (`[model] pocs` > 0).
    pocs: Option<Pocs>,
    /// `-T_pf` realized on Δp_pcc (state survives FMU state snapshots).
    t_pf: Option<LtiSimulator>,
    /// PCC operating point at initialization: p, q, v.
    pcc0: [f64; 3],
    /// The DVPP's summed active set point at initialization, on S_base.
    p_set0: f64,
    /// Gains currently sent, and gains waiting out the communication delay (time, gains).
    sent: Option<Gains>,
    queue: VecDeque<(f64, Gains)>,
    warned: Vec<(Degenerate, Option<f64>)>,
}

impl Operator {
    /// The DVPP's summed active set point, on S_base.
    fn set_point(&self, s: &Store) -> f64 {
        self.ders.iter().map(|d| s[d.p_set]).sum()
    }

    fn low_pass(&self) -> impl Iterator<Item = usize> + '_ {
        self.config
            .ders
            .iter()
            .enumerate()
            .filter(|(_, d)| d.role == Role::LowPass)
            .map(|(k, _)| k)
    }

    /// The floor of each low-pass unit's active dc gain, in the order of [`Operator::low_pass`]:
    /// `mu_min · min(1, κ S_i/(0.05 S_dvpp))` for a grid-forming unit (`S_i` its rating times
    /// its share): `mu_min` for a unit of at least 20 % of `S_dvpp`, proportional to its share
    /// below that. With the default `mu_min` = 0.05 it is the floor the DER clamps its own gain
    /// at ([`dvpp_control::mu_min_gfm`]); a larger `mu_min` only raises it. 0 for a
    /// grid-following unit.
    fn floors(&self, s: &Store) -> Vec<f64> {
        let s_dvpp = s[self.s_dvpp];
        self.low_pass()
            .map(|k| {
                let d = &self.config.ders[k];
                if d.form == Form::GridForming {
                    let rating = s[self.ders[k].s_rated] * d.share;
                    s[self.mu_min] * floor_scale(rating, s_dvpp)
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// The gains the current inputs call for.
    fn target(&mut self, s: &Store, t: f64, ctx: &mut Context) -> Result<Gains, ModelError> {
        let s_base = s[self.s_base];
        let lpf: Vec<usize> = self.low_pass().collect();
        let mut weights = Vec::with_capacity(lpf.len());
        for &k in &lpf {
            let avail = s[self.ders[k].p_avail];
            let name = &self.config.ders[k].name;
            warn_once(
                &mut self.warned,
                ctx,
                t,
                Degenerate::NegativeAvailability(k),
                (avail < 0.0, avail >= 0.0),
                || {
                    format!(
                        "DER {} '{name}': negative available power {avail} pu is taken as 0",
                        k + 1
                    )
                },
            );
            weights.push(avail.max(0.0) * self.config.ders[k].share);
        }
        let none = weights.iter().all(|&w| w == 0.0);
        warn_once(
            &mut self.warned,
            ctx,
            t,
            Degenerate::NoAvailability,
            (none, !none),
            || {
                "all low-pass DERs report zero available power: active dc gains fall back to equal shares".into()
            },
        );
        let floors = self.floors(s);
        let p = renormalize_with_floors(&weights, &floors)
            .map_err(|e| ModelError(format!("active dc gains: {e}")))?;

        let mut capacity = Vec::with_capacity(self.ders.len());
        for k in 0..self.ders.len() {
            let rating = s[self.ders[k].s_rated] * self.config.ders[k].share;
            let p_mw = s[self.ders[k].p] * s_base;
            let name = &self.config.ders[k].name;
            warn_once(
                &mut self.warned,
                ctx,
                t,
                Degenerate::OverRating(k),
                (
                    p_mw.abs() > rating,
                    p_mw.abs() < (1.0 - RATING_HYSTERESIS) * rating,
                ),
                || {
                    format!("DER {} '{name}': |p| = {:.2} MW exceeds its rating {rating:.2} MVA: no reactive capacity", k + 1, p_mw.abs())
                },
            );
            capacity.push(reactive_capacity(rating, p_mw));
        }
        let none = capacity.iter().all(|&c| c == 0.0);
        warn_once(
            &mut self.warned,
            ctx,
            t,
            Degenerate::NoReactiveCapacity,
            (none, !none),
            || {
                "no DER has reactive capacity left: reactive dc gains fall back to equal shares"
                    .into()
            },
        );
        let q = renormalize_with_floor(&capacity, &vec![false; capacity.len()], 0.0)
            .map_err(|e| ModelError(format!("reactive dc gains: {e}")))?;
        Ok(Gains { p, q })
    }

    /// Move the sent gains toward `target` by at most `rate · h` per gain; the step is scaled
    /// as a whole, so the sums stay exactly where they were.
    fn rate_limited(sent: &Gains, target: Gains, max_change: f64) -> Gains {
        let limit = |from: &[f64], to: Vec<f64>| -> Vec<f64> {
            let largest = from
                .iter()
                .zip(&to)
                .map(|(a, b)| (b - a).abs())
                .fold(0.0, f64::max);
            if largest <= max_change {
                return to;
            }
            let scale = max_change / largest;
            from.iter()
                .zip(&to)
                .map(|(a, b)| a + scale * (b - a))
                .collect()
        };
        Gains {
            p: limit(&sent.p, target.p),
            q: limit(&sent.q, target.q),
        }
    }

    fn write_gains(&self, s: &mut Store, g: &Gains) {
        // Only the low-pass units have `mu_p`, in the order of `g.p`.
        for (r, &mu) in self.ders.iter().filter_map(|d| d.mu_p).zip(&g.p) {
            s[r] = mu;
        }
        for (k, der) in self.ders.iter().enumerate() {
            s[der.mu_q] = g.q[k];
            for (j, &r) in der.mu_p_lpf.iter().enumerate() {
                s[r] = g.p[j];
            }
        }
        s[self.sum_mu_p] = g.p.iter().sum();
        s[self.sum_mu_q] = g.q.iter().sum();
    }

    fn desired_dv(&self, s: &Store) -> f64 {
        -s[self.dq] * (s[self.pcc_q] - self.pcc0[1]) * s[self.s_base] / s[self.s_dvpp]
    }
}

impl Pocs {
    /// `Σ_k Δp'_poc,k` less the rotated change `dp_set` of the DVPP's summed set point, on
    /// S_base: a set point moves a unit's `p` (its `q'`-`v` loop holds `q`), so its `p'` by
    /// the rotation's `p` component.
    fn rotated_deviation(&self, s: &Store, dp_set: f64) -> f64 {
        let sum: f64 = self
            .vars
            .iter()
            .zip(&self.pq0)
            .map(|(p, &(p0, q0))| self.rot.rotate(s[p.p] - p0, s[p.q] - q0).0)
            .sum();
        // What the area's loads draw more is not the DVPP's response: added back, the sum is
        // what the units deliver net of the area's losses.
        let (lp, lq) = self.load;
        let load = self
            .rot
            .rotate(s[lp] - self.load0.0, s[lq] - self.load0.1)
            .0;
        sum + load - self.rot.rotate(dp_set, 0.0).0
    }

    /// Declare the variables of `n` POCs and the rotation (start `rx`).
    fn declare(v: &mut Variables, n: usize, rx: f64) -> Pocs {
        let rot_rx = v.real(
            Spec::parameter(
                ports::ROT_RX,
                rx,
                "1",
                "R/X of the DVPP area's lines the POC powers are rotated for: p' = (p - rx q)/sqrt(1 + rx^2) (0 = plain p, classical p-f)",
            )
            .range(0.0, 20.0),
        );
        let mut vars = Vec::with_capacity(n);
        for k in 1..=n {
            let input = |v: &mut Variables, name: String, start: f64, what: &str| {
                v.real(Spec::input(&name, start, "pu", &format!("POC {k}: {what}")))
            };
            let p = input(
                v,
                ports::poc_p(k),
                0.0,
                "active power the DVPP area sends through the POC, on S_base",
            );
            let q = input(
                v,
                ports::poc_q(k),
                0.0,
                "reactive power the DVPP area sends through the POC, on S_base",
            );
            let f = input(v, ports::poc_f(k), 1.0, "frequency, pu of f_nom");
            input(v, ports::poc_v(k), 1.0, "voltage magnitude (monitoring)");
            let err_df = v.real(Spec::output(
                &ports::poc_err_df(k),
                "pu",
                &format!(
                    "POC {k}: measured minus desired frequency deviation (poc[{k}].f - 1) - ref.df"
                ),
            ));
            vars.push(PocVars { p, q, f, err_df });
        }
        let load = (
            v.real(Spec::input(
                ports::AREA_P_LOAD,
                0.0,
                "pu",
                "active power the loads inside the DVPP area draw, on S_base (its change is added to the POC powers: a load step inside the area is not the DVPP's response)",
            )),
            v.real(Spec::input(
                ports::AREA_Q_LOAD,
                0.0,
                "pu",
                "reactive power the loads inside the DVPP area draw, on S_base",
            )),
        );
        let dp = v.real(Spec::output(
            ports::POC_DP,
            "pu",
            "input of T_pf: rotated POC power deviation sum_k dp'_poc,k plus the rotated change of the area's load, less the rotated set-point change, on S_dvpp",
        ));
        Pocs {
            vars,
            rot_rx,
            dp,
            rot: Rotation::IDENTITY,
            pq0: vec![(0.0, 0.0); n],
            load,
            load0: (0.0, 0.0),
        }
    }
}

impl Model for Operator {
    type State = Operator;
    type Config = OperatorConfig;
    const IDENTIFIER: &'static str = "dvpp_operator";
    const NAME: &'static str = "DVPP operator";
    const DESCRIPTION: &'static str =
        "DVPP operator: online ADPF dc gains (sums exactly 1) and the desired aggregate response T_des";
    /// Phasor steps are 1e-4 to 1e-2 s; 1 s (100 times the longest) keeps one call short.
    const MAX_STEP: f64 = 1.0;

    fn declare(
        config: &OperatorConfig,
        _: Option<&std::path::Path>,
        v: &mut Variables,
    ) -> Result<Self, String> {
        config.check()?;
        let param = |v: &mut Variables, name: &str, start: f64, unit: &str, what: &str| {
            v.real(Spec::parameter(name, start, unit, what))
        };
        let s_base = v.real(Spec::parameter("S_base", 100.0, "MVA", "system base power").min(1e-3));
        let s_dvpp = v.real(
            Spec::parameter(
                ports::S_DVPP,
                96.0,
                "MVA",
                "DVPP base power T_des is specified on",
            )
            .min(1e-3),
        );
        let h = v.real(
            Spec::parameter(
                ports::TDES_H,
                5.55,
                "s",
                "virtual inertia of T_pf = 1/(H s + D)",
            )
            .min(1e-6),
        );
        let d = v.real(
            Spec::parameter(ports::TDES_D, 33.33, "pu", "damping of T_pf = 1/(H s + D)").min(1e-6),
        );
        let dq =
            v.real(Spec::parameter(ports::TDES_DQ, 0.01, "pu", "q-v droop: T_qv = Dq").min(1e-9));
        let mu_min = v.real(
            Spec::parameter(
                "mu_min",
                0.05,
                "1",
                "lower bound of a grid-forming low-pass unit's active dc gain (a unit of rating S_i below 0.2 S_dvpp: mu_min S_i/(0.2 S_dvpp))",
            )
            .range(0.0, 0.3),
        );
        let rate_limit = param(
            v,
            "rate_limit",
            0.0,
            "1/s",
            "largest change of a dc gain per second (0: none)",
        );
        let delay = param(
            v,
            "delay",
            0.0,
            "s",
            "communication delay of the dc gains (0: none)",
        );
        let lpf: Vec<usize> = config
            .ders
            .iter()
            .enumerate()
            .filter(|(_, d)| d.role == Role::LowPass)
            .map(|(k, _)| k)
            .collect();

        let mut ders = Vec::with_capacity(config.ders.len());
        for (k, entry) in config.ders.iter().enumerate() {
            let who = format!("DER {} ({})", k + 1, entry.name);
            ders.push(DerVars {
                s_rated: v.real(
                    Spec::parameter(
                        &ports::der_s_rated(k + 1),
                        entry.s_rated,
                        "MVA",
                        &format!("converter rating of {who}"),
                    )
                    .min(1e-3),
                ),
                p_avail: v.real(Spec::input(
                    &ports::der_p_avail(k + 1),
                    entry.s_rated / 200.0,
                    "pu",
                    &format!("available active power of {who}, on S_base"),
                )),
                p: v.real(Spec::input(
                    &ports::der_p(k + 1),
                    0.0,
                    "pu",
                    &format!("active power of {who}, on S_base (for its PQ capability)"),
                )),
                p_set: v.real(Spec::input(
                    &ports::der_p_set(k + 1),
                    0.0,
                    "pu",
                    &format!(
                        "active set point of {who}, on S_base: a change of the DVPP's summed set point is not a disturbance of ref.df"
                    ),
                )),
                mu_p: None,
                mu_q: Real(0),
                mu_p_lpf: Vec::new(),
            });
            v.real(Spec::input(
                &ports::der_q(k + 1),
                0.0,
                "pu",
                &format!("reactive power of {who}, on S_base (monitoring)"),
            ));
        }
        let deps: Vec<String> = (1..=config.ders.len())
            .flat_map(|k| [ports::der_p_avail(k), ports::der_p(k)])
            .collect();
        let deps: Vec<&str> = deps.iter().map(String::as_str).collect();
        for (k, entry) in config.ders.iter().enumerate() {
            let who = format!("DER {} ({})", k + 1, entry.name);
            if entry.role == Role::LowPass {
                ders[k].mu_p = Some(
                    v.real(
                        Spec::output(
                            &ports::der_mu_p(k + 1),
                            "1",
                            &format!("active ADPF dc gain of {who}"),
                        )
                        .initial_dependencies(&deps),
                    ),
                );
            }
            ders[k].mu_q = v.real(
                Spec::output(
                    &ports::der_mu_q(k + 1),
                    "1",
                    &format!("reactive ADPF dc gain of {who}"),
                )
                .initial_dependencies(&deps),
            );
            if entry.role == Role::Complement {
                ders[k].mu_p_lpf = lpf
                    .iter()
                    .enumerate()
                    .map(|(j, &l)| {
                        let what = format!(
                            "active dc gain of low-pass DER {} ({}) that {who} complements",
                            l + 1,
                            config.ders[l].name
                        );
                        v.real(
                            Spec::output(&ports::der_mu_p_lpf(k + 1, j + 1), "1", &what)
                                .initial_dependencies(&deps),
                        )
                    })
                    .collect();
            }
        }
        let pcc = |v: &mut Variables, name: &str, start: f64, what: &str| {
            v.real(Spec::input(name, start, "pu", what))
        };
        let out = |v: &mut Variables, name: &str, unit: &str, what: &str| {
            v.real(Spec::output(name, unit, what))
        };
        let mut op = Operator {
            config: config.clone(),
            s_base,
            s_dvpp,
            h,
            d,
            dq,
            mu_min,
            rate_limit,
            delay,
            ders,
            pcc_p: pcc(
                v,
                ports::PCC_P,
                0.0,
                "DVPP active power at the PCC, on S_base",
            ),
            pcc_q: pcc(
                v,
                ports::PCC_Q,
                0.0,
                "DVPP reactive power at the PCC, on S_base",
            ),
            pcc_f: pcc(v, ports::PCC_F, 1.0, "PCC frequency, pu of f_nom"),
            pcc_v: pcc(v, ports::PCC_V, 1.0, "PCC voltage magnitude"),
            ref_df: out(
                v,
                ports::REF_DF,
                "pu",
                "desired frequency deviation -T_pf Δp_pcc, pu of f_nom",
            ),
            ref_dv: out(
                v,
                ports::REF_DV,
                "pu",
                "desired voltage deviation -T_qv Δq_pcc",
            ),
            err_df: out(
                v,
                ports::ERR_DF,
                "pu",
                "measured minus desired frequency deviation",
            ),
            err_dv: out(
                v,
                ports::ERR_DV,
                "pu",
                "measured minus desired voltage deviation",
            ),
            sum_mu_p: out(
                v,
                "check.sum_mu_p",
                "1",
                "Σ μ_p over the low-pass units as sent (participation: 1)",
            ),
            sum_mu_q: out(
                v,
                "check.sum_mu_q",
                "1",
                "Σ μ_q over all units as sent (participation: 1)",
            ),
            pocs: None,
            t_pf: None,
            pcc0: [0.0, 0.0, 1.0],
            p_set0: 0.0,
            sent: None,
            queue: VecDeque::new(),
            warned: Vec::new(),
        };
        if config.pocs > 0 {
            op.pocs = Some(Pocs::declare(v, config.pocs, config.rot_rx));
        }
        Ok(op)
    }

    fn initialize(
        &self,
        _: Option<&Operator>,
        s: &mut Store,
        ctx: &mut Context,
    ) -> Result<Operator, ModelError> {
        let mut op = self.clone();
        op.start(s, ctx)?;
        Ok(op)
    }

    fn do_step(
        &self,
        op: &mut Operator,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        op.advance(s, t, h, ctx)
    }
}

impl Operator {
    fn start(&mut self, s: &mut Store, ctx: &mut Context) -> Result<(), ModelError> {
        for (name, r) in [("rate_limit", self.rate_limit), ("delay", self.delay)] {
            if s[r] < 0.0 {
                return Err(format!("parameter '{name}' = {} must not be negative", s[r]).into());
            }
        }
        // Only the p-f channel is simulated here; T_qv = Dq is static (the roll-off is irrelevant).
        let tdes = TDes::inertia_droop(s[self.h], s[self.d], s[self.dq], 1.0)
            .map_err(|e| ModelError(format!("parameters 'Tdes.H', 'Tdes.D', 'Tdes.Dq': {e}")))?;
        self.t_pf = Some(tdes.pf_simulator(Hold::Zero));
        self.pcc0 = [s[self.pcc_p], s[self.pcc_q], s[self.pcc_v]];
        self.p_set0 = self.set_point(s);
        self.warned.clear();
        self.queue.clear();
        let gains = self.target(s, 0.0, ctx)?;
        self.write_gains(s, &gains);
        self.sent = Some(gains);
        for r in [self.ref_df, self.ref_dv, self.err_df, self.err_dv] {
            s[r] = 0.0;
        }
        s[self.err_df] = s[self.pcc_f] - 1.0;
        if let Some(pocs) = &mut self.pocs {
            pocs.rot = Rotation::from_rx(s[pocs.rot_rx])
                .map_err(|e| ModelError(format!("parameter 'rot.rx': {e}")))?;
            pocs.pq0 = pocs.vars.iter().map(|p| (s[p.p], s[p.q])).collect();
            pocs.load0 = (s[pocs.load.0], s[pocs.load.1]);
            s[pocs.dp] = 0.0;
            for p in &pocs.vars {
                s[p.err_df] = s[p.f] - 1.0;
            }
        }
        Ok(())
    }

    fn advance(
        &mut self,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        // Gains: target now, delayed by the communication delay, then rate limited.
        let target = self.target(s, t + h, ctx)?;
        let delay = s[self.delay];
        self.queue.push_back((t + h, target));
        let mut due = None;
        while self
            .queue
            .front()
            .is_some_and(|(at, _)| *at <= t + h - delay + 1e-12)
        {
            due = self.queue.pop_front().map(|(_, g)| g);
        }
        let sent = self.sent.take().expect("initialized");
        let next = match due {
            Some(g) if s[self.rate_limit] > 0.0 => {
                Self::rate_limited(&sent, g, s[self.rate_limit] * h)
            }
            Some(g) => g,
            None => sent,
        };
        self.write_gains(s, &next);
        self.sent = Some(next);

        // Desired response on the DVPP base, input held over the step: the PCC power's deviation
        // from the DVPP's summed set point (a cloud that lowers a unit's set point is the same
        // disturbance as a load step of that size).
        let dp_set = self.set_point(s) - self.p_set0;
        let dp = match &self.pocs {
            None => (s[self.pcc_p] - self.pcc0[0] - dp_set) * s[self.s_base] / s[self.s_dvpp],
            Some(pocs) => {
                let dp = pocs.rotated_deviation(s, dp_set) * s[self.s_base] / s[self.s_dvpp];
                s[pocs.dp] = dp;
                dp
            }
        };
        let t_pf = self.t_pf.as_mut().expect("initialized");
        s[self.ref_df] = -t_pf.step(dp, h);
        s[self.ref_dv] = self.desired_dv(s);
        s[self.err_df] = (s[self.pcc_f] - 1.0) - s[self.ref_df];
        if let Some(pocs) = &self.pocs {
            for p in &pocs.vars {
                s[p.err_df] = (s[p.f] - 1.0) - s[self.ref_df];
            }
        }
        s[self.err_dv] = (s[self.pcc_v] - self.pcc0[2]) - s[self.ref_dv];
        Ok(())
    }
}

#[cfg(test)]
mod golden {
    #[test]
    fn model_description_matches_the_golden_copy() {
        fmi_export::assert_golden::<super::Operator>(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/modelDescription.xml"
        ));
    }
}
