//! Lowering an MPC184 joint to a Rapier `GenericJoint` (the Rapier backends).
//!
//! One exhaustive `match` decides what each kind becomes; every convention gap is commented:
//!
//! - **Axis.** Rapier's joint frame uses X as the principal axis; MPC184 uses e1 (x variants,
//!   slot, translational, ...) or e3 (z variants, screw). For an e3 kind the Rapier frame is the
//!   joint frame turned so that Rapier (X, Y, Z) = (e3, e1, e2), a cyclic (proper) permutation,
//!   and the ANSYS DOF on axis `a` becomes Rapier axis `(a + 1) % 3`.
//! - **Offset.** Both Rapier frames sit at node J's initial position with frame I's initial axes:
//!   they coincide at time 0, so every Rapier coordinate starts at 0 (multibody forward kinematics
//!   reproduces the initial pose) and a locked axis keeps its initial value. This is MPC184's
//!   rule: a slot keeps `e2I.(xJ - xI) = E2I.(XJ - XI)`, a spherical joint with separate nodes
//!   keeps their relative position, locked rotations keep the initial relative orientation.
//! - **Measures.** Rapier's coordinates are not the ANSYS measures; output (relative
//!   displacement, Bryant angles) is computed by [`crate::kinematics`] from the true frames I and J.
//! - **Rotation locks.** Rapier locks angular axes through quaternion components. That is exact
//!   when zero, two or three rotations are locked (the free axis, if any, stays aligned), but not
//!   for a single locked rotation with two free ones (universal, some general joints), where the
//!   ANSYS constraint is a Bryant angle: such kinds are `Unsupported` on the Rapier backends
//!   (the multibody backend would also panic on two free angular DOFs).
//! - **Rigid link.** A distance `|x_J - x_I| = L` is no set of locked axes. Rapier's nearest
//!   construct, the rope joint (a coupled linear limit), holds only the maximum distance (it
//!   goes slack under compression) and multibody joints ignore coupled axes, so neither is
//!   exact: the rigid link is `Unsupported` on both Rapier backends. On them, model the bar as a
//!   body with spherical joints at its ends.

use crate::catalogue::JointKind;
use crate::dof::{Dof, DofMask};
use crate::error::Error;
use crate::joint::ConstraintMethod;
use crate::math::rapier::dynamics::JointAxesMask;
use crate::math::{Matrix, Rotation, Vector};
pub use crate::settings::Backend;

/// Rapier axis index for the ANSYS frame-I axis `axis` (0 = e1, 1 = e2, 2 = e3) when the kind's
/// principal axis `principal` goes to Rapier's X.
pub const fn rapier_axis(axis: usize, principal: usize) -> usize {
    (axis + 3 - principal) % 3
}

/// The rotation from Rapier's joint axes to frame I axes: Rapier X = `e_principal`,
/// Y = e_(principal+1), Z = e_(principal+2).
pub fn principal_rotation(principal: usize) -> Rotation {
    let e = |i: usize| Vector::AXES[i % 3];
    Rotation::from_mat3(&Matrix::from_cols(
        e(principal),
        e(principal + 1),
        e(principal + 2),
    ))
}

/// The Rapier locked-axes mask of a set of ANSYS DOFs, permuted for `principal`.
pub fn rapier_mask(dofs: DofMask, principal: usize) -> JointAxesMask {
    let mut bits = 0u8;
    for d in dofs.iter() {
        let base = if d.is_rotation() { 3 } else { 0 };
        bits |= 1 << (base + rapier_axis(d.axis(), principal));
    }
    JointAxesMask::from_bits_truncate(bits)
}

/// What a kind becomes on a backend: the locked axes of the Rapier joint (empty on the Lagrange
/// backend, whose Rapier joint only links the bodies' islands), or why it cannot be lowered.
pub fn lower(
    kind: &JointKind,
    method: ConstraintMethod,
    backend: Backend,
) -> Result<JointAxesMask, Error> {
    if backend == Backend::Lagrange {
        return lagrange_support(kind).map(|()| JointAxesMask::empty());
    }
    if let ConstraintMethod::Penalty { .. } = method {
        return Err(Error::Unsupported {
            what: format!(
                "the penalty method (KEYOPT(2) = 1) on the {} backend",
                backend.name()
            ),
            hint: "Rapier joints are hard constraints; use KEYOPT(2) = 0".into(),
        });
    }
    let principal = kind.principal_axis();
    let locked_rotations = kind
        .constrained()
        .iter()
        .filter(|d| d.is_rotation())
        .count();
    match kind {
        // Exactly representable: all translations and 0, 2 or 3 rotations locked, or (spherical,
        // slot, point-in-plane, orient) no single lone rotation lock.
        JointKind::Revolute { .. }
        | JointKind::Slot
        | JointKind::PointInPlane
        | JointKind::Translational
        | JointKind::Cylindrical { .. }
        | JointKind::Planar { .. }
        | JointKind::Weld
        | JointKind::Orient
        | JointKind::Spherical => Ok(rapier_mask(kind.constrained(), principal)),
        JointKind::General { .. } | JointKind::Genb { .. } if locked_rotations != 1 => {
            // Genb's 3-1-3 measure only differs from general when some but not all rotations are
            // locked; with 0, 2 or 3 locked the constraint set is the same.
            if matches!(kind, JointKind::Genb { .. }) && locked_rotations == 2 {
                return Err(unsupported_lone(
                    kind,
                    backend,
                    "two locked 3-1-3 Euler angles",
                ));
            }
            Ok(rapier_mask(kind.constrained(), principal))
        }
        JointKind::General { .. } | JointKind::Genb { .. } | JointKind::Universal => Err(
            unsupported_lone(kind, backend, "one locked rotation with two free ones"),
        ),
        // The coupling UZ = pitch * ROTZ is imposed around each Rapier call
        // (`rapier/screw.rs`); Rapier sees a cylindrical joint about e3.
        JointKind::Screw { .. } => Ok(rapier_mask(kind.constrained(), principal)),
        JointKind::Spotweld => Err(Error::Unsupported {
            what: format!(
                "the spotweld 6x6 spring/damper on the {} backend",
                backend.name()
            ),
            hint: "a spotweld has no rigid rows, only TB,JOIN stiffness; use the Lagrange backend"
                .into(),
        }),
        JointKind::RigidLink => Err(Error::Unsupported {
            what: format!(
                "a rigid link (distance constraint, KEYOPT(1) = 0) on the {} backend",
                backend.name()
            ),
            hint: "Rapier joints lock axes and cannot hold a distance (its rope joint only \
                   bounds it from above); use the Lagrange backend, or model the bar as a body \
                   with spherical joints (KEYOPT(1) = 15) at its ends"
                .into(),
        }),
    }
}

/// The kinds the Lagrange backend imposes today.
fn lagrange_support(kind: &JointKind) -> Result<(), Error> {
    let locked_rotations = kind
        .constrained()
        .iter()
        .filter(|d| d.is_rotation())
        .count();
    match kind {
        JointKind::Genb { .. } if locked_rotations == 1 || locked_rotations == 2 => {
            Err(Error::Unsupported {
                what: "a genb joint locking some but not all of its 3-1-3 Euler angles".into(),
                hint: "the 3-1-3 angles are singular at an aligned start (beta = 0: alpha and \
                       gamma merge, and holding beta locks two rotations), so a partial lock is \
                       ill-posed there; use a general joint (KEYOPT(1) = 16), whose rotation \
                       rows are Bryant angles"
                    .into(),
            })
        }
        JointKind::Revolute { .. }
        | JointKind::Universal
        | JointKind::Slot
        | JointKind::PointInPlane
        | JointKind::Translational
        | JointKind::Cylindrical { .. }
        | JointKind::Planar { .. }
        | JointKind::Weld
        | JointKind::Orient
        | JointKind::Spherical
        | JointKind::General { .. }
        | JointKind::Screw { .. }
        | JointKind::Spotweld
        | JointKind::Genb { .. }
        | JointKind::RigidLink => Ok(()),
    }
}

fn unsupported_lone(kind: &JointKind, backend: Backend, why: &str) -> Error {
    Error::Unsupported {
        what: format!(
            "a {} joint ({why}) on the {} backend",
            kind.name(),
            backend.name()
        ),
        hint: "Rapier locks rotations through quaternion components (exact only when 0, 2 or 3 \
               rotations are locked; its multibody joints panic on two free rotations); use the \
               Lagrange backend, which imposes the Bryant-angle row"
            .into(),
    }
}

/// True if `dof` is a rotation axis of the kind that output should unwrap (free rotations).
pub fn unwraps(kind: &JointKind, dof: Dof) -> bool {
    dof.is_rotation() && kind.free().contains(dof)
}
