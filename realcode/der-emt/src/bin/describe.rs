//! Writes the DLL's headers and each preset's parameter set into a directory (used by `cargo xtask bundle`).

fn main() {
    let presets: Vec<&str> = der_model::PRESETS.iter().map(|p| p.name).collect();
    dvpp_realcode::describe_main::<der_model::emt::DerEmt>(&dvpp_der_emt_dll::SPEC, &presets);
}
