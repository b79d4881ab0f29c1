//! Parameter presets of the paper's case study I (wind + PV low-pass, BESS complement).

use crate::adaptation::{active_gains, reactive_gains, renormalize_with_floor};
use crate::adpf::{Adpf, LowPassSpec};
use crate::error::Result;
use crate::fleet::Fleet;
use crate::local::{GflFpModel, GfmPfModel, VqModel, MU_MIN_GFM};
use crate::tdes::TDes;
use serde::{Deserialize, Serialize};

/// Case study I parameters (`docs/control.md` §9). Unit order everywhere: wind, PV, BESS.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaseStudyI {
    /// `T_pf = 1/(5.55 s + 33.33)`, `T_qv = 0.01`, `τ_q = 0.01 s`.
    pub tdes: TDes,
    /// DVPP base, MVA.
    pub s_dvpp: f64,
    /// Ratings of wind, PV, BESS, MVA.
    pub s_rated: [f64; 3],
    /// Low-pass time constant of the wind unit (its `τ_dc`), s.
    pub tau_wind: f64,
    /// Low-pass time constant of the PV unit (its `τ_dc`), s.
    pub tau_pv: f64,
    /// dc-side time constant of the BESS (not used by its complement ADPF), s.
    pub tau_bess_dc: f64,
    /// PLL roll-off used when a unit is run grid-following: `1/k_p` of the paper's PLL
    /// (`k_p = 60`), an approximation of its bandwidth — an assumption of this crate.
    pub tau_pll: f64,
}

impl Default for CaseStudyI {
    fn default() -> Self {
        Self::new()
    }
}

impl CaseStudyI {
    /// The paper's values; the units are [`Fleet::case_study_i`]'s.
    pub fn new() -> Self {
        // Unit order everywhere: wind, PV, BESS (the fleet's).
        let fleet = Fleet::case_study_i();
        let [wind, pv, bess] = [0, 1, 2].map(|k| fleet.units[k].kind);
        Self {
            tdes: TDes::inertia_droop(5.55, 33.33, 0.01, 0.01).expect("case-study T_des is valid"),
            s_dvpp: 96.0,
            s_rated: [wind.s_rated, pv.s_rated, bess.s_rated],
            tau_wind: wind.tau_dc,
            tau_pv: pv.tau_dc,
            tau_bess_dc: bess.tau_dc,
            tau_pll: 1.0 / 60.0,
        }
    }

    /// Active dc gains `[μ_wind, μ_pv]` from available powers (MW), floored at
    /// [`MU_MIN_GFM`] (both are grid-forming low-pass units) and renormalized to sum 1.
    pub fn active_gains(&self, p_avail_wind: f64, p_avail_pv: f64) -> Result<[f64; 2]> {
        let raw = active_gains(&[p_avail_wind, p_avail_pv]).unwrap_or_else(|_| vec![0.0, 0.0]);
        let mu = renormalize_with_floor(&raw, &[true, true], MU_MIN_GFM)?;
        Ok([mu[0], mu[1]])
    }

    /// Nominal active dc gains (proportional to the ratings 46 and 73 MVA).
    pub fn nominal_active_gains(&self) -> [f64; 2] {
        self.active_gains(self.s_rated[0], self.s_rated[1])
            .expect("nominal gains are feasible")
    }

    /// p-f ADPFs `[wind LPF, PV LPF, BESS complement]` for the given LPF dc gains.
    pub fn active_adpfs(&self, mu_wind: f64, mu_pv: f64) -> Result<[Adpf; 3]> {
        let wind = Adpf::low_pass(mu_wind, self.tau_wind, 1)?;
        let pv = Adpf::low_pass(mu_pv, self.tau_pv, 1)?;
        let bess = Adpf::complement_of(&[wind.clone(), pv.clone()])?;
        Ok([wind, pv, bess])
    }

    /// The low-pass specs of wind and PV (what a participation bank needs).
    pub fn lpf_specs(&self, mu_wind: f64, mu_pv: f64) -> Result<[LowPassSpec; 2]> {
        Ok([
            LowPassSpec::new(mu_wind, self.tau_wind, 1)?,
            LowPassSpec::new(mu_pv, self.tau_pv, 1)?,
        ])
    }

    /// Reactive gains from the PQ circle at active operating points `p` (MW) of the three units.
    pub fn reactive_gains(&self, p: [f64; 3]) -> Result<[f64; 3]> {
        let mu = reactive_gains(&self.s_rated, &p)?;
        Ok([mu[0], mu[1], mu[2]])
    }

    /// All-grid-forming p-f models at nominal gains.
    pub fn gfm_pf_models(&self) -> Result<Vec<GfmPfModel>> {
        let [mw, mp] = self.nominal_active_gains();
        self.active_adpfs(mw, mp)?
            .iter()
            .map(|a| GfmPfModel::new(&self.tdes, a))
            .collect()
    }

    /// Grid-forming v-q models at reactive gains for zero active operating point.
    pub fn vq_models(&self) -> Result<Vec<VqModel>> {
        self.reactive_gains([0.0; 3])?
            .iter()
            .map(|mu| VqModel::grid_forming(&self.tdes, *mu))
            .collect()
    }

    /// Case study II split: each ADPF is divided into a grid-forming share `ε` and a
    /// grid-following share `1 − ε` (`0 < ε < 1`). Returns (grid-forming, grid-following) models.
    pub fn hybrid_pf_models(&self, eps: f64) -> Result<(Vec<GfmPfModel>, Vec<GflFpModel>)> {
        let [mw, mp] = self.nominal_active_gains();
        if !(eps > 0.0 && eps < 1.0) {
            return Err(crate::error::DvppError::InvalidParameter {
                what: "grid-forming share eps".into(),
                reason: format!("need 0 < eps < 1, got {eps}"),
            });
        }
        let gfm_adpfs = self.split(mw, mp, eps)?;
        let gfl_adpfs = self.split(mw, mp, 1.0 - eps)?;
        let gfm = gfm_adpfs
            .iter()
            .map(|a| GfmPfModel::new(&self.tdes, a))
            .collect::<Result<Vec<_>>>()?;
        let gfl = gfl_adpfs
            .iter()
            .map(|a| GflFpModel::new(&self.tdes, a, self.tau_pll, 1))
            .collect::<Result<Vec<_>>>()?;
        Ok((gfm, gfl))
    }

    /// `[wind, PV, BESS]` ADPFs at nominal gains scaled by `share` (`m = ε m + (1 − ε) m`).
    fn split(&self, mw: f64, mp: f64, share: f64) -> Result<[Adpf; 3]> {
        let [w, p, b] = self.active_adpfs(mw, mp)?;
        Ok([w.scaled(share)?, p.scaled(share)?, b.scaled(share)?])
    }
}
