//! Parameter bindings: inline parameter sets and `.ssv` files.

use super::xml::{parse_double, parse_tree, ssp_children, Doc, Node, Ns};
use super::{Error, Parameter, Value, NS_SSV, PARAMETER_SET_TYPE};
use std::path::Path;

/// The parameters of an `ssd:ParameterBindings` (inline sets and `.ssv` files, prefixes
/// applied), each with the binding element it came from.
pub(super) fn read_bindings<'n>(
    d: &Doc,
    n: &'n Node,
    dir: &Path,
) -> Result<Vec<(Parameter, &'n Node)>, Error> {
    let mut out = Vec::new();
    for (ns, local, b) in ssp_children(n) {
        if (ns, local) != (Ns::Ssd, "ParameterBinding") {
            return Err(d.unexpected(b, n));
        }
        if let Some(ty) = b.attr("type") {
            if ty != PARAMETER_SET_TYPE {
                return Err(d.err(
                    b,
                    format_args!("type \"{ty}\" is not supported (only {PARAMETER_SET_TYPE})"),
                ));
            }
        }
        let mut parameters = Vec::new();
        let mut inline = false;
        for (ns, local, c) in ssp_children(b) {
            match (ns, local) {
                (Ns::Ssd, "ParameterValues") => {
                    inline = true;
                    for (ns, local, s) in ssp_children(c) {
                        match (ns, local) {
                            (Ns::Ssv, "ParameterSet") => {
                                parameters.extend(read_parameter_set(d, s)?)
                            }
                            _ => return Err(d.unexpected(s, c)),
                        }
                    }
                }
                (Ns::Ssd, "ParameterMapping") => {
                    return Err(d.err(c, "parameter mappings are not supported"))
                }
                (Ns::Ssd, "Annotations") => {}
                _ => return Err(d.unexpected(c, b)),
            }
        }
        if let Some(source) = b.attr("source") {
            if inline {
                return Err(d.err(b, "has both a source and inline <ssd:ParameterValues>"));
            }
            if b.attr("sourceBase").is_some_and(|s| s != "SSD") {
                return Err(d.err(b, "sourceBase=\"component\" is not supported"));
            }
            let path = dir.join(source);
            let text = crate::archive::read_text(&path).map_err(|e| {
                d.err(
                    b,
                    format_args!(
                        "cannot read parameter file '{source}' ({}): {e}",
                        path.display()
                    ),
                )
            })?;
            let root = parse_tree(&text, source)?;
            let sd = Doc { file: source };
            if !root.is(NS_SSV, "ParameterSet") {
                return Err(sd.err(
                    &root,
                    format_args!(
                        "the root element must be <ssv:ParameterSet> in namespace {NS_SSV}"
                    ),
                ));
            }
            parameters.extend(read_parameter_set(&sd, &root)?);
        }
        let prefix = b.attr("prefix").unwrap_or("");
        for mut p in parameters {
            p.name.insert_str(0, prefix);
            out.push((p, b));
        }
    }
    Ok(out)
}

fn read_parameter_set(d: &Doc, n: &Node) -> Result<Vec<Parameter>, Error> {
    let mut out = Vec::new();
    for (ns, local, c) in ssp_children(n) {
        match (ns, local) {
            (Ns::Ssv, "Parameters") => {
                for (ns, local, p) in ssp_children(c) {
                    if (ns, local) != (Ns::Ssv, "Parameter") {
                        return Err(d.unexpected(p, c));
                    }
                    out.push(read_parameter(d, p)?);
                }
            }
            (Ns::Ssv, "Enumerations" | "Units" | "Annotations") => {}
            _ => return Err(d.unexpected(c, n)),
        }
    }
    Ok(out)
}

fn read_parameter(d: &Doc, n: &Node) -> Result<Parameter, Error> {
    let name = d.attr(n, "name")?;
    let mut value = None;
    for (ns, local, v) in ssp_children(n) {
        match (ns, local) {
            (Ns::Ssv, "Real" | "Integer" | "Boolean" | "String") => {
                if value.is_some() {
                    return Err(d.err(v, format_args!("parameter '{name}' has a second value")));
                }
                let text = d.attr(v, "value")?;
                let bad = || {
                    d.err(
                        v,
                        format_args!("parameter '{name}': value \"{text}\" is not a valid {local}"),
                    )
                };
                value = Some(match local {
                    "Real" => Value::Real(parse_double(text).ok_or_else(bad)?),
                    "Integer" => {
                        let x: i64 = text.trim().parse().map_err(|_| bad())?;
                        if i32::try_from(x).is_err() {
                            return Err(d.err(
                                v,
                                format_args!(
                                    "parameter '{name}': value {x} is outside the 32-bit range of an SSP/FMI Integer"
                                ),
                            ));
                        }
                        Value::Integer(x)
                    }
                    "Boolean" => Value::Boolean(match text.trim() {
                        "true" | "1" => true,
                        "false" | "0" => false,
                        _ => return Err(bad()),
                    }),
                    _ => Value::String(text.to_string()),
                });
            }
            (Ns::Ssv, "Enumeration" | "Binary") => {
                return Err(d.err(
                    v,
                    format_args!("parameter '{name}': {local} values are not supported"),
                ))
            }
            (Ns::Ssv, "Annotations") => {}
            _ => return Err(d.unexpected(v, n)),
        }
    }
    let value = value.ok_or_else(|| d.err(n, format_args!("parameter '{name}' has no value")))?;
    Ok(Parameter {
        name: name.to_string(),
        value,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ssp::fixtures::*;
    use crate::ssp::{read, SSD_FILE};

    #[test]
    fn ssv_binding() {
        let t = temp();
        std::fs::create_dir(t.path().join("resources")).unwrap();
        let ssv = r#"<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="p">
  <ssv:Parameters>
    <ssv:Parameter name="time"><ssv:Real value="0.25" unit="s"/></ssv:Parameter>
    <ssv:Parameter name="enabled"><ssv:Boolean value="false"/></ssv:Parameter>
  </ssv:Parameters>
</ssv:ParameterSet>"#;
        std::fs::write(t.path().join("resources/grid.ssv"), ssv).unwrap();
        let mut s = sample();
        s.components[0].parameters.clear();
        let xml = s.to_ssd().replacen(
            "<ssd:Connectors>",
            "<ssd:ParameterBindings><ssd:ParameterBinding source=\"resources/grid.ssv\" prefix=\"event[1].\"/></ssd:ParameterBindings><ssd:Connectors>",
            1,
        );
        // The XSD order (Connectors before ParameterBindings) is not enforced by the reader.
        std::fs::write(t.path().join(SSD_FILE), &xml).unwrap();
        let p = read(t.path()).unwrap();
        assert_eq!(
            p.system.components[0].parameters,
            vec![
                Parameter {
                    name: "event[1].time".into(),
                    value: Value::Real(0.25)
                },
                Parameter {
                    name: "event[1].enabled".into(),
                    value: Value::Boolean(false)
                },
            ]
        );
        assert_eq!(p.dir, t.path());

        std::fs::write(
            t.path().join("resources/grid.ssv"),
            ssv.replace("0.25", "x"),
        )
        .unwrap();
        let e = read(t.path()).unwrap_err().0;
        assert!(
            e.contains("resources/grid.ssv: <ssv:Real>: parameter 'time'"),
            "{e}"
        );
        std::fs::remove_file(t.path().join("resources/grid.ssv")).unwrap();
        let e = read(t.path()).unwrap_err().0;
        assert!(
            e.contains("<ssd:ParameterBinding>")
                && e.contains("cannot read parameter file 'resources/grid.ssv'"),
            "{e}"
        );
    }
}
