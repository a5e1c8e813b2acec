//! Compiles the FMI 2.0 logger shim (variadic in C, src/fmi2_logger.c).

fn main() {
    println!("cargo:rerun-if-changed=src/fmi2_logger.c");
    cc::Build::new().file("src/fmi2_logger.c").warnings(true).compile("tutti_fmu_fmi2_logger");
}
