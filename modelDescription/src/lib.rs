//! Typed FMI 2.0 model description: the schema as Rust types, its writer, its reader and its rules.
//!
//! The export layer builds a [`ModelDescription`] from a model's declared variables, [`check`]s it
//! against the FMI 2.0 rules (legal causality/variability/initial combinations, start values,
//! units, model structure) and writes it with [`ModelDescription::to_xml`]. The master reads any
//! FMU's description with [`ModelDescription::from_xml`]. The GUID is derived from the content
//! ([`ModelDescription::content_guid`]).

mod rules;
mod schema;

pub use rules::{check, direct_feedthrough, Problem};
pub use schema::*;

use std::fmt;

/// Why a description could not be written or read.
#[derive(Debug)]
pub enum Error {
    /// The description breaks FMI 2.0 rules; every problem is listed.
    Invalid(Vec<Problem>),
    /// The XML could not be parsed into an FMI 2.0 description.
    Parse(String),
    /// The XML could not be produced.
    Write(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Invalid(problems) => {
                write!(f, "invalid model description:")?;
                for p in problems {
                    write!(f, "\n  - {p}")?;
                }
                Ok(())
            }
            Error::Parse(m) => write!(f, "cannot read modelDescription.xml: {m}"),
            Error::Write(m) => write!(f, "cannot write modelDescription.xml: {m}"),
        }
    }
}

impl std::error::Error for Error {}

impl ModelDescription {
    /// Serialize to XML after checking the FMI 2.0 rules.
    pub fn to_xml(&self) -> Result<String, Error> {
        let problems = check(self);
        if !problems.is_empty() {
            return Err(Error::Invalid(problems));
        }
        self.to_xml_unchecked()
    }

    fn to_xml_unchecked(&self) -> Result<String, Error> {
        let mut body = String::new();
        let mut ser = quick_xml::se::Serializer::with_root(&mut body, Some("fmiModelDescription"))
            .map_err(|e| Error::Write(e.to_string()))?;
        ser.indent(' ', 2);
        serde::Serialize::serialize(self, ser).map_err(|e| Error::Write(e.to_string()))?;
        Ok(format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n{body}\n"
        ))
    }

    /// Parse a modelDescription.xml (ours or any other exporter's; unknown elements are ignored).
    pub fn from_xml(xml: &str) -> Result<Self, Error> {
        quick_xml::de::from_str(xml).map_err(|e| Error::Parse(e.to_string()))
    }

    /// The GUID derived from the content: a 128-bit FNV-1a hash of the description written with
    /// an empty GUID, so the same interface always gets the same GUID and any change a new one.
    pub fn content_guid(&self) -> Result<String, Error> {
        let mut blank = self.clone();
        blank.guid.clear();
        let xml = blank.to_xml_unchecked()?;
        Ok(format_guid(fnv1a_128(xml.as_bytes())))
    }

    /// Set the GUID from the content (see [`Self::content_guid`]).
    pub fn with_content_guid(mut self) -> Result<Self, Error> {
        self.guid = self.content_guid()?;
        Ok(self)
    }

    /// The co-simulation model identifier, if the FMU supports co-simulation.
    pub fn model_identifier(&self) -> Option<&str> {
        self.co_simulation
            .as_ref()
            .map(|cs| cs.model_identifier.as_str())
    }

    /// The variable with this name.
    pub fn variable(&self, name: &str) -> Option<&ScalarVariable> {
        self.model_variables
            .variables
            .iter()
            .find(|v| v.name == name)
    }
}

/// 128-bit FNV-1a.
pub fn fnv1a_128(bytes: &[u8]) -> u128 {
    const OFFSET: u128 = 0x6c62272e07bb014262b821756295c58d;
    const PRIME: u128 = 0x0000000001000000000000000000013B;
    bytes
        .iter()
        .fold(OFFSET, |h, &b| (h ^ b as u128).wrapping_mul(PRIME))
}

fn format_guid(h: u128) -> String {
    let x = format!("{h:032x}");
    format!(
        "{{{}-{}-{}-{}-{}}}",
        &x[0..8],
        &x[8..12],
        &x[12..16],
        &x[16..20],
        &x[20..32]
    )
}
