//! The DVPP operator FMU's binary: the 34 FMI 2.0 Co-Simulation functions of [`operator_model::Operator`].

fmi_export::export_fmu!(operator_model::Operator);
