//! A panel drawn into the figure: its layout, axes, grid, ticks, lines and legend.

use std::fmt::Write as _;

use super::pixels::{data_axes, series_pixels, Axis, Rect};
use super::text::{c, esc, minus, text_width, tick_width};
use super::ticks::{linear_ticks, x_ticks, Ticks};
use super::{
    Panel, Style, AXIS, GRID, LABEL_FONT, LEGEND_FONT, LINE_WIDTH, MINOR_GRID, PALETTE, TEXT,
    TICK_FONT, TITLE_FONT,
};

/// The vertical layout, axes and y ticks of a panel: everything its left margin depends on.
pub(super) struct Layout {
    xa: Axis,
    ya: Axis,
    yt: Ticks,
    top: f64,
    plot_h: f64,
    /// Widest y tick label.
    y_tick_w: f64,
    /// Left margin this panel needs (y label, tick labels, tick marks).
    pub(super) left: f64,
}

pub(super) fn layout(p: &Panel, ph: f64) -> Layout {
    let has_title = !p.title.trim().is_empty();
    let has_xl = !p.x_label.trim().is_empty();
    let has_yl = !p.y_label.trim().is_empty();
    let top = if has_title { 30.0 } else { 12.0 };
    let bottom = 4.0 + 4.0 + TICK_FONT + if has_xl { 8.0 + LABEL_FONT + 8.0 } else { 8.0 };
    let plot_h = (ph - top - bottom).max(20.0);
    let (xa, ya) = data_axes(p);
    let max_y_ticks = ((plot_h / 26.0).floor() as usize).clamp(2, 9);
    let yt = linear_ticks(ya.lo, ya.hi, max_y_ticks.min(7), max_y_ticks);
    let y_tick_w = yt
        .major
        .iter()
        .map(|(_, l)| tick_width(l))
        .fold(0.0, f64::max);
    let left = 10.0 + if has_yl { LABEL_FONT + 8.0 } else { 0.0 } + y_tick_w + 4.0 + 5.0;
    Layout {
        xa,
        ya,
        yt,
        top,
        plot_h,
        y_tick_w,
        left,
    }
}

/// Renders panel `p` into the cell at (ox, oy) of size pw × ph; `left` is the left margin
/// (the widest one of the figure column, so that plot areas line up).
#[allow(clippy::too_many_arguments)]
pub(super) fn render_panel(
    s: &mut String,
    p: &Panel,
    lay: Layout,
    left: f64,
    clip_id: &str,
    ox: f64,
    oy: f64,
    pw: f64,
) {
    let has_title = !p.title.trim().is_empty();
    let has_xl = !p.x_label.trim().is_empty();
    let has_yl = !p.y_label.trim().is_empty();
    let Layout {
        xa,
        ya,
        yt,
        top,
        plot_h,
        y_tick_w,
        ..
    } = lay;
    let right = 16.0;
    let plot_w = (pw - left - right).max(20.0);
    let r = Rect {
        x: ox + left,
        y: oy + top,
        w: plot_w,
        h: plot_h,
    };

    let xt = x_ticks(&xa, plot_w);

    let px = |v: f64| r.x + xa.frac(v) * r.w;
    let py = |v: f64| r.y + r.h - ya.frac(v) * r.h;

    let _ = writeln!(s, "<g>");
    // Plot-area clip.
    let _ = writeln!(
        s,
        "<defs><clipPath id=\"{clip_id}\"><rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\"/></clipPath></defs>",
        c(r.x),
        c(r.y),
        c(r.w),
        c(r.h)
    );

    // Grid.
    let mut grid = String::new();
    for &v in &xt.minor {
        let x = px(v);
        let _ = write!(grid, "M{} {}V{}", c(x), c(r.y), c(r.y + r.h));
    }
    if !grid.is_empty() {
        let _ = writeln!(
            s,
            "<path d=\"{grid}\" stroke=\"{MINOR_GRID}\" stroke-width=\"0.8\" fill=\"none\"/>"
        );
    }
    grid.clear();
    for (v, _) in &xt.major {
        let x = px(*v);
        let _ = write!(grid, "M{} {}V{}", c(x), c(r.y), c(r.y + r.h));
    }
    for (v, _) in &yt.major {
        let y = py(*v);
        let _ = write!(grid, "M{} {}H{}", c(r.x), c(y), c(r.x + r.w));
    }
    if !grid.is_empty() {
        let _ = writeln!(
            s,
            "<path d=\"{grid}\" stroke=\"{GRID}\" stroke-width=\"0.8\" fill=\"none\"/>"
        );
    }

    // Series.
    let mut lines: Vec<Vec<Vec<(f64, f64)>>> = Vec::with_capacity(p.series.len());
    for se in &p.series {
        lines.push(series_pixels(se, &xa, &ya, &r));
    }
    let _ = writeln!(s, "<g clip-path=\"url(#{clip_id})\" fill=\"none\">");
    for (k, (se, segs)) in p.series.iter().zip(&lines).enumerate() {
        let color = PALETTE[k % PALETTE.len()];
        for seg in segs {
            if seg.len() == 1 {
                let _ = writeln!(
                    s,
                    "<circle cx=\"{}\" cy=\"{}\" r=\"2.5\" fill=\"{color}\"/>",
                    c(seg[0].0),
                    c(seg[0].1)
                );
                continue;
            }
            let _ = write!(
                s,
                "<polyline stroke=\"{color}\" stroke-width=\"{LINE_WIDTH}\" stroke-linejoin=\"round\"{} points=\"",
                dash_attrs(se.style)
            );
            for (i, &(x, y)) in seg.iter().enumerate() {
                if i > 0 {
                    s.push(' ');
                }
                let _ = write!(s, "{},{}", c(x), c(y));
            }
            s.push_str("\"/>\n");
        }
    }
    s.push_str("</g>\n");

    // Frame and ticks.
    let _ = writeln!(
        s,
        "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"{AXIS}\" stroke-width=\"1\"/>",
        c(r.x),
        c(r.y),
        c(r.w),
        c(r.h)
    );
    let mut marks = String::new();
    for (v, _) in &xt.major {
        let _ = write!(marks, "M{} {}v4", c(px(*v)), c(r.y + r.h));
    }
    for (v, _) in &yt.major {
        let _ = write!(marks, "M{} {}h-4", c(r.x), c(py(*v)));
    }
    if !marks.is_empty() {
        let _ = writeln!(
            s,
            "<path d=\"{marks}\" stroke=\"{AXIS}\" stroke-width=\"1\" fill=\"none\"/>"
        );
    }
    let _ = writeln!(s, "<g font-size=\"{TICK_FONT}\" fill=\"{TEXT}\">");
    let label_y = r.y + r.h + 4.0 + 3.0 + TICK_FONT * 0.8;
    for (v, l) in &xt.major {
        // Keep edge labels inside the panel cell.
        let w = tick_width(l);
        let x = px(*v).clamp(ox + w / 2.0 + 2.0, ox + pw - w / 2.0 - 2.0);
        let _ = writeln!(
            s,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>",
            c(x),
            c(label_y),
            esc(&minus(l))
        );
    }
    for (v, l) in &yt.major {
        let _ = writeln!(
            s,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"end\">{}</text>",
            c(r.x - 4.0 - 3.0),
            c(py(*v) + TICK_FONT * 0.35),
            esc(&minus(l))
        );
    }
    if let Some(off) = &yt.offset {
        let _ = writeln!(
            s,
            "<text x=\"{}\" y=\"{}\">{}</text>",
            c(r.x),
            c(r.y - 5.0),
            esc(&minus(off))
        );
    }
    if let Some(off) = &xt.offset {
        let _ = writeln!(
            s,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"end\">{}</text>",
            c(r.x + r.w),
            c(label_y + 8.0 + LABEL_FONT),
            esc(&minus(off))
        );
    }
    s.push_str("</g>\n");

    // Labels and title.
    if has_xl {
        let _ = writeln!(
            s,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\" font-size=\"{LABEL_FONT}\" fill=\"{TEXT}\">{}</text>",
            c(r.x + r.w / 2.0),
            c(label_y + 8.0 + LABEL_FONT),
            esc(&truncate_to(&p.x_label, r.w, LABEL_FONT))
        );
    }
    if has_yl {
        // Right next to the tick labels.
        let x = r.x - 4.0 - 5.0 - y_tick_w - 8.0 - LABEL_FONT * 0.25;
        let y = r.y + r.h / 2.0;
        let _ = writeln!(
            s,
            "<text transform=\"translate({},{}) rotate(-90)\" text-anchor=\"middle\" font-size=\"{LABEL_FONT}\" fill=\"{TEXT}\">{}</text>",
            c(x),
            c(y),
            esc(&truncate_to(&p.y_label, r.h + 20.0, LABEL_FONT))
        );
    }
    if has_title {
        // Centred over the plot area, and kept inside the panel cell.
        let centre = r.x + r.w / 2.0;
        let room = 2.0 * (centre - ox).min(ox + pw - centre) - 8.0;
        let _ = writeln!(
            s,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\" font-size=\"{TITLE_FONT}\" fill=\"{TEXT}\">{}</text>",
            c(centre),
            c(r.y - 9.0),
            esc(&truncate_to(&p.title, room, TITLE_FONT))
        );
    }

    render_legend(s, p, &lines, &r);
    s.push_str("</g>\n");
}

fn dash_attrs(style: Style) -> &'static str {
    match style {
        Style::Solid => "",
        Style::Dashed => " stroke-dasharray=\"7 4\"",
        Style::Dotted => " stroke-dasharray=\"0.1 3.2\" stroke-linecap=\"round\"",
    }
}

fn render_legend(s: &mut String, p: &Panel, lines: &[Vec<Vec<(f64, f64)>>], r: &Rect) {
    let mut entries: Vec<(Option<usize>, String, Style)> = p
        .series
        .iter()
        .enumerate()
        .filter(|(_, se)| !se.label.trim().is_empty())
        .map(|(k, se)| (Some(k), se.label.clone(), se.style))
        .collect();
    if entries.is_empty() {
        return;
    }
    let row_h = LEGEND_FONT + 5.0;
    let pad = 6.0;
    let sample_w = 24.0;
    let col_gap = 12.0;
    let inset = 8.0;
    // Fit the legend into the plot area: more columns when too tall, shortened labels when too
    // wide, and a "+N more" entry as a last resort.
    let avail_w = r.w - 2.0 * inset;
    let avail_h = r.h - 2.0 * inset;
    let max_rows = (((avail_h - 2.0 * pad + 4.0) / row_h).floor() as usize).max(1);
    let min_col_w = sample_w + 6.0 + 60.0;
    let max_cols =
        (((avail_w - 2.0 * pad + col_gap) / (min_col_w + col_gap)).floor() as usize).max(1);
    let mut ncols = entries.len().div_ceil(max_rows);
    if ncols > max_cols {
        ncols = max_cols;
        let shown = (ncols * max_rows).saturating_sub(1);
        let hidden = entries.len() - shown;
        entries.truncate(shown);
        entries.push((None, format!("+{hidden} more"), Style::Solid));
    }
    let rows = entries.len().div_ceil(ncols);
    let widest = entries
        .iter()
        .map(|e| text_width(&e.1, LEGEND_FONT))
        .fold(0.0, f64::max);
    let text_room =
        (avail_w - 2.0 * pad - (ncols - 1) as f64 * col_gap) / ncols as f64 - sample_w - 6.0;
    let text_w = widest.min(text_room.max(20.0));
    for e in &mut entries {
        e.1 = truncate_to(&e.1, text_w, LEGEND_FONT);
    }
    let col_w = sample_w + 6.0 + text_w;
    let w = 2.0 * pad + ncols as f64 * col_w + (ncols - 1) as f64 * col_gap;
    let h = 2.0 * pad + rows as f64 * row_h - 4.0;
    // Candidates in matplotlib's "best" preference order: upper right, upper left, lower left,
    // lower right.
    let corners = [
        (r.x + r.w - inset - w, r.y + inset),
        (r.x + inset, r.y + inset),
        (r.x + inset, r.y + r.h - inset - h),
        (r.x + r.w - inset - w, r.y + r.h - inset - h),
    ];
    let mut best = (usize::MAX, 0usize);
    for (ci, &(bx, by)) in corners.iter().enumerate() {
        let n = overlap(lines, bx, by, w, h);
        if n < best.0 {
            best = (n, ci);
        }
    }
    let (bx, by) = corners[best.1];
    let _ = writeln!(
        s,
        "<g font-size=\"{LEGEND_FONT}\" fill=\"{TEXT}\">\n<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" rx=\"3\" fill=\"#ffffff\" fill-opacity=\"0.85\" stroke=\"#cccccc\" stroke-width=\"0.8\"/>",
        c(bx),
        c(by),
        c(w),
        c(h)
    );
    for (i, (k, label, style)) in entries.iter().enumerate() {
        let (col, row) = (i / rows, i % rows);
        let x = bx + pad + col as f64 * (col_w + col_gap);
        let cy = by + pad + row_h * (row as f64 + 0.5) - 2.0;
        let text_x = match k {
            Some(k) => {
                let color = PALETTE[k % PALETTE.len()];
                let _ = writeln!(
                    s,
                    "<path d=\"M{} {}h{}\" stroke=\"{color}\" stroke-width=\"{LINE_WIDTH}\" fill=\"none\"{}/>",
                    c(x),
                    c(cy),
                    c(sample_w),
                    dash_attrs(*style)
                );
                x + sample_w + 6.0
            }
            None => x,
        };
        let _ = writeln!(
            s,
            "<text x=\"{}\" y=\"{}\">{}</text>",
            c(text_x),
            c(cy + LEGEND_FONT * 0.35),
            esc(label)
        );
    }
    s.push_str("</g>\n");
}

/// `text` shortened with an ellipsis to at most `max_w` px.
pub(super) fn truncate_to(text: &str, max_w: f64, size: f64) -> String {
    if text_width(text, size) <= max_w {
        return text.to_string();
    }
    let budget = max_w - text_width("…", size);
    let mut out = String::new();
    let mut used = 0.0;
    for ch in text.chars() {
        let cw = text_width(ch.encode_utf8(&mut [0; 4]), size);
        if used + cw > budget {
            break;
        }
        used += cw;
        out.push(ch);
    }
    out.truncate(out.trim_end().len());
    out.push('…');
    out
}

/// How much of the drawn data lies under a legend box at (bx, by, w, h): points sampled every
/// few pixels along each segment.
fn overlap(lines: &[Vec<Vec<(f64, f64)>>], bx: f64, by: f64, w: f64, h: f64) -> usize {
    let (x0, x1, y0, y1) = (bx - 3.0, bx + w + 3.0, by - 3.0, by + h + 3.0);
    let inside = |x: f64, y: f64| x >= x0 && x <= x1 && y >= y0 && y <= y1;
    let mut n = 0usize;
    for segs in lines {
        for seg in segs {
            if seg.len() == 1 && inside(seg[0].0, seg[0].1) {
                n += 1;
            }
            for pair in seg.windows(2) {
                let (a, b) = (pair[0], pair[1]);
                // Skip segments clearly away from the box.
                if a.0.max(b.0) < x0 || a.0.min(b.0) > x1 || a.1.max(b.1) < y0 || a.1.min(b.1) > y1
                {
                    continue;
                }
                let len = (dvpp_math::hypot(b.0 - a.0, b.1 - a.1) / 4.0)
                    .ceil()
                    .clamp(1.0, 500.0) as usize;
                for i in 0..=len {
                    let t = i as f64 / len as f64;
                    if inside(a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1)) {
                        n += 1;
                    }
                }
            }
        }
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plot::tests::assert_well_formed;
    use crate::plot::Figure;

    #[test]
    fn crowded_legend_stays_inside_the_plot() {
        let x = [0.0, 1.0];
        let mut p = Panel::new("many", "x", "y");
        for k in 0..40 {
            let label = format!("a rather long series label number {k}");
            p = p.series(label, &x, &[k as f64, k as f64], Style::Solid);
        }
        let mut fig = Figure::new("").panel(p);
        fig.panel_width = 300.0;
        fig.panel_height = 200.0;
        let svg = fig.to_svg();
        assert_well_formed(&svg);
        assert!(svg.contains('…'), "labels are shortened");
        assert!(svg.contains(" more</text>"), "overflow is summarised");
        assert_eq!(truncate_to("short", 100.0, 11.0), "short");
        let cut = truncate_to("a very long label indeed", 60.0, 11.0);
        assert!(
            cut.ends_with('…') && text_width(&cut, 11.0) <= 60.0,
            "{cut}"
        );
    }

    #[test]
    fn legend_avoids_data() {
        // Data in the upper right: the legend must go elsewhere.
        let x: Vec<f64> = (0..100).map(|i| i as f64).collect();
        let y: Vec<f64> = x.iter().map(|v| dvpp_math::powi(v / 99.0, 8)).collect();
        let p = Panel::new("t", "x", "y").series("steep", &x, &y, Style::Solid);
        let svg = Figure::new("").panel(p).to_svg();
        let legend = svg.split("fill-opacity=\"0.85\"").next().unwrap();
        let rect = legend.rsplit("<rect").next().unwrap();
        let x_attr: f64 = rect
            .split("x=\"")
            .nth(1)
            .and_then(|s| s.split('"').next())
            .and_then(|s| s.parse().ok())
            .unwrap();
        assert!(x_attr < 200.0, "legend at x={x_attr} overlaps the curve");
    }
}
