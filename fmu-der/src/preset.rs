//! The named DER presets (`[model] preset`): a table of units and the start values each gives.

use crate::{AdpfKind, Mode};
use dvpp_control::MU_MIN_GFM;
use dvpp_control::{active_gains, renormalize_with_floor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// The p-f ADPF a preset unit is given.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// A low-pass with `τ` = the unit's `τ_dc` and dc gain its share of the low-pass units'
    /// ratings (floored, renormalized to sum 1).
    LowPass,
    /// The complement of all low-pass presets (their time constants and dc gains).
    Complement,
}

/// A named unit: rating, dc side, dispatch and p-f ADPF shape. Reactive ADPFs are static,
/// proportional to the unit's share of the presets' ratings (the reactive capacity at zero
/// active power).
#[derive(Debug, PartialEq)]
pub struct Preset {
    /// What `[model] preset` names it.
    pub name: &'static str,
    /// Rating, MVA.
    pub s_rated: f64,
    /// Time constant of the dc source, s (a low-pass unit's ADPF `τ` too).
    pub tau_dc: f64,
    /// Dispatch, pu on S_base.
    pub p: f64,
    /// Available power, pu on S_base.
    pub p_avail0: f64,
    /// The primary source can absorb power (a battery): dc source within ±P_avail.
    pub storage: bool,
    /// The p-f ADPF.
    pub shape: Shape,
}

/// The presets: case study I's units (`docs/control.md` §9; values of
/// [`dvpp_control::CaseStudyI`]). A new DER kind is one more entry.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "wind",
        s_rated: 46.0,
        tau_dc: 1.5,
        p: 0.2,
        p_avail0: 0.4,
        storage: false,
        shape: Shape::LowPass,
    },
    Preset {
        name: "pv",
        s_rated: 73.0,
        tau_dc: 0.6,
        p: 0.3,
        p_avail0: 0.6,
        storage: false,
        shape: Shape::LowPass,
    },
    Preset {
        name: "bess",
        s_rated: 60.0,
        tau_dc: 0.2,
        p: 0.1,
        p_avail0: 0.6,
        storage: true,
        shape: Shape::Complement,
    },
];

impl Preset {
    /// The preset called `name`, or why there is none.
    pub fn named(name: &str) -> Result<&'static Preset, String> {
        PRESETS.iter().find(|p| p.name == name).ok_or_else(|| {
            let names: Vec<_> = PRESETS.iter().map(|p| format!("\"{}\"", p.name)).collect();
            format!("unknown preset \"{name}\": {}", names.join(", "))
        })
    }
}

impl Serialize for Preset {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name)
    }
}

impl<'de> Deserialize<'de> for &'static Preset {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        Preset::named(&name).map_err(serde::de::Error::custom)
    }
}

/// Start values of one channel's ADPF parameters.
#[derive(Debug, Clone)]
pub struct AdpfDefaults {
    pub kind: AdpfKind,
    pub tau: f64,
    pub tau2: f64,
    pub order: i32,
    pub order2: i32,
    /// Complement: time constants of the closed low-pass units.
    pub lpf_tau: Vec<f64>,
}

impl AdpfDefaults {
    fn of(kind: AdpfKind, tau: f64) -> Self {
        AdpfDefaults {
            kind,
            tau,
            tau2: 0.1,
            order: 1,
            order2: 1,
            lpf_tau: Vec::new(),
        }
    }
}

/// Start values a preset gives (the rest are the generic unit's).
#[derive(Debug, Clone)]
pub struct UnitDefaults {
    pub mode: Mode,
    pub s_rated: f64,
    pub tau_dc: f64,
    pub p: f64,
    pub p_avail0: f64,
    pub mu_p: f64,
    pub mu_q: f64,
    pub mu_p_lpf: Vec<f64>,
    /// The primary source can absorb power (a battery): dc source within ±P_avail.
    pub storage: bool,
    pub adpf_p: AdpfDefaults,
    pub adpf_q: AdpfDefaults,
}

impl UnitDefaults {
    /// The same unit at `rating` MVA: rating, available power and dispatch scale together
    /// (participation gains are the operator's to set).
    pub fn resized(self, rating: Option<f64>) -> Result<Self, String> {
        let Some(r) = rating else {
            return Ok(self);
        };
        if !(r > 0.0 && r.is_finite()) {
            return Err(format!("[model] rating = {r}: a rating in MVA is > 0"));
        }
        let k = r / self.s_rated;
        Ok(UnitDefaults {
            s_rated: r,
            p: self.p * k,
            p_avail0: self.p_avail0 * k,
            ..self
        })
    }

    /// The generic unit (no preset): a static ADPF `m = μ_p`, so that its frequency channel is
    /// `Δf = -1/(μ_p (H s + D)) Δp`; or the preset's unit.
    pub fn of(preset: Option<&Preset>) -> Self {
        let generic = UnitDefaults {
            mode: Mode::GridForming,
            s_rated: 60.0,
            tau_dc: 0.2,
            p: 0.3,
            p_avail0: 0.6,
            mu_p: 1.0,
            mu_q: 1.0,
            mu_p_lpf: Vec::new(),
            storage: false,
            adpf_p: AdpfDefaults::of(AdpfKind::Static, 1.0),
            adpf_q: AdpfDefaults::of(AdpfKind::Static, 1.0),
        };
        let Some(preset) = preset else {
            return generic;
        };
        let total: f64 = PRESETS.iter().map(|u| u.s_rated).sum();
        let (low_pass, gains) = low_pass_gains();
        let common = UnitDefaults {
            s_rated: preset.s_rated,
            tau_dc: preset.tau_dc,
            p: preset.p,
            p_avail0: preset.p_avail0,
            mu_q: preset.s_rated / total,
            storage: preset.storage,
            ..generic
        };
        match preset.shape {
            Shape::LowPass => {
                let k = low_pass
                    .iter()
                    .position(|u| *u == preset)
                    .expect("a low-pass preset is in the table");
                UnitDefaults {
                    mu_p: gains[k],
                    adpf_p: AdpfDefaults::of(AdpfKind::LowPass, preset.tau_dc),
                    ..common
                }
            }
            Shape::Complement => UnitDefaults {
                mu_p: 0.0,
                mu_p_lpf: gains,
                adpf_p: AdpfDefaults {
                    lpf_tau: low_pass.iter().map(|u| u.tau_dc).collect(),
                    ..AdpfDefaults::of(AdpfKind::Complement, 1.0)
                },
                ..common
            },
        }
    }
}

/// The low-pass presets and their nominal dc gains: proportional to their ratings, floored at
/// [`MU_MIN_GFM`] (grid-forming units) and renormalized to sum 1.
fn low_pass_gains() -> (Vec<&'static Preset>, Vec<f64>) {
    let units: Vec<&Preset> = PRESETS
        .iter()
        .filter(|u| u.shape == Shape::LowPass)
        .collect();
    let ratings: Vec<f64> = units.iter().map(|u| u.s_rated).collect();
    let raw = active_gains(&ratings).unwrap_or_else(|_| vec![0.0; units.len()]);
    let gains = renormalize_with_floor(&raw, &vec![true; units.len()], MU_MIN_GFM)
        .expect("nominal gains are feasible");
    (units, gains)
}

#[cfg(test)]
mod tests {
    use super::*;
    use dvpp_control::CaseStudyI;

    /// The table holds case study I's values: ratings, time constants, nominal gains.
    #[test]
    fn presets_are_case_study_one() {
        let cs = CaseStudyI::new();
        let [mu_wind, mu_pv] = cs.nominal_active_gains();
        let total: f64 = cs.s_rated.iter().sum();
        let at = |name| UnitDefaults::of(Some(Preset::named(name).unwrap()));
        let (wind, pv, bess) = (at("wind"), at("pv"), at("bess"));
        assert_eq!(
            [wind.s_rated, pv.s_rated, bess.s_rated],
            cs.s_rated,
            "ratings"
        );
        assert_eq!(
            [wind.tau_dc, pv.tau_dc, bess.tau_dc],
            [cs.tau_wind, cs.tau_pv, cs.tau_bess_dc]
        );
        assert_eq!([wind.adpf_p.tau, pv.adpf_p.tau], [cs.tau_wind, cs.tau_pv]);
        assert_eq!([wind.mu_p, pv.mu_p, bess.mu_p], [mu_wind, mu_pv, 0.0]);
        assert_eq!(bess.mu_p_lpf, vec![mu_wind, mu_pv]);
        assert_eq!(bess.adpf_p.lpf_tau, vec![cs.tau_wind, cs.tau_pv]);
        for (u, s) in [&wind, &pv, &bess].iter().zip(cs.s_rated) {
            assert_eq!(u.mu_q, s / total);
        }
        assert!(bess.storage && !wind.storage && !pv.storage);
        assert_eq!(bess.adpf_p.kind, AdpfKind::Complement);
    }

    #[test]
    fn unknown_presets_are_named() {
        let e = Preset::named("hydro").unwrap_err();
        assert!(e.contains("hydro") && e.contains("\"wind\""), "{e}");
    }
}
