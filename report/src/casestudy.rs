//! Case study analysis of a co-simulation result: matching metrics against `T_des` and the
//! figures of the demo (PCC response vs desired, DER contributions, dc gains, dc links, ADPFs).

use crate::plot::{Figure, Panel, Style};
use crate::Columns;

/// System base of the shipped grid cases, MVA (powers are plotted in MW).
pub const S_BASE_MVA: f64 = 100.0;
/// Nominal frequency of the shipped grid cases, Hz.
pub const F_NOM_HZ: f64 = 50.0;

/// `max|x|`.
pub fn peak(x: &[f64]) -> f64 {
    x.iter().fold(0.0_f64, |m, v| m.max(v.abs()))
}

/// Normalized RMS error of `y` against the reference `r`: `rms(y - r) / max|r|`.
pub fn nrmse(y: &[f64], r: &[f64]) -> f64 {
    let n = y.len().min(r.len());
    if n == 0 {
        return f64::NAN;
    }
    let sq: f64 = y.iter().zip(r).map(|(a, b)| (a - b) * (a - b)).sum();
    (sq / n as f64).sqrt() / peak(r)
}

/// [`nrmse`] over the samples `[from, to)` only, still normalized by `max|r|` over the whole of
/// `r`: the error of a window (such as the transient after an event) on the same scale as the
/// whole run's.
pub fn nrmse_window(y: &[f64], r: &[f64], from: usize, to: usize) -> f64 {
    let to = to.min(y.len()).min(r.len());
    if from >= to {
        return f64::NAN;
    }
    let sq: f64 = y[from..to]
        .iter()
        .zip(&r[from..to])
        .map(|(a, b)| (a - b) * (a - b))
        .sum();
    (sq / (to - from) as f64).sqrt() / peak(r)
}

/// The samples of `time` in `[t0, t0 + window)`, as a range of indices.
pub fn window(time: &[f64], t0: f64, window: f64) -> std::ops::Range<usize> {
    let at = |t: f64| time.partition_point(|&x| x < t - 1e-9);
    at(t0)..at(t0 + window)
}

/// Largest `|a - b|` from sample `from` on, relative to `max|b|` over the whole of `b`.
pub fn max_gap(a: &[f64], b: &[f64], from: usize) -> f64 {
    max_gap_at(a, b, from).0
}

/// [`max_gap`] and the sample where it occurs.
pub fn max_gap_at(a: &[f64], b: &[f64], from: usize) -> (f64, usize) {
    let (gap, at) =
        a.iter()
            .zip(b)
            .enumerate()
            .skip(from)
            .fold((0.0_f64, from), |(m, at), (i, (x, y))| {
                let g = (x - y).abs();
                if g > m {
                    (g, i)
                } else {
                    (m, at)
                }
            });
    (gap / peak(b), at)
}

fn col(t: &(impl Columns + ?Sized), name: &str) -> Result<Vec<f64>, String> {
    t.column(name)
        .ok_or_else(|| format!("the results have no column '{name}'"))
}

/// Deviation from the first sample.
fn delta(x: &[f64]) -> Vec<f64> {
    let x0 = x.first().copied().unwrap_or(0.0);
    x.iter().map(|v| v - x0).collect()
}

/// The DER components of a result, in slot order (those with a `v_dc` output).
pub fn ders(t: &(impl Columns + ?Sized)) -> Vec<String> {
    t.names()
        .iter()
        .filter_map(|c| c.strip_suffix(".v_dc"))
        .map(str::to_owned)
        .collect()
}

/// The signals of a DVPP scenario's result.
pub struct Signals {
    pub time: Vec<f64>,
    /// `pcc.f - 1` and its desired value `ref.df` (pu of f_nom).
    pub df: Vec<f64>,
    pub df_ref: Vec<f64>,
    /// `pcc.v - pcc.v(0)` and `ref.dv` (pu).
    pub dv: Vec<f64>,
    pub dv_ref: Vec<f64>,
    /// Per DER: name, Δp, Δq (pu on S_base), μ_p (None: no active dc gain), μ_q, v_dc.
    pub der: Vec<DerSignals>,
}

pub struct DerSignals {
    pub name: String,
    pub dp: Vec<f64>,
    pub dq: Vec<f64>,
    pub mu_p: Option<Vec<f64>>,
    pub mu_q: Vec<f64>,
    pub v_dc: Vec<f64>,
    /// The unit's own frequency deviation `df` (pu of f_nom), when the results record it.
    pub df: Option<Vec<f64>>,
}

impl Signals {
    pub fn of(t: &(impl Columns + ?Sized)) -> Result<Signals, String> {
        let f = col(t, "grid.pcc.f")?;
        let v = col(t, "grid.pcc.v")?;
        let mut der = Vec::new();
        for (k, name) in ders(t).into_iter().enumerate() {
            let slot = k + 1;
            der.push(DerSignals {
                dp: delta(&col(t, &format!("grid.der[{slot}].p"))?),
                dq: delta(&col(t, &format!("grid.der[{slot}].q"))?),
                mu_p: t.column(&format!("operator.der[{slot}].mu_p")),
                mu_q: col(t, &format!("operator.der[{slot}].mu_q"))?,
                v_dc: col(t, &format!("{name}.v_dc"))?,
                df: t.column(&format!("{name}.df")),
                name,
            });
        }
        Ok(Signals {
            time: col(t, "time")?,
            df: f.iter().map(|x| x - 1.0).collect(),
            df_ref: col(t, "operator.ref.df")?,
            dv: delta(&v),
            dv_ref: col(t, "operator.ref.dv")?,
            der,
        })
    }

    /// The matching metrics of this run.
    pub fn metrics(&self) -> Metrics {
        Metrics {
            f_nrmse: nrmse(&self.df, &self.df_ref),
            v_nrmse: nrmse(&self.dv, &self.dv_ref),
            f_nadir_hz: self.df.iter().fold(0.0_f64, |m, v| m.min(*v)) * F_NOM_HZ,
            f_ref_nadir_hz: self.df_ref.iter().fold(0.0_f64, |m, v| m.min(*v)) * F_NOM_HZ,
            v_dc: self
                .der
                .iter()
                .map(|d| {
                    let dev: Vec<f64> = d.v_dc.iter().map(|x| x - 1.0).collect();
                    (d.name.clone(), peak(&dev))
                })
                .collect(),
        }
    }
}

impl Signals {
    /// The matching over the transient: NRMSE of `Δf_pcc` and `Δv_pcc` against their desired
    /// responses over `[t0, t0 + window)`, normalized by the desired peaks over the whole run
    /// (as [`Metrics`]), so that the two figures compare with the whole run's.
    pub fn transient(&self, t0: f64, window: f64) -> Transient {
        let w = self::window(&self.time, t0, window);
        Transient {
            window,
            f_nrmse: nrmse_window(&self.df, &self.df_ref, w.start, w.end),
            v_nrmse: nrmse_window(&self.dv, &self.dv_ref, w.start, w.end),
        }
    }

    /// Each unit's frequency against the PCC's (the paper's coherency `Δf_i ≈ Δf_pcc`), for the
    /// units whose `df` the results record. The PCC frequency is a meter's (`pcc.f`, the rate of
    /// change of the PCC angle through `s/(t_f s + 1)`), so each unit's `df` is compared as it
    /// is and through the same meter (`1/(t_f s + 1)` on the frequency, exact for a sample-and-
    /// hold at the recorded points).
    pub fn coherency(&self, t_f: f64) -> Vec<Coherency> {
        let h = match self.time.as_slice() {
            [a, b, ..] => b - a,
            _ => return Vec::new(),
        };
        let a = dvpp_math::exp(-h / t_f);
        let compare = |df: &[f64]| {
            let gap = df
                .iter()
                .zip(&self.df)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0_f64, f64::max);
            (gap * F_NOM_HZ, nrmse(df, &self.df))
        };
        self.der
            .iter()
            .filter_map(|d| {
                let df = d.df.as_ref()?;
                let mut y = df.first().copied().unwrap_or(0.0);
                let metered: Vec<f64> = df
                    .iter()
                    .map(|x| {
                        y = a * y + (1.0 - a) * x;
                        y
                    })
                    .collect();
                let (max_gap_hz, nrmse) = compare(df);
                let (metered_max_gap_hz, metered_nrmse) = compare(&metered);
                Some(Coherency {
                    name: d.name.clone(),
                    max_gap_hz,
                    nrmse,
                    metered_max_gap_hz,
                    metered_nrmse,
                })
            })
            .collect()
    }
}

/// The matching over a window after the event ([`Signals::transient`]).
#[derive(Debug, Clone)]
pub struct Transient {
    /// Length of the window, s.
    pub window: f64,
    pub f_nrmse: f64,
    pub v_nrmse: f64,
}

/// One unit's frequency against the PCC's ([`Signals::coherency`]).
#[derive(Debug, Clone)]
pub struct Coherency {
    pub name: String,
    /// Largest `|Δf_i − Δf_pcc|`, Hz, and the NRMSE of `Δf_i` against `Δf_pcc` relative to the
    /// PCC's peak deviation: the unit's frequency as it imposes it.
    pub max_gap_hz: f64,
    pub nrmse: f64,
    /// The same with `Δf_i` through the PCC's meter.
    pub metered_max_gap_hz: f64,
    pub metered_nrmse: f64,
}

/// Matching metrics of one run.
#[derive(Debug, Clone)]
pub struct Metrics {
    /// NRMSE of `Δf_pcc` against `ref.df` and of `Δv_pcc` against `ref.dv`.
    pub f_nrmse: f64,
    pub v_nrmse: f64,
    /// Lowest frequency deviation, measured and desired, Hz.
    pub f_nadir_hz: f64,
    pub f_ref_nadir_hz: f64,
    /// Per DER: the largest `|v_dc - 1|`, pu.
    pub v_dc: Vec<(String, f64)>,
}

fn mw(x: &[f64]) -> Vec<f64> {
    x.iter().map(|v| v * S_BASE_MVA).collect()
}

fn hz(x: &[f64]) -> Vec<f64> {
    x.iter().map(|v| v * F_NOM_HZ).collect()
}

/// The overview figure of a DVPP run; `compare` adds another run's `Δf_pcc` (dotted).
pub fn overview(title: &str, s: &Signals, compare: Option<(&str, &Signals)>) -> Figure {
    let t = &s.time;
    let mut f = Panel::new("PCC frequency deviation", "time (s)", "Δf (Hz)")
        .series("Δf_pcc", t, &hz(&s.df), Style::Solid)
        .series("desired −T_pf Δp_pcc", t, &hz(&s.df_ref), Style::Dashed);
    if let Some((label, c)) = compare {
        f = f.series(label, &c.time, &hz(&c.df), Style::Dotted);
    }
    let v = Panel::new("PCC voltage deviation", "time (s)", "Δv (pu)")
        .series("Δv_pcc", t, &s.dv, Style::Solid)
        .series("desired −T_qv Δq_pcc", t, &s.dv_ref, Style::Dashed);
    let mut p = Panel::new("DER active power change", "time (s)", "Δp (MW)");
    let mut q = Panel::new("DER reactive power change", "time (s)", "Δq (Mvar)");
    let mut mu = Panel::new("ADPF dc gains (operator)", "time (s)", "μ");
    let mut dc = Panel::new("dc-link voltages", "time (s)", "v_dc (pu)");
    for d in &s.der {
        p = p.series(d.name.as_str(), t, &mw(&d.dp), Style::Solid);
        q = q.series(d.name.as_str(), t, &mw(&d.dq), Style::Solid);
        if let Some(m) = &d.mu_p {
            mu = mu.series(format!("μ_p {}", d.name), t, m, Style::Solid);
        }
        mu = mu.series(format!("μ_q {}", d.name), t, &d.mu_q, Style::Dashed);
        dc = dc.series(d.name.as_str(), t, &d.v_dc, Style::Solid);
    }
    Figure::new(title)
        .columns(2)
        .panel(f)
        .panel(v)
        .panel(p)
        .panel(q)
        .panel(mu)
        .panel(dc)
}

/// A low-pass ADPF `μ/(τ s + 1)^d` of one DER (the complement is what the low-pass leave).
#[derive(Debug, Clone)]
pub struct LowPass {
    pub name: String,
    pub tau: f64,
    pub order: i32,
}

/// `|m_i(jω)|` of the low-pass units with gains `mu` and of their complement `1 - Σ m_j`.
pub fn adpf_magnitudes(lpf: &[LowPass], mu: &[f64], w: &[f64]) -> Vec<Vec<f64>> {
    let mut out = vec![Vec::with_capacity(w.len()); lpf.len() + 1];
    for &wk in w {
        let (mut re_sum, mut im_sum) = (0.0, 0.0);
        for (k, (l, m)) in lpf.iter().zip(mu).enumerate() {
            // μ / (1 + jωτ)^d
            let (mut re, mut im) = (*m, 0.0);
            for _ in 0..l.order.max(1) {
                let den = 1.0 + dvpp_math::powi(wk * l.tau, 2);
                let (a, b) = (1.0 / den, -wk * l.tau / den);
                (re, im) = (re * a - im * b, re * b + im * a);
            }
            re_sum += re;
            im_sum += im;
            out[k].push(dvpp_math::hypot(re, im));
        }
        out[lpf.len()].push(dvpp_math::hypot(1.0 - re_sum, -im_sum));
    }
    out
}

/// Bode magnitudes of the active ADPFs at two sets of dc gains (e.g. nominal and after a cloud).
pub fn adpf_figure(
    title: &str,
    lpf: &[LowPass],
    complement: &str,
    cases: &[(&str, &[f64])],
) -> Figure {
    let w: Vec<f64> = (0..=200)
        .map(|i| dvpp_math::pow(10f64, -3.0 + 6.0 * i as f64 / 200.0))
        .collect();
    let mut panel = Panel::new("active ADPFs |m_i(jω)|", "ω (rad/s)", "magnitude")
        .log_x()
        .y_range(0.0, 1.05);
    for (j, (label, mu)) in cases.iter().enumerate() {
        let style = if j == 0 { Style::Solid } else { Style::Dashed };
        let mags = adpf_magnitudes(lpf, mu, &w);
        for (k, m) in mags.iter().enumerate() {
            let name = lpf.get(k).map_or(complement, |l| l.name.as_str());
            panel = panel.series(format!("{name} ({label})"), &w, m, style);
        }
    }
    Figure::new(title).panel(panel)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nrmse_is_relative_to_the_reference_peak() {
        let r = [0.0, -1.0, -2.0, -1.0];
        let y = [0.0, -1.1, -2.0, -0.9];
        let expected = ((0.01 + 0.01) / 4.0_f64).sqrt() / 2.0;
        assert!((nrmse(&y, &r) - expected).abs() < 1e-15);
        assert_eq!(nrmse(&r, &r), 0.0);
    }

    #[test]
    fn a_window_keeps_the_whole_runs_peak() {
        let time = [0.0, 1.0, 2.0, 3.0];
        let r = [0.0, -1.0, -2.0, -1.0];
        let y = [0.0, -1.1, -2.0, -0.9];
        assert_eq!(window(&time, 1.0, 2.0), 1..3);
        // Samples 1 and 2: errors 0.1 and 0, over the whole run's peak 2.
        let expected = (0.01 / 2.0_f64).sqrt() / 2.0;
        assert!((nrmse_window(&y, &r, 1, 3) - expected).abs() < 1e-15);
        assert!(nrmse_window(&y, &r, 3, 3).is_nan());
    }

    #[test]
    fn adpfs_sum_to_one_at_every_frequency() {
        let lpf = [
            LowPass {
                name: "wind".into(),
                tau: 1.5,
                order: 1,
            },
            LowPass {
                name: "pv".into(),
                tau: 0.6,
                order: 1,
            },
        ];
        let w = [1e-3, 0.1, 1.0, 10.0, 1e3];
        let m = adpf_magnitudes(&lpf, &[0.4, 0.6], &w);
        // At dc the low-pass gains are the μ and the complement is 0; at high frequency the
        // complement takes everything.
        assert!((m[0][0] - 0.4).abs() < 1e-5 && (m[1][0] - 0.6).abs() < 1e-5);
        assert!(m[2][0] < 1e-3 && (m[2][4] - 1.0).abs() < 1e-3);
    }
}
