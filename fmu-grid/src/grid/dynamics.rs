//! The grid's dynamics: the network solve at its states, the state derivative, the
//! communication step (internal sub-steps of RK4, events) and the loss-of-synchronism check.
//!
//! Events split the sub-steps so they fire exactly at their time.

use super::{Grid, PocRt};
use crate::der::DerRt;
use crate::error::GridError;
use crate::integration::Dae;
use crate::machine::MachAlg;
use crate::machine::MachineRt;
use crate::network::{Injections, Network, Scratch, Solution};
use crate::numerics::{wrap, C64, EVENT_EPS};

/// The grid's equations at its present inputs, topology and angles: what the integrator steps,
/// borrowed from the grid beside the states it advances (`x`, `sol`) and its work buffers.
struct Equations<'a> {
    machines: &'a [MachineRt],
    ders: &'a [DerRt],
    load_s: &'a [C64],
    net: Option<&'a Network>,
    t: f64,
    wb: f64,
    sb: f64,
    pcc_bus: usize,
    pcc_state: usize,
    pcc_tf: f64,
    pcc_angle: f64,
    pocs: &'a [PocRt],
    poc_angle: &'a [f64],
}

/// The grid split for one solve or integration step: its equations, its states and solution,
/// and the work buffers (mutable from `&mut Grid`, shared from `&Grid`).
macro_rules! split {
    ($grid:expr) => {{
        let Grid {
            machines,
            ders,
            load_s,
            net,
            t,
            wb,
            sb,
            pcc_bus,
            pcc_state,
            pcc_tf,
            pcc_angle,
            pocs,
            poc_angle,
            x,
            sol,
            work,
            ..
        } = $grid;
        let eq = Equations {
            machines,
            ders,
            load_s,
            net: net.as_ref(),
            t: *t,
            wb: *wb,
            sb: *sb,
            pcc_bus: *pcc_bus,
            pcc_state: *pcc_state,
            pcc_tf: *pcc_tf,
            pcc_angle: *pcc_angle,
            pocs,
            poc_angle,
        };
        (eq, x, sol, work)
    }};
}

impl Dae for Equations<'_> {
    type Solution = Solution;
    type Scratch = Scratch;
    type Error = GridError;
    fn solve(&self, x: &[f64], sol: &mut Solution, w: &mut Scratch) -> Result<(), GridError> {
        self.solve_net(x, sol, w)
    }
    fn derivative(&self, x: &[f64], sol: &Solution, dx: &mut Vec<f64>) {
        self.deriv(x, &sol.v, &sol.alg, dx);
    }
    fn clamp(&self, x: &mut [f64]) {
        for m in self.machines {
            m.clamp(x);
        }
    }
    fn non_finite(&self) -> GridError {
        GridError::NonFinite { t: self.t }
    }
}

impl Equations<'_> {
    fn injections(&self) -> Injections<'_> {
        Injections {
            machines: self.machines,
            ders: self.ders,
            load_s: self.load_s,
        }
    }

    /// Whether a voltage source is in service (see [`Grid::energized`]).
    fn energized(&self) -> bool {
        Grid::has_voltage_source(self.machines, self.ders)
    }

    /// Network solution for states `x` (see [`Network::solve`]); a de-energized network
    /// (see [`Grid::energized`]) has every bus voltage 0.
    fn solve_net(&self, x: &[f64], sol: &mut Solution, w: &mut Scratch) -> Result<(), GridError> {
        if !self.energized() {
            // Nothing holds a voltage: current injections alone define no angle (a grid-
            // following unit follows the voltage it measures), so the network is dead.
            sol.v.fill(C64::new(0.0, 0.0));
            return Ok(());
        }
        let net = self.net.ok_or(GridError::SingularNetwork)?;
        net.solve(&self.injections(), x, sol, w, self.t)
    }

    /// Time derivative `dx` of the state vector at `x`, given its network solution (bus
    /// voltages `v`, stator solutions `alg`).
    fn deriv(&self, x: &[f64], v: &[C64], alg: &[MachAlg], dx: &mut Vec<f64>) {
        dx.clear();
        dx.resize(x.len(), 0.0);
        for (m, a) in self.machines.iter().zip(alg) {
            m.deriv(x, a, dvpp_math::cabs(v[m.bus]), self.wb, self.sb, dx);
        }
        // The PCC frequency filter works on the unwrapped angle: its lag behind the angle is
        // Δω T_f, beyond π at deviations above π/(ω_b T_f) (0.1 pu for T_f = 0.1 s).
        let i = self.pcc_state;
        let th = self.pcc_angle + wrap(dvpp_math::carg(v[self.pcc_bus]) - self.pcc_angle);
        dx[i] = (th - x[i]) / self.pcc_tf;
        for (k, p) in self.pocs.iter().enumerate() {
            let th = self.poc_angle[k] + wrap(dvpp_math::carg(v[p.bus]) - self.poc_angle[k]);
            dx[i + 1 + k] = (th - x[i + 1 + k]) / p.tf;
        }
    }
}

impl Grid {
    fn injections(&self) -> Injections<'_> {
        Injections {
            machines: &self.machines,
            ders: &self.ders,
            load_s: &self.load_s,
        }
    }

    pub(super) fn ensure_lu(&mut self) -> Result<(), GridError> {
        if self.net.is_none() {
            self.net = Some(Network::build(
                &self.case,
                &self.branches,
                &self.load_y,
                self.fault_shunt(),
                &self.injections(),
            )?);
        }
        Ok(())
    }

    /// Re-solve the network at the current state (after input or topology changes).
    pub fn resolve(&mut self) -> Result<(), GridError> {
        self.ensure_lu()?;
        // Solve on a copy: a failed solve leaves the voltages as they were.
        let (eq, x, sol, work) = split!(self);
        work.spare.clone_from(sol);
        let solved = eq.solve_net(x, &mut work.spare, &mut work.scratch);
        if solved.is_ok() {
            std::mem::swap(sol, &mut work.spare);
        }
        solved?;
        self.update_angles();
        Ok(())
    }

    fn update_angles(&mut self) {
        for (k, d) in self.ders.iter().enumerate() {
            let a = dvpp_math::carg(self.sol.v[d.bus]);
            self.der_angle[k] += wrap(a - self.der_angle[k]);
        }
        let a = dvpp_math::carg(self.sol.v[self.pcc_bus]);
        self.pcc_angle += wrap(a - self.pcc_angle);
        for (k, p) in self.pocs.iter().enumerate() {
            let a = dvpp_math::carg(self.sol.v[p.bus]);
            self.poc_angle[k] += wrap(a - self.poc_angle[k]);
        }
    }

    /// One RK4 step of length `h` from the current state, whose network solution is
    /// `self.sol` (left there by the last solve: `resolve` at the start of a communication step,
    /// an event, or the previous sub-step's final solve).
    fn rk4(&mut self, h: f64) -> Result<(), GridError> {
        let (eq, x, sol, work) = split!(self);
        if sol.alg.len() != eq.machines.len() {
            let mut s = sol.clone();
            eq.solve_net(x, &mut s, &mut work.scratch)?;
            *sol = s;
        }
        work.rk4.step(&eq, x, sol, &mut work.scratch, h)?;
        self.update_angles();
        Ok(())
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
                self.shed_load()?;
                self.check_frequency()?;
            }
            self.t = seg_end;
        }
        self.t = t_end;
        Ok(())
    }

    /// Largest |derivative| over all states at the current point (0 at an equilibrium).
    pub fn max_derivative(&self) -> Result<f64, GridError> {
        let (eq, x, sol, _) = split!(self);
        let mut w = Scratch::default();
        let mut sol = sol.clone();
        eq.solve_net(x, &mut sol, &mut w)?;
        let mut dx = Vec::new();
        eq.deriv(x, &sol.v, &sol.alg, &mut dx);
        Ok(dx.iter().fold(0.0, |a, d| a.max(d.abs())))
    }
}
