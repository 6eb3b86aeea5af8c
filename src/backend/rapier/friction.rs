//! Joint friction on the Rapier backends (an approximation): a velocity motor with target 0 on
//! the friction axis, force-based, very high damping, its force capped at `mu N` with the normal
//! force `N` from the joint's reactions of the previous step (recovered by momentum balance) and
//! `mu` at the previous relative rate. Rapier's motor sees only the bodies' own inertia and the
//! cap lags a step; `tests/friction_incline.rs` measures the difference to the exact stick/slip
//! of the Lagrange backend.

use crate::behaviour::Friction;
use crate::catalogue::JointKind;
use crate::joint::Mpc184Joint;
use crate::joint_set::RapierJoint;
use crate::math::rapier::dynamics::MotorModel;

use super::super::{Sets, lower};
use super::AXES;

/// True when the joint's friction is one a Rapier motor approximates: a joint with a single
/// friction DOF (revolute, slot, translational), not a screw.
pub(crate) fn fits(joint: &Mpc184Joint) -> bool {
    Friction::dofs(&joint.kind).is_some_and(|d| d.len() == 1)
        && !matches!(joint.kind, JointKind::Screw { .. })
}

/// Sets each friction joint's motor for the coming step (see the module docs).
pub(crate) fn set_motors(sets: &mut Sets) {
    let roles = sets.joints.roles();
    let physics = &mut *sets.physics;
    for e in roles.friction.iter().filter_map(|&j| sets.joints.get(j)) {
        let Some(fr) = &e.joint.behaviour.friction else {
            continue;
        };
        let Some(&[dof]) = Friction::dofs(&e.joint.kind) else {
            continue;
        };
        let o = &e.state.output;
        let l = [
            o.force.x, o.force.y, o.force.z, o.moment.x, o.moment.y, o.moment.z,
        ];
        let rate = if dof.is_rotation() {
            o.angular_velocity[dof.index() - 3]
        } else {
            o.velocity[dof.index()]
        };
        let mut cap = fr.law.mu(rate) * fr.normal(&e.joint.kind, &l);
        if let Some(m) = fr.max_force {
            cap = cap.min(m);
        }
        let principal = e.joint.kind.principal_axis();
        let base = if dof.is_rotation() { 3 } else { 0 };
        let axis = AXES[base + lower::rapier_axis(dof.axis(), principal)];
        let data = match e.rapier {
            RapierJoint::Impulse(h) => physics
                .impulse_joints
                .get_mut(h, false)
                .map(|j| &mut j.data),
            RapierJoint::Multibody(h) => physics
                .multibody_joints
                .get_mut(h)
                .and_then(|(mb, link)| mb.link_mut(link).map(|l| &mut l.joint.data)),
        };
        if let Some(data) = data {
            data.set_motor_model(axis, MotorModel::ForceBased);
            data.set_motor_velocity(axis, 0.0, 1e9);
            data.set_motor_max_force(axis, cap.max(0.0));
        }
    }
}
