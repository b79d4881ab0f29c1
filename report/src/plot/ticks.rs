//! Axis ticks: "nice" linear and logarithmic ticks and their labels.

use super::pixels::Axis;
use super::text::tick_width;

pub(super) struct Ticks {
    /// Labelled (major) ticks with grid lines.
    pub(super) major: Vec<(f64, String)>,
    /// Unlabelled minor grid lines (log axes).
    pub(super) minor: Vec<f64>,
    /// Printed once beside the axis: the labels show `value - offset`.
    pub(super) offset: Option<String>,
}

/// "Nice" linear ticks (1/2/5 × 10^k) inside [lo, hi]: as close to `target` ticks as possible,
/// never more than `max_count` (when avoidable), with labels formatted for the step.
///
/// When the labels would need more than 6 significant digits (a small change on a large value),
/// they show the difference to a round `offset`, printed once beside the axis (`+1e6`).
pub(super) fn linear_ticks(lo: f64, hi: f64, target: usize, max_count: usize) -> Ticks {
    let values = nice_values(lo, hi, target, max_count);
    let (offset, labels) = match tick_offset(&values) {
        Some((offset, text)) => {
            let deltas: Vec<f64> = values.iter().map(|v| v - offset).collect();
            (Some(text), format_ticks(&deltas))
        }
        None => (None, format_ticks(&values)),
    };
    Ticks {
        major: values.into_iter().zip(labels).collect(),
        minor: Vec::new(),
        offset,
    }
}

/// A round offset (and its label) for ticks whose labels would otherwise be too long.
fn tick_offset(values: &[f64]) -> Option<(f64, String)> {
    if values.len() < 2 {
        return None;
    }
    let (lo, hi) = (values[0], values[values.len() - 1]);
    let span = hi - lo;
    let max_abs = lo.abs().max(hi.abs());
    let step = values[1] - values[0];
    if !(span > 0.0 && step > 0.0 && max_abs.is_finite()) {
        return None;
    }
    let digits = dvpp_math::log10(max_abs).floor() - (dvpp_math::log10(step) + 1e-9).floor() + 1.0;
    if digits <= 6.0 {
        return None;
    }
    let g_exp = (dvpp_math::log10(span) + 1e-9).floor() as i32 + 1;
    let g = pow10(g_exp);
    let offset = (0.5 * (lo + hi) / g).round() * g;
    if offset == 0.0 || !offset.is_finite() {
        return None;
    }
    let text = if offset.abs() >= 1e5 || offset.abs() < 1e-2 {
        format_sci(offset, g_exp)
    } else {
        let decimals = (-g_exp).clamp(0, 12) as usize;
        let t = format!("{offset:.decimals$}");
        if t.contains('.') {
            t.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            t
        }
    };
    let sign = if offset > 0.0 { "+" } else { "" };
    Some((offset, format!("{sign}{text}")))
}

fn nice_values(lo: f64, hi: f64, target: usize, max_count: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return if lo.is_finite() { vec![lo] } else { Vec::new() };
    }
    let span = hi - lo;
    let target = target.max(2);
    let max_count = max_count.max(2);
    let k0 = dvpp_math::log10(span / target as f64).floor() as i32;
    // (score, step): prefer counts close to the target, within max_count, and at least 2.
    let mut best: Option<(f64, f64)> = None;
    for k in (k0 - 1)..=(k0 + 2) {
        for m in [1.0, 2.0, 5.0] {
            let step = m * dvpp_math::powi(10f64, k);
            if !(step.is_finite() && step > 0.0) {
                continue;
            }
            let first = (lo / step - 1e-9).ceil();
            let last = (hi / step + 1e-9).floor();
            let count = last - first + 1.0;
            if !(count.is_finite() && count <= 1000.0) {
                continue;
            }
            let count = count.max(0.0);
            let mut score = (count - target as f64).abs();
            if count > max_count as f64 {
                score += 1000.0 + count;
            }
            if count < 2.0 {
                score += 500.0;
            }
            if best.is_none() || best.is_some_and(|(b, _)| score < b) {
                best = Some((score, step));
            }
        }
    }
    let Some((_, step)) = best else {
        return vec![lo, hi];
    };
    let first = (lo / step - 1e-9).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    (first..=last)
        .map(|i| {
            let v = i as f64 * step;
            if v.abs() < step * 1e-9 {
                0.0
            } else {
                v
            }
        })
        .collect()
}

/// Labels for evenly spaced tick values: fixed decimals matching the step, or compact scientific
/// form (`2e-4`, `1.5e6`) for very small or very large magnitudes.
fn format_ticks(values: &[f64]) -> Vec<String> {
    let step = values
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(f64::INFINITY, f64::min);
    let max_abs = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let step = if step.is_finite() && step > 0.0 {
        step
    } else if max_abs > 0.0 {
        max_abs
    } else {
        1.0
    };
    let step_exp = (dvpp_math::log10(step) + 1e-9).floor() as i32;
    let sci = max_abs >= 1e5 || (max_abs > 0.0 && max_abs < 1e-2);
    values
        .iter()
        .map(|&v| {
            if sci {
                format_sci(v, step_exp)
            } else {
                let decimals = (-step_exp).clamp(0, 12) as usize;
                clean_zero(format!("{v:.decimals$}"))
            }
        })
        .collect()
}

/// `v` as `m e k` with as many mantissa digits as a step of 10^`step_exp` needs, trailing zeros
/// trimmed: 0.0002 → `2e-4`, 1500000 → `1.5e6`.
fn format_sci(v: f64, step_exp: i32) -> String {
    if v == 0.0 || !v.is_finite() {
        return "0".into();
    }
    let mut e = dvpp_math::log10(v.abs()).floor() as i32;
    let decimals = (e - step_exp).clamp(0, 12) as usize;
    let mut m = v / dvpp_math::powi(10f64, e);
    // Rounding may carry into the next decade (9.99 → 10.0).
    if format!("{:.decimals$}", m.abs()).starts_with("10") {
        e += 1;
        m = v / dvpp_math::powi(10f64, e);
    }
    let mut ms = format!("{m:.decimals$}");
    if ms.contains('.') {
        ms = ms.trim_end_matches('0').trim_end_matches('.').to_string();
    }
    format!("{ms}e{e}")
}

fn clean_zero(s: String) -> String {
    if s.starts_with('-') && s[1..].chars().all(|ch| ch == '0' || ch == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// Ticks for the x axis, thinned until neighbouring labels keep a gap.
pub(super) fn x_ticks(xa: &Axis, plot_w: f64) -> Ticks {
    let fits = |t: &Ticks| {
        t.major.windows(2).all(|w| {
            let gap = (xa.frac(w[1].0) - xa.frac(w[0].0)).abs() * plot_w;
            let need = 0.5 * (tick_width(&w[0].1) + tick_width(&w[1].1));
            gap >= need + 10.0
        })
    };
    let max = ((plot_w / 50.0).floor() as usize).clamp(2, 9);
    let mut target = max.min(7);
    loop {
        let t = if xa.log {
            log_ticks(xa.lo, xa.hi, target)
        } else {
            linear_ticks(xa.lo, xa.hi, target, target + 1)
        };
        if target <= 2 || fits(&t) {
            return t;
        }
        target -= 1;
    }
}

/// Log-axis ticks: labelled decades (every n-th when there are many), minor grid at 2..9 × 10^k.
/// Spans of less than three decades label 1/2/5 (or 1/5, or all) multiples; spans too narrow
/// for two such ticks fall back to linear ticks.
fn log_ticks(lo: f64, hi: f64, max_count: usize) -> Ticks {
    if !(lo > 0.0 && hi > lo && hi.is_finite()) {
        return Ticks {
            major: Vec::new(),
            minor: Vec::new(),
            offset: None,
        };
    }
    let max_count = max_count.max(2);
    let (llo, lhi) = (dvpp_math::log10(lo), dvpp_math::log10(hi));
    let inside = |v: f64| {
        let l = dvpp_math::log10(v);
        l >= llo - 1e-9 && l <= lhi + 1e-9
    };
    let (k_lo, k_hi) = (llo.floor() as i32, lhi.ceil() as i32);
    let with = |mantissas: &[i32]| -> Vec<(i32, i32)> {
        let mut out = Vec::new();
        for k in k_lo..=k_hi {
            for &m in mantissas {
                if inside(m as f64 * pow10(k)) {
                    out.push((m, k));
                }
            }
        }
        out
    };
    let decades = with(&[1]);
    let major: Vec<(i32, i32)> = if decades.len() >= 3 {
        let every = decades.len().div_ceil(max_count).max(1);
        let start = decades
            .iter()
            .position(|&(_, k)| k.rem_euclid(every as i32) == 0)
            .unwrap_or(0);
        decades[start..].iter().copied().step_by(every).collect()
    } else {
        let candidates = [
            with(&[1, 2, 5]),
            with(&[1, 5]),
            with(&[1, 2, 3, 4, 5, 6, 7, 8, 9]),
            decades,
        ];
        let pick = candidates
            .iter()
            .find(|c| (3..=max_count).contains(&c.len()))
            .or_else(|| candidates.iter().find(|c| c.len() == 2));
        match pick {
            Some(c) => c.clone(),
            None => {
                // Less than about a factor of two wide: linear ticks read better.
                let target = max_count.min(5);
                return linear_ticks(lo, hi, target, target);
            }
        }
    };
    let mut minor = Vec::new();
    if k_hi - k_lo <= 8 && (major.len() >= 2 && major.windows(2).all(|w| w[1].1 - w[0].1 <= 1)) {
        for (m, k) in with(&[1, 2, 3, 4, 5, 6, 7, 8, 9]) {
            if !major.contains(&(m, k)) {
                minor.push(m as f64 * pow10(k));
            }
        }
    }
    let plain = major.iter().all(|&(_, k)| (-2..=3).contains(&k));
    Ticks {
        major: major
            .into_iter()
            .map(|(m, k)| (m as f64 * pow10(k), format_log(m, k, plain)))
            .collect(),
        minor,
        offset: None,
    }
}

fn pow10(k: i32) -> f64 {
    dvpp_math::powi(10f64, k)
}

/// `m × 10^k` for a log axis: plain (`0.01` … `1000`) when the whole axis is `plain`, otherwise
/// plain only for 0.01 … 100 and `1e-3` / `2e4` style beyond.
fn format_log(m: i32, k: i32, plain: bool) -> String {
    if (-2..=2).contains(&k) || (plain && k == 3) {
        let decimals = (-k).max(0) as usize;
        format!("{:.decimals$}", m as f64 * pow10(k))
    } else {
        format!("{m}e{k}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn values(t: &Ticks) -> Vec<f64> {
        t.major.iter().map(|(v, _)| *v).collect()
    }
    fn labels(t: &Ticks) -> Vec<&str> {
        t.major.iter().map(|(_, l)| l.as_str()).collect()
    }
    fn close(a: &[f64], b: &[f64]) -> bool {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| (x - y).abs() <= 1e-9 * (1.0 + y.abs()))
    }

    #[test]
    fn ticks_unit_range() {
        let t = linear_ticks(0.0, 1.0, 6, 8);
        assert!(close(&values(&t), &[0.0, 0.2, 0.4, 0.6, 0.8, 1.0]));
        assert_eq!(labels(&t), ["0.0", "0.2", "0.4", "0.6", "0.8", "1.0"]);
    }

    #[test]
    fn ticks_grid_frequency() {
        let t = linear_ticks(49.8, 50.05, 6, 8);
        assert!(
            close(&values(&t), &[49.8, 49.85, 49.9, 49.95, 50.0, 50.05]),
            "{:?}",
            values(&t)
        );
        assert_eq!(
            labels(&t),
            ["49.80", "49.85", "49.90", "49.95", "50.00", "50.05"]
        );
    }

    #[test]
    fn ticks_count_and_niceness() {
        for &(lo, hi) in &[
            (0.0, 1.0),
            (-3.7, 12.2),
            (0.0, 0.3),
            (1e-7, 9e-6),
            (-1.0, 1.0),
            (1234.0, 98765.0),
            (0.0, 1.7e6),
            (49.999, 50.001),
        ] {
            let v = nice_values(lo, hi, 6, 8);
            assert!((4..=8).contains(&v.len()), "{lo}..{hi}: {v:?}");
            assert!(v.iter().all(|&x| x >= lo - 1e-12 && x <= hi + 1e-12));
            let step = v[1] - v[0];
            let m = step / dvpp_math::pow(10f64, dvpp_math::log10(step).floor());
            assert!(
                [1.0, 2.0, 5.0, 10.0].iter().any(|n| (m - n).abs() < 1e-6),
                "{step}"
            );
        }
    }

    #[test]
    fn tick_labels_compact() {
        let l = format_ticks(&nice_values(0.0, 0.3, 6, 8));
        assert_eq!(l, ["0.00", "0.05", "0.10", "0.15", "0.20", "0.25", "0.30"]);
        let l = format_ticks(&[0.1, 0.2, 0.30000000000000004, 0.4]);
        assert_eq!(l, ["0.1", "0.2", "0.3", "0.4"]);
        let l = format_ticks(&[-1.0, -0.5, -0.0, 0.5]);
        assert_eq!(l, ["-1.0", "-0.5", "0.0", "0.5"]);
        assert_eq!(format_ticks(&[0.0, 20.0, 40.0]), ["0", "20", "40"]);
        // Very small and very large magnitudes go scientific.
        let l = format_ticks(&nice_values(0.0, 0.001, 6, 8));
        assert_eq!(l, ["0", "2e-4", "4e-4", "6e-4", "8e-4", "1e-3"]);
        let l = format_ticks(&[0.0, 5e5, 1e6, 1.5e6]);
        assert_eq!(l, ["0", "5e5", "1e6", "1.5e6"]);
        let l = format_ticks(&[1.0e-3, 1.2e-3, 1.4e-3]);
        assert_eq!(l, ["1e-3", "1.2e-3", "1.4e-3"]);
        assert_eq!(format_sci(9.9999e-4, -4), "1e-3");
    }

    #[test]
    fn ticks_log_decades() {
        let t = log_ticks(1e-3, 1e2, 8);
        assert!(close(&values(&t), &[1e-3, 1e-2, 1e-1, 1.0, 10.0, 100.0]));
        assert_eq!(labels(&t), ["1e-3", "0.01", "0.1", "1", "10", "100"]);
        assert_eq!(t.minor.len(), 5 * 8);
        // Slightly inexact end points (logspace) still get their decade.
        let t = log_ticks(0.000999999999, 1000.0000001, 8);
        assert_eq!(t.major.len(), 7);
        // Many decades are thinned.
        let t = log_ticks(1e-9, 1e9, 6);
        assert!(t.major.len() <= 6 && t.major.len() >= 3, "{:?}", labels(&t));
        // Less than two decades: 1/2/5.
        let t = log_ticks(0.5, 30.0, 8);
        assert_eq!(labels(&t), ["0.5", "1", "2", "5", "10", "20"]);
        // Narrow: linear fallback.
        let t = log_ticks(2.1, 2.9, 6);
        assert!(t.major.len() >= 2);
    }

    #[test]
    fn small_change_on_large_value_uses_offset() {
        let t = linear_ticks(1e6 - 0.003, 1e6 + 0.007, 6, 8);
        assert_eq!(t.offset.as_deref(), Some("+1e6"));
        assert_eq!(labels(&t), ["-2e-3", "0", "2e-3", "4e-3", "6e-3"]);
        let t = linear_ticks(49.9999998, 50.0000003, 6, 8);
        assert_eq!(t.offset.as_deref(), Some("+50"));
        assert!(
            t.major.iter().all(|(_, l)| l.len() <= 6),
            "{:?}",
            labels(&t)
        );
        // Ordinary ranges have none.
        assert!(linear_ticks(49.8, 50.05, 6, 8).offset.is_none());
        assert!(linear_ticks(0.0, 2e6, 6, 8).offset.is_none());
    }
}
