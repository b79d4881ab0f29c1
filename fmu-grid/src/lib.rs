//! Reduced grid model (the `dvpp_grid` FMU; its binary is `fmu/`): a phasor (RMS) power-system
//! model built from a case file, with DER slots.
//!
//! The modules form layers, each importing only from those below it:
//! * leaves: [`numerics`] (complex type, solver constants, shared helpers) and [`error`]
//!   ([`CaseError`], [`GridError`]);
//! * models: [`exciter`], [`governor`], [`machine`] (the dynamic models), [`der`] (DER slots);
//! * [`case`] (the TOML case format, each element validating itself), [`powerflow`]
//!   (Newton–Raphson power flow);
//! * solvers: [`network`] (the admittance matrix, its factorization and the network solve, a
//!   type of its own) and [`integration`] (internal step, RK4 over a DAE trait);
//! * [`grid`] (the model: its construction, inputs, dynamics, outputs, [`events`] and
//!   [`snapshot`]), then [`analysis`] (load-step figures), [`config`] and [`ports`].
//!
//! This file wraps [`Grid`] as an FMI model ([`GridFmu`]; `fmu/` exports it as the FMU).
//!
//! `[model]` in `resources/config.toml` selects the case: `case = "<built-in name>"` or
//! `case_file = "<file in resources/>"` (default: the built-in `ieee9_dvpp`), and may append
//! events (`[[model.event]]`, same tables as a case file's `[[event]]`). The variables follow
//! the case: per DER slot k its inputs (`der[k].theta`, `der[k].E` grid-forming;
//! `der[k].p_ref`, `der[k].q_ref` grid-following; starts = the power-flow set points, so a run
//! with untouched inputs is a flat start) and outputs, per machine j its speed and powers, per
//! event i its override parameters, and the PCC, COI and power-balance outputs; per point of
//! coupling k (case `[[poc]]`) the outputs `poc[k].p/q/v/f`, and for a case with an `[mv]` line
//! group the R/X parameters `mv.rx`, `mv.line[k].rx` (the power flow is re-solved with them at
//! initialization). Every case has the balanced bus fault `fault.bus/R/X/t/duration` (a shunt
//! `1/(R + jX)` at the bus over the interval; `fault.bus` = 0, the default, is none) and its
//! outputs `fault.on/i/v`.
//!
//! In initialization mode the outputs are the power-flow operating point (they depend on no
//! input, so a master can initialize the DER FMUs from them); in step mode they are computed
//! by `fmi2DoStep` with the inputs held over the step (no direct feedthrough).

pub mod analysis;
pub mod case;
pub mod config;
pub mod der;
pub mod error;
pub mod exciter;
pub mod governor;
pub mod grid;
pub use grid::{events, snapshot};
pub mod integration;
pub mod machine;
pub mod network;
pub mod numerics;
pub mod ports;
pub mod powerflow;
pub mod pss;
mod variables;

pub use case::{Case, CaseError, DerKind, DerSlot, Event, LoadModel};
pub use config::{GridConfig, DEFAULT_CASE};
pub use events::{EventOverride, EventState};
pub use grid::{BusFault, FaultOutput};
pub use grid::{
    DerInput, DerOutput, DerSetpoint, Grid, GridError, MachineOutput, Outputs, PccOutput,
    SlotLimit, FREQUENCY_BAND, LOSS_OF_SYNCHRONISM_ANGLE,
};
pub use integration::{MAX_INTERNAL_STEP, MIN_INTERNAL_STEP, STEPS_PER_TIME_CONSTANT};
pub use network::CONST_POWER_V_MIN;
pub use powerflow::PowerFlow;

use fmi_export::{Boolean, Context, Model, ModelError, Real, Store, Variables};
use serde::{Deserialize, Serialize};
use std::path::Path;
use variables::{EventVars, FaultVars, MachineVars, RxVars, SlotVars};

/// Start value of the slot limit inputs, and the magnitude from which a limit input means none.
pub const NO_LIMIT: f64 = 1e6;

/// Highest internal voltage magnitude `der[k].E` a grid-forming slot accepts, pu: ten times the
/// nominal voltage, far beyond any converter (they run within about 0.8 to 1.2 pu), and low
/// enough that the slot's current and power stay far from overflowing.
pub const E_MAX: f64 = 10.0;

/// The grid FMU: the handles of its variables and the grid its configuration builds.
pub struct GridFmu {
    /// The grid as the case file builds it: what initialization starts from.
    built: Grid,
    /// The inputs' start values (θ, E or p_ref, q_ref per slot): see [`GridState::input_auto`].
    input_start: Vec<(f64, f64)>,
    slots: Vec<SlotVars>,
    events: Vec<EventVars>,
    machines: Vec<MachineVars>,
    pcc: [Real; 4],
    /// Per point of coupling: p, q, v, f.
    pocs: Vec<[Real; 4]>,
    /// Per DVPP PCC (`[[dvpp_pcc]]`): p, q, v, f.
    dvpp_pccs: Vec<[Real; 4]>,
    /// `area.p_load`, `area.q_load` (cases with POCs).
    area_load: Option<[Real; 2]>,
    /// The R/X parameters (cases with an `[mv]` table).
    rx: Option<RxVars>,
    coi_f: Real,
    /// `energized`: a voltage source is left.
    energized: Boolean,
    /// Generation, load, losses and generation − load − losses.
    balance: [Real; 4],
    load_shed: Real,
    /// The balanced bus fault's parameters and outputs.
    fault: FaultVars,
}

/// The grid FMU's running state: the grid being simulated.
#[derive(Clone, Serialize, Deserialize)]
pub struct GridState {
    grid: Grid,
    /// The clock was aligned with the master's start time (first `do_step`).
    started: bool,
    /// Per slot, the input values (θ, E or p_ref, q_ref) the FMU itself put in the store (the
    /// start values, or the set points of a power flow re-solved for new R/X parameters): an
    /// input still holding them has not been set by the master.
    input_auto: Vec<(f64, f64)>,
}

impl GridState {
    /// The grid being simulated.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }
}

/// A Boolean output (discrete; Real outputs come from [`Spec::output`]).
fn event_label(e: &Event) -> String {
    match e {
        Event::LoadStep { bus, .. } => format!("load step at bus {bus}"),
        Event::GeneratorTrip { machine, .. } => format!("trip of machine {machine}"),
        Event::LineTrip { branch, .. } => format!("trip of branch {branch}"),
    }
}

impl GridFmu {
    /// The grid as the case file builds it, before initialization.
    pub fn built(&self) -> &Grid {
        &self.built
    }

    fn write_outputs(&self, grid: &Grid, s: &mut Store) {
        let o = grid.outputs();
        for (vars, d) in self.slots.iter().zip(&o.der) {
            s[vars.p] = d.p;
            s[vars.q] = d.q;
            s[vars.v] = d.v;
            s[vars.v_angle] = d.v_angle;
        }
        for (vars, m) in self.machines.iter().zip(&o.sg) {
            s[vars.in_service] = m.in_service;
            s[vars.omega] = m.omega;
            s[vars.p] = m.p;
            s[vars.q] = m.q;
            s[vars.pm] = m.pm;
        }
        let [p, q, v, f] = self.pcc;
        s[p] = o.pcc.p;
        s[q] = o.pcc.q;
        s[v] = o.pcc.v;
        s[f] = o.pcc.f;
        for (vars, p) in self
            .pocs
            .iter()
            .zip(&o.poc)
            .chain(self.dvpp_pccs.iter().zip(&o.dvpp_pcc))
        {
            let [vp, vq, vv, vf] = *vars;
            s[vp] = p.p;
            s[vq] = p.q;
            s[vv] = p.v;
            s[vf] = p.f;
        }
        if let Some([p, q]) = self.area_load {
            s[p] = o.area_p_load;
            s[q] = o.area_q_load;
        }
        s[self.coi_f] = o.coi_f;
        s[self.energized] = grid.energized();
        let [gen, load, loss, mismatch] = self.balance;
        s[gen] = o.gen_p;
        s[load] = o.load_p;
        s[loss] = o.loss_p;
        s[mismatch] = o.balance_p;
        s[self.load_shed] = grid.load_shed();
        let fault = grid.fault_output();
        s[self.fault.on] = fault.on;
        s[self.fault.i] = fault.i;
        s[self.fault.v] = fault.v;
    }

    /// The bus fault the `fault.*` parameters configure (None: `fault.bus` = 0).
    fn fault_parameters(&self, s: &Store) -> Result<Option<BusFault>, ModelError> {
        let f = &self.fault;
        let bus = s[f.bus];
        if bus == 0 {
            return Ok(None);
        }
        let bus = u32::try_from(bus).map_err(|_| {
            ModelError(format!(
                "parameter 'fault.bus' = {bus}: need a bus id of the case, or 0 for no fault"
            ))
        })?;
        Ok(Some(BusFault {
            bus,
            r: s[f.r],
            x: s[f.x],
            t: s[f.t],
            duration: s[f.duration],
        }))
    }
}

impl GridFmu {
    /// Apply the R/X parameters: when they differ from the grid's case, rebuild the grid (power
    /// flow and initialization) from the case with the new ratios, and move the inputs the
    /// master has not set to the new set points.
    fn apply_rx(&self, st: &mut GridState, s: &mut Store) -> Result<(), ModelError> {
        let Some(rx) = &self.rx else {
            return Ok(());
        };
        let mut case = st.grid.case().clone();
        let lines = case.mv_line_indices();
        if let Some(mv) = case.mv.as_mut() {
            mv.rx = s[rx.mv];
        }
        for (&i, &vr) in lines.iter().zip(&rx.lines) {
            let v = s[vr];
            case.lines[i].rx = (v > 0.0).then_some(v);
        }
        if case == *st.grid.case() {
            return Ok(());
        }
        let grid = Grid::new(&case).map_err(|e| {
            ModelError(format!(
                "R/X parameters ({} = {}): {e}",
                ports::MV_RX,
                s[rx.mv]
            ))
        })?;
        st.grid = grid;
        for ((vars, auto), init) in self
            .slots
            .iter()
            .zip(&mut st.input_auto)
            .zip(st.grid.der_initial())
        {
            if (s[vars.a], s[vars.b]) != *auto {
                continue;
            }
            let new = match init {
                DerSetpoint::GridForming { theta0, e0 } => (theta0, e0),
                DerSetpoint::GridFollowing { p0, q0 } => (p0, q0),
            };
            s[vars.a] = new.0;
            s[vars.b] = new.1;
            *auto = new;
        }
        Ok(())
    }
}

impl Model for GridFmu {
    type Config = GridConfig;
    type State = GridState;
    const IDENTIFIER: &'static str = "dvpp_grid";
    const NAME: &'static str = "DVPP reduced grid";
    const DESCRIPTION: &'static str =
        "Phasor power-system model from a case file: power flow, sub-transient, two-axis or classical \
         machines with governors, exciters and stabilizers, grid-forming and grid-following DER \
         slots, scheduled events";
    /// Phasor steps are 1e-4 to 1e-2 s; 1 s (100 times the longest) is 1000 to 20000 internal
    /// integration steps, milliseconds of work (1e4 s took 73 s).
    const MAX_STEP: f64 = 1.0;

    fn declare(
        config: &GridConfig,
        resources: Option<&Path>,
        v: &mut Variables,
    ) -> Result<Self, String> {
        let case = config.load_case(resources)?;
        let grid = Grid::new(&case).map_err(|e| format!("case {}: {e}", case.name))?;
        let (sb, f_nom) = (case.base_mva, case.f_nom);
        variables::declare_bases(v, sb, f_nom);
        let events = (grid.events().iter().enumerate())
            .map(|(i, es)| EventVars::declare(v, i, es, sb))
            .collect();
        let inits = grid.der_initial();
        let slots = (inits.iter().enumerate())
            .map(|(k, init)| SlotVars::declare(v, k, init, case.ders[k].bus))
            .collect();
        let input_auto = inits
            .iter()
            .map(|init| match *init {
                DerSetpoint::GridForming { theta0, e0 } => (theta0, e0),
                DerSetpoint::GridFollowing { p0, q0 } => (p0, q0),
            })
            .collect();
        let pcc = variables::declare_pcc(v, &case);
        let energized = variables::declare_energized(v);
        let coi_f = variables::declare_coi(v);
        let machines = (case.machines.iter().enumerate())
            .map(|(j, m)| MachineVars::declare(v, j, m))
            .collect();
        let balance = variables::declare_balance(v);
        let load_shed = variables::declare_load_shed(v);
        let area_load = (!case.pocs.is_empty()).then(|| variables::declare_area_load(v));
        let pocs = (case.pocs.iter().enumerate())
            .map(|(k, p)| variables::declare_poc(v, k, p))
            .collect();
        let dvpp_pccs = (case.dvpp_pccs.iter())
            .map(|p| variables::declare_dvpp_pcc(v, p))
            .collect();
        let rx = case.mv.as_ref().map(|mv| RxVars::declare(v, &case, mv));
        let fault = FaultVars::declare(v, &case);
        Ok(GridFmu {
            built: grid,
            input_start: input_auto,
            slots,
            events,
            machines,
            pcc,
            pocs,
            dvpp_pccs,
            area_load,
            rx,
            coi_f,
            energized,
            balance,
            load_shed,
            fault,
        })
    }

    fn initialize(
        &self,
        previous: Option<&GridState>,
        s: &mut Store,
        ctx: &mut Context,
    ) -> Result<GridState, ModelError> {
        let mut st = match previous {
            Some(st) => st.clone(),
            None => {
                if let Some(note) = self.built.internal_step_note() {
                    ctx.warn(note);
                }
                GridState {
                    grid: self.built.clone(),
                    started: false,
                    input_auto: self.input_start.clone(),
                }
            }
        };
        self.apply_rx(&mut st, s)?;
        let sb = st.grid.case().base_mva;
        for (i, e) in self.events.iter().enumerate() {
            let ov = EventOverride {
                enabled: Some(s[e.enabled]),
                time: Some(s[e.time]),
                dp_mw: e.size.map(|(p, _)| s[p] * sb),
                dq_mvar: e.size.map(|(_, q)| s[q] * sb),
            };
            st.grid
                .set_event_override(i, ov)
                .map_err(|err| ModelError(err.to_string()))?;
        }
        let fault = self.fault_parameters(s)?;
        if fault != st.grid.fault() {
            st.grid
                .set_fault(fault)
                .map_err(|err| ModelError(err.to_string()))?;
        }
        self.write_outputs(&st.grid, s);
        Ok(st)
    }

    fn do_step(
        &self,
        st: &mut GridState,
        s: &mut Store,
        t: f64,
        h: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        if !st.started {
            st.grid.start_at(t).map_err(|e| ModelError(e.to_string()))?;
            st.started = true;
        }
        for (k, vars) in self.slots.iter().enumerate() {
            let (a, b) = (s[vars.a], s[vars.b]);
            let input = if vars.grid_forming {
                DerInput::GridForming { theta: a, e: b }
            } else {
                DerInput::GridFollowing { p_ref: a, q_ref: b }
            };
            st.grid
                .set_der_input_deferred(k, input)
                .map_err(|e| ModelError(e.to_string()))?;
            let none = |x: f64, inf: f64| if x.abs() >= NO_LIMIT { inf } else { x };
            let (p_min, p_max) = vars
                .p_range
                .map_or((-NO_LIMIT, NO_LIMIT), |(lo, hi)| (s[lo], s[hi]));
            let limit = SlotLimit {
                i_max: none(s[vars.i_max], f64::INFINITY),
                p_min: none(p_min, f64::NEG_INFINITY),
                p_max: none(p_max, f64::INFINITY),
            };
            st.grid
                .set_der_limit(k, limit)
                .map_err(|e| ModelError(format!("slot {}: {e}", k + 1)))?;
        }
        let energized = st.grid.energized();
        st.grid
            .step(t, h)
            .map_err(|e| ModelError(format!("grid step from t = {t} s: {e}")))?;
        if energized && !st.grid.energized() {
            ctx.warn(format!(
                "in the step from t = {t} s: no voltage source is left (no machine in service, no grid-forming \
                 unit): the grid-following units have no voltage to synchronize to and lose \
                 synchronism; the network is de-energized (blackout)"
            ));
        }
        self.write_outputs(&st.grid, s);
        Ok(())
    }
}

#[cfg(test)]
mod tests;
