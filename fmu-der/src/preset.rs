//! The start values a named DER kind (`[model] preset`) gives: its own values, and the dc gains and reactive share it has in case study I's fleet.

use crate::{AdpfKind, Mode};
/// The DER kinds (`[model] preset` names one): independent presets, each on its own.
pub use dvpp_control::fleet::{DerKind as Preset, Shape, KINDS as PRESETS};
use dvpp_control::Fleet;

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
        // The shares follow from the fleet the presets are units of: case study I's (a kind
        // outside it, as if added to it). Another kind changes no member's values.
        let mut fleet = Fleet::case_study_i();
        if fleet.position_of_kind(preset).is_none() {
            fleet = fleet.with(preset.name, *preset);
        }
        let k = fleet
            .position_of_kind(preset)
            .expect("the preset is a unit of its fleet");
        let low_pass = fleet.low_pass();
        let gains = fleet.nominal_active_gains();
        let common = UnitDefaults {
            s_rated: preset.s_rated,
            tau_dc: preset.tau_dc,
            p: preset.p,
            p_avail0: preset.p_avail0,
            mu_q: fleet.reactive_share(k),
            storage: preset.storage,
            ..generic
        };
        match preset.shape {
            Shape::LowPass => {
                let j = low_pass
                    .iter()
                    .position(|&u| u == k)
                    .expect("a low-pass unit is among the fleet's low-pass units");
                UnitDefaults {
                    mu_p: gains[j],
                    adpf_p: AdpfDefaults::of(AdpfKind::LowPass, preset.tau_dc),
                    ..common
                }
            }
            Shape::Complement => UnitDefaults {
                mu_p: 0.0,
                mu_p_lpf: gains,
                adpf_p: AdpfDefaults {
                    lpf_tau: low_pass
                        .iter()
                        .map(|&u| fleet.units[u].kind.tau_dc)
                        .collect(),
                    ..AdpfDefaults::of(AdpfKind::Complement, 1.0)
                },
                ..common
            },
        }
    }
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

    /// A kind that is no unit of case study I is valued as if added to its fleet, and the
    /// members keep their case-study values, not the four-unit fleet's: a preset's start
    /// values depend on its fleet, never on the other rows of [`PRESETS`].
    #[test]
    fn another_kind_changes_no_case_study_unit_s_start_values() {
        let hydro = Preset {
            name: "hydro",
            s_rated: 40.0,
            tau_dc: 5.0,
            p: 0.1,
            p_avail0: 0.3,
            storage: false,
            shape: Shape::LowPass,
        };
        let four = Fleet::case_study_i().with("hydro", hydro);
        let mu4 = four.nominal_active_gains();
        let h = UnitDefaults::of(Some(&hydro));
        assert_eq!((h.mu_p, h.mu_q), (mu4[2], 40.0 / 219.0));
        let mu3 = Fleet::case_study_i().nominal_active_gains();
        let at = |name| UnitDefaults::of(Some(Preset::named(name).unwrap()));
        let (wind, bess) = (at("wind"), at("bess"));
        assert_eq!(wind.mu_p, mu3[0]);
        assert_ne!(wind.mu_p, mu4[0], "the four-unit fleet's gain differs");
        assert_eq!(wind.mu_q, 46.0 / 179.0);
        assert_eq!(bess.mu_p_lpf, mu3);
    }

    #[test]
    fn unknown_presets_are_named() {
        let e = Preset::named("no_such_kind").unwrap_err();
        assert!(e.contains("no_such_kind") && e.contains("\"wind\""), "{e}");
    }
}
