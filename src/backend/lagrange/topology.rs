//! The solver's structure: which bodies and rows take part (sleeping islands leave), the KKT
//! block layout, and which integrator each island takes this step.

use std::collections::{BTreeMap, HashMap};

use crate::error::Error;
use crate::joint_set::{JointEntry, JointSet, RapierJoint};
use crate::math::rapier::dynamics::{JointAxesMask, RigidBodyHandle, RigidBodySet};
use crate::math::{Pose, Vector};
use crate::settings::{Backend, Integrator};
use crate::solver::forest;
use crate::solver::kkt::{JAC_ROW_STRIDE, JointBlockSpec, KktSolver};
use crate::spring::SpringSet;

use super::super::{Sets, lower};
use super::{
    BodyState, Island, LagrangeBackend, REGULARISATION_LOOPS, REGULARISATION_TREE, Warning,
};

impl LagrangeBackend {
    /// The structure is stale: invalidated, the joints' rows changed, an island fell asleep or
    /// woke, or colliders were added or removed.
    pub(super) fn needs_rebuild(&self, sets: &Sets) -> bool {
        self.dirty
            || self.topology != sets.joints.topology()
            || self.spring_topology != sets.springs.topology()
            || asleep_changed(sets.joints, &sets.physics.bodies, &self.asleep)
            || self.colliders != sets.physics.colliders.len()
    }

    /// Splits the awake joints into islands (joints connected through dynamic bodies) and
    /// builds each island's body index and KKT structure.
    pub(super) fn topology(&mut self, sets: &mut Sets) -> Result<(), Error> {
        contact_rows_in_rapier(sets);
        let physics = &*sets.physics;
        self.colliders = physics.colliders.len();
        let asleep = asleep(sets.joints, &physics.bodies);
        let groups = island_members(sets.joints, sets.springs, &physics.bodies, &asleep);
        let old = core::mem::take(&mut self.islands);
        self.block_of = vec![None; sets.joints.len()];
        self.island_of = vec![None; sets.joints.len()];
        for (members, springs) in groups {
            let mut island = Island::build(sets, members, springs)?;
            // A rebuilt island keeps the report of the last step (its redundancy).
            island.report.redundant_rows = old
                .iter()
                .find(|o| o.members.first() == island.members.first())
                .map_or(0, |o| o.report.redundant_rows);
            let i = self.islands.len();
            for (k, &j) in island.blocks.iter().enumerate() {
                self.block_of[j] = Some((i, k));
            }
            for &j in &island.members {
                self.island_of[j] = Some(i);
            }
            self.islands.push(island);
        }
        self.asleep = asleep;
        self.dirty = false;
        self.topology = sets.joints.topology();
        self.spring_topology = sets.springs.topology();
        Ok(())
    }
}

/// The awake joints and spring-dampers grouped into islands: elements sharing a dynamic body
/// are in one island (union-find); each island's joints and springs ascending, the islands by
/// their first element (joints first). A spring counts as asleep, as a joint does, when every
/// dynamic body it connects is asleep.
fn island_members(
    joints: &JointSet,
    springs: &SpringSet,
    bodies: &RigidBodySet,
    asleep: &[bool],
) -> Vec<(Vec<usize>, Vec<usize>)> {
    let slots = joints.slots();
    let nj = slots.len();
    // Elements 0..nj are the joints, nj.. the springs.
    let sides: Vec<Option<[RigidBodyHandle; 2]>> = slots
        .iter()
        .enumerate()
        .map(|(j, e)| {
            let e = e.as_ref()?;
            (!asleep.get(j).copied().unwrap_or(false)).then_some([e.body1, e.body2])
        })
        .chain(springs.slots().iter().map(|e| {
            let e = e.as_ref()?;
            let dynamic: Vec<_> = e
                .bodies
                .iter()
                .filter(|b| bodies[**b].is_dynamic())
                .collect();
            let sleeping = !dynamic.is_empty() && dynamic.iter().all(|b| bodies[**b].is_sleeping());
            (!sleeping).then_some(e.bodies)
        }))
        .collect();
    let mut parent: Vec<usize> = (0..sides.len()).collect();
    let mut owner: HashMap<RigidBodyHandle, usize> = HashMap::new();
    for (k, s) in sides.iter().enumerate() {
        let Some(s) = s else { continue };
        for b in s {
            if !bodies[*b].is_dynamic() {
                continue;
            }
            match owner.get(b) {
                Some(&other) => {
                    let (ra, rb) = (root(&mut parent, k), root(&mut parent, other));
                    if ra != rb {
                        parent[ra.max(rb)] = ra.min(rb);
                    }
                }
                None => {
                    owner.insert(*b, k);
                }
            }
        }
    }
    let mut groups: BTreeMap<usize, (Vec<usize>, Vec<usize>)> = BTreeMap::new();
    for (k, s) in sides.iter().enumerate() {
        if s.is_none() {
            continue;
        }
        let r = root(&mut parent, k);
        let g = groups.entry(r).or_default();
        if k < nj {
            g.0.push(k);
        } else {
            g.1.push(k - nj);
        }
    }
    groups.into_values().collect()
}

impl Island {
    /// The island of the joints `members` (ascending): its bodies, KKT structure and buffers.
    fn build(sets: &Sets, members: Vec<usize>, springs: Vec<usize>) -> Result<Island, Error> {
        let physics = &*sets.physics;
        let mut bodies = Vec::new();
        let mut index = HashMap::new();
        let mut specs = Vec::new();
        let mut blocks = Vec::new();
        for &j in &members {
            let Some(e) = sets.joints.get(j) else {
                continue;
            };
            let mut slot = |b: RigidBodyHandle| -> Option<usize> {
                if !physics.bodies[b].is_dynamic() {
                    return None;
                }
                Some(*index.entry(b).or_insert_with(|| {
                    bodies.push(b);
                    bodies.len() - 1
                }))
            };
            let s = [slot(e.body1), slot(e.body2)];
            if e.state.rows.is_empty() {
                continue;
            }
            specs.push(JointBlockSpec {
                rows: e.state.rows.len(),
                bodies: s,
            });
            blocks.push(j);
        }
        for &k in &springs {
            for &b in sets.springs.get(k).map(|e| &e.bodies).into_iter().flatten() {
                if physics.bodies[b].is_dynamic() {
                    index.entry(b).or_insert_with(|| {
                        bodies.push(b);
                        bodies.len() - 1
                    });
                }
            }
        }
        let has_kinematic = members.iter().filter_map(|&j| sets.joints.get(j)).any(|e| {
            physics.bodies[e.body1].is_kinematic() || physics.bodies[e.body2].is_kinematic()
        });
        let kkt = KktSolver::new(bodies.len(), &specs).map_err(|e| Error::Unsupported {
            what: format!("the constraint structure: {e}"),
            hint: "a joint carries at most 12 rows".into(),
        })?;
        let mut island = Island {
            members,
            springs,
            ..Island::default()
        };
        island.size_buffers(bodies.len(), kkt.num_rows());
        island.has_kinematic = has_kinematic;
        island.regularisation = if is_tree(bodies.len(), &specs) {
            REGULARISATION_TREE
        } else {
            REGULARISATION_LOOPS
        };
        island.bodies = bodies;
        island.index = index;
        island.blocks = blocks;
        island.shape = Some((
            kkt.num_bodies(),
            specs.iter().map(|s| (s.rows, s.bodies)).collect(),
        ));
        island.kkt = Some(kkt);
        Ok(island)
    }

    /// Sizes (and clears) every per-body and per-row buffer.
    fn size_buffers(&mut self, nb: usize, nr: usize) {
        self.st = vec![BodyState::default(); nb];
        self.mass = vec![[0.0; 36]; nb];
        self.rhs_b = vec![[0.0; 6]; nb];
        self.shift = vec![[0.0; 6]; nb];
        self.saved = vec![(0.0, Vector::ZERO, Vector::ZERO); nb];
        self.jac = vec![0.0; JAC_ROW_STRIDE * nr];
        self.compliance = vec![0.0; nr];
        self.value = vec![0.0; nr];
        self.kin = vec![0.0; nr];
        self.penalty = vec![false; nr];
        self.kpen = vec![0.0; nr];
        self.rate = vec![0.0; nr];
        self.reg_scale = 1.0;
        self.backup = vec![(Pose::IDENTITY, Vector::ZERO); nb];
        self.last_x = vec![[0.0; 6]; nb];
        self.last_lambda = vec![0.0; nr];
        self.mu = vec![0.0; nr];
        self.fresh_values = false;
        self.factor_valid = None;
        self.written = vec![(Pose::IDENTITY, Vector::ZERO, Vector::ZERO); nb];
        self.rhs_j = vec![0.0; nr];
        self.impulse = vec![0.0; nr];
        self.vp_carry = vec![0.0; nr];
        self.free_h = 0.0;
    }

    /// Picks the integrator of each body for this step: the world's, except that an island
    /// (bodies connected by joints) with an active contact takes the first-order step.
    pub(super) fn choose_order(&mut self, sets: &Sets) {
        let nb = self.bodies.len();
        let rattle = matches!(
            sets.integrator,
            Integrator::Rattle | Integrator::Composition4
        );
        self.second.clear();
        self.second.resize(nb, rattle);
        self.second_any = rattle && nb > 0;
        self.report.first_order_bodies = 0;
        if !rattle {
            return;
        }
        let touched = self.bodies_in_contact(sets);
        if touched.is_empty() {
            return;
        }
        // Islands by union-find over the joint blocks.
        let mut parent: Vec<usize> = (0..nb).collect();
        fn root(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        if let Some(kkt) = self.kkt.as_ref() {
            for spec in kkt.joint_specs() {
                if let [Some(a), Some(b)] = spec.bodies {
                    let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
                    parent[ra] = rb;
                }
            }
        }
        let mut contact_root = vec![false; nb];
        for i in touched {
            let r = root(&mut parent, i);
            contact_root[r] = true;
        }
        let mut fallback = 0;
        for i in 0..nb {
            if contact_root[root(&mut parent, i)] {
                self.second[i] = false;
                fallback += 1;
            }
        }
        self.second_any = self.second.iter().any(|x| *x);
        self.report.first_order_bodies = fallback;
        self.warn(
            Warning::Fallback,
            format!(
                "t = {}: {fallback} bod(ies) in islands with an active contact take the \
                 first-order step while the contact lasts (second order needs smooth forces)",
                sets.time
            ),
        );
    }

    /// Whether the island takes the fourth-order composition in this step (see
    /// [`Integrator::Composition4`]): the world asks for it, the islands integrate their
    /// bodies themselves (`alone`: the negative stage cannot go through Rapier), the island is
    /// plain (no behaviour, spring, drive or screw), has no penalty row (their compliance
    /// depends on the stage size) and needed no added inertia. Otherwise its bodies take
    /// RATTLE, counted in the report.
    pub(super) fn choose_composition(&mut self, integrator: Integrator, alone: bool) {
        self.rotor = alone;
        let asked = integrator == Integrator::Composition4;
        self.composed = asked
            && alone
            && self.plain
            && self.second_any
            && !self.would_stiffen
            && self.kpen.iter().all(|k| *k == 0.0);
        if asked && !self.composed {
            self.take_rattle();
        } else if !self.composed {
            self.forget_stages();
        }
    }

    /// The island takes RATTLE where the composition was asked for: its second-order bodies
    /// are counted in the report.
    pub(super) fn take_rattle(&mut self) {
        self.composed = false;
        self.forget_stages();
        self.report.second_order_bodies = self.second.iter().filter(|x| **x).count();
    }

    /// The solver's bodies with an active contact (their slots).
    fn bodies_in_contact(&self, sets: &Sets) -> Vec<usize> {
        let mut touched = Vec::new();
        for pair in sets.physics.contact_pairs() {
            if !pair.has_any_active_contact() {
                continue;
            }
            for c in [pair.collider1, pair.collider2] {
                if let Some(&i) = sets
                    .physics
                    .colliders
                    .get(c)
                    .and_then(|col| col.parent())
                    .and_then(|b| self.index.get(&b))
                {
                    touched.push(i);
                }
            }
        }
        touched
    }
}

/// Per joint: every dynamic body it connects is asleep in Rapier (and it has at least one).
pub(super) fn asleep(joints: &JointSet, bodies: &RigidBodySet) -> Vec<bool> {
    joints
        .slots()
        .iter()
        .map(|e| e.as_ref().is_some_and(|e| joint_asleep(e, bodies)))
        .collect()
}

/// [`asleep`] now differs from `was`, without building the list (the test runs every step:
/// with a list of each joint's dynamic bodies it allocated once per joint and step, 0.3 to
/// 0.7 % of the step's instructions on the pendulum, the chains and the mixed scene).
fn asleep_changed(joints: &JointSet, bodies: &RigidBodySet, was: &[bool]) -> bool {
    let slots = joints.slots();
    slots.len() != was.len()
        || slots
            .iter()
            .zip(was)
            .any(|(e, &w)| e.as_ref().is_some_and(|e| joint_asleep(e, bodies)) != w)
}

/// Every dynamic body joint `e` connects is asleep, and it has one.
fn joint_asleep(e: &JointEntry, bodies: &RigidBodySet) -> bool {
    let mut dynamic = false;
    for b in [e.body1, e.body2] {
        let rb = &bodies[b];
        if rb.is_dynamic() {
            if !rb.is_sleeping() {
                return false;
            }
            dynamic = true;
        }
    }
    dynamic
}

/// Rapier's own copy of a joint's rows rides along only where a contact can act (either body
/// has a collider): they do no work on the velocities the solve already made consistent, but
/// keep contact and joint consistent inside Rapier's solver (otherwise the two alternate
/// between our solve and Rapier's and a body resting on a floor creeps). Elsewhere the Rapier
/// joint locks nothing: it would cost a Rapier joint solve for nothing.
fn contact_rows_in_rapier(sets: &mut Sets) {
    let physics = &mut *sets.physics;
    for e in sets.joints.iter() {
        let RapierJoint::Impulse(handle) = e.rapier else {
            continue;
        };
        let touches = [e.body1, e.body2]
            .iter()
            .any(|b| !physics.bodies[*b].colliders().is_empty());
        let mask = match lower::lower(&e.joint.kind, e.joint.method, Backend::RapierImpulse) {
            Ok(m) if touches => m,
            _ => JointAxesMask::empty(),
        };
        if let Some(j) = physics.impulse_joints.get_mut(handle, false)
            && j.data.locked_axes != mask
        {
            j.data.lock_axes(mask);
        }
    }
}

/// The island's joint blocks form no closed loop: in the graph of its `nb` dynamic bodies and
/// one node for everything else (the ground, fixed and kinematic bodies, where a block has an
/// absent side), no block joins two nodes that other blocks already connect. Two blocks
/// between the same two bodies, or two blocks from one body to the ground, make a loop (see
/// [`forest::leaves_first`]).
fn is_tree(nb: usize, specs: &[JointBlockSpec]) -> bool {
    forest::leaves_first(specs, nb).is_some()
}

/// The root of `i` in the union-find forest `p` (path halving).
fn root(p: &mut [usize], mut i: usize) -> usize {
    while p[i] != i {
        p[i] = p[p[i]];
        i = p[i];
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(a: Option<usize>, b: Option<usize>) -> JointBlockSpec {
        JointBlockSpec {
            rows: 5,
            bodies: [a, b],
        }
    }

    #[test]
    fn trees_and_loops() {
        // A chain of three bodies hanging from the ground: a tree.
        let chain = [
            spec(None, Some(0)),
            spec(Some(0), Some(1)),
            spec(Some(1), Some(2)),
        ];
        assert!(is_tree(3, &chain));
        // A floating pair and a branch: trees.
        assert!(is_tree(2, &[spec(Some(0), Some(1))]));
        assert!(is_tree(
            3,
            &[
                spec(None, Some(0)),
                spec(Some(0), Some(1)),
                spec(Some(0), Some(2))
            ]
        ));
        // A four-bar (crank, coupler, rocker between two ground pivots): a loop through the
        // ground.
        let four_bar = [
            spec(None, Some(0)),
            spec(Some(0), Some(1)),
            spec(Some(1), Some(2)),
            spec(Some(2), None),
        ];
        assert!(!is_tree(3, &four_bar));
        // Two blocks between the same bodies, or from one body to the ground: loops.
        assert!(!is_tree(
            2,
            &[spec(Some(0), Some(1)), spec(Some(1), Some(0))]
        ));
        assert!(!is_tree(1, &[spec(None, Some(0)), spec(Some(0), None)]));
    }
}
