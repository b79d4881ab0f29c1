//! Local reference models (local matching conditions) that each DER realizes, with online dc gains.
//!
//! All signals are deviations on the DVPP base `S_dvpp`. Each model's `freq_response(ω)`
//! evaluates its **realization** (the matrices actually simulated) at frozen gains and
//! returns the transfer function in the paper's positive form (`T_i^pf`, `T_i^fp`, `T_i^vq`);
//! `step` returns the signed output (`Δf_i = −T_i^pf Δp_i`, `Δp_i = −T_i^fp Δf_i`,
//! `Δq_i = −T_i^vq Δv`). `transfer_function()` builds the same quantity independently by
//! rational algebra, for design checks.

use crate::adpf::{Adpf, LowPassSpec};
use crate::bank::{check_lpf_gains, lpf_chains};
use crate::error::{check_finite, DvppError, Result};
use crate::ss::{Hold, LtiSimulator, StateSpace};
use crate::tdes::TDes;
use crate::tf::{lag_poly, TransferFunction};
use nalgebra::{Complex, DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Lower bound `μ_min` on the p-f dc gain of a grid-forming low-pass unit.
///
/// `T_i^pf = (τ s + 1)/(μ (H s + D))` grows like `1/μ`: a grid-forming unit cannot have zero
/// p-f participation (it would impose an unbounded frequency for any power). Gains sent to a
/// grid-forming LPF unit are clamped to `[μ_min, 1]` at run time, rejected below it at design
/// time, and a gain set is made consistent with [`crate::adaptation::renormalize_with_floors`].
/// This is the floor of a unit that is large in its DVPP; a small unit's floor scales with its
/// share of the DVPP rating, see [`mu_min_gfm`].
pub const MU_MIN_GFM: f64 = 0.05;

/// Lower bound `κ` on a grid-forming low-pass unit's p-f stiffness per unit of its own rating,
/// relative to the DVPP's: see [`mu_min_gfm`].
pub const MU_FLOOR_KAPPA: f64 = 0.25;

/// The floor `μ_min,i = min(MU_MIN_GFM, κ S_i/S_dvpp)` of a grid-forming low-pass unit of rating
/// `s_rated` in a DVPP of base `s_dvpp` (both MVA), `κ` = [`MU_FLOOR_KAPPA`].
///
/// On its own rating, the unit's local reference `Δf = −T_i^pf Δp_i` reads
/// `Δf = −(τ s + 1)/((μ_i S_dvpp/S_i)(H s + D)) Δp_i,own`: its p-f stiffness per unit of its own
/// rating is `μ_i S_dvpp/S_i` times the DVPP's. What a grid-forming unit must not lose is that
/// stiffness, so the floor bounds it below by `κ`: `μ_i ≥ κ S_i/S_dvpp`. A fixed floor would make
/// `n` equal units infeasible as soon as `n μ_min > 1` (20 units at 0.05), whereas this one sums
/// to at most `κ Σ S_i/S_dvpp` and stays feasible for any number of units as long as the
/// floored units' ratings add up to less than `S_dvpp/κ` (four times the DVPP base). Units of
/// at least `MU_MIN_GFM/κ` = 20 % of `S_dvpp` keep the fixed floor `MU_MIN_GFM`, so DVPPs of a
/// few large units (case study I: 46 and 73 MVA in 96 MVA) are unchanged. Invalid ratings
/// (non-positive, non-finite) give `MU_MIN_GFM`.
pub fn mu_min_gfm(s_rated: f64, s_dvpp: f64) -> f64 {
    MU_MIN_GFM * floor_scale(s_rated, s_dvpp)
}

/// The factor `min(1, κ S_i/(MU_MIN_GFM S_dvpp))` by which a unit's floor is below the floor of a
/// large unit: [`mu_min_gfm`] is `MU_MIN_GFM` times it, and an operator whose floor for large
/// units is `mu_min` (≥ `MU_MIN_GFM`) floors unit `i` at `mu_min` times it, never below the
/// DER's own floor. 1 for invalid ratings.
pub fn floor_scale(s_rated: f64, s_dvpp: f64) -> f64 {
    let share = s_rated / s_dvpp;
    if share.is_finite() && share > 0.0 {
        (MU_FLOOR_KAPPA * share / MU_MIN_GFM).min(1.0)
    } else {
        1.0
    }
}

fn default_mu_min() -> f64 {
    MU_MIN_GFM
}

/// Relative tolerance used to detect the intended origin pole (integrator) of zero-dc-gain
/// grid-forming units in stability checks.
pub const INTEGRATOR_TOL: f64 = 1e-9;

fn stability_check(what: &str, tf: &TransferFunction, allow_integrator: bool) -> Result<()> {
    let ok = if allow_integrator {
        tf.is_stable_allowing_integrator(INTEGRATOR_TOL)
    } else {
        tf.is_stable()
    };
    if ok {
        Ok(())
    } else {
        Err(DvppError::Unstable { what: what.into() })
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
enum GfmPfRealization {
    /// Simulates `G = (τ s + 1)^d T_pf` driven by `Δp/μ(t)`.
    LowPass { spec: LowPassSpec },
    /// Feedback realization `w = (Δp + Σ μ_j x_j)/c`, chains driven by `w`, `Δf = −T_pf w`.
    Complement {
        share: f64,
        lpf: Vec<LowPassSpec>,
        tpf: StateSpace,
    },
    /// LTI `T_pf/m` (high-pass, band-pass).
    Fixed { adpf: Adpf },
}

/// Grid-forming p-f local reference model `Δf_i = −T_i^pf(s) Δp_i`, `T_i^pf = m_i⁻¹ T_pf`.
///
/// Where the time-varying gains enter (so that the participation bank identity
/// `Δp_i = μ_i(t) x_i`, `x_i = LPF_i(v)`, `v = −T_pf⁻¹ Δf` holds while gains move):
///
/// * **Low-pass** (`d = 1`: `T_i^pf = (τ s + 1)/(μ (H s + D))`, biproper): the LTI part
///   `G = (τ s + 1)^d T_pf` is simulated and driven by `Δp_i/μ(t)`, i.e. `μ(t)` enters at the
///   input. `μ` is kept in `[μ_min, 1]` (`MU_MIN_GFM` unless built with
///   [`GfmPfModel::with_floor`]).
/// * **Complement** (`m = c − Σ μ_j L_j`, with `c = 1` in the paper): no inverse is formed;
///   `w = (Δp_i + Σ_j μ_j(t) x_j)/c`, `x_j = L_j(w)` (chains `x' = (w − x)/τ_j`),
///   `Δf_i = −T_pf w`. This is a feedback loop through the states only (no algebraic loop);
///   its `A` matrix depends on the `μ_j`, so the model is rebuilt and re-discretized exactly
///   (ZOH, matrix exponential) whenever the gains change — the gains are held over each step.
///   With `Σ μ_j = c` the model has one pole at the origin: the unit gives transient power
///   and none in steady state.
/// * **High-/band-pass**: LTI `T_pf/m` (also with an origin pole).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GfmPfModel {
    tpf: TransferFunction,
    real: GfmPfRealization,
    mu: f64,
    lpf_mus: Vec<f64>,
    sim: LtiSimulator,
    /// Floor of a low-pass unit's dc gain ([`mu_min_gfm`]).
    #[serde(default = "default_mu_min")]
    mu_min: f64,
}

fn complement_gfm_system(
    tpf: &StateSpace,
    share: f64,
    lpf: &[LowPassSpec],
    mus: &[f64],
) -> StateSpace {
    let (chains, last) = lpf_chains(lpf, false);
    let nx = chains.order();
    let nt = tpf.order();
    let n = nx + nt;
    // g^T x = Σ μ_j x_j(last)
    let mut g = DVector::<f64>::zeros(nx);
    // w = (Δp + g^T x)/c: fold 1/c into g and into the input column
    for (j, l) in last.iter().enumerate() {
        g[*l] = mus[j] / share;
    }
    let bx = chains.b() / share;
    let bt = tpf.b() / share;
    let ct = tpf.c().row(0).into_owned();
    let dt = tpf.d()[0];
    let mut a = DMatrix::<f64>::zeros(n, n);
    a.view_mut((0, 0), (nx, nx))
        .copy_from(&(chains.a() + chains.b() * g.transpose()));
    a.view_mut((nx, 0), (nt, nx))
        .copy_from(&(tpf.b() * g.transpose()));
    a.view_mut((nx, nx), (nt, nt)).copy_from(tpf.a());
    let mut b = DVector::<f64>::zeros(n);
    b.rows_mut(0, nx).copy_from(&bx);
    b.rows_mut(nx, nt).copy_from(&bt);
    let mut c = DMatrix::<f64>::zeros(1, n);
    c.view_mut((0, 0), (1, nx)).copy_from(&(g.transpose() * dt));
    c.view_mut((0, nx), (1, nt)).copy_from(&ct);
    let d = DVector::from_element(1, dt / share);
    // positive form (T_i^pf); the sign is applied in `step`
    StateSpace::new(a, b, c, d).expect("complement realization dimensions")
}

impl GfmPfModel {
    /// Build the grid-forming p-f model for ADPF `adpf` (any kind).
    ///
    /// * Low-pass: `μ ≥ MU_MIN_GFM` required (else [`DvppError::GainOutOfRange`]);
    ///   `(τ s + 1)^d T_pf` must be proper (`T_pf` of relative degree ≥ `d`), else
    ///   [`DvppError::ImproperInverse`].
    /// * Complement: realized by feedback (no inverse formed); `T_pf` any proper stable.
    /// * High-/band-pass: `T_pf/m` must be proper.
    pub fn new(tdes: &TDes, adpf: &Adpf) -> Result<Self> {
        Self::with_floor(tdes, adpf, MU_MIN_GFM)
    }

    /// As [`GfmPfModel::new`] with the floor `mu_min` in `(0, MU_MIN_GFM]` of a low-pass unit's
    /// dc gain instead of `MU_MIN_GFM` (a unit's own floor, [`mu_min_gfm`]).
    pub fn with_floor(tdes: &TDes, adpf: &Adpf, mu_min: f64) -> Result<Self> {
        check_finite("μ_min", mu_min)?;
        if !(mu_min > 0.0 && mu_min <= MU_MIN_GFM) {
            return Err(DvppError::InvalidParameter {
                what: "μ_min".into(),
                reason: format!("must be in (0, {MU_MIN_GFM}], got {mu_min}"),
            });
        }
        let tpf = tdes.pf().clone();
        match adpf {
            Adpf::LowPass(spec) => {
                if spec.mu < mu_min {
                    return Err(DvppError::GainOutOfRange {
                        what: "grid-forming low-pass p-f dc gain".into(),
                        value: spec.mu,
                        min: mu_min,
                        max: 1.0,
                    });
                }
                let g = tpf.div(&TransferFunction::lag_power(spec.tau, spec.order)?)?;
                Ok(Self {
                    real: GfmPfRealization::LowPass { spec: *spec },
                    mu: spec.mu,
                    lpf_mus: Vec::new(),
                    sim: LtiSimulator::new(g.to_state_space(), Hold::Zero),
                    tpf,
                    mu_min,
                })
            }
            Adpf::Complement { share, lpf } => {
                Adpf::complement_of_specs(*share, lpf.clone())?;
                let mus: Vec<f64> = lpf.iter().map(|s| s.mu).collect();
                let tss = tpf.to_state_space();
                let sys = complement_gfm_system(&tss, *share, lpf, &mus);
                Ok(Self {
                    real: GfmPfRealization::Complement {
                        share: *share,
                        lpf: lpf.clone(),
                        tpf: tss,
                    },
                    mu: adpf.dc_gain(),
                    lpf_mus: mus,
                    sim: LtiSimulator::new(sys, Hold::Zero),
                    tpf,
                    mu_min,
                })
            }
            Adpf::HighPass { .. } | Adpf::BandPass { .. } => {
                let t = tpf.div(&adpf.transfer_function())?;
                Ok(Self {
                    real: GfmPfRealization::Fixed { adpf: adpf.clone() },
                    mu: 0.0,
                    lpf_mus: Vec::new(),
                    sim: LtiSimulator::new(t.to_state_space(), Hold::Zero),
                    tpf,
                    mu_min,
                })
            }
        }
    }

    /// The ADPF currently realized (with the current gains).
    pub fn adpf(&self) -> Adpf {
        match &self.real {
            GfmPfRealization::LowPass { spec } => Adpf::LowPass(LowPassSpec {
                mu: self.mu,
                ..*spec
            }),
            GfmPfRealization::Complement { share, lpf, .. } => Adpf::Complement {
                share: *share,
                lpf: lpf
                    .iter()
                    .zip(&self.lpf_mus)
                    .map(|(s, mu)| LowPassSpec { mu: *mu, ..*s })
                    .collect(),
            },
            GfmPfRealization::Fixed { adpf } => adpf.clone(),
        }
    }

    /// The floor of a low-pass unit's dc gain.
    pub fn mu_min(&self) -> f64 {
        self.mu_min
    }

    /// Set the own dc gain of a low-pass unit, clamped to `[μ_min, 1]`; returns the
    /// applied value. Errors for NaN or for other unit kinds.
    pub fn set_mu(&mut self, mu: f64) -> Result<f64> {
        check_finite("grid-forming dc gain", mu)?;
        match self.real {
            GfmPfRealization::LowPass { .. } => {
                self.mu = mu.clamp(self.mu_min, 1.0);
                Ok(self.mu)
            }
            _ => Err(DvppError::WrongUnitKind {
                what: "set_mu on a grid-forming unit that is not low-pass".into(),
            }),
        }
    }

    /// Set the dc gains of the low-pass units a complement unit closes (each in `[0,1]`,
    /// sum ≤ 1). The state is kept; the realization is rebuilt (and re-discretized on the next
    /// step) only when the gains change.
    pub fn set_lpf_gains(&mut self, mus: &[f64]) -> Result<()> {
        match &self.real {
            GfmPfRealization::Complement { share, lpf, tpf } => {
                check_lpf_gains(mus, lpf.len(), *share)?;
                if mus != self.lpf_mus.as_slice() {
                    let sys = complement_gfm_system(tpf, *share, lpf, mus);
                    self.sim.set_system(sys)?;
                    self.mu = share - mus.iter().sum::<f64>();
                    self.lpf_mus = mus.to_vec();
                }
                Ok(())
            }
            _ => Err(DvppError::WrongUnitKind {
                what: "set_lpf_gains on a grid-forming unit that is not a complement".into(),
            }),
        }
    }

    /// Advance by `h` with `Δp_i` held; returns `Δf_i` at the end of the step.
    pub fn step(&mut self, dp: f64, h: f64) -> f64 {
        match self.real {
            GfmPfRealization::LowPass { .. } => -self.sim.step(dp / self.mu, h),
            _ => -self.sim.step(dp, h),
        }
    }

    /// Advance by `h` with `Δp_i` held; returns `Δf_i` at the end of the step and its exact
    /// integral `∫ Δf_i dt` over the step (for the imposed angle `θ_i`).
    pub fn step_with_integral(&mut self, dp: f64, h: f64) -> (f64, f64) {
        let u = match self.real {
            GfmPfRealization::LowPass { .. } => dp / self.mu,
            _ => dp,
        };
        let (y, integral) = self.sim.step_with_integral(u, h);
        (-y, -integral)
    }

    /// `T_i^pf(jω)` of the realization at the current gains.
    pub fn freq_response(&self, omega: f64) -> Complex<f64> {
        let g = self.sim.system().freq_response(omega)[0];
        match self.real {
            GfmPfRealization::LowPass { .. } => g / self.mu,
            _ => g,
        }
    }

    /// `T_i^pf = T_pf/m_i` by rational algebra at the current gains.
    pub fn transfer_function(&self) -> Result<TransferFunction> {
        self.tpf.div(&self.adpf().transfer_function())
    }

    /// Poles stable; a single origin pole is allowed iff the ADPF has zero dc gain (the unit
    /// then injects transient power only).
    pub fn check_stability(&self) -> Result<()> {
        let allow = self.adpf().dc_gain().abs() <= 1e-12;
        stability_check(
            "grid-forming p-f local reference model",
            &self.transfer_function()?,
            allow,
        )
    }

    /// Internal simulator (state snapshots).
    pub fn simulator(&self) -> &LtiSimulator {
        &self.sim
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
enum ShapedRealization {
    /// `F/(τ s+1)^d` simulated, scaled by `μ(t)` at the output (static: `d = 0`).
    LowPass { spec: LowPassSpec },
    /// outputs `[v_f, x_1, …]`, output `c v_f − Σ μ_j x_j`.
    Complement { share: f64, lpf: Vec<LowPassSpec> },
    /// LTI `m F` (high-pass, band-pass).
    Fixed { adpf: Adpf },
}

/// A base reference `F(s)` followed by an ADPF `m(s)` whose dc gains enter at the output:
/// `y = m(s) F(s) u`.
///
/// `F` is realized once; low-pass (and static) units output `μ(t)·[F L](u)`, a complement
/// outputs `c v_f − Σ_j μ_j(t) x_j` with `v_f = F u` and `x_j = L_j(v_f)` realized jointly
/// (series connection, one state vector). The dynamics are LTI, so moving gains never force a
/// re-discretization, and units sharing `F` and the input sum to `F u` at every step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShapedModel {
    base: TransferFunction,
    real: ShapedRealization,
    mu: f64,
    lpf_mus: Vec<f64>,
    sim: LtiSimulator,
}

impl ShapedModel {
    /// `m(s) F(s)` for any ADPF kind.
    pub fn new(base: TransferFunction, adpf: &Adpf) -> Result<Self> {
        let (real, mu, lpf_mus, sys) = match adpf {
            Adpf::LowPass(spec) => {
                let g = if spec.is_static() {
                    base.clone()
                } else {
                    base.mul(&TransferFunction::lag_power(spec.tau, spec.order)?)
                };
                (
                    ShapedRealization::LowPass { spec: *spec },
                    spec.mu,
                    Vec::new(),
                    g.to_state_space(),
                )
            }
            Adpf::Complement { share, lpf } => {
                Adpf::complement_of_specs(*share, lpf.clone())?;
                let mus: Vec<f64> = lpf.iter().map(|s| s.mu).collect();
                let (chains, _) = lpf_chains(lpf, true);
                let sys = base.to_state_space().series(&chains);
                (
                    ShapedRealization::Complement {
                        share: *share,
                        lpf: lpf.clone(),
                    },
                    adpf.dc_gain(),
                    mus,
                    sys,
                )
            }
            _ => {
                let g = adpf.transfer_function().mul(&base);
                (
                    ShapedRealization::Fixed { adpf: adpf.clone() },
                    0.0,
                    Vec::new(),
                    g.to_state_space(),
                )
            }
        };
        Ok(Self {
            base,
            real,
            mu,
            lpf_mus,
            sim: LtiSimulator::new(sys, Hold::Zero),
        })
    }

    /// The base reference `F`.
    pub fn base(&self) -> &TransferFunction {
        &self.base
    }

    /// The ADPF currently realized (with the current gains).
    pub fn adpf(&self) -> Adpf {
        match &self.real {
            ShapedRealization::LowPass { spec } => Adpf::LowPass(LowPassSpec {
                mu: self.mu,
                ..*spec
            }),
            ShapedRealization::Complement { share, lpf } => Adpf::Complement {
                share: *share,
                lpf: lpf
                    .iter()
                    .zip(&self.lpf_mus)
                    .map(|(s, mu)| LowPassSpec { mu: *mu, ..*s })
                    .collect(),
            },
            ShapedRealization::Fixed { adpf } => adpf.clone(),
        }
    }

    /// Own dc gain of a static or low-pass unit, clamped to `[0, 1]`; returns the applied value.
    pub fn set_mu(&mut self, mu: f64) -> Result<f64> {
        check_finite("dc gain", mu)?;
        match self.real {
            ShapedRealization::LowPass { .. } => {
                self.mu = mu.clamp(0.0, 1.0);
                Ok(self.mu)
            }
            _ => Err(DvppError::WrongUnitKind {
                what: "set_mu on a unit that is neither static nor low-pass".into(),
            }),
        }
    }

    /// Gains of the complemented low-pass units (complement only; each in `[0,1]`, sum ≤ share).
    pub fn set_lpf_gains(&mut self, mus: &[f64]) -> Result<()> {
        match &self.real {
            ShapedRealization::Complement { share, lpf } => {
                check_lpf_gains(mus, lpf.len(), *share)?;
                self.lpf_mus.clear();
                self.lpf_mus.extend_from_slice(mus);
                self.mu = share - mus.iter().sum::<f64>();
                Ok(())
            }
            _ => Err(DvppError::WrongUnitKind {
                what: "set_lpf_gains on a unit that is not a complement".into(),
            }),
        }
    }

    /// Current dc gain `m(0)`.
    pub fn dc_gain(&self) -> f64 {
        self.mu
    }

    fn combine(&self, y: &DVector<f64>) -> f64 {
        match self.real {
            ShapedRealization::LowPass { .. } => self.mu * y[0],
            ShapedRealization::Complement { share, .. } => {
                let mut v = share * y[0];
                for (j, mu) in self.lpf_mus.iter().enumerate() {
                    v -= mu * y[j + 1];
                }
                v
            }
            ShapedRealization::Fixed { .. } => y[0],
        }
    }

    /// Advance by `h` with `u` held; returns `y = m F u` at the end of the step.
    pub fn step(&mut self, u: f64, h: f64) -> f64 {
        self.sim.step_all(u, h);
        self.combine(self.sim.last_outputs())
    }

    /// `m(jω) F(jω)` of the realization at the current gains.
    pub fn freq_response(&self, omega: f64) -> Complex<f64> {
        let y = self.sim.system().freq_response(omega);
        match self.real {
            ShapedRealization::LowPass { .. } => y[0] * self.mu,
            ShapedRealization::Complement { share, .. } => {
                let mut v = y[0] * share;
                for (j, mu) in self.lpf_mus.iter().enumerate() {
                    v -= y[j + 1] * *mu;
                }
                v
            }
            ShapedRealization::Fixed { .. } => y[0],
        }
    }

    /// `m F` by rational algebra at the current gains.
    pub fn transfer_function(&self) -> TransferFunction {
        self.adpf().transfer_function().mul(&self.base)
    }

    /// Internal simulator (state snapshots).
    pub fn simulator(&self) -> &LtiSimulator {
        &self.sim
    }
}

/// Grid-following p-f local reference model `Δp_i = −T_i^fp(s) Δf_i`,
/// `T_i^fp = m_i T_pf⁻¹ / (τ_pll s + 1)^d`.
///
/// A [`ShapedModel`] with base `F = T_pf⁻¹/(τ_pll s + 1)^d`: the gains enter at the output,
/// low-pass `Δp = −μ(t)·[F L](Δf)`, complement `Δp = −(c v_f − Σ_j μ_j(t) x_j)`. Hence the
/// sum over a unit set equals `−F Δf` at every step while gains move (tested).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GflFpModel {
    tau_pll: f64,
    pll_order: u32,
    shaped: ShapedModel,
}

impl GflFpModel {
    /// Build for ADPF `adpf` with PLL roll-off `1/(τ_pll s + 1)^d`. `T_pf⁻¹/(τ_pll s+1)^d` must
    /// be proper (`d ≥` relative degree of `T_pf`), else [`DvppError::ImproperInverse`].
    pub fn new(tdes: &TDes, adpf: &Adpf, tau_pll: f64, pll_order: u32) -> Result<Self> {
        let f = TransferFunction::lag_power(tau_pll, pll_order)?.div(tdes.pf())?;
        Ok(Self {
            tau_pll,
            pll_order,
            shaped: ShapedModel::new(f, adpf)?,
        })
    }

    /// PLL roll-off `(τ_pll, d)`.
    pub fn pll(&self) -> (f64, u32) {
        (self.tau_pll, self.pll_order)
    }

    /// The ADPF currently realized.
    pub fn adpf(&self) -> Adpf {
        self.shaped.adpf()
    }

    /// Own dc gain (static or low-pass), clamped to `[0, 1]`; returns the applied value.
    pub fn set_mu(&mut self, mu: f64) -> Result<f64> {
        self.shaped.set_mu(mu)
    }

    /// Gains of the complemented low-pass units (complement only).
    pub fn set_lpf_gains(&mut self, mus: &[f64]) -> Result<()> {
        self.shaped.set_lpf_gains(mus)
    }

    /// Advance by `h` with `Δf_i` (PLL measurement) held; returns `Δp_i` (change of `p_ref`).
    pub fn step(&mut self, df: f64, h: f64) -> f64 {
        -self.shaped.step(df, h)
    }

    /// `T_i^fp(jω)` of the realization at the current gains.
    pub fn freq_response(&self, omega: f64) -> Complex<f64> {
        self.shaped.freq_response(omega)
    }

    /// `T_i^fp` by rational algebra at the current gains.
    pub fn transfer_function(&self) -> Result<TransferFunction> {
        Ok(self.shaped.transfer_function())
    }

    /// All poles in the open left half plane.
    pub fn check_stability(&self) -> Result<()> {
        stability_check(
            "grid-following p-f local reference model",
            &self.shaped.transfer_function(),
            false,
        )
    }

    /// Internal simulator (state snapshots).
    pub fn simulator(&self) -> &LtiSimulator {
        self.shaped.simulator()
    }
}

/// v-q local reference model `Δq_i = −T_i^vq(s) Δv_pcc` with a reactive ADPF `m_i^q`:
/// grid-forming `T_i^vq = m_i^q T_qv⁻¹/(τ_q s + 1)`; grid-following additionally
/// `/(τ_pll s + 1)^d`. Static `m^q = μ_q` with `T_qv = D_q`: `Δq_i = −μ_q/D_q · 1/(τ_q s+1) Δv`.
/// Gains enter at the output (a [`ShapedModel`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VqModel {
    pll: Option<(f64, u32)>,
    shaped: ShapedModel,
}

impl VqModel {
    /// Grid-forming v-q model with a static participation `μ_q ∈ [0, 1]`.
    pub fn grid_forming(tdes: &TDes, mu_q: f64) -> Result<Self> {
        crate::error::check_unit_gain("reactive dc gain mu_q", mu_q)?;
        Self::grid_forming_shaped(tdes, &Adpf::static_gain(mu_q)?)
    }

    /// Grid-forming v-q model with any reactive ADPF.
    pub fn grid_forming_shaped(tdes: &TDes, adpf: &Adpf) -> Result<Self> {
        Ok(Self {
            pll: None,
            shaped: ShapedModel::new(tdes.vq_reference()?, adpf)?,
        })
    }

    /// Grid-following v-q model (static `μ_q`) with PLL/measurement roll-off `1/(τ_pll s + 1)^d`.
    pub fn grid_following(tdes: &TDes, mu_q: f64, tau_pll: f64, pll_order: u32) -> Result<Self> {
        crate::error::check_unit_gain("reactive dc gain mu_q", mu_q)?;
        Self::grid_following_shaped(tdes, &Adpf::static_gain(mu_q)?, tau_pll, pll_order)
    }

    /// Grid-following v-q model with any reactive ADPF and PLL roll-off `1/(τ_pll s + 1)^d`.
    pub fn grid_following_shaped(
        tdes: &TDes,
        adpf: &Adpf,
        tau_pll: f64,
        pll_order: u32,
    ) -> Result<Self> {
        let base = tdes
            .vq_reference()?
            .mul(&TransferFunction::lag_power(tau_pll, pll_order)?);
        Ok(Self {
            pll: Some((tau_pll, pll_order)),
            shaped: ShapedModel::new(base, adpf)?,
        })
    }

    /// PLL roll-off of a grid-following unit.
    pub fn pll(&self) -> Option<(f64, u32)> {
        self.pll
    }

    /// Current reactive dc gain `m^q(0)`.
    pub fn mu_q(&self) -> f64 {
        self.shaped.dc_gain()
    }

    /// The reactive ADPF currently realized.
    pub fn adpf(&self) -> Adpf {
        self.shaped.adpf()
    }

    /// Set `μ_q` (static or low-pass) clamped to `[0, 1]`; returns the applied value.
    pub fn set_mu(&mut self, mu_q: f64) -> Result<f64> {
        self.shaped.set_mu(mu_q)
    }

    /// Gains of the complemented low-pass units (complement only).
    pub fn set_lpf_gains(&mut self, mus: &[f64]) -> Result<()> {
        self.shaped.set_lpf_gains(mus)
    }

    /// Advance by `h` with `Δv_pcc` held; returns `Δq_i`.
    pub fn step(&mut self, dv: f64, h: f64) -> f64 {
        -self.shaped.step(dv, h)
    }

    /// `T_i^vq(jω)` of the realization.
    pub fn freq_response(&self, omega: f64) -> Complex<f64> {
        self.shaped.freq_response(omega)
    }

    /// `T_i^vq` by rational algebra.
    pub fn transfer_function(&self) -> TransferFunction {
        self.shaped.transfer_function()
    }

    /// All poles in the open left half plane (the base reference; ADPFs are stable).
    pub fn check_stability(&self) -> Result<()> {
        stability_check("v-q local reference model", self.shaped.base(), false)
    }
}

/// `(τ jω + 1)^d` — used to compensate a known PLL roll-off in the hybrid checks.
pub(crate) fn rolloff_inverse_at(tau: f64, d: u32, omega: f64) -> Complex<f64> {
    crate::tf::poly_eval(&lag_poly(tau, d), Complex::new(0.0, omega))
}
