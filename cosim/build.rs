//! Build script: compiles the C-variadic FMI logger shim (c/logger.c) that src/fmu.rs hands to FMUs.

fn main() {
    println!("cargo:rerun-if-changed=c/logger.c");
    println!("cargo:rerun-if-changed=c/fmi2.h");
    cc::Build::new()
        .file("c/logger.c")
        .include("c")
        .std("c99")
        .warnings(true)
        .extra_warnings(true)
        .warnings_into_errors(true)
        .compile("dvpp_cosim_logger");
}
