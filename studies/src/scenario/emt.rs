//! EMT-level systems (a scenario with `[emt]`): the EMT plant converted from the phasor grid case (one data source), the DERs as EMT-level controllers, and their wiring.
//!
//! With a grid case, the case must be a Thevenin equivalent: one classical machine at the slack
//! bus, one line from it to the PCC, and every DER slot, load and load step at the PCC. The
//! plant then gets the machine and the line as its Thevenin source (the machine's inertia and
//! damping swing the source's angle as they swing the machine's), the loads as series R-L
//! branches of the impedance they have at the power-flow voltage (the phasor grid's constant
//! impedance), each load step as a load switched on at its time, and each slot as a converter
//! starting at the slot's power-flow injection. Without a grid case, `[emt] plant` is the
//! plant's own `[model]` (a built-in case such as `island`, or units and loads listed) and the
//! system has no operator.

use serde::Deserialize;
use toml::{Table, Value};

use super::job::{DerUnit, GridUnit, Job, Slot, Unit};
use super::wiring::Wire;
use super::{real, start_of};
use emt_plant_model::config::PlantConfig;

/// The plant's component name (the grid's role in a phasor system).
pub(super) const PLANT: &str = "plant";

/// `[emt]`: the system runs at EMT level.
#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct EmtSpec {
    /// The plant's `[model]` when the scenario has no grid case (e.g. `case = "island"`).
    pub plant: Option<Table>,
    /// Start values of plant variables.
    #[serde(default)]
    pub start: Table,
}

/// A plant unit's rating and the primary-source lag of the DER controlling it.
pub(super) struct UnitData {
    pub(super) name: String,
    pub(super) s_rated: f64,
    pub(super) tau_dc: f64,
}

/// The plant's `[model]` and start values from a Thevenin-equivalent grid case at its power-flow
/// point `pf` (see the module docs).
pub(super) fn plant_from_case(
    case: &grid_model::Case,
    pf: &grid_model::Outputs,
    units: &[UnitData],
) -> Result<(Table, Table), String> {
    let not = |why: &str| {
        Err(format!(
            "grid case '{}': {why}; an EMT plant is one PCC behind a Thevenin equivalent (one classical machine at the slack bus, one line to the PCC)",
            case.name
        ))
    };
    let [machine] = case.machines.as_slice() else {
        return not("not exactly one machine");
    };
    if machine.model != grid_model::case::MachineModel::Classical
        || machine.governor.is_some()
        || machine.exciter.is_some()
    {
        return not("the machine is not a classical one without governor and exciter");
    }
    let [line] = case.lines.as_slice() else {
        return not("not exactly one line");
    };
    if !case.transformers.is_empty() || !case.shunts.is_empty() || line.b != 0.0 {
        return not("transformers, shunts or line charging");
    }
    let pcc = if line.from == machine.bus {
        line.to
    } else if line.to == machine.bus {
        line.from
    } else {
        return not("the line does not start at the machine's bus");
    };
    if case.ders.iter().any(|d| d.bus != pcc) || case.loads.iter().any(|l| l.bus != pcc) {
        return not("a DER slot or load is not at the PCC");
    }
    if case.ders.len() != units.len() || pf.der.len() != units.len() {
        return not("the scenario's DERs are not the case's slots");
    }
    let base = case.base_mva;
    // The machine's data on the system base.
    let to_sys = match machine.base {
        grid_model::case::ParamBase::Machine => base / machine.rating_mva,
        grid_model::case::ParamBase::System => 1.0,
    };
    let (r_th, x_th) = (line.r + machine.ra * to_sys, line.x + machine.xd_p * to_sys);
    let (h_th, d_th) = (machine.h / to_sys, machine.d / to_sys);
    // The source's EMF from the power-flow point: the PCC voltage plus the drop its current
    // makes in the Thevenin impedance (the loads draw their power-flow P + jQ there).
    let v = pf.der[0].v;
    let u = (
        dvpp_math::cos(pf.der[0].v_angle),
        dvpp_math::sin(pf.der[0].v_angle),
    );
    let (mut p_th, mut q_th) = (0.0, 0.0);
    for l in &case.loads {
        p_th += l.p_mw / base;
        q_th += l.q_mvar / base;
    }
    for d in &pf.der {
        p_th -= d.p;
        q_th -= d.q;
    }
    // I = conj(S / V), V = v u.
    let (i_re, i_im) = ((p_th * u.0 + q_th * u.1) / v, (p_th * u.1 - q_th * u.0) / v);
    let e = (
        v * u.0 + r_th * i_re - x_th * i_im,
        v * u.1 + r_th * i_im + x_th * i_re,
    );
    let mut loads = Vec::new();
    let mut load = |name: String, p: f64, q: f64, t_on: f64| {
        let mut t = Table::new();
        t.insert("name".into(), Value::String(name));
        // What the impedance draws at 1 pu: the power at the power-flow voltage over v².
        t.insert("p".into(), real(p / (v * v)));
        t.insert("q".into(), real(q / (v * v)));
        t.insert("t_on".into(), real(t_on));
        loads.push(Value::Table(t));
    };
    for (j, l) in case.loads.iter().enumerate() {
        load(
            format!("load{}", j + 1),
            l.p_mw / base,
            l.q_mvar / base,
            0.0,
        );
    }
    for (j, ev) in case.events.iter().enumerate() {
        match ev {
            grid_model::case::Event::LoadStep {
                time,
                bus,
                dp_mw,
                dq_mvar,
                model,
            } if *bus == pcc && *model == grid_model::case::LoadModel::ConstantImpedance => load(
                format!("step{}", j + 1),
                dp_mw / base,
                dq_mvar / base,
                *time,
            ),
            _ => return not("an event other than a constant-impedance load step at the PCC"),
        }
    }
    let mut plant_units = Vec::new();
    let mut start = Table::new();
    for (unit, o) in units.iter().zip(&pf.der) {
        let mut t = Table::new();
        t.insert("name".into(), Value::String(unit.name.clone()));
        t.insert("s_rated".into(), real(unit.s_rated));
        t.insert("tau_dc".into(), real(unit.tau_dc));
        t.insert("p0".into(), real(o.p));
        t.insert("q0".into(), real(o.q));
        plant_units.push(Value::Table(t));
    }
    let mut model = Table::new();
    model.insert("units".into(), Value::Array(plant_units));
    model.insert("loads".into(), Value::Array(loads));
    model.insert("thevenin".into(), Value::Boolean(true));
    for (n, x) in [
        ("S_base", base),
        ("f_nom", case.f_nom),
        ("thevenin.R", r_th),
        ("thevenin.X", x_th),
        ("thevenin.E", dvpp_math::hypot(e.0, e.1)),
        ("thevenin.angle", dvpp_math::atan2(e.1, e.0)),
        ("thevenin.H", h_th),
        ("thevenin.D", d_th),
    ] {
        start.insert(n.into(), real(x));
    }
    Ok((model, start))
}

fn wire(from: &str, output: &str, to: &str, input: &str) -> Wire {
    ((from.into(), output.into()), (to.into(), input.into()))
}

/// The measurement and drive connections of the DER `name` on the plant's unit `k` (1-based).
pub(super) fn unit_wiring(name: &str, k: usize) -> Vec<Wire> {
    let mut wires = Vec::new();
    for ph in ["a", "b", "c"] {
        for x in ["v", "i", "ig"] {
            let port = format!("{x}_{ph}");
            wires.push(wire(PLANT, &format!("der[{k}].{port}"), name, &port));
        }
    }
    wires.push(wire(PLANT, &format!("der[{k}].v_dc"), name, "v_dc"));
    for ph in ["a", "b", "c"] {
        let port = format!("m_{ph}");
        wires.push(wire(name, &port, PLANT, &format!("der[{k}].{port}")));
    }
    wires.push(wire(name, "i_dc_ref", PLANT, &format!("der[{k}].i_dc_ref")));
    for port in ["p_src_min", "p_src_max"] {
        wires.push(wire(name, port, PLANT, &format!("der[{k}].{port}")));
    }
    wires
}

impl Job<'_, '_> {
    /// `[emt] plant`: the plant's own `[model]` (a scenario without a grid case).
    fn plant_config(&self) -> Result<PlantConfig, String> {
        let table = self
            .sc
            .emt
            .as_ref()
            .and_then(|e| e.plant.clone())
            .ok_or_else(|| {
                self.here(
                    "[emt] needs a grid case ([grid] case) or the plant's own [emt.plant]".into(),
                )
            })?;
        Value::Table(table)
            .try_into()
            .map_err(|e| self.here(format!("[emt.plant]: {e}")))
    }

    /// The units of a plant of its own as the DERs' slots (grid-forming unless the DER's start
    /// values say `mode = 2`).
    pub(super) fn plant_slots(&self) -> Result<Vec<Slot>, String> {
        let layout = self.plant_config()?.layout().map_err(|e| self.here(e))?;
        if layout.units.len() != self.sc.der.len() {
            return Err(self.here(format!(
                "[emt.plant] has {} units but the scenario lists {} DERs",
                layout.units.len(),
                self.sc.der.len()
            )));
        }
        Ok(layout
            .units
            .iter()
            .zip(&self.sc.der)
            .map(|(u, d)| Slot {
                rating_mva: u.s_rated,
                r: 0.0,
                x: None,
                forming: d.start.get("mode").and_then(Value::as_integer) != Some(2),
                point: None,
            })
            .collect())
    }

    /// The EMT plant: converted from the grid case (its power-flow point), or its own
    /// `[model]`; each unit's primary-source lag is its controller's `tau_dc`.
    pub(super) fn plant(
        &mut self,
        grid: Option<&GridUnit>,
        ders: &[DerUnit],
    ) -> Result<Unit, String> {
        let units = ders
            .iter()
            .map(|d| {
                let get = |n: &str| {
                    start_of(&d.unit.md, n).ok_or(format!("DER '{}': no {n}", d.unit.name))
                };
                Ok(UnitData {
                    name: d.unit.name.clone(),
                    s_rated: get("S_rated")?,
                    tau_dc: get("tau_dc")?,
                })
            })
            .collect::<Result<Vec<_>, String>>()?;
        let (model, mut start) = match grid {
            Some(g) => plant_from_case(&g.case, &g.pf, &units).map_err(|e| self.here(e))?,
            None => {
                let mut layout = self.plant_config()?.layout().map_err(|e| self.here(e))?;
                for (u, d) in layout.units.iter_mut().zip(&units) {
                    u.tau_dc = d.tau_dc;
                }
                let config = PlantConfig {
                    case: None,
                    units: Some(layout.units),
                    loads: Some(layout.loads),
                    thevenin: Some(layout.thevenin),
                };
                let model = match Value::try_from(config).map_err(|e| e.to_string())? {
                    Value::Table(t) => t,
                    _ => unreachable!("a struct is a table"),
                };
                (model, Table::new())
            }
        };
        start.extend(
            self.sc
                .emt
                .as_ref()
                .map_or(Table::new(), |e| e.start.clone()),
        );
        let md = self.build(&dvpp_catalog::EMT_PLANT, PLANT, model, &start, Vec::new())?;
        Ok(Unit {
            name: PLANT.into(),
            md,
            start,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use fmi_export::harness::Harness;
    use fmi_export::Status;

    /// The plant converted from the phasor Thevenin case starts where the phasor grid's power
    /// flow is: each unit's injection, the PCC voltage and the source's power agree.
    #[test]
    fn the_plant_from_a_thevenin_case_starts_at_its_power_flow() {
        let case = grid_model::Case::builtin("thevenin_dvpp").unwrap();
        let pf = grid_model::Grid::new(&case).unwrap().outputs();
        let units: Vec<UnitData> = dvpp_control::Fleet::case_study_i()
            .units
            .iter()
            .map(|u| UnitData {
                name: u.name.clone(),
                s_rated: u.kind.s_rated,
                tau_dc: u.kind.tau_dc,
            })
            .collect();
        let (model, start) = plant_from_case(&case, &pf, &units).unwrap();
        let mut doc = Table::new();
        doc.insert("model".into(), Value::Table(model));
        let mut h = Harness::<emt_plant_model::Plant>::from_toml(&toml::to_string(&doc).unwrap());
        assert_eq!(h.setup_experiment(0.0, None), Status::Ok);
        for (name, v) in &start {
            h.set(name, v.as_float().unwrap());
        }
        assert_eq!(h.enter_initialization_mode(), Status::Ok);
        assert_eq!(h.exit_initialization_mode(), Status::Ok);
        let mut worst: f64 = 0.0;
        for (k, o) in pf.der.iter().enumerate() {
            let [p, q] = h.get_many([&format!("der[{}].p", k + 1), &format!("der[{}].q", k + 1)]);
            worst = worst.max((p - o.p).abs()).max((q - o.q).abs());
        }
        worst = worst.max((h.get("pcc.v") - pf.der[0].v).abs());
        assert!(
            worst < 1e-9,
            "largest difference to the power flow {worst:e}"
        );
        // The loads draw their power-flow P + jQ: the source supplies the rest.
        let load: f64 = case.loads.iter().map(|l| l.p_mw / case.base_mva).sum();
        let ders: f64 = pf.der.iter().map(|d| d.p).sum();
        assert!((h.get("thevenin.p") - (load - ders)).abs() < 1e-9);
    }

    /// A case that is not one PCC behind a Thevenin equivalent is refused with the reason.
    #[test]
    fn a_case_that_is_no_thevenin_equivalent_is_refused() {
        let case = grid_model::Case::builtin("ieee9_dvpp").unwrap();
        let pf = grid_model::Grid::new(&case).unwrap().outputs();
        let e = plant_from_case(&case, &pf, &[]).unwrap_err();
        assert!(e.contains("not exactly one machine"), "{e}");
    }
}
