//! Scalar and vector types, switched between f64 (default, `rapier3d-f64`) and f32 (`rapier3d`).
//!
//! Everything physical in this crate is expressed with these aliases so that the precision is one
//! feature switch. SI units and radians throughout.

#[cfg(all(feature = "f32", feature = "f64"))]
compile_error!(
    "features `f32` and `f64` are exclusive: use `--no-default-features --features f32[,ecs]` for f32"
);
#[cfg(not(any(feature = "f32", feature = "f64")))]
compile_error!("enable exactly one of the features `f64` (default) or `f32`");

#[cfg(feature = "f32")]
pub use rapier3d as rapier;
#[cfg(feature = "f64")]
pub use rapier3d_f64 as rapier;

pub use rapier::math::{Matrix, Pose, Real, Rotation, Vector};

/// The constant pi in [`Real`] precision.
pub const PI: Real = core::f64::consts::PI as Real;
