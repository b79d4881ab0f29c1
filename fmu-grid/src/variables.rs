//! The grid FMU's variables, declared in groups: the case's bases, each scheduled event's
//! overrides, each DER slot, the PCC, each machine, the power balance, the area's load, each
//! point of coupling and DVPP PCC, the R/X parameters of the `[mv]` lines, and the balanced
//! bus fault.

use crate::case::{self, Case, DvppPcc, Machine, MvLines, Poc};
use crate::{event_label, ports, DerSetpoint, Event, EventState, E_MAX, NO_LIMIT};
use fmi_export::{Boolean, Integer, Real, Spec, Variables};

/// Handles of one DER slot: its two inputs (θ, E or p_ref, q_ref), its converter's limits and
/// four outputs.
pub(crate) struct SlotVars {
    pub(crate) grid_forming: bool,
    pub(crate) a: Real,
    pub(crate) b: Real,
    pub(crate) i_max: Real,
    /// Grid-forming slots: the active-power range (the converter's dc budget).
    pub(crate) p_range: Option<(Real, Real)>,
    pub(crate) p: Real,
    pub(crate) q: Real,
    pub(crate) v: Real,
    pub(crate) v_angle: Real,
}

/// Handles of the parameters that override one scheduled event.
pub(crate) struct EventVars {
    pub(crate) enabled: Boolean,
    pub(crate) time: Real,
    /// Load steps only: ΔP, ΔQ in pu on S_base.
    pub(crate) size: Option<(Real, Real)>,
}

/// Handles of the R/X parameters of the case's `[mv]` lines.
pub(crate) struct RxVars {
    /// `mv.rx`.
    pub(crate) mv: Real,
    /// `mv.line[k].rx`, in the order of the `[mv]` group.
    pub(crate) lines: Vec<Real>,
}

/// Handles of one machine's outputs.
pub(crate) struct MachineVars {
    pub(crate) in_service: Boolean,
    pub(crate) omega: Real,
    pub(crate) p: Real,
    pub(crate) q: Real,
    pub(crate) pm: Real,
}

/// The case's bases, as fixed parameters (a master reads them; they cannot change).
pub(crate) fn declare_bases(v: &mut Variables, sb: f64, f_nom: f64) {
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
}

impl EventVars {
    /// The overrides of scheduled event `i` (from 0), `event[i+1].*`.
    pub(crate) fn declare(v: &mut Variables, i: usize, es: &EventState, sb: f64) -> Self {
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
        EventVars {
            enabled,
            time,
            size,
        }
    }
}

impl SlotVars {
    /// DER slot `k` (from 0) at `bus`, its inputs starting at the power-flow set point `init`.
    pub(crate) fn declare(v: &mut Variables, k: usize, init: &DerSetpoint, bus: u32) -> Self {
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
        SlotVars {
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
        }
    }
}

/// The PCC's outputs p, q, v, f.
pub(crate) fn declare_pcc(v: &mut Variables, case: &Case) -> [Real; 4] {
    let pcc_bus = case
        .pcc
        .as_ref()
        .map(|p| p.bus)
        .or(case.ders.first().map(|d| d.bus))
        .unwrap_or(case.buses[0].id);
    [
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
    ]
}

/// `energized`: whether a voltage source is left.
pub(crate) fn declare_energized(v: &mut Variables) -> Boolean {
    v.boolean(Spec::boolean_output(
        "energized",
        "a voltage source is in service (a machine or a grid-forming unit); false: the \
             network is de-energized, grid-following units alone cannot hold a voltage",
    ))
}

/// `coi.f`: the centre-of-inertia frequency.
pub(crate) fn declare_coi(v: &mut Variables) -> Real {
    v.real(Spec::output(
        "coi.f",
        "pu",
        "centre-of-inertia frequency, pu of f_nom: sum H_j omega_j / sum H_j over the \
             machines in service (pcc.f when none is)",
    ))
}

impl MachineVars {
    /// Machine `j` (from 0): its outputs `sg[j+1].*`.
    pub(crate) fn declare(v: &mut Variables, j: usize, m: &Machine) -> Self {
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
    }
}

/// The power balance `sys.p_gen`, `sys.p_load`, `sys.p_loss`, `sys.p_mismatch`.
pub(crate) fn declare_balance(v: &mut Variables) -> [Real; 4] {
    [
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
    ]
}

/// `sys.load_shed`.
pub(crate) fn declare_load_shed(v: &mut Variables) -> Real {
    v.real(Spec::output(
        "sys.load_shed",
        "1",
        "share of the power-flow point's load shed by the case's under-frequency load \
             shedding stages ([[ufls]]), 0 to 1",
    ))
}

/// `area.p_load`, `area.q_load` (cases with POCs).
pub(crate) fn declare_area_load(v: &mut Variables) -> [Real; 2] {
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
}

/// Point of coupling `k` (from 0): `poc[k+1].p/q/v/f`.
pub(crate) fn declare_poc(v: &mut Variables, k: usize, p: &Poc) -> [Real; 4] {
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
}

/// A DVPP PCC (`[[dvpp_pcc]]`): its p, q, v, f.
pub(crate) fn declare_dvpp_pcc(v: &mut Variables, p: &DvppPcc) -> [Real; 4] {
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
}

impl RxVars {
    /// `mv.rx` and `mv.line[k].rx` of the case's `[mv]` group.
    pub(crate) fn declare(v: &mut Variables, case: &Case, mv: &MvLines) -> Self {
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
    }
}

/// Handles of the balanced bus fault's parameters and outputs (`fault.*`).
pub(crate) struct FaultVars {
    pub(crate) bus: Integer,
    pub(crate) r: Real,
    pub(crate) x: Real,
    pub(crate) t: Real,
    pub(crate) duration: Real,
    pub(crate) on: Boolean,
    pub(crate) i: Real,
    pub(crate) v: Real,
}

impl FaultVars {
    /// The fault's parameters (named as the EMT plant's test bench names its fault's) and
    /// outputs; declared last, so that every other variable keeps its value reference.
    pub(crate) fn declare(v: &mut Variables, case: &Case) -> Self {
        let ids: Vec<String> = case.buses.iter().map(|b| b.id.to_string()).collect();
        let real = |v: &mut Variables, name: &str, start: f64, unit: &str, what: &str| {
            v.real(Spec::parameter(name, start, unit, what).min(0.0))
        };
        FaultVars {
            bus: v.integer(
                Spec::parameter(
                    "fault.bus",
                    0,
                    "",
                    &format!(
                        "balanced fault: the faulted bus, a bus id of the case ({}); 0 = no fault",
                        ids.join(", ")
                    ),
                )
                .min(0.0),
            ),
            r: real(
                v,
                "fault.R",
                0.0,
                "pu",
                "balanced fault: fault resistance per phase, on S_base",
            ),
            x: real(
                v,
                "fault.X",
                0.001,
                "pu",
                "balanced fault: fault reactance per phase, on S_base (fault.R and fault.X not both 0; 0.001 is a bolted fault)",
            ),
            t: real(
                v,
                "fault.t",
                1.0,
                "s",
                "balanced fault: the fault's shunt 1/(fault.R + j fault.X) enters the network solution at this time (the internal steps split there)",
            ),
            duration: real(
                v,
                "fault.duration",
                0.15,
                "s",
                "balanced fault: the fault is cleared at fault.t + fault.duration",
            ),
            on: v.boolean(Spec::boolean_output(
                "fault.on",
                "balanced fault: the fault is in the network",
            )),
            i: v.real(Spec::output(
                "fault.i",
                "pu",
                "balanced fault: magnitude of the fault current, on S_base (0 while the fault is off)",
            )),
            v: v.real(Spec::output(
                "fault.v",
                "pu",
                "balanced fault: voltage magnitude at the faulted bus (0 without a fault)",
            )),
        }
    }
}
