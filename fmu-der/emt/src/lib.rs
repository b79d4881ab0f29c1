//! The EMT-level DER controller FMU's binary: the 34 FMI 2.0 Co-Simulation functions of [`der_model::emt::DerEmt`].

fmi_export::export_fmu!(der_model::emt::DerEmt);
