//! SSP 1.0 system structures: the data model, the writer (SystemStructure.ssd + .ssp archive) and the reader.
//!
//! The writer emits the subset of SSP 1.0 that both fmpy.ssp (which validates against the SSP 1.0
//! XSD) and libcosim accept.  libcosim parses the SSD with boost::property_tree, i.e. by the
//! *literal* prefixes `ssd:`, `ssc:`, `ssv:` and `osp:`, so the writer always uses exactly those:
//!
//! ```text
//! ssd:SystemStructureDescription version="1.0" name=..   (xmlns:ssd, ssc, ssv, osp)
//!   ssd:System name=.. [description=..]
//!     ssd:Elements                                      (omitted without components)
//!       ssd:Component name=.. type="application/x-fmu-sharedlibrary" source="resources/x.fmu"
//!         ssd:Connectors / ssd:Connector name=.. kind=..  / ssc:Real|ssc:Integer|ssc:Boolean|ssc:String
//!         ssd:ParameterBindings / ssd:ParameterBinding / ssd:ParameterValues
//!           / ssv:ParameterSet version="1.0" name="initialValues" / ssv:Parameters
//!             / ssv:Parameter name=.. / ssv:Real|ssv:Integer|ssv:Boolean|ssv:String value=..
//!     ssd:Connections                                   (omitted without connections)
//!       ssd:Connection startElement startConnector endElement endConnector
//!         [ssc:LinearTransformation factor=.. offset=..]
//!   ssd:DefaultExperiment startTime=.. [stopTime=..]
//!     ssd:Annotations / ssc:Annotation type="com.opensimulationplatform"
//!       / osp:Algorithm / osp:FixedStepAlgorithm baseStepSize=..   (only with a step size)
//! ```
//!
//! The reader is namespace-aware (elements are matched by namespace URI and local name, so any
//! prefixes or a default namespace work), skips elements in foreign namespaces (annotations,
//! vendor extensions) and reports anything it does not understand inside the SSP elements it
//! interprets.  It reads inline parameter sets and `.ssv` files, system-level parameter bindings
//! (names `component.variable`), linear transformations and the OSP step-size annotation.  It does
//! not open FMUs: the master checks the FMU files and their variables itself.

use crate::tmp::TempDir;
use std::fmt;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use quick_xml::events::{BytesStart, Event};
use quick_xml::name::ResolveResult;
use quick_xml::NsReader;

/// Namespace of `ssd:` elements.
pub const NS_SSD: &str = "http://ssp-standard.org/SSP1/SystemStructureDescription";
/// Namespace of `ssc:` elements.
pub const NS_SSC: &str = "http://ssp-standard.org/SSP1/SystemStructureCommon";
/// Namespace of `ssv:` elements.
pub const NS_SSV: &str = "http://ssp-standard.org/SSP1/SystemStructureParameterValues";
/// Namespace the writer binds `osp:` to (libcosim only looks at the literal prefix; the reader
/// accepts the OSP elements in any namespace, the annotation's `type` identifies them).
pub const NS_OSP: &str = "http://opensimulationplatform.com/SSP/OSPAnnotations";
/// `type` of the `ssc:Annotation` holding libcosim's algorithm settings.
pub const OSP_ANNOTATION: &str = "com.opensimulationplatform";
/// `type` of the `ssc:Annotation` holding the signals our master records by default
/// (`<Record signals="grid.pcc.*,*.p"/>`); other masters ignore it.
pub const RECORD_ANNOTATION: &str = "org.dvpp-fmu.record";
/// The system structure file at the root of an .ssp archive.
pub const SSD_FILE: &str = "SystemStructure.ssd";
/// MIME type of FMU components (the default of `ssd:Component type`).
pub const FMU_TYPE: &str = "application/x-fmu-sharedlibrary";
const PARAMETER_SET_TYPE: &str = "application/x-ssp-parameter-set";
/// Name of the parameter set the writer puts in each component's binding.
const PARAMETER_SET_NAME: &str = "initialValues";

/// A reader or writer error; the message names the file, the element and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Error(pub String);

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Error {}

/// `ssd:Connector kind` (`inout`, meant for signal dictionaries, is not supported).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Kind {
    Input,
    Output,
    Parameter,
    CalculatedParameter,
}

impl Kind {
    /// The attribute value.
    pub fn as_str(self) -> &'static str {
        match self {
            Kind::Input => "input",
            Kind::Output => "output",
            Kind::Parameter => "parameter",
            Kind::CalculatedParameter => "calculatedParameter",
        }
    }

    fn parse(s: &str) -> Option<Kind> {
        Some(match s {
            "input" => Kind::Input,
            "output" => Kind::Output,
            "parameter" => Kind::Parameter,
            "calculatedParameter" => Kind::CalculatedParameter,
            _ => return None,
        })
    }
}

/// Connector and parameter types (`Enumeration` and `Binary` are not supported).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Type {
    Real,
    Integer,
    Boolean,
    String,
}

impl From<model_description::BaseType> for Type {
    fn from(t: model_description::BaseType) -> Type {
        use model_description::BaseType as B;
        match t {
            B::Real => Type::Real,
            B::Integer => Type::Integer,
            B::Boolean => Type::Boolean,
            B::String => Type::String,
        }
    }
}

impl From<Type> for model_description::BaseType {
    fn from(t: Type) -> Self {
        use model_description::BaseType as B;
        match t {
            Type::Real => B::Real,
            Type::Integer => B::Integer,
            Type::Boolean => B::Boolean,
            Type::String => B::String,
        }
    }
}

impl Type {
    /// The element's local name (`ssc:Real`, `ssv:Real`, ...).
    pub fn as_str(self) -> &'static str {
        match self {
            Type::Real => "Real",
            Type::Integer => "Integer",
            Type::Boolean => "Boolean",
            Type::String => "String",
        }
    }

    fn parse(s: &str) -> Option<Type> {
        Some(match s {
            "Real" => Type::Real,
            "Integer" => Type::Integer,
            "Boolean" => Type::Boolean,
            "String" => Type::String,
            _ => return None,
        })
    }
}

/// An `ssd:Connector` of a component: the name of an FMU variable, its kind and type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Connector {
    pub name: String,
    pub kind: Kind,
    pub ty: Type,
}

/// A parameter value.  SSP's `ssv:Integer` is an `xs:int`: keep values within `i32`.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    Real(f64),
    Integer(i64),
    Boolean(bool),
    String(String),
}

impl Value {
    pub fn ty(&self) -> Type {
        match self {
            Value::Real(_) => Type::Real,
            Value::Integer(_) => Type::Integer,
            Value::Boolean(_) => Type::Boolean,
            Value::String(_) => Type::String,
        }
    }
}

/// A start value for a component's variable.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameter {
    /// The component's variable name.
    pub name: String,
    pub value: Value,
}

/// An FMU component.
#[derive(Debug, Clone, PartialEq)]
pub struct Component {
    pub name: String,
    /// The FMU, relative to the package directory, e.g. `resources/grid.fmu`.
    pub source: String,
    pub connectors: Vec<Connector>,
    pub parameters: Vec<Parameter>,
}

impl Component {
    pub fn connector(&self, name: &str) -> Option<&Connector> {
        self.connectors.iter().find(|c| c.name == name)
    }
}

/// `end = offset + factor * start` (Real connections only).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearTransformation {
    pub factor: f64,
    pub offset: f64,
}

/// A connection from a component's output (or parameter) to another component's input.
#[derive(Debug, Clone, PartialEq)]
pub struct Connection {
    pub start_element: String,
    pub start_connector: String,
    pub end_element: String,
    pub end_connector: String,
    pub transformation: Option<LinearTransformation>,
}

/// A flat system of FMU components.
#[derive(Debug, Clone, PartialEq)]
pub struct System {
    pub name: String,
    pub description: Option<String>,
    pub components: Vec<Component>,
    pub connections: Vec<Connection>,
    pub start_time: f64,
    pub stop_time: Option<f64>,
    /// OSP `FixedStepAlgorithm baseStepSize`.
    pub step_size: Option<f64>,
    /// The `component.variable` patterns our master records unless told otherwise
    /// ([`RECORD_ANNOTATION`]); empty: every output.
    pub record: Vec<String>,
}

impl System {
    pub fn component(&self, name: &str) -> Option<&Component> {
        self.components.iter().find(|c| c.name == name)
    }

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

/// Parse an `xs:double` (`1`, `-1.5e-3`, `.5`, `INF`, `-INF`, `NaN`).
fn parse_double(s: &str) -> Option<f64> {
    let t = s.trim();
    match t {
        "INF" | "+INF" => Some(f64::INFINITY),
        "-INF" => Some(f64::NEG_INFINITY),
        "NaN" => Some(f64::NAN),
        _ if !t.is_empty()
            && t.bytes()
                .all(|b| b.is_ascii_digit() || matches!(b, b'+' | b'-' | b'.' | b'e' | b'E')) =>
        {
            t.parse().ok()
        }
        _ => None,
    }
}

// ---------------------------------------------------------------------------------------------
// Reader
// ---------------------------------------------------------------------------------------------

/// A read system: the structure and the directory its files are in (an unpacked .ssp in a
/// temporary directory that is removed on drop, or the directory given).
#[derive(Debug)]
pub struct Package {
    pub system: System,
    pub dir: PathBuf,
    _temp: Option<TempDir>,
}

impl Package {
    /// The same files with another structure (e.g. other start values), for runs that vary a
    /// system; its files stay valid as long as `self` lives.
    pub fn with_system(&self, system: System) -> Package {
        Package {
            system,
            dir: self.dir.clone(),
            _temp: None,
        }
    }

    /// The file a component's `source` refers to.
    pub fn source_path(&self, c: &Component) -> PathBuf {
        let s = c.source.as_str();
        if let Some(abs) = s.strip_prefix("file://") {
            return PathBuf::from(abs);
        }
        self.dir.join(s.strip_prefix("./").unwrap_or(s))
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

/// Read an .ssp archive (unpacked into a temporary directory), a directory holding
/// `SystemStructure.ssd`, or an `.ssd` file (its directory is the package directory).
pub fn read(path: &Path) -> Result<Package, Error> {
    let at = |e: Error| Error(format!("{}: {e}", path.display()));
    if path.is_dir() {
        let ssd = path.join(SSD_FILE);
        if !ssd.is_file() {
            return Err(at(Error(format!("not an SSP directory: no {SSD_FILE}"))));
        }
        let system = read_ssd_file(&ssd, path, SSD_FILE).map_err(at)?;
        return Ok(Package {
            system,
            dir: path.to_path_buf(),
            _temp: None,
        });
    }
    if path.extension().is_some_and(|e| e == "ssd") {
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let label = path.display().to_string();
        let system = read_ssd_file(path, &dir, &label)?;
        return Ok(Package {
            system,
            dir,
            _temp: None,
        });
    }
    let file = std::fs::File::open(path).map_err(|e| at(Error(format!("cannot open: {e}"))))?;
    let mut archive = zip::ZipArchive::new(file)
        .map_err(|e| at(Error(format!("not an SSP archive (zip): {e}"))))?;
    if archive.index_for_name(SSD_FILE).is_none() {
        return Err(at(Error(format!(
            "not an SSP: the archive has no {SSD_FILE} at its root"
        ))));
    }
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("ssp");
    let temp = TempDir::new(&format!("ssp-{stem}"))
        .map_err(|e| at(Error(format!("cannot unpack: {e}"))))?;
    crate::archive::unpack(&mut archive, path, temp.path(), |_| true).map_err(Error)?;
    let system = read_ssd_file(&temp.path().join(SSD_FILE), temp.path(), SSD_FILE).map_err(at)?;
    Ok(Package {
        system,
        dir: temp.path().to_path_buf(),
        _temp: Some(temp),
    })
}

fn read_ssd_file(path: &Path, dir: &Path, label: &str) -> Result<System, Error> {
    let xml = crate::archive::read_text(path)
        .map_err(|e| Error(format!("{label}: cannot read {}: {e}", path.display())))?;
    parse_ssd_labelled(&xml, dir, label)
}

/// Parse SystemStructure.ssd text; `dir` is the package directory `.ssv` sources are relative to.
pub fn parse_ssd(xml: &str, dir: &Path) -> Result<System, Error> {
    parse_ssd_labelled(xml, dir, SSD_FILE)
}

/// An XML element: namespace URI, names, unqualified attributes, child elements, line.
#[derive(Debug)]
struct Node {
    ns: Option<String>,
    local: String,
    qname: String,
    attrs: Vec<(String, String)>,
    children: Vec<Node>,
    line: usize,
}

impl Node {
    fn attr(&self, name: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    }

    fn is(&self, ns: &str, local: &str) -> bool {
        self.ns.as_deref() == Some(ns) && self.local == local
    }
}

/// Which SSP namespace an element is in (`None`: no namespace at all).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Ns {
    Ssd,
    Ssc,
    Ssv,
    None,
}

/// The children in SSP namespaces (or in no namespace), with their namespace; elements in
/// foreign namespaces (vendor annotations, extensions) are skipped.
fn ssp_children(n: &Node) -> impl Iterator<Item = (Ns, &str, &Node)> {
    n.children.iter().filter_map(|c| {
        let ns = match c.ns.as_deref() {
            None => Ns::None,
            Some(NS_SSD) => Ns::Ssd,
            Some(NS_SSC) => Ns::Ssc,
            Some(NS_SSV) => Ns::Ssv,
            Some(_) => return None,
        };
        Some((ns, c.local.as_str(), c))
    })
}

/// Line numbers of byte offsets (offsets asked for in increasing order, mostly).
struct Lines<'a> {
    text: &'a str,
    offset: usize,
    line: usize,
}

impl Lines<'_> {
    fn line_at(&mut self, offset: usize) -> usize {
        let offset = offset.min(self.text.len());
        if offset < self.offset {
            self.offset = 0;
            self.line = 1;
        }
        let bytes = &self.text.as_bytes()[self.offset..offset];
        self.line += bytes.iter().filter(|&&b| b == b'\n').count();
        self.offset = offset;
        self.line
    }

    fn column_at(&self, offset: usize) -> usize {
        let offset = offset.min(self.text.len());
        let start = self.text.as_bytes()[..offset]
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |p| p + 1);
        self.text[start..offset].chars().count() + 1
    }
}

/// Build the element tree of an XML document (namespaces resolved).
fn parse_tree(xml: &str, file: &str) -> Result<Node, Error> {
    let mut reader = NsReader::from_str(xml);
    let mut lines = Lines {
        text: xml,
        offset: 0,
        line: 1,
    };
    let mut stack: Vec<Node> = Vec::new();
    // Per open element: whether its content is free (it is, or is inside, an ssc:Annotation).
    let mut free: Vec<bool> = Vec::new();
    let mut root: Option<Node> = None;
    let malformed = |lines: &mut Lines, pos: u64, what: String| {
        let pos = pos as usize;
        let line = lines.line_at(pos);
        Error(format!(
            "{file}: malformed XML at line {line}, column {}: {what}",
            lines.column_at(pos)
        ))
    };
    loop {
        let pos = reader.buffer_position();
        let (ns, event) = match reader.read_resolved_event() {
            Ok((ns, event)) => (owned_ns(ns), event),
            Err(e) => {
                let at = reader.error_position();
                return Err(malformed(&mut lines, at, e.to_string()));
            }
        };
        let line = lines.line_at(pos as usize);
        let inside_free = free.last().copied().unwrap_or(false);
        let start = |e: &BytesStart| -> Result<Node, Error> {
            let node = make_node(&reader, ns.clone(), e, line, file)?;
            if !inside_free {
                check_namespace(&node, file)?;
            }
            if stack.len() >= MAX_DEPTH {
                return Err(Error(format!(
                    "{file}: <{}>: elements nested deeper than {MAX_DEPTH} (line {line}), the reader's limit",
                    node.qname
                )));
            }
            Ok(node)
        };
        let (node, open) = match event {
            Event::Start(e) => (start(&e)?, true),
            Event::Empty(e) => (start(&e)?, false),
            Event::End(_) => match stack.pop() {
                Some(node) => {
                    free.pop();
                    (node, false)
                }
                None => return Err(malformed(&mut lines, pos, "unexpected end tag".into())),
            },
            Event::Text(t) if !inside_free && !stack.is_empty() => {
                let text = String::from_utf8_lossy(t.as_ref()).into_owned();
                if text.trim().is_empty() {
                    continue;
                }
                let parent = stack.last().map_or("", |n| n.qname.as_str());
                let shown: String = text.trim().chars().take(40).collect();
                return Err(Error(format!(
                    "{file}: <{parent}>: unexpected text \"{shown}\" at line {line} (SSP elements hold no text outside <ssc:Annotation>; a lost '<'?)"
                )));
            }
            Event::CData(_) if !inside_free && !stack.is_empty() => {
                let parent = stack.last().map_or("", |n| n.qname.as_str());
                return Err(Error(format!(
                    "{file}: <{parent}>: unexpected CDATA at line {line} (SSP elements hold no text outside <ssc:Annotation>)"
                )));
            }
            // An entity declared in a DTD would stand for content the reader never sees (a
            // connection, a parameter): documents with a DTD are refused, whatever it declares.
            Event::DocType(_) => {
                return Err(Error(format!(
                    "{file}: a <!DOCTYPE> declaration at line {line}: DTDs and entities are not supported"
                )))
            }
            Event::GeneralRef(r) => {
                let name = String::from_utf8_lossy(r.as_ref()).into_owned();
                let predefined =
                    r.is_char_ref() || ["lt", "gt", "amp", "apos", "quot"].contains(&name.as_str());
                if !predefined {
                    return Err(Error(format!(
                        "{file}: entity reference &{name}; at line {line}: DTDs and entities are not supported"
                    )));
                }
                if !inside_free && !stack.is_empty() {
                    let parent = stack.last().map_or("", |n| n.qname.as_str());
                    return Err(Error(format!(
                        "{file}: <{parent}>: unexpected text \"&{name};\" at line {line} (SSP elements hold no text outside <ssc:Annotation>)"
                    )));
                }
                continue;
            }
            Event::Eof => break,
            _ => continue,
        };
        if open {
            free.push(inside_free || node.is(NS_SSC, "Annotation"));
            stack.push(node);
        } else if let Some(parent) = stack.last_mut() {
            parent.children.push(node);
        } else if root.is_some() {
            return Err(malformed(
                &mut lines,
                pos,
                format!("second root element <{}>", node.qname),
            ));
        } else {
            root = Some(node);
        }
    }
    if let Some(open) = stack.last() {
        return Err(Error(format!(
            "{file}: malformed XML: end of file inside <{}> (opened at line {})",
            open.qname, open.line
        )));
    }
    root.ok_or_else(|| Error(format!("{file}: malformed XML: no root element")))
}

/// How deep elements may nest in an SSD or SSV file (the SSP structure needs about a dozen
/// levels; the limit keeps a hostile file from exhausting the stack).
pub const MAX_DEPTH: usize = 256;

/// Refuse an element outside `ssc:Annotation` in a namespace the reader does not interpret:
/// silently skipping it would drop what its author meant (a connection, a parameter set).
fn check_namespace(node: &Node, file: &str) -> Result<(), Error> {
    let Some(ns) = node.ns.as_deref() else {
        return Ok(());
    };
    if [NS_SSD, NS_SSC, NS_SSV].contains(&ns) {
        return Ok(());
    }
    let near = [NS_SSD, NS_SSC, NS_SSV]
        .into_iter()
        .find(|k| ns.trim_end_matches('/').eq_ignore_ascii_case(k));
    let hint = match near {
        Some(k) => format!(" (did you mean {k}?)"),
        None => {
            " (only SSP 1.0 elements are read; vendor content belongs in <ssc:Annotation>)".into()
        }
    };
    Err(Error(format!(
        "{file}: <{}>: namespace {ns} is not an SSP namespace the reader can interpret (line {}){hint}",
        node.qname, node.line
    )))
}

fn owned_ns(r: ResolveResult) -> Result<Option<String>, String> {
    match r {
        ResolveResult::Bound(ns) => Ok(Some(String::from_utf8_lossy(ns.as_ref()).into_owned())),
        ResolveResult::Unbound => Ok(None),
        ResolveResult::Unknown(p) => Err(String::from_utf8_lossy(&p).into_owned()),
    }
}

fn make_node(
    reader: &NsReader<&[u8]>,
    ns: Result<Option<String>, String>,
    e: &BytesStart,
    line: usize,
    file: &str,
) -> Result<Node, Error> {
    let qname = String::from_utf8_lossy(e.name().as_ref()).into_owned();
    let fail = |what: String| Error(format!("{file}: <{qname}>: {what} (line {line})"));
    let ns = ns.map_err(|p| fail(format!("undeclared namespace prefix '{p}'")))?;
    let mut attrs = Vec::new();
    for a in e.attributes() {
        let a = a.map_err(|err| fail(format!("malformed attribute: {err}")))?;
        if a.key.as_namespace_binding().is_some() {
            continue;
        }
        // Qualified attributes (xml:lang, xsi:..., vendor ones) are not SSP attributes.
        if let (ResolveResult::Bound(_), _) = reader.resolve_attribute(a.key) {
            continue;
        }
        let key = String::from_utf8_lossy(a.key.as_ref()).into_owned();
        let value = a
            .unescape_value()
            .map_err(|err| fail(format!("attribute '{key}': {err}")))?
            .into_owned();
        attrs.push((key, value));
    }
    Ok(Node {
        ns,
        local: String::from_utf8_lossy(e.local_name().as_ref()).into_owned(),
        qname,
        attrs,
        children: Vec::new(),
        line,
    })
}

/// Error construction for one document.
struct Doc<'a> {
    file: &'a str,
}

impl Doc<'_> {
    fn err(&self, n: &Node, what: impl fmt::Display) -> Error {
        Error(format!(
            "{}: <{}>: {what} (line {})",
            self.file, n.qname, n.line
        ))
    }

    fn unexpected(&self, child: &Node, parent: &Node) -> Error {
        self.err(
            child,
            format_args!("unexpected element inside <{}>", parent.qname),
        )
    }

    fn attr<'n>(&self, n: &'n Node, name: &str) -> Result<&'n str, Error> {
        n.attr(name)
            .ok_or_else(|| self.err(n, format_args!("missing required attribute '{name}'")))
    }

    fn real_attr(&self, n: &Node, name: &str) -> Result<Option<f64>, Error> {
        n.attr(name)
            .map(|v| {
                parse_double(v).ok_or_else(|| {
                    self.err(n, format_args!("attribute {name}=\"{v}\" is not a number"))
                })
            })
            .transpose()
    }
}

fn parse_ssd_labelled(xml: &str, dir: &Path, file: &str) -> Result<System, Error> {
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

/// The OSP `FixedStepAlgorithm baseStepSize` in `ssd:DefaultExperiment/ssd:Annotations`.
fn read_step_size(d: &Doc, experiment: &Node) -> Result<Option<f64>, Error> {
    let mut step = None;
    for (ns, local, annotations) in ssp_children(experiment) {
        if (ns, local) != (Ns::Ssd, "Annotations") {
            return Err(d.unexpected(annotations, experiment));
        }
        for (ns, local, a) in ssp_children(annotations) {
            if (ns, local) != (Ns::Ssc, "Annotation") {
                return Err(d.unexpected(a, annotations));
            }
            if d.attr(a, "type")? != OSP_ANNOTATION {
                continue;
            }
            for algorithms in a.children.iter().filter(|c| c.local == "Algorithm") {
                for alg in &algorithms.children {
                    if alg.local != "FixedStepAlgorithm" {
                        return Err(
                            d.err(alg, "unsupported OSP algorithm (only FixedStepAlgorithm)")
                        );
                    }
                    let h = d
                        .real_attr(alg, "baseStepSize")?
                        .ok_or_else(|| d.err(alg, "missing required attribute 'baseStepSize'"))?;
                    if !(h > 0.0 && h.is_finite()) {
                        return Err(d.err(alg, format_args!("baseStepSize {h} is not positive")));
                    }
                    step = Some(h);
                }
            }
        }
    }
    Ok(step)
}

/// The signals of the [`RECORD_ANNOTATION`] in `ssd:DefaultExperiment/ssd:Annotations` (after
/// [`read_step_size`] checked the annotations' shape).
fn read_record(d: &Doc, experiment: &Node) -> Result<Vec<String>, Error> {
    let mut record = Vec::new();
    for (_, _, annotations) in ssp_children(experiment) {
        for (_, _, a) in ssp_children(annotations) {
            if d.attr(a, "type")? != RECORD_ANNOTATION {
                continue;
            }
            for r in &a.children {
                if r.local != "Record" {
                    return Err(d.err(r, "unexpected element (the record annotation holds <Record signals=\"...\"/>)"));
                }
                let signals = d.attr(r, "signals")?;
                record.extend(
                    signals
                        .split(',')
                        .map(str::trim)
                        .filter(|p| !p.is_empty())
                        .map(String::from),
                );
            }
        }
    }
    Ok(record)
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

fn read_connectors(d: &Doc, n: &Node) -> Result<Vec<Connector>, Error> {
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

/// The parameters of an `ssd:ParameterBindings` (inline sets and `.ssv` files, prefixes
/// applied), each with the binding element it came from.
fn read_bindings<'n>(
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

fn read_connections(
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

    fn connector(name: &str, kind: Kind, ty: Type) -> Connector {
        Connector {
            name: name.into(),
            kind,
            ty,
        }
    }

    fn connect(a: &str, ac: &str, b: &str, bc: &str) -> Connection {
        Connection {
            start_element: a.into(),
            start_connector: ac.into(),
            end_element: b.into(),
            end_connector: bc.into(),
            transformation: None,
        }
    }

    /// Three components, a transformation, parameters of every type and awkward values.
    fn sample() -> System {
        let grid = Component {
            name: "grid".into(),
            source: "resources/grid.fmu".into(),
            connectors: vec![
                connector("der[1].p", Kind::Output, Type::Real),
                connector("der[1].theta", Kind::Input, Type::Real),
                connector("n_events", Kind::Output, Type::Integer),
            ],
            parameters: vec![
                Parameter {
                    name: "event[1].time".into(),
                    value: Value::Real(0.1 + 0.2),
                },
                Parameter {
                    name: "event[1].enabled".into(),
                    value: Value::Boolean(false),
                },
                Parameter {
                    name: "tiny".into(),
                    value: Value::Real(1e-300),
                },
                Parameter {
                    name: "big".into(),
                    value: Value::Real(-1.5e300),
                },
                Parameter {
                    name: "inf".into(),
                    value: Value::Real(f64::INFINITY),
                },
            ],
        };
        let der = Component {
            name: "der1".into(),
            source: "resources/der.fmu".into(),
            connectors: vec![
                connector("p", Kind::Input, Type::Real),
                connector("theta", Kind::Output, Type::Real),
                connector("mode", Kind::Parameter, Type::Integer),
            ],
            parameters: vec![
                Parameter {
                    name: "mode".into(),
                    value: Value::Integer(-2147483648),
                },
                Parameter {
                    name: "S_base".into(),
                    value: Value::Real(1e-3),
                },
            ],
        };
        let op = Component {
            name: "operator & co".into(),
            source: "resources/op \"x\".fmu".into(),
            connectors: vec![connector("count", Kind::Input, Type::Integer)],
            parameters: vec![Parameter {
                name: "label".into(),
                value: Value::String("a<b>&\"c\"\t'd'\nline2 ü".into()),
            }],
        };
        let mut c1 = connect("grid", "der[1].p", "der1", "p");
        c1.transformation = Some(LinearTransformation {
            factor: -2.5,
            offset: 1.0 / 3.0,
        });
        System {
            name: "demo <1>".into(),
            description: Some("a \"demo\" & test".into()),
            components: vec![grid, der, op],
            connections: vec![
                c1,
                connect("der1", "theta", "grid", "der[1].theta"),
                connect("grid", "n_events", "operator & co", "count"),
            ],
            start_time: 0.5,
            stop_time: Some(10.0),
            step_size: Some(1e-3),
            record: Vec::new(),
        }
    }

    fn temp() -> TempDir {
        TempDir::new("test").unwrap()
    }

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

    fn parse_err(xml: &str) -> String {
        match parse_ssd(xml, Path::new("/nonexistent")) {
            Ok(s) => panic!("accepted: {s:?}"),
            Err(e) => e.0,
        }
    }

    fn assert_err(xml: &str, parts: &[&str]) {
        let e = parse_err(xml);
        for p in parts {
            assert!(e.contains(p), "error {e:?} lacks {p:?}");
        }
    }

    #[test]
    fn not_an_ssp() {
        let t = temp();
        let junk = t.path().join("junk.ssp");
        std::fs::write(&junk, "hello").unwrap();
        let e = read(&junk).unwrap_err().0;
        assert!(
            e.contains("junk.ssp") && e.contains("not an SSP archive"),
            "{e}"
        );

        let empty = t.path().join("empty.ssp");
        let mut zip = zip::ZipWriter::new(std::fs::File::create(&empty).unwrap());
        zip.start_file("other.txt", zip::write::SimpleFileOptions::default())
            .unwrap();
        zip.finish().unwrap();
        let e = read(&empty).unwrap_err().0;
        assert!(e.contains("no SystemStructure.ssd"), "{e}");

        let e = read(t.path()).unwrap_err().0;
        assert!(e.contains("not an SSP directory"), "{e}");
        let e = read(&t.path().join("missing.ssp")).unwrap_err().0;
        assert!(
            e.contains("missing.ssp") && e.contains("cannot open"),
            "{e}"
        );
    }

    #[test]
    fn malformed_xml() {
        let xml = sample()
            .to_ssd()
            .replace("</ssd:Connections>", "</ssd:Connection>");
        assert_err(
            &xml,
            &["SystemStructure.ssd: malformed XML at line", "column"],
        );
        assert_err("", &["no root element"]);
        let cut = &sample().to_ssd()[..200];
        assert_err(cut, &["malformed XML"]);
        assert_err(
            "<ssd:SystemStructureDescription version=\"1.0\" name=\"x\"/>",
            &["undeclared namespace prefix 'ssd'"],
        );
    }

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

    #[test]
    fn bad_numbers() {
        let xml = sample().to_ssd();
        let e = xml.replace("value=\"0.001\"", "value=\"abc\"");
        assert_err(
            &e,
            &[
                "<ssv:Real>",
                "parameter 'S_base': value \"abc\" is not a valid Real",
            ],
        );
        let e = xml.replace("value=\"-2147483648\"", "value=\"1.5\"");
        assert_err(
            &e,
            &["parameter 'mode': value \"1.5\" is not a valid Integer"],
        );
        let e = xml.replace("value=\"false\"", "value=\"yes\"");
        assert_err(&e, &["value \"yes\" is not a valid Boolean"]);
        let e = xml.replace("startTime=\"0.5\"", "startTime=\"soon\"");
        assert_err(
            &e,
            &[
                "<ssd:DefaultExperiment>",
                "startTime=\"soon\" is not a number",
            ],
        );
        let e = xml.replace("factor=\"-2.5\"", "factor=\"inf\"");
        assert_err(
            &e,
            &[
                "<ssc:LinearTransformation>",
                "factor=\"inf\" is not a number",
            ],
        );
        let e = xml.replace("baseStepSize=\"0.001\"", "baseStepSize=\"0\"");
        assert_err(&e, &["<osp:FixedStepAlgorithm>", "not positive"]);
        assert_eq!(parse_double("1e-3"), Some(1e-3));
        assert_eq!(parse_double(" -INF "), Some(f64::NEG_INFINITY));
        assert_eq!(parse_double(".5"), Some(0.5));
        assert_eq!(parse_double("0x10"), None);
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
