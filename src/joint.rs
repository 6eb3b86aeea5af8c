//! [`Mpc184Joint`]: the plain, serialisable description of one MPC184 joint element.

use serde::{Deserialize, Serialize};

use crate::behaviour::{Behaviour, Friction, Limit, Sym6, Table};
use crate::catalogue::{Axis, JointKind};
use crate::dof::Dof;
use crate::math::{Real, Rotation, Vector};

/// How far apart nodes I and J of a revolute or universal joint may start, relative to the
/// size of their coordinates: `|x_J - x_I| <= COINCIDENCE_TOLERANCE * max(1, |x_I|, |x_J|)` (m),
/// so 1 um for a model within a metre of the origin. MPC184 requires these nodes to coincide;
/// beyond the tolerance `Mpc184World::insert_joint` refuses the joint
/// ([`crate::Error::NodesApart`]) rather than hold an offset the user did not mean.
pub const COINCIDENCE_TOLERANCE: Real = 1e-6;

/// How the constraint equations are imposed (KEYOPT(2)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub enum ConstraintMethod {
    /// KEYOPT(2) = 0: exact constraints through Lagrange multipliers (the ANSYS default).
    #[default]
    Lagrange,
    /// KEYOPT(2) = 1: penalty springs on the constrained DOFs.
    Penalty {
        /// `SECJOINT,PNLT,DISP,val`: on translations (val > 0 scales the default penalty,
        /// val < 0 gives |val| as the absolute stiffness in N/m; default 1).
        #[doc(alias = "PNLT")]
        disp: Real,
        /// `SECJOINT,PNLT,ROT,val`: on rotations (same rule, N m/rad; default 1).
        rot: Real,
    },
}

/// One MPC184 joint between node I (`1`) and node J (`2`), as given at the start of the
/// analysis (time 0).
///
/// Positions and axes are global. The local coordinate system at I (`axes1`, columns e1 e2 e3)
/// evolves with body 1; the one at J (`axes2`, default: `axes1`) with body 2. A grounded side
/// (no body) is the fixed world, placed at the other node (the ANSYS `E,,J` / `E,I` forms).
///
/// ```
/// use rapier3d_mpc184::prelude::*;
/// let hinge = Mpc184Joint::new(JointKind::Revolute { axis: Axis::Z }, Vector::ZERO);
/// assert_eq!(hinge.kind.constraint_count(), 5);
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Mpc184Joint {
    /// The joint type (KEYOPT(1), KEYOPT(4)).
    pub kind: JointKind,
    /// Lagrange or penalty (KEYOPT(2)).
    pub method: ConstraintMethod,
    /// Global position of node I at time 0 (m).
    pub node1: Vector,
    /// Global position of node J at time 0 (m; default: `node1`).
    pub node2: Vector,
    /// Orientation of the local system at I at time 0: maps local e1 e2 e3 to global axes
    /// (`SECJOINT,LSYS` first value; default: the global axes).
    #[doc(alias = "LSYS")]
    pub axes1: Rotation,
    /// Orientation of the local system at J at time 0 (`SECJOINT,LSYS` second value; default:
    /// the same as `axes1`).
    pub axes2: Option<Rotation>,
    /// Stops, locks, springs and dampers on the free DOFs (`SECSTOP`, `SECLOCK`, `TB,JOIN`,
    /// `SECDATA`; default: none).
    #[serde(default)]
    pub behaviour: Behaviour,
}

impl Mpc184Joint {
    /// A joint of `kind` with both nodes at `at` (global, m) and global axes.
    pub fn new(kind: JointKind, at: Vector) -> Self {
        Self {
            kind,
            method: ConstraintMethod::Lagrange,
            node1: at,
            node2: at,
            axes1: Rotation::IDENTITY,
            axes2: None,
            behaviour: Behaviour::default(),
        }
    }

    /// Revolute joint about e1 (`Axis::X`) or e3 (`Axis::Z`) at `at`.
    pub fn revolute(axis: Axis, at: Vector) -> Self {
        Self::new(JointKind::Revolute { axis }, at)
    }

    /// A rigid link (KEYOPT(1) = 0): a pin-ended rigid bar from `node1` (on body 1, node I) to
    /// `node2` (on body 2, node J), global, m; its length is their distance. A grounded side
    /// is the ground at its own node (unlike the joints, whose grounded node is taken at the
    /// other one). Frame I (for output) is the global axes unless set with
    /// [`Mpc184Joint::with_axes`].
    ///
    /// ```
    /// use rapier3d_mpc184::prelude::*;
    /// let bar = Mpc184Joint::rigid_link(Vector::ZERO, Vector::new(0.0, -1.0, 0.0));
    /// assert_eq!(bar.kind.constraint_count(), 1);
    /// ```
    #[doc(alias = "LINK")]
    pub fn rigid_link(node1: Vector, node2: Vector) -> Self {
        Self::new(JointKind::RigidLink, node1).with_node2(node2)
    }

    /// Sets the local system at I (and at J unless set separately).
    #[must_use]
    pub fn with_axes(mut self, axes1: Rotation) -> Self {
        self.axes1 = axes1;
        self
    }

    /// Sets a separate local system at J.
    #[must_use]
    pub fn with_axes2(mut self, axes2: Rotation) -> Self {
        self.axes2 = Some(axes2);
        self
    }

    /// Places node J at `at` (global, m), for joints whose nodes need not coincide.
    #[must_use]
    pub fn with_node2(mut self, at: Vector) -> Self {
        self.node2 = at;
        self
    }

    /// Sets the constraint method (KEYOPT(2)).
    #[must_use]
    pub fn with_method(mut self, method: ConstraintMethod) -> Self {
        self.method = method;
        self
    }

    /// Adds a stop on a free DOF (`SECSTOP,dof,min,max`; absolute measure, m or rad).
    #[doc(alias = "SECSTOP")]
    #[must_use]
    pub fn with_stop(mut self, dof: Dof, min: Real, max: Real) -> Self {
        self.behaviour.stops.push(Limit { dof, min, max });
        self
    }

    /// Adds a lock on a free DOF (`SECLOCK,dof,min,max`).
    #[doc(alias = "SECLOCK")]
    #[must_use]
    pub fn with_lock(mut self, dof: Dof, min: Real, max: Real) -> Self {
        self.behaviour.locks.push(Limit { dof, min, max });
        self
    }

    /// Sets the linear stiffness matrix (`TB,JOIN,,,,STIF`).
    #[must_use]
    pub fn with_stiffness(mut self, k: Sym6) -> Self {
        self.behaviour.stiffness = Some(k);
        self
    }

    /// Sets the linear damping matrix (`TB,JOIN,,,,DAMP`).
    #[must_use]
    pub fn with_damping(mut self, c: Sym6) -> Self {
        self.behaviour.damping = Some(c);
        self
    }

    /// Sets a nonlinear stiffness table on one DOF (`TB,JOIN,,,,JNSn` with `TBPT` pairs).
    #[must_use]
    pub fn with_stiffness_table(mut self, dof: Dof, table: Table) -> Self {
        self.behaviour.stiffness_tables[dof.index()] = Some(table);
        self
    }

    /// Sets a nonlinear damping table on one DOF (`TB,JOIN,,,,JNDn`).
    #[must_use]
    pub fn with_damping_table(mut self, dof: Dof, table: Table) -> Self {
        self.behaviour.damping_tables[dof.index()] = Some(table);
        self
    }

    /// Sets the joint friction (`TB,JOIN` MUSn / EXPn, `SECJOINT,FRIC`).
    #[doc(alias = "FRIC")]
    #[must_use]
    pub fn with_friction(mut self, friction: Friction) -> Self {
        self.behaviour.friction = Some(friction);
        self
    }

    /// Sets the springs' zero of one DOF (`SECDATA`; absolute measure, m or rad).
    #[doc(alias = "SECDATA")]
    #[must_use]
    pub fn with_reference(mut self, dof: Dof, value: Real) -> Self {
        self.behaviour.reference[dof.index()] = Some(value);
        self
    }

    /// The local system at J.
    pub fn axes2(&self) -> Rotation {
        self.axes2.unwrap_or(self.axes1)
    }

    /// The joint with its grounded sides placed (`ground1`, `ground2`: node I or J on the
    /// ground): the fixed world side sits at the other node's location, so that a grounded
    /// revolute or spherical joint turns about its body's node. A rigid link keeps both nodes
    /// where they are given (the bar's pin on the ground).
    pub(crate) fn grounded(mut self, ground1: bool, ground2: bool) -> Self {
        if matches!(self.kind, JointKind::RigidLink) {
            return self;
        }
        if ground1 {
            self.node1 = self.node2;
        }
        if ground2 {
            self.node2 = self.node1;
        }
        self
    }
}
