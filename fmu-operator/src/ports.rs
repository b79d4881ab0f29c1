//! Names of the operator FMU's connectors and the parameters a system sets.

/// The variable `name` of DER `k` (1-based): `der[k].name`.
fn der(k: usize, name: &str) -> String {
    format!("der[{k}].{name}")
}

/// Parameter: converter rating of DER `k` (1-based).
pub fn der_s_rated(k: usize) -> String {
    der(k, "S_rated")
}

/// Input: available active power of DER `k` (1-based).
pub fn der_p_avail(k: usize) -> String {
    der(k, "P_avail")
}

/// Input: active power of DER `k` (1-based).
pub fn der_p(k: usize) -> String {
    der(k, "p")
}

/// Input: the active set point of DER `k`.
pub fn der_p_set(k: usize) -> String {
    der(k, "p_set")
}

/// Input: reactive power of DER `k` (1-based).
pub fn der_q(k: usize) -> String {
    der(k, "q")
}

/// Output: active ADPF dc gain of low-pass DER `k` (1-based).
pub fn der_mu_p(k: usize) -> String {
    der(k, "mu_p")
}

/// Output: reactive ADPF dc gain of DER `k` (1-based).
pub fn der_mu_q(k: usize) -> String {
    der(k, "mu_q")
}

/// Output of complement DER `k` (1-based): the gain of the `j`-th (1-based) low-pass unit it closes.
pub fn der_mu_p_lpf(k: usize, j: usize) -> String {
    der(k, &format!("mu_p_lpf[{j}]"))
}

/// Input: DVPP active power at the PCC.
pub const PCC_P: &str = "pcc.p";
/// Input: DVPP reactive power at the PCC.
pub const PCC_Q: &str = "pcc.q";
/// Input: PCC frequency.
pub const PCC_F: &str = "pcc.f";
/// Input: PCC voltage magnitude.
pub const PCC_V: &str = "pcc.v";
/// Output: desired frequency deviation.
pub const REF_DF: &str = "ref.df";
/// Output: desired voltage deviation.
pub const REF_DV: &str = "ref.dv";
/// Output: measured minus desired frequency deviation.
pub const ERR_DF: &str = "err.df";
/// Output: measured minus desired voltage deviation.
pub const ERR_DV: &str = "err.dv";

/// The variable `name` of point of coupling `k` (1-based): `poc[k].name`.
fn poc(k: usize, name: &str) -> String {
    format!("poc[{k}].{name}")
}

/// Input: active power the DVPP area sends through POC `k` (1-based).
pub fn poc_p(k: usize) -> String {
    poc(k, "p")
}

/// Input: reactive power the DVPP area sends through POC `k` (1-based).
pub fn poc_q(k: usize) -> String {
    poc(k, "q")
}

/// Input: frequency at POC `k` (1-based).
pub fn poc_f(k: usize) -> String {
    poc(k, "f")
}

/// Input: voltage magnitude at POC `k` (1-based).
pub fn poc_v(k: usize) -> String {
    poc(k, "v")
}

/// Output: measured minus desired frequency deviation at POC `k` (1-based).
pub fn poc_err_df(k: usize) -> String {
    poc(k, "err_df")
}

/// Input (with POCs): active power the loads inside the DVPP area draw (the grid's output of
/// the same name).
pub const AREA_P_LOAD: &str = "area.p_load";
/// Input (with POCs): reactive power the loads inside the DVPP area draw.
pub const AREA_Q_LOAD: &str = "area.q_load";

/// Output: the rotated POC power deviation `T_pf` acts on.
pub const POC_DP: &str = "poc.dp";
/// Parameter: R/X of the DVPP area's lines the POC powers are rotated for.
pub const ROT_RX: &str = "rot.rx";

/// Parameter: DVPP base, MVA.
pub const S_DVPP: &str = "S_dvpp";
/// Parameter: virtual inertia of `T_pf`.
pub const TDES_H: &str = "Tdes.H";
/// Parameter: damping of `T_pf`.
pub const TDES_D: &str = "Tdes.D";
/// Parameter: q-v droop `T_qv`.
pub const TDES_DQ: &str = "Tdes.Dq";

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Operator;
    use fmi_export::model_description::Causality;
    use fmi_export::{describe, Config};

    #[test]
    fn names_match_the_declared_variables() {
        // The default DVPP: DERs 1 and 2 low-pass, DER 3 their complement.
        let md = describe::<Operator>(&Config::default(), None).unwrap();
        let check = |name: &str, causality: Causality| {
            let v = md
                .variable(name)
                .unwrap_or_else(|| panic!("'{name}' is not a variable of the operator FMU"));
            assert_eq!(v.causality(), causality, "'{name}'");
        };
        for p in [PCC_P, PCC_Q, PCC_F, PCC_V] {
            check(p, Causality::Input);
        }
        for p in [REF_DF, REF_DV, ERR_DF, ERR_DV] {
            check(p, Causality::Output);
        }
        for p in [S_DVPP, TDES_H, TDES_D, TDES_DQ] {
            check(p, Causality::Parameter);
        }
        for k in 1..=3 {
            check(&der_s_rated(k), Causality::Parameter);
            check(&der_p_avail(k), Causality::Input);
            check(&der_p(k), Causality::Input);
            check(&der_q(k), Causality::Input);
            check(&der_mu_q(k), Causality::Output);
        }
        check(&der_mu_p(1), Causality::Output);
        check(&der_mu_p(2), Causality::Output);
        check(&der_mu_p_lpf(3, 1), Causality::Output);
        check(&der_mu_p_lpf(3, 2), Causality::Output);
        // The POCs' variables exist only when the configuration has POCs.
        assert!(md.variable(&poc_p(1)).is_none() && md.variable(ROT_RX).is_none());
        let mut with_pocs = Config::<crate::OperatorConfig>::default();
        with_pocs.model.pocs = 2;
        with_pocs.model.rot_rx = 1.0;
        let md = describe::<Operator>(&with_pocs, None).unwrap();
        let check = |name: &str, causality: Causality| {
            let v = md.variable(name).unwrap_or_else(|| panic!("no '{name}'"));
            assert_eq!(v.causality(), causality, "'{name}'");
        };
        for k in 1..=2 {
            for p in [poc_p(k), poc_q(k), poc_f(k), poc_v(k)] {
                check(&p, Causality::Input);
            }
            check(&poc_err_df(k), Causality::Output);
        }
        check(POC_DP, Causality::Output);
        check(AREA_P_LOAD, Causality::Input);
        check(AREA_Q_LOAD, Causality::Input);
        check(ROT_RX, Causality::Parameter);
        assert!(md.variable(&poc_p(3)).is_none());
    }
}
