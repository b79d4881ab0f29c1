//! The writer: SystemStructure.ssd text (shape in the `ssp` module docs) and .ssp archives.

use super::{
    parse_ssd, Component, Connector, Error, Kind, System, Value, FMU_TYPE, NS_OSP, NS_SSC, NS_SSD,
    NS_SSV, OSP_ANNOTATION, PARAMETER_SET_NAME, RECORD_ANNOTATION, SSD_FILE,
};
use std::io::Write as _;
use std::path::{Path, PathBuf};

impl System {
    /// The SystemStructure.ssd text (see the module documentation for its shape).
    pub fn to_ssd(&self) -> String {
        let mut w = XmlWriter::default();
        w.out
            .push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
        w.open(
            "ssd:SystemStructureDescription",
            &[
                ("xmlns:ssd", NS_SSD),
                ("xmlns:ssc", NS_SSC),
                ("xmlns:ssv", NS_SSV),
                ("xmlns:osp", NS_OSP),
                ("version", "1.0"),
                ("name", &self.name),
            ],
        );
        let mut attrs = vec![("name", self.name.as_str())];
        if let Some(d) = &self.description {
            attrs.push(("description", d));
        }
        w.open("ssd:System", &attrs);
        if !self.components.is_empty() {
            w.open("ssd:Elements", &[]);
            for c in &self.components {
                write_component(&mut w, c);
            }
            w.close("ssd:Elements");
        }
        if !self.connections.is_empty() {
            w.open("ssd:Connections", &[]);
            for c in &self.connections {
                let attrs = [
                    ("startElement", c.start_element.as_str()),
                    ("startConnector", &c.start_connector),
                    ("endElement", &c.end_element),
                    ("endConnector", &c.end_connector),
                ];
                match &c.transformation {
                    None => w.leaf("ssd:Connection", &attrs),
                    Some(t) => {
                        w.open("ssd:Connection", &attrs);
                        let (factor, offset) = (format_real(t.factor), format_real(t.offset));
                        w.leaf(
                            "ssc:LinearTransformation",
                            &[("factor", &factor), ("offset", &offset)],
                        );
                        w.close("ssd:Connection");
                    }
                }
            }
            w.close("ssd:Connections");
        }
        w.close("ssd:System");

        let start = format_real(self.start_time);
        let stop = self.stop_time.map(format_real);
        let mut attrs = vec![("startTime", start.as_str())];
        if let Some(stop) = &stop {
            attrs.push(("stopTime", stop));
        }
        if self.step_size.is_none() && self.record.is_empty() {
            w.leaf("ssd:DefaultExperiment", &attrs);
        } else {
            w.open("ssd:DefaultExperiment", &attrs);
            w.open("ssd:Annotations", &[]);
            if let Some(h) = self.step_size {
                w.open("ssc:Annotation", &[("type", OSP_ANNOTATION)]);
                w.open("osp:Algorithm", &[]);
                w.leaf(
                    "osp:FixedStepAlgorithm",
                    &[("baseStepSize", &format_real(h))],
                );
                w.close("osp:Algorithm");
                w.close("ssc:Annotation");
            }
            if !self.record.is_empty() {
                w.open("ssc:Annotation", &[("type", RECORD_ANNOTATION)]);
                w.leaf("Record", &[("signals", &self.record.join(","))]);
                w.close("ssc:Annotation");
            }
            w.close("ssd:Annotations");
            w.close("ssd:DefaultExperiment");
        }
        w.close("ssd:SystemStructureDescription");
        w.out
    }

    /// Write an .ssp archive (deflate): `SystemStructure.ssd` at the root and each FMU, given as
    /// (path inside the archive, file on disk), at its archive path.  Every component's `source`
    /// must be one of the archive paths.  The system is checked with the reader's rules first.
    pub fn write_ssp(&self, fmus: &[(String, PathBuf)], out: &Path) -> Result<(), Error> {
        let ssd = self.to_ssd();
        let dir = out.parent().unwrap_or(Path::new("."));
        parse_ssd(&ssd, dir).map_err(|e| Error(format!("{}: {e}", out.display())))?;
        let mut names = std::collections::HashSet::new();
        for (name, disk) in fmus {
            check_archive_path(name).map_err(|e| Error(format!("{}: {e}", out.display())))?;
            if !names.insert(name.as_str()) {
                return Err(Error(format!(
                    "{}: archive path '{name}' given twice",
                    out.display()
                )));
            }
            if !disk.is_file() {
                return Err(Error(format!(
                    "{}: {} (for '{name}') is not a file",
                    out.display(),
                    disk.display()
                )));
            }
        }
        for c in &self.components {
            if !names.contains(c.source.as_str()) {
                return Err(Error(format!(
                    "{}: component '{}': source '{}' is not among the files given",
                    out.display(),
                    c.name,
                    c.source
                )));
            }
        }
        let result = write_zip(&ssd, fmus, out);
        if result.is_err() {
            let _ = std::fs::remove_file(out);
        }
        result.map_err(|e| Error(format!("{}: cannot write: {e}", out.display())))
    }
}

fn write_component(w: &mut XmlWriter, c: &Component) {
    w.open(
        "ssd:Component",
        &[("name", &c.name), ("type", FMU_TYPE), ("source", &c.source)],
    );
    if !c.connectors.is_empty() {
        w.open("ssd:Connectors", &[]);
        for k in &c.connectors {
            w.open(
                "ssd:Connector",
                &[("name", &k.name), ("kind", k.kind.as_str())],
            );
            w.leaf(&format!("ssc:{}", k.ty.as_str()), &[]);
            w.close("ssd:Connector");
        }
        w.close("ssd:Connectors");
    }
    if !c.parameters.is_empty() {
        w.open("ssd:ParameterBindings", &[]);
        w.open("ssd:ParameterBinding", &[]);
        w.open("ssd:ParameterValues", &[]);
        w.open(
            "ssv:ParameterSet",
            &[("version", "1.0"), ("name", PARAMETER_SET_NAME)],
        );
        w.open("ssv:Parameters", &[]);
        for p in &c.parameters {
            w.open("ssv:Parameter", &[("name", &p.name)]);
            let value = match &p.value {
                Value::Real(x) => format_real(*x),
                Value::Integer(i) => i.to_string(),
                Value::Boolean(b) => b.to_string(),
                Value::String(s) => s.clone(),
            };
            w.leaf(
                &format!("ssv:{}", p.value.ty().as_str()),
                &[("value", &value)],
            );
            w.close("ssv:Parameter");
        }
        w.close("ssv:Parameters");
        w.close("ssv:ParameterSet");
        w.close("ssd:ParameterValues");
        w.close("ssd:ParameterBinding");
        w.close("ssd:ParameterBindings");
    }
    w.close("ssd:Component");
}

fn check_archive_path(name: &str) -> Result<(), Error> {
    let bad = name.is_empty()
        || name == SSD_FILE
        || name.starts_with('/')
        || name.contains('\\')
        || name.contains(':')
        || name
            .split('/')
            .any(|p| p.is_empty() || p == "." || p == "..");
    if bad {
        return Err(Error(format!(
            "'{name}' is not a valid path inside the archive (relative, '/'-separated, no '.' or '..', not {SSD_FILE})"
        )));
    }
    Ok(())
}

fn write_zip(
    ssd: &str,
    fmus: &[(String, PathBuf)],
    out: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let file = std::fs::File::create(out)?;
    let mut zip = zip::ZipWriter::new(file);
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    zip.start_file(SSD_FILE, options)?;
    zip.write_all(ssd.as_bytes())?;
    // FMUs are zip archives already: stored as they are, so a master inflates them only once.
    let stored = options.compression_method(zip::CompressionMethod::Stored);
    for (name, disk) in fmus {
        zip.start_file(name.as_str(), stored)?;
        let mut f = std::fs::File::open(disk)?;
        std::io::copy(&mut f, &mut zip)?;
    }
    zip.finish()?.sync_all()?;
    Ok(())
}

/// A tiny indenting XML writer (attribute values are escaped here).
#[derive(Default)]
struct XmlWriter {
    out: String,
    depth: usize,
}

impl XmlWriter {
    fn tag(&mut self, name: &str, attrs: &[(&str, &str)], empty: bool) {
        for _ in 0..self.depth {
            self.out.push_str("  ");
        }
        self.out.push('<');
        self.out.push_str(name);
        for (k, v) in attrs {
            self.out.push(' ');
            self.out.push_str(k);
            self.out.push_str("=\"");
            escape_attr(&mut self.out, v);
            self.out.push('"');
        }
        self.out.push_str(if empty { "/>\n" } else { ">\n" });
    }

    fn open(&mut self, name: &str, attrs: &[(&str, &str)]) {
        self.tag(name, attrs, false);
        self.depth += 1;
    }

    fn leaf(&mut self, name: &str, attrs: &[(&str, &str)]) {
        self.tag(name, attrs, true);
    }

    fn close(&mut self, name: &str) {
        self.depth -= 1;
        for _ in 0..self.depth {
            self.out.push_str("  ");
        }
        self.out.push_str("</");
        self.out.push_str(name);
        self.out.push_str(">\n");
    }
}

/// Escape an attribute value (double-quoted).  Tab, newline and carriage return are written as
/// character references so that attribute-value normalization keeps them; other characters that
/// XML 1.0 cannot represent become U+FFFD.
fn escape_attr(out: &mut String, s: &str) {
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\t' => out.push_str("&#9;"),
            '\n' => out.push_str("&#10;"),
            '\r' => out.push_str("&#13;"),
            c if (c as u32) < 0x20 || c == '\u{FFFE}' || c == '\u{FFFF}' => out.push('\u{FFFD}'),
            c => out.push(c),
        }
    }
}

/// An `xs:double` that parses back to exactly `x` (shortest round-trip form).
fn format_real(x: f64) -> String {
    if x.is_nan() {
        "NaN".into()
    } else if x == f64::INFINITY {
        "INF".into()
    } else if x == f64::NEG_INFINITY {
        "-INF".into()
    } else {
        format!("{x:?}")
    }
}

/// Write into `dir` an SSP directory of `n` unconnected components `unit1` … `unitN` of the FMU
/// at `fmu` (copied to `resources/unit.fmu`), each recording every output, stepping by `step`:
/// the systems of the scale benchmark and of the federation test.
pub fn write_copies(fmu: &Path, n: usize, dir: &Path, step: f64) -> Result<(), String> {
    use model_description::{BaseType, Causality};
    let loaded = crate::Fmu::load(fmu).map_err(|e| e.to_string())?;
    let connectors: Vec<Connector> = loaded
        .description
        .model_variables
        .variables
        .iter()
        .filter(|v| v.causality() == Causality::Output && v.base_type() != BaseType::String)
        .map(|v| Connector {
            name: v.name.clone(),
            kind: Kind::Output,
            ty: v.base_type().into(),
        })
        .collect();
    let system = System {
        name: format!("units{n}"),
        description: Some(format!("{n} units of {}", fmu.display())),
        components: (1..=n)
            .map(|k| Component {
                name: format!("unit{k}"),
                source: "resources/unit.fmu".into(),
                connectors: connectors.clone(),
                parameters: Vec::new(),
            })
            .collect(),
        connections: Vec::new(),
        start_time: 0.0,
        stop_time: Some(1.0),
        step_size: Some(step),
        record: Vec::new(),
    };
    let at = |e: std::io::Error| format!("{}: {e}", dir.display());
    std::fs::create_dir_all(dir.join("resources")).map_err(at)?;
    std::fs::copy(fmu, dir.join("resources").join("unit.fmu")).map_err(at)?;
    std::fs::write(dir.join("SystemStructure.ssd"), system.to_ssd()).map_err(at)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ssp::fixtures::*;
    use crate::ssp::{read, LinearTransformation, Parameter, Type};

    #[test]
    fn round_trip_ssd() {
        let s = sample();
        let xml = s.to_ssd();
        assert_eq!(parse_ssd(&xml, Path::new(".")).unwrap(), s);
        assert!(
            xml.contains("<osp:FixedStepAlgorithm baseStepSize=\"0.001\"/>"),
            "{xml}"
        );
        let mut bare = s.clone();
        bare.step_size = None;
        bare.stop_time = None;
        bare.description = None;
        assert_eq!(parse_ssd(&bare.to_ssd(), Path::new(".")).unwrap(), bare);
    }

    #[test]
    fn round_trip_archive() {
        let t = temp();
        let fmu_a = t.path().join("a.fmu");
        let fmu_b = t.path().join("b.fmu");
        std::fs::write(&fmu_a, b"grid bytes").unwrap();
        std::fs::write(&fmu_b, b"der bytes").unwrap();
        let s = sample();
        let fmus = vec![
            ("resources/grid.fmu".to_string(), fmu_a.clone()),
            ("resources/der.fmu".to_string(), fmu_b),
            ("resources/op \"x\".fmu".to_string(), fmu_a),
        ];
        let out = t.path().join("demo.ssp");
        s.write_ssp(&fmus, &out).unwrap();
        let dir;
        {
            let p = read(&out).unwrap();
            assert_eq!(p.system, s);
            let grid = p.system.component("grid").unwrap();
            assert_eq!(std::fs::read(p.source_path(grid)).unwrap(), b"grid bytes");
            dir = p.dir.clone();
            assert!(dir.join(SSD_FILE).is_file());
            // The unpacked directory and the .ssd file read the same.
            assert_eq!(read(&p.dir).unwrap().system, s);
            assert_eq!(read(&p.dir.join(SSD_FILE)).unwrap().system, s);
        }
        assert!(!dir.exists(), "temporary directory not removed");

        let e = s.write_ssp(&fmus[..1], &out).unwrap_err();
        assert!(
            e.0.contains("source 'resources/der.fmu' is not among"),
            "{e}"
        );
        let mut bad = s.clone();
        bad.connections[0].end_connector = "nope".into();
        let e = bad.write_ssp(&fmus, &out).unwrap_err();
        assert!(e.0.contains("endConnector 'nope'"), "{e}");
        let e = s
            .write_ssp(&[("../x.fmu".to_string(), t.path().join("a.fmu"))], &out)
            .unwrap_err();
        assert!(e.0.contains("'../x.fmu' is not a valid path"), "{e}");
    }

    /// Writes `$DVPP_SSP_DIR/dvpp.ssp` (grid + three DERs, bundled FMUs from `$DVPP_DIST` or
    /// dist/default) and `dvpp_transform.ssp` (the same with a LinearTransformation on
    /// der1.v), for checking the output with fmpy.ssp and libcosim; plus the unit tests'
    /// `sample.ssd` (for XSD validation).
    #[test]
    #[ignore]
    fn demo_ssp() {
        let out = PathBuf::from(std::env::var("DVPP_SSP_DIR").expect("set DVPP_SSP_DIR"));
        let dist = std::env::var("DVPP_DIST")
            .map(PathBuf::from)
            .unwrap_or_else(|_| Path::new(env!("CARGO_MANIFEST_DIR")).join("../dist/default"));
        let mut s = demo_system();
        let fmus: Vec<(String, PathBuf)> = vec![
            ("resources/grid.fmu".into(), dist.join("dvpp_grid.fmu")),
            ("resources/wind.fmu".into(), dist.join("dvpp_der.fmu")),
            ("resources/pv.fmu".into(), dist.join("dvpp_der.fmu")),
            ("resources/bess.fmu".into(), dist.join("dvpp_der.fmu")),
        ];
        s.write_ssp(&fmus, &out.join("dvpp.ssp")).unwrap();
        let c = s
            .connections
            .iter_mut()
            .find(|c| c.end_element == "der1" && c.end_connector == "v")
            .unwrap();
        c.transformation = Some(LinearTransformation {
            factor: 2.0,
            offset: 0.5,
        });
        s.write_ssp(&fmus, &out.join("dvpp_transform.ssp")).unwrap();
        assert_eq!(read(&out.join("dvpp_transform.ssp")).unwrap().system, s);
        std::fs::write(out.join("sample.ssd"), sample().to_ssd()).unwrap();
    }

    fn demo_system() -> System {
        let mut grid = Component {
            name: "grid".into(),
            source: "resources/grid.fmu".into(),
            connectors: vec![],
            parameters: vec![
                Parameter {
                    name: "event[1].time".into(),
                    value: Value::Real(0.25),
                },
                Parameter {
                    name: "event[1].enabled".into(),
                    value: Value::Boolean(true),
                },
            ],
        };
        let mut components = vec![];
        let mut connections = vec![];
        for (k, source) in ["wind", "pv", "bess"].iter().enumerate() {
            let k = k + 1;
            let der = format!("der{k}");
            let mut c = Component {
                name: der.clone(),
                source: format!("resources/{source}.fmu"),
                connectors: vec![],
                parameters: vec![
                    Parameter {
                        name: "S_rated".into(),
                        value: Value::Real(30.0 + 10.0 * k as f64),
                    },
                    Parameter {
                        name: "mode".into(),
                        value: Value::Integer(1),
                    },
                ],
            };
            for v in ["p", "q", "v", "v_angle"] {
                let g = format!("der[{k}].{v}");
                grid.connectors
                    .push(connector(&g, Kind::Output, Type::Real));
                c.connectors.push(connector(v, Kind::Input, Type::Real));
                connections.push(connect("grid", &g, &der, v));
            }
            for v in ["theta", "E"] {
                let g = format!("der[{k}].{v}");
                grid.connectors.push(connector(&g, Kind::Input, Type::Real));
                c.connectors.push(connector(v, Kind::Output, Type::Real));
                connections.push(connect(&der, v, "grid", &g));
            }
            components.push(c);
        }
        for v in ["pcc.f", "coi.f", "pcc.p"] {
            grid.connectors.push(connector(v, Kind::Output, Type::Real));
        }
        components.insert(0, grid);
        System {
            name: "dvpp".into(),
            description: Some("reduced grid with three grid-forming DERs".into()),
            components,
            connections,
            start_time: 0.0,
            stop_time: Some(0.5),
            step_size: Some(1e-3),
            record: Vec::new(),
        }
    }
}
