//! Reaction recovery on the Rapier backends (see the parent module's docs): the constraint
//! impulses over the recorded span (the step, or the multibody's last substep), split among the
//! joints by momentum balance.

mod forest;

use arrayvec::ArrayVec;

use crate::joint_set::JointEntry;
use crate::math::rapier::dynamics::{RigidBodyHandle, RigidBodySet};
use crate::math::{Matrix, Pose, Real, Vector};
use crate::rows::{FramePair, NodeWrench, RowEval, RowKind};
use crate::solver::kkt::{JointBlockSpec, KktSolver, MAX_JOINT_ROWS};

use super::super::Sets;
use super::RapierBackend;

/// The reaction recovery's buffers, kept from step to step: they are rebuilt every step, and
/// allocating them anew cost about a third of the impulse backend's step on the 1000-joint
/// mixed scene (their growth by `realloc`, and the pages the allocator returned to the system
/// and faulted in again).
#[derive(Default)]
pub(crate) struct Scratch {
    /// Per rigid-body arena slot: the body's place in the recorded starts (`NONE` if absent).
    index: Vec<usize>,
    /// The joint set's topology and the recorded bodies' count that `index`, `specs` and
    /// `joint_of` were built for: they change only with it (the bodies recorded are the
    /// backend's jointed bodies, listed again on the same change).
    listed_for: Option<(u64, usize)>,
    /// Per recorded body: its pose and centre of mass halfway through the span.
    mid: Vec<(Pose, Vector)>,
    mass: Vec<[Real; 36]>,
    /// Per recorded body: its inverse mass and world inverse inertia at the start, and whether
    /// every body has both (the forest's metric needs them).
    inv_mass: Vec<(Real, Matrix)>,
    invertible: bool,
    impulse: Vec<[Real; 6]>,
    /// Per joint with rows: its row count and its bodies' places in the recorded starts, and
    /// its index in the joint set (see [`Scratch::list_joints`]).
    specs: Vec<JointBlockSpec>,
    joint_of: Vec<usize>,
    /// Per listed joint: the forest's walk reached it.
    done: Vec<bool>,
    jac: Vec<Real>,
    owner: Vec<(usize, RowEval)>,
    /// Per row: the prescribed rate when it is a drive's row (its work is booked).
    driven: Vec<Option<Real>>,
    mu: Vec<Real>,
    compliance: Vec<Real>,
    wrench: Vec<(Vector, Vector)>,
    /// The joints' forest, when they form one (see [`forest`]), and whether they do (with
    /// at most [`MAX_JOINT_ROWS`] rows each), found when they are listed.
    forest: forest::Forest,
    is_forest: bool,
}

impl Scratch {
    /// Each recorded body's place by its arena slot.
    fn index_bodies(&mut self, starts: &[(RigidBodyHandle, super::BodyStart)]) {
        self.index.clear();
        for (i, (b, _)) in starts.iter().enumerate() {
            let slot = b.into_raw_parts().0 as usize;
            if self.index.len() <= slot {
                self.index.resize(slot + 1, NONE);
            }
            self.index[slot] = i;
        }
    }

    /// Every joint with rows: its row count and its bodies' places in the recorded starts
    /// (`None`: not recorded, a fixed or kinematic body), and its index; a joint without rows
    /// has no reaction (written here: the steps in between write none). Listed again only when
    /// the joints' topology changes (see `Scratch::listed_for`): listing every step was a pass
    /// over the joints and a comparison of the lists for nothing.
    fn list_joints(&mut self, sets: &mut Sets, starts: &[(RigidBodyHandle, super::BodyStart)]) {
        self.specs.clear();
        self.joint_of.clear();
        let index = &self.index;
        let place = |b: RigidBodyHandle| {
            (index.get(b.into_raw_parts().0 as usize).copied())
                .filter(|&i| i != NONE && starts[i].0 == b)
        };
        let bodies = &sets.physics.bodies;
        for (ji, e) in sets.joints.slots_mut().iter_mut().enumerate() {
            let Some(e) = e else { continue };
            if e.state.rows.is_empty() {
                e.set_reaction(bodies, Vector::ZERO, Vector::ZERO);
                continue;
            }
            self.specs.push(JointBlockSpec {
                rows: e.state.rows.len(),
                bodies: [place(e.body1), place(e.body2)],
            });
            self.joint_of.push(ji);
        }
    }
}

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
        let mut sc = self.scratch.take().unwrap_or_default();
        let key = (sets.joints.topology(), starts.len());
        if sc.listed_for != Some(key) {
            sc.index_bodies(&starts);
            sc.list_joints(sets, &starts);
            sc.is_forest = sc.specs.iter().all(|s| s.rows <= MAX_JOINT_ROWS)
                && sc.forest.update(&sc.specs, starts.len());
            sc.listed_for = Some(key);
        }
        self.body_blocks(sets, &starts, h, &mut sc);
        // (J M^-1 J^T) mu = J M^-1 p: joint by joint where the joints form a forest, else the
        // KKT system with f = p, g = 0 and no compliance.
        if sc.invertible && sc.is_forest {
            self.forest_reactions(sets, h, &mut sc);
        } else {
            self.rows_halfway(sets, h, &mut sc);
            self.kkt_split(sets, &starts, &mut sc);
            self.kkt_reactions(sets, h, &mut sc);
        }
        self.starts = starts;
        self.scratch = Some(sc);
    }

    /// The reactions where the joints form a forest, in one walk from the leaves: each
    /// joint's rows halfway through the span, its multipliers from the impulse of the
    /// subtree it carries ([`forest`]), a drive's work, and the reaction written, without
    /// storing the rows (the rows stored for a later pass cost 15 % of the recovery on the
    /// 400-arm mixed scene).
    fn forest_reactions(&self, sets: &mut Sets, h: Real, sc: &mut Scratch) {
        let Scratch {
            mid,
            inv_mass,
            impulse,
            specs,
            joint_of,
            done,
            forest,
            ..
        } = sc;
        done.clear();
        done.resize(specs.len(), false);
        let span = (self.span_start, self.span_start + h);
        let duration = self.step_duration;
        let bodies = &sets.physics.bodies;
        let joints = &mut *sets.joints;
        let ledger = &mut *sets.ledger;
        forest.walk(
            impulse,
            |b| mid[b].1,
            |edge, w| {
                done[edge.joint] = true;
                let Some(e) = joints.get_mut(joint_of[edge.joint]) else {
                    return;
                };
                let places = specs[edge.joint].bodies;
                let (pose1, pose2) = (
                    pose_at(bodies, mid, e.body1, places[0]),
                    pose_at(bodies, mid, e.body2, places[1]),
                );
                let f = FramePair::at(&e.low, pose1, pose2);
                let m = e.state.rows.len();
                let mut mu = [0.0; MAX_JOINT_ROWS];
                let mu = &mut mu[..m];
                // Pure forces and moments at the node where the rows allow it (every kind's
                // but the screw's and an idle spin's), else the child's mass metric.
                let mut dirs = ArrayVec::<NodeWrench, MAX_JOINT_ROWS>::new();
                let at_node = e
                    .state
                    .rows
                    .iter()
                    .all(|r| r.node_wrench(&f).is_some_and(|d| dirs.try_push(d).is_ok()));
                let child_com = if edge.side == 0 { f.c1 } else { f.c2 };
                let node = at_node
                    .then(|| forest::project_at_node(&dirs, edge.side, f.p2 - child_com, w, mu))
                    .flatten();
                if let Some([force, moment]) = node {
                    // The step's mean force and moment about node J, in frame I halfway
                    // through the step, where the rows took them (a free direction's
                    // component is zero there).
                    // Frame I's axes are the row frame's where the two agree (every kind but
                    // those whose rows turn frame I): the same product, already converted.
                    let axes_i = if e.low[0].rotation == e.ansys[0].rotation {
                        f.r1
                    } else {
                        Matrix::from_quat(pose1.0.rotation * e.ansys[0].rotation)
                    };
                    e.set_reaction_in(&axes_i, force / h, moment / h);
                } else {
                    let mut rows = ArrayVec::<RowEval, MAX_JOINT_ROWS>::new();
                    rows.extend(e.state.rows.iter().map(|r| r.eval(&f)));
                    forest::project(&rows, edge.side, inv_mass[edge.child], w, mu);
                    let (force, torque) = rows
                        .iter()
                        .zip(mu.iter())
                        .fold((Vector::ZERO, Vector::ZERO), |(fo, to), (ev, &m)| {
                            (fo + ev.j2[0] * (m / h), to + ev.j2[1] * (m / h))
                        });
                    e.set_reaction(bodies, force, torque);
                }
                for (r, &m) in e.state.rows.iter().zip(mu.iter()) {
                    if let Some(rate) = drive_rate(e, r, span) {
                        ledger.work += m / h * rate * duration;
                    }
                }
            },
        );
        // Rows between two bodies that are not recorded act on none: no reaction.
        for (k, _) in done.iter().enumerate().filter(|(_, d)| !**d) {
            if let Some(e) = joints.get_mut(joint_of[k]) {
                e.set_reaction(bodies, Vector::ZERO, Vector::ZERO);
            }
        }
    }

    /// The reactions from the KKT split's multipliers (the scratch's `mu`, one per row of its
    /// `owner`): a drive's work, and each joint's wrench on body 2 written at node J in
    /// frame I.
    fn kkt_reactions(&self, sets: &mut Sets, h: Real, sc: &mut Scratch) {
        let Scratch {
            owner,
            driven,
            mu,
            wrench,
            ..
        } = sc;
        // A drive's work over the step: its force `mu / h` times the prescribed rate, over the
        // step (the recorded span is the whole step on the impulse backend, its last substep on
        // the multibody one).
        for (rate, m) in driven.iter().zip(mu.iter()) {
            if let Some(rate) = rate {
                sets.ledger.work += m / h * rate * self.step_duration;
            }
        }
        wrench.clear();
        wrench.resize(sets.joints.len(), (Vector::ZERO, Vector::ZERO));
        for ((ji, ev), m) in owner.iter().zip(mu.iter()) {
            wrench[*ji].0 += ev.j2[0] * (*m / h);
            wrench[*ji].1 += ev.j2[1] * (*m / h);
        }
        let bodies = &sets.physics.bodies;
        for (ji, e) in sets.joints.slots_mut().iter_mut().enumerate() {
            if let Some(e) = e {
                e.set_reaction(bodies, wrench[ji].0, wrench[ji].1);
            }
        }
    }

    /// The multipliers by the KKT solve over every recorded body (when the joints close a loop
    /// or a body lacks a mass or a moment), into the scratch's `mu` (zero if it fails).
    fn kkt_split(
        &mut self,
        sets: &Sets,
        starts: &[(RigidBodyHandle, super::BodyStart)],
        sc: &mut Scratch,
    ) {
        let Scratch {
            mass,
            impulse,
            specs,
            jac,
            owner,
            mu,
            compliance,
            ..
        } = sc;
        mu.clear();
        mu.resize(owner.len(), 0.0);
        mass.clear();
        for (b, s) in starts {
            let rb = &sets.physics.bodies[*b];
            let (m, inertia) = (rb.mass(), crate::body::inertia_at(rb, &s.pose));
            let mut block = [0.0; 36];
            for k in 0..3 {
                block[6 * k + k] = m;
                for l in 0..3 {
                    block[6 * (3 + k) + 3 + l] = inertia.col(l)[k];
                }
            }
            mass.push(block);
        }
        jac.clear();
        for (_, ev) in owner.iter() {
            for half in [ev.j1, ev.j2] {
                jac.extend_from_slice(&[half[0].x, half[0].y, half[0].z]);
                jac.extend_from_slice(&[half[1].x, half[1].y, half[1].z]);
            }
        }
        let rebuild = self
            .recovery
            .as_ref()
            .is_none_or(|k| k.joint_specs() != specs.as_slice() || k.num_bodies() != starts.len());
        if rebuild {
            self.recovery = KktSolver::new(starts.len(), specs).ok();
        }
        compliance.clear();
        compliance.resize(owner.len(), 0.0);
        let solved = self.recovery.as_mut().is_some_and(|kkt| {
            kkt.factor(mass, jac, compliance).is_ok() && kkt.solve(impulse, mu).is_ok()
        });
        if !solved {
            mu.iter_mut().for_each(|m| *m = 0.0);
        }
    }

    /// The listed joints' rows halfway through the span (the constraint forces turn with the
    /// bodies over it) into the scratch's owners (with the rows) and drive rates.
    fn rows_halfway(&self, sets: &Sets, h: Real, sc: &mut Scratch) {
        let Scratch {
            mid,
            specs,
            joint_of,
            owner,
            driven,
            ..
        } = sc;
        owner.clear();
        driven.clear();
        let span = (self.span_start, self.span_start + h);
        let bodies = &sets.physics.bodies;
        for (spec, &ji) in specs.iter().zip(joint_of.iter()) {
            let Some(e) = sets.joints.get(ji) else {
                continue;
            };
            let f = FramePair::at(
                &e.low,
                pose_at(bodies, mid, e.body1, spec.bodies[0]),
                pose_at(bodies, mid, e.body2, spec.bodies[1]),
            );
            for r in &e.state.rows {
                driven.push(drive_rate(e, r, span));
                owner.push((ji, r.eval(&f)));
            }
        }
    }

    /// Per recorded body, in one pass: its pose and centre of mass halfway through the span,
    /// the inverse mass at the start and the constraint impulse over the span `h`,
    /// `p_b = m dv - h f` and `l_b = I_1 w_1 - I_0 w_0 - h tau` (angular momenta at the end and
    /// start poses), into the scratch's `mid`, `inv_mass` and `impulse`.
    fn body_blocks(
        &self,
        sets: &Sets,
        starts: &[(RigidBodyHandle, super::BodyStart)],
        h: Real,
        sc: &mut Scratch,
    ) {
        let nb = starts.len();
        let impulse = &mut sc.impulse;
        sc.mid.clear();
        sc.inv_mass.clear();
        sc.invertible = true;
        impulse.clear();
        impulse.resize(nb, [0.0; 6]);
        for (i, (b, s)) in starts.iter().enumerate() {
            let rb = &sets.physics.bodies[*b];
            sc.mid
                .push(halfway((s.pose, s.com), crate::body::pose_and_com(rb)));
            let m = rb.mass();
            let mp = &rb.mass_properties().local_mprops;
            let inv_i = mp.inv_principal_inertia;
            sc.invertible &= mp.inv_mass > 0.0 && inv_i.min_element() > 0.0;
            let inv_inertia = if inv_i.x == inv_i.y && inv_i.y == inv_i.z {
                // Equal principal moments: the same in every frame.
                Matrix::from_diagonal(inv_i)
            } else {
                let r = Matrix::from_quat(s.pose.rotation * mp.principal_inertia_local_frame);
                r * Matrix::from_diagonal(inv_i) * r.transpose()
            };
            sc.inv_mass.push((mp.inv_mass, inv_inertia));
            let (v, w) = self.velocity(sets.physics, *b);
            let p = (v - s.linvel) * m - s.force * h;
            let l = crate::body::angular_momentum(rb, w) - s.momentum - s.torque * h;
            impulse[i] = [p.x, p.y, p.z, l.x, l.y, l.z];
        }
    }
}

/// An arena slot with no recorded body (see `Scratch::index`).
const NONE: usize = usize::MAX;

/// A body's pose and centre of mass halfway through the span: from the recorded ones at its
/// place `i`, or as it is (a body that is not recorded does not move over the span).
fn pose_at(
    bodies: &RigidBodySet,
    mid: &[(Pose, Vector)],
    b: RigidBodyHandle,
    i: Option<usize>,
) -> (Pose, Vector) {
    match i {
        Some(i) => mid[i],
        None => crate::body::pose_and_com(&bodies[b]),
    }
}

/// The mean prescribed rate over `span` (start, end; s) of a drive's row (`None` for any other
/// row): its work is the row's force times it.
fn drive_rate(e: &JointEntry, row: &RowKind, (t0, t1): (Real, Real)) -> Option<Real> {
    match row {
        RowKind::Drive { dof, .. } => e
            .drives
            .iter()
            .find(|d| d.dof == *dof)
            .map(|d| super::drives::mean_rate(d, t0, t1)),
        _ => None,
    }
}

/// The pose and centre of mass halfway between `a` and `b` (translation and centre of mass
/// linearly, rotation by slerp: at one half that is the normalised sum of the two unit
/// quaternions in the same hemisphere, without slerp's inverse cosine and sines).
fn halfway(a: (Pose, Vector), b: (Pose, Vector)) -> (Pose, Vector) {
    let (qa, qb) = (a.0.rotation, b.0.rotation);
    let qb = if qa.dot(qb) < 0.0 { -qb } else { qb };
    let rotation = (qa + qb).normalize();
    let translation = (a.0.translation + b.0.translation) * 0.5;
    (Pose::from_parts(translation, rotation), (a.1 + b.1) * 0.5)
}
