//! Real-coefficient proper rational transfer functions `N(s)/D(s)` (SISO).
//!
//! **Coefficient order: ascending powers of `s`.** `num[k]` and `den[k]` multiply `s^k`, so
//! `1/(H s + D)` is `TransferFunction::new(vec![1.0], vec![D, H])`.

use crate::error::{check_finite, check_tau, DvppError, Result};
use crate::ss::StateSpace;
use nalgebra::{Complex, DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Polynomial product (ascending coefficients).
pub(crate) fn poly_mul(a: &[f64], b: &[f64]) -> Vec<f64> {
    if a.is_empty() || b.is_empty() {
        return vec![0.0];
    }
    let mut c = vec![0.0; a.len() + b.len() - 1];
    for (i, ai) in a.iter().enumerate() {
        for (j, bj) in b.iter().enumerate() {
            c[i + j] += ai * bj;
        }
    }
    c
}

/// Polynomial sum with cancellation-aware zeroing: a coefficient whose magnitude is within a
/// few rounding units of the magnitudes that produced it is set to exactly zero, so that
/// e.g. `1 − Σ μ_j/(τ_j s+1)` with `Σ μ_j = 1` gets an exact zero constant term.
pub(crate) fn poly_add(a: &[f64], b: &[f64]) -> Vec<f64> {
    let n = a.len().max(b.len());
    let mut c = vec![0.0; n];
    for (k, ck) in c.iter_mut().enumerate() {
        let x = a.get(k).copied().unwrap_or(0.0);
        let y = b.get(k).copied().unwrap_or(0.0);
        let s = x + y;
        let scale = x.abs() + y.abs();
        *ck = if s.abs() <= 8.0 * f64::EPSILON * scale {
            0.0
        } else {
            s
        };
    }
    c
}

/// Remove exactly-zero highest-order coefficients (keeps at least one coefficient).
pub(crate) fn poly_trim(mut p: Vec<f64>) -> Vec<f64> {
    while p.len() > 1 && *p.last().unwrap() == 0.0 {
        p.pop();
    }
    if p.is_empty() {
        p.push(0.0);
    }
    p
}

/// Degree of a trimmed polynomial (`0` for constants, including the zero polynomial).
pub(crate) fn poly_degree(p: &[f64]) -> usize {
    let mut d = p.len().saturating_sub(1);
    while d > 0 && p[d] == 0.0 {
        d -= 1;
    }
    d
}

/// Horner evaluation at a complex point.
pub(crate) fn poly_eval(p: &[f64], s: Complex<f64>) -> Complex<f64> {
    let mut acc = Complex::new(0.0, 0.0);
    for c in p.iter().rev() {
        acc = acc * s + Complex::new(*c, 0.0);
    }
    acc
}

/// `(tau s + 1)^d` in ascending coefficients.
pub(crate) fn lag_poly(tau: f64, d: u32) -> Vec<f64> {
    let mut p = vec![1.0];
    for _ in 0..d {
        p = poly_mul(&p, &[1.0, tau]);
    }
    p
}

/// Strict Hurwitz test by the Routh array: `true` iff every root of `p` has negative real part.
/// A constant non-zero polynomial has no roots and is Hurwitz.
pub(crate) fn routh_hurwitz(p: &[f64]) -> bool {
    let p = poly_trim(p.to_vec());
    let n = poly_degree(&p);
    if n == 0 {
        return p[0] != 0.0;
    }
    // descending coefficients, normalized to a positive leading coefficient
    let sign = p[n].signum();
    let desc: Vec<f64> = (0..=n).rev().map(|k| p[k] * sign).collect();
    // necessary condition: all coefficients strictly positive
    if desc.iter().any(|c| *c <= 0.0) {
        return false;
    }
    let width = n / 2 + 1;
    let mut r0: Vec<f64> = (0..width)
        .map(|i| desc.get(2 * i).copied().unwrap_or(0.0))
        .collect();
    let mut r1: Vec<f64> = (0..width)
        .map(|i| desc.get(2 * i + 1).copied().unwrap_or(0.0))
        .collect();
    for _ in 0..n {
        if r1[0] <= 0.0 {
            return false;
        }
        let mut r2 = vec![0.0; width];
        for i in 0..width - 1 {
            r2[i] = (r1[0] * r0[i + 1] - r0[0] * r1[i + 1]) / r1[0];
        }
        r0 = r1;
        r1 = r2;
    }
    // the array is exhausted after n rows below the first one; every first-column entry
    // visited was positive
    true
}

/// A real-coefficient proper rational transfer function `N(s)/D(s)`.
///
/// Invariants (enforced by every constructor): finite coefficients, non-zero denominator,
/// `deg N ≤ deg D` (proper), highest-order denominator coefficient non-zero, no exact trailing
/// zeros. Coefficients are in **ascending** powers of `s`. No pole/zero cancellation is
/// attempted, so products keep the full order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TransferFunction {
    num: Vec<f64>,
    den: Vec<f64>,
}

impl TransferFunction {
    /// Build `N(s)/D(s)` from ascending coefficients. Rejects empty, non-finite or zero
    /// denominators, non-finite numerators and improper ratios.
    pub fn new(num: Vec<f64>, den: Vec<f64>) -> Result<Self> {
        if den.is_empty() || den.iter().all(|c| *c == 0.0) {
            return Err(DvppError::ZeroPolynomial {
                what: "transfer function denominator".into(),
            });
        }
        if num.is_empty() {
            return Err(DvppError::ZeroPolynomial {
                what: "transfer function numerator (empty)".into(),
            });
        }
        for c in num.iter().chain(den.iter()) {
            check_finite("transfer function coefficient", *c)?;
        }
        let num = poly_trim(num);
        let den = poly_trim(den);
        let (dn, dd) = (poly_degree(&num), poly_degree(&den));
        // The realizations divide by the leading denominator coefficient: a (subnormal) leading
        // coefficient that overflows them is refused here rather than met there.
        let lead = den[dd];
        if num
            .iter()
            .chain(den.iter())
            .any(|c| !(c / lead).is_finite())
        {
            return Err(DvppError::NonFinite {
                what: format!(
                    "transfer function coefficient over the leading denominator coefficient {lead:e}"
                ),
            });
        }
        if num.iter().any(|c| *c != 0.0) && dn > dd {
            return Err(DvppError::Improper {
                what: "transfer function".into(),
                num_degree: dn,
                den_degree: dd,
            });
        }
        Ok(Self { num, den })
    }

    /// Static gain `k`.
    pub fn gain(k: f64) -> Result<Self> {
        Self::new(vec![k], vec![1.0])
    }

    /// First-order lag `k/(tau s + 1)`; `tau > 0`.
    pub fn first_order_lag(k: f64, tau: f64) -> Result<Self> {
        check_tau("first-order lag", tau)?;
        Self::new(vec![k], vec![1.0, tau])
    }

    /// `1/(tau s + 1)^d`; `tau > 0`.
    pub fn lag_power(tau: f64, d: u32) -> Result<Self> {
        check_tau("lag power", tau)?;
        Self::new(vec![1.0], lag_poly(tau, d))
    }

    /// Numerator coefficients (ascending powers).
    pub fn num(&self) -> &[f64] {
        &self.num
    }

    /// Denominator coefficients (ascending powers).
    pub fn den(&self) -> &[f64] {
        &self.den
    }

    /// `true` for the identically-zero transfer function.
    pub fn is_zero(&self) -> bool {
        self.num.iter().all(|c| *c == 0.0)
    }

    /// Numerator degree (0 for the zero function).
    pub fn num_degree(&self) -> usize {
        poly_degree(&self.num)
    }

    /// Denominator degree (number of poles, counted without cancellation).
    pub fn den_degree(&self) -> usize {
        poly_degree(&self.den)
    }

    /// Relative degree `deg D − deg N` (≥ 0 for every stored value; `i64::MAX` for zero).
    pub fn relative_degree(&self) -> i64 {
        if self.is_zero() {
            return i64::MAX;
        }
        self.den_degree() as i64 - self.num_degree() as i64
    }

    /// Always `true` for a constructed value (kept for symmetry with design checks).
    pub fn is_proper(&self) -> bool {
        self.relative_degree() >= 0
    }

    /// Relative degree exactly zero (invertible with a proper inverse).
    pub fn is_biproper(&self) -> bool {
        self.relative_degree() == 0
    }

    /// Relative degree ≥ 1.
    pub fn is_strictly_proper(&self) -> bool {
        self.relative_degree() >= 1
    }

    /// Value at a complex frequency `s`.
    pub fn eval(&self, s: Complex<f64>) -> Complex<f64> {
        poly_eval(&self.num, s) / poly_eval(&self.den, s)
    }

    /// Frequency response at `s = jω`.
    pub fn freq_response(&self, omega: f64) -> Complex<f64> {
        self.eval(Complex::new(0.0, omega))
    }

    /// Dc gain `N(0)/D(0)` (infinite if there is a pole at the origin).
    pub fn dc_gain(&self) -> f64 {
        self.num[0] / self.den[0]
    }

    /// Product `self · other` (proper × proper is proper).
    pub fn mul(&self, other: &Self) -> Self {
        Self {
            num: poly_trim(poly_mul(&self.num, &other.num)),
            den: poly_trim(poly_mul(&self.den, &other.den)),
        }
    }

    /// Scalar multiple `k · self`.
    pub fn scale(&self, k: f64) -> Self {
        Self {
            num: poly_trim(self.num.iter().map(|c| c * k).collect()),
            den: self.den.clone(),
        }
    }

    /// Sum `self + other` over the common denominator `D₁ D₂` (no cancellation).
    pub fn add(&self, other: &Self) -> Self {
        if self.den == other.den {
            return Self {
                num: poly_trim(poly_add(&self.num, &other.num)),
                den: self.den.clone(),
            };
        }
        let num = poly_add(
            &poly_mul(&self.num, &other.den),
            &poly_mul(&other.num, &self.den),
        );
        Self {
            num: poly_trim(num),
            den: poly_trim(poly_mul(&self.den, &other.den)),
        }
    }

    /// Difference `self − other`.
    pub fn sub(&self, other: &Self) -> Self {
        self.add(&other.scale(-1.0))
    }

    /// Inverse `1/self`; only when it is proper, i.e. `self` is biproper.
    pub fn inverse(&self) -> Result<Self> {
        if self.is_zero() {
            return Err(DvppError::ZeroPolynomial {
                what: "inverse of the zero transfer function".into(),
            });
        }
        if !self.is_biproper() {
            return Err(DvppError::ImproperInverse {
                what: "transfer function inverse".into(),
                relative_degree: self.relative_degree(),
            });
        }
        Self::new(self.den.clone(), self.num.clone())
    }

    /// Quotient `self / other = self · other⁻¹`, accepted whenever the result is proper
    /// (e.g. `T_pf / m_i` or `m_i / T_pf` with enough roll-off in `m_i`).
    pub fn div(&self, other: &Self) -> Result<Self> {
        if other.is_zero() {
            return Err(DvppError::ZeroPolynomial {
                what: "division by the zero transfer function".into(),
            });
        }
        let num = poly_trim(poly_mul(&self.num, &other.den));
        let den = poly_trim(poly_mul(&self.den, &other.num));
        let rd = poly_degree(&den) as i64 - poly_degree(&num) as i64;
        if num.iter().any(|c| *c != 0.0) && rd < 0 {
            return Err(DvppError::ImproperInverse {
                what: "transfer function quotient".into(),
                relative_degree: other.relative_degree(),
            });
        }
        Self::new(num, den)
    }

    /// Poles: eigenvalues of the companion matrix of the denominator.
    pub fn poles(&self) -> Vec<Complex<f64>> {
        let n = self.den_degree();
        if n == 0 {
            return Vec::new();
        }
        let lead = self.den[n];
        let mut m = DMatrix::<f64>::zeros(n, n);
        for i in 1..n {
            m[(i, i - 1)] = 1.0;
        }
        for i in 0..n {
            m[(i, n - 1)] = -self.den[i] / lead;
        }
        m.complex_eigenvalues().iter().copied().collect()
    }

    /// Zeros: roots of the numerator (companion-matrix eigenvalues).
    pub fn zeros(&self) -> Vec<Complex<f64>> {
        let p = TransferFunction {
            num: vec![1.0],
            den: self.num.clone(),
        };
        if self.is_zero() {
            return Vec::new();
        }
        p.poles()
    }

    /// Every pole strictly in the open left half plane (Routh–Hurwitz on the denominator).
    pub fn is_stable(&self) -> bool {
        routh_hurwitz(&self.den)
    }

    /// Stable except for at most one pole at the origin (an integrator), detected as a
    /// denominator constant term below `rel_tol · max|coefficient|`. Used for grid-forming
    /// units whose ADPF has zero dc gain (their `T_i^pf = T_pf/m_i` integrates).
    pub fn is_stable_allowing_integrator(&self, rel_tol: f64) -> bool {
        let scale = self.den.iter().fold(0.0f64, |a, c| a.max(c.abs()));
        if self.den[0].abs() <= rel_tol * scale && self.den.len() > 1 {
            routh_hurwitz(&self.den[1..])
        } else {
            routh_hurwitz(&self.den)
        }
    }

    /// Controllable-canonical state-space realization (normalized to a monic denominator).
    /// For a relative degree of 0 the direct feedthrough is `D = b_n/a_n`.
    pub fn to_state_space(&self) -> StateSpace {
        let n = self.den_degree();
        let lead = self.den[n];
        let a: Vec<f64> = self.den.iter().take(n + 1).map(|c| c / lead).collect();
        let mut b: Vec<f64> = self.num.iter().map(|c| c / lead).collect();
        b.resize(n + 1, 0.0);
        let d = b[n];
        if n == 0 {
            return StateSpace::new(
                DMatrix::zeros(0, 0),
                DVector::zeros(0),
                DMatrix::zeros(1, 0),
                DVector::from_element(1, d),
            )
            .expect("static gain realization");
        }
        let mut am = DMatrix::<f64>::zeros(n, n);
        for i in 0..n - 1 {
            am[(i, i + 1)] = 1.0;
        }
        for j in 0..n {
            am[(n - 1, j)] = -a[j];
        }
        let mut bm = DVector::<f64>::zeros(n);
        bm[n - 1] = 1.0;
        let mut cm = DMatrix::<f64>::zeros(1, n);
        for j in 0..n {
            cm[(0, j)] = b[j] - d * a[j];
        }
        StateSpace::new(am, bm, cm, DVector::from_element(1, d)).expect("canonical realization")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subnormal_leading_coefficients_are_refused_not_realized() {
        // 1/(4.9e-324 s + 33.33) and 1/4.9e-324 would overflow the realizations.
        assert!(TransferFunction::new(vec![1.0], vec![33.33, 4.9e-324]).is_err());
        assert!(TransferFunction::new(vec![1.0], vec![4.9e-324]).is_err());
        let t = TransferFunction::new(vec![1.0], vec![33.33, 5.55]).unwrap();
        assert_eq!(t.to_state_space().a().nrows(), 1);
        let d = 4.9e-324;
        let e = crate::TDes::inertia_droop(d, 33.33, 0.01, 0.01).unwrap_err();
        assert!(e.to_string().contains("T_des H"), "{e}");
        let e = crate::TDes::inertia_droop(5.55, 33.33, d, 0.01).unwrap_err();
        assert!(e.to_string().contains("T_des D_q"), "{e}");
        assert!(crate::TDes::inertia_droop(0.0, 33.33, 0.01, 0.01).is_ok());
    }

    #[test]
    fn routh_examples() {
        assert!(routh_hurwitz(&[6.0, 11.0, 6.0, 1.0])); // (s+1)(s+2)(s+3)
        assert!(!routh_hurwitz(&[-6.0, 11.0, -6.0, 1.0])); // (s-1)(s-2)(s-3)
        assert!(!routh_hurwitz(&[1.0, 0.0, 1.0])); // s^2+1
        assert!(!routh_hurwitz(&[0.0, 1.0])); // s
                                              // s^3 + s^2 + 2 s + 8: two RHP roots though all coefficients positive
        assert!(!routh_hurwitz(&[8.0, 2.0, 1.0, 1.0]));
        assert!(routh_hurwitz(&[3.0]));
    }

    #[test]
    fn poles_of_second_order() {
        let tf = TransferFunction::new(vec![1.0], vec![2.0, 3.0, 1.0]).unwrap();
        let mut re: Vec<f64> = tf.poles().iter().map(|p| p.re).collect();
        re.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert!((re[0] + 2.0).abs() < 1e-12 && (re[1] + 1.0).abs() < 1e-12);
    }

    #[test]
    fn realization_matches_tf() {
        let tf = TransferFunction::new(vec![2.0, 0.5, 0.3], vec![4.0, 3.0, 1.5]).unwrap();
        let ss = tf.to_state_space();
        for w in [0.0, 0.1, 1.0, 10.0, 1e3] {
            let e = dvpp_math::cabs(ss.freq_response(w)[0] - tf.freq_response(w));
            assert!(
                e < 1e-12 * dvpp_math::cabs(tf.freq_response(w)).max(1.0),
                "{w} {e}"
            );
        }
    }
}
