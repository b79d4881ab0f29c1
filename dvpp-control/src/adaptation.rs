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
/// floor `mu_min` on the units flagged in `floored`: [`renormalize_with_floors`] with one floor
/// for all flagged units (0 for the others).
pub fn renormalize_with_floor(weights: &[f64], floored: &[bool], mu_min: f64) -> Result<Vec<f64>> {
    if weights.len() != floored.len() {
        return Err(DvppError::DimensionMismatch {
            what: "floor mask".into(),
            expected: weights.len(),
            found: floored.len(),
        });
    }
    check_finite("mu_min", mu_min)?;
    let floors: Vec<f64> = floored
        .iter()
        .map(|&f| if f { mu_min } else { 0.0 })
        .collect();
    renormalize_with_floors(weights, &floors)
}

/// Normalize non-negative weights to gains summing to 1, proportional to the weights, with a
/// floor `floors[i]` on unit `i` (0: none; the grid-forming low-pass units' own floors, see
/// [`crate::local::mu_min_gfm`]). Units that would fall below their floor are pinned to it and
/// the remaining budget `1 − Σ_pinned μ_min,i` is shared proportionally among the others
/// (iterated until no new unit hits its floor; each round is linear in the number of units and
/// pins at least one more, and in practice one or two rounds settle). If every unit is pinned,
/// what is left of the budget goes to them in proportion to their floors. Errors if the floors
/// alone exceed 1 or there are no units.
pub fn renormalize_with_floors(weights: &[f64], floors: &[f64]) -> Result<Vec<f64>> {
    if weights.len() != floors.len() {
        return Err(DvppError::DimensionMismatch {
            what: "floors".into(),
            expected: weights.len(),
            found: floors.len(),
        });
    }
    check_nonneg("participation weight", weights)?;
    check_nonneg("μ_min", floors)?;
    let n = weights.len();
    let floor_sum: f64 = floors.iter().sum();
    if n == 0 || floor_sum > 1.0 {
        let n_floor = floors.iter().filter(|f| **f > 0.0).count();
        return Err(DvppError::InfeasibleGains {
            reason: format!(
                "{n_floor} floored units: their floors sum to {floor_sum} > 1 (or no units)"
            ),
        });
    }
    let mut pinned = vec![false; n];
    let mut mu = vec![0.0; n];
    loop {
        let mut budget = 1.0;
        let mut w = 0.0;
        let mut n_free = 0usize;
        for i in 0..n {
            if pinned[i] {
                budget -= floors[i];
            } else {
                w += weights[i];
                n_free += 1;
            }
        }
        if n_free == 0 {
            // Only floored units are pinned, and their floors sum to at most 1.
            return Ok(floors.iter().map(|f| f + budget * f / floor_sum).collect());
        }
        let mut changed = false;
        for i in 0..n {
            if pinned[i] {
                mu[i] = floors[i];
                continue;
            }
            mu[i] = if w > 0.0 {
                budget * weights[i] / w
            } else {
                budget / n_free as f64
            };
            if floors[i] > 0.0 && mu[i] < floors[i] {
                pinned[i] = true;
                changed = true;
            }
        }
        if !changed {
            return Ok(mu);
        }
    }
}
