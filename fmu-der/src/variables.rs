//! The FMU's variables: the declaration of every parameter, input and output, with its start value.

use crate::adpf::AdpfVars;
use crate::unit_vars::{par, tun, DcVars, GainVars, PllVars, SourceVars, UnitVars};
use crate::{ports, Der, DerConfig, Priority, UnitDefaults};
use fmi_export::{Spec, Variables};

impl Der {
    /// The DER's variables for `config` (its preset's start values).
    pub(crate) fn declare_variables(config: &DerConfig, v: &mut Variables) -> Result<Der, String> {
        let u = UnitDefaults::of(config.preset).resized(config.rating)?;
        let io = [ports::P, ports::Q, ports::V, ports::V_ANGLE];
        let unit = UnitVars::declare(v, &u);
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
        let adpf_p = AdpfVars::declare(v, "p", &u.adpf_p, true);
        let adpf_q = AdpfVars::declare(v, "q", &u.adpf_q, false);
        let pll = PllVars::declare(v);
        let qpi_kp = tun(
            v,
            "qpi.kp",
            0.05,
            "pu",
            "grid-forming PI matching controller: proportional gain from q error to E",
            0.0,
        );
        let e_max = v.real(
            Spec::parameter(
                "E_max",
                1.5,
                "pu",
                "grid-forming: modulation limit, the largest voltage magnitude the converter can impose at the nominal dc voltage (E <= E_max * v_dc)",
            )
            .min(0.0)
            .tunable(),
        );
        let qpi_ki = tun(
            v,
            "qpi.ki",
            5.0,
            "1/s",
            "grid-forming PI matching controller: integral gain from q error to E",
            0.0,
        );
        let dc = DcVars::declare(v, &u);
        let v_dc_min = v.real(
            Spec::parameter(
                "v_dc_min",
                0.8,
                "pu",
                "lowest dc-link voltage the ac side may draw the link down to (below it the ac power is held to what the source gives)",
            )
            .range(0.0, 1.0),
        );
        let v_dc_max = v.real(
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
                "grid-following at I_max: 0 active current kept first, 1 reactive current kept first",
            )
            .range(0.0, 1.0)
            .tunable(),
        );
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
        let gains = GainVars::declare(v, &u);
        let out = |v: &mut Variables, name: &str, unit: &str, desc: &str| {
            v.real(Spec::output(name, unit, desc).initial_dependencies(&io))
        };
        Ok(Der {
            unit,
            r_f,
            x_f,
            adpf_p,
            adpf_q,
            pll,
            qpi_kp,
            qpi_ki,
            e_max,
            dc,
            v_dc_min,
            v_dc_max,
            t_budget,
            i_max,
            delay_c,
            vi_r,
            priority,
            current_tau,
            vq_tau,
            v_sync,
            t_hold,
            ramp,
            source,
            redispatch,
            p,
            q,
            v: vv,
            v_angle,
            gains,
            theta: out(
                v,
                ports::THETA,
                "rad",
                "grid-forming: internal voltage angle the converter imposes; grid-following: PLL angle",
            ),
            e: out(
                v,
                ports::E,
                "pu",
                "grid-forming: internal voltage magnitude the converter imposes (held in grid-following)",
            ),
            df: v.real(Spec::output(
                "df",
                "pu",
                "the unit's frequency deviation, pu of f_nom (grid-forming: imposed; grid-following: PLL)",
            )),
            p_ref: out(
                v,
                ports::P_REF,
                "pu",
                "grid-following: active power reference on S_base; grid-forming: the active set point (dispatch curtailed to P_avail)",
            ),
            p_set: out(
                v,
                ports::P_SET,
                "pu",
                "the unit's active set point on S_base: the dispatch, curtailed to what the primary source allows (deload * P_avail - G_dc); the operator measures the DVPP's response against the sum of these",
            ),
            q_ref: out(
                v,
                ports::Q_REF,
                "pu",
                "reactive power reference q_0 - T_i^vq dv on S_base (grid-forming: tracked by E)",
            ),
            p_avail: v.real(Spec::output(
                ports::P_AVAIL,
                "pu",
                "available active power of the primary source, on S_base",
            )),
            v_dc: v.real(Spec::output(ports::V_DC, "pu", "dc-link voltage")),
            p_dc: out(v, "p_dc", "pu", "power of the dc source, on S_base"),
            i_ac: out(
                v,
                ports::I_AC,
                "pu",
                "magnitude of the ac current at the terminal, pu of the rated current",
            ),
            i_limit: v.real(Spec::output(
                ports::I_LIMIT,
                "pu",
                "the current limit I_max, for the grid's slot (the output stage holds it in every network solution)",
            )),
            p_min: v.real(Spec::output(
                ports::P_MIN,
                "pu",
                "grid-forming: lowest active power at the terminal the dc link can take now, on S_base (for the grid's slot)",
            )),
            p_max: v.real(Spec::output(
                ports::P_MAX,
                "pu",
                "grid-forming: highest active power at the terminal the dc link can give now, on S_base (for the grid's slot)",
            )),
            e_src: v.real(Spec::output(
                ports::ENERGY_SOURCE,
                "MJ",
                "energy the primary source delivered since initialization",
            )),
            e_ac: v.real(Spec::output(
                ports::ENERGY_AC,
                "MJ",
                "energy the ac side drew from the dc link since initialization (terminal power and, grid-forming, the R_f loss)",
            )),
            e_loss: v.real(Spec::output(
                ports::ENERGY_LOSS,
                "MJ",
                "energy lost in the dc link (G_dc) since initialization",
            )),
            w_dc: v.real(Spec::output(
                ports::ENERGY_STORED,
                "MJ",
                "energy stored in the dc link, C_dc v_dc^2 / 2 (source - ac - loss = change of this)",
            )),
            limit_current: v.boolean(Spec::boolean_output(
                "limit.current",
                "the current limit I_max acts (on until 1 s after it last acted; the same for the other limit flags)",
            )),
            limit_dc: v.boolean(Spec::boolean_output(
                "limit.dc",
                "the dc link's power budget limits the active current (link near v_dc_min or v_dc_max)",
            )),
            limit_source: v.boolean(Spec::boolean_output(
                "limit.source",
                "the primary source sits at its availability (or its floor)",
            )),
            limit_modulation: v.boolean(Spec::boolean_output(
                "limit.modulation",
                "grid-forming: the imposed voltage is cut to E_max * v_dc",
            )),
            synchronized: v.boolean(Spec::boolean_output(
                ports::SYNCHRONIZED,
                "the unit is synchronized (false while it waits for the terminal voltage after a start from zero voltage, and for a grid-following unit that lost its terminal voltage)",
            )),
            // Declared last, so the variables above keep their value references.
            rot_rx: v.real(
                Spec::parameter(
                    ports::ROT_RX,
                    0.0,
                    "1",
                    "rotational power control: R/X of the lines around the unit; the p-f channel shapes p' = (p - rx q)/sqrt(1 + rx^2) and the v-q channel controls q' = (rx p + q)/sqrt(1 + rx^2) instead of p and q (0 = classical p-f and q-v control)",
                )
                .min(0.0),
            ),
            p_rot: v.real(
                Spec::output(
                    ports::P_ROT,
                    "pu",
                    "measured rotated active power p' = (p - rx q)/sqrt(1 + rx^2) on S_base (rx = rot.rx; p when 0)",
                )
                .initial_dependencies(&[ports::P, ports::Q]),
            ),
            q_rot: v.real(
                Spec::output(
                    ports::Q_ROT,
                    "pu",
                    "measured rotated reactive power q' = (rx p + q)/sqrt(1 + rx^2) on S_base (rx = rot.rx; q when 0)",
                )
                .initial_dependencies(&[ports::P, ports::Q]),
            ),
        })
    }
}
