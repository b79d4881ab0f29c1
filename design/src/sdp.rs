//! Linear matrix inequalities handed to clarabel: affine symmetric matrix functions in svec form.
//!
//! An LMI `F(x) ≼ -ε I` with `F` affine in the decision vector `x` is given as a function that
//! evaluates `F` at any `x`; its coefficient matrices are recovered exactly as `F(0)` and
//! `F(e_i) - F(0)` (every entry of the problems here is a sum of products with one decision
//! variable, so the differences are exact). Clarabel's conic form is `A x + s = b`, `s ∈ K`;
//! a PSD cone of order `n` holds the upper triangle of a symmetric matrix column by column with
//! the off-diagonal entries scaled by `√2` (its `PSDTriangleConeT`), so `-F(x) - ε I ≽ 0` becomes
//! the rows `svec(F_i)` of `A` and `b = -svec(F_0) - ε svec(I)`.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use nalgebra::DMatrix;

/// An affine symmetric matrix function of the decision vector.
pub type AffineMatrix<'a> = Box<dyn Fn(&[f64]) -> DMatrix<f64> + 'a>;

/// One LMI `F(x) ≼ -margin · I`.
pub struct Lmi<'a> {
    /// What it is (for messages).
    pub name: String,
    /// `F`.
    pub f: AffineMatrix<'a>,
    /// The strictness margin `ε`.
    pub margin: f64,
}

/// `svec` of the symmetric part of `m`: the upper triangle column by column, off-diagonals × √2.
pub fn svec(m: &DMatrix<f64>) -> Vec<f64> {
    let n = m.nrows();
    let mut out = Vec::with_capacity(n * (n + 1) / 2);
    for col in 0..n {
        for row in 0..=col {
            out.push(if row == col {
                m[(row, col)]
            } else {
                (m[(row, col)] + m[(col, row)]) * std::f64::consts::FRAC_1_SQRT_2
            });
        }
    }
    out
}

/// The solution of [`minimize`].
#[derive(Debug, Clone)]
pub struct Solution {
    /// The decision vector.
    pub x: Vec<f64>,
    /// Clarabel's status, as text.
    pub status: String,
    /// Interior-point iterations.
    pub iterations: u32,
}

/// Minimize `c·x` over the LMIs; `Err` unless clarabel reports the problem solved.
pub fn minimize(c: &[f64], lmis: &[Lmi]) -> Result<Solution, String> {
    let nx = c.len();
    let zero = vec![0.0; nx];
    let mut cols: Vec<Vec<(usize, f64)>> = vec![Vec::new(); nx];
    let mut b = Vec::new();
    let mut cones = Vec::new();
    let mut row0 = 0;
    for lmi in lmis {
        let f0 = (lmi.f)(&zero);
        let n = f0.nrows();
        let s0 = svec(&f0);
        let eye = svec(&DMatrix::identity(n, n));
        b.extend(s0.iter().zip(&eye).map(|(f, i)| -f - lmi.margin * i));
        let mut e = zero.clone();
        for (i, col) in cols.iter_mut().enumerate() {
            e[i] = 1.0;
            let fi = svec(&((lmi.f)(&e) - &f0));
            e[i] = 0.0;
            for (r, v) in fi.into_iter().enumerate() {
                if v != 0.0 {
                    col.push((row0 + r, v));
                }
            }
        }
        row0 += s0.len();
        cones.push(SupportedConeT::PSDTriangleConeT(n));
    }
    let mut colptr = vec![0];
    let (mut rowval, mut nzval) = (Vec::new(), Vec::new());
    for col in &cols {
        for &(r, v) in col {
            rowval.push(r);
            nzval.push(v);
        }
        colptr.push(rowval.len());
    }
    let a = CscMatrix::new(row0, nx, colptr, rowval, nzval);
    let p = CscMatrix::zeros((nx, nx));
    let settings = DefaultSettings {
        verbose: false,
        max_iter: 500,
        ..DefaultSettings::default()
    };
    let mut solver = DefaultSolver::new(&p, c, &a, &b, &cones, settings)
        .map_err(|e| format!("clarabel refused the problem: {e:?}"))?;
    solver.solve();
    let status = solver.solution.status;
    let out = Solution {
        x: solver.solution.x.clone(),
        status: format!("{status:?}"),
        iterations: solver.solution.iterations,
    };
    match status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => Ok(out),
        _ => Err(format!(
            "clarabel: {} after {} iterations",
            out.status, out.iterations
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The smallest `t` with `t I ≽ M` is the largest eigenvalue of `M`.
    #[test]
    fn largest_eigenvalue_by_sdp() {
        let m = DMatrix::from_row_slice(3, 3, &[2.0, 1.0, 0.0, 1.0, 3.0, 0.5, 0.0, 0.5, 1.0]);
        let lmi = Lmi {
            name: "M - t I".into(),
            f: Box::new(|x: &[f64]| &m - DMatrix::identity(3, 3) * x[0]),
            margin: 0.0,
        };
        let sol = minimize(&[1.0], &[lmi]).unwrap();
        let top = m.symmetric_eigen().eigenvalues.max();
        assert!((sol.x[0] - top).abs() < 1e-6, "{} {top}", sol.x[0]);
    }

    #[test]
    fn svec_order_and_scaling() {
        let m = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 3.0]);
        let s = svec(&m);
        assert_eq!(s.len(), 3);
        assert_eq!(s[0], 1.0);
        assert!((s[1] - 2.0 * 2f64.sqrt()).abs() < 1e-15);
        assert_eq!(s[2], 3.0);
    }
}
