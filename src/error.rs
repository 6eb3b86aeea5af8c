//! Errors of the library: every variant names where the problem came from.

use crate::dof::Dof;
use crate::math::Real;

/// Identifier of a joint in an [`crate::Mpc184World`] (dense index, stable for the joint's life).
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub struct JointId(pub u32);

impl core::fmt::Display for JointId {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "joint {}", self.0)
    }
}

/// Identifier of a spring-damper in an [`crate::Mpc184World`] (dense index, stable for the
/// spring's life).
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub struct SpringId(pub u32);

impl core::fmt::Display for SpringId {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "spring {}", self.0)
    }
}

fn at_joint(joint: &Option<JointId>) -> String {
    joint.map_or_else(String::new, |j| format!(" at {j}"))
}

/// What went wrong, with the joint, body, field or option it concerns.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A KEYOPT value that MPC184 does not define.
    #[error("KEYOPT({keyopt}) = {value}: {reason}")]
    InvalidKeyopt {
        /// Which KEYOPT (1..6).
        keyopt: u8,
        /// The value given.
        value: i64,
        /// What is allowed.
        reason: String,
    },
    /// Something this crate (or this backend) cannot do, with what to do instead.
    #[error("unsupported: {what} (hint: {hint})")]
    Unsupported {
        /// What was asked for.
        what: String,
        /// What to do instead.
        hint: String,
    },
    /// A joint frame (local coordinate system) that is not a proper rotation, or a non-finite node.
    #[error("{joint}: degenerate frame at node {node}: {reason}")]
    DegenerateFrame {
        /// The joint.
        joint: JointId,
        /// 1 (node I) or 2 (node J).
        node: u8,
        /// What is wrong.
        reason: String,
    },
    /// A body handle that is not in the world, or a joint between a body and itself.
    #[error("{joint}: body {which}: {reason}")]
    InvalidBody {
        /// The joint.
        joint: JointId,
        /// 1 or 2.
        which: u8,
        /// What is wrong.
        reason: String,
    },
    /// Nodes I and J of a joint whose nodes must coincide (revolute, universal) are further
    /// apart than [`crate::joint::COINCIDENCE_TOLERANCE`] allows.
    #[error(
        "{joint}: nodes I and J of a {kind} joint are {distance:e} m apart: they must coincide \
         (to {tolerance:e} m)"
    )]
    NodesApart {
        /// The joint.
        joint: JointId,
        /// The joint kind's name.
        kind: &'static str,
        /// The distance between the nodes at time 0 (m).
        distance: Real,
        /// The largest distance allowed (m).
        tolerance: Real,
    },
    /// A screw joint whose pitch (`SECJOINT,PITC`) is zero or not finite.
    #[error(
        "{joint}: screw pitch {pitch} m/rad: must be finite and nonzero (a screw of zero pitch \
         is a cylindrical joint with UZ held: use KEYOPT(1) = 11 and a SECLOCK on UZ)"
    )]
    InvalidPitch {
        /// The joint.
        joint: JointId,
        /// The pitch given (m/rad).
        pitch: Real,
    },
    /// A dynamic body of a joint without mass or with a singular (zero, infinite or non-finite)
    /// inertia: Rapier would treat it as infinitely heavy on that axis. Make it fixed, or give
    /// it mass properties.
    #[error("{joint}: body {which}: {reason}")]
    MassProperties {
        /// The joint.
        joint: JointId,
        /// 1 (node I) or 2 (node J).
        which: u8,
        /// What is wrong, with the body's handle.
        reason: String,
    },
    /// A joint id that does not exist (removed or never inserted).
    #[error("{0}: no such joint")]
    UnknownJoint(JointId),
    /// A body handle that is not in the world (never was, or removed).
    #[error("body {0:?}: no such body")]
    UnknownBody(crate::math::rapier::dynamics::RigidBodyHandle),
    /// A spring-damper id that does not exist (removed or never inserted).
    #[error("{0}: no such spring")]
    UnknownSpring(SpringId),
    /// A spring-damper's data (`COMBIN14` real constants, points, bodies) is inconsistent.
    #[error("{spring}: {field}: {reason}")]
    InvalidSpring {
        /// The spring.
        spring: SpringId,
        /// The offending field (`K`, `CV1`, `CV2`, `ILEN`, `IFORCE`, `nodes`, `body 1`, ...).
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// A world setting out of range.
    #[error("invalid setting `{field}` = {value}: {reason}")]
    InvalidSetting {
        /// The setting.
        field: &'static str,
        /// Its value.
        value: Real,
        /// What is allowed.
        reason: &'static str,
    },
    /// A DOF used where the joint kind does not allow it (for example a stop on a constrained DOF).
    #[error("{joint}: DOF {dof}: {reason}")]
    InvalidDof {
        /// The joint.
        joint: JointId,
        /// The DOF.
        dof: Dof,
        /// What is wrong.
        reason: String,
    },
    /// A joint's behaviour data (SECSTOP, SECLOCK, TB,JOIN, SECDATA) is inconsistent.
    #[error("{joint}: {field}: {reason}")]
    InvalidBehaviour {
        /// The joint.
        joint: JointId,
        /// The ANSYS name of the offending data (`SECSTOP`, `STIF`, `JNS`, ...).
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// The simulation produced non-finite values or a constraint error past its bound (see
    /// [`crate::DivergenceLimits`]) during the step that started at `time`. The world keeps its
    /// last good state: everything as it was at `time`, before the failed step.
    #[error("simulation diverged in the step from t = {time} s{}: {reason}", at_joint(.joint))]
    Diverged {
        /// Simulated time of the last good state: the start of the failed step (s). The world's
        /// `time()` after the error.
        time: Real,
        /// The joint it was found at (non-finite, or the largest constraint error relative to
        /// its bound); `None` only when no joint is involved (a free body).
        joint: Option<JointId>,
        /// What diverged.
        reason: String,
    },
    /// A world snapshot that could not be written or read (see `Mpc184World::snapshot`,
    /// feature `serde-snapshot`).
    #[error("snapshot: {reason}")]
    Snapshot {
        /// What is wrong.
        reason: String,
    },
    /// A static analysis ([`crate::Mpc184World::static_step`]) of a mechanism that still has
    /// free DOFs after its drives: static equilibrium under loads is not supported, only the
    /// position analysis of a kinematically driven mechanism.
    #[error(
        "static equilibrium is not supported: the mechanism has {free_dofs} free DOF(s) left \
         after its drives (a static run solves the positions of a kinematically driven \
         mechanism only; drive the free DOFs or run a transient analysis)"
    )]
    StaticEquilibrium {
        /// Free DOFs: 6 per dynamic body minus the rank of the constraint Jacobian with the drives.
        free_dofs: usize,
    },
    /// An APDL deck that could not be read.
    #[error(transparent)]
    Deck(#[from] crate::apdl::DeckError),
}
