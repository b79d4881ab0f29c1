//! The DVPP operator as a host-independent object: online ADPF dc gains and the desired aggregate response.
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
//! units whose `share` (ε and 1 - ε) scales its availability and its rating.
//!
//! A DVPP area with several points of coupling (case study III, `pocs = n`): the desired
//! frequency deviation is matched at the POCs, `ref.df = -T_pf Σ_k Δp'_poc,k`, with `Δp'` the
//! POC power deviation rotated by the lines' R/X (`rot.rx`, as the DERs'; 0: plain `Δp`), and
//! every POC reports its own matching error `poc[k].err_df`. The change of what the area's own
//! loads draw (`area.p_load`, `area.q_load`) is added back to `Σ_k Δp_poc,k`: a load step inside
//! the area is a disturbance, not the DVPP's response.
//!
//! The host (the `dvpp_operator` FMU, or any other) turns its inputs into a [`Measurement`],
//! calls [`Operator::initialize`] once and [`Operator::step`] every communication step, and
//! writes the [`Command`] back; the command's [`Notice`]s are what it logs. Every field that can
//! be at fault is named as the FMU names it (`Tdes.H`, `der[2].S_rated`, `pcc.p`, ...).

use dvpp_control::adaptation::{
    reactive_capacity, renormalize_with_floor, renormalize_with_floors,
};
use dvpp_control::fleet::Shape;
use dvpp_control::floor_scale;
use dvpp_control::{Fleet, Hold, LtiSimulator, Rotation, TDes};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::fmt;

use crate::{Error, Notice};

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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Unit {
    pub name: String,
    pub role: Role,
    pub form: Form,
    /// Converter rating of the whole unit, MVA (the FMU's parameter `der[k].S_rated`).
    pub s_rated: f64,
    /// The part of the unit this entry stands for (ε or 1 - ε in a hybrid DVPP; 1 otherwise).
    #[serde(default = "one")]
    pub share: f64,
}

fn one() -> f64 {
    1.0
}

impl Unit {
    /// The units of `fleet`, grid-forming, whole.
    pub fn fleet(fleet: &Fleet) -> Vec<Unit> {
        fleet
            .units
            .iter()
            .map(|u| Unit {
                name: u.name.clone(),
                role: match u.kind.shape {
                    Shape::LowPass => Role::LowPass,
                    Shape::Complement => Role::Complement,
                },
                form: Form::GridForming,
                s_rated: u.kind.s_rated,
                share: 1.0,
            })
            .collect()
    }
}

/// Largest number of points of coupling.
pub const MAX_POCS: usize = 16;

/// Everything the operator is configured with; [`Operator::initialize`] validates it (the structure alone: [`Params::check_structure`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Params {
    /// The DERs served, in the order of the FMU's `der[k]` (k = 1, 2, ...).
    pub units: Vec<Unit>,
    /// Points of coupling of a DVPP area: `ref.df` is matched at them; 0: at the PCC.
    pub pocs: usize,
    /// `rot.rx`: the R/X ratio the rotation `p' = (p - rx q)/sqrt(1 + rx²)` of the POC powers
    /// compensates (0: plain `Δp`; only with `pocs` > 0).
    pub rot_rx: f64,
    /// `S_base`: the system base of the powers measured, MVA.
    pub s_base: f64,
    /// `S_dvpp`: the DVPP base `T_des` is specified on, MVA.
    pub s_dvpp: f64,
    /// `Tdes.H`: virtual inertia of `T_pf = 1/(H s + D)`, s.
    pub h: f64,
    /// `Tdes.D`: damping of `T_pf`, pu.
    pub d: f64,
    /// `Tdes.Dq`: q-v droop `T_qv = Dq`, pu.
    pub dq: f64,
    /// `mu_min`: floor of a grid-forming low-pass unit's active dc gain (at least 20 % of `S_dvpp`).
    pub mu_min: f64,
    /// `rate_limit`: largest change of a dc gain per second (0: none), 1/s.
    pub rate_limit: f64,
    /// `delay`: communication delay of the dc gains (0: none), s.
    pub delay: f64,
}

impl Default for Params {
    /// Case study I ([`Fleet::case_study_i`]: wind and PV low-pass, BESS the complement), all
    /// grid-forming, at the PCC; the FMU's parameter start values.
    fn default() -> Self {
        Params {
            units: Unit::fleet(&Fleet::case_study_i()),
            pocs: 0,
            rot_rx: 0.0,
            s_base: 100.0,
            s_dvpp: 96.0,
            h: 5.55,
            d: 33.33,
            dq: 0.01,
            mu_min: 0.05,
            rate_limit: 0.0,
            delay: 0.0,
        }
    }
}

/// An error naming `field` (of the `[model]` table, or a parameter or input as the FMU names it).
fn named(field: impl AsRef<str>, message: impl fmt::Display) -> Error {
    Error::field(field.as_ref(), message)
}

impl Params {
    /// The structure alone (what an FMU's variables depend on, its `[model]` table, whose
    /// fields the errors name: `ders`, `ders[k].s_rated`, `ders[k].share`, `pocs`, `rot_rx`):
    /// at least one unit, each with a positive rating and a share in (0, 1], a low-pass unit,
    /// at most [`MAX_POCS`] POCs, and a valid rotation, only where there are POCs.
    pub fn check_structure(&self) -> Result<(), Error> {
        for (k, u) in self.units.iter().enumerate() {
            if !(u.s_rated.is_finite() && u.s_rated > 0.0) {
                return Err(named(
                    format!("ders[{}].s_rated", k + 1),
                    format!("= {} ({}): must be positive", u.s_rated, u.name),
                ));
            }
        }
        self.check_units_and_pocs()?;
        Rotation::from_rx(self.rot_rx).map_err(|e| named("rot_rx", e))?;
        if self.rot_rx != 0.0 && self.pocs == 0 {
            return Err(named(
                "rot_rx",
                format!(
                    "= {}: the rotation applies to the POC powers, but pocs = 0",
                    self.rot_rx
                ),
            ));
        }
        Ok(())
    }

    /// What [`Params::check_structure`] checks but the ratings and the rotation (which are
    /// parameters once running).
    fn check_units_and_pocs(&self) -> Result<(), Error> {
        if self.units.is_empty() {
            return Err(named("ders", "no entries, expected at least one DER"));
        }
        for (k, u) in self.units.iter().enumerate() {
            if !(u.share > 0.0 && u.share <= 1.0) {
                return Err(named(
                    format!("ders[{}].share", k + 1),
                    format!("= {} ({}): must be in (0, 1]", u.share, u.name),
                ));
            }
        }
        if !self.units.iter().any(|u| u.role == Role::LowPass) {
            return Err(named("ders", "no low-pass unit carries the steady state"));
        }
        if self.pocs > MAX_POCS {
            return Err(named(
                "pocs",
                format!("= {}: at most {MAX_POCS} points of coupling", self.pocs),
            ));
        }
        Ok(())
    }

    /// The structure and every parameter's value (each named as the FMU's parameter); returns
    /// the realization of `T_pf` and the rotation of the POC powers they give.
    fn realize(&self) -> Result<(LtiSimulator, Rotation), Error> {
        // The ratings are the parameters `der[k].S_rated` here: named as such.
        for (k, u) in self.units.iter().enumerate() {
            if !(u.s_rated.is_finite() && u.s_rated > 0.0) {
                return Err(named(
                    format!("der[{}].S_rated", k + 1),
                    format!("= {}: must be positive", u.s_rated),
                ));
            }
        }
        self.check_units_and_pocs()?;
        for (name, x) in [("S_base", self.s_base), ("S_dvpp", self.s_dvpp)] {
            if !(x.is_finite() && x > 0.0) {
                return Err(named(name, format!("= {x}: must be positive")));
            }
        }
        if !(0.0..=1.0).contains(&self.mu_min) {
            return Err(named(
                "mu_min",
                format!("= {}: must be in [0, 1]", self.mu_min),
            ));
        }
        for (name, x) in [("rate_limit", self.rate_limit), ("delay", self.delay)] {
            // NaN is refused as well.
            if x.is_nan() || x < 0.0 {
                return Err(named(name, format!("= {x}: must not be negative")));
            }
        }
        // Only the p-f channel is simulated here; T_qv = Dq is static (the roll-off is irrelevant).
        let tdes = TDes::inertia_droop(self.h, self.d, self.dq, 1.0).map_err(|e| {
            let e = e.to_string();
            let field = if e.contains("T_des H") {
                "Tdes.H"
            } else if e.contains("T_des D_q") {
                "Tdes.Dq"
            } else if e.contains("T_des D") {
                "Tdes.D"
            } else {
                "Tdes.H, Tdes.D"
            };
            named(field, e)
        })?;
        let rot = Rotation::from_rx(self.rot_rx).map_err(|e| named("rot.rx", e))?;
        if self.rot_rx != 0.0 && self.pocs == 0 {
            return Err(named(
                "rot.rx",
                format!(
                    "= {}: the rotation applies to the POC powers, but there are none",
                    self.rot_rx
                ),
            ));
        }
        Ok((tdes.pf_simulator(Hold::Zero), rot))
    }

    /// The indices of the low-pass units, in order: the order of [`Command::mu_p`].
    pub fn low_pass(&self) -> impl Iterator<Item = usize> + '_ {
        self.units
            .iter()
            .enumerate()
            .filter(|(_, u)| u.role == Role::LowPass)
            .map(|(k, _)| k)
    }
}

/// What the operator reads of one DER each step (powers on `S_base`).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct UnitMeasurement {
    /// `der[k].P_avail`: available active power, pu.
    pub p_avail: f64,
    /// `der[k].p`: active power (for its PQ capability), pu.
    pub p: f64,
    /// `der[k].p_set`: active set point, pu.
    pub p_set: f64,
}

/// The DVPP's point of common coupling (powers on `S_base`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pcc {
    /// `pcc.p`: active power the DVPP sends, pu.
    pub p: f64,
    /// `pcc.q`: reactive power, pu.
    pub q: f64,
    /// `pcc.f`: frequency, pu of `f_nom`.
    pub f: f64,
    /// `pcc.v`: voltage magnitude, pu.
    pub v: f64,
}

impl Default for Pcc {
    fn default() -> Self {
        Pcc {
            p: 0.0,
            q: 0.0,
            f: 1.0,
            v: 1.0,
        }
    }
}

/// One point of coupling of a DVPP area (powers on `S_base`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PocMeasurement {
    /// `poc[k].p`: active power the area sends through the POC, pu.
    pub p: f64,
    /// `poc[k].q`: reactive power, pu.
    pub q: f64,
    /// `poc[k].f`: frequency, pu of `f_nom`.
    pub f: f64,
}

impl Default for PocMeasurement {
    fn default() -> Self {
        PocMeasurement {
            p: 0.0,
            q: 0.0,
            f: 1.0,
        }
    }
}

/// Everything the operator reads each step.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Measurement {
    /// One per unit of [`Params::units`], in order.
    pub units: Vec<UnitMeasurement>,
    pub pcc: Pcc,
    /// One per point of coupling ([`Params::pocs`]; none at the PCC).
    pub pocs: Vec<PocMeasurement>,
    /// `area.p_load`, `area.q_load`: what the loads inside the DVPP area draw, on `S_base`
    /// (read with POCs only).
    pub area_load: (f64, f64),
}

impl Measurement {
    /// The measurement fits the parameters (one entry per unit and POC) and is finite, each
    /// value named as the FMU's input.
    fn check(&self, params: &Params) -> Result<(), Error> {
        for (field, found, expected) in [
            ("der", self.units.len(), params.units.len()),
            ("poc", self.pocs.len(), params.pocs),
        ] {
            if found != expected {
                return Err(named(
                    field,
                    format!("{found} entries, expected {expected}"),
                ));
            }
        }
        let not_finite = |field: String, x: f64| named(field, format!("= {x}: not finite"));
        for (k, u) in self.units.iter().enumerate() {
            for (name, x) in [("P_avail", u.p_avail), ("p", u.p), ("p_set", u.p_set)] {
                if !x.is_finite() {
                    return Err(not_finite(format!("der[{}].{name}", k + 1), x));
                }
            }
        }
        let pcc = self.pcc;
        for (name, x) in [
            ("pcc.p", pcc.p),
            ("pcc.q", pcc.q),
            ("pcc.f", pcc.f),
            ("pcc.v", pcc.v),
        ] {
            if !x.is_finite() {
                return Err(not_finite(name.into(), x));
            }
        }
        for (k, poc) in self.pocs.iter().enumerate() {
            for (name, x) in [("p", poc.p), ("q", poc.q), ("f", poc.f)] {
                if !x.is_finite() {
                    return Err(not_finite(format!("poc[{}].{name}", k + 1), x));
                }
            }
        }
        for (name, x) in [
            ("area.p_load", self.area_load.0),
            ("area.q_load", self.area_load.1),
        ] {
            if !x.is_finite() {
                return Err(not_finite(name.into(), x));
            }
        }
        Ok(())
    }

    /// The DVPP's summed active set point, on S_base.
    fn set_point(&self) -> f64 {
        self.units.iter().map(|u| u.p_set).sum()
    }
}

/// What the operator sends each step.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Command {
    /// Active dc gains of the low-pass units, in the order of [`Params::low_pass`]
    /// (`der[k].mu_p`; a complement unit receives all of them, `der[k].mu_p_lpf[j]`).
    pub mu_p: Vec<f64>,
    /// Reactive dc gains of all units (`der[k].mu_q`).
    pub mu_q: Vec<f64>,
    /// `check.sum_mu_p`, `check.sum_mu_q`: the sums as sent (participation: 1).
    pub sum_mu_p: f64,
    pub sum_mu_q: f64,
    /// `ref.df`: desired frequency deviation, pu of `f_nom`.
    pub ref_df: f64,
    /// `ref.dv`: desired voltage deviation, pu.
    pub ref_dv: f64,
    /// `err.df`: measured minus desired frequency deviation at the PCC.
    pub err_df: f64,
    /// `err.dv`: measured minus desired voltage deviation.
    pub err_dv: f64,
    /// The input of `T_pf` on `S_dvpp` (with POCs the FMU's `poc.dp`).
    pub dp: f64,
    /// `poc[k].err_df`: measured minus desired frequency deviation at each POC.
    pub poc_err_df: Vec<f64>,
    /// What happened that the host logs, in order.
    pub notices: Vec<Notice>,
}

impl Command {
    /// The active dc gain `unit` (an index into [`Params::units`]) receives, if it is low-pass.
    pub fn mu_p_of(&self, params: &Params, unit: usize) -> Option<f64> {
        params
            .low_pass()
            .position(|k| k == unit)
            .map(|j| self.mu_p[j])
    }
}

/// Gains as sent: active for the low-pass units (in their order), reactive for all units.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Gains {
    p: Vec<f64>,
    q: Vec<f64>,
}

/// Which degenerate input a warning was given for (each is logged once per episode).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
enum Degenerate {
    NoAvailability,
    NegativeAvailability(usize),
    OverRating(usize),
    NoReactiveCapacity,
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

/// The conditions warned of, each with the time it has been clear since.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
struct Warned(Vec<(Degenerate, Option<f64>)>);

impl Warned {
    /// Warn once per episode: `active` says whether the condition holds now, `clear` whether it
    /// has ended (for a threshold, below it by a margin); an episode ends when it has been clear
    /// for [`RELEASE`] seconds, so that a value hovering at a threshold is one episode, not one
    /// per crossing. The end of an episode is an event.
    fn note(
        &mut self,
        notices: &mut Vec<Notice>,
        t: f64,
        what: Degenerate,
        (active, clear): (bool, bool),
        message: impl FnOnce() -> String,
    ) {
        let warned = &mut self.0;
        match warned.iter().position(|(w, _)| *w == what) {
            None if active => {
                warned.push((what, None));
                notices.push(Notice::Warning(message()));
            }
            None => {}
            Some(i) if clear => {
                let since = *warned[i].1.get_or_insert(t);
                if t - since >= RELEASE {
                    warned.remove(i);
                    notices.push(Notice::Event(what.ended()));
                }
            }
            Some(i) => warned[i].1 = None,
        }
    }
}

/// Where the desired frequency deviation is matched.
#[derive(Debug, Clone, Serialize, Deserialize)]
enum Matching {
    /// At the PCC: `Δp = Δp_pcc`.
    Pcc,
    /// At the points of coupling of a DVPP area.
    Pocs {
        /// The rotation of `rot.rx`.
        rot: Rotation,
        /// Every POC's p, q at initialization.
        pq0: Vec<(f64, f64)>,
        /// The area's load at initialization.
        load0: (f64, f64),
    },
}

/// The running operator: its parameters and the state a step advances.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Operator {
    params: Params,
    /// `-T_pf` realized on Δp.
    t_pf: LtiSimulator,
    matching: Matching,
    /// PCC operating point at initialization: p, q, v.
    pcc0: [f64; 3],
    /// The DVPP's summed active set point at initialization, on S_base.
    p_set0: f64,
    /// Gains currently sent, and gains waiting out the communication delay (time, gains).
    sent: Gains,
    queue: VecDeque<(f64, Gains)>,
    warned: Warned,
}

impl Operator {
    /// Validate `params`, take `m` as the operating point the deviations are measured from,
    /// and return the operator with its first command (the gains `m` calls for, zero desired
    /// deviations).
    pub fn initialize(params: Params, m: &Measurement) -> Result<(Operator, Command), Error> {
        Operator::initialize_with(params, m, Warned::default())
    }

    /// [`Operator::initialize`] again, while the host is still initializing (new parameters or
    /// inputs): the same, except that a degenerate input `previous` warned of is not warned
    /// again.
    pub fn initialize_after(
        previous: &Operator,
        params: Params,
        m: &Measurement,
    ) -> Result<(Operator, Command), Error> {
        Operator::initialize_with(params, m, previous.warned.clone())
    }

    fn initialize_with(
        params: Params,
        m: &Measurement,
        mut warned: Warned,
    ) -> Result<(Operator, Command), Error> {
        let (t_pf, rot) = params.realize()?;
        m.check(&params)?;
        let mut notices = Vec::new();
        let gains = target(&params, m, &mut warned, 0.0, &mut notices)?;
        let matching = if params.pocs == 0 {
            Matching::Pcc
        } else {
            Matching::Pocs {
                rot,
                pq0: m.pocs.iter().map(|p| (p.p, p.q)).collect(),
                load0: m.area_load,
            }
        };
        let command = Command {
            mu_p: gains.p.clone(),
            mu_q: gains.q.clone(),
            sum_mu_p: gains.p.iter().sum(),
            sum_mu_q: gains.q.iter().sum(),
            ref_df: 0.0,
            ref_dv: 0.0,
            err_df: m.pcc.f - 1.0,
            err_dv: 0.0,
            dp: 0.0,
            poc_err_df: m.pocs.iter().map(|p| p.f - 1.0).collect(),
            notices,
        };
        let op = Operator {
            t_pf,
            matching,
            pcc0: [m.pcc.p, m.pcc.q, m.pcc.v],
            p_set0: m.set_point(),
            sent: gains,
            queue: VecDeque::new(),
            warned,
            params,
        };
        Ok((op, command))
    }

    /// The parameters the operator runs with.
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// Advance from `t` to `t + h` with the measurement `m` (held over the step): the gains
    /// the inputs call for, delayed by the communication delay, then rate limited; the desired
    /// response and the matching errors at `t + h`. `t` is the host's time (the delay and the
    /// end of a warned episode are measured on it).
    pub fn step(&mut self, m: &Measurement, t: f64, h: f64) -> Result<Command, Error> {
        m.check(&self.params)?;
        let p = &self.params;
        let mut notices = Vec::new();
        let target = target(p, m, &mut self.warned, t + h, &mut notices)?;
        self.queue.push_back((t + h, target));
        let mut due = None;
        while self
            .queue
            .front()
            .is_some_and(|(at, _)| *at <= t + h - p.delay + 1e-12)
        {
            due = self.queue.pop_front().map(|(_, g)| g);
        }
        if let Some(g) = due {
            self.sent = if p.rate_limit > 0.0 {
                rate_limited(&self.sent, g, p.rate_limit * h)
            } else {
                g
            };
        }

        // Desired response on the DVPP base, input held over the step: the PCC power's deviation
        // from the DVPP's summed set point (a cloud that lowers a unit's set point is the same
        // disturbance as a load step of that size).
        let dp_set = m.set_point() - self.p_set0;
        let dp = match &self.matching {
            Matching::Pcc => (m.pcc.p - self.pcc0[0] - dp_set) * p.s_base / p.s_dvpp,
            Matching::Pocs { rot, pq0, load0 } => {
                rotated_deviation(m, *rot, pq0, *load0, dp_set) * p.s_base / p.s_dvpp
            }
        };
        let ref_df = -self.t_pf.step(dp, h);
        let ref_dv = -p.dq * (m.pcc.q - self.pcc0[1]) * p.s_base / p.s_dvpp;
        let g = &self.sent;
        Ok(Command {
            mu_p: g.p.clone(),
            mu_q: g.q.clone(),
            sum_mu_p: g.p.iter().sum(),
            sum_mu_q: g.q.iter().sum(),
            ref_df,
            ref_dv,
            err_df: (m.pcc.f - 1.0) - ref_df,
            err_dv: (m.pcc.v - self.pcc0[2]) - ref_dv,
            dp,
            poc_err_df: m.pocs.iter().map(|poc| (poc.f - 1.0) - ref_df).collect(),
            notices,
        })
    }
}

/// The floor of each low-pass unit's active dc gain, in the order of [`Params::low_pass`]:
/// `mu_min · min(1, κ S_i/(0.05 S_dvpp))` for a grid-forming unit (`S_i` its rating times its
/// share): `mu_min` for a unit of at least 20 % of `S_dvpp`, proportional to its share below
/// that. With the default `mu_min` = 0.05 it is the floor the DER clamps its own gain at
/// ([`dvpp_control::mu_min_gfm`]); a larger `mu_min` only raises it. 0 for a grid-following unit.
fn floors(p: &Params) -> Vec<f64> {
    p.low_pass()
        .map(|k| {
            let u = &p.units[k];
            if u.form == Form::GridForming {
                let rating = u.s_rated * u.share;
                p.mu_min * floor_scale(rating, p.s_dvpp)
            } else {
                0.0
            }
        })
        .collect()
}

/// The gains the measurement calls for; degenerate inputs noted at time `t`.
fn target(
    p: &Params,
    m: &Measurement,
    warned: &mut Warned,
    t: f64,
    notices: &mut Vec<Notice>,
) -> Result<Gains, Error> {
    let lpf: Vec<usize> = p.low_pass().collect();
    let mut weights = Vec::with_capacity(lpf.len());
    for &k in &lpf {
        let avail = m.units[k].p_avail;
        let name = &p.units[k].name;
        warned.note(
            notices,
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
        weights.push(avail.max(0.0) * p.units[k].share);
    }
    let none = weights.iter().all(|&w| w == 0.0);
    warned.note(
        notices,
        t,
        Degenerate::NoAvailability,
        (none, !none),
        || {
            "all low-pass DERs report zero available power: active dc gains fall back to equal shares".into()
        },
    );
    let mu_p = renormalize_with_floors(&weights, &floors(p))
        .map_err(|e| Error::unit(format!("active dc gains: {e}")))?;

    let mut capacity = Vec::with_capacity(p.units.len());
    for (k, u) in p.units.iter().enumerate() {
        let rating = u.s_rated * u.share;
        let p_mw = m.units[k].p * p.s_base;
        let name = &u.name;
        warned.note(
            notices,
            t,
            Degenerate::OverRating(k),
            (
                p_mw.abs() > rating,
                p_mw.abs() < (1.0 - RATING_HYSTERESIS) * rating,
            ),
            || {
                format!(
                    "DER {} '{name}': |p| = {:.2} MW exceeds its rating {rating:.2} MVA: no reactive capacity",
                    k + 1,
                    p_mw.abs()
                )
            },
        );
        capacity.push(reactive_capacity(rating, p_mw));
    }
    let none = capacity.iter().all(|&c| c == 0.0);
    warned.note(
        notices,
        t,
        Degenerate::NoReactiveCapacity,
        (none, !none),
        || "no DER has reactive capacity left: reactive dc gains fall back to equal shares".into(),
    );
    let mu_q = renormalize_with_floor(&capacity, &vec![false; capacity.len()], 0.0)
        .map_err(|e| Error::unit(format!("reactive dc gains: {e}")))?;
    Ok(Gains { p: mu_p, q: mu_q })
}

/// Move the sent gains toward `target` by at most `max_change` per gain; the step is scaled as
/// a whole, so the sums stay exactly where they were.
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

/// `Σ_k Δp'_poc,k` less the rotated change `dp_set` of the DVPP's summed set point, on S_base:
/// a set point moves a unit's `p` (its `q'`-`v` loop holds `q`), so its `p'` by the rotation's
/// `p` component.
fn rotated_deviation(
    m: &Measurement,
    rot: Rotation,
    pq0: &[(f64, f64)],
    load0: (f64, f64),
    dp_set: f64,
) -> f64 {
    let sum: f64 = m
        .pocs
        .iter()
        .zip(pq0)
        .map(|(p, &(p0, q0))| rot.rotate(p.p - p0, p.q - q0).0)
        .sum();
    // What the area's loads draw more is not the DVPP's response: added back, the sum is what
    // the units deliver net of the area's losses.
    let (lp, lq) = m.area_load;
    let load = rot.rotate(lp - load0.0, lq - load0.1).0;
    sum + load - rot.rotate(dp_set, 0.0).0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Case study I's three units at half availability, everything at its operating point.
    fn measurement() -> Measurement {
        Measurement {
            units: vec![
                UnitMeasurement {
                    p_avail: 0.23,
                    p: 0.2,
                    p_set: 0.2,
                },
                UnitMeasurement {
                    p_avail: 0.365,
                    p: 0.3,
                    p_set: 0.3,
                },
                UnitMeasurement::default(),
            ],
            ..Measurement::default()
        }
    }

    fn field_of(e: Error) -> String {
        e.field.unwrap_or_default()
    }

    #[test]
    fn a_bad_parameter_or_measurement_is_refused_by_the_fmu_s_name() {
        let refused = |edit: &dyn Fn(&mut Params, &mut Measurement)| {
            let (mut p, mut m) = (Params::default(), measurement());
            edit(&mut p, &mut m);
            field_of(Operator::initialize(p, &m).expect_err("refused"))
        };
        assert_eq!(refused(&|p, _| p.h = 4.9e-324), "Tdes.H");
        assert_eq!(refused(&|p, _| p.dq = 0.0), "Tdes.Dq");
        assert_eq!(refused(&|p, _| p.delay = -1.0), "delay");
        assert_eq!(refused(&|p, _| p.rate_limit = f64::NAN), "rate_limit");
        assert_eq!(refused(&|p, _| p.s_dvpp = 0.0), "S_dvpp");
        assert_eq!(refused(&|p, _| p.rot_rx = 1.0), "rot.rx");
        assert_eq!(refused(&|p, _| p.units[1].s_rated = 0.0), "der[2].S_rated");
        assert_eq!(refused(&|_, m| m.units.truncate(2)), "der");
        assert_eq!(refused(&|_, m| m.pcc.q = f64::NAN), "pcc.q");
        assert_eq!(
            refused(&|_, m| m.units[1].p_set = f64::INFINITY),
            "der[2].p_set"
        );
        let mut p = Params::default();
        p.units.retain(|u| u.role != Role::LowPass);
        assert_eq!(field_of(p.check_structure().unwrap_err()), "ders");
        let mut p = Params::default();
        p.units[1].share = 0.0;
        assert_eq!(field_of(p.check_structure().unwrap_err()), "ders[2].share");
    }

    #[test]
    fn the_gains_sum_to_one_and_follow_the_availability() {
        let (mut op, first) = Operator::initialize(Params::default(), &measurement()).unwrap();
        assert_eq!(first.mu_p.len(), 2);
        assert_eq!(first.mu_q.len(), 3);
        assert!((first.sum_mu_p - 1.0).abs() < 1e-12 && (first.sum_mu_q - 1.0).abs() < 1e-12);
        assert_eq!(first.mu_p_of(op.params(), 1), Some(first.mu_p[1]));
        assert_eq!(first.mu_p_of(op.params(), 2), None);
        // Wind loses its availability: PV's share grows.
        let mut m = measurement();
        m.units[0].p_avail = 0.0;
        let next = op.step(&m, 0.0, 0.01).unwrap();
        assert!(next.mu_p[1] > first.mu_p[1], "{next:?}");
        assert!((next.sum_mu_p - 1.0).abs() < 1e-12);
        assert!(next.notices.is_empty(), "{:?}", next.notices);
    }

    #[test]
    fn a_pcc_power_step_gives_a_desired_response_of_the_opposite_sign() {
        let (mut op, _) = Operator::initialize(Params::default(), &measurement()).unwrap();
        let mut m = measurement();
        m.pcc.p = 0.1;
        m.pcc.f = 0.999;
        let c = op.step(&m, 0.0, 0.01).unwrap();
        assert!(c.dp > 0.0 && c.ref_df < 0.0, "{c:?}");
        assert_eq!(c.err_df, (0.999 - 1.0) - c.ref_df);
        // A set point raised by as much is not a disturbance.
        let (mut op, _) = Operator::initialize(Params::default(), &measurement()).unwrap();
        m.units[0].p_set += 0.1;
        let c = op.step(&m, 0.0, 0.01).unwrap();
        assert!(c.dp.abs() < 1e-15, "{c:?}");
    }

    #[test]
    fn a_degenerate_input_is_one_warning_and_its_end_one_event() {
        let (mut op, _) = Operator::initialize(Params::default(), &measurement()).unwrap();
        let mut m = measurement();
        m.units[1].p_avail = -0.1;
        let mut notices = Vec::new();
        let mut t = 0.0;
        for k in 0..300 {
            if k == 100 {
                m.units[1].p_avail = 0.3;
            }
            notices.extend(op.step(&m, t, 0.01).unwrap().notices);
            t += 0.01;
        }
        assert_eq!(notices.len(), 2, "{notices:?}");
        assert!(matches!(&notices[0], Notice::Warning(w) if w.contains("DER 2 'pv': negative")));
        assert!(matches!(&notices[1], Notice::Event(e) if e.contains("no longer negative")));
    }

    #[test]
    fn a_saved_operator_continues_bit_identically() {
        let params = Params {
            rate_limit: 0.5,
            delay: 0.03,
            ..Params::default()
        };
        let (mut op, _) = Operator::initialize(params, &measurement()).unwrap();
        let mut m = measurement();
        let mut t = 0.0;
        let mut saved = None;
        let mut after = Vec::new();
        for k in 0..40 {
            m.units[0].p_avail = 0.23 * (1.0 - 0.02 * k as f64);
            m.pcc.p = 0.001 * k as f64;
            if k == 20 {
                saved = Some((postcard::to_allocvec(&op).unwrap(), t));
            }
            if k >= 20 {
                after.push(op.step(&m, t, 0.01).unwrap());
            } else {
                op.step(&m, t, 0.01).unwrap();
            }
            t += 0.01;
        }
        let (bytes, mut t) = saved.unwrap();
        let mut restored: Operator = postcard::from_bytes(&bytes).unwrap();
        let mut m = measurement();
        for (k, expected) in (20..40).zip(&after) {
            m.units[0].p_avail = 0.23 * (1.0 - 0.02 * k as f64);
            m.pcc.p = 0.001 * k as f64;
            assert_eq!(&restored.step(&m, t, 0.01).unwrap(), expected, "step {k}");
            t += 0.01;
        }
    }
}
