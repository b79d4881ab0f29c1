//! Online adaptation of the LPF dc gains by the DVPP operator (capacity-proportional participation).

use crate::error::{check_finite, DvppError, Result};

fn check_nonneg(what: &str, v: &[f64]) -> Result<()> {
    for x in v {
        check_finite(what, *x)?;
        if *x < 0.0 {
            return Err(DvppError::InvalidParameter {
                what: what.into(),
                reason: format!("must be ≥ 0, got {x}"),
            });
        }
    }
    Ok(())
}

/// Active participation of the low-pass units: `μ_j = P_avail,j / Σ_k P_avail,k`.
/// Errors if the list is empty, has negative/non-finite entries, or sums to zero.
pub fn active_gains(p_avail: &[f64]) -> Result<Vec<f64>> {
    check_nonneg("available active power", p_avail)?;
    let sum: f64 = p_avail.iter().sum();
    if sum <= 0.0 {
        return Err(DvppError::InfeasibleGains {
            reason: "no low-pass unit has available active power".into(),
        });
    }
    Ok(p_avail.iter().map(|p| p / sum).collect())
}

/// Reactive capacity on the PQ circle `Q_cap = sqrt(max(S_rated² − P², 0))`.
pub fn reactive_capacity(s_rated: f64, p: f64) -> f64 {
    (s_rated * s_rated - p * p).max(0.0).sqrt()
}

/// Reactive participation `μ_i^q = Q_cap,i / Σ_k Q_cap,k` at the units' operating points.
pub fn reactive_gains(s_rated: &[f64], p: &[f64]) -> Result<Vec<f64>> {
    if s_rated.len() != p.len() {
        return Err(DvppError::DimensionMismatch {
            what: "operating points vs ratings".into(),
            expected: s_rated.len(),
            found: p.len(),
        });
    }
    check_nonneg("rating", s_rated)?;
    for x in p {
        check_finite("operating point", *x)?;
    }
    let q: Vec<f64> = s_rated
        .iter()
        .zip(p)
        .map(|(s, p)| reactive_capacity(*s, *p))
        .collect();
    active_gains(&q)
}

/// Normalize non-negative weights to gains summing to 1, proportional to the weights, with a
/// floor `mu_min` on the units flagged in `floored` (the grid-forming low-pass units, see
/// [`crate::local::MU_MIN_GFM`]). Floored units that would fall below the floor are pinned to
/// it and the remaining budget is shared proportionally among the others (iterated until no
/// new unit hits the floor). Errors if the floors alone exceed 1 or nothing can carry the gain.
pub fn renormalize_with_floor(weights: &[f64], floored: &[bool], mu_min: f64) -> Result<Vec<f64>> {
    if weights.len() != floored.len() {
        return Err(DvppError::DimensionMismatch {
            what: "floor mask".into(),
            expected: weights.len(),
            found: floored.len(),
        });
    }
    check_nonneg("participation weight", weights)?;
    check_finite("mu_min", mu_min)?;
    let n = weights.len();
    let n_floor = floored.iter().filter(|f| **f).count();
    if n == 0 || n_floor as f64 * mu_min > 1.0 {
        return Err(DvppError::InfeasibleGains {
            reason: format!("{n_floor} floored units × μ_min {mu_min} exceeds 1 (or no units)"),
        });
    }
    let mut pinned = vec![false; n];
    loop {
        let n_pinned = pinned.iter().filter(|p| **p).count();
        let budget = 1.0 - n_pinned as f64 * mu_min;
        let free: Vec<usize> = (0..n).filter(|i| !pinned[*i]).collect();
        let mut mu = vec![0.0; n];
        for i in 0..n {
            if pinned[i] {
                mu[i] = mu_min;
            }
        }
        if free.is_empty() {
            let extra = budget / n_pinned as f64;
            return Ok(mu.iter().map(|m| m + extra).collect());
        }
        let w: f64 = free.iter().map(|i| weights[*i]).sum();
        for &i in &free {
            mu[i] = if w > 0.0 {
                budget * weights[i] / w
            } else {
                budget / free.len() as f64
            };
        }
        let mut changed = false;
        for &i in &free {
            if floored[i] && mu[i] < mu_min {
                pinned[i] = true;
                changed = true;
            }
        }
        if !changed {
            return Ok(mu);
        }
    }
}
