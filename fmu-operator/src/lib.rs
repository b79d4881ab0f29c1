//! DVPP operator FMU: splits the DVPP's steady-state participation into ADPF dc gains `μ_p`.
//!
//! Each DER's active dc gain is its share of the total available power, `μ_k = P_k / Σ P`,
//! bounded below by `mu_min` (a grid-forming unit cannot have zero p-f participation) and
//! renormalized so that `Σ μ_k = 1` holds at every output.

use fmi_export::{Context, Model, ModelError, Real, Spec, Store, Variables};
use serde::{Deserialize, Serialize};

/// The handles of the operator's variables.
#[derive(Clone, Serialize, Deserialize)]
pub struct Operator {
    mu_min: Real,
    p_avail: Vec<Real>,
    mu_p: Vec<Real>,
    /// Whether the all-zero availability warning was given (it is given once).
    warned_zero: bool,
}

/// Structure of the DVPP the operator serves.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OperatorConfig {
    /// Number of DERs in the DVPP.
    pub ders: usize,
}

impl Default for OperatorConfig {
    fn default() -> Self {
        OperatorConfig { ders: 3 }
    }
}

/// `μ_k = P_k / Σ P`, bounded below by `mu_min` and renormalized; equal shares when `Σ P = 0`.
pub fn dc_gains(available: &[f64], mu_min: f64) -> Vec<f64> {
    let n = available.len();
    let total: f64 = available.iter().map(|p| p.max(0.0)).sum();
    let mut mu: Vec<f64> = if total > 0.0 {
        available.iter().map(|p| p.max(0.0) / total).collect()
    } else {
        vec![1.0 / n as f64; n]
    };
    // Raise the units below the bound to it and take the difference from the others in
    // proportion to their share; repeat until no unit is below (at most n rounds).
    let mut fixed = vec![false; n];
    for _ in 0..n {
        let low: Vec<usize> = (0..n).filter(|&k| !fixed[k] && mu[k] < mu_min).collect();
        if low.is_empty() {
            break;
        }
        for &k in &low {
            mu[k] = mu_min;
            fixed[k] = true;
        }
        let fixed_sum: f64 = (0..n).filter(|&k| fixed[k]).map(|k| mu[k]).sum();
        let free_sum: f64 = (0..n).filter(|&k| !fixed[k]).map(|k| mu[k]).sum();
        for k in (0..n).filter(|&k| !fixed[k]) {
            mu[k] *= (1.0 - fixed_sum) / free_sum;
        }
    }
    mu
}

impl Operator {
    fn update(&mut self, s: &mut Store, ctx: &mut Context) {
        let available: Vec<f64> = self.p_avail.iter().map(|&r| s[r]).collect();
        if available.iter().all(|&p| p <= 0.0) && !self.warned_zero {
            self.warned_zero = true;
            ctx.warn("all DER availabilities are zero: dc gains fall back to equal shares");
        }
        for (mu, &r) in dc_gains(&available, s[self.mu_min])
            .into_iter()
            .zip(&self.mu_p)
        {
            s[r] = mu;
        }
    }
}

impl Model for Operator {
    type Config = OperatorConfig;
    const IDENTIFIER: &'static str = "dvpp_operator";
    const NAME: &'static str = "DVPP operator";
    const DESCRIPTION: &'static str =
        "DVPP operator: ADPF dc gains mu_p proportional to the DERs' available power, summing to 1";

    fn declare(
        config: &OperatorConfig,
        _: Option<&std::path::Path>,
        v: &mut Variables,
    ) -> Result<Self, String> {
        let n = config.ders;
        if !(1..=64).contains(&n) {
            return Err(format!("[model] ders = {n} is outside 1..=64"));
        }
        let mu_min = v.real(
            Spec::parameter("mu_min", 0.05, "1", "lower bound of a DER's dc gain")
                .range(0.0, 1.0 / n as f64),
        );
        let p_avail: Vec<Real> = (1..=n)
            .map(|k| {
                v.real(Spec::input(
                    &format!("der[{k}].P_avail"),
                    0.5,
                    "pu",
                    &format!("available active power of DER {k}, on S_base"),
                ))
            })
            .collect();
        let names: Vec<String> = (1..=n).map(|k| format!("der[{k}].P_avail")).collect();
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        let mu_p = (1..=n)
            .map(|k| {
                v.real(
                    Spec::output(
                        &format!("der[{k}].mu_p"),
                        "1",
                        &format!("ADPF dc gain of DER {k}'s p-f channel"),
                    )
                    .initial_dependencies(&names),
                )
            })
            .collect();
        Ok(Operator {
            mu_min,
            p_avail,
            mu_p,
            warned_zero: false,
        })
    }

    fn initialize(&mut self, s: &mut Store, ctx: &mut Context) -> Result<(), ModelError> {
        self.update(s, ctx);
        Ok(())
    }

    fn do_step(
        &mut self,
        s: &mut Store,
        _t: f64,
        _h: f64,
        ctx: &mut Context,
    ) -> Result<(), ModelError> {
        self.update(s, ctx);
        Ok(())
    }
}

fmi_export::export_fmu!(Operator);

#[cfg(test)]
mod tests {
    use super::dc_gains;

    #[test]
    fn gains_sum_to_one_and_respect_the_bound() {
        for avail in [
            vec![0.4, 0.6, 0.0],
            vec![0.0, 0.0, 0.0],
            vec![1.0, 0.01, 0.02],
            vec![0.3, 0.3, 0.4],
        ] {
            let mu = dc_gains(&avail, 0.05);
            assert!(
                (mu.iter().sum::<f64>() - 1.0).abs() < 1e-12,
                "{avail:?} -> {mu:?}"
            );
            assert!(mu.iter().all(|&m| m >= 0.05 - 1e-15), "{avail:?} -> {mu:?}");
        }
        let mu = dc_gains(&[0.2, 0.6, 0.2], 0.05);
        assert!((mu[1] - 0.6).abs() < 1e-15);
    }
}

#[cfg(test)]
mod golden {
    #[test]
    fn model_description_matches_the_golden_copy() {
        fmi_export::assert_golden::<super::Operator>(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/modelDescription.xml"
        ));
    }
}
