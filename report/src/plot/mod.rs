//! SVG figures of simulation results: panels of line series with axes, ticks, legends; linear or log x.
//!
//! Dependency-free and deliberately small. A [`Figure`] is a grid of [`Panel`]s; each panel draws
//! line [`Series`] with "nice" ticks (1/2/5 × 10^k), light grid lines, axis labels, a title and a
//! legend placed in the emptiest corner. Large series are decimated to the min/max per pixel column
//! (peaks survive), non-finite values break the line, and no data can make rendering panic.
//!
//! ```
//! use dvpp_report::plot::{Figure, Panel, Style};
//! let t: Vec<f64> = (0..100).map(|i| i as f64 * 0.1).collect();
//! let y: Vec<f64> = t.iter().map(|t| 1.0 - (-t).exp()).collect();
//! let svg = Figure::new("Step response")
//!     .panel(
//!         Panel::new("Active power", "time [s]", "P [pu]")
//!             .series("measured", &t, &y, Style::Solid)
//!             .series("desired", &t, &vec![1.0; t.len()], Style::Dashed),
//!     )
//!     .to_svg();
//! assert!(svg.starts_with("<svg"));
//! ```

use std::fmt::Write as _;
use std::path::Path;

/// A figure: a title above a grid of panels, `columns` panels per row.
#[derive(Debug, Clone)]
pub struct Figure {
    pub title: String,
    pub panels: Vec<Panel>,
    /// Panels per row (values below 1 are treated as 1).
    pub columns: usize,
    /// Size of one panel cell in px (including its margins, ticks and labels).
    pub panel_width: f64,
    pub panel_height: f64,
}

/// One set of axes with its series.
#[derive(Debug, Clone)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    /// Logarithmic x axis; points with x <= 0 are skipped.
    pub log_x: bool,
    pub series: Vec<Series>,
    /// Fixed y range; `None` = automatic with a small margin.
    pub y_range: Option<(f64, f64)>,
}

/// One line. An empty label keeps the series out of the legend.
#[derive(Debug, Clone)]
pub struct Series {
    pub label: String,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub style: Style,
}

/// Line style.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Style {
    #[default]
    Solid,
    /// For reference curves ("desired response").
    Dashed,
    Dotted,
}

impl Figure {
    pub fn new(title: impl Into<String>) -> Self {
        Figure {
            title: title.into(),
            panels: Vec::new(),
            columns: 1,
            panel_width: 520.0,
            panel_height: 260.0,
        }
    }

    pub fn panel(mut self, p: Panel) -> Self {
        self.panels.push(p);
        self
    }

    pub fn columns(mut self, n: usize) -> Self {
        self.columns = n.max(1);
        self
    }

    /// Renders the figure as a standalone SVG document.
    pub fn to_svg(&self) -> String {
        let n = self.panels.len();
        let cols = self.columns.clamp(1, n.max(1));
        let pw = finite_or(self.panel_width, 520.0).clamp(120.0, 10_000.0);
        let ph = finite_or(self.panel_height, 260.0).clamp(90.0, 10_000.0);
        let title_h = if self.title.trim().is_empty() {
            6.0
        } else {
            38.0
        };
        let rows = n.div_ceil(cols);
        let width = (cols as f64 * pw).ceil();
        let height = (title_h + rows as f64 * ph + 6.0).ceil();

        let mut s = String::new();
        let _ = write!(
            s,
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" \
             viewBox=\"0 0 {w} {h}\" font-family=\"{FONT}\">\n\
             <rect x=\"0\" y=\"0\" width=\"{w}\" height=\"{h}\" fill=\"#ffffff\"/>\n",
            w = width,
            h = height,
        );
        if !self.title.trim().is_empty() {
            let _ = writeln!(
                s,
                "<text x=\"{}\" y=\"26\" text-anchor=\"middle\" font-size=\"17\" \
                 font-weight=\"bold\" fill=\"{TEXT}\">{}</text>",
                c(width / 2.0),
                esc(&truncate_to(&self.title, width - 10.0, 17.0 * 1.08))
            );
        }
        // Clip-path ids unique per figure, so that several figures can share an HTML page.
        let id = {
            use std::hash::{Hash, Hasher};
            let mut h = std::collections::hash_map::DefaultHasher::new();
            self.title.hash(&mut h);
            for p in &self.panels {
                p.title.hash(&mut h);
                p.series.len().hash(&mut h);
            }
            h.finish() as u32
        };
        let layouts: Vec<Layout> = self.panels.iter().map(|p| layout(p, ph)).collect();
        // Plot areas in one column line up: each column uses its widest left margin.
        let mut column_left = vec![0.0f64; cols];
        for (i, l) in layouts.iter().enumerate() {
            column_left[i % cols] = column_left[i % cols].max(l.left);
        }
        for (i, (p, lay)) in self.panels.iter().zip(layouts).enumerate() {
            let ox = (i % cols) as f64 * pw;
            let oy = title_h + (i / cols) as f64 * ph;
            let clip_id = format!("plot-clip-{id:08x}-{i}");
            render_panel(&mut s, p, lay, column_left[i % cols], &clip_id, ox, oy, pw);
        }
        s.push_str("</svg>\n");
        s
    }

    /// Writes [`Figure::to_svg`] to `path`, creating missing parent directories.
    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        if let Some(dir) = path.parent() {
            if !dir.as_os_str().is_empty() {
                std::fs::create_dir_all(dir)?;
            }
        }
        std::fs::write(path, self.to_svg())
    }
}

impl Panel {
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> Self {
        Panel {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            log_x: false,
            series: Vec::new(),
            y_range: None,
        }
    }

    pub fn log_x(mut self) -> Self {
        self.log_x = true;
        self
    }

    pub fn y_range(mut self, lo: f64, hi: f64) -> Self {
        self.y_range = Some((lo, hi));
        self
    }

    pub fn series(mut self, label: impl Into<String>, x: &[f64], y: &[f64], style: Style) -> Self {
        self.series.push(Series {
            label: label.into(),
            x: x.to_vec(),
            y: y.to_vec(),
            style,
        });
        self
    }
}

// ---------------------------------------------------------------------------------------------
// Look

const FONT: &str = "DejaVu Sans, Arial, sans-serif";
/// matplotlib's tab10.
const PALETTE: [&str; 10] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf",
];
const TEXT: &str = "#222222";
const AXIS: &str = "#444444";
const GRID: &str = "#dddddd";
const MINOR_GRID: &str = "#efefef";
const TICK_FONT: f64 = 11.0;
const LABEL_FONT: f64 = 12.0;
const TITLE_FONT: f64 = 13.5;
const LEGEND_FONT: f64 = 11.0;
const LINE_WIDTH: f64 = 1.6;
/// Pixel coordinates are clamped to this far outside the plot area (the rest is clipped anyway).
const FAR: f64 = 50_000.0;

// ---------------------------------------------------------------------------------------------
// Panel rendering

struct Rect {
    x: f64,
    y: f64,
    w: f64,
    h: f64,
}

#[derive(Clone, Copy)]
struct Axis {
    lo: f64,
    hi: f64,
    log: bool,
}

impl Axis {
    /// Position of `v` as a fraction of the axis (0 = lo, 1 = hi).
    fn frac(&self, v: f64) -> f64 {
        if self.log {
            let (a, b) = (self.lo.log10(), self.hi.log10());
            (v.log10() - a) / (b - a)
        } else {
            (v - self.lo) / (self.hi - self.lo)
        }
    }
}

struct Ticks {
    /// Labelled (major) ticks with grid lines.
    major: Vec<(f64, String)>,
    /// Unlabelled minor grid lines (log axes).
    minor: Vec<f64>,
    /// Printed once beside the axis: the labels show `value - offset`.
    offset: Option<String>,
}

/// The vertical layout, axes and y ticks of a panel: everything its left margin depends on.
struct Layout {
    xa: Axis,
    ya: Axis,
    yt: Ticks,
    top: f64,
    plot_h: f64,
    /// Widest y tick label.
    y_tick_w: f64,
    /// Left margin this panel needs (y label, tick labels, tick marks).
    left: f64,
}

fn layout(p: &Panel, ph: f64) -> Layout {
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
fn render_panel(
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
fn truncate_to(text: &str, max_w: f64, size: f64) -> String {
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
                let len = ((b.0 - a.0).hypot(b.1 - a.1) / 4.0)
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

// ---------------------------------------------------------------------------------------------
// Data → pixels

/// The x and y axes of a panel from its data (or the fixed y range).
fn data_axes(p: &Panel) -> (Axis, Axis) {
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
fn series_pixels(se: &Series, xa: &Axis, ya: &Axis, r: &Rect) -> Vec<Vec<(f64, f64)>> {
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

// ---------------------------------------------------------------------------------------------
// Ticks

/// "Nice" linear ticks (1/2/5 × 10^k) inside [lo, hi]: as close to `target` ticks as possible,
/// never more than `max_count` (when avoidable), with labels formatted for the step.
///
/// When the labels would need more than 6 significant digits (a small change on a large value),
/// they show the difference to a round `offset`, printed once beside the axis (`+1e6`).
fn linear_ticks(lo: f64, hi: f64, target: usize, max_count: usize) -> Ticks {
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
    let digits = max_abs.log10().floor() - (step.log10() + 1e-9).floor() + 1.0;
    if digits <= 6.0 {
        return None;
    }
    let g_exp = (span.log10() + 1e-9).floor() as i32 + 1;
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
    let k0 = (span / target as f64).log10().floor() as i32;
    // (score, step): prefer counts close to the target, within max_count, and at least 2.
    let mut best: Option<(f64, f64)> = None;
    for k in (k0 - 1)..=(k0 + 2) {
        for m in [1.0, 2.0, 5.0] {
            let step = m * 10f64.powi(k);
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
    let step_exp = (step.log10() + 1e-9).floor() as i32;
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
    let mut e = v.abs().log10().floor() as i32;
    let decimals = (e - step_exp).clamp(0, 12) as usize;
    let mut m = v / 10f64.powi(e);
    // Rounding may carry into the next decade (9.99 → 10.0).
    if format!("{:.decimals$}", m.abs()).starts_with("10") {
        e += 1;
        m = v / 10f64.powi(e);
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
fn x_ticks(xa: &Axis, plot_w: f64) -> Ticks {
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
    let (llo, lhi) = (lo.log10(), hi.log10());
    let inside = |v: f64| {
        let l = v.log10();
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
    10f64.powi(k)
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

// ---------------------------------------------------------------------------------------------
// Text

/// Rough rendered width of `text` in DejaVu Sans at `size` px (good enough for layout).
fn text_width(text: &str, size: f64) -> f64 {
    text.chars()
        .map(|ch| match ch {
            '0'..='9' => 0.64,
            '.' | ',' | ':' | ';' | 'i' | 'l' | 'j' | '|' | '!' | '\'' | 'I' => 0.3,
            ' ' => 0.32,
            '-' | '(' | ')' | '[' | ']' | '/' | 'f' | 't' | 'r' => 0.4,
            '\u{2212}' | '+' | '=' | '<' | '>' => 0.84,
            'm' | 'w' => 0.95,
            'M' | 'W' => 0.95,
            'A'..='Z' => 0.72,
            'a'..='z' => 0.6,
            _ => 0.75,
        })
        .sum::<f64>()
        * size
}

/// Estimated width of a tick label as rendered (with its typographic minus).
fn tick_width(label: &str) -> f64 {
    text_width(&minus(label), TICK_FONT)
}

/// Tick labels use a typographic minus sign (U+2212), as matplotlib does.
fn minus(label: &str) -> String {
    label.replace('-', "\u{2212}")
}

/// XML-escapes text and attribute values.
fn esc(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for ch in text.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            // Control characters are not allowed in XML 1.0.
            c if (c as u32) < 0x20 && c != '\t' && c != '\n' && c != '\r' => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

/// A coordinate with at most one decimal ("12.5", "12"); non-finite values become 0.
fn c(v: f64) -> String {
    if !v.is_finite() {
        return "0".into();
    }
    let r = (v * 10.0).round() / 10.0;
    let s = format!("{r:.1}");
    let s = s.strip_suffix(".0").unwrap_or(&s).to_string();
    if s == "-0" {
        "0".into()
    } else {
        s
    }
}

fn finite_or(v: f64, default: f64) -> f64 {
    if v.is_finite() {
        v
    } else {
        default
    }
}

// ---------------------------------------------------------------------------------------------

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

    /// Parses the whole document with quick-xml; panics on malformed XML.
    fn assert_well_formed(svg: &str) {
        use quick_xml::events::Event;
        let mut reader = quick_xml::Reader::from_str(svg);
        reader.config_mut().check_end_names = true;
        let mut depth = 0i32;
        let mut elements = 0usize;
        loop {
            match reader.read_event() {
                Ok(Event::Start(_)) => {
                    depth += 1;
                    elements += 1;
                }
                Ok(Event::Empty(_)) => elements += 1,
                Ok(Event::End(_)) => depth -= 1,
                Ok(Event::Eof) => break,
                Ok(_) => {}
                Err(e) => panic!(
                    "malformed SVG at {}: {e}\n{}",
                    reader.error_position(),
                    &svg[..svg.len().min(2000)]
                ),
            }
        }
        assert_eq!(depth, 0, "unbalanced elements");
        assert!(elements > 1);
        assert!(svg.starts_with("<svg xmlns=\"http://www.w3.org/2000/svg\""));
    }

    fn assert_clean_numbers(svg: &str) {
        // How Rust prints non-finite floats (test titles avoid these words).
        assert!(!svg.contains("NaN"), "NaN in SVG");
        assert!(!svg.contains("inf"), "inf in SVG");
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
            let m = step / 10f64.powf(step.log10().floor());
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
    fn degenerate_data_never_panics() {
        let nan = f64::NAN;
        let inf = f64::INFINITY;
        let panels = vec![
            Panel::new("empty", "x", "y"),
            Panel::new("empty series", "x", "y").series("e", &[], &[], Style::Solid),
            Panel::new("single", "x", "y").series("one", &[1.0], &[2.0], Style::Dotted),
            Panel::new("constant", "x", "y").series("c", &[0.0, 1.0, 2.0], &[5.0; 3], Style::Solid),
            Panel::new("zero", "x", "y").series("z", &[0.0, 1.0], &[0.0; 2], Style::Solid),
            Panel::new("mismatched", "x", "y").series("m", &[0.0, 1.0, 2.0], &[1.0], Style::Solid),
            Panel::new("all nan", "x", "y").series("n", &[nan, inf], &[nan, -inf], Style::Dashed),
            Panel::new("log nonpositive", "f", "g").log_x().series(
                "g",
                &[-1.0, 0.0],
                &[1.0, 2.0],
                Style::Solid,
            ),
            Panel::new("log mixed", "f", "g").log_x().series(
                "g",
                &[-1.0, 0.0, 0.1, 1.0, 10.0],
                &[1.0, 2.0, 3.0, 4.0, 5.0],
                Style::Solid,
            ),
            Panel::new("huge", "x", "y").series(
                "h",
                &[-f64::MAX, 0.0, f64::MAX],
                &[f64::MAX, -f64::MAX, f64::MIN_POSITIVE],
                Style::Solid,
            ),
            Panel::new("tiny", "x", "y").series("t", &[0.0, 1e-320], &[1e-320, 0.0], Style::Solid),
            Panel::new("precision", "x", "y").series(
                "p",
                &[1e15, 1e15 + 1.0],
                &[1.0, 1.0 + 1e-15],
                Style::Solid,
            ),
            Panel::new("bad range", "x", "y").y_range(nan, 1.0).series(
                "b",
                &[0.0, 1.0],
                &[0.0, 1.0],
                Style::Solid,
            ),
            Panel::new("reversed range", "x", "y")
                .y_range(2.0, -2.0)
                .series("r", &[0.0, 1.0], &[-5.0, 5.0], Style::Solid),
            Panel::new("", "", "").series("", &[0.0, 1.0], &[0.0, 1.0], Style::Solid),
        ];
        let mut fig = Figure::new("Degenerate <data> & \"quotes\"").columns(0);
        fig.columns = usize::MAX;
        fig.panel_width = nan;
        fig.panel_height = -3.0;
        for p in panels {
            fig = fig.panel(p);
        }
        let svg = fig.to_svg();
        assert_well_formed(&svg);
        assert_clean_numbers(&svg);
        assert!(svg.contains("Degenerate &lt;data&gt; &amp; &quot;quotes&quot;"));
        assert!(svg.contains("<circle"), "single point is drawn as a dot");
        // A figure without panels is still a valid document.
        assert_well_formed(&Figure::new("nothing").to_svg());
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

    #[test]
    fn escaping_and_coordinates() {
        assert_eq!(
            esc("a<b & 'c' \"d\">"),
            "a&lt;b &amp; &apos;c&apos; &quot;d&quot;&gt;"
        );
        assert_eq!(c(12.04), "12");
        assert_eq!(c(12.06), "12.1");
        assert_eq!(c(-0.01), "0");
        assert_eq!(c(f64::NAN), "0");
    }

    #[test]
    fn legend_avoids_data() {
        // Data in the upper right: the legend must go elsewhere.
        let x: Vec<f64> = (0..100).map(|i| i as f64).collect();
        let y: Vec<f64> = x.iter().map(|v| (v / 99.0).powi(8)).collect();
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

    /// The README-style sample: a 2×2 figure. Set `DVPP_PLOT_SAMPLE=/path/sample.svg` to write it.
    #[test]
    fn sample_figure() {
        let t: Vec<f64> = (0..=600).map(|i| i as f64 * 0.01).collect();
        let desired: Vec<f64> = t
            .iter()
            .map(|&t| {
                if t < 0.5 {
                    0.0
                } else {
                    1.0 - (-(t - 0.5) / 0.4).exp()
                }
            })
            .collect();
        let actual: Vec<f64> = t
            .iter()
            .map(|&t| {
                if t < 0.5 {
                    0.0
                } else {
                    let s = t - 0.5;
                    1.0 - (-s / 0.35).exp() * (1.0 + 0.6 * (6.0 * s).sin())
                }
            })
            .collect();
        let f: Vec<f64> = (0..=600)
            .map(|i| 10f64.powf(-3.0 + i as f64 * 0.01))
            .collect();
        let mag = |f: f64, tau: f64| {
            -10.0 * (1.0 + (2.0 * std::f64::consts::PI * f * tau).powi(2)).log10()
        };
        let g1: Vec<f64> = f.iter().map(|&f| mag(f, 0.5)).collect();
        let g2: Vec<f64> = f.iter().map(|&f| mag(f, 0.5) + mag(f, 0.02)).collect();
        fn i_of(t: f64) -> usize {
            (t * 1e4).round() as usize
        }
        let n = 200_000;
        let tn: Vec<f64> = (0..n).map(|i| i as f64 * 1e-4).collect();
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let freq: Vec<f64> = tn
            .iter()
            .map(|&t| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let noise = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                let dip = if t > 5.0 {
                    -0.15 * (1.0 - (-(t - 5.0) / 1.5).exp())
                } else {
                    0.0
                };
                50.0 + dip + 0.004 * noise + if i_of(t) == 123_456 { 0.05 } else { 0.0 }
            })
            .collect();
        let fig = Figure::new("DVPP sample results")
            .columns(2)
            .panel(
                Panel::new("Step response", "time [s]", "active power [pu]")
                    .series("DVPP output", &t, &actual, Style::Solid)
                    .series("desired response", &t, &desired, Style::Dashed),
            )
            .panel(
                Panel::new("Bode magnitude", "frequency [Hz]", "magnitude [dB]")
                    .log_x()
                    .series("first order", &f, &g1, Style::Solid)
                    .series("second order", &f, &g2, Style::Dashed),
            )
            .panel(
                Panel::new("Grid frequency (200 000 samples)", "time [s]", "f [Hz]").series(
                    "measured",
                    &tn,
                    &freq,
                    Style::Solid,
                ),
            )
            .panel(
                Panel::new("Constant set-point", "time [s]", "Q [pu]").series(
                    "Q ref",
                    &[0.0, 10.0],
                    &[0.3, 0.3],
                    Style::Dotted,
                ),
            );
        let svg = fig.to_svg();
        assert_well_formed(&svg);
        assert_clean_numbers(&svg);
        assert!(svg.len() < 300_000, "{} bytes", svg.len());
        if let Some(path) = std::env::var_os("DVPP_PLOT_SAMPLE") {
            fig.save(Path::new(&path)).unwrap();
        }
    }
}
