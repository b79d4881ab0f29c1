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
//! initialization).
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

pub use case::{Case, CaseError, DerKind, DerSlot, Event, LoadModel};
pub use config::{GridConfig, DEFAULT_CASE};
pub use events::{EventOverride, EventState};
pub use grid::{
    DerInput, DerOutput, DerSetpoint, Grid, GridError, MachineOutput, Outputs, PccOutput,
    SlotLimit, FREQUENCY_BAND, LOSS_OF_SYNCHRONISM_ANGLE,
};
pub use integration::{MAX_INTERNAL_STEP, MIN_INTERNAL_STEP, STEPS_PER_TIME_CONSTANT};
pub use network::CONST_POWER_V_MIN;
pub use powerflow::PowerFlow;

use fmi_export::{Boolean, Context, Model, ModelError, Real, Spec, Store, Variables};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Start value of the slot limit inputs, and the magnitude from which a limit input means none.
pub const NO_LIMIT: f64 = 1e6;

/// Highest internal voltage magnitude `der[k].E` a grid-forming slot accepts, pu: ten times the
/// nominal voltage, far beyond any converter (they run within about 0.8 to 1.2 pu), and low
/// enough that the slot's current and power stay far from overflowing.
pub const E_MAX: f64 = 10.0;

/// Handles of one DER slot: its two inputs (θ, E or p_ref, q_ref), its converter's limits and
/// four outputs.
#[derive(Clone, Serialize, Deserialize)]
struct SlotVars {
    grid_forming: bool,
    a: Real,
    b: Real,
    i_max: Real,
    /// Grid-forming slots: the active-power range (the converter's dc budget).
    p_range: Option<(Real, Real)>,
    p: Real,
    q: Real,
    v: Real,
    v_angle: Real,
}

/// Handles of the parameters that override one scheduled event.
#[derive(Clone, Serialize, Deserialize)]
struct EventVars {
    enabled: Boolean,
    time: Real,
    /// Load steps only: ΔP, ΔQ in pu on S_base.
    size: Option<(Real, Real)>,
}

/// Handles of the R/X parameters of the case's `[mv]` lines, and of what they last applied.
#[derive(Clone, Serialize, Deserialize)]
struct RxVars {
    /// `mv.rx`.
    mv: Real,
    /// `mv.line[k].rx`, in the order of the `[mv]` group.
    lines: Vec<Real>,
}

/// Handles of one machine's outputs.
#[derive(Clone, Serialize, Deserialize)]
struct MachineVars {
    in_service: Boolean,
    omega: Real,
    p: Real,
    q: Real,
    pm: Real,
}

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
        v.real(
            Spec::parameter(
                "S_base",
                sb,
                "MVA",
                "system base power (fixed by the case file)",
            )
            .range(sb, sb),
        );
        v.real(
            Spec::parameter(
                "f_nom",
                f_nom,
                "Hz",
                "nominal frequency (fixed by the case file)",
            )
            .range(f_nom, f_nom),
        );

        let mut events = Vec::new();
        for (i, es) in grid.events().iter().enumerate() {
            let name = |s: &str| format!("event[{}].{s}", i + 1);
            let what = event_label(&es.event);
            let enabled = v.boolean(Spec::parameter(
                &name("enabled"),
                true,
                "",
                &format!("event {}, {what}: false cancels it", i + 1),
            ));
            let time = v.real(
                Spec::parameter(
                    &name("time"),
                    es.event.time(),
                    "s",
                    &format!("event {}, {what}: time it happens", i + 1),
                )
                .min(0.0),
            );
            let size = match &es.event {
                Event::LoadStep { dp_mw, dq_mvar, .. } => Some((
                    v.real(Spec::parameter(
                        &name("dP"),
                        dp_mw / sb,
                        "pu",
                        &format!(
                            "event {}, {what}: added active load on S_base (positive = more load)",
                            i + 1
                        ),
                    )),
                    v.real(Spec::parameter(
                        &name("dQ"),
                        dq_mvar / sb,
                        "pu",
                        &format!("event {}, {what}: added reactive load on S_base", i + 1),
                    )),
                )),
                _ => None,
            };
            events.push(EventVars {
                enabled,
                time,
                size,
            });
        }

        let mut slots = Vec::new();
        let mut input_auto = Vec::new();
        for (k, init) in grid.der_initial().iter().enumerate() {
            input_auto.push(match *init {
                DerSetpoint::GridForming { theta0, e0 } => (theta0, e0),
                DerSetpoint::GridFollowing { p0, q0 } => (p0, q0),
            });
            let bus = case.ders[k].bus;
            let (grid_forming, a, b) = match *init {
                DerSetpoint::GridForming { theta0, e0 } => (
                    true,
                    v.real(Spec::input(
                        &ports::der_theta(k + 1),
                        theta0,
                        "rad",
                        "grid-forming slot: internal voltage angle behind the slot impedance",
                    )),
                    v.real(
                        Spec::input(
                            &ports::der_e(k + 1),
                            e0,
                            "pu",
                            "grid-forming slot: internal voltage magnitude behind the slot impedance",
                        )
                        .range(0.0, E_MAX),
                    ),
                ),
                DerSetpoint::GridFollowing { p0, q0 } => (
                    false,
                    v.real(Spec::input(
                        &ports::der_p_ref(k + 1),
                        p0,
                        "pu",
                        "grid-following slot: active power injected at its bus, on S_base",
                    )),
                    v.real(Spec::input(
                        &ports::der_q_ref(k + 1),
                        q0,
                        "pu",
                        "grid-following slot: reactive power injected at its bus, on S_base",
                    )),
                ),
            };
            let i_max = v.real(
                Spec::input(
                    &ports::der_i_max(k + 1),
                    NO_LIMIT,
                    "pu",
                    "current limit of the slot's converter, pu of the slot rating at 1 pu voltage, enforced in every network solution (1e6 and above: none)",
                )
                .min(0.0),
            );
            let p_range = grid_forming.then(|| {
                let p = |v: &mut Variables, name: String, start: f64, desc: &str| {
                    v.real(Spec::input(&name, start, "pu", desc))
                };
                (
                    p(
                        v,
                        ports::der_p_min(k + 1),
                        -NO_LIMIT,
                        "lowest active power the slot's converter takes in, on S_base (its dc link's budget; -1e6 and below: none)",
                    ),
                    p(
                        v,
                        ports::der_p_max(k + 1),
                        NO_LIMIT,
                        "highest active power the slot's converter gives, on S_base (its dc link's budget; 1e6 and above: none)",
                    ),
                )
            });
            slots.push(SlotVars {
                grid_forming,
                a,
                b,
                i_max,
                p_range,
                p: v.real(Spec::output(
                    &ports::der_p(k + 1),
                    "pu",
                    &format!("active power the slot injects into bus {bus}, on S_base"),
                )),
                q: v.real(Spec::output(
                    &ports::der_q(k + 1),
                    "pu",
                    &format!("reactive power the slot injects into bus {bus}, on S_base"),
                )),
                v: v.real(Spec::output(
                    &ports::der_v(k + 1),
                    "pu",
                    &format!("voltage magnitude at the slot's bus {bus}"),
                )),
                v_angle: v.real(Spec::output(
                    &ports::der_v_angle(k + 1),
                    "rad",
                    &format!(
                        "voltage angle at the slot's bus {bus}, frame rotating at f_nom, unwrapped"
                    ),
                )),
            });
        }

        let pcc_bus = case
            .pcc
            .as_ref()
            .map(|p| p.bus)
            .or(case.ders.first().map(|d| d.bus))
            .unwrap_or(case.buses[0].id);
        let pcc = [
            v.real(Spec::output(
                ports::PCC_P,
                "pu",
                "DVPP active power at the PCC (sum of its slots and branches), on S_base",
            )),
            v.real(Spec::output(
                ports::PCC_Q,
                "pu",
                "DVPP reactive power at the PCC (sum of its slots and branches), on S_base",
            )),
            v.real(Spec::output(
                ports::PCC_V,
                "pu",
                &format!("PCC voltage magnitude (bus {pcc_bus})"),
            )),
            v.real(Spec::output(
                ports::PCC_F,
                "pu",
                "PCC frequency, pu of f_nom: rate of change of the PCC voltage angle through \
                 s/(T_f s + 1), T_f from the case (default 0.02 s)",
            )),
        ];
        let energized = v.boolean(Spec::boolean_output(
            "energized",
            "a voltage source is in service (a machine or a grid-forming unit); false: the \
             network is de-energized, grid-following units alone cannot hold a voltage",
        ));
        let coi_f = v.real(Spec::output(
            "coi.f",
            "pu",
            "centre-of-inertia frequency, pu of f_nom: sum H_j omega_j / sum H_j over the \
             machines in service (pcc.f when none is)",
        ));
        let machines = case
            .machines
            .iter()
            .enumerate()
            .map(|(j, m)| {
                let name = |s: &str| format!("sg[{}].{s}", j + 1);
                let label = m
                    .name
                    .clone()
                    .unwrap_or_else(|| format!("machine at bus {}", m.bus));
                MachineVars {
                    in_service: v.boolean(Spec::boolean_output(
                        &name("in_service"),
                        &format!(
                            "{label}: connected to the grid (false after a generator trip; \
                             coi.f and the sys.* totals count connected machines only)"
                        ),
                    )),
                    omega: v.real(Spec::output(
                        &name("omega"),
                        "pu",
                        &format!(
                            "{label}: rotor speed, pu of f_nom (after a trip: the isolated \
                             unit's own speed under its governor)"
                        ),
                    )),
                    p: v.real(Spec::output(
                        &name("p"),
                        "pu",
                        &format!("{label}: electrical active power at its terminal, on S_base"),
                    )),
                    q: v.real(Spec::output(
                        &name("q"),
                        "pu",
                        &format!("{label}: reactive power at its terminal, on S_base"),
                    )),
                    pm: v.real(Spec::output(
                        &name("pm"),
                        "pu",
                        &format!("{label}: mechanical power from its turbine, on S_base"),
                    )),
                }
            })
            .collect();
        let balance = [
            v.real(Spec::output(
                "sys.p_gen",
                "pu",
                "total generation: machine terminal powers + DER slot injections, on S_base",
            )),
            v.real(Spec::output(
                "sys.p_load",
                "pu",
                "total load: loads, event loads and shunt conductances at their present voltage, \
                 on S_base",
            )),
            v.real(Spec::output(
                "sys.p_loss",
                "pu",
                "series losses of lines and transformers, on S_base",
            )),
            v.real(Spec::output(
                "sys.p_mismatch",
                "pu",
                "power balance sys.p_gen - sys.p_load - sys.p_loss, on S_base (zero up to the \
                 network solver tolerance)",
            )),
        ];
        let load_shed = v.real(Spec::output(
            "sys.load_shed",
            "1",
            "share of the power-flow point's load shed by the case's under-frequency load \
             shedding stages ([[ufls]]), 0 to 1",
        ));
        let area_load = (!case.pocs.is_empty()).then(|| {
            [
                v.real(Spec::output(
                    ports::AREA_P_LOAD,
                    "pu",
                    "active power the loads inside the area behind the points of coupling draw, on S_base (an operator adds its change to the POC powers: a load step inside the area is not the DVPP's response)",
                )),
                v.real(Spec::output(
                    ports::AREA_Q_LOAD,
                    "pu",
                    "reactive power the loads inside the area behind the points of coupling draw, on S_base",
                )),
            ]
        });
        let pocs = case
            .pocs
            .iter()
            .enumerate()
            .map(|(k, p)| {
                let label = p
                    .name
                    .clone()
                    .unwrap_or_else(|| format!("point of coupling {}", k + 1));
                let bus = p.bus;
                let through = p.branches.join(", ");
                let at = match p.side {
                    case::PocSide::Grid => format!("at bus {bus}"),
                    case::PocSide::Area => "at their area-side ends".to_string(),
                };
                [
                    v.real(Spec::output(
                        &ports::poc_p(k + 1),
                        "pu",
                        &format!(
                            "{label}: active power the area sends through {through} towards bus {bus}, measured {at} (positive: into the grid, as pcc.p), on S_base"
                        ),
                    )),
                    v.real(Spec::output(
                        &ports::poc_q(k + 1),
                        "pu",
                        &format!(
                            "{label}: reactive power the area sends through {through} towards bus {bus}, measured {at}, on S_base"
                        ),
                    )),
                    v.real(Spec::output(
                        &ports::poc_v(k + 1),
                        "pu",
                        &format!("{label}: voltage magnitude at bus {bus}"),
                    )),
                    v.real(Spec::output(
                        &ports::poc_f(k + 1),
                        "pu",
                        &format!(
                            "{label}: frequency at bus {bus}, pu of f_nom, measured as pcc.f (T_f = {} s)",
                            p.f_filter_t
                        ),
                    )),
                ]
            })
            .collect();
        let dvpp_pccs = case
            .dvpp_pccs
            .iter()
            .map(|p| {
                let (name, bus) = (&p.name, p.bus);
                let slots = p
                    .slots
                    .iter()
                    .map(|k| k.to_string())
                    .collect::<Vec<_>>()
                    .join(", ");
                [
                    v.real(Spec::output(
                        &ports::dvpp_pcc_p(name),
                        "pu",
                        &format!("DVPP {name}: active power of its slots {slots} at its PCC, on S_base"),
                    )),
                    v.real(Spec::output(
                        &ports::dvpp_pcc_q(name),
                        "pu",
                        &format!("DVPP {name}: reactive power of its slots {slots} at its PCC, on S_base"),
                    )),
                    v.real(Spec::output(
                        &ports::dvpp_pcc_v(name),
                        "pu",
                        &format!("DVPP {name}: voltage magnitude at its PCC (bus {bus})"),
                    )),
                    v.real(Spec::output(
                        &ports::dvpp_pcc_f(name),
                        "pu",
                        &format!(
                            "DVPP {name}: frequency at its PCC (bus {bus}), pu of f_nom, measured as pcc.f (T_f = {} s)",
                            p.f_filter_t
                        ),
                    )),
                ]
            })
            .collect();
        let rx = case.mv.as_ref().map(|mv| {
            let rx_max = case::RX_MAX;
            let mv_rx = v.real(
                Spec::parameter(
                    ports::MV_RX,
                    mv.rx,
                    "",
                    "R/X ratio of every line of the case's [mv] group that has no ratio of its own (mv.line[k].rx = 0), each line keeping |r + jx|; the power flow is re-solved at initialization",
                )
                .range(0.0, rx_max),
            );
            let lines = case
                .mv_line_indices()
                .into_iter()
                .enumerate()
                .map(|(k, i)| {
                    let l = &case.lines[i];
                    v.real(
                        Spec::parameter(
                            &ports::mv_line_rx(k + 1),
                            l.rx.unwrap_or(0.0),
                            "",
                            &format!(
                                "R/X ratio of line {} ({}-{}), keeping its |r + jx|; 0: mv.rx",
                                case.line_name(l),
                                l.from,
                                l.to
                            ),
                        )
                        .range(0.0, rx_max),
                    )
                })
                .collect();
            RxVars { mv: mv_rx, lines }
        });
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
