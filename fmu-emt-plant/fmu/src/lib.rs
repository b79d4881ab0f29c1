//! The EMT plant FMU's binary: the 34 FMI 2.0 Co-Simulation functions of [`emt_plant_model::Plant`].

fmi_export::export_fmu!(emt_plant_model::Plant);
