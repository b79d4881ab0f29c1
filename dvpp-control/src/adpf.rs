//! Adaptive dynamic participation factors (ADPFs) `m_i(s)` and the participation condition.

use crate::error::{check_tau, check_unit_gain, DvppError, Result};
use crate::tf::{lag_poly, TransferFunction};
use nalgebra::Complex;
use serde::{Deserialize, Serialize};

/// Tolerance on `Σ μ_j ≤ 1` for the dc gains a complement closes.
pub const GAIN_SUM_TOL: f64 = 1e-9;

/// One low-pass participation `μ/(τ s + 1)^d`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LowPassSpec {
    /// Dc gain `μ ∈ [0, 1]`.
    pub mu: f64,
    /// Roll-off time constant `τ > 0` (s).
    pub tau: f64,
    /// Order `d ≥ 1`.
    pub order: u32,
}

impl LowPassSpec {
    /// Validated low-pass spec.
    pub fn new(mu: f64, tau: f64, order: u32) -> Result<Self> {
        check_unit_gain("ADPF dc gain mu", mu)?;
        check_tau("ADPF low-pass tau", tau)?;
        check_order(order)?;
        Ok(Self { mu, tau, order })
    }

    /// A static participation `m = μ` (order 0; the time constant is unused). Not accepted
    /// by complements or participation banks, which need a roll-off.
    pub fn static_gain(mu: f64) -> Result<Self> {
        check_unit_gain("ADPF dc gain mu", mu)?;
        Ok(Self {
            mu,
            tau: 1.0,
            order: 0,
        })
    }

    /// `true` for a static participation (order 0).
    pub fn is_static(&self) -> bool {
        self.order == 0
    }

    /// `1/(τ jω + 1)^d` without the gain.
    pub fn shape_at(&self, s: Complex<f64>) -> Complex<f64> {
        let base = Complex::new(1.0, 0.0) / (s * self.tau + 1.0);
        base.powi(self.order as i32)
    }
}

fn check_order(order: u32) -> Result<()> {
    if order == 0 {
        return Err(DvppError::InvalidParameter {
            what: "ADPF order".into(),
            reason: "order d must be ≥ 1".into(),
        });
    }
    Ok(())
}

/// An ADPF shape (paper section III): low-pass, high-pass, band-pass or the complement of a
/// set of low-pass units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Adpf {
    /// `μ/(τ s + 1)^d`: slow unit with steady-state contribution.
    LowPass(LowPassSpec),
    /// `τ s/(τ s + 1)^d`: fast unit, zero dc gain.
    HighPass {
        /// Time constant.
        tau: f64,
        /// Order `d ≥ 1`.
        order: u32,
    },
    /// `(τ₁ − τ₂) s/((τ₁ s + 1)^d₁ (τ₂ s + 1)^d₂)` with `τ₁ > τ₂`: intermediate regime.
    BandPass {
        /// Slow time constant.
        tau1: f64,
        /// Fast time constant.
        tau2: f64,
        /// Order of the slow factor.
        order1: u32,
        /// Order of the fast factor.
        order2: u32,
    },
    /// `c − Σ_j μ_j/(τ_j s + 1)^{d_j}` with share `c ∈ (0, 1]` (`c = 1` in the paper; `c < 1`
    /// when a unit is split into grid-forming and grid-following parts): the unit that closes
    /// the participation condition. Requires `Σ μ_j ≤ c`.
    Complement {
        /// Total participation closed by this unit (1 for a plain complement).
        share: f64,
        /// The low-pass units complemented (their current dc gains included).
        lpf: Vec<LowPassSpec>,
    },
}

impl Adpf {
    /// Static ADPF `m = μ`, `μ ∈ [0, 1]` (a low-pass of order 0).
    pub fn static_gain(mu: f64) -> Result<Self> {
        Ok(Adpf::LowPass(LowPassSpec::static_gain(mu)?))
    }

    /// Low-pass ADPF; `μ ∈ [0,1]`, `τ > 0`, `d ≥ 1`.
    pub fn low_pass(mu: f64, tau: f64, order: u32) -> Result<Self> {
        Ok(Adpf::LowPass(LowPassSpec::new(mu, tau, order)?))
    }

    /// High-pass ADPF; `τ > 0`, `d ≥ 1`.
    pub fn high_pass(tau: f64, order: u32) -> Result<Self> {
        check_tau("ADPF high-pass tau", tau)?;
        check_order(order)?;
        Ok(Adpf::HighPass { tau, order })
    }

    /// Band-pass ADPF; `τ₁ > τ₂ > 0`, orders ≥ 1.
    pub fn band_pass(tau1: f64, tau2: f64, order1: u32, order2: u32) -> Result<Self> {
        check_tau("ADPF band-pass tau1", tau1)?;
        check_tau("ADPF band-pass tau2", tau2)?;
        check_order(order1)?;
        check_order(order2)?;
        if tau1 <= tau2 {
            return Err(DvppError::InvalidParameter {
                what: "ADPF band-pass".into(),
                reason: format!("need tau1 > tau2, got {tau1} ≤ {tau2}"),
            });
        }
        Ok(Adpf::BandPass {
            tau1,
            tau2,
            order1,
            order2,
        })
    }

    /// Complement of the given low-pass ADPFs. Every member must be [`Adpf::LowPass`] and
    /// their dc gains must sum to at most 1.
    pub fn complement_of(lpfs: &[Adpf]) -> Result<Self> {
        let mut specs = Vec::with_capacity(lpfs.len());
        for a in lpfs {
            match a {
                Adpf::LowPass(s) => specs.push(*s),
                _ => {
                    return Err(DvppError::WrongUnitKind {
                        what: "a complement can only close low-pass ADPFs".into(),
                    })
                }
            }
        }
        Self::complement_of_specs(1.0, specs)
    }

    /// Complement with share `c ∈ (0, 1]` from low-pass specs directly (`Σ μ_j ≤ c`).
    pub fn complement_of_specs(share: f64, specs: Vec<LowPassSpec>) -> Result<Self> {
        check_unit_gain("complement share", share)?;
        if share == 0.0 {
            return Err(DvppError::GainOutOfRange {
                what: "complement share".into(),
                value: share,
                min: f64::MIN_POSITIVE,
                max: 1.0,
            });
        }
        for s in &specs {
            LowPassSpec::new(s.mu, s.tau, s.order)?;
        }
        let sum: f64 = specs.iter().map(|s| s.mu).sum();
        if sum > share + GAIN_SUM_TOL {
            return Err(DvppError::GainOutOfRange {
                what: "sum of complemented low-pass dc gains".into(),
                value: sum,
                min: 0.0,
                max: share,
            });
        }
        Ok(Adpf::Complement { share, lpf: specs })
    }

    /// `k · m(s)` for `k ∈ (0, 1]` (splitting a unit into grid-forming and grid-following
    /// parts, `m = ε m + (1 − ε) m`). Low-pass: `k μ`; complement: share and gains times `k`.
    /// High-/band-pass shapes have no gain parameter and are rejected.
    pub fn scaled(&self, k: f64) -> Result<Self> {
        check_unit_gain("ADPF scale factor", k)?;
        match self {
            Adpf::LowPass(s) if s.is_static() => Adpf::static_gain(k * s.mu),
            Adpf::LowPass(s) => Adpf::low_pass(k * s.mu, s.tau, s.order),
            Adpf::Complement { share, lpf } => Adpf::complement_of_specs(
                k * share,
                lpf.iter()
                    .map(|s| LowPassSpec { mu: k * s.mu, ..*s })
                    .collect(),
            ),
            _ => Err(DvppError::WrongUnitKind {
                what: format!("cannot scale a {} ADPF", self.kind_name()),
            }),
        }
    }

    /// Short name of the kind.
    pub fn kind_name(&self) -> &'static str {
        match self {
            Adpf::LowPass(s) if s.is_static() => "static",
            Adpf::LowPass(_) => "low-pass",
            Adpf::HighPass { .. } => "high-pass",
            Adpf::BandPass { .. } => "band-pass",
            Adpf::Complement { .. } => "complement",
        }
    }

    /// Value at a complex frequency `s` (evaluated from the factored form).
    pub fn eval(&self, s: Complex<f64>) -> Complex<f64> {
        let one = Complex::new(1.0, 0.0);
        match self {
            Adpf::LowPass(spec) => spec.shape_at(s) * spec.mu,
            Adpf::HighPass { tau, order } => {
                s * *tau * (one / (s * *tau + 1.0)).powi(*order as i32 - 1) / (s * *tau + 1.0)
            }
            Adpf::BandPass {
                tau1,
                tau2,
                order1,
                order2,
            } => {
                s * (tau1 - tau2)
                    * (one / (s * *tau1 + 1.0)).powi(*order1 as i32)
                    * (one / (s * *tau2 + 1.0)).powi(*order2 as i32)
            }
            Adpf::Complement { share, lpf } => {
                let mut acc = Complex::new(*share, 0.0);
                for spec in lpf {
                    acc -= spec.shape_at(s) * spec.mu;
                }
                acc
            }
        }
    }

    /// `m(jω)`.
    pub fn freq_response(&self, omega: f64) -> Complex<f64> {
        self.eval(Complex::new(0.0, omega))
    }

    /// Dc gain `m(0)`.
    pub fn dc_gain(&self) -> f64 {
        match self {
            Adpf::LowPass(s) => s.mu,
            Adpf::HighPass { .. } | Adpf::BandPass { .. } => 0.0,
            Adpf::Complement { share, lpf } => share - lpf.iter().map(|s| s.mu).sum::<f64>(),
        }
    }

    /// The ADPF as a rational transfer function (ascending coefficients).
    pub fn transfer_function(&self) -> TransferFunction {
        let tf = match self {
            Adpf::LowPass(s) => TransferFunction::new(vec![s.mu], lag_poly(s.tau, s.order)),
            Adpf::HighPass { tau, order } => {
                TransferFunction::new(vec![0.0, *tau], lag_poly(*tau, *order))
            }
            Adpf::BandPass {
                tau1,
                tau2,
                order1,
                order2,
            } => TransferFunction::new(
                vec![0.0, tau1 - tau2],
                crate::tf::poly_mul(&lag_poly(*tau1, *order1), &lag_poly(*tau2, *order2)),
            ),
            Adpf::Complement { share, lpf } => {
                let mut acc = TransferFunction::gain(*share);
                for s in lpf {
                    let m = TransferFunction::new(vec![s.mu], lag_poly(s.tau, s.order));
                    acc = acc.and_then(|a| m.map(|m| a.sub(&m)));
                }
                acc
            }
        };
        tf.expect("validated ADPF parameters give a proper rational function")
    }

    /// Same shape with a new dc gain (static and low-pass only).
    pub fn with_mu(&self, mu: f64) -> Result<Self> {
        match self {
            Adpf::LowPass(s) if s.is_static() => Adpf::static_gain(mu),
            Adpf::LowPass(s) => Adpf::low_pass(mu, s.tau, s.order),
            _ => Err(DvppError::WrongUnitKind {
                what: format!("with_mu on a {} ADPF", self.kind_name()),
            }),
        }
    }

    /// Same complement with new dc gains of the complemented low-pass units.
    pub fn with_lpf_gains(&self, mus: &[f64]) -> Result<Self> {
        match self {
            Adpf::Complement { share, lpf } => {
                if mus.len() != lpf.len() {
                    return Err(DvppError::DimensionMismatch {
                        what: "complement low-pass gains".into(),
                        expected: lpf.len(),
                        found: mus.len(),
                    });
                }
                let specs = lpf
                    .iter()
                    .zip(mus)
                    .map(|(s, mu)| LowPassSpec::new(*mu, s.tau, s.order))
                    .collect::<Result<Vec<_>>>()?;
                Adpf::complement_of_specs(*share, specs)
            }
            _ => Err(DvppError::WrongUnitKind {
                what: format!("with_lpf_gains on a {} ADPF", self.kind_name()),
            }),
        }
    }
}

/// Logarithmic frequency grid from `lo` to `hi` rad/s with `per_decade` points per decade
/// (both ends included).
pub fn log_grid(lo: f64, hi: f64, per_decade: usize) -> Vec<f64> {
    let (a, b) = (dvpp_math::log10(lo), dvpp_math::log10(hi));
    let n = (((b - a) * per_decade as f64).ceil() as usize).max(1);
    (0..=n)
        .map(|k| dvpp_math::pow(10f64, a + (b - a) * k as f64 / n as f64))
        .collect()
}

/// The design grid of the project: 1e-3 … 1e4 rad/s, 50 points per decade.
pub fn design_grid() -> Vec<f64> {
    log_grid(1e-3, 1e4, 50)
}

/// Every ADPF of a set evaluated at `jω`.
pub fn eval_set(set: &[Adpf], omega: f64) -> Vec<Complex<f64>> {
    set.iter().map(|m| m.freq_response(omega)).collect()
}

/// `(max_ω |Σ m_i(jω) − 1|, argmax ω)` over a grid.
pub fn participation_error(set: &[Adpf], grid: &[f64]) -> (f64, f64) {
    let mut worst = (0.0, grid.first().copied().unwrap_or(0.0));
    for &w in grid {
        let sum: Complex<f64> = eval_set(set, w).into_iter().sum();
        let e = dvpp_math::cabs(sum - Complex::new(1.0, 0.0));
        if e > worst.0 || e.is_nan() {
            worst = (e, w);
        }
    }
    worst
}

/// `max_ω |Σ m_i(jω) − 1|` on [`design_grid`].
pub fn max_participation_error(set: &[Adpf]) -> f64 {
    participation_error(set, &design_grid()).0
}
