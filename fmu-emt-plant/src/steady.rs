//! The circuit's sinusoidal steady state (phasors at `ω_b`) the plant starts from: the PCC
//! voltage by Newton's method with a slack source (the Thevenin source, or unit 1's capacitor
//! voltage in an island), then every branch from it.
//!
//! Phasors are peak values, `x_a(t) = Re(X e^{jω_b t})`; the αβ space vector is `X e^{jω_b t}`.

use crate::network::{Network, Topology};
use nalgebra::Complex;

/// A complex number.
pub type C = Complex<f64>;

/// One unit's steady state, pu on its rating.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnitPhasors {
    /// Converter voltage `v_conv = v_c + (R_f + jX_f) i_f`.
    pub v_conv: C,
    pub i_f: C,
    pub v_c: C,
    pub i_g: C,
}

impl UnitPhasors {
    /// Active power the converter delivers to the filter, pu on its rating.
    pub fn p_conv(&self) -> f64 {
        (self.v_conv * self.i_f.conj()).re
    }
}

/// The whole circuit's steady state.
#[derive(Debug, Clone, PartialEq)]
pub struct SteadyState {
    pub units: Vec<UnitPhasors>,
    /// PCC voltage, pu on the MV base.
    pub v_pcc: C,
    /// Load currents (zero for a load not connected at the start), pu on `S_base`.
    pub loads: Vec<C>,
    /// Thevenin current into the PCC, pu on `S_base`.
    pub i_th: C,
}

/// What fixes the operating point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Slack {
    /// The Thevenin source's phasor.
    Thevenin(C),
    /// Unit 1's capacitor-voltage phasor (an island).
    Unit(C),
}

/// The steady state with every unit but a slack unit injecting `s0[k]` (pu on `S_base`) into
/// the PCC.
pub fn solve(
    net: &Network,
    topo: &Topology,
    slack: Slack,
    s0: &[C],
) -> Result<SteadyState, String> {
    let j = C::new(0.0, 1.0);
    let z = |r: f64, x: f64| C::new(r, x);
    // The slack as a source behind an impedance (system pu).
    let (e, zs, slack_unit) = match slack {
        Slack::Thevenin(e) => {
            let th = net
                .thevenin
                .filter(|_| topo.thevenin)
                .ok_or("the Thevenin source is not connected")?;
            (e, z(th.r, th.l), None)
        }
        Slack::Unit(v) => {
            let u = net.units[0];
            (v, z(u.r_t, u.l_t) / net.c(0), Some(0))
        }
    };
    let y_load: C = net
        .loads
        .iter()
        .enumerate()
        .filter(|(k, _)| topo.load(*k))
        .map(|(_, l)| C::new(1.0, 0.0) / z(l.r, l.l))
        .sum();
    let injected = |v: C| -> C {
        s0.iter()
            .enumerate()
            .filter(|(k, _)| Some(*k) != slack_unit)
            .map(|(_, s)| (s / v).conj())
            .sum()
    };
    let mismatch = |v: C| (e - v) / zs + injected(v) - v * y_load;
    let mut v = e;
    // A dead slack with nothing injected: everything at rest.
    let at_rest = dvpp_math::cabs(e) == 0.0
        && s0
            .iter()
            .enumerate()
            .all(|(k, s)| Some(k) == slack_unit || dvpp_math::cabs(*s) == 0.0);
    let mut converged = at_rest;
    for _ in 0..if at_rest { 0 } else { 60 } {
        let f = mismatch(v);
        if dvpp_math::cabs(f) < 1e-14 {
            converged = true;
            break;
        }
        // Newton on (Re v, Im v) with a difference Jacobian.
        let d = 1e-7;
        let fx = (mismatch(v + d) - f) / d;
        let fy = (mismatch(v + j * d) - f) / d;
        let det = fx.re * fy.im - fy.re * fx.im;
        if det.abs() < 1e-300 || !det.is_finite() {
            break;
        }
        let dx = (f.re * fy.im - fy.re * f.im) / det;
        let dy = (fx.re * f.im - f.re * fx.im) / det;
        v -= C::new(dx, dy);
    }
    if !converged || !dvpp_math::cabs(v).is_finite() || (!at_rest && dvpp_math::cabs(v) < 1e-3) {
        return Err(format!(
            "no steady state: the PCC voltage does not converge (last {:.4} pu); the start powers der[k].p0, der[k].q0 exceed what the network can carry",
            dvpp_math::cabs(v)
        ));
    }
    let units = net
        .units
        .iter()
        .enumerate()
        .map(|(k, u)| {
            let i_g_sys = if Some(k) == slack_unit {
                (e - v) / zs
            } else if at_rest {
                C::new(0.0, 0.0)
            } else {
                (s0[k] / v).conj()
            };
            let i_g = i_g_sys / net.c(k);
            let v_c = v + z(u.r_t, u.l_t) * i_g;
            let i_f = i_g + j * u.c_f * v_c;
            let v_conv = v_c + z(u.r_f, u.l_f) * i_f;
            UnitPhasors {
                v_conv,
                i_f,
                v_c,
                i_g,
            }
        })
        .collect();
    let loads = net
        .loads
        .iter()
        .enumerate()
        .map(|(k, l)| {
            if topo.load(k) {
                v / z(l.r, l.l)
            } else {
                C::new(0.0, 0.0)
            }
        })
        .collect();
    let i_th = match slack {
        Slack::Thevenin(_) => (e - v) / zs,
        Slack::Unit(_) => C::new(0.0, 0.0),
    };
    Ok(SteadyState {
        units,
        v_pcc: v,
        loads,
        i_th,
    })
}
