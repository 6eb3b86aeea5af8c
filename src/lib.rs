#![doc = include_str!("../README.md")]
pub mod behaviour;
pub mod benchmarks;
pub mod catalogue;
pub mod deck;
pub mod divergence;
pub mod dof;
pub mod drive;
#[cfg(feature = "ecs")]
pub mod ecs;
pub mod effects;
pub mod error;
pub mod joint;
pub mod kinematics;
pub mod lagrange;
pub mod lower;
pub mod math;
pub mod metrics;
pub mod output;
pub mod rows;
pub mod scenes;
pub mod settings;
#[cfg(feature = "serde-snapshot")]
pub mod snapshot;
pub mod solver;
pub mod statics;
pub mod world;

pub use divergence::DivergenceLimits;
pub use error::{Error, JointId};
pub use joint::Mpc184Joint;
pub use world::Mpc184World;

/// The entry types.
pub mod prelude {
    pub use crate::behaviour::{Behaviour, Friction, FrictionLaw, Limit, Sym6, Table};
    pub use crate::catalogue::{Axis, JointKind};
    pub use crate::divergence::DivergenceLimits;
    pub use crate::dof::{Dof, DofMask};
    pub use crate::effects::EnergyReport;
    pub use crate::error::{Error, JointId};
    pub use crate::joint::{ConstraintMethod, Mpc184Joint};
    pub use crate::lower::Backend;
    pub use crate::math::{Real, Rotation, Vector};
    #[cfg(feature = "serde-snapshot")]
    pub use crate::snapshot::Snapshot;
    pub use crate::world::{
        DriveLevel, DriveProfile, Integrator, JointOutput, Mpc184World, WorldSettings,
    };
}
