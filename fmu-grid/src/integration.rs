//! Time integration: the internal step matched to the case's time constants, and fixed-step RK4.
//!
//! Classical fourth-order Runge–Kutta with a fixed internal step (the communication step is
//! split into equal sub-steps), with a full algebraic network solve at every stage. Events split
//! the sub-steps so they fire exactly at their time.
//!
//! RK4 is stable for a decaying mode of time constant τ only while h < 2.785 τ. The internal step
//! is therefore at most [`MAX_INTERNAL_STEP`] and at most τ_min / [`STEPS_PER_TIME_CONSTANT`],
//! τ_min being the smallest time constant of the case (see [`Grid::internal_step_note`]); a case
//! that would need a step below [`MIN_INTERNAL_STEP`] is refused when the grid is built.

pub use crate::numerics::{MAX_INTERNAL_STEP, MIN_INTERNAL_STEP, STEPS_PER_TIME_CONSTANT};

use crate::error::GridError;
use crate::grid::Grid;
use crate::network::Work;
use crate::numerics::{wrap, TimeConstant, C64, EVENT_EPS};

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

impl Grid {
    /// Time derivative `dx` of the state vector at `x`, given its network solution (bus
    /// voltages `v`, stator solutions `w_alg`).
    pub(crate) fn deriv(
        &self,
        x: &[f64],
        v: &[C64],
        alg: &[crate::machine::MachAlg],
        dx: &mut Vec<f64>,
    ) {
        dx.clear();
        dx.resize(x.len(), 0.0);
        for (m, a) in self.machines.iter().zip(alg) {
            m.deriv(x, a, v[m.bus].norm(), self.wb, self.sb, dx);
        }
        // The PCC frequency filter works on the unwrapped angle: its lag behind the angle is
        // Δω T_f, beyond π at deviations above π/(ω_b T_f) (0.1 pu for T_f = 0.1 s).
        let i = self.pcc_state;
        let th = self.pcc_angle + wrap(v[self.pcc_bus].arg() - self.pcc_angle);
        dx[i] = (th - x[i]) / self.pcc_tf;
        for (k, p) in self.pocs.iter().enumerate() {
            let th = self.poc_angle[k] + wrap(v[p.bus].arg() - self.poc_angle[k]);
            dx[i + 1 + k] = (th - x[i + 1 + k]) / p.tf;
        }
    }

    fn clamp_states(&mut self) {
        for m in &self.machines {
            m.clamp(&mut self.x);
        }
    }

    /// One RK4 step of length `h` from the current state, whose network solution is the one
    /// in `self.v` and the work buffers (left there by the last solve: `resolve` at the start of
    /// a communication step, an event, or the previous sub-step's final solve).
    fn rk4(&mut self, h: f64) -> Result<(), GridError> {
        let mut w = std::mem::take(&mut self.work);
        let result = self.rk4_with(h, &mut w);
        self.work = w;
        result
    }

    fn rk4_with(&mut self, h: f64, w: &mut Work) -> Result<(), GridError> {
        let mut x0 = std::mem::take(&mut w.x0);
        let mut v0 = std::mem::take(&mut w.v0);
        let mut xs = std::mem::take(&mut w.xs);
        let mut vs = std::mem::take(&mut w.vs);
        let mut k = std::mem::take(&mut w.k);
        x0.clone_from(&self.x);
        v0.clone_from(&self.v);
        if w.alg.len() != self.machines.len() {
            self.solve_net(&x0, &mut v0, w)?;
        }
        self.deriv(&x0, &v0, &w.alg, &mut k[0]);
        vs.clone_from(&v0);
        let mut stages = || -> Result<(), GridError> {
            for (stage, c) in [(1, 0.5), (2, 0.5), (3, 1.0)] {
                xs.clear();
                xs.extend(x0.iter().zip(&k[stage - 1]).map(|(x, d)| x + c * h * d));
                self.solve_net(&xs, &mut vs, w)?;
                self.deriv(&xs, &vs, &w.alg, &mut k[stage]);
            }
            Ok(())
        };
        let staged = stages();
        let result = staged.and_then(|()| {
            for i in 0..x0.len() {
                self.x[i] = x0[i] + h / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i]);
            }
            if self.x.iter().any(|v| !v.is_finite()) {
                self.x.clone_from(&x0);
                return Err(GridError::NonFinite { t: self.t });
            }
            self.clamp_states();
            // The solution at the new state: the outputs, and the next sub-step's first stage.
            vs.clone_from(&v0);
            self.solve_net(&self.x, &mut vs, w)?;
            std::mem::swap(&mut self.v, &mut vs);
            self.update_angles();
            Ok(())
        });
        (w.x0, w.v0, w.xs, w.vs, w.k) = (x0, v0, xs, vs, k);
        result
    }

    /// Integrate from `t` to `t + h` (FMI doStep semantics). Events fire when their time is
    /// reached; the internal step is at most [`Grid::internal_step`].
    ///
    /// After every internal step the angles are checked against the centre of inertia (see
    /// [`Grid::check_synchronism`]): a unit that lost synchronism ends the step with
    /// [`GridError::LossOfSynchronism`] at the time of that internal step.
    pub fn step(&mut self, t: f64, h: f64) -> Result<(), GridError> {
        if !(h >= 0.0 && h.is_finite() && t.is_finite()) {
            return Err(GridError::InvalidStep { t, h });
        }
        if (t - self.t).abs() > 1e-6 * t.abs().max(1.0) {
            return Err(GridError::TimeMismatch {
                expected: self.t,
                got: t,
            });
        }
        self.t = t;
        self.ensure_lu()?;
        // inputs may have been set deferred
        self.resolve()?;
        let t_end = t + h;
        loop {
            self.fire_due_events()?;
            if self.t >= t_end - EVENT_EPS {
                break;
            }
            let seg_end = t_end.min(self.next_event_time());
            let span = seg_end - self.t;
            let ns = (span / self.h_max - 1e-9).ceil().max(1.0) as usize;
            let hs = span / ns as f64;
            let t0 = self.t;
            for i in 0..ns {
                self.rk4(hs)?;
                self.t = t0 + (i + 1) as f64 * hs;
                self.check_synchronism()?;
            }
            self.t = seg_end;
        }
        self.t = t_end;
        Ok(())
    }

    /// Largest |derivative| over all states at the current point (0 at an equilibrium).
    pub fn max_derivative(&self) -> Result<f64, GridError> {
        let mut w = Work::default();
        let mut v = self.v.clone();
        self.solve_net(&self.x, &mut v, &mut w)?;
        let mut dx = Vec::new();
        self.deriv(&self.x, &v, &w.alg, &mut dx);
        Ok(dx.iter().fold(0.0, |a, d| a.max(d.abs())))
    }
}
