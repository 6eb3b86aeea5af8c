#![doc = include_str!("../README.md")]
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
    pub use crate::settings::{Backend, Integrator, WorldSettings};
    #[cfg(feature = "serde-snapshot")]
    pub use crate::snapshot::Snapshot;
    pub use crate::spring::{SpringDamper, SpringId, SpringOutput};
    pub use crate::world::{DriveLevel, DriveProfile, Mpc184World};
}
