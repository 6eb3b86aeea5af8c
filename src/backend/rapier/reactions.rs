//! Reaction recovery on the Rapier backends (see the parent module's docs): the constraint
//! impulses over the recorded span (the step, or the multibody's last substep), split among the
//! joints by momentum balance.

use std::collections::HashMap;

use crate::math::rapier::dynamics::RigidBodyHandle;
use crate::math::{Pose, Real, Vector};
use crate::rows::{FramePair, RowEval};
use crate::solver::kkt::{JointBlockSpec, KktSolver};

use super::super::Sets;
use super::RapierBackend;

impl RapierBackend {
    /// Splits the constraint impulses of the recorded span among the joints and writes each
    /// joint's reaction force and moment into its output (the world's substep `_h` is not it on
    /// the impulse backend: the span is the whole step there).
    pub(crate) fn write_reactions(&mut self, sets: &mut Sets, _h: Real) {
        let h = self.span;
        if h <= 0.0 {
            return;
        }
        let starts = core::mem::take(&mut self.starts);
        let index: HashMap<RigidBodyHandle, usize> = starts
            .iter()
            .enumerate()
            .map(|(i, (b, _))| (*b, i))
            .collect();
        let (mass, mut impulse) = self.body_blocks(sets, &starts, h);
        // Rows halfway through the span: the constraint forces turn with the bodies over it.
        let mut specs = Vec::new();
        let mut jac: Vec<Real> = Vec::new();
        let mut owner: Vec<(usize, RowEval)> = Vec::new();
        // Per row: the prescribed rate when it is a drive's row (its work is booked below).
        let mut driven: Vec<Option<Real>> = Vec::new();
        let (t0, t1) = (self.span_start, self.span_start + h);
        for (ji, e) in sets.joints.slots().iter().enumerate() {
            let Some(e) = e else { continue };
            if e.state.rows.is_empty() {
                continue;
            }
            let pose_of = |b: RigidBodyHandle| {
                let now = crate::body::pose_and_com(&sets.physics.bodies[b]);
                match index.get(&b) {
                    Some(&i) => halfway((starts[i].1.pose, starts[i].1.com), now),
                    None => now,
                }
            };
            let f = FramePair::at(&e.low, pose_of(e.body1), pose_of(e.body2));
            specs.push(JointBlockSpec {
                rows: e.state.rows.len(),
                bodies: [index.get(&e.body1).copied(), index.get(&e.body2).copied()],
            });
            for r in &e.state.rows {
                let ev = r.eval(&f);
                driven.push(match r {
                    crate::rows::RowKind::Drive { dof, .. } => e
                        .drives
                        .iter()
                        .find(|d| d.dof == *dof)
                        .map(|d| super::drives::mean_rate(d, t0, t1)),
                    _ => None,
                });
                for half in [ev.j1, ev.j2] {
                    jac.extend_from_slice(&[half[0].x, half[0].y, half[0].z]);
                    jac.extend_from_slice(&[half[1].x, half[1].y, half[1].z]);
                }
                owner.push((ji, ev));
            }
        }
        // (J M^-1 J^T) mu = J M^-1 p: the KKT system with f = p, g = 0 and no compliance.
        let mut mu = vec![0.0 as Real; owner.len()];
        let rebuild = self
            .recovery
            .as_ref()
            .is_none_or(|k| k.joint_specs() != specs.as_slice() || k.num_bodies() != starts.len());
        if rebuild {
            self.recovery = KktSolver::new(starts.len(), &specs).ok();
        }
        let compliance = vec![0.0 as Real; owner.len()];
        if let Some(kkt) = self.recovery.as_mut()
            && kkt.factor(&mass, &jac, &compliance).is_ok()
            && kkt.solve(&mut impulse, &mut mu).is_ok()
        {
            // mu now holds the multipliers (impulses, N s).
        } else {
            mu.iter_mut().for_each(|m| *m = 0.0);
        }
        // A drive's work over the step: its force `mu / h` times the prescribed rate, over the
        // step (the recorded span is the whole step on the impulse backend, its last substep on
        // the multibody one).
        for (rate, m) in driven.iter().zip(&mu) {
            if let Some(rate) = rate {
                sets.ledger.work += m / h * rate * self.step_duration;
            }
        }
        // Accumulate each joint's wrench on body 2 and express it at node J in frame I.
        let mut wrench: Vec<(Vector, Vector)> =
            vec![(Vector::ZERO, Vector::ZERO); sets.joints.len()];
        for ((ji, ev), m) in owner.iter().zip(&mu) {
            wrench[*ji].0 += ev.j2[0] * (*m / h);
            wrench[*ji].1 += ev.j2[1] * (*m / h);
        }
        let bodies = &sets.physics.bodies;
        for (ji, e) in sets.joints.slots_mut().iter_mut().enumerate() {
            if let Some(e) = e {
                e.set_reaction(bodies, wrench[ji].0, wrench[ji].1);
            }
        }
        self.starts = starts;
    }

    /// Per recorded body: the mass block `M_b` and the constraint impulse over the span `h`,
    /// `p_b = m dv - h f` and `l_b = I_1 w_1 - I_0 w_0 - h tau` (angular momenta at the end and
    /// start poses).
    fn body_blocks(
        &self,
        sets: &Sets,
        starts: &[(RigidBodyHandle, super::BodyStart)],
        h: Real,
    ) -> (Vec<[Real; 36]>, Vec<[Real; 6]>) {
        let nb = starts.len();
        let mut mass = vec![[0.0 as Real; 36]; nb];
        let mut impulse = vec![[0.0 as Real; 6]; nb];
        for (i, (b, s)) in starts.iter().enumerate() {
            let rb = &sets.physics.bodies[*b];
            let m = rb.mass();
            let inertia = crate::body::inertia_at(rb, &s.pose);
            for k in 0..3 {
                mass[i][6 * k + k] = m;
                for l in 0..3 {
                    mass[i][6 * (3 + k) + 3 + l] = inertia.col(l)[k];
                }
            }
            let (v, w) = self.velocity(sets.physics, *b);
            let p = (v - s.linvel) * m - s.force * h;
            let l = crate::body::world_inertia(rb) * w - s.momentum - s.torque * h;
            impulse[i] = [p.x, p.y, p.z, l.x, l.y, l.z];
        }
        (mass, impulse)
    }
}

/// The pose and centre of mass halfway between `a` and `b` (translation and centre of mass
/// linearly, rotation by slerp).
fn halfway(a: (Pose, Vector), b: (Pose, Vector)) -> (Pose, Vector) {
    let rotation = a.0.rotation.slerp(b.0.rotation, 0.5);
    let translation = (a.0.translation + b.0.translation) * 0.5;
    (Pose::from_parts(translation, rotation), (a.1 + b.1) * 0.5)
}
