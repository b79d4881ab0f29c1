//! The EMT-level controller's variables: every parameter, measurement, command and monitoring output, with its start value.

use super::DerEmt;
use crate::adpf::AdpfVars;
use crate::unit_vars::{par, tun, DcVars, GainVars, PllVars, QPiVars, SourceVars, UnitVars};
use crate::{ports, DerConfig, UnitDefaults};
use dvpp_control::converter::{Abc, ConverterData, InnerDesign};
use dvpp_controllers::emt::{EmtMeasurement, FilterParams};
use fmi_export::{Boolean, Real, Spec, Store, Variables};

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
        let unit = UnitVars::declare(v, &u);
        let adpf_p = AdpfVars::declare(v, "p", &u.adpf_p, true);
        let adpf_q = AdpfVars::declare(v, "q", &u.adpf_q, false);
        let pll = PllVars::declare(v);
        let qpi = QPiVars::declare_emt(v);
        let vq_tau = tun(
            v,
            "vq.tau",
            0.5,
            "s",
            "grid-following: time constant of the voltage deviation ahead of the v-q droop (as the phasor DER); 0 = none",
            0.0,
        );
        let circuit = CircuitVars::declare(v);
        let inner = InnerVars::declare(v);
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
        let measured = Measurements::declare(v);
        let gains = GainVars::declare(v, &u);
        let commands = Commands::declare(v);
        let out = Outputs::declare(v);
        let inner_kind = v.integer(
            Spec::parameter(
                "inner.kind",
                0,
                "",
                "grid-forming: the matching controller's v-q part, 0 = option A (the q PI, the capacitor-voltage and converter-current PI loops), 1 = option B (the LPV H-infinity state feedback of dvpp-control's hinf_gains, scheduled on mu_q: docs/hinf.md)",
            )
            .range(0.0, 1.0),
        );
        let limit = LimitFlags::declare(v);
        Ok(DerEmt {
            unit,
            adpf_p,
            adpf_q,
            pll,
            qpi,
            vq_tau,
            circuit,
            inner,
            t_s,
            dc,
            source,
            measured,
            gains,
            commands,
            out,
            inner_kind,
            limit,
        })
    }
}

/// An output that depends on every measurement at initialization.
fn output(v: &mut Variables, name: &str, unit: &str, desc: &str) -> Real {
    v.real(Spec::output(name, unit, desc).initial_dependencies(&MEASUREMENTS))
}

/// The circuit the converter drives: the filter `R_f`, `L_f`, `C_f`, the LV/MV transformer `R_t`,
/// `L_t`, and the converter's dc-to-ac voltage ratio `vdc_ratio` (the paper's data as start values).
pub(crate) struct CircuitVars {
    pub(crate) r_f: Real,
    pub(crate) l_f: Real,
    pub(crate) c_f: Real,
    pub(crate) r_t: Real,
    pub(crate) l_t: Real,
    pub(crate) vdc_ratio: Real,
}

impl CircuitVars {
    fn declare(v: &mut Variables) -> Self {
        let paper = ConverterData::PAPER;
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
        CircuitVars {
            r_f,
            l_f,
            c_f,
            r_t,
            l_t,
            vdc_ratio,
        }
    }

    /// The filter and the transformer.
    pub(crate) fn filter(&self, s: &Store) -> FilterParams {
        FilterParams {
            r_f: s[self.r_f],
            l_f: s[self.l_f],
            c_f: s[self.c_f],
            r_t: s[self.r_t],
            l_t: s[self.l_t],
        }
    }
}

/// The inner loops' design (`inner.current_hz`, `inner.voltage_hz`, `inner.zero_ratio`,
/// `I_max`) and, ahead of them, the grid-forming virtual resistance `vi.r`.
pub(crate) struct InnerVars {
    pub(crate) vi_r: Real,
    pub(crate) current_hz: Real,
    pub(crate) voltage_hz: Real,
    pub(crate) zero_ratio: Real,
    pub(crate) i_max: Real,
}

impl InnerVars {
    fn declare(v: &mut Variables) -> Self {
        let inner = InnerDesign::default();
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
        InnerVars {
            vi_r,
            current_hz,
            voltage_hz,
            zero_ratio,
            i_max,
        }
    }

    /// The inner loops' design.
    pub(crate) fn read(&self, s: &Store) -> InnerDesign {
        InnerDesign {
            current_hz: s[self.current_hz],
            voltage_hz: s[self.voltage_hz],
            zero_ratio: s[self.zero_ratio],
            i_max: s[self.i_max],
        }
    }
}

/// The three-phase measurements (inputs): capacitor voltage, converter-side and grid-side
/// currents, and the dc-link voltage.
pub(crate) struct Measurements {
    pub(crate) v_abc: [Real; 3],
    pub(crate) i_abc: [Real; 3],
    pub(crate) ig_abc: [Real; 3],
    pub(crate) v_dc: Real,
}

impl Measurements {
    fn declare(v: &mut Variables) -> Self {
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
        Measurements {
            v_abc,
            i_abc,
            ig_abc,
            v_dc,
        }
    }

    /// The measurement at time `t`.
    pub(crate) fn read(&self, s: &Store, t: f64) -> EmtMeasurement {
        let abc = |r: &[Real; 3]| Abc {
            a: s[r[0]],
            b: s[r[1]],
            c: s[r[2]],
        };
        EmtMeasurement {
            t,
            v_c: abc(&self.v_abc),
            i_f: abc(&self.i_abc),
            i_g: abc(&self.ig_abc),
            v_dc: s[self.v_dc],
        }
    }
}

/// The commands to the host's converter and source: modulation indices, the dc source's current
/// command and the bounds of the source's power.
pub(crate) struct Commands {
    pub(crate) m_abc: [Real; 3],
    pub(crate) i_dc_ref: Real,
    /// `p_src_min`, `p_src_max`.
    pub(crate) p_src: [Real; 2],
}

impl Commands {
    fn declare(v: &mut Variables) -> Self {
        let m_abc = PHASES.map(|ph| {
            output(
                v,
                &format!("m_{ph}"),
                "1",
                &format!("modulation index of phase {ph}, within [-1, 1]: the converter's phase voltage is m * v_dc * vdc_ratio/2 (pu of v_r); for the step after this output"),
            )
        });
        let i_dc_ref = output(
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
            output(
                v,
                name,
                "pu",
                &format!("the {which} power the primary source can deliver now, on S_rated ({what}): for the host's source model"),
            )
        });
        Commands {
            m_abc,
            i_dc_ref,
            p_src,
        }
    }
}

/// The DVPP layer's monitoring outputs: powers and voltage at the MV side, the frame, the set
/// points, the availability and the converter current.
pub(crate) struct Outputs {
    pub(crate) p: Real,
    pub(crate) q: Real,
    pub(crate) v: Real,
    pub(crate) df: Real,
    pub(crate) theta: Real,
    pub(crate) e: Real,
    pub(crate) p_set: Real,
    pub(crate) q_ref: Real,
    pub(crate) p_avail: Real,
    pub(crate) i_ac: Real,
}

impl Outputs {
    fn declare(v: &mut Variables) -> Self {
        let p = output(
            v,
            ports::P,
            "pu",
            "active power into the grid at the MV side of the transformer, on S_base (computed from v_c and i_g)",
        );
        let q = output(
            v,
            ports::Q,
            "pu",
            "reactive power into the grid at the MV side of the transformer, on S_base",
        );
        let vv = output(
            v,
            ports::V,
            "pu",
            "voltage magnitude at the MV side of the transformer, pu of nominal",
        );
        let df = output(
            v,
            "df",
            "pu",
            "the unit's frequency deviation, pu of f_nom (grid-forming: its frame's; grid-following: the PLL's)",
        );
        let theta = output(
            v,
            ports::THETA,
            "rad",
            "the frame's angle beyond 2 pi f_nom t (grid-forming: from m^-1 T_pf; grid-following: the PLL's)",
        );
        let e = output(
            v,
            ports::E,
            "pu",
            "grid-forming: the capacitor-voltage reference magnitude the matching controller sets",
        );
        let [p_set, q_ref, p_avail, i_ac] = Self::set_points(v);
        Outputs {
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
        }
    }

    /// `p_set`, `q_ref`, `p_avail`, `i_ac`.
    fn set_points(v: &mut Variables) -> [Real; 4] {
        let p_set = output(
            v,
            ports::P_SET,
            "pu",
            "the active set point on S_base: the dispatch (p at initialization), curtailed to deload * P_avail - G_dc",
        );
        let q_ref = output(
            v,
            ports::Q_REF,
            "pu",
            "the reactive power reference on S_base (q0 - T_vq dv)",
        );
        let p_avail = output(
            v,
            ports::P_AVAIL,
            "pu",
            "available active power of the primary source, on S_base",
        );
        let i_ac = output(
            v,
            ports::I_AC,
            "pu",
            "magnitude of the converter-side current, pu of the rated current",
        );
        [p_set, q_ref, p_avail, i_ac]
    }
}

/// The limit flags (boolean outputs).
pub(crate) struct LimitFlags {
    pub(crate) current: Boolean,
    pub(crate) modulation: Boolean,
    pub(crate) source: Boolean,
}

impl LimitFlags {
    fn declare(v: &mut Variables) -> Self {
        let mut flag = |name: &str, desc: &str| v.boolean(Spec::boolean_output(name, desc));
        let current = flag(
            "limit.current",
            "option A: the converter-current reference is held at I_max; option B (inner.kind = 1): its current-limited mode runs (option A's cascade in place of the H-infinity state feedback, from the converter current reaching I_max until no limit has acted for 50 ms: docs/hinf.md)",
        );
        let modulation = flag(
            "limit.modulation",
            "the converter voltage is held at the modulation limit",
        );
        let source = flag(
            "limit.source",
            "the converter draws more (or less) power from its dc side, ac power plus link losses, than the primary source can deliver now (p_src_min, p_src_max): the dc link, or a host's ideal dc supply, makes up the difference",
        );
        LimitFlags {
            current,
            modulation,
            source,
        }
    }
}
