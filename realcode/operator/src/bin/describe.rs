//! Writes the DLL's headers into a directory (used by `cargo xtask bundle`).

fn main() {
    dvpp_realcode::describe_main::<operator_model::Operator>(&dvpp_operator_dll::SPEC, &[]);
}
