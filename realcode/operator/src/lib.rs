//! The DVPP operator's real-code DLL: the eight IEEE/Cigré functions of [`operator_model::Operator`] (the FMU `dvpp_operator`'s model, case study I's three units) at its own fixed step of 1 ms.

pub use dvpp_realcode;

/// The DLL's fixed step and the running state's capacity.
pub const SPEC: dvpp_realcode::DllSpec = dvpp_realcode::DllSpec {
    step: 1e-3,
    emt_rms_mode: 3,
    state_words: 8192,
    step_parameter: None,
    config: "",
};

dvpp_realcode::export_dll!(operator_model::Operator, crate::SPEC);
