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

mod pixels;
mod render;
mod text;
mod ticks;

use std::fmt::Write as _;
use std::path::Path;

use render::{layout, render_panel, truncate_to, Layout};
use text::{c, esc, finite_or};

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

#[cfg(test)]
mod tests {
    use super::*;

    /// Parses the whole document with quick-xml; panics on malformed XML.
    pub(super) fn assert_well_formed(svg: &str) {
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

    pub(super) fn assert_clean_numbers(svg: &str) {
        // How Rust prints non-finite floats (test titles avoid these words).
        assert!(!svg.contains("NaN"), "NaN in SVG");
        assert!(!svg.contains("inf"), "inf in SVG");
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
                    1.0 - dvpp_math::exp(-(t - 0.5) / 0.4)
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
                    1.0 - dvpp_math::exp(-s / 0.35) * (1.0 + 0.6 * dvpp_math::sin(6.0 * s))
                }
            })
            .collect();
        let f: Vec<f64> = (0..=600)
            .map(|i| dvpp_math::pow(10f64, -3.0 + i as f64 * 0.01))
            .collect();
        let mag = |f: f64, tau: f64| {
            -10.0 * dvpp_math::log10(1.0 + dvpp_math::powi(2.0 * std::f64::consts::PI * f * tau, 2))
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
                    -0.15 * (1.0 - dvpp_math::exp(-(t - 5.0) / 1.5))
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
