//! Names of the grid FMU's connectors that a system wires: DER slots, the PCC, the points of
//! coupling of a DVPP area and the R/X parameters of its lines.

/// The input or output `port` of DER slot `k` (1-based): `der[k].port`.
fn der(k: usize, port: &str) -> String {
    format!("der[{k}].{port}")
}

/// Grid-forming slot `k` (1-based), input: internal voltage angle.
pub fn der_theta(k: usize) -> String {
    der(k, "theta")
}

/// Grid-forming slot `k` (1-based), input: internal voltage magnitude.
pub fn der_e(k: usize) -> String {
    der(k, "E")
}

/// Grid-following slot `k` (1-based), input: active power injected.
pub fn der_p_ref(k: usize) -> String {
    der(k, "p_ref")
}

/// Grid-following slot `k` (1-based), input: reactive power injected.
pub fn der_q_ref(k: usize) -> String {
    der(k, "q_ref")
}

/// Slot `k` (1-based), input: current limit of its converter.
pub fn der_i_max(k: usize) -> String {
    der(k, "i_max")
}

/// Grid-forming slot `k` (1-based), input: lowest active power of its converter.
pub fn der_p_min(k: usize) -> String {
    der(k, "p_min")
}

/// Grid-forming slot `k` (1-based), input: highest active power of its converter.
pub fn der_p_max(k: usize) -> String {
    der(k, "p_max")
}

/// Slot `k` (1-based), output: active power it injects.
pub fn der_p(k: usize) -> String {
    der(k, "p")
}

/// Slot `k` (1-based), output: reactive power it injects.
pub fn der_q(k: usize) -> String {
    der(k, "q")
}

/// Slot `k` (1-based), output: voltage magnitude at its bus.
pub fn der_v(k: usize) -> String {
    der(k, "v")
}

/// Slot `k` (1-based), output: voltage angle at its bus.
pub fn der_v_angle(k: usize) -> String {
    der(k, "v_angle")
}

/// Output: DVPP active power at the PCC.
pub const PCC_P: &str = "pcc.p";
/// Output: DVPP reactive power at the PCC.
pub const PCC_Q: &str = "pcc.q";
/// Output: PCC frequency.
pub const PCC_F: &str = "pcc.f";
/// Output: PCC voltage magnitude.
pub const PCC_V: &str = "pcc.v";

/// The output `port` of the PCC of DVPP `name` (case `[[dvpp_pcc]]`): `pcc_<name>.port`.
fn dvpp_pcc(name: &str, port: &str) -> String {
    format!("pcc_{name}.{port}")
}

/// PCC of DVPP `name`, output: the active power its slots inject.
pub fn dvpp_pcc_p(name: &str) -> String {
    dvpp_pcc(name, "p")
}

/// PCC of DVPP `name`, output: the reactive power its slots inject.
pub fn dvpp_pcc_q(name: &str) -> String {
    dvpp_pcc(name, "q")
}

/// PCC of DVPP `name`, output: voltage magnitude at its bus.
pub fn dvpp_pcc_v(name: &str) -> String {
    dvpp_pcc(name, "v")
}

/// PCC of DVPP `name`, output: frequency at its bus.
pub fn dvpp_pcc_f(name: &str) -> String {
    dvpp_pcc(name, "f")
}

/// The output `port` of point of coupling `k` (1-based): `poc[k].port`.
fn poc(k: usize, port: &str) -> String {
    format!("poc[{k}].{port}")
}

/// POC `k` (1-based), output: active power the area sends through the POC.
pub fn poc_p(k: usize) -> String {
    poc(k, "p")
}

/// POC `k` (1-based), output: reactive power the area sends through the POC.
pub fn poc_q(k: usize) -> String {
    poc(k, "q")
}

/// POC `k` (1-based), output: voltage magnitude at the POC bus.
pub fn poc_v(k: usize) -> String {
    poc(k, "v")
}

/// POC `k` (1-based), output: frequency at the POC bus.
pub fn poc_f(k: usize) -> String {
    poc(k, "f")
}

/// Output (cases with POCs): active power the loads inside the POC area draw.
pub const AREA_P_LOAD: &str = "area.p_load";
/// Output (cases with POCs): reactive power the loads inside the POC area draw.
pub const AREA_Q_LOAD: &str = "area.q_load";

/// Parameter: homogeneous R/X ratio of the case's `[mv]` lines.
pub const MV_RX: &str = "mv.rx";

/// Parameter: R/X ratio of the `k`-th (1-based) line of the case's `[mv]` group (0: `mv.rx`).
pub fn mv_line_rx(k: usize) -> String {
    format!("mv.line[{k}].rx")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::GridFmu;
    use fmi_export::model_description::{Causality, ModelDescription};
    use fmi_export::{describe, Config};

    fn described(case: &str) -> ModelDescription {
        let config = Config::from_toml(&format!("[model]\ncase = \"{case}\"\n")).unwrap();
        describe::<GridFmu>(&config, None).unwrap()
    }

    fn assert_port(md: &ModelDescription, name: &str, causality: Causality) {
        let v = md
            .variable(name)
            .unwrap_or_else(|| panic!("'{name}' is not a variable of the grid FMU"));
        assert_eq!(v.causality(), causality, "'{name}'");
    }

    #[test]
    fn names_match_the_declared_variables() {
        // ieee9_dvpp: grid-forming slots; ieee9_hybrid: grid-following ones as well.
        for case in ["ieee9_dvpp", "ieee9_hybrid"] {
            let md = described(case);
            for p in [PCC_P, PCC_Q, PCC_F, PCC_V] {
                assert_port(&md, p, Causality::Output);
            }
            let mut k = 1;
            while md.variable(&der_p(k)).is_some() {
                for p in [der_p(k), der_q(k), der_v(k), der_v_angle(k)] {
                    assert_port(&md, &p, Causality::Output);
                }
                let drive = if md.variable(&der_theta(k)).is_some() {
                    [der_theta(k), der_e(k)]
                } else {
                    [der_p_ref(k), der_q_ref(k)]
                };
                for p in drive {
                    assert_port(&md, &p, Causality::Input);
                }
                k += 1;
            }
            assert!(k > 1, "{case}: no DER slot found");
        }
    }

    #[test]
    fn poc_and_rx_names_match_the_declared_variables() {
        let md = described("ieee9_mv");
        for k in 1..=2 {
            for p in [poc_p(k), poc_q(k), poc_v(k), poc_f(k)] {
                assert_port(&md, &p, Causality::Output);
            }
        }
        assert!(md.variable(&poc_p(3)).is_none());
        assert_port(&md, MV_RX, Causality::Parameter);
        let n = fmu_grid_case().mv.unwrap().lines.len();
        for k in 1..=n {
            assert_port(&md, &mv_line_rx(k), Causality::Parameter);
        }
        assert!(md.variable(&mv_line_rx(n + 1)).is_none());
        // cases without [[poc]] or [mv] declare none of them
        let md = described("ieee9_dvpp");
        assert!(md.variable(&poc_p(1)).is_none() && md.variable(MV_RX).is_none());
    }

    fn fmu_grid_case() -> crate::Case {
        crate::Case::builtin("ieee9_mv").unwrap()
    }
}
