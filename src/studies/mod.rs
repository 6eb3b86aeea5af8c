//! The accuracy-and-speed study: the benchmark scenes (IFToMM A01, A02, A03, A04, the spatial
//! slider-crank, chains with end-mass ratios), the analytic references and the metrics that the
//! demos, the charts (`chart`), `joint_bench` and the tests measure with.
//!
//! Not part of the MPC184 core: nothing else in the crate uses it. It builds its worlds through
//! the public API only, so a study here is what a user could write.

pub mod andrews;
pub mod benchmarks;
pub mod metrics;
pub mod scenes;
