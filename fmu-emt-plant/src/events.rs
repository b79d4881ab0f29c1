//! The test bench's events as plant parameters (faults, the source's voltage step, frequency ramp and breaker, a line and a parallel line, the units' grounding), their checks, and the plant's initialization and steps on the bench's circuit.
//!
//! The source's voltage step and frequency ramp only move the Thevenin source's oscillator and
//! run on the plant's balanced αβ circuit. Everything else changes the circuit; when any of it
//! is configured the plant runs on [`crate::bench`]'s αβ0 circuit instead (a run with none of
//! these parameters set is the plant's αβ run, unchanged).

use crate::bench::{self, Bench, BenchCache, BenchData, BenchTopo, Fault, FaultKind, Grounding};
use crate::config::Layout;
use crate::dc::DcState;
use crate::meter::{clarke, inverse_clarke, Pll};
use crate::network::{Branch, Topology, UnitData};
use crate::steady::{self, Slack, C};
use crate::{non_negative, positive, unit_name, Energies, Fixed, Plant, PlantState, Run};
use fmi_export::{Context, Integer, ModelError, Real, Spec, Store, Variables};
use nalgebra::DVector;
use serde::{Deserialize, Serialize};

/// Handles of the source's events and the lines (declared with a Thevenin source).
#[derive(Clone, Serialize, Deserialize)]
struct SourceVars {
    step: Real,
    step_t: Real,
    rocof: Real,
    rocof_t: Real,
    rocof_duration: Real,
    t_open: Real,
    line_r: Real,
    line_x: Real,
    par_r: Real,
    par_x: Real,
    par_t_on: Real,
    par_t_off: Real,
}

/// Handles of the fault's parameters.
#[derive(Clone, Serialize, Deserialize)]
struct FaultVars {
    kind: Integer,
    location: Integer,
    r: Real,
    x: Real,
    t: Real,
    duration: Real,
    clearing: Integer,
}

/// Handles of the test bench's variables.
#[derive(Clone, Serialize, Deserialize)]
pub(crate) struct BenchVars {
    grounding: Vec<Integer>,
    source: Option<SourceVars>,
    fault: FaultVars,
    fault_i: [Real; 3],
    pub(crate) energy_fault: Real,
    pub(crate) energy_switching: Real,
    /// The source's frequency (declared with a Thevenin source).
    pub(crate) f_source: Option<Real>,
}

/// What initialization fixes for the bench: its circuit and the switching times.
#[derive(Clone, Serialize, Deserialize)]
pub(crate) struct BenchFixed {
    pub(crate) bench: Bench,
    /// The source's breaker opens (None: never).
    t_open: Option<f64>,
    /// The parallel line enters / leaves service (None: never).
    par_on: Option<f64>,
    par_off: Option<f64>,
    /// The fault is applied / cleared.
    fault: Option<(f64, f64)>,
    /// Each faulted phase's branch opens at its current's first zero after the clearing time
    /// (as a breaker pole), rather than all at once.
    at_current_zero: bool,
}

const PHASES: [&str; 3] = ["a", "b", "c"];

fn reached(t: f64, at: Option<f64>) -> bool {
    let tol = 1e-9 * t.abs().max(1.0);
    at.is_some_and(|at| t >= at - tol)
}

impl Plant {
    /// Declare the bench's variables (after every other variable of the plant).
    pub(crate) fn declare_bench(v: &mut Variables, layout: &Layout) -> BenchVars {
        let par = |v: &mut Variables, n: &str, start: f64, unit: &str, what: &str| {
            v.real(Spec::parameter(n, start, unit, what))
        };
        let source = layout.thevenin.then(|| SourceVars {
            step: par(v, "thevenin.step", 0.0, "pu", "test bench: voltage step, added to the source's amplitude thevenin.E from thevenin.step_t on (any sign; 0: none)"),
            step_t: par(v, "thevenin.step_t", 1.0, "s", "test bench: time of the voltage step"),
            rocof: par(v, "thevenin.rocof", 0.0, "Hz/s", "test bench: frequency ramp of the source (RoCoF, any sign; 0: none), from thevenin.rocof_t for thevenin.rocof_duration, then held"),
            rocof_t: par(v, "thevenin.rocof_t", 1.0, "s", "test bench: start of the frequency ramp"),
            rocof_duration: v.real(Spec::parameter("thevenin.rocof_duration", 0.5, "s", "test bench: duration of the frequency ramp (the frequency then stays at f_nom + rocof duration)").min(0.0)),
            t_open: par(v, "thevenin.t_open", -1.0, "s", "test bench: the source's breaker opens (an island) at the first step boundary at or after this time (negative: never)"),
            line_r: v.real(Spec::parameter("line.R", 0.0, "pu", "test bench: resistance of a line from the source bus (behind the Thevenin impedance) to the PCC, on S_base").min(0.0)),
            line_x: v.real(Spec::parameter("line.X", 0.0, "pu", "test bench: reactance of the line from the source bus to the PCC, on S_base (0: no line, no source bus)").min(0.0)),
            par_r: v.real(Spec::parameter("parallel.R", 0.015, "pu", "test bench: resistance of the parallel line, on S_base (beside the line, or beside the Thevenin impedance without one)").min(0.0)),
            par_x: v.real(Spec::parameter("parallel.X", 0.15, "pu", "test bench: reactance of the parallel line, on S_base").min(0.0)),
            par_t_on: par(v, "parallel.t_on", -1.0, "s", "test bench: the parallel line enters service at the first step boundary at or after this time (0: from the start; negative: never)"),
            par_t_off: par(v, "parallel.t_off", -1.0, "s", "test bench: the parallel line leaves service at the first step boundary at or after this time (negative: never): an SCR step"),
        });
        let int = |v: &mut Variables, n: &str, start: i32, lo: f64, hi: f64, what: &str| {
            v.integer(Spec::parameter(n, start, "", what).range(lo, hi))
        };
        let fault = FaultVars {
            kind: int(v, "fault.type", 0, 0.0, 4.0, "test bench: fault: 0 = none, 1 = three-phase to ground, 2 = single line to ground (phase a), 3 = line to line (b-c), 4 = line to line to ground (b-c-g)"),
            location: int(v, "fault.location", 1, 1.0, 2.0, "test bench: where the fault is: 1 = the PCC, 2 = the source bus (needs a line, line.X > 0)"),
            r: v.real(Spec::parameter("fault.R", 0.0, "pu", "test bench: fault resistance per faulted phase, on S_base").min(0.0)),
            x: v.real(Spec::parameter("fault.X", 0.001, "pu", "test bench: fault reactance per faulted phase, on S_base (> 0: the faulted node joins only inductive branches; 0.001 is a bolted fault)").min(0.0)),
            t: par(v, "fault.t", 1.0, "s", "test bench: the fault is applied at the first step boundary at or after this time"),
            duration: v.real(Spec::parameter("fault.duration", 0.15, "s", "test bench: the fault is cleared from the first step boundary at or after fault.t + fault.duration (see fault.clearing)").min(0.0)),
            clearing: int(v, "fault.clearing", 0, 0.0, 1.0, "test bench: how the fault is cleared: 0 = each faulted branch opens at the first step boundary after its current crossed zero (as a breaker pole), 1 = all at once (the currents of the inductive branches jump so KCL holds; the magnetic energy released is energy.switching)"),
        };
        let grounding = layout
            .units
            .iter()
            .enumerate()
            .map(|(k, u)| {
                let who = format!("unit {} ({}, {} MVA)", k + 1, u.name, u.s_rated);
                int(v, &unit_name(k, "grounding"), 0, 0.0, 2.0, &format!("{who}: test bench: 0 = three-wire (no zero-sequence current in the unit), 1 = grounded star (transformer YNyn, filter-capacitor star point and the converter's dc midpoint grounded: zero-sequence current flows through the unit, driven by the modulation's zero sequence), 2 = transformer Dyn with its MV star grounded (zero-sequence current flows in the transformer, ig_*, and circulates in its delta; none in the filter or the converter)"))
            })
            .collect();
        let fault_i = PHASES.map(|x| {
            v.real(Spec::output(
                &format!("fault.i_{x}"),
                "pu",
                &format!(
                    "test bench: fault current leaving phase {x} of the faulted node, on S_base"
                ),
            ))
        });
        let energy_fault = v.real(Spec::output(
            "energy.fault",
            "MJ",
            "test bench: energy dissipated in the fault impedance since initialization",
        ));
        let energy_switching = v.real(Spec::output(
            "energy.switching",
            "MJ",
            "test bench: magnetic energy the breakers removed interrupting inductive currents (fault clearing, the source's breaker, the parallel line) since initialization",
        ));
        let f_source = layout.thevenin.then(|| {
            v.real(Spec::output(
                "thevenin.f",
                "pu",
                "test bench: the source's frequency at the end of the step, pu of f_nom: 1 + thevenin.df + the frequency ramp's deviation",
            ))
        });
        BenchVars {
            f_source,
            grounding,
            source,
            fault,
            fault_i,
            energy_fault,
            energy_switching,
        }
    }

    /// The source's voltage step and frequency ramp, checked (None where not configured).
    #[allow(clippy::type_complexity)]
    pub(crate) fn source_events(
        &self,
        s: &Store,
        thevenin: bool,
    ) -> Result<(Option<(f64, f64)>, Option<(f64, f64, f64)>), ModelError> {
        let Some(sv) = self.bench.source.as_ref().filter(|_| thevenin) else {
            return Ok((None, None));
        };
        let finite = |r: Real, name: &str| {
            let x = s[r];
            if x.is_finite() {
                Ok(x)
            } else {
                Err(ModelError(format!(
                    "parameter '{name}' = {x} must be finite"
                )))
            }
        };
        let de = finite(sv.step, "thevenin.step")?;
        let step_t = finite(sv.step_t, "thevenin.step_t")?;
        let rocof = finite(sv.rocof, "thevenin.rocof")?;
        let rocof_t = finite(sv.rocof_t, "thevenin.rocof_t")?;
        let dur = non_negative(s, sv.rocof_duration, "thevenin.rocof_duration")?;
        if let Some(t) = &self.thevenin {
            if s[t.e] + de < 0.0 {
                return Err(format!(
                    "parameter 'thevenin.step' = {de} would make the source's amplitude negative (thevenin.E = {})",
                    s[t.e]
                )
                .into());
            }
        }
        Ok((
            (de != 0.0).then_some((de, step_t)),
            (rocof != 0.0 && dur > 0.0).then_some((rocof, rocof_t, dur)),
        ))
    }

    /// The bench's circuit and switching times, checked; None when no bench element is
    /// configured.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn bench_fixed(
        &self,
        s: &Store,
        units: &[UnitData],
        loads: &[Branch],
        thevenin: Option<Branch>,
        s_base: f64,
        omega_b: f64,
    ) -> Result<Option<BenchFixed>, ModelError> {
        let bv = &self.bench;
        let mut grounding = Vec::new();
        for (k, g) in bv.grounding.iter().enumerate() {
            match s[*g] {
                0 => grounding.push(Grounding::ThreeWire),
                1 => grounding.push(Grounding::Star),
                2 => grounding.push(Grounding::Delta),
                x => {
                    return Err(format!(
                        "parameter '{}' = {x} must be 0 (three-wire), 1 (grounded star) or 2 (Dyn, MV star grounded)",
                        unit_name(k, "grounding")
                    )
                    .into())
                }
            }
        }
        let fv = &bv.fault;
        let kind = match s[fv.kind] {
            0 => None,
            1 => Some(FaultKind::ThreePhase),
            2 => Some(FaultKind::Slg),
            3 => Some(FaultKind::Ll),
            4 => Some(FaultKind::Llg),
            x => return Err(format!("parameter 'fault.type' = {x} must be 0 to 4").into()),
        };
        let finite = |r: Real, name: &str| {
            let x = s[r];
            if x.is_finite() {
                Ok(x)
            } else {
                Err(ModelError(format!(
                    "parameter '{name}' = {x} must be finite"
                )))
            }
        };
        let (mut line, mut parallel, mut t_open, mut par_on, mut par_off) =
            (None, None, None, None, None);
        if let (Some(sv), Some(_)) = (&bv.source, thevenin) {
            let r = non_negative(s, sv.line_r, "line.R")?;
            let x = non_negative(s, sv.line_x, "line.X")?;
            if x > 0.0 {
                line = Some(Branch { r, l: x });
            } else if r > 0.0 {
                return Err(format!(
                    "parameter 'line.R' = {r} needs a line reactance: 'line.X' = 0 declares no line"
                )
                .into());
            }
            let on = finite(sv.par_t_on, "parallel.t_on")?;
            if on >= 0.0 {
                parallel = Some(Branch {
                    r: non_negative(s, sv.par_r, "parallel.R")?,
                    l: positive(s, sv.par_x, "parallel.X")?,
                });
                par_on = Some(on);
                let off = finite(sv.par_t_off, "parallel.t_off")?;
                par_off = (off >= 0.0).then_some(off);
            }
            let open = finite(sv.t_open, "thevenin.t_open")?;
            t_open = (open >= 0.0).then_some(open);
        }
        let mut at_current_zero = true;
        let fault = match kind {
            None => None,
            Some(kind) => {
                let at_source_bus = match s[fv.location] {
                    1 => false,
                    2 => true,
                    x => {
                        return Err(format!(
                            "parameter 'fault.location' = {x} must be 1 (PCC) or 2 (source bus)"
                        )
                        .into())
                    }
                };
                if at_source_bus && line.is_none() {
                    return Err("parameter 'fault.location' = 2 (source bus) needs a source bus: a Thevenin source and a line (line.X > 0)".to_string().into());
                }
                let r = non_negative(s, fv.r, "fault.R")?;
                let x = positive(s, fv.x, "fault.X").map_err(|e| {
                    ModelError(format!(
                        "{e} (the faulted node joins only inductive branches; 0.001 makes a bolted fault)"
                    ))
                })?;
                let t = finite(fv.t, "fault.t")?;
                let clearing = s[fv.clearing];
                if !(0..=1).contains(&clearing) {
                    return Err(format!(
                        "parameter 'fault.clearing' = {clearing} must be 0 (at current zero) or 1 (at once)"
                    )
                    .into());
                }
                at_current_zero = clearing == 0;
                let dur = non_negative(s, fv.duration, "fault.duration")?;
                Some((
                    Fault {
                        kind,
                        at_source_bus,
                        z: Branch { r, l: x },
                    },
                    (t, t + dur),
                ))
            }
        };
        let active = fault.is_some()
            || line.is_some()
            || parallel.is_some()
            || t_open.is_some()
            || grounding.iter().any(|g| *g != Grounding::ThreeWire);
        if !active {
            return Ok(None);
        }
        Ok(Some(BenchFixed {
            bench: Bench::new(BenchData {
                units: units.to_vec(),
                grounding,
                loads: loads.to_vec(),
                thevenin,
                line,
                parallel,
                fault: fault.map(|f| f.0),
                s_base,
                omega_b,
            }),
            t_open,
            par_on,
            par_off,
            fault: fault.map(|f| f.1),
            at_current_zero,
        }))
    }
}

impl Fixed {
    /// The bench's topology of the step that starts at `t`.
    fn bench_topology(&self, t: f64) -> BenchTopo {
        let b = self.bench.as_ref().expect("the bench is configured");
        let tol = 1e-9 * t.abs().max(1.0);
        BenchTopo {
            loads: self.topology(t).loads,
            thevenin: self.thevenin_on && !reached(t, b.t_open),
            parallel: reached(t, b.par_on) && !reached(t, b.par_off),
            fault: if b
                .fault
                .is_some_and(|(on, off)| t >= on - tol && t < off - tol)
            {
                b.bench.fault_all()
            } else {
                0
            },
            rotating_hold: self.rotating_hold,
        }
    }

    /// The bench's topology at initialization: before any event (the loads and the parallel
    /// line connected from the start, the breaker closed, no fault).
    fn bench_topology_init(&self) -> BenchTopo {
        let b = self.bench.as_ref().expect("the bench is configured");
        BenchTopo {
            loads: self.topology(0.0).loads,
            thevenin: self.thevenin_on,
            parallel: b.par_on.is_some_and(|at| at <= 0.0),
            fault: 0,
            rotating_hold: self.rotating_hold,
        }
    }
}

/// An impedance as a complex number.
fn zc(b: Branch) -> C {
    C::new(b.r, b.l)
}

fn parallel(a: C, b: C) -> C {
    a * b / (a + b)
}

impl Plant {
    /// Initialization on the bench's circuit: the balanced steady state with the source's
    /// lines reduced to their equivalent impedance, then each line's current from it.
    pub(crate) fn initialize_bench(
        &self,
        fixed: Fixed,
        s: &mut Store,
    ) -> Result<PlantState, ModelError> {
        let bf = fixed.bench.as_ref().expect("the bench is configured");
        let b = &bf.bench;
        let d = &b.data;
        let topo0 = fixed.bench_topology_init();
        let par_on = topo0.parallel && d.parallel.is_some();
        let zeq = d
            .thevenin
            .map(|th| match (d.line, d.parallel.filter(|_| par_on)) {
                (None, None) => zc(th),
                (None, Some(p)) => parallel(zc(th), zc(p)),
                (Some(l), None) => zc(th) + zc(l),
                (Some(l), Some(p)) => zc(th) + parallel(zc(l), zc(p)),
            });
        let mut net = fixed.net.clone();
        net.thevenin = zeq.map(|z| Branch { r: z.re, l: z.im });
        let topo = Topology {
            loads: topo0.loads,
            thevenin: topo0.thevenin,
            rotating_hold: topo0.rotating_hold,
        };
        let s0: Vec<C> = self
            .units
            .iter()
            .map(|u| C::new(s[u.p0], s[u.q0]))
            .collect();
        let (e_mag, angle) = fixed.source(0.0);
        let e = dvpp_math::cpolar(e_mag, angle);
        let slack = if topo.thevenin {
            Slack::Thevenin(e)
        } else {
            let v0 = self.units[0].v0.expect("unit 1 declares v0");
            Slack::Unit(C::new(s[v0], 0.0))
        };
        let st = steady::solve(&net, &topo, slack, &s0).map_err(ModelError)?;
        let mut x = vec![0.0; b.nx()];
        for (k, u) in st.units.iter().enumerate() {
            let ix = b.unit(k);
            Bench::put(&mut x, ix.i_f, u.i_f);
            Bench::put(&mut x, ix.v_c, u.v_c);
            Bench::put(&mut x, ix.i_g, u.i_g);
        }
        for (j, i) in st.loads.iter().enumerate() {
            let [a, bb] = b.load(j);
            Bench::put(&mut x, [Some(a), Some(bb), None], *i);
        }
        let [th_ix, line_ix, par_ix] = b.grid_index();
        let mut i_source = C::new(0.0, 0.0);
        if let (true, Some(th)) = (topo.thevenin, d.thevenin) {
            let v = st.v_pcc;
            let put = |x: &mut [f64], ix: Option<[usize; 3]>, c: C| {
                if let Some(ix) = ix {
                    Bench::put(x, [Some(ix[0]), Some(ix[1]), None], c);
                }
            };
            match d.line {
                None => {
                    let i_th = if par_on { (e - v) / zc(th) } else { st.i_th };
                    put(&mut x, th_ix, i_th);
                    i_source = i_th;
                    if let (true, Some(p)) = (par_on, d.parallel) {
                        let i_par = (e - v) / zc(p);
                        put(&mut x, par_ix, i_par);
                        i_source += i_par;
                    }
                }
                Some(l) => {
                    put(&mut x, th_ix, st.i_th);
                    i_source = st.i_th;
                    let v_bus = e - zc(th) * st.i_th;
                    put(&mut x, line_ix, (v_bus - v) / zc(l));
                    if let (true, Some(p)) = (par_on, d.parallel) {
                        put(&mut x, par_ix, (v_bus - v) / zc(p));
                    }
                }
            }
        }
        let e = if topo.thevenin {
            [e.re, e.im]
        } else {
            [0.0; 2]
        };
        let dc = st
            .units
            .iter()
            .zip(&fixed.dc)
            .map(|(u, p)| DcState::steady(p, u.p_conv()))
            .collect();
        let p_m = e[0] * i_source.re + e[1] * i_source.im;
        let run = Run {
            x,
            e,
            dc,
            pll: Pll::locked(dvpp_math::carg(st.v_pcc)),
            energy: Energies::default(),
            t0: None,
            topo,
            delta: 0.0,
            dw: 0.0,
            p_m,
            df_lag: 0.0,
            t_end: None,
            btopo: topo0,
            fault_last: Vec::new(),
        };
        for u in &self.units {
            s[u.m_clamped] = false;
        }
        self.write_outputs_bench(&fixed, &run, s);
        Ok(PlantState {
            fixed,
            run,
            cache: Default::default(),
            bench_cache: Default::default(),
        })
    }

    /// One step on the bench's circuit: the switchings due at `t`, then the exact step.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn step_bench(
        &self,
        fixed: &mut Fixed,
        run: &mut Run,
        cache: &mut BenchCache,
        s: &mut Store,
        t: f64,
        h: f64,
        t0: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        if let Some(bf) = fixed.bench.as_mut() {
            bf.bench.ensure_built();
        }
        let fixed = &*fixed;
        let bf = fixed.bench.as_ref().expect("the bench is configured");
        let (b, bf_zero) = (&bf.bench, bf.at_current_zero);
        let mut topo = fixed.bench_topology(t);
        let was = run.btopo;
        // Clearing at current zero: a branch stays until its current changed sign over the last
        // step (it is then within one step's change of zero).
        if let (true, Some((_, off))) = (bf_zero, fixed.bench.as_ref().and_then(|b| b.fault)) {
            if reached(t, Some(off)) && was.fault != 0 {
                let now = b.fault_branch_currents(&run.x);
                for (j, (i1, i0)) in now.iter().zip(&run.fault_last).enumerate() {
                    if was.fault >> j & 1 == 1 && i0 * i1 > 0.0 {
                        topo.fault |= 1 << j;
                    }
                }
            }
        }
        if topo != was {
            for (now, what) in [
                (topo.fault != 0 && was.fault == 0, "fault applied"),
                (
                    was.fault & !topo.fault != 0 && topo.fault != 0,
                    "a fault branch opened",
                ),
                (was.fault != 0 && topo.fault == 0, "fault cleared"),
                (
                    was.thevenin && !topo.thevenin,
                    "the source's breaker opened",
                ),
                (topo.parallel && !was.parallel, "parallel line in service"),
                (
                    was.parallel && !topo.parallel,
                    "parallel line out of service",
                ),
            ] {
                if now {
                    ctx.event(format!("t = {t}: {what}"));
                }
            }
            for j in 0..b.data.loads.len() {
                if topo.loads >> j & 1 == 1 && was.loads >> j & 1 == 0 {
                    ctx.event(format!("t = {t}: load {} connected", j + 1));
                }
            }
            run.energy.switching += b.switch(&was, &topo, &mut run.x);
        }
        if topo.thevenin {
            let (e, phase) = fixed.source_phase(t, h, t0, run.delta);
            let c = dvpp_math::cpolar(e, phase);
            run.e = [c.re, c.im];
        }
        let mut z = Self::augmented_bench(b, run);
        for (k, u) in self.units.iter().enumerate() {
            let m = u.modulation(s);
            let v_dc = run.dc[k].v(&fixed.dc[k]);
            let [a, bb] = clarke(m);
            let ix = b.unit(k).u;
            let m0 = (m[0] + m[1] + m[2]) / 3.0;
            for (i, x) in ix.iter().zip([a, bb, m0]) {
                if let Some(i) = i {
                    z[*i] = 1.5 * v_dc * x;
                }
            }
        }
        let d = cache.get(b, &topo, h).map_err(ModelError)?;
        self.account(fixed, run, s, &d.forms, &z, h, topo.thevenin)?;
        run.energy.fault +=
            crate::network::quadratic(&d.forms[b.data.units.len() + bench::FORM_FAULT], &z);
        let z1 = &d.phi * &z;
        let nx = run.x.len();
        run.x.copy_from_slice(z1.rows(0, nx).as_slice());
        run.e = [z1[b.e()], z1[b.e() + 1]];
        run.btopo = topo;
        run.fault_last = b.fault_branch_currents(&z.as_slice()[..nx]);
        let v = b.vpcc(&topo, &z1);
        run.meter(fixed, [v[0], v[1]], h);
        self.write_outputs_bench(fixed, run, s);
        Ok(())
    }

    fn augmented_bench(b: &Bench, run: &Run) -> DVector<f64> {
        let mut z = DVector::zeros(b.n());
        z.rows_mut(0, run.x.len()).copy_from_slice(&run.x);
        z[b.e()] = run.e[0];
        z[b.e() + 1] = run.e[1];
        z
    }

    /// Write every measurement of the bench's current state (phase quantities with their zero
    /// sequence).
    pub(crate) fn write_outputs_bench(&self, fixed: &Fixed, run: &Run, s: &mut Store) {
        let b = &fixed.bench.as_ref().expect("the bench is configured").bench;
        let x = &run.x;
        let z = Self::augmented_bench(b, run);
        let vp = b.vpcc(&run.btopo, &z);
        let get = |i: Option<usize>| i.map_or(0.0, |i| x[i]);
        let seq = |ix: [Option<usize>; 3]| [get(ix[0]), get(ix[1]), get(ix[2])];
        let abc = |v: [f64; 3]| inverse_clarke([v[0], v[1]]).map(|y| y + v[2]);
        let power = |v: [f64; 3], i: [f64; 3]| {
            (
                v[0] * i[0] + v[1] * i[1] + 2.0 * v[2] * i[2],
                v[1] * i[0] - v[0] * i[1],
            )
        };
        let (mut p_sum, mut q_sum) = (0.0, 0.0);
        for (k, u) in self.units.iter().enumerate() {
            let ix = b.unit(k);
            for (r, y) in u.v.iter().zip(abc(seq(ix.v_c))) {
                s[*r] = y;
            }
            for (r, y) in u.i.iter().zip(abc(seq(ix.i_f))) {
                s[*r] = y;
            }
            let ig = seq(ix.i_g);
            for (r, y) in u.ig.iter().zip(abc(ig)) {
                s[*r] = y;
            }
            s[u.v_dc] = run.dc[k].v(&fixed.dc[k]);
            s[u.i_src] = run.dc[k].i_src;
            let (p, q) = power(vp, ig);
            s[u.p] = p * b.c(k);
            s[u.q] = q * b.c(k);
            p_sum += s[u.p];
            q_sum += s[u.q];
        }
        s[self.pcc_p] = p_sum;
        s[self.pcc_q] = q_sum;
        s[self.pcc_f] = 1.0 + run.df_lag;
        for (j, l) in self.loads.iter().enumerate() {
            let [a, bb] = b.load(j);
            let (p, q) = power(vp, [x[a], x[bb], 0.0]);
            s[l.p] = p;
            s[l.q] = q;
        }
        if let Some(t) = &self.thevenin {
            let i = b.grid_current(x);
            for (r, y) in t.i.iter().zip(abc(i)) {
                s[*r] = y;
            }
            let (p, q) = power(vp, i);
            s[t.p] = p;
            s[t.q] = q;
            s[t.df] = run.dw;
        }
        for (r, y) in self.pcc_v.iter().zip(abc(vp)) {
            s[*r] = y;
        }
        s[self.pcc_mag] = dvpp_math::hypot(vp[0], vp[1]);
        for (r, y) in self.bench.fault_i.iter().zip(b.fault_current(x)) {
            s[*r] = y;
        }
        self.write_meters_and_energies(fixed, run, s, b.stored(x));
    }
}
