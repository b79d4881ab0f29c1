//! The FMU's variables: the declaration of every parameter, input and output, with its start value.

use crate::adpf::AdpfVars;
use crate::unit_vars::{par, tun, DcVars, GainVars, PllVars, QPiVars, SourceVars, UnitVars};
use crate::{ports, Der, DerConfig, Priority, UnitDefaults};
use dvpp_controllers::phasor::{
    DcRange, OutputStage, PhasorMeasurement, SlotImpedance, StartupParams,
};
use fmi_export::{Boolean, ModelError, Real, Spec, Store, Variables};
use serde::{Deserialize, Serialize};

/// The inputs every command output depends on at initialization.
const IO: [&str; 4] = [ports::P, ports::Q, ports::V, ports::V_ANGLE];

impl Der {
    /// The DER's variables for `config` (its preset's start values).
    pub(crate) fn declare_variables(config: &DerConfig, v: &mut Variables) -> Result<Der, String> {
        let u = UnitDefaults::of(config.preset).resized(config.rating)?;
        let unit = UnitVars::declare(v, &u);
        let slot = SlotVars::declare(v);
        let adpf_p = AdpfVars::declare(v, "p", &u.adpf_p, true);
        let adpf_q = AdpfVars::declare(v, "q", &u.adpf_q, false);
        let pll = PllVars::declare(v);
        let qpi = QPiVars::declare_phasor(v);
        let dc = DcVars::declare(v, &u);
        let dc_range = DcRangeVars::declare(v);
        let stage = StageVars::declare(v);
        let startup = StartupVars::declare(v);
        let source = SourceVars::declare(v, &u);
        let redispatch = v.real(
            Spec::parameter(
                "dispatch.dP",
                0.0,
                "pu",
                "change of the dispatch on S_base (the dispatch is the power-flow point at initialization; a host redispatches the unit with this)",
            )
            .tunable(),
        );
        let measured = MeasuredVars::declare(v, &u);
        let gains = GainVars::declare(v, &u);
        let out = Outputs::declare(v);
        let link = LinkOutputs::declare(v);
        let energy = EnergyOutputs::declare(v);
        let flags = LimitFlags::declare(v);
        // Declared last, so the variables above keep their value references.
        let rot = RotationVars::declare(v);
        Ok(Der {
            unit,
            slot,
            adpf_p,
            adpf_q,
            pll,
            qpi,
            dc,
            dc_range,
            stage,
            startup,
            source,
            redispatch,
            measured,
            gains,
            out,
            link,
            energy,
            flags,
            rot,
        })
    }
}

/// A command output that depends on the measured bus quantities at initialization.
fn output(v: &mut Variables, name: &str, unit: &str, desc: &str) -> Real {
    v.real(Spec::output(name, unit, desc).initial_dependencies(&IO))
}

/// Grid-forming: the impedance between the imposed voltage and the terminal bus (`R_f`, `X_f`).
#[derive(Clone, Copy, Serialize, Deserialize)]
pub(crate) struct SlotVars {
    pub(crate) r_f: Real,
    pub(crate) x_f: Real,
}

impl SlotVars {
    fn declare(v: &mut Variables) -> Self {
        let r_f = par(
            v,
            ports::R_F,
            0.01,
            "pu",
            "grid-forming: resistance between the imposed voltage (the regulated filter-capacitor voltage) and the terminal bus, the LV/MV transformer, on S_rated",
            0.0,
        );
        let x_f = par(
            v,
            ports::X_F,
            0.10,
            "pu",
            "grid-forming: reactance between the imposed voltage and the terminal bus, the LV/MV transformer, on S_rated",
            1e-6,
        );
        SlotVars { r_f, x_f }
    }

    pub(crate) fn read(&self, s: &Store) -> SlotImpedance {
        SlotImpedance {
            r_f: s[self.r_f],
            x_f: s[self.x_f],
        }
    }
}

/// The range the ac side may move the dc link in (`v_dc_min`, `v_dc_max`) and its energy budget
/// time `dc.t_budget`.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub(crate) struct DcRangeVars {
    pub(crate) v_min: Real,
    pub(crate) v_max: Real,
    pub(crate) t_budget: Real,
}

impl DcRangeVars {
    fn declare(v: &mut Variables) -> Self {
        let v_min = v.real(
            Spec::parameter(
                "v_dc_min",
                0.8,
                "pu",
                "lowest dc-link voltage the ac side may draw the link down to (below it the ac power is held to what the source gives)",
            )
            .range(0.0, 1.0),
        );
        let v_max = v.real(
            Spec::parameter(
                "v_dc_max",
                1.2,
                "pu",
                "highest dc-link voltage the ac side may charge the link to",
            )
            .min(1.0),
        );
        let t_budget = par(
            v,
            "dc.t_budget",
            0.02,
            "s",
            "the ac side may draw the link's usable energy (above v_dc_min) at most at the rate usable energy / t_budget beyond the source's power",
            0.0,
        );
        DcRangeVars {
            v_min,
            v_max,
            t_budget,
        }
    }

    pub(crate) fn read(&self, s: &Store) -> DcRange {
        DcRange {
            v_min: s[self.v_min],
            v_max: s[self.v_max],
            t_budget: s[self.t_budget],
        }
    }
}

/// The output stage (`I_max`, `delay.c`, `limit.priority`, `current.tau`, `vq.tau`) and, declared
/// among them, the grid-forming virtual resistance `vi.r`.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub(crate) struct StageVars {
    pub(crate) i_max: Real,
    pub(crate) delay_c: Real,
    pub(crate) vi_r: Real,
    pub(crate) priority: fmi_export::Integer,
    pub(crate) current_tau: Real,
    pub(crate) vq_tau: Real,
}

impl StageVars {
    fn declare(v: &mut Variables) -> Self {
        let i_max = tun(
            v,
            "I_max",
            1.2,
            "pu",
            "current limit, pu of the rated current (S_rated at 1 pu voltage)",
            1e-3,
        );
        let delay_c = v.real(
            Spec::parameter(
                "delay.c",
                dvpp_controllers::phasor::DELAY_COMPENSATION,
                "1",
                "grid-forming: share of the change its own last angle move makes in its (limited) power that the controls add to the measured power, which shows the angle sent one communication step earlier (docs/control.md §7); 0 = off, for a host that answers the angle within the step",
            )
            .range(0.0, 1.0)
            .tunable(),
        );
        let vi_r = v.real(
            Spec::parameter(
                "vi.r",
                0.0,
                "pu",
                "grid-forming: virtual resistance on S_rated between the internal voltage the controls set and the converter's output, lossless (as the EMT controller's vi.r); the output E∠θ is the divider between them at the measured bus voltage",
            )
            .min(0.0),
        );
        let priority = v.integer(
            Spec::parameter(
                "limit.priority",
                Priority::Active.code(),
                "",
                "at I_max: grid-following 0 active current kept first, 1 reactive current kept first; grid-forming 0 the current keeps its direction, 1 a request beyond I_max turns to the direction of a virtual impedance X/R = 5 on the voltage across the internal node (reactive current in dips)",
            )
            .range(0.0, 1.0)
            .tunable(),
        );
        let (current_tau, vq_tau) = Self::lags(v);
        StageVars {
            i_max,
            delay_c,
            vi_r,
            priority,
            current_tau,
            vq_tau,
        }
    }

    /// Grid-following: `current.tau` and `vq.tau`.
    fn lags(v: &mut Variables) -> (Real, Real) {
        let current_tau = tun(
            v,
            "current.tau",
            0.02,
            "s",
            "grid-following: time constant of the converter's current response to its references (inner current control and plant, as the WECC REGC_A model's Tg); 0 = immediate",
            0.0,
        );
        let vq_tau = tun(
            v,
            "vq.tau",
            0.5,
            "s",
            "grid-following: time constant of the plant's voltage control ahead of the v-q droop (a current-injecting unit's droop 1/Dq through the grid's impedance needs a dominant lag); 0 = none",
            0.0,
        );
        (current_tau, vq_tau)
    }

    /// The output stage; an unknown `limit.priority` is refused by name.
    pub(crate) fn read(&self, s: &Store) -> Result<OutputStage, ModelError> {
        Ok(OutputStage {
            i_max: s[self.i_max],
            priority: Priority::from_code(s[self.priority])?,
            delay_c: s[self.delay_c],
            current_tau: s[self.current_tau],
            vq_tau: s[self.vq_tau],
        })
    }
}

/// The start from zero voltage: `startup.v_sync`, `startup.t_hold`, `startup.ramp`.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub(crate) struct StartupVars {
    pub(crate) v_sync: Real,
    pub(crate) t_hold: Real,
    pub(crate) ramp: Real,
}

impl StartupVars {
    fn declare(v: &mut Variables) -> Self {
        let v_sync = v.real(
            Spec::parameter(
                "startup.v_sync",
                0.5,
                "pu",
                "a unit initialized below this terminal voltage waits (zero current) until the voltage is above it and steady, then synchronizes",
            )
            .range(0.0, 1.0),
        );
        let t_hold = par(
            v,
            "startup.t_hold",
            0.05,
            "s",
            "how long the voltage must be above startup.v_sync and steady (|dv/dt| < 0.5 pu/s) before the unit synchronizes",
            0.0,
        );
        let ramp = par(
            v,
            "startup.ramp",
            1.0,
            "s",
            "after a start from zero voltage, the set point ramps from 0 to the dispatch over this time",
            0.0,
        );
        StartupVars {
            v_sync,
            t_hold,
            ramp,
        }
    }

    pub(crate) fn read(&self, s: &Store) -> StartupParams {
        StartupParams {
            v_sync: s[self.v_sync],
            t_hold: s[self.t_hold],
            ramp: s[self.ramp],
        }
    }
}

/// The measured bus quantities (inputs): `p`, `q`, `v`, `v_angle`.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub(crate) struct MeasuredVars {
    pub(crate) p: Real,
    pub(crate) q: Real,
    pub(crate) v: Real,
    pub(crate) v_angle: Real,
}

impl MeasuredVars {
    fn declare(v: &mut Variables, u: &UnitDefaults) -> Self {
        let p = v.real(Spec::input(
            ports::P,
            u.p,
            "pu",
            "measured active power injected at the terminal, on S_base",
        ));
        let q = v.real(Spec::input(
            ports::Q,
            0.0,
            "pu",
            "measured reactive power injected at the terminal, on S_base",
        ));
        let vv = v.real(
            Spec::input(
                ports::V,
                1.0,
                "pu",
                "voltage magnitude at the regulated point",
            )
            .min(0.0),
        );
        let v_angle = v.real(Spec::input(
            ports::V_ANGLE,
            0.0,
            "rad",
            "voltage angle at the regulated point, rotating frame at f_nom",
        ));
        MeasuredVars {
            p,
            q,
            v: vv,
            v_angle,
        }
    }

    /// The measurement at time `t`.
    pub(crate) fn read(&self, s: &Store, t: f64) -> PhasorMeasurement {
        PhasorMeasurement {
            t,
            p: s[self.p],
            q: s[self.q],
            v: s[self.v],
            v_angle: s[self.v_angle],
        }
    }
}

/// The command's angle, magnitude, frequency and set points.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub(crate) struct Outputs {
    pub(crate) theta: Real,
    pub(crate) e: Real,
    pub(crate) df: Real,
    pub(crate) p_ref: Real,
    pub(crate) p_set: Real,
    pub(crate) q_ref: Real,
    pub(crate) p_avail: Real,
}

impl Outputs {
    fn declare(v: &mut Variables) -> Self {
        let theta = output(
            v,
            ports::THETA,
            "rad",
            "grid-forming: internal voltage angle the converter imposes; grid-following: PLL angle",
        );
        let e = output(
            v,
            ports::E,
            "pu",
            "grid-forming: internal voltage magnitude the converter imposes (held in grid-following)",
        );
        let df = v.real(Spec::output(
            "df",
            "pu",
            "the unit's frequency deviation, pu of f_nom (grid-forming: imposed; grid-following: PLL)",
        ));
        let p_ref = output(
            v,
            ports::P_REF,
            "pu",
            "grid-following: active power reference on S_base; grid-forming: the active set point (dispatch curtailed to P_avail)",
        );
        let p_set = output(
            v,
            ports::P_SET,
            "pu",
            "the unit's active set point on S_base: the dispatch, curtailed to what the primary source allows (deload * P_avail - G_dc); the operator measures the DVPP's response against the sum of these",
        );
        let q_ref = output(
            v,
            ports::Q_REF,
            "pu",
            "reactive power reference q_0 - T_i^vq dv on S_base (grid-forming: tracked by E)",
        );
        let p_avail = v.real(Spec::output(
            ports::P_AVAIL,
            "pu",
            "available active power of the primary source, on S_base",
        ));
        Outputs {
            theta,
            e,
            df,
            p_ref,
            p_set,
            q_ref,
            p_avail,
        }
    }
}

/// The dc link's and the ac current's outputs, and the grid slot's limits.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub(crate) struct LinkOutputs {
    pub(crate) v_dc: Real,
    pub(crate) p_dc: Real,
    pub(crate) i_ac: Real,
    pub(crate) i_limit: Real,
    pub(crate) p_min: Real,
    pub(crate) p_max: Real,
}

impl LinkOutputs {
    fn declare(v: &mut Variables) -> Self {
        let v_dc = v.real(Spec::output(ports::V_DC, "pu", "dc-link voltage"));
        let p_dc = output(v, "p_dc", "pu", "power of the dc source, on S_base");
        let i_ac = output(
            v,
            ports::I_AC,
            "pu",
            "magnitude of the ac current at the terminal, pu of the rated current",
        );
        let i_limit = v.real(Spec::output(
            ports::I_LIMIT,
            "pu",
            "the current limit I_max, for the grid's slot (the output stage holds it in every network solution)",
        ));
        let p_min = v.real(Spec::output(
            ports::P_MIN,
            "pu",
            "grid-forming: lowest active power at the terminal the dc link can take now, on S_base (for the grid's slot)",
        ));
        let p_max = v.real(Spec::output(
            ports::P_MAX,
            "pu",
            "grid-forming: highest active power at the terminal the dc link can give now, on S_base (for the grid's slot)",
        ));
        LinkOutputs {
            v_dc,
            p_dc,
            i_ac,
            i_limit,
            p_min,
            p_max,
        }
    }
}

/// The energy balance since initialization: source, ac side, loss, stored.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub(crate) struct EnergyOutputs {
    pub(crate) source: Real,
    pub(crate) ac: Real,
    pub(crate) loss: Real,
    pub(crate) stored: Real,
}

impl EnergyOutputs {
    fn declare(v: &mut Variables) -> Self {
        let source = v.real(Spec::output(
            ports::ENERGY_SOURCE,
            "MJ",
            "energy the primary source delivered since initialization",
        ));
        let ac = v.real(Spec::output(
            ports::ENERGY_AC,
            "MJ",
            "energy the ac side drew from the dc link since initialization (terminal power and, grid-forming, the R_f loss)",
        ));
        let loss = v.real(Spec::output(
            ports::ENERGY_LOSS,
            "MJ",
            "energy lost in the dc link (G_dc) since initialization",
        ));
        let stored = v.real(Spec::output(
            ports::ENERGY_STORED,
            "MJ",
            "energy stored in the dc link, C_dc v_dc^2 / 2 (source - ac - loss = change of this)",
        ));
        EnergyOutputs {
            source,
            ac,
            loss,
            stored,
        }
    }
}

/// The limit flags and `synchronized` (boolean outputs).
#[derive(Clone, Copy, Serialize, Deserialize)]
pub(crate) struct LimitFlags {
    pub(crate) current: Boolean,
    pub(crate) dc: Boolean,
    pub(crate) source: Boolean,
    pub(crate) modulation: Boolean,
    pub(crate) synchronized: Boolean,
}

impl LimitFlags {
    fn declare(v: &mut Variables) -> Self {
        let mut flag = |name: &str, desc: &str| v.boolean(Spec::boolean_output(name, desc));
        let current = flag(
            "limit.current",
            "the current limit I_max acts (on until 1 s after it last acted; the same for the other limit flags)",
        );
        let dc = flag(
            "limit.dc",
            "the dc link's power budget limits the active current (link near v_dc_min or v_dc_max)",
        );
        let source = flag(
            "limit.source",
            "the primary source sits at its availability (or its floor)",
        );
        let modulation = flag(
            "limit.modulation",
            "grid-forming: the imposed voltage is cut to E_max * v_dc",
        );
        let synchronized = flag(
            ports::SYNCHRONIZED,
            "the unit is synchronized (false while it waits for the terminal voltage after a start from zero voltage, and for a grid-following unit that lost its terminal voltage)",
        );
        LimitFlags {
            current,
            dc,
            source,
            modulation,
            synchronized,
        }
    }
}

/// Rotational power control: `rot.rx` and the rotated powers `p_rot`, `q_rot`.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub(crate) struct RotationVars {
    pub(crate) rx: Real,
    pub(crate) p_rot: Real,
    pub(crate) q_rot: Real,
}

impl RotationVars {
    fn declare(v: &mut Variables) -> Self {
        let rx = v.real(
            Spec::parameter(
                ports::ROT_RX,
                0.0,
                "1",
                "rotational power control: R/X of the lines around the unit; the p-f channel shapes p' = (p - rx q)/sqrt(1 + rx^2) and the v-q channel controls q' = (rx p + q)/sqrt(1 + rx^2) instead of p and q (0 = classical p-f and q-v control)",
            )
            .min(0.0),
        );
        let p_rot = v.real(
            Spec::output(
                ports::P_ROT,
                "pu",
                "measured rotated active power p' = (p - rx q)/sqrt(1 + rx^2) on S_base (rx = rot.rx; p when 0)",
            )
            .initial_dependencies(&[ports::P, ports::Q]),
        );
        let q_rot = v.real(
            Spec::output(
                ports::Q_ROT,
                "pu",
                "measured rotated reactive power q' = (rx p + q)/sqrt(1 + rx^2) on S_base (rx = rot.rx; q when 0)",
            )
            .initial_dependencies(&[ports::P, ports::Q]),
        );
        RotationVars { rx, p_rot, q_rot }
    }
}
