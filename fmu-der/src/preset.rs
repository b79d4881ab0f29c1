//! Start values of the paper's case-study units (wind, PV, BESS) that `[model] preset` selects.

use dvpp_control::CaseStudyI;
use serde::{Deserialize, Serialize};

/// A case-study I unit (`docs/control.md` §9): wind and PV low-pass with `τ` = their `τ_dc` and dc
/// gains proportional to their ratings, the BESS the complement of both; reactive ADPFs static,
/// proportional to the reactive capacity at zero active power (the ratings).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    Wind,
    Pv,
    Bess,
}

/// Start values of one channel's ADPF parameters.
#[derive(Debug, Clone)]
pub struct AdpfDefaults {
    pub kind: i32,
    pub tau: f64,
    pub tau2: f64,
    pub order: i32,
    pub order2: i32,
    /// Complement: time constants of the closed low-pass units.
    pub lpf_tau: Vec<f64>,
}

impl AdpfDefaults {
    fn of(kind: i32, tau: f64) -> Self {
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
    pub mode: i32,
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
    pub fn of(preset: Option<Preset>) -> Self {
        use crate::kind::{COMPLEMENT, LOW_PASS, STATIC};
        let generic = UnitDefaults {
            mode: crate::GRID_FORMING,
            s_rated: 60.0,
            tau_dc: 0.2,
            p: 0.3,
            p_avail0: 0.6,
            mu_p: 1.0,
            mu_q: 1.0,
            mu_p_lpf: Vec::new(),
            storage: false,
            adpf_p: AdpfDefaults::of(STATIC, 1.0),
            adpf_q: AdpfDefaults::of(STATIC, 1.0),
        };
        let Some(preset) = preset else {
            return generic;
        };
        let cs = CaseStudyI::new();
        let [mu_wind, mu_pv] = cs.nominal_active_gains();
        let total: f64 = cs.s_rated.iter().sum();
        let share = |k: usize| cs.s_rated[k] / total;
        match preset {
            Preset::Wind => UnitDefaults {
                s_rated: cs.s_rated[0],
                tau_dc: cs.tau_wind,
                p: 0.2,
                p_avail0: 0.4,
                mu_p: mu_wind,
                mu_q: share(0),
                adpf_p: AdpfDefaults::of(LOW_PASS, cs.tau_wind),
                ..generic
            },
            Preset::Pv => UnitDefaults {
                s_rated: cs.s_rated[1],
                tau_dc: cs.tau_pv,
                p: 0.3,
                p_avail0: 0.6,
                mu_p: mu_pv,
                mu_q: share(1),
                adpf_p: AdpfDefaults::of(LOW_PASS, cs.tau_pv),
                ..generic
            },
            Preset::Bess => UnitDefaults {
                s_rated: cs.s_rated[2],
                tau_dc: cs.tau_bess_dc,
                p: 0.1,
                p_avail0: 0.6,
                mu_p: 0.0,
                mu_q: share(2),
                mu_p_lpf: vec![mu_wind, mu_pv],
                storage: true,
                adpf_p: AdpfDefaults {
                    lpf_tau: vec![cs.tau_wind, cs.tau_pv],
                    ..AdpfDefaults::of(COMPLEMENT, 1.0)
                },
                ..generic
            },
        }
    }
}
