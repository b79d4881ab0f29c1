//! Case study II's generator outage: the `case2_outage_eps*` family run side by side, a verdict
//! per grid-forming share ε (stable within ratings, oscillatory, or lost synchronism), a CSV,
//! a table and the figure.

use der_model::ports;
use dvpp_cosim::master::{self, Options, Record, Scheme};
use dvpp_cosim::Table;
use dvpp_report::casestudy::Signals;
use dvpp_report::plot::{Figure, Panel, Style};
use std::path::Path;

use crate::sweep::EPS;

/// The trip of SG1 and SG3, s.
const T_TRIP: f64 = 1.0;
const F_NOM_HZ: f64 = 50.0;

/// What one outage run showed.
pub struct Verdict {
    pub eps: u32,
    /// The run's error, when it did not complete.
    pub error: Option<String>,
    /// First time the grid had no voltage source left (every bus at 0).
    pub deenergized_at: Option<f64>,
    /// Units whose `synchronized` fell after the trip, with the first time.
    pub lost_sync: Vec<(String, f64)>,
    /// PCC frequency: lowest and final deviation, Hz; the desired final deviation, Hz.
    pub f_nadir_hz: f64,
    pub f_end_hz: f64,
    pub f_ref_end_hz: f64,
    /// NRMSE of the PCC frequency against the operator's desired response over the run.
    pub f_nrmse: f64,
    /// Largest |pcc.f − (1 + ref.df)| after the trip, Hz: how far the response swings off the
    /// desired one (the oscillations of the smaller ε).
    pub f_gap_hz: f64,
    /// Lowest PCC voltage after the trip, pu.
    pub v_min: f64,
    /// Largest unit current over its rating (pu of rated current) and the unit.
    pub i_max: (f64, String),
    /// Lowest dc-link voltage of any unit (pu) and the unit.
    pub v_dc_min: (f64, String),
    /// Time series for the figure: t, PCC Δf (Hz), desired Δf (Hz), PCC v (pu), DVPP p (MW).
    pub series: [Vec<f64>; 5],
}

impl Verdict {
    /// One line: what happened.
    pub fn summary(&self) -> String {
        if let Some(e) = &self.error {
            return format!("failed: {e}");
        }
        if let Some(t) = self.deenergized_at {
            let units: Vec<&str> = self.lost_sync.iter().map(|u| u.0.as_str()).collect();
            return format!(
                "no voltage source left at t = {t:.3} s: the grid-following units ({}) lose synchronism, blackout",
                units.join(", ")
            );
        }
        if !self.lost_sync.is_empty() {
            return format!("units lost synchronism: {:?}", self.lost_sync);
        }
        let within = self.i_max.0 <= 1.0 + 1e-9;
        format!(
            "stable, settles at {:+.3} Hz (desired {:+.3} Hz); {}",
            self.f_end_hz,
            self.f_ref_end_hz,
            if within {
                "within ratings".to_string()
            } else {
                format!(
                    "above rating for a while ({} at {:.2} of rated current; I_max 1.2)",
                    self.i_max.1, self.i_max.0
                )
            }
        )
    }
}

fn column(t: &Table, name: &str) -> Result<Vec<f64>, String> {
    t.column(name).ok_or(format!("no column {name}"))
}

/// The verdict of one completed run of `case2_outage_eps{eps}` whose DER units are `expected`.
pub fn judge(eps: u32, t: &Table, expected: &[String]) -> Result<Verdict, String> {
    let time = column(t, "time")?;
    let after = time.partition_point(|&x| x < T_TRIP);
    let f = column(t, "grid.pcc.f")?;
    let v = column(t, "grid.pcc.v")?;
    let p = column(t, "grid.pcc.p")?;
    let df_ref = column(t, "operator.ref.df")?;
    let energized = column(t, "grid.energized")?;
    let deenergized_at = (after..time.len())
        .find(|&k| energized[k] < 0.5)
        .map(|k| time[k]);
    let units = crate::units_with(&t.columns, ports::I_AC, expected)?;
    crate::units_with(&t.columns, ports::SYNCHRONIZED, expected)?;
    crate::units_with(&t.columns, ports::V_DC, expected)?;
    let mut lost_sync = Vec::new();
    let mut i_max = (0.0, String::new());
    let mut v_dc_min = (f64::INFINITY, String::new());
    for u in &units {
        let sync = column(t, &format!("{u}.{}", ports::SYNCHRONIZED))?;
        if let Some(k) = (after..time.len()).find(|&k| sync[k] < 0.5) {
            lost_sync.push((u.clone(), time[k]));
        }
        let i = column(t, &format!("{u}.{}", ports::I_AC))?
            .into_iter()
            .fold(0.0, f64::max);
        if i > i_max.0 {
            i_max = (i, u.clone());
        }
        let vdc = column(t, &format!("{u}.{}", ports::V_DC))
            .map(|x| x.into_iter().fold(f64::INFINITY, f64::min))?;
        if vdc < v_dc_min.0 {
            v_dc_min = (vdc, u.clone());
        }
    }
    let hz = |x: f64| (x - 1.0) * F_NOM_HZ;
    let f_gap_hz = (after..time.len())
        .map(|k| (f[k] - 1.0 - df_ref[k]).abs() * F_NOM_HZ)
        .fold(0.0, f64::max);
    let last = time.len() - 1;
    Ok(Verdict {
        eps,
        error: None,
        deenergized_at,
        lost_sync,
        f_nadir_hz: f[after..].iter().map(|&x| hz(x)).fold(0.0, f64::min),
        f_end_hz: hz(f[last]),
        f_ref_end_hz: df_ref[last] * F_NOM_HZ,
        f_nrmse: Signals::of(t)?.metrics().f_nrmse,
        f_gap_hz,
        v_min: v[after..].iter().copied().fold(f64::INFINITY, f64::min),
        i_max,
        v_dc_min,
        series: [
            time.clone(),
            f.iter().map(|&x| hz(x)).collect(),
            df_ref.iter().map(|&x| x * F_NOM_HZ).collect(),
            v,
            p.iter().map(|&x| x * 100.0).collect(),
        ],
    })
}

/// Run `dist/case2_outage_eps*/` (bundled from `studies/scenarios/`), one thread per run up to
/// the cores.
fn run(root: &Path) -> Result<Vec<Verdict>, String> {
    let dist = root.join("dist");
    let jobs: Vec<u32> = EPS.to_vec();
    let results = std::sync::Mutex::new(Vec::new());
    let next = std::sync::atomic::AtomicUsize::new(0);
    let workers = std::thread::available_parallelism().map_or(1, |n| n.get());
    std::thread::scope(|s| {
        for _ in 0..workers.min(jobs.len()) {
            s.spawn(|| loop {
                let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(&eps) = jobs.get(k) else { break };
                let name = format!("case2_outage_eps{eps:03}");
                let path = dist.join(&name).join(format!("{name}.ssp"));
                let scenario = root
                    .join("studies")
                    .join("scenarios")
                    .join(format!("{name}.toml"));
                let expected = crate::scenario::units(&scenario);
                let table = dvpp_cosim::ssp::read(&path)
                    .map_err(|e| format!("{name}: {e}"))
                    .and_then(|pkg| {
                        let mut sys = master::System::builder(&pkg)
                            .load()
                            .map_err(|e| e.to_string())?;
                        sys.quiet();
                        sys.simulate_recording(
                            &Options {
                                stop: None,
                                step: None,
                                algorithm: Scheme::Jacobi,
                            },
                            Record::system_default(),
                        )
                        .map_err(|e| format!("{name}: {e}"))
                    });
                let verdict = table
                    .and_then(|t| judge(eps, &t, &expected?))
                    .unwrap_or_else(|e| Verdict {
                        eps,
                        error: Some(e),
                        deenergized_at: None,
                        lost_sync: Vec::new(),
                        f_nadir_hz: f64::NAN,
                        f_end_hz: f64::NAN,
                        f_ref_end_hz: f64::NAN,
                        f_nrmse: f64::NAN,
                        f_gap_hz: f64::NAN,
                        v_min: f64::NAN,
                        i_max: (f64::NAN, String::new()),
                        v_dc_min: (f64::NAN, String::new()),
                        series: Default::default(),
                    });
                println!(
                    "outage: ε = {:.2}: {}",
                    eps as f64 / 100.0,
                    verdict.summary()
                );
                results.lock().expect("results").push(verdict);
            });
        }
    });
    let mut v = results.into_inner().map_err(|_| "outage: a run panicked")?;
    v.sort_by_key(|x| x.eps);
    Ok(v)
}

/// The verdicts as a Markdown table.
pub fn table(v: &[Verdict]) -> String {
    let mut out = String::from(
        "| ε | verdict | PCC nadir | settles at (desired) | largest gap to the desired response | lowest PCC voltage | largest current / rating | lowest dc link |\n|---|---|---|---|---|---|---|---|\n",
    );
    for x in v {
        let short = if x.error.is_some() {
            "failed".to_string()
        } else if x.deenergized_at.is_some() {
            format!("lost synchronism ({} units), blackout", x.lost_sync.len())
        } else if x.i_max.0 <= 1.0 + 1e-9 {
            "stable within ratings".into()
        } else if x.i_max.0 < 1.2 - 1e-3 {
            "stable, briefly above rating".into()
        } else {
            "stable, briefly at the current limit".into()
        };
        let settle = if x.deenergized_at.is_some() {
            "—".to_string()
        } else {
            format!("{:+.3} Hz ({:+.3} Hz)", x.f_end_hz, x.f_ref_end_hz)
        };
        out += &format!(
            "| {:.2} | {short} | {:+.3} Hz | {settle} | {:.3} Hz | {:.3} pu | {:.2} ({}) | {:.3} pu ({}) |\n",
            x.eps as f64 / 100.0,
            x.f_nadir_hz,
            x.f_gap_hz,
            x.v_min,
            x.i_max.0,
            x.i_max.1,
            x.v_dc_min.0,
            x.v_dc_min.1,
        );
    }
    out
}

/// The figure shows the first seconds after the trip (the rest is flat).
const T_SHOWN: f64 = 6.0;

/// How many samples of `t` fall within the figure's window.
fn shown(t: &[f64]) -> usize {
    t.partition_point(|&x| x <= T_SHOWN)
}

/// PCC frequency against the desired response, PCC voltage and DVPP power, per ε.
pub fn figure(v: &[Verdict]) -> Figure {
    let mut f = Panel::new(
        "PCC frequency deviation (desired response of ε = 1 dashed)",
        "t (s)",
        "Hz",
    );
    let mut volt = Panel::new("PCC voltage", "t (s)", "pu");
    let mut p = Panel::new("DVPP active power at the PCC", "t (s)", "MW");
    for x in v {
        let style = Style::Solid;
        if x.series[0].is_empty() {
            continue;
        }
        let label = format!("ε = {:.2}", x.eps as f64 / 100.0);
        let n = shown(&x.series[0]);
        let t = &x.series[0][..n];
        f = f.series(label.clone(), t, &x.series[1][..n], style);
        volt = volt.series(label.clone(), t, &x.series[3][..n], style);
        p = p.series(label, t, &x.series[4][..n], style);
    }
    if let Some(x) = v.iter().rev().find(|x| !x.series[0].is_empty()) {
        let n = shown(&x.series[0]);
        f = f.series(
            "desired",
            &x.series[0][..n],
            &x.series[2][..n],
            Style::Dashed,
        );
    }
    Figure::new("Case study II: outage of SG1 and SG3 at t = 1 s, per grid-forming share ε")
        .panel(f)
        .panel(volt)
        .panel(p)
        .columns(3)
}

/// Run the family, write `results/case2_outage.csv` and the figure, print the table.
pub fn outage(root: &Path) -> Result<Vec<Verdict>, String> {
    let verdicts = run(root)?;
    let results = root.join("results");
    std::fs::create_dir_all(&results).map_err(|e| e.to_string())?;
    let mut csv = String::from(
        "eps,verdict,deenergized_at_s,lost_sync,pcc_nadir_Hz,pcc_end_Hz,desired_end_Hz,f_nrmse,max_gap_Hz,min_pcc_v,max_i_over_rating,max_i_unit,min_v_dc,min_v_dc_unit\n",
    );
    for x in &verdicts {
        csv += &format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            x.eps as f64 / 100.0,
            x.summary().replace([',', '\n'], ";"),
            x.deenergized_at.map_or(String::new(), |t| t.to_string()),
            x.lost_sync
                .iter()
                .map(|u| u.0.as_str())
                .collect::<Vec<_>>()
                .join(" "),
            x.f_nadir_hz,
            x.f_end_hz,
            x.f_ref_end_hz,
            x.f_nrmse,
            x.f_gap_hz,
            x.v_min,
            x.i_max.0,
            x.i_max.1,
            x.v_dc_min.0,
            x.v_dc_min.1,
        );
    }
    let path = results.join("case2_outage.csv");
    std::fs::write(&path, csv).map_err(|e| format!("{}: {e}", path.display()))?;
    crate::sweep::save_figure(root, &figure(&verdicts), "case2_outage.svg")?;
    let table = table(&verdicts);
    println!("{table}");
    crate::docs::update_between(
        root,
        crate::docs::CASE_STUDIES,
        "<!-- outage:begin -->",
        "<!-- outage:end -->",
        &table,
    )?;
    println!("outage: updated the table in {}", crate::docs::CASE_STUDIES);
    println!(
        "outage: {} and tests/figures/case2_outage.svg",
        path.display()
    );
    Ok(verdicts)
}
