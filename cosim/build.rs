//! Build script: compiles the C-variadic FMI logger shim (c/logger.c) that src/fmu/instance.rs hands to FMUs.

fn main() {
    // The C header of the ABI, from the `fmi2` crate (its `links` metadata).
    let include = std::env::var("DEP_FMI2_INCLUDE").expect("the fmi2 crate names its header");
    println!("cargo:rerun-if-changed=c/logger.c");
    cc::Build::new()
        .file("c/logger.c")
        .include(include)
        .std("c11")
        .warnings(true)
        .extra_warnings(true)
        .warnings_into_errors(true)
        .compile("dvpp_cosim_logger");
}
