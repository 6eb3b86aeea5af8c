//! Helpers on Rapier bodies that every layer above uses: world inertia, the mass checks a
//! jointed body must pass, and the set-up a body gets when it joins a joint.

use crate::math::rapier::dynamics::{LockedAxes, RigidBody, RigidBodyHandle, RigidBodySet};
use crate::math::rapier::geometry::ColliderSet;
use crate::math::{Matrix, Pose, Real, Rotation, Vector};

/// World inertia tensor of a body at its current pose (kg m^2).
pub(crate) fn world_inertia(rb: &RigidBody) -> Matrix {
    inertia_at(rb, rb.position())
}

/// World inertia tensor of a body at `pose` (kg m^2).
pub(crate) fn inertia_at(rb: &RigidBody, pose: &Pose) -> Matrix {
    let mp = &rb.mass_properties().local_mprops;
    let r = Matrix::from_quat(pose.rotation * mp.principal_inertia_local_frame);
    let ip = mp.principal_inertia();
    r * Matrix::from_diagonal(ip) * r.transpose()
}

/// A body's principal axes in the world at its current pose and its principal moments
/// (kg m^2): `I = q diag(moments) q^-1`.
fn principal(rb: &RigidBody) -> (Rotation, Vector) {
    let mp = &rb.mass_properties().local_mprops;
    (
        rb.position().rotation * mp.principal_inertia_local_frame,
        mp.principal_inertia(),
    )
}

/// A body's angular momentum `I w` about its centre of mass at its current pose (kg m^2/s), `w`
/// in rad/s in the world frame: turned into the principal frame and back, without building
/// the world inertia tensor ([`world_inertia`] costs two 3x3 products).
pub(crate) fn angular_momentum(rb: &RigidBody, w: Vector) -> Vector {
    let (q, moments) = principal(rb);
    // Equal moments: the same inertia in every frame, no turn there and back.
    if isotropic(moments) {
        return moments.x * w;
    }
    q * (moments * (q.inverse() * w))
}

/// A body's rotational kinetic energy `w . I w / 2` at its current pose (J), `w` in rad/s in
/// the world frame (see [`angular_momentum`]).
pub(crate) fn rotational_energy(rb: &RigidBody, w: Vector) -> Real {
    let (q, moments) = principal(rb);
    if isotropic(moments) {
        return 0.5 * moments.x * w.length_squared();
    }
    let wl = q.inverse() * w;
    0.5 * (moments * wl).dot(wl)
}

/// A body's largest radius of gyration about its centre of mass, `sqrt(I_max / m)` (m); `None`
/// for a body without mass.
pub(crate) fn gyration_radius(rb: &RigidBody) -> Option<Real> {
    let ip = rb.mass_properties().local_mprops.principal_inertia();
    (rb.mass() > 0.0).then(|| (ip.max_element() / rb.mass()).sqrt())
}

/// A body's pose and centre of mass, the pair [`crate::rows::FramePair::at`] takes.
pub(crate) fn pose_and_com(rb: &RigidBody) -> (Pose, Vector) {
    (*rb.position(), rb.center_of_mass())
}

/// The body's pose and velocities are finite.
pub(crate) fn is_finite(rb: &RigidBody) -> bool {
    let p = rb.position();
    p.translation.is_finite()
        && p.rotation.is_finite()
        && rb.linvel().is_finite()
        && rb.angvel().is_finite()
}

/// Why a dynamic body cannot take part in a joint: no (or a non-finite) mass, or a singular
/// inertia, on axes that are not locked. Fixed and kinematic bodies are always fine.
pub(crate) fn mass_defect(rb: &RigidBody) -> Option<String> {
    if !rb.is_dynamic() {
        return None;
    }
    let locked = rb.locked_axes();
    let mp = &rb.mass_properties().local_mprops;
    let translations = LockedAxes::TRANSLATION_LOCKED_X
        | LockedAxes::TRANSLATION_LOCKED_Y
        | LockedAxes::TRANSLATION_LOCKED_Z;
    let has_mass = mp.inv_mass.is_finite() && mp.inv_mass > 0.0;
    if !(has_mass || locked.contains(translations)) {
        return Some(format!(
            "a dynamic body with mass {} kg: give it mass, or make it fixed",
            mp.mass()
        ));
    }
    let rotations = LockedAxes::ROTATION_LOCKED_X
        | LockedAxes::ROTATION_LOCKED_Y
        | LockedAxes::ROTATION_LOCKED_Z;
    let inv = mp.inv_principal_inertia;
    let regular = inv.is_finite() && inv.min_element() > 0.0;
    if !(regular || locked.intersects(rotations)) {
        return Some(format!(
            "a dynamic body with a singular inertia (principal moments {} kg m^2): give it \
             rotary inertia about every axis, lock the rotation, or make it fixed",
            mp.principal_inertia()
        ));
    }
    None
}

/// Whether the principal moments `moments` are equal (a sphere, a cube, a point mass given
/// isotropic rotary inertia): the inertia is the same about every axis and the gyroscopic term
/// `w x I w` is zero at every velocity.
pub(crate) fn isotropic(moments: Vector) -> bool {
    moments.x == moments.y && moments.y == moments.z
}

/// Prepares a body that a joint now connects: its mass properties filled in now (Rapier does it
/// lazily at the first step; the energies, the reaction recovery and the initial output need
/// them), and on a dynamic body Rapier's own gyroscopic term off and no angular-velocity cap:
/// the Lagrange backend integrates `-w x Iw` itself (implicit midpoint), multibody links get it
/// from the multibody dynamics, and the Rapier impulse backend turns Rapier's own back on
/// (its reaction recovery balances angular momentum, which the term does not change).
pub(crate) fn join(bodies: &mut RigidBodySet, colliders: &ColliderSet, h: RigidBodyHandle) {
    let rb = &mut bodies[h];
    rb.recompute_mass_properties_from_colliders(colliders);
    if rb.is_dynamic() {
        rb.enable_gyroscopic_forces(false);
        rb.set_allow_fast_rotation(true);
    }
}
