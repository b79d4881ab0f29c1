//! Data to pixels: a panel's axes from its data, and each series as decimated pixel polylines.

use super::{Panel, Series, FAR};

/// A panel's plot area in pixels: its corner `x`, `y` and its size `w`, `h`.
pub(super) struct Rect {
    pub(super) x: f64,
    pub(super) y: f64,
    pub(super) w: f64,
    pub(super) h: f64,
}

#[derive(Clone, Copy)]
pub(super) struct Axis {
    pub(super) lo: f64,
    pub(super) hi: f64,
    pub(super) log: bool,
}

impl Axis {
    /// Position of `v` as a fraction of the axis (0 = lo, 1 = hi).
    pub(super) fn frac(&self, v: f64) -> f64 {
        if self.log {
            let (a, b) = (dvpp_math::log10(self.lo), dvpp_math::log10(self.hi));
            (dvpp_math::log10(v) - a) / (b - a)
        } else {
            (v - self.lo) / (self.hi - self.lo)
        }
    }
}

/// The x and y axes of a panel from its data (or the fixed y range).
pub(super) fn data_axes(p: &Panel) -> (Axis, Axis) {
    let usable = |x: f64, y: f64| x.is_finite() && y.is_finite() && (!p.log_x || x > 0.0);
    let mut xs = (f64::INFINITY, f64::NEG_INFINITY);
    let mut ys = (f64::INFINITY, f64::NEG_INFINITY);
    for se in &p.series {
        for (&x, &y) in se.x.iter().zip(&se.y) {
            if usable(x, y) {
                xs = (xs.0.min(x), xs.1.max(x));
                ys = (ys.0.min(y), ys.1.max(y));
            }
        }
    }
    let xa = if p.log_x {
        let (lo, hi) = if xs.0 <= xs.1 {
            (xs.0.clamp(1e-300, 1e300), xs.1.clamp(1e-300, 1e300))
        } else {
            (1.0, 10.0)
        };
        let (lo, hi) = if hi / lo < 1.0 + 1e-9 {
            (lo / 10.0, hi * 10.0)
        } else {
            (lo, hi)
        };
        Axis { lo, hi, log: true }
    } else {
        let (lo, hi) = padded_range(xs, 0.0);
        Axis { lo, hi, log: false }
    };
    let fixed = p
        .y_range
        .filter(|&(lo, hi)| lo.is_finite() && hi.is_finite() && lo != hi)
        .map(|(lo, hi)| (lo.min(hi), lo.max(hi)));
    let (lo, hi) = match fixed {
        Some((lo, hi)) => padded_range((lo, hi), 0.0),
        None => padded_range(ys, 0.05),
    };
    (xa, Axis { lo, hi, log: false })
}

/// A usable linear range from (min, max) of the data with `margin` (fraction of the span) added
/// on both sides. Empty data gives 0..1; a constant gives a symmetric range around it.
fn padded_range((lo, hi): (f64, f64), margin: f64) -> (f64, f64) {
    if lo.is_nan() || hi.is_nan() || lo > hi {
        return (0.0, 1.0);
    }
    let (lo, hi) = (lo.clamp(-1e300, 1e300), hi.clamp(-1e300, 1e300));
    let mid = 0.5 * (lo + hi);
    let span = hi - lo;
    // Too small to resolve (a constant, or a difference at the edge of f64 precision).
    if span <= mid.abs() * 1e-12 || span < 1e-290 {
        let d = if mid.abs() > 1e-290 {
            mid.abs() * 0.1
        } else {
            1.0
        };
        return (mid - d, mid + d);
    }
    (lo - margin * span, hi + margin * span)
}

/// Pixel polylines of one series: broken at non-finite values (and x <= 0 on a log axis),
/// decimated to first/min/max/last per pixel column.
pub(super) fn series_pixels(se: &Series, xa: &Axis, ya: &Axis, r: &Rect) -> Vec<Vec<(f64, f64)>> {
    let mut segs = Vec::new();
    let mut dec = Decimator::default();
    for (&x, &y) in se.x.iter().zip(&se.y) {
        if !(x.is_finite() && y.is_finite()) || (xa.log && x <= 0.0) {
            dec.finish_into(&mut segs);
            continue;
        }
        let px = (r.x + xa.frac(x) * r.w).clamp(r.x - FAR, r.x + r.w + FAR);
        let py = (r.y + r.h - ya.frac(y) * r.h).clamp(r.y - FAR, r.y + r.h + FAR);
        if px.is_finite() && py.is_finite() {
            dec.push(px, py);
        } else {
            dec.finish_into(&mut segs);
        }
    }
    dec.finish_into(&mut segs);
    segs
}

/// Run-length decimation of consecutive points falling into the same pixel column: keeps the
/// first, the lowest, the highest and the last of each run, in their original order. Works for
/// non-monotonic x too (it only merges consecutive points).
#[derive(Default)]
struct Decimator {
    out: Vec<(f64, f64)>,
    run: Vec<(f64, f64)>,
    column: f64,
}

impl Decimator {
    fn push(&mut self, x: f64, y: f64) {
        let col = x.floor();
        if !self.run.is_empty() && col != self.column {
            self.flush_run();
        }
        self.column = col;
        self.run.push((x, y));
    }

    fn flush_run(&mut self) {
        let run = &self.run;
        if run.len() <= 4 {
            self.out.extend_from_slice(run);
        } else {
            let (mut lo, mut hi) = (0, 0);
            for (i, p) in run.iter().enumerate() {
                if p.1 < run[lo].1 {
                    lo = i;
                }
                if p.1 > run[hi].1 {
                    hi = i;
                }
            }
            let mut keep = [0, lo, hi, run.len() - 1];
            keep.sort_unstable();
            let mut last = usize::MAX;
            for i in keep {
                if i != last {
                    self.out.push(run[i]);
                    last = i;
                }
            }
        }
        self.run.clear();
    }

    fn finish_into(&mut self, segs: &mut Vec<Vec<(f64, f64)>>) {
        if !self.run.is_empty() {
            self.flush_run();
        }
        if !self.out.is_empty() {
            segs.push(std::mem::take(&mut self.out));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plot::tests::{assert_clean_numbers, assert_well_formed};
    use crate::plot::{Figure, Style};

    #[test]
    fn decimation_keeps_extremes() {
        let n = 200_000;
        let x: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let mut y: Vec<f64> = (0..n).map(|i| ((i * 7919) % 1000) as f64 * 1e-3).collect();
        y[123_457] = 50.0;
        y[77_777] = -20.0;
        let se = Series {
            label: "noisy".into(),
            x: x.clone(),
            y,
            style: Style::Solid,
        };
        let xa = Axis {
            lo: 0.0,
            hi: n as f64,
            log: false,
        };
        let ya = Axis {
            lo: -20.0,
            hi: 50.0,
            log: false,
        };
        let r = Rect {
            x: 0.0,
            y: 0.0,
            w: 400.0,
            h: 200.0,
        };
        let segs = series_pixels(&se, &xa, &ya, &r);
        assert_eq!(segs.len(), 1);
        assert!(segs[0].len() <= 4 * 401, "{}", segs[0].len());
        let top = segs[0].iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
        let bottom = segs[0]
            .iter()
            .map(|p| p.1)
            .fold(f64::NEG_INFINITY, f64::max);
        assert!(top.abs() < 1e-9, "peak lost: {top}");
        assert!((bottom - 200.0).abs() < 1e-9, "dip lost: {bottom}");

        // And through the whole figure: the peak drives the auto range, the size stays small.
        let panel = Panel::new("big", "t", "y").series("noisy", &x, &se.y, Style::Solid);
        let svg = Figure::new("").panel(panel).to_svg();
        assert!(svg.len() < 150_000, "{} bytes", svg.len());
        assert_well_formed(&svg);
    }

    #[test]
    fn nan_and_inf_break_the_line() {
        let x = [0.0, 1.0, 2.0, 3.0, 4.0, f64::NAN, 6.0, 7.0, 8.0];
        let y = [0.0, 1.0, f64::NAN, 3.0, 4.0, 5.0, f64::INFINITY, 7.0, 8.0];
        let p = Panel::new("p", "x", "y").series("s", &x, &y, Style::Solid);
        let (xa, ya) = data_axes(&p);
        assert!(xa.lo == 0.0 && xa.hi == 8.0);
        assert!(ya.lo < 0.0 && ya.hi > 8.0 && ya.hi < 9.0);
        let r = Rect {
            x: 0.0,
            y: 0.0,
            w: 100.0,
            h: 100.0,
        };
        let segs = series_pixels(&p.series[0], &xa, &ya, &r);
        let lens: Vec<usize> = segs.iter().map(Vec::len).collect();
        assert_eq!(lens, [2, 2, 2]);
        let svg = Figure::new("Broken lines").panel(p).to_svg();
        assert_well_formed(&svg);
        assert_clean_numbers(&svg);
        assert_eq!(svg.matches("<polyline").count(), 3);
    }

    #[test]
    fn constant_series_gets_symmetric_range() {
        let p = Panel::new("c", "x", "y").series("c", &[0.0, 1.0], &[50.0, 50.0], Style::Solid);
        let (_, ya) = data_axes(&p);
        assert!((ya.lo - 45.0).abs() < 1e-9 && (ya.hi - 55.0).abs() < 1e-9);
        let p = Panel::new("c", "x", "y").series("c", &[0.0, 1.0], &[0.0, 0.0], Style::Solid);
        let (_, ya) = data_axes(&p);
        assert_eq!((ya.lo, ya.hi), (-1.0, 1.0));
        let p = Panel::new("c", "x", "y").series("c", &[3.0], &[-2.0], Style::Solid);
        let (xa, ya) = data_axes(&p);
        assert!(xa.lo < 3.0 && xa.hi > 3.0 && (xa.lo + xa.hi - 6.0).abs() < 1e-12);
        assert!((ya.lo + ya.hi + 4.0).abs() < 1e-12);
    }
}
