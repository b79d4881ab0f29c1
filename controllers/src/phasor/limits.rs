//! Converter limits on the ac side: current-reference saturation (grid-forming and
//! grid-following), the dc link's power budget, the modulation limit, and their episodes.
//!
//! Currents are pu on `S_rated` at 1 pu voltage, split along the measured terminal voltage into an
//! active part `i_p` (`p = |V| i_p`) and a reactive part `i_q` (`q = |V| i_q`). A grid-forming
//! unit's saturation is enforced by the grid's slot in every network solution (the DER sends
//! `i_limit`, `p_min`, `p_max`); here the same rule estimates what it holds back.

use super::Priority;
use crate::Notice;
use dvpp_control::Complex;
use serde::{Deserialize, Serialize};

/// Below this terminal voltage (pu) the current split uses this value (a dead bus has no
/// direction; the magnitude limit still holds).
pub const V_FLOOR: f64 = 0.05;

/// A limit episode ends after this long without the limit acting (s).
pub const RELEASE: f64 = 1.0;

/// Grid-forming with `limit.priority` = 1: the ratio `X/R` of the virtual impedance whose
/// current's direction a limited request turns to, `(E - V)/(R + jX)` (reactive current in a
/// dip, active current as the internal angle moves ahead of the bus: a synchronizing power).
pub const LIMIT_X_R: f64 = 5.0;

/// Grid-forming with `limit.priority` = 1: how far beyond `I_max` (fraction) the request goes
/// before its direction has turned fully to the virtual impedance's (linearly from `I_max`, so
/// that the current stays continuous where the limit starts to act).
pub const LIMIT_BAND: f64 = 0.05;

/// What a limiter did to one current reference.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Limited {
    /// The current after the limits, same frame as the request.
    pub current: Complex<f64>,
    /// The magnitude reached `I_max`.
    pub current_limit: bool,
    /// The active part reached the dc link's budget.
    pub dc_limit: bool,
}

/// Grid-forming current-reference saturation: the requested current `i` (rated pu, in the frame
/// of the terminal voltage direction `u`) is cut to the dc budget `[p_lo, p_hi]/|V|` on its active
/// part, then scaled onto the circle `I_max` keeping its direction.
pub fn saturate_forming(
    i: Complex<f64>,
    u: Complex<f64>,
    v: f64,
    i_max: f64,
    (p_lo, p_hi): (f64, f64),
) -> Limited {
    let v = v.max(V_FLOOR);
    // Components along and across the voltage: i = (i_p - j i_q) u.
    let local = i * u.conj();
    let (mut ip, mut iq) = (local.re, -local.im);
    let (lo, hi) = (p_lo / v, p_hi / v);
    let mut dc_limit = false;
    if ip > hi || ip < lo {
        ip = ip.clamp(lo.min(hi), hi);
        dc_limit = true;
    }
    let mag = dvpp_math::hypot(ip, iq);
    let current_limit = mag > i_max;
    if !(current_limit || dc_limit) {
        return Limited {
            current: i,
            ..Limited::default()
        };
    }
    if current_limit {
        ip *= i_max / mag;
        iq *= i_max / mag;
    }
    Limited {
        current: Complex::new(ip, -iq) * u,
        current_limit,
        dc_limit,
    }
}

/// Grid-forming, reactive current in dips (`limit.priority` = 1): a request `wanted` whose
/// magnitude is `request` times `I_max` (> 1: the limit acts) turned, keeping its magnitude,
/// toward the direction of `ev/(1 + j LIMIT_X_R)`, `ev = E - V` the voltage from the bus to the
/// internal voltage, by the weight `(request - 1)/LIMIT_BAND` (at most 1). The output stage then
/// holds its magnitude at `I_max` in the turned direction. Unchanged at or below `I_max`, or
/// with no voltage across (`ev` = 0).
pub fn turn_reactive(wanted: Complex<f64>, request: f64, ev: Complex<f64>) -> Complex<f64> {
    let (n_w, n_ev) = (dvpp_math::cabs(wanted), dvpp_math::cabs(ev));
    if request <= 1.0 || n_w == 0.0 || n_ev == 0.0 {
        return wanted;
    }
    let w = ((request - 1.0) / LIMIT_BAND).min(1.0);
    let z = ev / Complex::new(1.0, LIMIT_X_R);
    let dir = wanted / n_w * (1.0 - w) + z / dvpp_math::cabs(z) * w;
    let n_dir = dvpp_math::cabs(dir);
    if n_dir == 0.0 {
        return wanted;
    }
    dir * (n_w / n_dir)
}

/// Grid-following current limit: active part within the dc budget, then `|i| <= I_max` with the
/// component `first` kept first. Takes and returns `(i_p, i_q)`.
pub fn saturate_following(
    (ip, iq): (f64, f64),
    v: f64,
    i_max: f64,
    (p_lo, p_hi): (f64, f64),
    first: Priority,
) -> ((f64, f64), bool, bool) {
    let v = v.max(V_FLOOR);
    let (lo, hi) = (p_lo / v, p_hi / v);
    let ip_dc = ip.clamp(lo.min(hi), hi);
    let dc_limit = ip_dc != ip;
    let current_limit = dvpp_math::hypot(ip_dc, iq) > i_max;
    if !current_limit {
        return ((ip_dc, iq), false, dc_limit);
    }
    let keep = |x: f64| x.clamp(-i_max, i_max);
    let rest = |x: f64, kept: f64| {
        let room = (i_max * i_max - kept * kept).max(0.0).sqrt();
        x.clamp(-room, room)
    };
    let out = if first == Priority::Reactive {
        let q = keep(iq);
        (rest(ip_dc, q), q)
    } else {
        let p = keep(ip_dc);
        (p, rest(iq, p))
    };
    (out, true, dc_limit)
}

/// One limit's episode: a warning when it starts acting, an event when it has not acted for
/// [`RELEASE`] seconds, nothing in between.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Episode {
    active: bool,
    /// Time the limit last acted.
    last: f64,
    /// Worst value seen in this episode (for the closing line).
    worst: f64,
}

impl Episode {
    /// Whether the episode is on (the output flag).
    pub fn active(&self) -> bool {
        self.active
    }

    /// Record the limit at time `t`: `acting` with the measure `value` (e.g. the requested
    /// current in pu of `I_max`); `what` names the limit in the log lines (called only when
    /// one is written: formatting a label every step would cost more than the step).
    pub fn record<S: std::fmt::Display>(
        &mut self,
        t: f64,
        acting: bool,
        value: f64,
        what: impl FnOnce() -> S,
        notices: &mut Vec<Notice>,
    ) {
        if acting {
            if !self.active {
                self.active = true;
                self.worst = value;
                notices.push(Notice::Warning(format!(
                    "{} acts from t = {t:.4} s ({value:.3})",
                    what()
                )));
            }
            self.worst = self.worst.max(value);
            self.last = t;
        } else if self.active && t - self.last >= RELEASE {
            self.active = false;
            notices.push(Notice::Event(format!(
                "{} released at t = {t:.4} s (acted until t = {:.4} s; worst {:.3})",
                what(),
                self.last,
                self.worst
            )));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forming_saturation_keeps_the_direction_and_the_budget() {
        let u = dvpp_math::cpolar(1.0, 0.3);
        let i = Complex::new(1.5, -0.9) * u;
        let l = saturate_forming(i, u, 1.0, 1.2, (-5.0, 5.0));
        assert!(l.current_limit && !l.dc_limit);
        assert!((dvpp_math::cabs(l.current) - 1.2).abs() < 1e-12);
        assert!((dvpp_math::carg(l.current) - dvpp_math::carg(i)).abs() < 1e-12);
        // Below the limit nothing changes.
        let small = Complex::new(0.5, 0.2) * u;
        let l = saturate_forming(small, u, 1.0, 1.2, (-5.0, 5.0));
        assert_eq!(l.current, small);
        assert!(!l.current_limit && !l.dc_limit);
        // An empty link: no active current beyond what the source gives.
        let l = saturate_forming(Complex::new(0.8, 0.0) * u, u, 0.9, 1.2, (-1.0, 0.09));
        assert!(l.dc_limit);
        assert!(((l.current * u.conj()).re * 0.9 - 0.09).abs() < 1e-12);
    }

    #[test]
    fn a_limited_forming_request_turns_to_reactive_current() {
        // In a dip the voltage across the internal node is in phase with the bus: the request
        // at twice I_max turns fully to the virtual impedance's lagging current, its magnitude
        // kept.
        let u = dvpp_math::cpolar(0.5, 0.2);
        let ev = u * 1.2;
        let wanted = Complex::new(2.0, -0.6) * (u / 0.5);
        let turned = turn_reactive(wanted, 2.0, ev);
        assert!((dvpp_math::cabs(turned) - dvpp_math::cabs(wanted)).abs() < 1e-12);
        let local = turned * (u / 0.5).conj();
        let lag = -dvpp_math::atan2(local.im, local.re);
        assert!((lag - dvpp_math::atan(LIMIT_X_R)).abs() < 1e-12, "{lag}");
        // At the limit's edge nothing turns; halfway through the band halfway.
        assert_eq!(turn_reactive(wanted, 1.0, ev), wanted);
        assert_eq!(turn_reactive(wanted, 0.7, ev), wanted);
        let half = turn_reactive(wanted, 1.0 + LIMIT_BAND / 2.0, ev);
        let a = |x: Complex<f64>| dvpp_math::carg(x * (u / 0.5).conj());
        assert!(a(half) < a(wanted) && a(half) > a(turned), "{}", a(half));
    }

    #[test]
    fn following_priority_decides_which_current_stays() {
        let (p, lim, _) = saturate_following((1.0, 1.0), 1.0, 1.2, (-9.0, 9.0), Priority::Active);
        assert!(lim);
        assert_eq!(p.0, 1.0);
        assert!((dvpp_math::hypot(p.0, p.1) - 1.2).abs() < 1e-12);
        let (q, _, _) = saturate_following((1.0, 1.0), 1.0, 1.2, (-9.0, 9.0), Priority::Reactive);
        assert_eq!(q.1, 1.0);
        assert!((dvpp_math::hypot(q.0, q.1) - 1.2).abs() < 1e-12);
    }
}
