//! Stops (`SECSTOP`) and locks (`SECLOCK`) on the Rapier backends: Rapier's own limits on the
//! stopped axes, plus the restitution and the latching Rapier lacks.
//!
//! - **Limits**: each stop is a Rapier limit on its joint axis (impulse and multibody joints
//!   alike), in Rapier's measure: Rapier's joint frames coincide at time 0, so a limit on the
//!   DOF's absolute measure `q` becomes `q - q(0)` there. Rapier keeps the DOF inside; its limit
//!   is plastic: the approach rate is taken out at the contact.
//! - **Restitution** (the Lagrange method's elastic stop, MPC184's energy-momentum handling in
//!   dynamics): around each Rapier call the joint's two bodies' kinetic plus gravitational energy
//!   is taken; when a DOF reached its stop in the call, the energy the plastic limit took is
//!   given back along the stop's own direction, through the joint: the impulse `J^T lambda` on
//!   the stop row and the joint's constrained rows that changes the stop DOF's rate by `delta`
//!   away from the stop and leaves the constrained rows' rates alone (`W lambda = e_stop delta`,
//!   `W = J M^-1 J^T` of those rows on the two bodies), with `delta` the root of
//!   `lambda_0 delta^2 / 2 + (lambda . J v) delta = E_before - E_after`. Energy is then kept
//!   across the impact to the energy error of the call itself, and the momentum the stop's
//!   reaction carries is reversed. The penalty method's stop stays plastic, as on the Lagrange
//!   backend.
//! - **Locks**: a lock reached in a call engages at the call's end: the DOF is put back on the
//!   lock value and its rate taken out through the joint (the same response as above, plastic),
//!   the energy that takes is booked as dissipated (exact whatever the overshoot: the energy
//!   before is the motion's, after it the body rests at the lock value), and from the next call
//!   a Rapier limit closed on the value holds it, from the next step a row holds it for the
//!   reaction recovery, as on the Lagrange backend.
//! - Approximations: the two bodies' energy stands for the mechanism's (exact for a body on a
//!   grounded joint; in a chain the other joints' share of the impact is left to Rapier's next
//!   call), the multibody backend's rate is set on the joint's own generalized coordinate, and
//!   a stop reached at the end of a call is handled at that call.

use crate::behaviour::dof_rows;
use crate::dof::Dof;
use crate::joint::ConstraintMethod;
use crate::joint_set::{JointEntry, RapierJoint};
use crate::math::rapier::dynamics::{GenericJoint, RigidBodyHandle, RigidBodySet};
use crate::math::rapier::pipeline::PhysicsWorld;
use crate::math::{Real, Vector};
use crate::rows::{FramePair, RowEval};
use crate::solver::dense;

use super::super::{Sets, lower};
use super::{AXES, RapierBackend};

/// A stop DOF's state at the start of a Rapier call.
pub(super) struct Approach {
    slot: usize,
    dof: usize,
    /// A lock (`SECLOCK`) not engaged yet, rather than a stop.
    lock: bool,
    /// The DOF's rate (m/s or rad/s).
    rate: Real,
    /// Kinetic plus gravitational energy of the joint's two bodies (J).
    energy: Real,
    /// The power of gravity on them (W).
    power: Real,
}

/// The Rapier joint data of a joint (impulse or multibody link).
pub(super) fn joint_data<'a>(
    physics: &'a mut PhysicsWorld,
    rapier: &RapierJoint,
) -> Option<&'a mut GenericJoint> {
    match *rapier {
        RapierJoint::Impulse(h) => physics
            .impulse_joints
            .get_mut(h, false)
            .map(|j| &mut j.data),
        RapierJoint::Multibody(h) => physics
            .multibody_joints
            .get_mut(h)
            .and_then(|(mb, link)| mb.link_mut(link).map(|l| &mut l.joint.data)),
    }
}

/// The Rapier axis of ANSYS DOF `dof` (0..6) of a joint.
pub(super) fn rapier_axis(e: &JointEntry, dof: usize) -> usize {
    let principal = e.joint.kind.principal_axis();
    let base = if dof >= 3 { 3 } else { 0 };
    base + lower::rapier_axis(dof % 3, principal)
}

impl RapierBackend {
    /// Sets the Rapier limits of every stop (see the module docs), and records each stop DOF's
    /// measure and its joint's energy at the start of the call.
    pub(super) fn approach(&self, sets: &mut Sets) -> Vec<Approach> {
        let mut out = Vec::new();
        let roles = sets.joints.roles();
        for &slot in &roles.limits {
            let Some(e) = sets.joints.get(slot) else {
                continue;
            };
            let b = &e.joint.behaviour;
            if let Some(data) = joint_data(sets.physics, &e.rapier) {
                for s in &b.stops {
                    let k = s.dof.index();
                    let (lo, hi) = (s.min - e.initial[k], s.max - e.initial[k]);
                    data.set_limits(AXES[rapier_axis(e, k)], [lo, hi]);
                }
                // An engaged lock: a Rapier limit closed on its value.
                for l in &b.locks {
                    let k = l.dof.index();
                    if let Some(v) = e.state.locked[k] {
                        data.set_limits(AXES[rapier_axis(e, k)], [v - e.initial[k]; 2]);
                    }
                }
            }
            let (energy, power) = self.local_energy(sets, e);
            let (_, rate) = self.dof_state(sets, e);
            let stops = b.stops.iter().map(|s| (s.dof, false));
            let locks = b
                .locks
                .iter()
                .filter(|l| e.state.locked[l.dof.index()].is_none())
                .map(|l| (l.dof, true));
            for (dof, lock) in stops.chain(locks) {
                out.push(Approach {
                    slot,
                    dof: dof.index(),
                    lock,
                    rate: rate[dof.index()],
                    energy,
                    power,
                });
            }
        }
        out
    }

    /// After a call: marks the DOFs at a stop and gives back, on an elastic stop reached in the
    /// call, the energy the plastic limit took (see the module docs).
    pub(super) fn rebound(&self, sets: &mut Sets, approaches: &[Approach], step: Real) {
        for a in approaches {
            if a.lock {
                self.engage(sets, a);
                continue;
            }
            let Some(Some(e)) = sets.joints.slots().get(a.slot) else {
                continue;
            };
            let Some(stop) = e
                .joint
                .behaviour
                .stops
                .iter()
                .find(|s| s.dof.index() == a.dof)
            else {
                continue;
            };
            let stop = *stop;
            let side = |b: RigidBodyHandle| crate::body::pose_and_com(&sets.physics.bodies[b]);
            let f = FramePair::at(&e.low, side(e.body1), side(e.body2));
            let o = &e.state.output;
            let (m, rows) = dof_rows(&f, [o.measure[3], o.measure[5]]);
            let (_, rate) = self.dof_state(sets, e);
            let (q, v) = (m[a.dof], rate[a.dof]);
            // At a stop: within a thousandth of the range (Rapier's limit holds the DOF a
            // little short of it). Reached in this call: it approached that limit, is now
            // within a hundredth of the range of it, and the limit took the approach rate.
            let span = (stop.max - stop.min).abs().max(1e-3);
            let at_min = q <= stop.min + 1e-3 * span;
            let at_max = q >= stop.max - 1e-3 * span;
            let near_min = q <= stop.min + 1e-2 * span;
            let near_max = q >= stop.max - 1e-2 * span;
            let reached_min = a.rate < 0.0 && near_min && v >= 0.1 * a.rate;
            let reached_max = a.rate > 0.0 && near_max && v <= 0.1 * a.rate;
            let reached = reached_min || reached_max;
            // What the plastic limit took, less what keeps the integrator's own conserved
            // energy `H + h P / 2` (symplectic Euler, `P` the power of gravity, `h` the
            // integration step) across the reversal: with the rate reversed, `P` changes sign,
            // so `H` itself must come back `h |P|` lower (restoring `H` in full gained 0.024 J
            // per impact on the stop pendulum, 1.2 % of its energy).
            let lost = a.energy - self.local_energy(sets, e).0 + step * a.power;
            let elastic = !matches!(e.joint.method, ConstraintMethod::Penalty { .. });
            let (body1, body2, rapier) = (e.body1, e.body2, e.rapier);
            let axis = rapier_axis(e, a.dof);
            let set = dof_and_constraints(e, &rows, a.dof);
            if let Some(Some(e)) = sets.joints.slots_mut().get_mut(a.slot) {
                e.state.at_stop[a.dof] = at_min || at_max || reached;
            }
            if !(reached && elastic && lost > 0.0) {
                continue;
            }
            let away: Real = if reached_min { 1.0 } else { -1.0 };
            // How far the DOF went past the stop (Rapier's limit slop), taken back so that
            // Rapier's position correction does not push the body out with energy of its own.
            let past = if reached_min {
                (q - stop.min).min(0.0)
            } else {
                (q - stop.max).max(0.0)
            };
            if self.multibody() {
                Self::rebound_multibody(sets, rapier, axis, lost, away, past);
                continue;
            }
            let Some((m_eff, unit)) = response(&sets.physics.bodies, [body1, body2], &set) else {
                continue;
            };
            // m_eff d^2 / 2 + p d = lost with p = m_eff v (the stop row's rate now; the other
            // rows' rates are kept), d with the sign `away`.
            let p = m_eff * v;
            let d = away * ((p * p + 2.0 * m_eff * lost).sqrt() - away * p) / m_eff;
            correct(&mut sets.physics.bodies, [body1, body2], unit, -past, d);
        }
    }

    /// A lock reached in the call engages: the DOF is put back on the lock value and its
    /// rate taken out through the joint (plastic, as MPC184's lock), the energy that took is
    /// booked as dissipated, and the DOF is held there for good (a Rapier limit closed on the
    /// value from the next call, a row for the reactions from the next step).
    fn engage(&self, sets: &mut Sets, a: &Approach) {
        let Some(Some(e)) = sets.joints.slots().get(a.slot) else {
            return;
        };
        let Some(lock) = e
            .joint
            .behaviour
            .locks
            .iter()
            .find(|l| l.dof.index() == a.dof)
        else {
            return;
        };
        let lock = *lock;
        let (m, rate) = self.dof_state(sets, e);
        let (q, v) = (m[a.dof], rate[a.dof]);
        let value = if q <= lock.min {
            lock.min
        } else if q >= lock.max {
            lock.max
        } else {
            return;
        };
        let before = self.local_energy(sets, e).0;
        let (body1, body2, rapier) = (e.body1, e.body2, e.rapier);
        let axis = rapier_axis(e, a.dof);
        let side = |b: RigidBodyHandle| crate::body::pose_and_com(&sets.physics.bodies[b]);
        let f = FramePair::at(&e.low, side(body1), side(body2));
        let (_, rows) = dof_rows(&f, [e.state.output.measure[3], e.state.output.measure[5]]);
        let set = dof_and_constraints(e, &rows, a.dof);
        let past = q - value;
        if self.multibody() {
            Self::set_coordinate_rate(sets, rapier, axis, None, -past);
        } else if let Some((_, unit)) = response(&sets.physics.bodies, [body1, body2], &set) {
            correct(&mut sets.physics.bodies, [body1, body2], unit, -past, -v);
        }
        let Some(Some(e)) = sets.joints.slots().get(a.slot) else {
            return;
        };
        let after = self.local_energy(sets, e).0;
        sets.ledger.dissipated += before - after;
        if let Some(Some(e)) = sets.joints.slots_mut().get_mut(a.slot) {
            e.state.locked[a.dof] = Some(value);
            e.state.pending.push((lock.dof, value));
        }
    }

    /// The joint's six DOF measures (with the output's unwrapping) and rates now.
    fn dof_state(&self, sets: &Sets, e: &JointEntry) -> ([Real; 6], [Real; 6]) {
        let side = |b: RigidBodyHandle| crate::body::pose_and_com(&sets.physics.bodies[b]);
        let f = FramePair::at(&e.low, side(e.body1), side(e.body2));
        let o = &e.state.output;
        let (m, rows) = dof_rows(&f, [o.measure[3], o.measure[5]]);
        let vel = [e.body1, e.body2].map(|b| self.velocity(sets.physics, b));
        let rate =
            core::array::from_fn(|k| rows[k].rate([vel[0].0, vel[0].1], [vel[1].0, vel[1].1]));
        (m, rate)
    }

    /// Kinetic plus gravitational energy of a joint's two bodies (J), and the power of gravity
    /// on them (W).
    fn local_energy(&self, sets: &Sets, e: &JointEntry) -> (Real, Real) {
        let g = sets.physics.gravity;
        let (mut total, mut power) = (0.0, 0.0);
        for b in [e.body1, e.body2] {
            let rb = &sets.physics.bodies[b];
            if !rb.is_dynamic() {
                continue;
            }
            let (v, w) = self.velocity(sets.physics, b);
            let weight = g * (rb.mass() * rb.gravity_scale());
            total += 0.5 * rb.mass() * v.length_squared() + crate::body::rotational_energy(rb, w)
                - weight.dot(com(rb));
            power += weight.dot(v);
        }
        (total, power)
    }

    /// The multibody backend: sets the generalized velocity of the joint's coordinate on
    /// Rapier axis `axis` (to `rate`, or to 0 with `None`) and moves that coordinate by `disp`.
    pub(super) fn set_coordinate_rate(
        sets: &mut Sets,
        rapier: RapierJoint,
        axis: usize,
        rate: Option<Real>,
        disp: Real,
    ) {
        let RapierJoint::Multibody(h) = rapier else {
            return;
        };
        let Some((mb, link)) = sets.physics.multibody_joints.get_mut(h) else {
            return;
        };
        let Some(l) = mb.link(link) else {
            return;
        };
        let Some(index) = coordinate_index(l, axis) else {
            return;
        };
        let n = mb.generalized_velocity().len();
        if index >= n {
            return;
        }
        mb.generalized_velocity_mut()[index] = rate.unwrap_or(0.0);
        if disp != 0.0 {
            let mut d = vec![0.0 as Real; n];
            d[index] = disp;
            displace_multibody(mb, &mut sets.physics.bodies, &d);
        }
    }

    /// The multibody backend: the joint's own generalized velocity (Rapier axis `axis` of
    /// the link of `rapier`) gets the rate that gives back `lost`, with the kinetic energy
    /// `K(q' + d e_i) = K + a d + b d^2` taken from the links' Jacobians.
    fn rebound_multibody(
        sets: &mut Sets,
        rapier: RapierJoint,
        axis: usize,
        lost: Real,
        away: Real,
        past: Real,
    ) {
        let RapierJoint::Multibody(h) = rapier else {
            return;
        };
        let bodies = &sets.physics.bodies;
        let Some((mb, link)) = sets.physics.multibody_joints.get_mut(h) else {
            return;
        };
        let Some(l) = mb.link(link) else {
            return;
        };
        let Some(index) = coordinate_index(l, axis) else {
            return;
        };
        let qd = mb.generalized_velocity().clone_owned();
        if index >= qd.len() {
            return;
        }
        let (mut a, mut b) = (0.0 as Real, 0.0 as Real);
        for (li, link) in mb.links().enumerate() {
            let rb = &bodies[link.rigid_body_handle()];
            let jac = mb.body_jacobian(li);
            if jac.ncols() != qd.len() || jac.nrows() != 6 {
                return;
            }
            let v = jac * &qd;
            let col = |r: usize| jac[(r, index)];
            let (vl, va) = (Vector::new(v[0], v[1], v[2]), Vector::new(v[3], v[4], v[5]));
            let (cl, ca) = (
                Vector::new(col(0), col(1), col(2)),
                Vector::new(col(3), col(4), col(5)),
            );
            let inertia = crate::body::world_inertia(rb);
            a += rb.mass() * vl.dot(cl) + va.dot(inertia * ca);
            b += 0.5 * (rb.mass() * cl.length_squared() + ca.dot(inertia * ca));
        }
        if b <= 0.0 {
            return;
        }
        // b d^2 + a d = lost, d with the sign `away`.
        let d = away * ((a * a + 4.0 * b * lost).sqrt() - away * a) / (2.0 * b);
        mb.generalized_velocity_mut()[index] += d;
        if past != 0.0 {
            let mut disp = vec![0.0 as Real; qd.len()];
            disp[index] = -past;
            displace_multibody(mb, &mut sets.physics.bodies, &disp);
        }
    }
}

/// The two bodies' velocity changes `(dv, dw)` per unit change of the first of `rows` (the
/// stop) that leave the others' rates alone, with the stop's effective mass `m_eff` (see the
/// module docs); `None` when the rows are degenerate.
pub(super) fn response(
    bodies: &RigidBodySet,
    pair: [RigidBodyHandle; 2],
    rows: &[RowEval],
) -> Option<(Real, [(Vector, Vector); 2])> {
    let n = rows.len();
    // M^-1 per body (linear, world angular); zero for fixed bodies.
    let inv: Vec<(Real, crate::math::Matrix)> = pair
        .iter()
        .map(|&b| {
            let rb = &bodies[b];
            if rb.is_dynamic() {
                (1.0 / rb.mass(), crate::body::world_inertia(rb).inverse())
            } else {
                (0.0, crate::math::Matrix::ZERO)
            }
        })
        .collect();
    let half = |r: &RowEval, k: usize| if k == 0 { r.j1 } else { r.j2 };
    // M^-1 J_i^T per body.
    let mj: Vec<[(Vector, Vector); 2]> = rows
        .iter()
        .map(|r| core::array::from_fn(|k| (half(r, k)[0] * inv[k].0, inv[k].1 * half(r, k)[1])))
        .collect();
    let mut w = vec![0.0 as Real; n * n];
    for i in 0..n {
        for j in 0..n {
            w[i * n + j] = (0..2)
                .map(|k| {
                    half(&rows[i], k)[0].dot(mj[j][k].0) + half(&rows[i], k)[1].dot(mj[j][k].1)
                })
                .sum();
        }
    }
    let mut lambda = vec![0.0 as Real; n];
    lambda[0] = 1.0;
    dense::cholesky_solve_dropping(&mut w, &mut lambda, n);
    let m_eff = lambda[0];
    if !(m_eff.is_finite() && m_eff > 0.0) {
        return None;
    }
    let unit = core::array::from_fn(|k| {
        (0..n).fold((Vector::ZERO, Vector::ZERO), |acc, i| {
            (
                acc.0 + mj[i][k].0 * lambda[i],
                acc.1 + mj[i][k].1 * lambda[i],
            )
        })
    });
    Some((m_eff, unit))
}

/// Moves a dynamic body's centre of mass by `dl` and turns it by the rotation vector `da`
/// about it.
fn displace(bodies: &mut RigidBodySet, b: RigidBodyHandle, dl: Vector, da: Vector) {
    let rb = &mut bodies[b];
    if !rb.is_dynamic() {
        return;
    }
    let pose = *rb.position();
    let com = com(rb);
    let turn = crate::math::Rotation::from_scaled_axis(da);
    let origin = com + dl + turn * (pose.translation - com);
    let rotation = (turn * pose.rotation).normalize();
    rb.set_position(crate::math::Pose::from_parts(origin, rotation), true);
}

/// A body's centre of mass from its pose (Rapier's own world centre of mass is only brought up
/// to date at its next step, and the latching moves bodies between steps).
fn com(rb: &crate::math::rapier::dynamics::RigidBody) -> Vector {
    *rb.position() * rb.mass_properties().local_mprops.local_com
}

/// The index among a multibody's generalized coordinates of Rapier axis `axis` of a link's
/// joint (its coordinates follow its free axes in order); `None` for a locked axis.
fn coordinate_index(
    l: &crate::math::rapier::dynamics::MultibodyLink,
    axis: usize,
) -> Option<usize> {
    let free_axes = !l.joint.data.locked_axes.bits() & 0x3f;
    (free_axes & (1 << axis) != 0)
        .then(|| l.assembly_id() + (0..axis).filter(|a| free_axes & (1 << a) != 0).count())
}

/// Moves a multibody's coordinates by `disp` and puts its links' bodies at their new poses
/// (Rapier would only at its next step).
pub(super) fn displace_multibody(
    mb: &mut crate::math::rapier::dynamics::Multibody,
    bodies: &mut RigidBodySet,
    disp: &[Real],
) {
    mb.apply_displacements(disp);
    mb.forward_kinematics(bodies, false);
    for l in mb.links() {
        if let Some(rb) = bodies.get_mut(l.rigid_body_handle()) {
            rb.set_position(*l.local_to_world(), true);
        }
    }
}

/// The row of DOF `dof` followed by the joint's constrained DOF rows: the set whose response
/// changes that DOF's rate and leaves the joint's constraints alone.
pub(super) fn dof_and_constraints(e: &JointEntry, rows: &[RowEval; 6], dof: usize) -> Vec<RowEval> {
    let free = e.joint.kind.free();
    core::iter::once(rows[dof])
        .chain(
            (0..6)
                .filter(|&k| !free.contains(Dof::ALL[k]))
                .map(|k| rows[k]),
        )
        .collect()
}

/// Moves the two bodies by `unit` times `position` and changes their velocities by `unit` times
/// `rate` (`unit`: a [`response`] per unit change of its row).
pub(super) fn correct(
    bodies: &mut RigidBodySet,
    pair: [RigidBodyHandle; 2],
    unit: [(Vector, Vector); 2],
    position: Real,
    rate: Real,
) {
    for (b, (dl, da)) in pair.into_iter().zip(unit) {
        displace(bodies, b, dl * position, da * position);
        let rb = &mut bodies[b];
        if rb.is_dynamic() {
            let (lin, ang) = (rb.linvel() + dl * rate, rb.angvel() + da * rate);
            rb.set_linvel(lin, true);
            rb.set_angvel(ang, true);
        }
    }
}
