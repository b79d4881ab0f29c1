//! The EMT-level DER controller's real-code DLL: the eight IEEE/Cigré functions of [`der_model::emt::DerEmt`] (the FMU `dvpp_der_emt`'s model) at a fixed step of 50 µs.

pub use dvpp_realcode;

/// The DLL's fixed step, the running state's capacity and the parameter that states the step.
pub const SPEC: dvpp_realcode::DllSpec = dvpp_realcode::DllSpec {
    step: 50e-6,
    emt_rms_mode: 1,
    state_words: 4096,
    step_parameter: Some("t_s"),
    config: "",
};

dvpp_realcode::export_dll!(der_model::emt::DerEmt, crate::SPEC);
