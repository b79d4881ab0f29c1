//! The FMU's variables: the declaration of every parameter, input and output, with its start value.

use crate::adpf::AdpfParams;
use crate::{limits, ports, Der, DerConfig, UnitDefaults, MAX_LPF};
use fmi_export::{Spec, Variables};

impl Der {
    /// The DER's variables for `config` (its preset's start values).
    pub(crate) fn declare_variables(config: &DerConfig, v: &mut Variables) -> Result<Der, String> {
        let u = UnitDefaults::of(config.preset).resized(config.rating)?;
        let io = [ports::P, ports::Q, ports::V, ports::V_ANGLE];
        let par = |v: &mut Variables, name: &str, start: f64, unit: &str, desc: &str, min: f64| {
            v.real(Spec::parameter(name, start, unit, desc).min(min))
        };
        // Gains, limits and set points a host may retune between steps; structure stays fixed.
        let tun = |v: &mut Variables, name: &str, start: f64, unit: &str, desc: &str, min: f64| {
            v.real(Spec::parameter(name, start, unit, desc).min(min).tunable())
        };
        let s_rated = par(
            v,
            ports::S_RATED,
            u.s_rated,
            "MVA",
            "converter rating",
            1e-3,
        );
        let s_base = par(v, "S_base", 100.0, "MVA", "system base power", 1e-3);
        let s_dvpp = par(
            v,
            ports::S_DVPP,
            96.0,
            "MVA",
            "DVPP base power T_des is specified on",
            1e-3,
        );
        let f_nom = par(v, "f_nom", 50.0, "Hz", "nominal frequency", 1e-3);
        let mode = v.integer(
            Spec::parameter(
                ports::MODE,
                u.mode.code(),
                "",
                "1 = grid-forming, 2 = grid-following",
            )
            .range(1.0, 2.0),
        );
        let h = par(
            v,
            ports::TDES_H,
            5.55,
            "s",
            "virtual inertia of T_pf = 1/(H s + D)",
            0.0,
        );
        let d = par(
            v,
            ports::TDES_D,
            33.33,
            "pu",
            "damping (droop gain) of T_pf = 1/(H s + D)",
            0.0,
        );
        let dq = par(
            v,
            ports::TDES_DQ,
            0.01,
            "pu",
            "q-v droop of T_qv = Dq (dv = -Dq dq)",
            0.0,
        );
        let tau_q = par(
            v,
            "Tdes.tau_q",
            0.01,
            "s",
            "roll-off 1/(tau_q s + 1) of the inverse q-v reference",
            0.0,
        );
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
        let adpf_p = AdpfParams::declare(v, "p", &u.adpf_p, true);
        let adpf_q = AdpfParams::declare(v, "q", &u.adpf_q, false);
        let pll_kp = tun(
            v,
            "pll.kp",
            60.0,
            "1/s",
            "PLL proportional gain (grid-following)",
            1e-6,
        );
        let pll_ki = tun(
            v,
            "pll.ki",
            240.0,
            "1/s2",
            "PLL integral gain (grid-following)",
            1e-6,
        );
        let pll_tau = par(
            v,
            "pll.tau",
            1.0 / 60.0,
            "s",
            "roll-off time constant tau_pll of the grid-following references",
            0.0,
        );
        let pll_order = v.integer(
            Spec::parameter(
                "pll.order",
                2,
                "",
                "order d of the grid-following p-f roll-off 1/(tau_pll s + 1)^d (the v-q reference has order 1); 2 makes m T_pf^-1 strictly proper for every ADPF, so the PLL's proportional path does not reach the current at the gain H/tau_pll of a first-order roll-off",
            )
            .range(0.0, 4.0),
        );
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
        let tau_dc = par(
            v,
            "tau_dc",
            u.tau_dc,
            "s",
            "time constant of the dc source following its command",
            0.0,
        );
        let c_dc = par(
            v,
            "C_dc",
            0.096,
            "pu",
            "dc-link capacitance on S_rated",
            0.0,
        );
        let g_dc = par(
            v,
            "G_dc",
            0.05,
            "pu",
            "dc-link conductance (losses) on S_rated",
            0.0,
        );
        let k_dc = par(
            v,
            "k_dc",
            100.0,
            "pu",
            "dc-voltage control gain (source power per pu of v_dc deviation)",
            0.0,
        );
        let dc_zeta = v.real(
            Spec::parameter(
                "dc.zeta",
                0.7,
                "1",
                "damping ratio the dc-voltage control's capacitor-power term gives the k_dc, C_dc, tau_dc loop (0: no damping term)",
            )
            .range(0.0, 2.0),
        );
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
        let priority = v.integer(
            Spec::parameter(
                "limit.priority",
                limits::priority::ACTIVE,
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
        let storage = v.boolean(Spec::parameter(
            "storage",
            u.storage,
            "",
            "the primary source can absorb power (a battery): dc source within [-P_avail, P_avail] instead of [0, P_avail]",
        ));
        let deload = v.real(
            Spec::parameter(
                "deload",
                1.0,
                "1",
                "deloading: the set point stays at or below deload * P_avail - G_dc (reserve for participation)",
            )
            .range(1e-3, 1.0)
            .tunable(),
        );
        let p_avail0 = tun(
            v,
            ports::P_AVAIL0,
            u.p_avail0,
            "pu",
            "available active power of the primary source, on S_base",
            0.0,
        );
        let avail_t = v.real(
            Spec::parameter(
                "avail.t_step",
                1.0,
                "s",
                "time of the availability step (a cloud, a wind drop)",
            )
            .tunable(),
        );
        let avail_dp = v.real(
            Spec::parameter(
                "avail.dP",
                0.0,
                "pu",
                "availability step on S_base (negative = less available power)",
            )
            .tunable(),
        );
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
        let mu_p = v.real(
            Spec::input(
                ports::MU_P,
                u.mu_p,
                "1",
                "ADPF dc gain of the p-f channel from the operator (static, low-pass)",
            )
            .range(0.0, 1.0),
        );
        let mu_q = v.real(
            Spec::input(
                ports::MU_Q,
                u.mu_q,
                "1",
                "ADPF dc gain of the v-q channel from the operator (static, low-pass)",
            )
            .range(0.0, 1.0),
        );
        let mu_p_lpf = (1..=MAX_LPF)
            .map(|k| {
                v.real(
                    Spec::input(
                        &ports::mu_p_lpf(k),
                        u.mu_p_lpf.get(k - 1).copied().unwrap_or(0.0),
                        "1",
                        &format!("complement unit: dc gain of low-pass unit {k} it closes"),
                    )
                    .range(0.0, 1.0),
                )
            })
            .collect();
        let out = |v: &mut Variables, name: &str, unit: &str, desc: &str| {
            v.real(Spec::output(name, unit, desc).initial_dependencies(&io))
        };
        Ok(Der {
            mode,
            s_rated,
            s_base,
            s_dvpp,
            f_nom,
            h,
            d,
            dq,
            tau_q,
            r_f,
            x_f,
            adpf_p,
            adpf_q,
            pll_kp,
            pll_ki,
            pll_tau,
            pll_order,
            qpi_kp,
            qpi_ki,
            e_max,
            tau_dc,
            c_dc,
            g_dc,
            storage,
            deload,
            k_dc,
            dc_zeta,
            v_dc_min,
            v_dc_max,
            t_budget,
            i_max,
            priority,
            current_tau,
            vq_tau,
            v_sync,
            t_hold,
            ramp,
            p_avail0,
            avail_t,
            avail_dp,
            redispatch,
            p,
            q,
            v: vv,
            v_angle,
            mu_p,
            mu_q,
            mu_p_lpf,
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
            rt: None,
        })
    }
}
