//! Names of the DER FMU's connectors and the parameters a system sets or reads.

/// Input: measured active power at the terminal.
pub const P: &str = "p";
/// Input: measured reactive power at the terminal.
pub const Q: &str = "q";
/// Input: voltage magnitude at the regulated point.
pub const V: &str = "v";
/// Input: voltage angle at the regulated point.
pub const V_ANGLE: &str = "v_angle";
/// Input: ADPF dc gain of the p-f channel from the operator.
pub const MU_P: &str = "mu_p";
/// Input: ADPF dc gain of the v-q channel from the operator.
pub const MU_Q: &str = "mu_q";

/// Input of a complement unit: dc gain of the `j`-th (1-based) low-pass unit it closes.
pub fn mu_p_lpf(j: usize) -> String {
    format!("mu_p_lpf[{j}]")
}

/// Output: internal voltage angle.
pub const THETA: &str = "theta";
/// Output: internal voltage magnitude.
pub const E: &str = "E";
/// Output: active power reference.
pub const P_REF: &str = "p_ref";
/// Output: reactive power reference.
pub const Q_REF: &str = "q_ref";
/// Output: available active power of the primary source.
pub const P_AVAIL: &str = "P_avail";
/// Output: the active set point (dispatch curtailed by the primary source).
pub const P_SET: &str = "p_set";

/// Output: the measured rotated active power `p'`.
pub const P_ROT: &str = "p_rot";
/// Output: the measured rotated reactive power `q'`.
pub const Q_ROT: &str = "q_rot";

/// Output: magnitude of the ac current at the terminal, pu of the rated current.
pub const I_AC: &str = "i_ac";
/// Output: dc-link voltage.
pub const V_DC: &str = "v_dc";
/// Output: the unit is synchronized.
pub const SYNCHRONIZED: &str = "synchronized";
/// Output: energy the primary source delivered since initialization.
pub const ENERGY_SOURCE: &str = "energy.source";
/// Output: energy the ac side drew from the dc link since initialization.
pub const ENERGY_AC: &str = "energy.ac";
/// Output: energy lost in the dc link since initialization.
pub const ENERGY_LOSS: &str = "energy.loss";
/// Output: energy stored in the dc link.
pub const ENERGY_STORED: &str = "energy.stored";

/// Output: the current limit, for the grid's slot.
pub const I_LIMIT: &str = "i_limit";
/// Output: lowest active power the dc link can take, for the grid's slot.
pub const P_MIN: &str = "p_min";
/// Output: highest active power the dc link can give, for the grid's slot.
pub const P_MAX: &str = "p_max";

/// Parameter: converter rating, MVA.
pub const S_RATED: &str = "S_rated";
/// Parameter: DVPP base, MVA.
pub const S_DVPP: &str = "S_dvpp";
/// Parameter: 1 = grid-forming, 2 = grid-following.
pub const MODE: &str = "mode";
/// Parameter: virtual inertia of `T_pf`.
pub const TDES_H: &str = "Tdes.H";
/// Parameter: damping of `T_pf`.
pub const TDES_D: &str = "Tdes.D";
/// Parameter: q-v droop `T_qv`.
pub const TDES_DQ: &str = "Tdes.Dq";
/// Parameter: resistance behind the imposed voltage.
pub const R_F: &str = "R_f";
/// Parameter: reactance behind the imposed voltage.
pub const X_F: &str = "X_f";
/// Parameter: R/X of the lines the rotational power control compensates (0 = classical).
pub const ROT_RX: &str = "rot.rx";
/// Parameter: available active power of the primary source at the start.
pub const P_AVAIL0: &str = "P_avail0";
/// Parameter: ADPF shape of the p-f channel (an [`AdpfKind`](crate::AdpfKind) code).
pub const ADPF_P_KIND: &str = "adpf.p.kind";
/// Parameter: p-f ADPF time constant.
pub const ADPF_P_TAU: &str = "adpf.p.tau";
/// Parameter: p-f ADPF order.
pub const ADPF_P_ORDER: &str = "adpf.p.order";
/// Parameter of a complement unit: number of low-pass units it closes.
pub const ADPF_P_N_LPF: &str = "adpf.p.n_lpf";

/// Parameter of a complement unit: time constant of the `j`-th (1-based) low-pass unit.
pub fn adpf_p_lpf_tau(j: usize) -> String {
    format!("adpf.p.lpf[{j}].tau")
}

/// Parameter of a complement unit: order of the `j`-th (1-based) low-pass unit.
pub fn adpf_p_lpf_order(j: usize) -> String {
    format!("adpf.p.lpf[{j}].order")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Der, MAX_LPF};
    use fmi_export::model_description::Causality;
    use fmi_export::{describe, Config};

    #[test]
    fn names_match_the_declared_variables() {
        let md = describe::<Der>(&Config::default(), None).unwrap();
        let check = |name: &str, causality: Causality| {
            let v = md
                .variable(name)
                .unwrap_or_else(|| panic!("'{name}' is not a variable of the DER FMU"));
            assert_eq!(v.causality(), causality, "'{name}'");
        };
        for p in [P, Q, V, V_ANGLE, MU_P, MU_Q] {
            check(p, Causality::Input);
        }
        for p in [
            THETA, E, P_REF, Q_REF, P_AVAIL, P_SET, I_LIMIT, P_MIN, P_MAX, P_ROT, Q_ROT,
        ] {
            check(p, Causality::Output);
        }
        for p in [
            S_RATED,
            S_DVPP,
            MODE,
            TDES_H,
            TDES_D,
            TDES_DQ,
            R_F,
            X_F,
            ROT_RX,
            P_AVAIL0,
            ADPF_P_KIND,
            ADPF_P_TAU,
            ADPF_P_ORDER,
            ADPF_P_N_LPF,
        ] {
            check(p, Causality::Parameter);
        }
        for j in [1, MAX_LPF] {
            check(&mu_p_lpf(j), Causality::Input);
            check(&adpf_p_lpf_tau(j), Causality::Parameter);
            check(&adpf_p_lpf_order(j), Causality::Parameter);
        }
    }
}
