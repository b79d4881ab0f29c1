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

mod annotations;
mod connections;
#[cfg(test)]
mod fixtures;
mod model;
mod package;
mod parameters;
mod reader;
mod writer;
mod xml;

pub use model::{
    Component, Connection, Connector, Kind, LinearTransformation, Parameter, System, Type, Value,
};
pub use package::{read, Package};
pub use reader::parse_ssd;
pub use writer::write_copies;
pub use xml::MAX_DEPTH;

use std::fmt;

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
