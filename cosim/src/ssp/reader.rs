//! The reader of SystemStructure.ssd: the document, the system, its components and connectors.

use super::annotations::{read_record, read_step_size};
use super::connections::read_connections;
use super::parameters::read_bindings;
use super::xml::{parse_tree, ssp_children, Doc, Node, Ns};
use super::{
    Component, Connector, Error, Kind, Parameter, System, Type, FMU_TYPE, NS_SSD, SSD_FILE,
};
use std::path::Path;

/// Parse SystemStructure.ssd text; `dir` is the package directory `.ssv` sources are relative to.
pub fn parse_ssd(xml: &str, dir: &Path) -> Result<System, Error> {
    parse_ssd_labelled(xml, dir, SSD_FILE)
}

pub(super) fn parse_ssd_labelled(xml: &str, dir: &Path, file: &str) -> Result<System, Error> {
    let root = parse_tree(xml, file)?;
    let d = Doc { file };
    if !root.is(NS_SSD, "SystemStructureDescription") {
        return Err(d.err(
            &root,
            format_args!(
                "the root element must be <ssd:SystemStructureDescription> in namespace {NS_SSD} (found namespace {})",
                root.ns.as_deref().unwrap_or("none")
            ),
        ));
    }
    let version = d.attr(&root, "version")?;
    let minor = version
        .strip_prefix("1.")
        .map(|r| r.split('-').next().unwrap_or(""));
    if !minor.is_some_and(|m| !m.is_empty() && m.bytes().all(|b| b.is_ascii_digit())) {
        return Err(d.err(
            &root,
            format_args!("version \"{version}\" is not supported (SSP 1.x)"),
        ));
    }
    d.attr(&root, "name")?;
    let mut system_node = None;
    let mut experiment = None;
    for (ns, local, c) in ssp_children(&root) {
        match (ns, local) {
            (Ns::Ssd, "System") if system_node.is_none() => system_node = Some(c),
            (Ns::Ssd, "System") => return Err(d.err(c, "more than one system")),
            (Ns::Ssd, "DefaultExperiment") if experiment.is_none() => experiment = Some(c),
            (Ns::Ssd, "DefaultExperiment") => {
                return Err(d.err(
                    c,
                    "a second <ssd:DefaultExperiment> (one experiment per system)",
                ))
            }
            (Ns::Ssd, "Enumerations" | "Units" | "Annotations") => {}
            _ => return Err(d.unexpected(c, &root)),
        }
    }
    let system_node = system_node.ok_or_else(|| d.err(&root, "has no <ssd:System>"))?;
    let mut system = read_system(&d, system_node, dir)?;
    if let Some(e) = experiment {
        system.start_time = d.real_attr(e, "startTime")?.unwrap_or(0.0);
        system.stop_time = d.real_attr(e, "stopTime")?;
        if !system.start_time.is_finite() {
            return Err(d.err(
                e,
                format_args!("startTime {} is not finite", system.start_time),
            ));
        }
        if let Some(stop) = system.stop_time {
            if !(stop.is_finite() && stop > system.start_time) {
                return Err(d.err(
                    e,
                    format_args!(
                        "stopTime {stop} must be finite and after startTime {}",
                        system.start_time
                    ),
                ));
            }
        }
        system.step_size = read_step_size(&d, e)?;
        system.record = read_record(&d, e)?;
    }
    Ok(system)
}

fn read_system(d: &Doc, n: &Node, dir: &Path) -> Result<System, Error> {
    let name = d.attr(n, "name")?.to_string();
    let description = n.attr("description").map(str::to_string);
    let mut components: Vec<Component> = Vec::new();
    let mut connections: Vec<&Node> = Vec::new();
    let mut system_bindings: Vec<&Node> = Vec::new();
    let mut seen_connectors = false;
    for (ns, local, c) in ssp_children(n) {
        match (ns, local) {
            // The system's own connectors: fine as long as nothing connects to them.
            (Ns::Ssd, "Connectors") if seen_connectors => {
                return Err(d.err(
                    c,
                    format_args!("system '{name}' has a second <ssd:Connectors>"),
                ))
            }
            (Ns::Ssd, "Connectors") => {
                seen_connectors = true;
                read_connectors(d, c)?;
            }
            (Ns::Ssd, "ParameterBindings") => system_bindings.push(c),
            (Ns::Ssd, "Elements") => {
                for (ns, local, e) in ssp_children(c) {
                    match (ns, local) {
                        (Ns::Ssd, "Component") => {
                            let component = read_component(d, e, dir)?;
                            if components.iter().any(|x| x.name == component.name) {
                                return Err(d.err(
                                    e,
                                    format_args!("duplicate component name '{}'", component.name),
                                ));
                            }
                            components.push(component);
                        }
                        (Ns::Ssd, "System") => {
                            return Err(d.err(e, "nested systems are not supported"))
                        }
                        (Ns::Ssd, "SignalDictionaryReference") => {
                            return Err(d.err(e, "signal dictionaries are not supported"))
                        }
                        _ => return Err(d.unexpected(e, c)),
                    }
                }
            }
            (Ns::Ssd, "Connections") => {
                for (ns, local, e) in ssp_children(c) {
                    match (ns, local) {
                        (Ns::Ssd, "Connection") => connections.push(e),
                        _ => return Err(d.unexpected(e, c)),
                    }
                }
            }
            (
                Ns::Ssd,
                "ElementGeometry" | "SignalDictionaries" | "SystemGeometry" | "GraphicalElements"
                | "Annotations",
            ) => {}
            _ => return Err(d.unexpected(c, n)),
        }
    }
    // System-level bindings name `component.variable` (after the binding's prefix).
    for b in system_bindings {
        for (p, at) in read_bindings(d, b, dir)? {
            let target = components
                .iter()
                .enumerate()
                .filter(|(_, c)| {
                    p.name.len() > c.name.len() + 1
                        && p.name.starts_with(c.name.as_str())
                        && p.name.as_bytes()[c.name.len()] == b'.'
                })
                .max_by_key(|(_, c)| c.name.len())
                .map(|(i, _)| i);
            let Some(i) = target else {
                return Err(d.err(
                    at,
                    format_args!(
                        "system-level parameter '{}' does not name a component's variable (component.variable)",
                        p.name
                    ),
                ));
            };
            let variable = p.name[components[i].name.len() + 1..].to_string();
            set_parameter(
                &mut components[i].parameters,
                Parameter {
                    name: variable,
                    value: p.value,
                },
            );
        }
    }
    let connections = read_connections(d, &connections, &components)?;
    Ok(System {
        name,
        description,
        components,
        connections,
        start_time: 0.0,
        stop_time: None,
        step_size: None,
        record: Vec::new(),
    })
}

/// Add or replace (a later binding overrides an earlier one).
fn set_parameter(parameters: &mut Vec<Parameter>, p: Parameter) {
    match parameters.iter_mut().find(|q| q.name == p.name) {
        Some(q) => q.value = p.value,
        None => parameters.push(p),
    }
}

fn read_component(d: &Doc, n: &Node, dir: &Path) -> Result<Component, Error> {
    let name = d.attr(n, "name")?.to_string();
    let source = d.attr(n, "source")?.to_string();
    if source.is_empty() {
        return Err(d.err(n, format_args!("component '{name}' has an empty source")));
    }
    if let Some(ty) = n.attr("type") {
        if ty != FMU_TYPE {
            return Err(d.err(
                n,
                format_args!(
                    "component '{name}': type \"{ty}\" is not supported (only {FMU_TYPE})"
                ),
            ));
        }
    }
    let mut connectors = Vec::new();
    let mut parameters = Vec::new();
    let mut seen_connectors = false;
    for (ns, local, c) in ssp_children(n) {
        match (ns, local) {
            (Ns::Ssd, "Connectors") if seen_connectors => {
                return Err(d.err(
                    c,
                    format_args!("component '{name}' has a second <ssd:Connectors>"),
                ))
            }
            (Ns::Ssd, "Connectors") => {
                seen_connectors = true;
                connectors.extend(read_connectors(d, c)?)
            }
            (Ns::Ssd, "ParameterBindings") => {
                for (p, _) in read_bindings(d, c, dir)? {
                    set_parameter(&mut parameters, p);
                }
            }
            (Ns::Ssd, "ElementGeometry" | "Annotations") => {}
            _ => return Err(d.unexpected(c, n)),
        }
    }
    Ok(Component {
        name,
        source,
        connectors,
        parameters,
    })
}

pub(super) fn read_connectors(d: &Doc, n: &Node) -> Result<Vec<Connector>, Error> {
    let mut out: Vec<Connector> = Vec::new();
    for (ns, local, c) in ssp_children(n) {
        if (ns, local) != (Ns::Ssd, "Connector") {
            return Err(d.unexpected(c, n));
        }
        let name = d.attr(c, "name")?;
        let kind = d.attr(c, "kind")?;
        let kind = Kind::parse(kind).ok_or_else(|| {
            d.err(
                c,
                format_args!(
                    "connector '{name}': kind \"{kind}\" is not supported (input, output, parameter, calculatedParameter)"
                ),
            )
        })?;
        let mut ty = None;
        for (ns, local, t) in ssp_children(c) {
            match (ns, local) {
                (Ns::Ssc, "Real" | "Integer" | "Boolean" | "String") => {
                    if ty.is_some() {
                        return Err(d.err(t, format_args!("connector '{name}' has a second type")));
                    }
                    ty = Type::parse(local);
                }
                (Ns::Ssc, "Enumeration" | "Binary") => {
                    return Err(d.err(
                        t,
                        format_args!("connector '{name}': {local} connectors are not supported"),
                    ))
                }
                (Ns::Ssd, "ConnectorGeometry" | "Annotations") => {}
                _ => return Err(d.unexpected(t, c)),
            }
        }
        let ty = ty.ok_or_else(|| {
            d.err(
                c,
                format_args!(
                    "connector '{name}' has no type element (<ssc:Real>, <ssc:Integer>, <ssc:Boolean> or <ssc:String>)"
                ),
            )
        })?;
        if out.iter().any(|k| k.name == name) {
            return Err(d.err(c, format_args!("duplicate connector '{name}'")));
        }
        out.push(Connector {
            name: name.to_string(),
            kind,
            ty,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ssp::fixtures::*;
    use crate::ssp::{LinearTransformation, Package, Value, MAX_DEPTH, NS_SSV};
    use std::path::PathBuf;

    #[test]
    fn wrong_root_or_version() {
        assert_err(
            "<foo/>",
            &[
                "<foo>",
                "root element must be <ssd:SystemStructureDescription>",
            ],
        );
        let xml = sample().to_ssd();
        let other_ns = xml.replace(
            NS_SSD,
            "http://ssp-standard.org/SSP2/SystemStructureDescription",
        );
        assert_err(
            &other_ns,
            &[
                "<ssd:SystemStructureDescription>",
                "SSP2",
                "not an SSP namespace",
            ],
        );
        let v2 = xml.replace("version=\"1.0\" name=\"demo", "version=\"2.0\" name=\"demo");
        assert_err(
            &v2,
            &[
                "<ssd:SystemStructureDescription>",
                "version \"2.0\" is not supported",
            ],
        );
        let no_version = xml.replace(" version=\"1.0\" name=\"demo", " name=\"demo");
        assert_err(&no_version, &["missing required attribute 'version'"]);
    }

    #[test]
    fn unknown_elements() {
        let xml = sample().to_ssd();
        let typo = xml
            .replace("<ssd:Connection ", "<ssd:Conection ")
            .replace("</ssd:Connection>", "</ssd:Conection>");
        assert_err(
            &typo,
            &[
                "<ssd:Conection>",
                "unexpected element inside <ssd:Connections>",
                "line",
            ],
        );
        let no_ns = xml.replace("<ssd:Connections>", "<ssd:Connections><Connection/>");
        assert_err(&no_ns, &["<Connection>", "unexpected element"]);
        // Foreign namespaces are refused where the reader would have to drop them ...
        let foreign = xml.replace(
            "<ssd:Connections>",
            "<ssd:Connections><x:Note xmlns:x=\"urn:x\"><x:y/></x:Note>",
        );
        assert_err(&foreign, &["<x:Note>", "urn:x", "not an SSP namespace"]);
        let slash = xml.replace(NS_SSV, &format!("{NS_SSV}/"));
        assert_err(&slash, &["<ssv:ParameterSet>", "did you mean"]);
        let text = xml.replace("<ssd:Connection ", "ssd:Connection ");
        assert_err(
            &text,
            &["<ssd:Connections>", "unexpected text", "ssd:Connection"],
        );
        // ... and free inside an annotation, at any depth up to the reader's limit.
        let annotated = xml.replace(
            "</ssd:SystemStructureDescription>",
            "<ssd:Annotations><ssc:Annotation type=\"x\"><x:Note xmlns:x=\"urn:x\">text<x:y/></x:Note></ssc:Annotation></ssd:Annotations></ssd:SystemStructureDescription>",
        );
        assert_ne!(annotated, xml);
        assert_eq!(parse_ssd(&annotated, Path::new(".")).unwrap(), sample());
        let deep = format!(
            "{}{}",
            "<a>".repeat(MAX_DEPTH * 1000),
            "</a>".repeat(MAX_DEPTH * 1000)
        );
        assert_err(&deep, &["nested deeper than 256"]);
        let nested = xml.replace(
            "<ssd:Elements>",
            "<ssd:Elements><ssd:System name=\"inner\"/>",
        );
        assert_err(
            &nested,
            &["<ssd:System>", "nested systems are not supported"],
        );
        let mapping = xml.replace(
            "<ssc:LinearTransformation factor=\"-2.5\" offset=\"0.3333333333333333\"/>",
            "<ssc:BooleanMappingTransformation><ssc:MapEntry source=\"true\" target=\"false\"/></ssc:BooleanMappingTransformation>",
        );
        assert_err(
            &mapping,
            &[
                "<ssd:Connection> 1",
                "<ssc:BooleanMappingTransformation> is not supported",
            ],
        );
        let enum_ty = xml.replacen("<ssc:Real/>", "<ssc:Enumeration name=\"e\"/>", 1);
        assert_err(
            &enum_ty,
            &[
                "connector 'der[1].p'",
                "Enumeration connectors are not supported",
            ],
        );
    }

    #[test]
    fn missing_attributes() {
        let xml = sample().to_ssd();
        let e = xml.replacen(" startConnector=\"theta\"", "", 1);
        assert_err(
            &e,
            &[
                "<ssd:Connection>",
                "missing required attribute 'startConnector'",
            ],
        );
        let e = xml.replacen(" source=\"resources/grid.fmu\"", "", 1);
        assert_err(
            &e,
            &["<ssd:Component>", "missing required attribute 'source'"],
        );
        let e = xml.replacen(" kind=\"output\"", "", 1);
        assert_err(
            &e,
            &["<ssd:Connector>", "missing required attribute 'kind'"],
        );
        let e = xml.replacen(" value=\"false\"", "", 1);
        assert_err(&e, &["<ssv:Boolean>", "missing required attribute 'value'"]);
        let e = xml.replacen("<ssc:Real/>", "", 1);
        assert_err(&e, &["connector 'der[1].p' has no type element"]);
    }

    /// A hand-written SSD: default namespace for ssd, other prefixes, no component type,
    /// system connectors nothing connects to, parameter connectors, system-level bindings.
    const OTHER_PREFIXES: &str = r#"<?xml version="1.0"?>
<!-- written by hand -->
<SystemStructureDescription xmlns="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:c="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:v="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    xmlns:o="http://opensimulationplatform.com/SSP/OSPAnnotations"
    xmlns:vendor="urn:vendor" version="1.0" name="hand">
  <System name="sys" vendor:color="red">
    <Connectors>
      <Connector name="ext_in" kind="input"><c:Real unit="pu"/></Connector>
    </Connectors>
    <ParameterBindings>
      <ParameterBinding prefix="a.">
        <ParameterValues>
          <v:ParameterSet version="1.0" name="sys">
            <v:Parameters>
              <v:Parameter name="gain"><v:Real value="2"/></v:Parameter>
            </v:Parameters>
          </v:ParameterSet>
        </ParameterValues>
      </ParameterBinding>
      <ParameterBinding>
        <ParameterValues>
          <v:ParameterSet version="1.0" name="sys2">
            <v:Parameters>
              <v:Parameter name="b.on"><v:Boolean value="1"/></v:Parameter>
            </v:Parameters>
          </v:ParameterSet>
        </ParameterValues>
      </ParameterBinding>
    </ParameterBindings>
    <Elements>
      <Component name="a" source="a.fmu">
        <Connectors>
          <Connector name="y" kind="output"><c:Real/><ConnectorGeometry x="0" y="0"/></Connector>
          <Connector name="gain" kind="parameter"><c:Real/></Connector>
        </Connectors>
        <ParameterBindings>
          <ParameterBinding>
            <ParameterValues>
              <v:ParameterSet version="1.0" name="a">
                <v:Parameters>
                  <v:Parameter name="gain"><v:Real value="1"/></v:Parameter>
                  <v:Parameter name="n"><v:Integer value="+7"/></v:Parameter>
                </v:Parameters>
              </v:ParameterSet>
            </ParameterValues>
          </ParameterBinding>
        </ParameterBindings>
        <Annotations><c:Annotation type="com.opensimulationplatform"><o:StepSizeHint value="0.1"/></c:Annotation></Annotations>
      </Component>
      <Component name="b" type="application/x-fmu-sharedlibrary" source="./b.fmu">
        <Connectors>
          <Connector name="u" kind="input"><c:Real/></Connector>
          <Connector name="on" kind="parameter"><c:Boolean/></Connector>
        </Connectors>
      </Component>
    </Elements>
    <Connections>
      <Connection startElement="a" startConnector="y" endElement="b" endConnector="u">
        <c:LinearTransformation factor="1E3"/>
        <Annotations><c:Annotation type="x"><vendor:z/></c:Annotation></Annotations>
      </Connection>
    </Connections>
  </System>
  <DefaultExperiment stopTime="2">
    <Annotations>
      <c:Annotation type="org.other"><vendor:x/></c:Annotation>
      <c:Annotation type="com.opensimulationplatform">
        <o:Algorithm><o:FixedStepAlgorithm baseStepSize="1e-4" numWorkerThreads="1"/></o:Algorithm>
      </c:Annotation>
    </Annotations>
  </DefaultExperiment>
</SystemStructureDescription>
"#;

    #[test]
    fn other_prefixes() {
        let s = parse_ssd(OTHER_PREFIXES, Path::new(".")).unwrap();
        assert_eq!(s.name, "sys");
        assert_eq!(
            (s.start_time, s.stop_time, s.step_size),
            (0.0, Some(2.0), Some(1e-4))
        );
        let a = s.component("a").unwrap();
        assert_eq!(a.source, "a.fmu");
        assert_eq!(
            a.connectors[1],
            connector("gain", Kind::Parameter, Type::Real)
        );
        // The system-level binding (prefix "a.") overrides the component's own.
        assert_eq!(
            a.parameters,
            vec![
                Parameter {
                    name: "gain".into(),
                    value: Value::Real(2.0)
                },
                Parameter {
                    name: "n".into(),
                    value: Value::Integer(7)
                },
            ]
        );
        let b = s.component("b").unwrap();
        assert_eq!(
            b.parameters,
            vec![Parameter {
                name: "on".into(),
                value: Value::Boolean(true)
            }]
        );
        assert_eq!(
            s.connections[0].transformation,
            Some(LinearTransformation {
                factor: 1000.0,
                offset: 0.0
            })
        );
        let p = Package {
            system: s.clone(),
            dir: PathBuf::from("/x"),
            _temp: None,
        };
        assert_eq!(p.source_path(b), PathBuf::from("/x/b.fmu"));

        // A connection to the system's own connector.
        let to_system = OTHER_PREFIXES.replace(
            "</Connections>",
            "<Connection startConnector=\"ext_in\" endElement=\"b\" endConnector=\"on\"/></Connections>",
        );
        let e = parse_ssd(&to_system, Path::new(".")).unwrap_err().0;
        assert!(
            e.contains(
                "<Connection> 2: connections to the system's own connectors are not supported"
            ),
            "{e}"
        );
        let bad_route = OTHER_PREFIXES.replace("prefix=\"a.\"", "prefix=\"c.\"");
        let e = parse_ssd(&bad_route, Path::new(".")).unwrap_err().0;
        assert!(
            e.contains("<ParameterBinding>") && e.contains("'c.gain' does not name a component"),
            "{e}"
        );
        let alg = OTHER_PREFIXES.replace("o:FixedStepAlgorithm", "o:EccoAlgorithm");
        let e = parse_ssd(&alg, Path::new(".")).unwrap_err().0;
        assert!(
            e.contains("<o:EccoAlgorithm>: unsupported OSP algorithm"),
            "{e}"
        );
    }
}
