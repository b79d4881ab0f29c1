//! Participation filter bank: time-varying LPF dc gains with `Σ m_i ≡ 1` held exactly.
//!
//! Realization (`docs/control.md` §5): each low-pass unit `j` owns a chain of `d_j` first-order
//! stages `x' = (input − x)/τ_j` driven by the common input `u`; its share is `μ_j(t) x_j`
//! (last stage). The complement share is `u − Σ_j μ_j(t) x_j` on the *same* states, so the
//! shares add up to `u` at every instant, whatever the gains do. The gains enter only at the
//! output, so the chain dynamics are LTI and their exact ZOH discretization is cached per `h`.

use crate::adpf::{LowPassSpec, GAIN_SUM_TOL};
use crate::error::{check_finite, check_unit_gain, DvppError, Result};
use crate::ss::{Hold, LtiSimulator, StateSpace};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Parallel low-pass chains with a common input. Outputs: (optionally the input itself, then)
/// the last stage of every chain. Returns the model and the index of each chain's last state.
pub(crate) fn lpf_chains(specs: &[LowPassSpec], passthrough: bool) -> (StateSpace, Vec<usize>) {
    let n: usize = specs.iter().map(|s| s.order as usize).sum();
    let p = specs.len() + usize::from(passthrough);
    let mut a = DMatrix::<f64>::zeros(n, n);
    let mut b = DVector::<f64>::zeros(n);
    let mut c = DMatrix::<f64>::zeros(p.max(1), n);
    let mut d = DVector::<f64>::zeros(p.max(1));
    let mut last = Vec::with_capacity(specs.len());
    let mut k = 0;
    let off = usize::from(passthrough);
    if passthrough {
        d[0] = 1.0;
    }
    for (j, s) in specs.iter().enumerate() {
        let r = 1.0 / s.tau;
        for stage in 0..s.order as usize {
            a[(k + stage, k + stage)] = -r;
            if stage == 0 {
                b[k] = r;
            } else {
                a[(k + stage, k + stage - 1)] = r;
            }
        }
        let l = k + s.order as usize - 1;
        c[(off + j, l)] = 1.0;
        last.push(l);
        k += s.order as usize;
    }
    (
        StateSpace::new(a, b, c, d).expect("chain dimensions are consistent"),
        last,
    )
}

/// Validate a set of low-pass dc gains: each in `[0, 1]`, sum ≤ `cap`.
pub(crate) fn check_lpf_gains(mus: &[f64], expected: usize, cap: f64) -> Result<()> {
    if mus.len() != expected {
        return Err(DvppError::DimensionMismatch {
            what: "low-pass dc gains".into(),
            expected,
            found: mus.len(),
        });
    }
    for mu in mus {
        check_unit_gain("low-pass dc gain", *mu)?;
    }
    let sum: f64 = mus.iter().sum();
    if sum > cap + GAIN_SUM_TOL {
        return Err(DvppError::GainOutOfRange {
            what: "sum of low-pass dc gains".into(),
            value: sum,
            min: 0.0,
            max: cap,
        });
    }
    Ok(())
}

/// Shared participation filter bank (low-pass units + one complement unit).
///
/// `step(u, h)` returns the shares `[μ_1 x_1, …, μ_n x_n, u − Σ μ_j x_j]`; their sum equals
/// `u` to rounding at every step (and exactly in exact arithmetic).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParticipationBank {
    specs: Vec<LowPassSpec>,
    mus: Vec<f64>,
    sim: LtiSimulator,
}

impl ParticipationBank {
    /// Bank for the given low-pass units (their `mu` fields are the initial gains).
    pub fn new(specs: &[LowPassSpec]) -> Result<Self> {
        for s in specs {
            LowPassSpec::new(s.mu, s.tau, s.order)?;
        }
        let mus: Vec<f64> = specs.iter().map(|s| s.mu).collect();
        check_lpf_gains(&mus, specs.len(), 1.0)?;
        let (sys, _) = lpf_chains(specs, false);
        Ok(Self {
            specs: specs.to_vec(),
            mus,
            sim: LtiSimulator::new(sys, Hold::Zero),
        })
    }

    /// Number of low-pass units (the complement is one more share).
    pub fn lpf_count(&self) -> usize {
        self.specs.len()
    }

    /// Current low-pass dc gains.
    pub fn gains(&self) -> &[f64] {
        &self.mus
    }

    /// Set new low-pass dc gains (each in `[0,1]`, sum ≤ 1); states are untouched.
    pub fn set_gains(&mut self, mus: &[f64]) -> Result<()> {
        check_lpf_gains(mus, self.specs.len(), 1.0)?;
        self.mus.copy_from_slice(mus);
        Ok(())
    }

    /// Shares for input `u` at the current state (no time advance).
    pub fn shares(&self, u: f64) -> Vec<f64> {
        let y = self.sim.output(u);
        self.compose(u, &y)
    }

    fn compose(&self, u: f64, y: &DVector<f64>) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.specs.len() + 1);
        let mut lpf_sum = 0.0;
        for (j, mu) in self.mus.iter().enumerate() {
            let share = mu * if self.specs.is_empty() { 0.0 } else { y[j] };
            lpf_sum += share;
            out.push(share);
        }
        out.push(u - lpf_sum);
        out
    }

    /// Advance by `h` with `u` held over the step; returns the shares at the end of the step.
    pub fn step(&mut self, u: f64, h: f64) -> Result<Vec<f64>> {
        check_finite("bank input", u)?;
        if self.specs.is_empty() {
            return Ok(self.compose(u, &DVector::zeros(1)));
        }
        self.sim.step_all(u, h);
        Ok(self.compose(u, self.sim.last_outputs()))
    }
}
