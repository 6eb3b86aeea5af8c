//! Forces this crate adds around each Rapier call on the Rapier backends: the spring-dampers
//! ([`crate::spring`]) and the applied joint loads (`FJ`), as user forces on the bodies for the
//! length of the call, taken off again after it (Rapier keeps user forces between steps).
//!
//! - A spring is evaluated at its points moved on by `(n - 1) / (2 n)` of the call at their
//!   current velocities (`n` Rapier substeps in the call): with a force held over the call, that
//!   makes a linear spring's step map area-preserving (see [`crate::spring`]).
//! - A joint load is the generalised force on its DOF, `J^T f` with the DOF's own rows
//!   ([`crate::behaviour::dof_rows`]) at the call's start, the value just after the call's
//!   start time (a stepped load acts from its first call). Its work over the call is booked at
//!   the rates of the call's start: first order in the call, as the force is.
//! - A joint's springs and dampers (`TB,JOIN` STIF, DAMP, JNS, JND; [`Behaviour::forces`]) act
//!   the same way on its free DOFs: the springs at the deflection moved on by the same lead as
//!   the spring-dampers (a linear spring's step map is then area-preserving: its frequency is
//!   off by `(omega dt)^2 / 24` only), the dampers at the rates of the call's start, their
//!   dissipation booked at those rates. Explicit, like the Lagrange backend's: stable while
//!   `omega dt < 2` per DOF, with `dt` the whole Rapier call (the step on the impulse backend,
//!   the substep on the multibody one).
//!
//! [`Behaviour::forces`]: crate::behaviour::Behaviour::forces

use crate::behaviour::dof_rows;
use crate::dof::Dof;
use crate::math::rapier::dynamics::MotorModel;
use crate::math::rapier::dynamics::RigidBodyHandle;
use crate::math::{Real, Vector};
use crate::rows::FramePair;
use crate::spring::Side;

use super::super::Sets;
use super::{AXES, RapierBackend};

/// The DOFs whose linear spring is too stiff for a force held over a call of `span` s:
/// `K span^2 > m_eff` (`omega span > 1`, half the explicit limit) with `m_eff` the DOF's
/// effective mass through the joint. Only an uncoupled diagonal term without a table qualifies
/// (Rapier's motor acts on one axis): `(dof, K, C)` with `C` the diagonal damping.
fn stiff_dofs(
    sets: &Sets,
    e: &crate::joint_set::JointEntry,
    rows: &[crate::rows::RowEval; 6],
    span: Real,
) -> Vec<(usize, Real, Real)> {
    let b = &e.joint.behaviour;
    let Some(kmat) = &b.stiffness else {
        return Vec::new();
    };
    let free = e.joint.kind.free();
    let mut out = Vec::new();
    for k in 0..6 {
        let kk = kmat.get(k, k);
        let uncoupled =
            (0..6).all(|j| j == k || !free.contains(Dof::ALL[j]) || kmat.get(k, j) == 0.0);
        if !free.contains(Dof::ALL[k]) || kk <= 0.0 || !uncoupled || b.stiffness_tables[k].is_some()
        {
            continue;
        }
        let set = super::stops::dof_and_constraints(e, rows, k);
        let Some((m_eff, _)) =
            super::stops::response(&sets.physics.bodies, [e.body1, e.body2], &set)
        else {
            continue;
        };
        if kk * span * span > m_eff {
            let cc = b.damping.as_ref().map_or(0.0, |c| c.get(k, k));
            out.push((k, kk, cc));
        }
    }
    out
}

/// The bodies' own user force and torque, to put back after the call.
pub(super) type Held = Vec<(RigidBodyHandle, Vector, Vector)>;

impl RapierBackend {
    /// Adds the springs' and the joint loads' forces for a call of `n` Rapier substeps spanning
    /// `span` s from time `t`, books the dampers' and loads' work, and returns what to put back.
    pub(super) fn apply_forces(&self, sets: &mut Sets, span: Real, n: usize, t: Real) -> Held {
        let mut held = Held::new();
        let lead = span * (n.max(1) - 1) as Real / (2 * n.max(1)) as Real;
        let mut wrenches: Vec<(RigidBodyHandle, Vector, Vector)> = Vec::new();
        for (_, e) in sets.springs.iter() {
            let sides = e.bodies.map(|b| {
                let mut s = Side::of(&sets.physics.bodies, b);
                (s.linvel, s.angvel) = self.velocity(sets.physics, b);
                s.ahead(lead)
            });
            let ev = e.eval(sides);
            sets.ledger.dissipated += ev.damper * ev.output.rate * span;
            for (k, side) in sides.iter().enumerate() {
                let (f, tq) = ev.wrench(k, side.com, ev.output.force);
                wrenches.push((e.bodies[k], f, tq));
            }
        }
        let mut element = Vec::new();
        let mut motors = Vec::new();
        let roles = sets.joints.roles();
        for &ji in &roles.forces {
            let Some(e) = sets.joints.get(ji) else {
                continue;
            };
            let b = &e.joint.behaviour;
            let side = |b: RigidBodyHandle| crate::body::pose_and_com(&sets.physics.bodies[b]);
            let f = FramePair::at(&e.low, side(e.body1), side(e.body2));
            let o = &e.state.output;
            let (m, rows) = dof_rows(&f, [o.measure[3], o.measure[5]]);
            let vel = [e.body1, e.body2].map(|b| self.velocity(sets.physics, b));
            let rate: [Real; 6] =
                core::array::from_fn(|k| rows[k].rate([vel[0].0, vel[0].1], [vel[1].0, vel[1].1]));
            // Springs at the deflection `lead` ahead (as the spring-dampers), dampers at the
            // rates of the call's start.
            let x: [Real; 6] = core::array::from_fn(|k| {
                m[k] - b.reference[k].unwrap_or(e.initial[k]) + lead * rate[k]
            });
            let mut forces = b.forces(&x, &rate, e.joint.kind.free());
            // Springs too stiff for a force held over the call become Rapier motors.
            for (k, kk, cc) in stiff_dofs(sets, e, &rows, span) {
                forces.spring[k] += kk * x[k];
                forces.damper[k] += cc * rate[k];
                let target = b.reference[k].unwrap_or(e.initial[k]) - e.initial[k];
                motors.push((e.rapier, super::stops::rapier_axis(e, k), target, kk, cc));
                sets.ledger.dissipated += cc * rate[k] * rate[k] * span;
            }
            let mut total: [Real; 6] =
                core::array::from_fn(|k| forces.spring[k] + forces.damper[k]);
            for (d, r) in forces.damper.iter().zip(&rate) {
                sets.ledger.dissipated -= d * r * span;
            }
            for d in &e.loads {
                let value = d.profile.value_after(t);
                sets.ledger.work += value * rate[d.dof.index()] * span;
                total[d.dof.index()] += value;
            }
            for (k, row) in rows.iter().enumerate() {
                if total[k] != 0.0 {
                    wrenches.push((e.body1, row.j1[0] * total[k], row.j1[1] * total[k]));
                    wrenches.push((e.body2, row.j2[0] * total[k], row.j2[1] * total[k]));
                }
            }
            element.push((ji, total));
        }
        for (rapier, axis, target, stiffness, damping) in motors {
            if let Some(data) = super::stops::joint_data(sets.physics, &rapier) {
                let axis = AXES[axis];
                data.set_motor_model(axis, MotorModel::ForceBased);
                data.set_motor(axis, target, 0.0, stiffness, damping);
            }
        }
        for (ji, total) in element {
            if let Some(Some(e)) = sets.joints.slots_mut().get_mut(ji) {
                e.state.output.element_force = total;
            }
        }
        for (b, f, tq) in wrenches {
            let rb = &mut sets.physics.bodies[b];
            if !rb.is_dynamic() {
                continue;
            }
            if !held.iter().any(|(h, _, _)| *h == b) {
                held.push((b, rb.user_force(), rb.user_torque()));
            }
            rb.add_force(f, true);
            rb.add_torque(tq, true);
        }
        held
    }
}

/// Puts back the bodies' own user forces after a call.
pub(super) fn release(sets: &mut Sets, held: Held) {
    for (b, f, t) in held {
        let rb = &mut sets.physics.bodies[b];
        rb.reset_forces(false);
        rb.reset_torques(false);
        rb.add_force(f, false);
        rb.add_torque(t, false);
    }
}
