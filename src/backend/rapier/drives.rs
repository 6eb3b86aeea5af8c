//! Prescribed relative motion (`DJ`: displacement, velocity or acceleration drives) on the
//! Rapier backends, as close as Rapier's own parts allow:
//!
//! - **during a call**: a velocity motor on the driven axis, force-based with a damping of
//!   `MOTOR_DAMPING` and no force cap, its target the drive's mean rate over the call: a stiff
//!   velocity constraint in Rapier's solver, so the rest of the mechanism feels the driving
//!   force or moment while Rapier steps (Rapier's motor sees only the two bodies' own inertia,
//!   hence the correction after it);
//! - **after the call**: the DOF is put on the drive's value and rate at the call's end through
//!   the joint (the same mass-metric response as a stop's, [`super::stops`]; on multibody the
//!   joint's own coordinate and its rate), so the drive is exact at every step's end to the
//!   other joints' error, which Rapier's next call takes back;
//! - **work**: the drive row's multiplier from the reaction recovery times the prescribed rate,
//!   per step (`RapierBackend::write_reactions`).

use crate::drive::Drive;
use crate::math::Real;
use crate::math::rapier::dynamics::{MotorModel, RigidBodyHandle};
use crate::rows::FramePair;

use super::super::Sets;
use super::stops::{correct, dof_and_constraints, joint_data, rapier_axis, response};
use super::{AXES, RapierBackend};

/// The motor's damping (N s/m or N m s/rad): far above any mechanism's own, so that Rapier's
/// implicit motor holds the rate to its solver's tolerance.
const MOTOR_DAMPING: Real = 1e9;

/// The drive's mean rate over `[t0, t1]` (m/s or rad/s).
pub(super) fn mean_rate(d: &Drive, t0: Real, t1: Real) -> Real {
    (d.value(t1) - d.value(t0)) / (t1 - t0)
}

impl RapierBackend {
    /// Sets every drive's motor for the call over `[t0, t1]`.
    pub(super) fn drive_motors(&self, sets: &mut Sets, t0: Real, t1: Real) {
        let roles = sets.joints.roles();
        for &slot in &roles.drives {
            let Some(e) = sets.joints.get(slot) else {
                continue;
            };
            let settings: Vec<(usize, Real)> = e
                .drives
                .iter()
                .map(|d| (rapier_axis(e, d.dof.index()), mean_rate(d, t0, t1)))
                .collect();
            let rapier = e.rapier;
            if let Some(data) = joint_data(sets.physics, &rapier) {
                for (axis, rate) in settings {
                    data.set_motor_model(AXES[axis], MotorModel::ForceBased);
                    data.set_motor_velocity(AXES[axis], rate, MOTOR_DAMPING);
                    data.set_motor_max_force(AXES[axis], Real::INFINITY);
                }
            }
        }
    }

    /// Puts every driven DOF on its drive's value and rate at `t` (the call's end).
    pub(super) fn drive_positions(&self, sets: &mut Sets, t: Real, span: Real) {
        let roles = sets.joints.roles();
        for &slot in &roles.drives {
            let Some(e) = sets.joints.get(slot) else {
                continue;
            };
            let side = |b: RigidBodyHandle| crate::body::pose_and_com(&sets.physics.bodies[b]);
            let f = FramePair::at(&e.low, side(e.body1), side(e.body2));
            let o = &e.state.output;
            let (m, rows) = crate::behaviour::dof_rows(&f, [o.measure[3], o.measure[5]]);
            let (body1, body2, rapier) = (e.body1, e.body2, e.rapier);
            let vel = [body1, body2].map(|b| self.velocity(sets.physics, b));
            let mut targets = Vec::new();
            for d in &e.drives {
                let k = d.dof.index();
                let q = m[k] - e.initial[k];
                let v = rows[k].rate([vel[0].0, vel[0].1], [vel[1].0, vel[1].1]);
                let rate = mean_rate(d, t - 0.5 * span, t + 0.5 * span);
                let set = dof_and_constraints(e, &rows, k);
                targets.push((set, rapier_axis(e, k), d.value(t) - q, rate - v, rate));
            }
            for (set, axis, dq, dv, rate) in targets {
                if self.multibody() {
                    Self::set_coordinate_rate(sets, rapier, axis, Some(rate), dq);
                    continue;
                }
                let Some((_, unit)) = response(&sets.physics.bodies, [body1, body2], &set) else {
                    continue;
                };
                correct(&mut sets.physics.bodies, [body1, body2], unit, dq, dv);
            }
        }
    }
}
