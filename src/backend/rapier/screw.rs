//! The screw coupling (`UZ = pitch * ROTZ`, KEYOPT(1) = 17) on the Rapier backends: Rapier has
//! no joint that couples a translation to a rotation, so a screw is lowered to a cylindrical
//! joint about e3 and the coupling is imposed after every Rapier call by a projection in the
//! mass metric, through the joint:
//!
//! - **velocity**: the coupling row's rate `c . v` is taken out by the impulse along the row
//!   (and the joint's constrained rows, whose rates stay) that does it at least kinetic energy:
//!   `dv = -M^-1 J^T lambda`, the same response as a stop's ([`super::stops`]); on the multibody
//!   backend over the generalized velocities, `dq' = -M^-1 c (c . q') / (c M^-1 c)` with `M`
//!   from the links' Jacobians;
//! - **position**: the coupling's drift `C` is taken back the same way (first order: the next
//!   call's projection sees the rest).
//!
//! Between two projections the nut moves as a cylindrical joint (gravity accelerates its travel
//! without turning it), and the projection then shares that momentum between travel and turn as
//! the coupling would have: for a constant load the step map is exact in the velocities
//! (`a = F / (m + I / p^2)`), first order in the positions. The coupling error is the joint's
//! gap in its output (the screw row's `C`).

use crate::math::rapier::dynamics::RigidBodyHandle;
use crate::math::{Real, Vector};
use crate::rows::{FramePair, RowEval, RowKind};
use crate::solver::dense;

use super::super::Sets;
use super::RapierBackend;
use super::stops::{correct, response};
use crate::joint_set::RapierJoint;

impl RapierBackend {
    /// Projects every screw joint's velocities and positions back onto its coupling (see the
    /// module docs).
    pub(super) fn couple_screws(&self, sets: &mut Sets) {
        sets.joints.update_row_references(&sets.physics.bodies);
        let roles = sets.joints.roles();
        for &slot in &roles.screws {
            let Some(e) = sets.joints.get(slot) else {
                continue;
            };
            let Some(screw) = e
                .state
                .rows
                .iter()
                .find(|r| matches!(r, RowKind::Screw { .. }))
            else {
                continue;
            };
            let side = |b: RigidBodyHandle| crate::body::pose_and_com(&sets.physics.bodies[b]);
            let f = FramePair::at(&e.low, side(e.body1), side(e.body2));
            let row = screw.eval(&f);
            let (body1, body2, rapier) = (e.body1, e.body2, e.rapier);
            if self.multibody() {
                couple_multibody(sets, rapier, &row, [body1, body2]);
                continue;
            }
            let mut set: Vec<RowEval> = vec![row];
            set.extend(
                e.state
                    .rows
                    .iter()
                    .filter(|r| !matches!(r, RowKind::Screw { .. }))
                    .map(|r| r.eval(&f)),
            );
            let Some((_, unit)) = response(&sets.physics.bodies, [body1, body2], &set) else {
                continue;
            };
            let vel = [body1, body2].map(|b| self.velocity(sets.physics, b));
            let rate = row.rate([vel[0].0, vel[0].1], [vel[1].0, vel[1].1]);
            correct(
                &mut sets.physics.bodies,
                [body1, body2],
                unit,
                -row.value,
                -rate,
            );
        }
    }
}

/// The multibody projection over the generalized velocities and coordinates (see the module
/// docs): `c_i` is the coupling row's rate for a unit generalized velocity `i`.
fn couple_multibody(
    sets: &mut Sets,
    rapier: RapierJoint,
    row: &RowEval,
    sides: [RigidBodyHandle; 2],
) {
    let RapierJoint::Multibody(h) = rapier else {
        return;
    };
    let bodies = &sets.physics.bodies;
    let Some((mb, _)) = sets.physics.multibody_joints.get_mut(h) else {
        return;
    };
    let n = mb.generalized_velocity().len();
    if n == 0 {
        return;
    }
    let mut mass = vec![0.0 as Real; n * n];
    // The coupling row's rate per generalized velocity: its two sides are links (or the fixed
    // root) of this multibody.
    let mut c = vec![0.0 as Real; n];
    let (mut b1, mut b2) = (None, None);
    for (li, link) in mb.links().enumerate() {
        let rb = &bodies[link.rigid_body_handle()];
        let jac = mb.body_jacobian(li);
        if jac.ncols() != n || jac.nrows() != 6 {
            return;
        }
        let col = |k: usize| {
            (
                Vector::new(jac[(0, k)], jac[(1, k)], jac[(2, k)]),
                Vector::new(jac[(3, k)], jac[(4, k)], jac[(5, k)]),
            )
        };
        let inertia = crate::body::world_inertia(rb);
        for a in 0..n {
            let (la, aa) = col(a);
            for b in 0..n {
                let (lb, ab) = col(b);
                mass[a * n + b] += rb.mass() * la.dot(lb) + aa.dot(inertia * ab);
            }
        }
        if link.rigid_body_handle() == sides[0] {
            b1 = Some(li);
        }
        if link.rigid_body_handle() == sides[1] {
            b2 = Some(li);
        }
    }
    for (side, li) in [(0, b1), (1, b2)] {
        let Some(li) = li else { continue };
        let jac = mb.body_jacobian(li);
        let j = if side == 0 { row.j1 } else { row.j2 };
        for (k, ck) in c.iter_mut().enumerate() {
            let l = Vector::new(jac[(0, k)], jac[(1, k)], jac[(2, k)]);
            let a = Vector::new(jac[(3, k)], jac[(4, k)], jac[(5, k)]);
            *ck += j[0].dot(l) + j[1].dot(a);
        }
    }
    // M^-1 c.
    let mut minv_c = c.clone();
    dense::cholesky_solve_dropping(&mut mass, &mut minv_c, n);
    let cmc: Real = c.iter().zip(&minv_c).map(|(a, b)| a * b).sum();
    if !(cmc.is_finite() && cmc > 0.0) {
        return;
    }
    let qd = mb.generalized_velocity();
    let rate: Real = c.iter().zip(qd.iter()).map(|(a, b)| a * b).sum();
    for (k, m) in minv_c.iter().enumerate() {
        mb.generalized_velocity_mut()[k] -= m * rate / cmc;
    }
    let disp: Vec<Real> = minv_c.iter().map(|m| -m * row.value / cmc).collect();
    super::stops::displace_multibody(mb, &mut sets.physics.bodies, &disp);
}
