//! Work done on the bodies that no backend books, per step: the persistent user forces and
//! torques on dynamic bodies (ANSYS nodal `F`, a game's `add_force`), and kinematic bodies
//! pushing through the joints. Gravity that changes in time is booked where it changes
//! ([`crate::Mpc184World::set_gravity`]); joint loads, drives, springs and dampers are booked
//! by the backends.
//!
//! - A user force `F` and torque `tau` held over the step (Rapier keeps them between steps;
//!   they change only between steps) do `F . (c_1 - c_0) + tau . theta`, `c` the centre of
//!   mass at the step's ends and `theta` the rotation vector of `q_1 q_0^-1`: exact for the
//!   force whatever the integrator, and for the torque to second order in the step's rotation.
//! - A kinematic body pushes the dynamic ones through its joints with the opposite of the
//!   joint's reaction on it: power `-(F_k . v_k(p_J) + M_k . w_k)` with `F_k`, `M_k` the
//!   joint's force and moment on the kinematic side at node J, booked as that power at the
//!   step's end times `dt` (the reaction of the last substep: first order in the step).

use crate::joint_set::JointSet;
use crate::math::rapier::dynamics::{RigidBodyHandle, RigidBodySet};
use crate::math::{Real, Rotation, Vector};

/// The bodies a step's external work is measured on, as the step starts.
#[derive(Default)]
pub(crate) struct StepStart {
    /// Dynamic bodies with a user force or torque: the force, the torque, the centre of mass
    /// and the rotation at the start.
    forced: Vec<(RigidBodyHandle, Vector, Vector, Vector, Rotation)>,
    /// Some body is kinematic (else no joint pushes: the joints are not visited).
    kinematic: bool,
}

impl StepStart {
    /// Records the forced bodies, and whether any body is kinematic.
    pub(crate) fn record(bodies: &RigidBodySet) -> StepStart {
        let mut start = StepStart::default();
        for (h, rb) in bodies.iter() {
            start.kinematic |= rb.is_kinematic();
            if rb.is_dynamic()
                && (rb.user_force() != Vector::ZERO || rb.user_torque() != Vector::ZERO)
            {
                start.forced.push((
                    h,
                    rb.user_force(),
                    rb.user_torque(),
                    rb.center_of_mass(),
                    rb.position().rotation,
                ));
            }
        }
        start
    }

    /// The work of the user forces over the step that ended now, plus the work of the
    /// kinematic bodies through the joints over `dt` (J).
    pub(crate) fn work(&self, bodies: &RigidBodySet, joints: &JointSet, dt: Real) -> Real {
        let mut w = 0.0;
        for &(h, f, tau, c0, q0) in &self.forced {
            let Some(rb) = bodies.get(h) else { continue };
            let turn = crate::math::turn_between(q0, rb.position().rotation);
            w += f.dot(rb.center_of_mass() - c0) + tau.dot(turn);
        }
        if !self.kinematic {
            return w;
        }
        for e in joints.iter() {
            let kinematic = [e.body1, e.body2].map(|b| bodies[b].is_kinematic());
            if !kinematic.contains(&true) {
                continue;
            }
            let (force, moment, node_j) = e.reaction_world(bodies);
            // The joint's wrench on body 2 at node J, and the opposite on body 1.
            for (k, b) in [e.body1, e.body2].into_iter().enumerate() {
                if !kinematic[k] {
                    continue;
                }
                let sign = if k == 1 { 1.0 } else { -1.0 };
                let rb = &bodies[b];
                let v = rb.linvel() + rb.angvel().cross(node_j - rb.center_of_mass());
                w -= sign * (force.dot(v) + moment.dot(rb.angvel())) * dt;
            }
        }
        w
    }
}
