//! Design-time checks: participation, aggregation (grid-forming, hybrid, voltage) and stability.
//!
//! Aggregation checks evaluate the **realized** local models (their simulated matrices, via
//! `freq_response`) on a frequency grid and compare with `T_des`; they fail with
//! [`DvppError::AggregationViolated`] beyond a relative tolerance.

use crate::adpf::{participation_error, Adpf};
use crate::error::{DvppError, Result};
use crate::local::{rolloff_inverse_at, GflFpModel, GfmPfModel, VqModel};
use crate::tdes::TDes;
use nalgebra::Complex;
use serde::{Deserialize, Serialize};

/// Participation condition `max_ω |Σ m_i(jω) − 1| ≤ tol`; returns the worst deviation.
pub fn check_participation(set: &[Adpf], grid: &[f64], tol: f64) -> Result<f64> {
    let (e, w) = participation_error(set, grid);
    if e <= tol {
        Ok(e)
    } else {
        Err(DvppError::ParticipationViolated {
            max_error: e,
            omega: w,
            tol,
        })
    }
}

fn worst<F: Fn(f64) -> f64>(grid: &[f64], f: F) -> (f64, f64) {
    let mut out = (0.0, grid.first().copied().unwrap_or(0.0));
    for &w in grid {
        let e = f(w);
        if e > out.0 || e.is_nan() {
            out = (e, w);
        }
    }
    out
}

fn verdict(condition: &str, (e, w): (f64, f64), tol: f64) -> Result<f64> {
    if e <= tol {
        Ok(e)
    } else {
        Err(DvppError::AggregationViolated {
            condition: condition.into(),
            max_rel_error: e,
            omega: w,
            tol,
        })
    }
}

/// Grid-forming frequency aggregation `(Σ_i T_i^pf(jω)⁻¹)⁻¹ = T_pf(jω)`; returns the worst
/// relative error `|agg − T_pf|/|T_pf|` on the grid.
pub fn check_gfm_aggregation(
    tdes: &TDes,
    gfm: &[GfmPfModel],
    grid: &[f64],
    tol: f64,
) -> Result<f64> {
    let e = worst(grid, |w| {
        let y: Complex<f64> = gfm
            .iter()
            .map(|u| Complex::new(1.0, 0.0) / u.freq_response(w))
            .sum();
        let t = tdes.pf_at(w);
        dvpp_math::cabs(Complex::new(1.0, 0.0) / y - t) / dvpp_math::cabs(t)
    });
    verdict("grid-forming frequency", e, tol)
}

/// Result of the hybrid aggregation check.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HybridReport {
    /// Worst relative error with the known PLL roll-offs compensated (should be rounding).
    pub compensated: f64,
    /// Worst relative error of the raw condition on `ω ≤ band_limit`.
    pub raw_in_band: f64,
    /// `0.1/max τ_pll` (rad/s): the band in which the raw condition is reported.
    pub band_limit: f64,
}

/// Hybrid aggregation `(Σ_form T_i^pf⁻¹ + Σ_foll T_i^fp)⁻¹ = T_pf`.
///
/// The grid-following references carry the causal roll-off `1/(τ_pll s+1)^d`, so the raw
/// condition holds only below the PLL bandwidth: with grid-following participation `m_F(s)`
/// the raw relative error is `|m_F (1 − (τ jω+1)^{-d})|` up to second order, i.e. about
/// `|m_F| d ω τ_pll` (≤ 10 % of `|m_F| d` at `ω = 0.1/τ_pll`). The check therefore
/// **fails on the compensated condition** (each grid-following term multiplied by its known
/// `(τ_pll jω+1)^d`, which must hold to `tol`) and **reports** the raw error on
/// `ω ≤ 0.1/max τ_pll` for information.
pub fn check_hybrid_aggregation(
    tdes: &TDes,
    gfm: &[GfmPfModel],
    gfl: &[GflFpModel],
    grid: &[f64],
    tol: f64,
) -> Result<HybridReport> {
    let one = Complex::new(1.0, 0.0);
    let agg = |w: f64, compensate: bool| {
        let mut y: Complex<f64> = gfm.iter().map(|u| one / u.freq_response(w)).sum();
        for u in gfl {
            let (tau, d) = u.pll();
            let k = if compensate {
                rolloff_inverse_at(tau, d, w)
            } else {
                one
            };
            y += u.freq_response(w) * k;
        }
        let t = tdes.pf_at(w);
        dvpp_math::cabs(one / y - t) / dvpp_math::cabs(t)
    };
    let comp = verdict(
        "hybrid frequency (PLL-compensated)",
        worst(grid, |w| agg(w, true)),
        tol,
    )?;
    let tau_max = gfl.iter().map(|u| u.pll().0).fold(0.0, f64::max);
    let band_limit = if tau_max > 0.0 {
        0.1 / tau_max
    } else {
        f64::INFINITY
    };
    let band: Vec<f64> = grid.iter().copied().filter(|w| *w <= band_limit).collect();
    let raw = worst(&band, |w| agg(w, false)).0;
    Ok(HybridReport {
        compensated: comp,
        raw_in_band: raw,
        band_limit,
    })
}

/// Voltage aggregation `Σ_i T_i^vq(jω) = T_qv(jω)⁻¹/(τ_q jω + 1)`; grid-following units'
/// PLL roll-off is compensated as in [`check_hybrid_aggregation`]. Returns the worst relative error.
pub fn check_voltage_aggregation(
    tdes: &TDes,
    units: &[VqModel],
    grid: &[f64],
    tol: f64,
) -> Result<f64> {
    let target = tdes.vq_reference()?;
    let e = worst(grid, |w| {
        let mut y = Complex::new(0.0, 0.0);
        for u in units {
            let k = match u.pll() {
                Some((tau, d)) => rolloff_inverse_at(tau, d, w),
                None => Complex::new(1.0, 0.0),
            };
            y += u.freq_response(w) * k;
        }
        let t = target.freq_response(w);
        dvpp_math::cabs(y - t) / dvpp_math::cabs(t)
    });
    verdict("voltage", e, tol)
}

/// Summary of [`validate_design`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DesignReport {
    /// Worst `|Σ m_i − 1|` of the p-f ADPFs (grid-forming and grid-following units together).
    pub participation_pf: f64,
    /// Worst `|Σ μ_q − 1|` of the reactive gains.
    pub participation_q: f64,
    /// Hybrid (or pure grid-forming) frequency aggregation.
    pub frequency: HybridReport,
    /// Voltage aggregation relative error.
    pub voltage: f64,
}

/// All design checks at once: participation (p-f ADPFs and reactive gains), properness (by
/// construction of the models), stability of every local reference model, frequency and
/// voltage aggregation.
pub fn validate_design(
    tdes: &TDes,
    gfm: &[GfmPfModel],
    gfl: &[GflFpModel],
    vq: &[VqModel],
    grid: &[f64],
    tol: f64,
) -> Result<DesignReport> {
    let adpfs: Vec<Adpf> = gfm
        .iter()
        .map(|u| u.adpf())
        .chain(gfl.iter().map(|u| u.adpf()))
        .collect();
    let participation_pf = check_participation(&adpfs, grid, tol)?;
    let q_sum: f64 = vq.iter().map(|u| u.mu_q()).sum();
    let participation_q = (q_sum - 1.0).abs();
    if participation_q > tol {
        return Err(DvppError::ParticipationViolated {
            max_error: participation_q,
            omega: 0.0,
            tol,
        });
    }
    for u in gfm {
        u.check_stability()?;
    }
    for u in gfl {
        u.check_stability()?;
    }
    for u in vq {
        u.check_stability()?;
    }
    let frequency = check_hybrid_aggregation(tdes, gfm, gfl, grid, tol)?;
    let voltage = check_voltage_aggregation(tdes, vq, grid, tol)?;
    Ok(DesignReport {
        participation_pf,
        participation_q,
        frequency,
        voltage,
    })
}
