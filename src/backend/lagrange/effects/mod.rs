//! The solver side of joint behaviour on the Lagrange backend (the physics and the data are in
//! [`crate::behaviour`]).
//!
//! - Springs, dampers and applied loads (`FJ`) act as generalised forces on the free DOFs
//!   ([`forces`]), half an impulse at the start of each substep (from the state there) and half
//!   at its end (from the new state) — kick-drift-kick, second order for the force element.
//! - Stops and locks ([`limits`]) cost nothing while inactive: each substep reads the limited
//!   DOFs' measures and predicted rates, and only a DOF predicted to pass a limit gets a row.
//!   That row does not enter the KKT structure: its response through the constrained system is
//!   one more solve with the substep's existing factorisation (a Schur complement over the
//!   active limits, solved with non-negative impulses), so the joints' own rows keep their
//!   rates.
//!   - Lagrange method, transient: energy-momentum consistent elastic impact: the approach rate
//!     `g-` becomes `-g-` (the impulse `p` changes the kinetic energy by `p (g- + g+) / 2 = 0`).
//!   - Penalty method or a screw joint: plain inequality: the DOF lands on the limit
//!     (`g+ = -gap / h`) and stays while pushed; the kinetic energy lost is dissipated.
//!   - Locks land the same way and are then held by a permanent row from the next step on.
//!
//!   After the position projection a limit still violated by more than the projection
//!   tolerance is projected back the same way (position level, start-of-substep directions).
//! - Friction ([`friction`]): a bounded impulse on the friction DOF(s), with the normal force
//!   from the joint's own reactions in the substep.
//! - The second-order step's energy-consistent impact after an elastic stop ([`energy`]).

mod energy;
mod forces;
mod friction;
mod limits;

use crate::error::Error;
use crate::joint_set::{JointEntry, JointSet, Roles};
use crate::math::rapier::dynamics::RigidBodySet;
use crate::math::{Real, Vector};
use crate::rows::{FramePair, RowEval};

use super::Island;

/// A joint's ANSYS frame pair, the dynamic-body slots of its two sides and each side's velocity
/// (linear at the centre of mass, angular).
type EffectFrames = (FramePair, [Option<usize>; 2], [[Vector; 2]; 2]);

/// Per row: the body velocity changes and the joint rows' multiplier changes of a unit impulse.
type Responses = Vec<(Vec<[Real; 6]>, Vec<Real>)>;

/// What the behaviour of one joint left in the last substep (solver scratch, not state: every
/// substep recomputes it).
#[derive(Clone, Debug, Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct JointScratch {
    /// Generalised spring + damper + load force of the last evaluation (per DOF).
    pub(crate) force: [Real; 6],
    /// World force and torque on body 2 (about its centre of mass) from the elements and the
    /// limit impulses of the last substep (N, N m).
    pub(crate) on_body2: (Vector, Vector),
    /// Spring energy at the last evaluation (J).
    spring_energy: Real,
    /// The loads and the DOFs' measures at the current substep's start (the loads' work is
    /// booked at its end from them).
    load_start: [Real; 6],
    measure_start: [Real; 6],
    /// Stops that reflected elastically in the current substep (DOF, side: +1 lower, -1 upper).
    bounced: Vec<(crate::dof::Dof, Real)>,
}

/// The joint behaviour of the Lagrange backend: per joint scratch, by joint index.
#[derive(Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct Effects {
    scratch: Vec<JointScratch>,
    /// The joint set's topology the scratch was fitted to.
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    fitted_for: Option<u64>,
}

impl Effects {
    /// One scratch entry per joint slot (cleared where the joint was removed), after a change
    /// of the joints.
    pub(crate) fn fit(&mut self, joints: &JointSet) {
        if self.fitted_for == Some(joints.topology()) {
            return;
        }
        self.fitted_for = Some(joints.topology());
        self.scratch
            .resize_with(joints.len(), JointScratch::default);
        for (s, e) in self.scratch.iter_mut().zip(joints.slots()) {
            if e.is_none() {
                *s = JointScratch::default();
            }
        }
    }

    /// Joint `j`'s element forces (N or N m per DOF) and its wrench on body 2 (force, torque
    /// about its centre of mass, world frame) in the last substep; zero if it never stepped.
    pub(crate) fn forces_of(&self, j: usize) -> ([Real; 6], (Vector, Vector)) {
        self.scratch
            .get(j)
            .map_or(([0.0; 6], (Vector::ZERO, Vector::ZERO)), |s| {
                (s.force, s.on_body2)
            })
    }

    /// Elastic energy of the springs of `members` at their last evaluation (J).
    pub(crate) fn spring_energy(&self, members: &[usize]) -> Real {
        members
            .iter()
            .filter_map(|&j| self.scratch.get(j))
            .map(|s| s.spring_energy)
            .sum()
    }

    /// Resets the per-step limit flags (called at a step's start) of the joints with stops or
    /// locks, the only ones that set them.
    pub(crate) fn begin_step(&mut self, joints: &mut JointSet, roles: &Roles) {
        for &j in &roles.limits {
            if let Some(e) = joints.get_mut(j) {
                e.state.at_stop = [false; 6];
            }
        }
    }

    /// Resets the per-substep force accumulators of `members` (called before a substep's
    /// first kick).
    pub(crate) fn begin_substep(&mut self, members: &[usize]) {
        for &j in members {
            if let Some(s) = self.scratch.get_mut(j) {
                s.on_body2 = (Vector::ZERO, Vector::ZERO);
                s.bounced.clear();
            }
        }
    }
}

/// Joint `e`'s ANSYS frame pair at the solver's current body states, the dynamic-body slots of
/// its two sides, and each side's velocity (linear at the centre of mass, angular).
fn frames(ls: &Island, bodies: &RigidBodySet, e: &JointEntry) -> EffectFrames {
    let side = |b| match ls.index.get(&b) {
        Some(&i) => {
            let s = &ls.st[i];
            (s.pose, s.com, Some(i), [s.linvel, s.angvel])
        }
        None => {
            let rb = &bodies[b];
            (
                *rb.position(),
                rb.center_of_mass(),
                None,
                [rb.linvel(), rb.angvel()],
            )
        }
    };
    let (p1, c1, i1, v1) = side(e.body1);
    let (p2, c2, i2, v2) = side(e.body2);
    (
        FramePair::at(&e.ansys, (p1, c1), (p2, c2)),
        [i1, i2],
        [v1, v2],
    )
}

/// The response of the constrained system to a unit impulse along each row: the body velocity
/// changes and the joint rows' multiplier changes (`-impulse`), from the current factorisation
/// with two steps of iterative refinement towards the unregularised hard rows (the relative
/// regularisation otherwise lets a response to a large torque on a small inertia leak through
/// the joint's own rows: measured 3e-4 of the impact energy lost per bounce with a bob of
/// inertia 1e-4 kg m^2 on 1 m; the second pass takes a 1e-6 kg m^2 bob from 4e-5 to
/// round-off). Empty when there is no factorisation.
fn responses(
    ls: &Island,
    rows: &[(RowEval, [Option<usize>; 2])],
    time: Real,
) -> Result<Responses, Error> {
    let nb = ls.bodies.len();
    let Some(kkt) = ls.kkt.as_ref() else {
        return Ok(Vec::new());
    };
    let fail = |e| Error::Diverged {
        time,
        joint: None,
        reason: format!("joint stop/friction solve failed: {e}"),
    };
    let mut out = Vec::with_capacity(rows.len());
    for (row, slots) in rows {
        let mut rb = vec![[0.0; 6]; nb];
        let mut rj = vec![0.0; kkt.num_rows()];
        for (slot, jb) in [(slots[0], row.j1), (slots[1], row.j2)] {
            if let Some(i) = slot {
                for c in 0..3 {
                    rb[i][c] += jb[0][c];
                    rb[i][3 + c] += jb[1][c];
                }
            }
        }
        kkt.solve(&mut rb, &mut rj).map_err(fail)?;
        let mut last = rj.clone();
        for _ in 0..2 {
            let mut rb2 = vec![[0.0; 6]; nb];
            let mut rj2: Vec<Real> = last
                .iter()
                .zip(&ls.compliance)
                .zip(&ls.kpen)
                .map(|((m, c), k)| if *k > 0.0 { 0.0 } else { -c * m })
                .collect();
            kkt.solve(&mut rb2, &mut rj2).map_err(fail)?;
            for (x, y) in rb.iter_mut().zip(&rb2) {
                for c in 0..6 {
                    x[c] += y[c];
                }
            }
            for (x, y) in rj.iter_mut().zip(&rj2) {
                *x += y;
            }
            last = rj2;
        }
        out.push((rb, rj));
    }
    Ok(out)
}
