//! Time integration: the internal step matched to the case's time constants, and fixed-step RK4
//! over a semi-explicit DAE ([`Dae`]: states, their derivative, an algebraic solve per stage).
//!
//! Classical fourth-order Runge–Kutta with a fixed internal step (the grid splits the
//! communication step into equal sub-steps), with a full algebraic solve (the grid: its network)
//! at every stage. This module knows nothing of the grid: it integrates any [`Dae`].
//!
//! RK4 is stable for a decaying mode of time constant τ only while h < 2.785 τ. The internal step
//! is therefore at most [`MAX_INTERNAL_STEP`] and at most τ_min / [`STEPS_PER_TIME_CONSTANT`],
//! τ_min being the smallest time constant of the case (see [`crate::Grid::internal_step_note`]); a case
//! that would need a step below [`MIN_INTERNAL_STEP`] is refused when the grid is built.

pub use crate::numerics::{MAX_INTERNAL_STEP, MIN_INTERNAL_STEP, STEPS_PER_TIME_CONSTANT};

use crate::error::GridError;
use crate::numerics::TimeConstant;

/// The internal step for time constants `tcs`: [`MAX_INTERNAL_STEP`] or less, and why it is
/// less (a note naming the limiting parameter); an error names a time constant too small.
pub(crate) fn choose_internal_step(
    tcs: &[TimeConstant],
) -> Result<(f64, Option<String>), GridError> {
    let Some(min) = tcs.iter().min_by(|a, b| a.tau.total_cmp(&b.tau)) else {
        return Ok((MAX_INTERNAL_STEP, None));
    };
    let h = min.tau / STEPS_PER_TIME_CONSTANT;
    if h >= MAX_INTERNAL_STEP {
        return Ok((MAX_INTERNAL_STEP, None));
    }
    if h.is_nan() || h < MIN_INTERNAL_STEP {
        return Err(GridError::TimeConstantTooSmall {
            parameter: min.describe(),
            min: MIN_INTERNAL_STEP * STEPS_PER_TIME_CONSTANT,
        });
    }
    let note = format!(
        "internal integration step reduced from {} ms to {:.4} ms for the whole grid: {} is \
         shorter than {} ms (the step is at most 1/{} of the smallest time constant)",
        MAX_INTERNAL_STEP * 1e3,
        h * 1e3,
        min.describe(),
        MAX_INTERNAL_STEP * STEPS_PER_TIME_CONSTANT * 1e3,
        STEPS_PER_TIME_CONSTANT
    );
    Ok((h, Some(note)))
}

/// A semi-explicit DAE `x' = f(x, y)`, `0 = g(x, y)`: what [`Rk4`] integrates.
pub trait Dae {
    /// The algebraic variables `y`; also the starting guess of the next solve.
    type Solution: Clone;
    /// Work buffers of the algebraic solve.
    type Scratch;
    type Error;
    /// Solve the algebraic equations at states `x`: `sol` holds the starting guess and receives
    /// the solution.
    fn solve(
        &self,
        x: &[f64],
        sol: &mut Self::Solution,
        scratch: &mut Self::Scratch,
    ) -> Result<(), Self::Error>;
    /// Time derivative `dx` of the states at `x` with their algebraic solution `sol`.
    fn derivative(&self, x: &[f64], sol: &Self::Solution, dx: &mut Vec<f64>);
    /// Bring the states within their limits after a step (default: none).
    fn clamp(&self, _x: &mut [f64]) {}
    /// The error for a step that made a state non-finite.
    fn non_finite(&self) -> Self::Error;
}

/// Classical fixed-step RK4 with its stage buffers (reused, so that a step allocates nothing).
#[derive(Clone, Debug, Default)]
pub struct Rk4<S> {
    x0: Vec<f64>,
    xs: Vec<f64>,
    k: [Vec<f64>; 4],
    stage: S,
}

impl<S: Clone> Rk4<S> {
    /// One step of length `h` of `sys` from states `x` whose algebraic solution is `sol`.
    ///
    /// Every stage solves the algebraic equations (starting from the previous stage's
    /// solution); the new states are clamped, then solved (starting from `sol`). On success `x`
    /// and `sol` hold the new point; a failed stage leaves both as they were, a non-finite
    /// state restores `x`, a failed final solve leaves `sol` as it was.
    pub fn step<D: Dae<Solution = S>>(
        &mut self,
        sys: &D,
        x: &mut [f64],
        sol: &mut S,
        scratch: &mut D::Scratch,
        h: f64,
    ) -> Result<(), D::Error> {
        let Rk4 { x0, xs, k, stage } = self;
        x0.clear();
        x0.extend_from_slice(x);
        sys.derivative(x0, sol, &mut k[0]);
        stage.clone_from(sol);
        for (s, c) in [(1, 0.5), (2, 0.5), (3, 1.0)] {
            xs.clear();
            xs.extend(x0.iter().zip(&k[s - 1]).map(|(x, d)| x + c * h * d));
            sys.solve(xs, stage, scratch)?;
            sys.derivative(xs, stage, &mut k[s]);
        }
        for i in 0..x0.len() {
            x[i] = x0[i] + h / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i]);
        }
        if x.iter().any(|v| !v.is_finite()) {
            x.copy_from_slice(x0);
            return Err(sys.non_finite());
        }
        sys.clamp(x);
        // The solution at the new state: the next step's first stage.
        stage.clone_from(sol);
        sys.solve(x, stage, scratch)?;
        std::mem::swap(sol, stage);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `x' = A x` with an algebraic `y = x_0 + x_1` (the derivative reads it), and a clamp.
    struct Oscillator {
        clamp_at: f64,
    }

    impl Dae for Oscillator {
        type Solution = f64;
        type Scratch = usize;
        type Error = &'static str;
        fn solve(&self, x: &[f64], sol: &mut f64, solves: &mut usize) -> Result<(), &'static str> {
            *solves += 1;
            *sol = x[0] + x[1];
            Ok(())
        }
        fn derivative(&self, x: &[f64], y: &f64, dx: &mut Vec<f64>) {
            dx.clear();
            // x0' = x1, x1' = -x0 written through y: x1' = x1 - y
            dx.extend([x[1], x[1] - y]);
        }
        fn clamp(&self, x: &mut [f64]) {
            x[0] = x[0].min(self.clamp_at);
        }
        fn non_finite(&self) -> &'static str {
            "non-finite"
        }
    }

    #[test]
    fn rk4_integrates_a_linear_oscillator_to_fourth_order() {
        let sys = Oscillator {
            clamp_at: f64::INFINITY,
        };
        let run = |n: usize| {
            let (mut x, mut y, mut solves) = (vec![1.0, 0.0], 1.0, 0);
            let mut rk = Rk4::default();
            let h = 1.0 / n as f64;
            for _ in 0..n {
                rk.step(&sys, &mut x, &mut y, &mut solves, h).unwrap();
            }
            assert_eq!(solves, 4 * n);
            assert_eq!(y, x[0] + x[1]);
            (
                dvpp_math::hypot(x[0] - dvpp_math::cos(1f64), x[1] + dvpp_math::sin(1f64)),
                x,
            )
        };
        let (e10, _) = run(10);
        let (e20, x) = run(20);
        assert!(e20 < 1e-6, "{x:?}");
        let order = dvpp_math::log2(e10 / e20);
        assert!((order - 4.0).abs() < 0.2, "order {order}");
    }

    #[test]
    fn rk4_clamps_and_refuses_non_finite_states() {
        let sys = Oscillator { clamp_at: 0.5 };
        let (mut x, mut y, mut solves) = (vec![0.0, 1.0], 1.0, 0);
        let mut rk = Rk4::default();
        rk.step(&sys, &mut x, &mut y, &mut solves, 1.0).unwrap();
        assert_eq!(x[0], 0.5);
        let mut x = vec![f64::MAX, f64::MAX];
        let mut y = 0.0;
        assert_eq!(
            rk.step(&sys, &mut x, &mut y, &mut solves, 1e300),
            Err("non-finite")
        );
        assert_eq!(x, vec![f64::MAX, f64::MAX]);
    }
}
