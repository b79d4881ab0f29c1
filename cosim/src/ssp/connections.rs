//! `ssd:Connection`s: endpoints, kinds, types, transformations and single drivers.

use super::xml::{ssp_children, Doc, Node, Ns};
use super::{Component, Connection, Error, Kind, LinearTransformation, Type};

pub(super) fn read_connections(
    d: &Doc,
    nodes: &[&Node],
    components: &[Component],
) -> Result<Vec<Connection>, Error> {
    let mut out = Vec::new();
    // (end element, end connector) -> index of the connection driving it
    let mut driven: std::collections::HashMap<(&str, &str), usize> = Default::default();
    for (i, &n) in nodes.iter().enumerate() {
        let index = i + 1;
        let fail = |what: String| {
            Error(format!(
                "{}: <{}> {index}: {what} (line {})",
                d.file, n.qname, n.line
            ))
        };
        let start_connector = d.attr(n, "startConnector")?;
        let end_connector = d.attr(n, "endConnector")?;
        let (Some(start_element), Some(end_element)) =
            (n.attr("startElement"), n.attr("endElement"))
        else {
            return Err(fail(
                "connections to the system's own connectors are not supported (startElement or endElement is missing)".into(),
            ));
        };
        let component = |role: &str, name: &str| {
            components
                .iter()
                .find(|c| c.name == name)
                .ok_or_else(|| fail(format!("{role}Element '{name}' is not a component")))
        };
        let start = component("start", start_element)?;
        let end = component("end", end_element)?;
        let connector = |role: &str, c: &'_ Component, name: &str| {
            c.connector(name).cloned().ok_or_else(|| {
                fail(format!(
                    "{role}Connector '{name}' is not a connector of component '{}'",
                    c.name
                ))
            })
        };
        let from = connector("start", start, start_connector)?;
        let to = connector("end", end, end_connector)?;
        let (from_name, to_name) = (
            format!("{start_element}.{start_connector}"),
            format!("{end_element}.{end_connector}"),
        );
        if !matches!(
            from.kind,
            Kind::Output | Kind::Parameter | Kind::CalculatedParameter
        ) {
            return Err(fail(format!(
                "start {from_name} is an {}; a connection starts at an output, parameter or calculatedParameter",
                from.kind.as_str()
            )));
        }
        if !matches!(to.kind, Kind::Input | Kind::Parameter) {
            return Err(fail(format!(
                "end {to_name} is {} {}; a connection ends at an input or parameter",
                if to.kind == Kind::Output { "an" } else { "a" },
                to.kind.as_str()
            )));
        }
        if from.ty != to.ty {
            return Err(fail(format!(
                "types differ: {from_name} is {} but {to_name} is {}",
                from.ty.as_str(),
                to.ty.as_str()
            )));
        }
        let mut transformation = None;
        for (ns, local, t) in ssp_children(n) {
            match (ns, local) {
                (Ns::Ssc, "LinearTransformation") => {
                    if transformation.is_some() {
                        return Err(fail("more than one transformation".into()));
                    }
                    transformation = Some(LinearTransformation {
                        factor: d.real_attr(t, "factor")?.unwrap_or(1.0),
                        offset: d.real_attr(t, "offset")?.unwrap_or(0.0),
                    });
                }
                (
                    Ns::Ssc,
                    "BooleanMappingTransformation"
                    | "IntegerMappingTransformation"
                    | "EnumerationMappingTransformation",
                ) => {
                    return Err(fail(format!(
                        "<{}> is not supported (only <ssc:LinearTransformation>)",
                        t.qname
                    )))
                }
                (Ns::Ssd, "ConnectionGeometry" | "Annotations") => {}
                _ => return Err(d.unexpected(t, n)),
            }
        }
        if transformation.is_some() && from.ty != Type::Real {
            return Err(fail(format!(
                "a LinearTransformation needs Real connectors, {from_name} is {}",
                from.ty.as_str()
            )));
        }
        if let Some(first) = driven.insert((end_element, end_connector), index) {
            return Err(fail(format!(
                "{to_name} is already connected by <ssd:Connection> {first}"
            )));
        }
        out.push(Connection {
            start_element: start_element.to_string(),
            start_connector: start_connector.to_string(),
            end_element: end_element.to_string(),
            end_connector: end_connector.to_string(),
            transformation,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ssp::fixtures::*;
    use crate::ssp::parse_ssd;
    use std::path::Path;

    #[test]
    fn component_and_connection_errors() {
        let s = sample();
        let mut dup = s.clone();
        dup.components[2].name = "grid".into();
        dup.connections.pop();
        assert_err(
            &dup.to_ssd(),
            &["<ssd:Component>", "duplicate component name 'grid'"],
        );

        let mut c = s.clone();
        c.connections[2].start_element = "gird".into();
        assert_err(
            &c.to_ssd(),
            &["SystemStructure.ssd: <ssd:Connection> 3: startElement 'gird' is not a component"],
        );
        let mut c = s.clone();
        c.connections[1].end_connector = "der[9].theta".into();
        assert_err(
            &c.to_ssd(),
            &["<ssd:Connection> 2: endConnector 'der[9].theta' is not a connector of component 'grid'"],
        );
        let mut c = s.clone();
        c.connections[2].start_connector = "der[1].p".into();
        assert_err(
            &c.to_ssd(),
            &["types differ: grid.der[1].p is Real but operator & co.count is Integer"],
        );
        let mut c = s.clone();
        c.connections[1] = connect("grid", "der[1].theta", "der1", "p");
        assert_err(
            &c.to_ssd(),
            &["<ssd:Connection> 2: start grid.der[1].theta is an input"],
        );
        let mut c = s.clone();
        c.connections[1] = connect("der1", "theta", "grid", "der[1].p");
        assert_err(&c.to_ssd(), &["end grid.der[1].p is an output"]);
        let mut c = s.clone();
        c.connections.push(connect("grid", "der[1].p", "der1", "p"));
        assert_err(
            &c.to_ssd(),
            &["<ssd:Connection> 4: der1.p is already connected by <ssd:Connection> 1"],
        );
        let mut c = s.clone();
        c.connections[2].transformation = Some(LinearTransformation {
            factor: 1.0,
            offset: 0.0,
        });
        assert_err(&c.to_ssd(), &["LinearTransformation needs Real connectors"]);
        // A parameter may be driven by a calculated parameter / output; a parameter may start one.
        let mut c = s.clone();
        c.components[1]
            .connectors
            .push(connector("n", Kind::CalculatedParameter, Type::Integer));
        c.connections[2] = connect("der1", "n", "der1", "mode");
        assert_eq!(parse_ssd(&c.to_ssd(), Path::new(".")).unwrap(), c);
    }
}
