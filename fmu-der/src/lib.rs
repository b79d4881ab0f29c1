//! DER matching controller FMU: a grid-forming DVPP unit that realizes its share of `T_des`.
//!
//! The frequency channel realizes the local reference model `Δf = -T_pf/μ_p Δp` with
//! `T_pf = 1/(H s + D)` on the DVPP base (a static ADPF `m = μ_p`), and imposes the converter's
//! internal angle `θ = θ₀ + ∫ 2π f_nom Δf dt`. The internal voltage `E∠θ` is initialized behind
//! the filter and transformer impedance so that the unit starts at the measured operating point.

use dvpp_control::phasor::internal_voltage;
use fmi_export::{Context, Model, ModelError, Real, Spec, Store, Variables};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The handles of the DER's variables and its controller state.
#[derive(Clone, Serialize, Deserialize)]
pub struct Der {
    s_rated: Real,
    s_base: Real,
    s_dvpp: Real,
    f_nom: Real,
    h: Real,
    d: Real,
    r_f: Real,
    x_f: Real,
    p_avail0: Real,
    p: Real,
    q: Real,
    v: Real,
    v_angle: Real,
    mu_p: Real,
    theta: Real,
    e: Real,
    df: Real,
    p_avail: Real,
    /// Active power at initialization (the operating point Δp is measured from).
    p0: f64,
}

/// The DER has no structural configuration yet; its parameters are FMI parameters.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DerConfig {}

impl Model for Der {
    type Config = DerConfig;
    const IDENTIFIER: &'static str = "dvpp_der";
    const NAME: &'static str = "DVPP DER matching controller";
    const DESCRIPTION: &'static str =
        "Grid-forming DVPP unit: local reference model Δf = -T_pf/μ_p Δp with T_pf = 1/(H s + D)";

    fn declare(
        _: &DerConfig,
        _: Option<&std::path::Path>,
        v: &mut Variables,
    ) -> Result<Self, String> {
        let io = ["p", "q", "v", "v_angle"];
        Ok(Der {
            s_rated: v.real(Spec::parameter("S_rated", 60.0, "MVA", "converter rating").min(1e-3)),
            s_base: v.real(Spec::parameter("S_base", 100.0, "MVA", "system base power").min(1e-3)),
            s_dvpp: v.real(
                Spec::parameter(
                    "S_dvpp",
                    96.0,
                    "MVA",
                    "DVPP base power T_des is specified on",
                )
                .min(1e-3),
            ),
            f_nom: v.real(Spec::parameter("f_nom", 50.0, "Hz", "nominal frequency").min(1e-3)),
            h: v.real(
                Spec::parameter("Tdes.H", 5.55, "s", "virtual inertia of T_pf = 1/(H s + D)")
                    .min(1e-6),
            ),
            d: v.real(
                Spec::parameter(
                    "Tdes.D",
                    33.33,
                    "pu",
                    "damping (droop gain) of T_pf = 1/(H s + D)",
                )
                .min(1e-6),
            ),
            r_f: v.real(
                Spec::parameter(
                    "R_f",
                    0.02,
                    "pu",
                    "filter + transformer resistance on S_rated",
                )
                .min(0.0),
            ),
            x_f: v.real(
                Spec::parameter(
                    "X_f",
                    0.21,
                    "pu",
                    "filter + transformer reactance on S_rated",
                )
                .min(1e-6),
            ),
            p_avail0: v.real(
                Spec::parameter(
                    "P_avail0",
                    0.6,
                    "pu",
                    "available active power of the primary source, on S_base",
                )
                .min(0.0),
            ),
            p: v.real(Spec::input(
                "p",
                0.3,
                "pu",
                "measured active power injected at the terminal, on S_base",
            )),
            q: v.real(Spec::input(
                "q",
                0.0,
                "pu",
                "measured reactive power injected at the terminal, on S_base",
            )),
            v: v.real(
                Spec::input("v", 1.0, "pu", "voltage magnitude at the regulated point").min(1e-3),
            ),
            v_angle: v.real(Spec::input(
                "v_angle",
                0.0,
                "rad",
                "voltage angle at the regulated point, rotating frame at f_nom",
            )),
            mu_p: v.real(
                Spec::input(
                    "mu_p",
                    1.0,
                    "1",
                    "ADPF dc gain of the p-f channel from the operator",
                )
                .range(0.05, 1.0),
            ),
            theta: v.real(
                Spec::output(
                    "theta",
                    "rad",
                    "internal voltage angle the converter imposes",
                )
                .initial_dependencies(&io),
            ),
            e: v.real(
                Spec::output(
                    "E",
                    "pu",
                    "internal voltage magnitude the converter imposes",
                )
                .initial_dependencies(&io),
            ),
            df: v.real(Spec::output(
                "df",
                "pu",
                "the unit's frequency deviation, pu of f_nom",
            )),
            p_avail: v.real(Spec::output(
                "P_avail",
                "pu",
                "available active power of the primary source, on S_base",
            )),
            p0: 0.0,
        })
    }

    fn initialize(&mut self, s: &mut Store, _: &mut Context) -> Result<(), ModelError> {
        // Filter and transformer impedance on the system base.
        let zbase = s[self.s_base] / s[self.s_rated];
        let (r, x) = (s[self.r_f] * zbase, s[self.x_f] * zbase);
        let p = s[self.p];
        let (e, theta) = internal_voltage(p, s[self.q], s[self.v], s[self.v_angle], r, x);
        s[self.theta] = theta;
        s[self.e] = e;
        s[self.df] = 0.0;
        s[self.p_avail] = s[self.p_avail0];
        self.p0 = p;
        Ok(())
    }

    fn do_step(
        &mut self,
        s: &mut Store,
        _t: f64,
        h: f64,
        _: &mut Context,
    ) -> Result<(), ModelError> {
        // H dΔf/dt = -D Δf - Δp/μ, Δp held over the step: solved exactly.
        let dp = (s[self.p] - self.p0) * s[self.s_base] / s[self.s_dvpp];
        let (inertia, damping) = (s[self.h], s[self.d]);
        let a = damping / inertia;
        let steady = -dp / (s[self.mu_p] * damping);
        let df0 = s[self.df];
        let decay = (-a * h).exp();
        s[self.df] = steady + (df0 - steady) * decay;
        s[self.theta] +=
            2.0 * PI * s[self.f_nom] * (steady * h + (df0 - steady) * (1.0 - decay) / a);
        Ok(())
    }
}

fmi_export::export_fmu!(Der);

#[cfg(test)]
mod golden {
    #[test]
    fn model_description_matches_the_golden_copy() {
        fmi_export::assert_golden::<super::Der>(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/modelDescription.xml"
        ));
    }
}
