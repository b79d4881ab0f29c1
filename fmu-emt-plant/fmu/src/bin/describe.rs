//! Prints this FMU's modelDescription.xml for a resources directory (used by `cargo xtask bundle`).

fn main() {
    fmi_export::describe_main::<emt_plant_model::Plant>();
}
