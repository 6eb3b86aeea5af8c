//! Shared measurement helpers for the analytic tests (the library's own metrics).
#![allow(unused_imports, reason = "each test file uses a subset of the helpers")]

pub use rapier3d_mpc184::studies::metrics::*;
