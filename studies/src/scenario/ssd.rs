//! The SSP system of a scenario: its components with their bound parameters, wired.

use dvpp_cosim::ssp;
use model_description::{BaseType, Causality, ModelDescription};
use toml::{Table, Value};

use super::job::Unit;
use super::wiring::Wire;
use super::{Scenario, RECORD};

/// The SSP system of `units` wired by `wires`, each connected input declared on its component.
pub(super) fn system(
    name: &str,
    sc: &Scenario,
    units: &[Unit],
    wires: Vec<Wire>,
) -> Result<ssp::System, String> {
    let mut components = units
        .iter()
        .map(|u| component(&u.name, &u.md, &u.start))
        .collect::<Result<Vec<_>, _>>()?;
    let connections: Vec<ssp::Connection> = wires
        .into_iter()
        .map(|((a, x), (b, y))| ssp::Connection {
            start_element: a,
            start_connector: x,
            end_element: b,
            end_connector: y,
            transformation: None,
        })
        .collect();
    for c in &connections {
        let comp = components
            .iter_mut()
            .find(|x| x.name == c.end_element)
            .expect("a scenario component");
        if !comp.connectors.iter().any(|k| k.name == c.end_connector) {
            let md_ty = comp
                .connectors
                .iter()
                .find(|k| k.name == c.start_connector)
                .map(|k| k.ty)
                .unwrap_or(ssp::Type::Real);
            comp.connectors.push(ssp::Connector {
                name: c.end_connector.clone(),
                kind: ssp::Kind::Input,
                ty: md_ty,
            });
        }
    }
    let record = match &sc.experiment.record {
        Some(r) => r.clone(),
        None => default_record(&components),
    };
    Ok(ssp::System {
        name: name.into(),
        description: Some(sc.description.clone()),
        components,
        connections,
        start_time: sc.experiment.start,
        stop_time: Some(sc.experiment.stop),
        step_size: Some(sc.experiment.step),
        record,
    })
}

/// Of [`RECORD`], the patterns that match an output of `components` (the master refuses a
/// record pattern that matches nothing; the default list names what any scenario may have).
fn default_record(components: &[ssp::Component]) -> Vec<String> {
    let outputs: Vec<String> = components
        .iter()
        .flat_map(|c| {
            c.connectors
                .iter()
                .filter(|k| k.kind == ssp::Kind::Output && k.ty != ssp::Type::String)
                .map(move |k| format!("{}.{}", c.name, k.name))
        })
        .collect();
    RECORD
        .iter()
        .filter(|p| outputs.iter().any(|o| dvpp_cosim::master::matches(p, o)))
        .map(|p| p.to_string())
        .collect()
}

/// A component of the system: every output as a connector, the parameters among `start` bound.
fn component(name: &str, md: &ModelDescription, start: &Table) -> Result<ssp::Component, String> {
    let connectors = md
        .model_variables
        .variables
        .iter()
        .filter(|v| v.causality() == Causality::Output)
        .map(|v| ssp::Connector {
            name: v.name.clone(),
            kind: ssp::Kind::Output,
            ty: v.base_type().into(),
        })
        .collect();
    let mut parameters = Vec::new();
    for (key, value) in start {
        let v = md.variable(key).ok_or_else(|| {
            format!(
                "component '{name}': '{key}' is not a variable of {}",
                md.model_name
            )
        })?;
        if v.causality() != Causality::Parameter {
            continue;
        }
        let value = match (v.base_type(), value) {
            (BaseType::Real, Value::Float(x)) => ssp::Value::Real(*x),
            (BaseType::Real, Value::Integer(x)) => ssp::Value::Real(*x as f64),
            (BaseType::Integer, Value::Integer(x)) => ssp::Value::Integer(*x),
            (BaseType::Boolean, Value::Boolean(b)) => ssp::Value::Boolean(*b),
            (BaseType::String, Value::String(s)) => ssp::Value::String(s.clone()),
            (t, v) => {
                return Err(format!(
                    "component '{name}': '{key}' = {v} does not fit its type {t}"
                ))
            }
        };
        parameters.push(ssp::Parameter {
            name: key.clone(),
            value,
        });
    }
    Ok(ssp::Component {
        name: name.into(),
        source: format!("resources/{name}.fmu"),
        connectors,
        parameters,
    })
}
