//! Shared measurement helpers for the analytic tests (the library's own metrics).
#![allow(unused_imports, reason = "each test file uses a subset of the helpers")]

pub use rapier3d_mpc184::studies::metrics::*;

/// The path of the example `name` (`examples/NAME.rs`), which `cargo test` builds beside the
/// test binaries (`target/<profile>/examples/`) before it runs any test.
#[allow(dead_code, reason = "only the tests that run examples use it")]
pub fn example(name: &str) -> std::path::PathBuf {
    let exe = std::env::current_exe().expect("the test binary's path");
    let profile = exe
        .parent()
        .and_then(std::path::Path::parent)
        .expect("target/<profile>/deps/<test>");
    profile
        .join("examples")
        .join(format!("{name}{}", std::env::consts::EXE_SUFFIX))
}
