//! `[model]` of the FMU's `resources/config.toml`: the units, the loads and whether a Thevenin
//! source is present, as a built-in case (`case = "dvpp3"`, the default, or `"island"`) or listed.

use dvpp_control::fleet::BESS;
use serde::{Deserialize, Serialize};

/// The built-in case used when `[model]` names none.
pub const DEFAULT_CASE: &str = "dvpp3";

/// The built-in cases.
pub const CASES: &[&str] = &["dvpp3", "island"];

/// Largest number of units and of loads (the exact energy integrals cost one matrix exponential
/// of twice the state's size per unit and topology: 16 units take 0.5 s to discretize).
pub const MAX_UNITS: usize = 16;
pub const MAX_LOADS: usize = 32;

/// One converter unit: its name and the start values of its parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UnitSpec {
    pub name: String,
    /// Rating `S_rated`, MVA.
    pub s_rated: f64,
    /// Primary-source lag `tau_dc`, s.
    pub tau_dc: f64,
    /// Active power injected at the PCC at initialization, pu on `S_base`.
    #[serde(default)]
    pub p0: f64,
    /// Reactive power injected at the PCC at initialization, pu on `S_base`.
    #[serde(default)]
    pub q0: f64,
}

/// One series R-L load, given by what it draws at 1 pu voltage (pu on `S_base`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoadSpec {
    pub name: String,
    pub p: f64,
    pub q: f64,
    /// Switch-on time, s (0: connected from the start; negative: never).
    #[serde(default)]
    pub t_on: f64,
}

/// The plant's structure: units, loads, Thevenin source.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    pub units: Vec<UnitSpec>,
    pub loads: Vec<LoadSpec>,
    /// A Thevenin source is declared (its parameter `thevenin.enabled` can still turn it off).
    pub thevenin: bool,
}

/// `[model]` of `resources/config.toml`.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantConfig {
    /// A built-in case: `dvpp3` (default) or `island`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub case: Option<String>,
    /// Units replacing the case's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub units: Option<Vec<UnitSpec>>,
    /// Loads replacing the case's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loads: Option<Vec<LoadSpec>>,
    /// Whether a Thevenin source is declared (replacing the case's choice).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thevenin: Option<bool>,
}

fn unit(name: &str, s_rated: f64, tau_dc: f64, p0: f64) -> UnitSpec {
    UnitSpec {
        name: name.into(),
        s_rated,
        tau_dc,
        p0,
        q0: 0.0,
    }
}

fn load(name: &str, p: f64, q: f64, t_on: f64) -> LoadSpec {
    LoadSpec {
        name: name.into(),
        p,
        q,
        t_on,
    }
}

/// The built-in case `name`.
pub fn builtin(name: &str) -> Option<Layout> {
    match name {
        // Case study I: wind, PV and BESS at the case-I dispatch (31.5 MW, 50 MW, 0) on a
        // Thevenin equivalent, a base load and the 28 MW step at 1 s.
        "dvpp3" => Some(Layout {
            units: dvpp_control::Fleet::case_study_i()
                .units
                .iter()
                .zip([0.315, 0.5, 0.0])
                .map(|(u, p0)| unit(&u.name, u.kind.s_rated, u.kind.tau_dc, p0))
                .collect(),
            loads: vec![load("base", 0.8, 0.1, 0.0), load("step", 0.28, 0.02, 1.0)],
            thevenin: true,
        }),
        // One 60 MVA unit feeding a series R-L load of 0.5 + j0.1 pu on its rating, and a step
        // of 0.1 + j0.02 pu of its rating at 1 s; no Thevenin source.
        "island" => Some(Layout {
            units: vec![unit("bess", BESS.s_rated, BESS.tau_dc, 0.0)],
            loads: vec![load("base", 0.3, 0.06, 0.0), load("step", 0.06, 0.012, 1.0)],
            thevenin: false,
        }),
        _ => None,
    }
}

impl PlantConfig {
    /// The layout this configuration selects, checked.
    pub fn layout(&self) -> Result<Layout, String> {
        let name = self.case.as_deref().unwrap_or(DEFAULT_CASE);
        let mut layout = builtin(name).ok_or_else(|| {
            format!(
                "[model] case = \"{name}\" is not a built-in case (built-in: {})",
                CASES.join(", ")
            )
        })?;
        if let Some(units) = &self.units {
            layout.units = units.clone();
        }
        if let Some(loads) = &self.loads {
            layout.loads = loads.clone();
        }
        if let Some(th) = self.thevenin {
            layout.thevenin = th;
        }
        layout.check()?;
        Ok(layout)
    }
}

impl Layout {
    fn check(&self) -> Result<(), String> {
        if self.units.is_empty() || self.units.len() > MAX_UNITS {
            return Err(format!(
                "[model] units: {} entries, expected 1 to {MAX_UNITS}",
                self.units.len()
            ));
        }
        if self.loads.len() > MAX_LOADS {
            return Err(format!("[model] loads: at most {MAX_LOADS} entries"));
        }
        for (k, u) in self.units.iter().enumerate() {
            let at = format!("[model] units[{}] '{}'", k + 1, u.name);
            if !(u.s_rated.is_finite() && u.s_rated > 0.0) {
                return Err(format!("{at}: s_rated = {} must be positive", u.s_rated));
            }
            if !(u.tau_dc.is_finite() && u.tau_dc > 0.0) {
                return Err(format!("{at}: tau_dc = {} must be positive", u.tau_dc));
            }
            if !(u.p0.is_finite() && u.q0.is_finite()) {
                return Err(format!("{at}: p0, q0 must be finite"));
            }
        }
        for (j, l) in self.loads.iter().enumerate() {
            let at = format!("[model] loads[{}] '{}'", j + 1, l.name);
            if !(l.p.is_finite() && l.p >= 0.0 && l.q.is_finite() && l.q > 0.0) {
                return Err(format!(
                    "{at}: p = {}, q = {}: a series R-L load needs p >= 0 and q > 0",
                    l.p, l.q
                ));
            }
            if !l.t_on.is_finite() {
                return Err(format!("{at}: t_on must be finite"));
            }
        }
        Ok(())
    }
}
