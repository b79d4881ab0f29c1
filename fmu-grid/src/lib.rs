//! Reduced grid FMU: a single swing-equation bus with a governed machine, a load and DER slots.
//!
//! The bus voltage `V∠δ` rotates with the machine speed ω (`δ' = 2π f_nom (ω - 1)`); the machine
//! obeys `2H ω' = P_m - P_e - D (ω - 1)` with `P_e = P_load - Σ p_k`, and its governor
//! `T_g P_m' = P_m0 - (ω - 1)/R - P_m`. Each grid-forming DER slot injects through its impedance
//! from the internal voltage `E_k∠θ_k` it receives. A load step event perturbs the balance.

use dvpp_control::phasor::{injection, internal_voltage};
use fmi_export::{Context, Model, ModelError, Real, Spec, Store, Variables};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Handles of one grid-forming DER slot.
#[derive(Clone, Serialize, Deserialize)]
struct Slot {
    r: Real,
    x: Real,
    p0: Real,
    q0: Real,
    theta: Real,
    e: Real,
    p: Real,
    q: Real,
    v: Real,
    v_angle: Real,
}

/// Handles of the grid's variables and its dynamic state.
#[derive(Clone, Serialize, Deserialize)]
pub struct Grid {
    f_nom: Real,
    h: Real,
    d: Real,
    droop: Real,
    t_g: Real,
    v_bus: Real,
    p_load: Real,
    event_time: Real,
    event_dp: Real,
    slots: Vec<Slot>,
    pcc_p: Real,
    pcc_q: Real,
    pcc_v: Real,
    pcc_f: Real,
    coi_f: Real,
    sg_omega: Real,
    sg_p: Real,
    /// Bus angle δ (rad), machine speed ω (pu), mechanical power P_m (pu).
    state: [f64; 3],
    p_m0: f64,
}

/// Structure of the grid: how many DER slots it has.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridConfig {
    pub der_slots: usize,
}

impl Default for GridConfig {
    fn default() -> Self {
        GridConfig { der_slots: 3 }
    }
}

/// Internal integration step (s); a communication step is split into equal RK4 sub-steps.
const MAX_SUBSTEP: f64 = 1e-3;

impl Grid {
    /// DER injections for bus angle `delta` with the held internal voltages.
    fn injections(&self, s: &Store, delta: f64) -> Vec<(f64, f64)> {
        self.slots
            .iter()
            .map(|k| injection(s[k.e], s[k.theta], s[self.v_bus], delta, s[k.r], s[k.x]))
            .collect()
    }

    fn derivative(&self, s: &Store, load: f64, x: [f64; 3]) -> [f64; 3] {
        let [delta, omega, p_m] = x;
        let der: f64 = self.injections(s, delta).iter().map(|(p, _)| p).sum();
        let p_e = load - der;
        [
            2.0 * PI * s[self.f_nom] * (omega - 1.0),
            (p_m - p_e - s[self.d] * (omega - 1.0)) / (2.0 * s[self.h]),
            (self.p_m0 - (omega - 1.0) / s[self.droop] - p_m) / s[self.t_g],
        ]
    }

    fn write_outputs(&self, s: &mut Store, powers: &[(f64, f64)], load: f64) {
        let [delta, omega, _] = self.state;
        for (k, &(p, q)) in self.slots.iter().zip(powers) {
            s[k.p] = p;
            s[k.q] = q;
            s[k.v] = s[self.v_bus];
            s[k.v_angle] = delta;
        }
        s[self.pcc_p] = powers.iter().map(|(p, _)| p).sum();
        s[self.pcc_q] = powers.iter().map(|(_, q)| q).sum();
        s[self.pcc_v] = s[self.v_bus];
        s[self.pcc_f] = omega;
        s[self.coi_f] = omega;
        s[self.sg_omega] = omega;
        s[self.sg_p] = load - s[self.pcc_p];
    }
}

impl Model for Grid {
    type Config = GridConfig;
    const IDENTIFIER: &'static str = "dvpp_grid";
    const NAME: &'static str = "DVPP reduced grid";
    const DESCRIPTION: &'static str =
        "Swing-equation bus: governed machine, load with a step event, grid-forming DER slots";

    fn declare(
        config: &GridConfig,
        _: Option<&std::path::Path>,
        v: &mut Variables,
    ) -> Result<Self, String> {
        let n = config.der_slots;
        if !(1..=16).contains(&n) {
            return Err(format!("[model] der_slots = {n} is outside 1..=16"));
        }
        let (p0_default, r_default, x_default, v_default) = (0.3, 0.0333, 0.35, 1.0);
        let (e_start, theta_start) =
            internal_voltage(p0_default, 0.0, v_default, 0.0, r_default, x_default);
        let f_nom = v.real(Spec::parameter("f_nom", 50.0, "Hz", "nominal frequency").min(1e-3));
        let h = v.real(
            Spec::parameter("sg.H", 6.0, "s", "machine inertia constant on S_base").min(1e-3),
        );
        let d = v.real(
            Spec::parameter("sg.D", 1.0, "pu", "machine and load damping on S_base").min(0.0),
        );
        let droop = v.real(Spec::parameter("sg.R", 0.05, "pu", "governor droop").min(1e-4));
        let t_g = v.real(Spec::parameter("sg.T_g", 0.5, "s", "governor time constant").min(1e-4));
        let v_bus =
            v.real(Spec::parameter("bus.V", v_default, "pu", "bus voltage magnitude").min(0.1));
        let p_load =
            v.real(Spec::parameter("load.P", 3.15, "pu", "load active power on S_base").min(0.0));
        let event_time = v.real(Spec::parameter(
            "event.time",
            1.0,
            "s",
            "time of the load step",
        ));
        let event_dp = v.real(Spec::parameter(
            "event.dP",
            0.28,
            "pu",
            "load step on S_base (positive = load increase)",
        ));
        let mut slots = Vec::with_capacity(n);
        for k in 1..=n {
            let name = |s: &str| format!("der[{k}].{s}");
            slots.push(Slot {
                r: v.real(
                    Spec::parameter(
                        &name("R"),
                        r_default,
                        "pu",
                        "slot filter + transformer resistance on S_base",
                    )
                    .min(0.0),
                ),
                x: v.real(
                    Spec::parameter(
                        &name("X"),
                        x_default,
                        "pu",
                        "slot filter + transformer reactance on S_base",
                    )
                    .min(1e-6),
                ),
                p0: v.real(Spec::parameter(
                    &name("p0"),
                    p0_default,
                    "pu",
                    "initial active dispatch of the slot on S_base",
                )),
                q0: v.real(Spec::parameter(
                    &name("q0"),
                    0.0,
                    "pu",
                    "initial reactive dispatch of the slot on S_base",
                )),
                theta: v.real(Spec::input(
                    &name("theta"),
                    theta_start,
                    "rad",
                    "grid-forming slot: internal voltage angle",
                )),
                e: v.real(
                    Spec::input(
                        &name("E"),
                        e_start,
                        "pu",
                        "grid-forming slot: internal voltage magnitude",
                    )
                    .min(0.0),
                ),
                p: v.real(Spec::output(
                    &name("p"),
                    "pu",
                    "active power the slot injects, on S_base",
                )),
                q: v.real(Spec::output(
                    &name("q"),
                    "pu",
                    "reactive power the slot injects, on S_base",
                )),
                v: v.real(Spec::output(
                    &name("v"),
                    "pu",
                    "voltage magnitude at the slot's regulated bus",
                )),
                v_angle: v.real(Spec::output(
                    &name("v_angle"),
                    "rad",
                    "voltage angle at the slot's regulated bus",
                )),
            });
        }
        Ok(Grid {
            f_nom,
            h,
            d,
            droop,
            t_g,
            v_bus,
            p_load,
            event_time,
            event_dp,
            slots,
            pcc_p: v.real(Spec::output(
                "pcc.p",
                "pu",
                "DVPP active power at the PCC, on S_base",
            )),
            pcc_q: v.real(Spec::output(
                "pcc.q",
                "pu",
                "DVPP reactive power at the PCC, on S_base",
            )),
            pcc_v: v.real(Spec::output("pcc.v", "pu", "PCC voltage magnitude")),
            pcc_f: v.real(Spec::output("pcc.f", "pu", "PCC frequency, pu of f_nom")),
            coi_f: v.real(Spec::output(
                "coi.f",
                "pu",
                "centre-of-inertia frequency, pu of f_nom",
            )),
            sg_omega: v.real(Spec::output("sg[1].omega", "pu", "machine speed")),
            sg_p: v.real(Spec::output(
                "sg[1].p",
                "pu",
                "machine electrical power on S_base",
            )),
            state: [0.0, 1.0, 0.0],
            p_m0: 0.0,
        })
    }

    fn initialize(&mut self, s: &mut Store, _: &mut Context) -> Result<(), ModelError> {
        let dispatch: Vec<(f64, f64)> = self.slots.iter().map(|k| (s[k.p0], s[k.q0])).collect();
        let der: f64 = dispatch.iter().map(|(p, _)| p).sum();
        self.p_m0 = s[self.p_load] - der;
        self.state = [0.0, 1.0, self.p_m0];
        let load = s[self.p_load];
        self.write_outputs(s, &dispatch, load);
        Ok(())
    }

    fn do_step(
        &mut self,
        s: &mut Store,
        t: f64,
        h: f64,
        _: &mut Context,
    ) -> Result<(), ModelError> {
        let n = (h / MAX_SUBSTEP).ceil().max(1.0) as usize;
        let dt = h / n as f64;
        let load_at = |tau: f64| {
            s[self.p_load]
                + if tau >= s[self.event_time] {
                    s[self.event_dp]
                } else {
                    0.0
                }
        };
        for i in 0..n {
            let load = load_at(t + i as f64 * dt);
            let x = self.state;
            let add = |a: [f64; 3], b: [f64; 3], c: f64| {
                [a[0] + c * b[0], a[1] + c * b[1], a[2] + c * b[2]]
            };
            let k1 = self.derivative(s, load, x);
            let k2 = self.derivative(s, load, add(x, k1, dt / 2.0));
            let k3 = self.derivative(s, load, add(x, k2, dt / 2.0));
            let k4 = self.derivative(s, load, add(x, k3, dt));
            self.state = std::array::from_fn(|j| {
                x[j] + dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
            });
        }
        let powers = self.injections(s, self.state[0]);
        self.write_outputs(s, &powers, load_at(t + h));
        Ok(())
    }
}

fmi_export::export_fmu!(Grid);

#[cfg(test)]
mod golden {
    #[test]
    fn model_description_matches_the_golden_copy() {
        fmi_export::assert_golden::<super::Grid>(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/modelDescription.xml"
        ));
    }
}
