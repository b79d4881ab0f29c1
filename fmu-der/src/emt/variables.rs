//! The EMT-level controller's variables: every parameter, measurement, command and monitoring output, with its start value.

use super::{DerEmt, Outputs};
use crate::adpf::AdpfVars;
use crate::unit_vars::{par, tun, DcVars, GainVars, PllVars, SourceVars, UnitVars};
use crate::{ports, DerConfig, UnitDefaults};
use dvpp_control::converter::{ConverterData, InnerDesign};
use fmi_export::{Spec, Variables};

/// Phase suffixes of the three-phase connectors.
const PHASES: [&str; 3] = ["a", "b", "c"];

/// The measurement inputs, the initial dependencies of every output.
const MEASUREMENTS: [&str; 10] = [
    "v_a", "v_b", "v_c", "i_a", "i_b", "i_c", "ig_a", "ig_b", "ig_c", "v_dc",
];

impl DerEmt {
    /// The controller's variables for `config` (its preset's start values).
    pub(crate) fn declare_variables(
        config: &DerConfig,
        v: &mut Variables,
    ) -> Result<DerEmt, String> {
        let u = UnitDefaults::of(config.preset).resized(config.rating)?;
        let paper = ConverterData::PAPER;
        let inner = InnerDesign::default();
        let unit = UnitVars::declare(v, &u);
        let adpf_p = AdpfVars::declare(v, "p", &u.adpf_p, true);
        let adpf_q = AdpfVars::declare(v, "q", &u.adpf_q, false);
        let pll = PllVars::declare(v);
        let qpi_kp = tun(
            v,
            "qpi.kp",
            0.05,
            "pu",
            "grid-forming PI matching controller: proportional gain from the q error to the capacitor-voltage reference E",
            0.0,
        );
        let qpi_ki = tun(
            v,
            "qpi.ki",
            0.5,
            "1/s",
            "grid-forming PI matching controller: integral gain from the q error to E",
            0.0,
        );
        let e_max = tun(
            v,
            "E_max",
            1.5,
            "pu",
            "grid-forming: largest capacitor-voltage reference E the matching controller sets",
            0.0,
        );
        let vq_tau = tun(
            v,
            "vq.tau",
            0.5,
            "s",
            "grid-following: time constant of the voltage deviation ahead of the v-q droop (as the phasor DER); 0 = none",
            0.0,
        );
        let filter = |v: &mut Variables, name: &str, start: f64, desc: &str, min: f64| {
            par(v, name, start, "pu", &format!("{desc}, pu on S_rated"), min)
        };
        let r_f = filter(v, "R_f", paper.r_f, "filter resistance", 0.0);
        let l_f = filter(
            v,
            "L_f",
            paper.l_f,
            "filter inductance (its reactance at f_nom)",
            1e-6,
        );
        let c_f = filter(
            v,
            "C_f",
            paper.c_f,
            "filter capacitance (its susceptance at f_nom)",
            1e-6,
        );
        let r_t = filter(v, "R_t", paper.r_t, "LV/MV transformer resistance", 0.0);
        let l_t = filter(
            v,
            "L_t",
            paper.l_t,
            "LV/MV transformer leakage inductance (its reactance at f_nom)",
            0.0,
        );
        let vdc_ratio = par(
            v,
            "vdc_ratio",
            paper.v_dc_ratio,
            "1",
            "nominal dc voltage over the rated phase-to-neutral peak voltage, v_dc*/v_r: the converter's phase voltage is m * v_dc * vdc_ratio/2",
            1e-3,
        );
        let vi_r = tun(
            v,
            "vi.r",
            0.3,
            "pu",
            "grid-forming: virtual resistance on S_rated: the capacitor-voltage reference is (E, 0) - vi.r i_g. It damps the swing of the frame angle through the network's inductances (without it a unit on a stiff grid behind its transformer, R/X = 0.1, is unstable at this level of modelling: docs/emt.md)",
            0.0,
        );
        let current_hz = tun(
            v,
            "inner.current_hz",
            inner.current_hz,
            "Hz",
            "bandwidth of the converter-current PI loop (k_p = w L_f, k_i = w R_f: the loop is w/s)",
            1e-3,
        );
        let voltage_hz = tun(
            v,
            "inner.voltage_hz",
            inner.voltage_hz,
            "Hz",
            "bandwidth of the capacitor-voltage PI loop (k_p = w C_f)",
            1e-3,
        );
        let zero_ratio = tun(
            v,
            "inner.zero_ratio",
            inner.zero_ratio,
            "1",
            "capacitor-voltage loop: its crossover over its PI zero (k_i = k_p w/zero_ratio)",
            1e-3,
        );
        let i_max = tun(
            v,
            "I_max",
            inner.i_max,
            "pu",
            "current limit: the converter-current reference's magnitude, pu of the rated current",
            1e-3,
        );
        let t_s = par(
            v,
            "t_s",
            50e-6,
            "s",
            "the host's step, for the output at initialization only (later outputs use the step the host takes)",
            1e-9,
        );
        let dc = DcVars::declare(v, &u);
        let source = SourceVars::declare(v, &u);
        // Start values: a balanced 1 pu capacitor voltage at angle 0 and no current (the unit
        // at no load), so that the FMU initializes and steps on its own.
        let three = |v: &mut Variables, prefix: &str, start: [f64; 3], desc: &str| {
            let phase = |k: usize| {
                Spec::input(
                    &format!("{prefix}_{}", PHASES[k]),
                    start[k],
                    "pu",
                    &format!("{desc}, phase {}", PHASES[k]),
                )
            };
            [0, 1, 2].map(|k| v.real(phase(k)))
        };
        let v_abc = three(
            v,
            "v",
            [1.0, -0.5, -0.5],
            "measured filter-capacitor voltage, pu of the rated phase-to-neutral peak",
        );
        let i_abc = three(
            v,
            "i",
            [0.0; 3],
            "measured converter-side filter current, pu of the rated peak current",
        );
        let ig_abc = three(
            v,
            "ig",
            [0.0; 3],
            "measured grid-side (transformer) current toward the grid, pu of the rated peak current",
        );
        let v_dc = v.real(
            Spec::input(
                "v_dc",
                1.0,
                "pu",
                "measured dc-link voltage, pu of its nominal v_dc*",
            )
            .min(0.0),
        );
        let gains = GainVars::declare(v, &u);
        let out = |v: &mut Variables, name: &str, unit: &str, desc: &str| {
            v.real(Spec::output(name, unit, desc).initial_dependencies(&MEASUREMENTS))
        };
        let m_abc = PHASES.map(|ph| {
            out(
                v,
                &format!("m_{ph}"),
                "1",
                &format!("modulation index of phase {ph}, within [-1, 1]: the converter's phase voltage is m * v_dc * vdc_ratio/2 (pu of v_r); for the step after this output"),
            )
        });
        let i_dc_ref = out(
            v,
            "i_dc_ref",
            "pu",
            "current command to the primary (dc) source's lag, pu of S_rated/v_dc* (the source itself holds its power within [p_src_min, p_src_max])",
        );
        let p_src = [
            ("p_src_min", "lowest", "0, or -P_avail for storage"),
            ("p_src_max", "highest", "P_avail"),
        ]
        .map(|(name, which, what)| {
            out(
                v,
                name,
                "pu",
                &format!("the {which} power the primary source can deliver now, on S_rated ({what}): for the host's source model"),
            )
        });
        let p = out(
            v,
            ports::P,
            "pu",
            "active power into the grid at the MV side of the transformer, on S_base (computed from v_c and i_g)",
        );
        let q = out(
            v,
            ports::Q,
            "pu",
            "reactive power into the grid at the MV side of the transformer, on S_base",
        );
        let vv = out(
            v,
            ports::V,
            "pu",
            "voltage magnitude at the MV side of the transformer, pu of nominal",
        );
        let df = out(
            v,
            "df",
            "pu",
            "the unit's frequency deviation, pu of f_nom (grid-forming: its frame's; grid-following: the PLL's)",
        );
        let theta = out(
            v,
            ports::THETA,
            "rad",
            "the frame's angle beyond 2 pi f_nom t (grid-forming: from m^-1 T_pf; grid-following: the PLL's)",
        );
        let e = out(
            v,
            ports::E,
            "pu",
            "grid-forming: the capacitor-voltage reference magnitude the matching controller sets",
        );
        let p_set = out(
            v,
            ports::P_SET,
            "pu",
            "the active set point on S_base: the dispatch (p at initialization), curtailed to deload * P_avail - G_dc",
        );
        let q_ref = out(
            v,
            ports::Q_REF,
            "pu",
            "the reactive power reference on S_base (q0 - T_vq dv)",
        );
        let p_avail = out(
            v,
            ports::P_AVAIL,
            "pu",
            "available active power of the primary source, on S_base",
        );
        let i_ac = out(
            v,
            ports::I_AC,
            "pu",
            "magnitude of the converter-side current, pu of the rated current",
        );
        let inner_kind = v.integer(
            Spec::parameter(
                "inner.kind",
                0,
                "",
                "grid-forming: the matching controller's v-q part, 0 = option A (the q PI, the capacitor-voltage and converter-current PI loops), 1 = option B (the LPV H-infinity state feedback of dvpp-control's hinf_gains, scheduled on mu_q: docs/hinf.md)",
            )
            .range(0.0, 1.0),
        );
        let flag =
            |v: &mut Variables, name: &str, desc: &str| v.boolean(Spec::boolean_output(name, desc));
        let limit = [
            (
                "limit.current",
                "option A: the converter-current reference is held at I_max; option B (inner.kind = 1, no current limit): the converter current is beyond I_max",
            ),
            (
                "limit.modulation",
                "the converter voltage is held at the modulation limit",
            ),
            (
                "limit.source",
                "the primary source is held at a bound of its availability (p_src_min, p_src_max) while the dc command asks for more",
            ),
        ]
        .map(|(name, desc)| flag(v, name, desc));
        Ok(DerEmt {
            unit,
            adpf_p,
            adpf_q,
            pll,
            qpi: [qpi_kp, qpi_ki, e_max],
            vq_tau,
            filter: [r_f, l_f, c_f, r_t, l_t],
            vdc_ratio,
            vi_r,
            inner: [current_hz, voltage_hz, zero_ratio, i_max],
            t_s,
            dc,
            source,
            v_abc,
            i_abc,
            ig_abc,
            v_dc,
            gains,
            out: Outputs {
                m_abc,
                i_dc_ref,
                p_src,
                p,
                q,
                v: vv,
                df,
                theta,
                e,
                p_set,
                q_ref,
                p_avail,
                i_ac,
                limit,
            },
            inner_kind,
        })
    }
}
