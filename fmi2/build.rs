//! Build script: tells dependents' build scripts where the C header is (`DEP_FMI2_INCLUDE`).

fn main() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("include");
    println!("cargo:rerun-if-changed=include/fmi2.h");
    println!("cargo:include={}", dir.display());
}
