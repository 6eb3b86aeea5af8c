//! The joint semantics of the ANSYS Mechanical APDL **MPC184** joint element on the
//! [Rapier](https://rapier.rs) physics engine: every joint type (KEYOPT(1) = 6..19) with the
//! Lagrange-multiplier and penalty methods, stops, locks, linear and tabulated stiffness and
//! damping, screw coupling, joint friction, prescribed motion and loads, and ANSYS-style output
//! (relative DOFs, Bryant angles, rates, reactions, stop/lock/stick-slip status), on three
//! backends: this crate's exact Lagrange solver (the default), Rapier's impulse joints and
//! Rapier's multibody joints.
//!
//! ```
//! use rapier3d_mpc184::prelude::*;
//! use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
//!
//! // A 1 kg bob, 1 m from a grounded revolute joint about Z, released horizontally, with a
//! // stop at -60 deg; the default backend (exact Lagrange), dt 1/60 s, 4 substeps.
//! let mut world = Mpc184World::new(WorldSettings::default());
//! let bob = world.physics.bodies.insert(
//!     RigidBodyBuilder::dynamic()
//!         .translation(Vector::new(1.0, 0.0, 0.0))
//!         .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, Vector::splat(1e-4))),
//! );
//! let joint = Mpc184Joint::revolute(Axis::Z, Vector::ZERO).with_stop(Dof::RotZ, -1.047, 1.047);
//! let hinge = world.insert_joint(None, Some(bob), joint)?;
//! for _ in 0..30 {
//!     world.step()?;
//! }
//! let out = world.output(hinge)?;
//! // The hinge holds: its gap is round-off (1e-10 m in f64, 6e-8 m in the f32 build).
//! assert!(out.rotation.z < 0.0 && out.gap < 1e-6);
//! println!("ROTZ {:.4} rad, reaction {:.3} N", out.rotation.z, out.force.length());
//! # Ok::<(), rapier3d_mpc184::Error>(())
//! ```
//!
//! Where to start:
//! - [`Mpc184Joint`] (the joint data: kind, method, nodes, axes, behaviour), [`catalogue`] (the
//!   table of joint types, their DOFs and Rapier lowering), [`behaviour`] (stops, locks,
//!   stiffness, damping, friction);
//! - [`Mpc184World`] (bodies, joints, springs, drives, loads, stepping, energy, output) and
//!   [`settings`] (time step, substeps, backend, integrator);
//! - [`deck`] (APDL input decks: parse, build, run load steps);
//! - `ecs` (features `ecs` and `bevy`: the `bevy_ecs` and `bevy_app` plugins).
//!
//! Features: `f64` (default), `f32`, `ecs`, `bevy`, `serde-snapshot`, `parallel`, `charts`; the
//! `mpc184` command is the workspace member `cli/`. The README has the measured accuracy and
//! cost of every backend, the deck reader's coverage and the charts.
// The layers, each importing only those above it in this list (see the README's
// "Architecture" section):
// 1. plain data and pure functions: math, error, dof, catalogue, behaviour, joint, kinematics,
//    rows, settings, drive, output, spring; the KKT solver (solver);
// 2. body helpers (body), the joint registry (joint_set), the insertion checks (validate) and
//    the work no backend books (work);
// 3. the joint backends (backend: lower, lagrange, rapier);
// 4. the static analysis (statics), the divergence guard (divergence), snapshot bytes
//    (snapshot);
// 5. the facade (world);
// 6. the deck reader (deck), the ECS plugin (ecs), the benchmark study (studies).
pub mod behaviour;
pub mod catalogue;
pub mod deck;
pub mod divergence;
pub mod dof;
pub mod drive;
#[cfg(feature = "ecs")]
pub mod ecs;
pub mod error;
pub mod idle;
pub mod joint;
pub mod kinematics;
pub mod math;
pub mod output;
pub mod rows;
pub mod settings;
#[cfg(feature = "serde-snapshot")]
pub mod snapshot;
pub mod spring;
pub mod statics;
pub mod studies;
pub mod world;

pub(crate) mod apdl;
pub(crate) mod backend;
pub(crate) mod body;
pub(crate) mod joint_set;
pub(crate) mod solver;
pub(crate) mod validate;
pub(crate) mod work;

pub use backend::lower;
pub use divergence::DivergenceLimits;
pub use error::{Error, JointId};
pub use joint::Mpc184Joint;
#[doc(hidden)]
pub use studies::{benchmarks, metrics, scenes};
pub use world::Mpc184World;

/// The Lagrange backend's public constants and diagnostics (the solver itself is internal).
pub mod lagrange {
    pub use crate::backend::LagrangeDiagnostics;
    pub use crate::backend::lagrange::{
        DEFAULT_PENALTY_DISP, DEFAULT_PENALTY_ROT, PROJECTION_TOLERANCE, penalty_stiffness,
    };
}

/// Old home of the output types, now in [`output`].
#[doc(hidden)]
pub mod effects {
    pub use crate::output::{EnergyLedger, EnergyReport, FrictionState};
}

/// The entry types.
pub mod prelude {
    pub use crate::behaviour::{Behaviour, Friction, FrictionLaw, Limit, Sym6, Table};
    pub use crate::catalogue::{Axis, JointKind};
    pub use crate::divergence::DivergenceLimits;
    pub use crate::dof::{Dof, DofMask};
    pub use crate::error::{Error, JointId};
    pub use crate::joint::{ConstraintMethod, Mpc184Joint};
    pub use crate::math::{Real, Rotation, Vector};
    pub use crate::output::{EnergyReport, JointOutput};
    pub use crate::settings::{Backend, Integrator, Outputs, StepControl, WorldSettings};
    #[cfg(feature = "serde-snapshot")]
    pub use crate::snapshot::Snapshot;
    pub use crate::spring::{SpringDamper, SpringId, SpringOutput};
    pub use crate::world::{
        CutReason, DriveLevel, DriveProfile, EventKind, Mpc184World, StepEvent, StepStats,
    };
}
