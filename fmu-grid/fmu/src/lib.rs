//! The reduced grid FMU's binary: the 34 FMI 2.0 Co-Simulation functions of [`grid_model::GridFmu`].

fmi_export::export_fmu!(grid_model::GridFmu);
