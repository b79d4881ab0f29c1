//! `[model]` of the FMU's `resources/config.toml`: which case the grid is built from, with
//! extra events and the PCC filter override.

use crate::case::{self, Case, Event};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The built-in case used when `[model]` names none.
pub const DEFAULT_CASE: &str = "ieee9_dvpp";

/// `[model]` of `resources/config.toml`: which case the grid is built from.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridConfig {
    /// A built-in case: `ieee9`, `ieee9_dvpp`, `ieee9_hybrid`, `ieee9_mv` or `thevenin_dvpp`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub case: Option<String>,
    /// A case file (TOML) in the FMU's `resources/` directory, relative to it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub case_file: Option<String>,
    /// Events appended to the case's own (e.g. a load step on a case that has none).
    #[serde(default, rename = "event", skip_serializing_if = "Vec::is_empty")]
    pub events: Vec<Event>,
    /// Overrides the case's PCC frequency-measurement time constant `[pcc] f_filter_t`, s (and
    /// the `f_filter_t` of every `[[poc]]` and `[[dvpp_pcc]]`, so that all frequencies are measured alike).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pcc_f_filter_t: Option<f64>,
}

impl GridConfig {
    /// Read and validate the case this configuration selects, with its extra events appended.
    pub fn load_case(&self, resources: Option<&Path>) -> Result<Case, String> {
        let mut case = match (&self.case, &self.case_file) {
            (Some(_), Some(_)) => {
                return Err("[model] sets both `case` and `case_file`; choose one".into())
            }
            (None, Some(file)) => {
                let rel = Path::new(file);
                if rel.is_absolute()
                    || rel
                        .components()
                        .any(|c| !matches!(c, std::path::Component::Normal(_)))
                {
                    return Err(format!(
                        "[model] case_file = \"{file}\" must be a relative path inside resources/"
                    ));
                }
                let dir = resources.ok_or_else(|| {
                    format!("[model] case_file = \"{file}\" needs the FMU's resources directory")
                })?;
                let path = dir.join(rel);
                let text = fmi_export::read_resource(&path)
                    .map_err(|e| format!("case file {file}: {e}"))?;
                Case::from_toml_str(&text).map_err(|e| format!("case file {file}: {e}"))?
            }
            (name, None) => {
                let name = name.as_deref().unwrap_or(DEFAULT_CASE);
                let text = case::builtin_text(name).ok_or_else(|| {
                    format!(
                        "[model] case = \"{name}\" is not a built-in case (built-in: {})",
                        Case::builtin_names().join(", ")
                    )
                })?;
                Case::from_toml_str(text).map_err(|e| format!("built-in case {name}: {e}"))?
            }
        };
        if !self.events.is_empty() {
            case.events.extend(self.events.iter().cloned());
            case.validate()
                .map_err(|e| format!("[model] event tables: {e}"))?;
        }
        if let Some(t) = self.pcc_f_filter_t {
            let pcc = case
                .pcc
                .as_mut()
                .ok_or("[model] pcc_f_filter_t: the case has no [pcc] table")?;
            pcc.f_filter_t = t;
            for poc in &mut case.pocs {
                poc.f_filter_t = t;
            }
            for pcc in &mut case.dvpp_pccs {
                pcc.f_filter_t = t;
            }
            case.validate()
                .map_err(|e| format!("[model] pcc_f_filter_t = {t}: {e}"))?;
        }
        Ok(case)
    }
}
