//! The connections of a system: the wiring rules per DER and per DVPP.

use der_model::ports as der;
use grid_model::ports as grid;
use operator_model::ports as op;
use operator_model::Role;

use super::job::DerUnit;
use super::{GRID, OPERATOR};

/// One connection: from (component, output) to (component, input).
pub(super) type Wire = ((String, String), (String, String));

fn wire(from: &str, output: &str, to: &str, input: &str) -> Wire {
    ((from.into(), output.into()), (to.into(), input.into()))
}

/// A wiring rule: the connections it makes for one DER, `source` the component that measures
/// its slot (the grid, or the EMT plant, whose units' ports carry the grid slots' names).
type DerRule = fn(&DerUnit, &str) -> Vec<Wire>;

/// Grid → DER: the measurements at the DER's slot.
fn slot_measurements(d: &DerUnit, _: &str) -> Vec<Wire> {
    let (n, k) = (d.unit.name.as_str(), d.slot);
    vec![
        wire(GRID, &grid::der_p(k), n, der::P),
        wire(GRID, &grid::der_q(k), n, der::Q),
        wire(GRID, &grid::der_v(k), n, der::V),
        wire(GRID, &grid::der_v_angle(k), n, der::V_ANGLE),
    ]
}

/// DER → grid: what drives its slot (`E∠θ` grid-forming, `p_ref`, `q_ref` grid-following) and
/// its converter's limits.
fn slot_drive(d: &DerUnit, _: &str) -> Vec<Wire> {
    let (n, k) = (d.unit.name.as_str(), d.slot);
    // The converter's limits go with its drive: the slot's output stage holds them.
    if d.forming {
        vec![
            wire(n, der::THETA, GRID, &grid::der_theta(k)),
            wire(n, der::E, GRID, &grid::der_e(k)),
            wire(n, der::I_LIMIT, GRID, &grid::der_i_max(k)),
            wire(n, der::P_MIN, GRID, &grid::der_p_min(k)),
            wire(n, der::P_MAX, GRID, &grid::der_p_max(k)),
        ]
    } else {
        vec![
            wire(n, der::P_REF, GRID, &grid::der_p_ref(k)),
            wire(n, der::Q_REF, GRID, &grid::der_q_ref(k)),
            wire(n, der::I_LIMIT, GRID, &grid::der_i_max(k)),
        ]
    }
}

/// DER and grid → its operator: the DER's availability and its slot's power.
fn operator_measurements(d: &DerUnit, source: &str) -> Vec<Wire> {
    let (n, k, s, o) = (d.unit.name.as_str(), d.entry, d.slot, d.operator.as_str());
    vec![
        wire(n, der::P_AVAIL, o, &op::der_p_avail(k)),
        wire(n, der::P_SET, o, &op::der_p_set(k)),
        wire(source, &grid::der_p(s), o, &op::der_p(k)),
        wire(source, &grid::der_q(s), o, &op::der_q(k)),
    ]
}

/// EMT plant ↔ EMT-level DER: the instantaneous measurements and the modulation.
fn plant_unit(d: &DerUnit, _: &str) -> Vec<Wire> {
    super::emt::unit_wiring(&d.unit.name, d.slot)
}

/// Its operator → DER: the dc gains its role takes.
fn operator_gains(d: &DerUnit, _: &str) -> Vec<Wire> {
    let (n, k, o) = (d.unit.name.as_str(), d.entry, d.operator.as_str());
    let mut wires = vec![wire(o, &op::der_mu_q(k), n, der::MU_Q)];
    match d.role {
        Role::LowPass => wires.push(wire(o, &op::der_mu_p(k), n, der::MU_P)),
        Role::Complement => wires.extend(
            d.closes
                .iter()
                .enumerate()
                .map(|(i, &j)| wire(o, &op::der_mu_p_lpf(k, j), n, &der::mu_p_lpf(i + 1))),
        ),
        Role::HighPass | Role::BandPass => {}
    }
    wires
}

/// Grid → operator: the PCC measurements (`dvpp`: a named DVPP's own PCC, `pcc_<name>.*`).
fn pcc_measurements(source: &str, dvpp: Option<&str>, operator: &str) -> Vec<Wire> {
    let from: [String; 4] = match dvpp {
        None => [grid::PCC_P, grid::PCC_Q, grid::PCC_F, grid::PCC_V].map(String::from),
        Some(n) => [
            grid::dvpp_pcc_p(n),
            grid::dvpp_pcc_q(n),
            grid::dvpp_pcc_f(n),
            grid::dvpp_pcc_v(n),
        ],
    };
    from.iter()
        .zip([op::PCC_P, op::PCC_Q, op::PCC_F, op::PCC_V])
        .map(|(from, to)| wire(source, from, operator, to))
        .collect()
}

/// Grid → operator: each point of coupling's measurements.
fn poc_measurements(pocs: usize) -> Vec<Wire> {
    (1..=pocs)
        .flat_map(|k| {
            [
                (grid::poc_p(k), op::poc_p(k)),
                (grid::poc_q(k), op::poc_q(k)),
                (grid::poc_f(k), op::poc_f(k)),
                (grid::poc_v(k), op::poc_v(k)),
            ]
        })
        .chain(if pocs > 0 {
            vec![
                (grid::AREA_P_LOAD.to_string(), op::AREA_P_LOAD.to_string()),
                (grid::AREA_Q_LOAD.to_string(), op::AREA_Q_LOAD.to_string()),
            ]
        } else {
            Vec::new()
        })
        .map(|(from, to)| wire(GRID, &from, OPERATOR, &to))
        .collect()
}

/// Rules per DER of every phasor system, in the order of the connections.
const DER_RULES: &[DerRule] = &[slot_measurements, slot_drive];
/// Rules per DER of an EMT-level system.
const EMT_RULES: &[DerRule] = &[plant_unit];
/// Rules per DER of a system with an operator, after those of `DER_RULES`.
const OPERATOR_RULES: &[DerRule] = &[operator_measurements, operator_gains];

/// Every connection of the system: `operators` are the DVPPs' (name, operator component) if
/// the system has operators, `pocs` the grid's points of coupling; `source` measures the slots
/// (the grid, or the EMT plant).
pub(super) fn wiring(
    ders: &[DerUnit],
    operators: &[(Option<String>, String)],
    pocs: usize,
    source: &str,
) -> Vec<Wire> {
    let per_der = |rules: &[DerRule]| -> Vec<Wire> {
        ders.iter()
            .flat_map(|d| rules.iter().flat_map(move |rule| rule(d, source)))
            .collect()
    };
    let emt = ders.iter().any(|d| d.emt);
    let mut wires = per_der(if emt { EMT_RULES } else { DER_RULES });
    if !operators.is_empty() {
        wires.extend(per_der(OPERATOR_RULES));
        for (name, component) in operators {
            wires.extend(pcc_measurements(source, name.as_deref(), component));
        }
        wires.extend(poc_measurements(pocs));
    }
    wires
}
