//! Load-step experiment and its frequency figures (nadir, RoCoF, settling, droop check).
//!
//! Shared by the tests and the `load_step` example.

use crate::case::{Case, Event, LoadModel};
use crate::grid::{Grid, GridError};
use serde::{Deserialize, Serialize};

/// Figures of a load step, COI frequency (pu; multiply by f_nom for Hz).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LoadStepFigures {
    pub f_nom: f64,
    pub dp_mw: f64,
    pub t_event: f64,
    /// Lowest COI frequency, pu, and when (s, absolute time).
    pub nadir: f64,
    pub t_nadir: f64,
    /// COI RoCoF right after the event (first 10 ms), pu/s.
    pub rocof_initial: f64,
    /// COI RoCoF over the first 100 ms after the event, pu/s.
    pub rocof_100ms: f64,
    /// Analytic initial RoCoF −ΔP_e(0+)/(2 ΣH), with ΔP_e(0+) the jump in machine air-gap power.
    pub rocof_analytic: f64,
    /// COI frequency at the end of the run (quasi steady state), pu.
    pub f_settled: f64,
    /// Last time |Δf − Δf_settled| exceeded 5 % of |Δf_settled|, s after the event.
    pub settling_time_5pct: f64,
    /// Measured change of total machine air-gap power, pu on S_base.
    pub dpe_total: f64,
    /// Droop stiffness Σ (S_i/S_base)/R_i + Σ D_i, pu/pu.
    pub stiffness: f64,
    /// −dpe_total / stiffness: the analytic droop deviation for the measured power change.
    pub df_droop_measured_dp: f64,
    /// −(dp_mw/S_base) / stiffness: the droop deviation for the nominal step size.
    pub df_droop_nominal_dp: f64,
    /// Largest |generation − load − losses| seen at any communication step, pu.
    pub max_balance_error: f64,
    /// (t, coi_f) trace at the communication step.
    pub trace: Vec<(f64, f64)>,
}

/// Run `case` with all its own events disabled plus a constant-impedance load step of `dp_mw`
/// at `bus` and time `t_event`, until `t_end`, with communication step `h`.
pub fn run_load_step(
    case: &Case,
    bus: u32,
    dp_mw: f64,
    t_event: f64,
    t_end: f64,
    h: f64,
) -> Result<LoadStepFigures, GridError> {
    run_load_step_with(
        case,
        bus,
        dp_mw,
        LoadModel::ConstantImpedance,
        t_event,
        t_end,
        h,
    )
}

/// As [`run_load_step`] with the model of the added load chosen by the caller.
pub fn run_load_step_with(
    case: &Case,
    bus: u32,
    dp_mw: f64,
    model: LoadModel,
    t_event: f64,
    t_end: f64,
    h: f64,
) -> Result<LoadStepFigures, GridError> {
    let mut g = Grid::new(case)?;
    g.disable_events();
    g.add_event(Event::LoadStep {
        time: t_event,
        bus,
        dp_mw,
        dq_mvar: 0.0,
        model,
    })?;
    let o0 = g.outputs();
    let pe0: f64 = o0.sg.iter().map(|m| m.pe).sum();
    let h_tot = g.total_inertia();
    let stiffness = g.droop_stiffness();
    let mut trace = vec![(0.0, o0.coi_f)];
    let mut max_bal = o0.balance_p.abs();
    let mut pe_jump = None;
    let nsteps = (t_end / h).round() as usize;
    for i in 0..nsteps {
        let t = i as f64 * h;
        g.step(t, h)?;
        let o = g.outputs();
        max_bal = max_bal.max(o.balance_p.abs());
        if pe_jump.is_none() && o.t > t_event {
            // first point after the event: air-gap power jump approximated by the value one
            // communication step later (machine angles barely move in h).
            let pe: f64 = o.sg.iter().map(|m| m.pe).sum();
            pe_jump = Some(pe - pe0);
        }
        trace.push((o.t, o.coi_f));
    }
    let o = g.outputs();
    let pe_end: f64 = o.sg.iter().map(|m| m.pe).sum();
    let f_at = |tq: f64| -> f64 {
        let i = trace
            .iter()
            .position(|&(t, _)| t >= tq - 1e-9)
            .unwrap_or(trace.len() - 1);
        trace[i].1
    };
    let (t_nadir, nadir) =
        trace
            .iter()
            .cloned()
            .fold((0.0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
    let f_ev = f_at(t_event);
    let rocof_initial = (f_at(t_event + 0.01) - f_ev) / 0.01;
    let rocof_100ms = (f_at(t_event + 0.1) - f_ev) / 0.1;
    let f_settled = o.coi_f;
    let dfs = f_settled - 1.0;
    let settling_time_5pct = trace
        .iter()
        .filter(|&&(t, f)| t > t_event && ((f - 1.0) - dfs).abs() > 0.05 * dfs.abs())
        .map(|&(t, _)| t - t_event)
        .fold(0.0, f64::max);
    let dpe_total = pe_end - pe0;
    Ok(LoadStepFigures {
        f_nom: case.f_nom,
        dp_mw,
        t_event,
        nadir,
        t_nadir,
        rocof_initial,
        rocof_100ms,
        rocof_analytic: -pe_jump.unwrap_or(0.0) / (2.0 * h_tot),
        f_settled,
        settling_time_5pct,
        dpe_total,
        stiffness,
        df_droop_measured_dp: -dpe_total / stiffness,
        df_droop_nominal_dp: -(dp_mw / case.base_mva) / stiffness,
        max_balance_error: max_bal,
        trace,
    })
}

impl std::fmt::Display for LoadStepFigures {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let hz = self.f_nom;
        writeln!(
            f,
            "load step {} MW at t = {} s (COI frequency, f_nom = {} Hz)",
            self.dp_mw, self.t_event, hz
        )?;
        writeln!(f, "  nadir            {:.6} pu = {:.4} Hz (Δf = {:.2} mHz) at t = {:.3} s ({:.3} s after the step)",
            self.nadir, self.nadir * hz, (self.nadir - 1.0) * hz * 1e3, self.t_nadir, self.t_nadir - self.t_event)?;
        writeln!(
            f,
            "  RoCoF first 10 ms {:.5} pu/s = {:.4} Hz/s (analytic −ΔPe/(2ΣH) = {:.4} Hz/s)",
            self.rocof_initial,
            self.rocof_initial * hz,
            self.rocof_analytic * hz
        )?;
        writeln!(
            f,
            "  RoCoF over 100 ms {:.5} pu/s = {:.4} Hz/s",
            self.rocof_100ms,
            self.rocof_100ms * hz
        )?;
        writeln!(
            f,
            "  settled          {:.7} pu = {:.4} Hz (Δf = {:.3} mHz), within 5 % after {:.1} s",
            self.f_settled,
            self.f_settled * hz,
            (self.f_settled - 1.0) * hz * 1e3,
            self.settling_time_5pct
        )?;
        writeln!(f, "  droop            ΣK = {:.3} pu/pu; ΔPe measured = {:.4} pu -> Δf = {:.6e} pu (sim {:.6e}, error {:.3} %)",
            self.stiffness, self.dpe_total, self.df_droop_measured_dp, self.f_settled - 1.0,
            100.0 * ((self.f_settled - 1.0) / self.df_droop_measured_dp - 1.0))?;
        writeln!(
            f,
            "                   nominal ΔP = {:.4} pu -> Δf = {:.6e} pu (sim differs by {:.3} %)",
            self.dp_mw / 100.0,
            self.df_droop_nominal_dp,
            100.0 * ((self.f_settled - 1.0) / self.df_droop_nominal_dp - 1.0)
        )?;
        write!(
            f,
            "  max |gen − load − losses| over the run: {:.3e} pu",
            self.max_balance_error
        )
    }
}
