//! Assembly: the body states from Rapier, every row's value and Jacobian at the current
//! states, the compliances (penalty springs, the hard rows' relative regularisation), the mass
//! blocks with the geometric-stiffness inertia, and the factorisation.

use crate::catalogue::JointKind;
use crate::error::Error;
use crate::joint::ConstraintMethod;
use crate::joint_set::JointSet;
use crate::math::rapier::dynamics::{RigidBodyHandle, RigidBodySet};
use crate::math::{Matrix, Pose, Real, Vector};
use crate::rows::{
    FramePair, RowEval, RowKind, angular_row, angular_value, linear_row, linear_value,
};
use crate::solver::kkt::{FactorReport, JAC_ROW_STRIDE};

/// What an evaluation of the rows computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Eval {
    /// The values only.
    Values,
    /// The values and the Jacobian.
    Geometry,
}

use super::{
    DEFAULT_PENALTY_DISP, DEFAULT_PENALTY_ROT, Island, REGULARISATION_LOOPS, Warning, kkt_err,
    penalty_stiffness,
};

/// One side of a joint as [`Island::constraint_terms`] reads it.
enum Side {
    /// A body of the island: its mass (kg) and world inverse inertia.
    Dynamic(Real, Matrix),
    /// A body outside it (fixed or kinematic): its linear and angular velocity.
    Moving(Vector, Vector),
}

impl Island {
    /// Reads pose, mass and velocity of every jointed body from Rapier.
    pub(super) fn gather(&mut self, bodies: &RigidBodySet, g: Vector) {
        for (i, b) in self.bodies.iter().enumerate() {
            let rb = &bodies[*b];
            let s = &mut self.st[i];
            let mp = &rb.mass_properties().local_mprops;
            s.principal = mp.principal_inertia();
            s.principal_inv = mp.inv_principal_inertia;
            s.principal_frame = mp.principal_inertia_local_frame;
            s.local_com = mp.local_com;
            s.min_inertia = s.principal.min_element();
            s.pose = *rb.position();
            s.refresh_inertia();
            s.com = rb.center_of_mass();
            s.mass = rb.mass();
            s.linvel = rb.linvel();
            s.angvel = rb.angvel();
            s.force = rb.user_force() + g * (rb.mass() * rb.gravity_scale());
            // The gyroscopic torque is added in the velocity solve (implicit midpoint).
            s.torque = rb.user_torque();
        }
    }

    /// The factorisation of the last substep still holds for a step of `h`: same `h`, no
    /// kinematic body, and every body exactly as it was written back (the user may have moved
    /// bodies or changed velocities between steps). Call after [`Island::gather`].
    pub(super) fn factor_holds(&self, h: Real) -> bool {
        !self.has_kinematic
            && self.factor_valid == Some(h)
            && self
                .st
                .iter()
                .zip(&self.written)
                .all(|(s, w)| s.pose == w.0 && s.linvel == w.1 && s.angvel == w.2)
    }

    /// Kinetic energy of the solver's bodies plus the potential of their constant forces
    /// (gravity and user forces: `-f . c`), at the current body states (J).
    pub(super) fn body_energy(&self) -> Real {
        self.st
            .iter()
            .map(|s| {
                0.5 * s.mass * s.linvel.length_squared() + 0.5 * s.angvel.dot(s.inertia * s.angvel)
                    - s.force.dot(s.com)
            })
            .sum()
    }

    /// Evaluates every row at the bodies' current state (`st`); with `jacobian`, also fills the
    /// Jacobian arena, the compliances and the kinematic terms.
    pub(super) fn rows(
        &mut self,
        joints: &JointSet,
        bodies: &RigidBodySet,
        h: Real,
        jacobian: bool,
    ) {
        if jacobian {
            self.eval_rows(joints, bodies, Eval::Geometry);
            self.constraint_terms(joints, bodies, h);
        } else {
            self.eval_rows(joints, bodies, Eval::Values);
        }
    }

    /// Evaluates every row at the bodies' current state (`st`): the values, and with
    /// [`Eval::Geometry`] the Jacobian arena too.
    ///
    /// The translation and rotation rows (all but a few joints' rows) are evaluated inline
    /// ([`linear_row`], [`angular_row`]) with the joint's shared vectors computed once
    /// ([`FramePair::arms`]) and stored straight into the arena; the others through
    /// [`RowKind::eval`]. Measured against one `RowKind::eval` call per row (callgrind,
    /// 1/60 s x 4, with the frame axes read by index, [`FramePair::axis1`]): -2.8 %
    /// instructions per step on the 100-link chain, -3.3 % on the mixed scene of 100 arms,
    /// the same results to the bit.
    pub(super) fn eval_rows(&mut self, joints: &JointSet, bodies: &RigidBodySet, what: Eval) {
        let Some(kkt) = self.kkt.as_ref() else { return };
        // Local slices: the stores into them would otherwise make every access reload the
        // vectors' pointers from `self`.
        let (st, value, jac) = (&self.st[..], &mut self.value[..], &mut self.jac[..]);
        for (k, &j) in self.blocks.iter().enumerate() {
            let Some(e) = joints.get(j) else { continue };
            let slots = kkt.joint_specs()[k].bodies;
            let side = |b: RigidBodyHandle, slot: Option<usize>| -> (Pose, Vector) {
                match slot {
                    Some(i) => (st[i].pose, st[i].com),
                    None => crate::body::pose_and_com(&bodies[b]),
                }
            };
            let f = FramePair::at(&e.low, side(e.body1, slots[0]), side(e.body2, slots[1]));
            let (r0, n) = (kkt.row_offset(k), e.state.rows.len());
            let values = &mut value[r0..r0 + n];
            if what == Eval::Values {
                let d = f.p2 - f.p1;
                for (v, row) in values.iter_mut().zip(&e.state.rows) {
                    *v = match *row {
                        RowKind::Linear { axis } => linear_value(&f, d, axis),
                        RowKind::Angular { a, b, target } => angular_value(&f, a, b, target),
                        _ => row.value(&f),
                    };
                }
                continue;
            }
            let arms = f.arms();
            let (outs, _) = jac[JAC_ROW_STRIDE * r0..JAC_ROW_STRIDE * (r0 + n)]
                .as_chunks_mut::<JAC_ROW_STRIDE>();
            for ((v, row), out) in values.iter_mut().zip(&e.state.rows).zip(outs) {
                // Each arm stores its own result: merged into one `RowEval` first, the three
                // went through a stack slot (0.9 % more instructions on the 100-link chain).
                match *row {
                    RowKind::Linear { axis } => put_row(out, v, linear_row(&f, &arms, axis)),
                    RowKind::Angular { a, b, target } => {
                        put_row(out, v, angular_row(&f, a, b, target));
                    }
                    _ => put_row(out, v, row.eval(&f)),
                }
            }
        }
    }

    /// From the Jacobian arena and the bodies' current states: each row's kinematic term (the
    /// rate a non-dynamic side gives it), whether it is a penalty row and its stiffness, and
    /// its compliance.
    ///
    /// Each joint's two sides are read once (a dynamic side's mass and inverse inertia, a
    /// non-dynamic side's velocities) and the arrays are local slices: read through `self`
    /// per row, with the stores between, this pass took 192 instructions a row, 167 now
    /// (callgrind, mixed scene at 50 arms; the same results to the bit).
    ///
    /// Once per step on a plain tree island without penalty rows or kinematic bodies, at the
    /// nominal regularisation (`terms_fresh`): there every term but the hard rows' compliance
    /// is zero, and that compliance, the regularisation times the row's effective inverse
    /// mass, only preconditions the solves (the projection converges on the rows' values,
    /// and the velocity projection's refinement takes its bias out), so the inverse mass at
    /// the first evaluation of the step serves its other substeps. Measured (2026-11-27,
    /// callgrind, 1/60 s x 4): -4.4 % instructions per step on the 100-link chain, -4.3 % at
    /// 1:1000, -4.8 % on the mixed scene of 20 arms, -4.0 % on the pendulum; `joint_bench
    /// --quick`'s accuracy tables the same but for two round-off figures (the pendulum's RATTLE
    /// drift -2.88e-12 -> -4.06e-12 J, the penalty table's Lagrange gap 9.78e-12 -> 8.76e-12
    /// m).
    pub(super) fn constraint_terms(&mut self, joints: &JointSet, bodies: &RigidBodySet, h: Real) {
        let steady = self.plain
            && !self.has_kinematic
            && self.regularisation < REGULARISATION_LOOPS
            && self.reg_scale == 1.0;
        if steady && self.terms_fresh {
            return;
        }
        self.terms_fresh = false;
        let Some(kkt) = self.kkt.as_ref() else { return };
        let reg = self.regularisation * self.reg_scale;
        let (jac, st) = (&self.jac[..], &self.st[..]);
        let (kin, penalty) = (&mut self.kin[..], &mut self.penalty[..]);
        let (kpen, compliance) = (&mut self.kpen[..], &mut self.compliance[..]);
        for (k, &j) in self.blocks.iter().enumerate() {
            let Some(e) = joints.get(j) else { continue };
            let [i1, i2] = kkt.joint_specs()[k].bodies;
            let (kd, kr) = match e.joint.method {
                ConstraintMethod::Lagrange => (None, None),
                ConstraintMethod::Penalty { disp, rot } => (
                    Some(penalty_stiffness(disp, DEFAULT_PENALTY_DISP)),
                    Some(penalty_stiffness(rot, DEFAULT_PENALTY_ROT)),
                ),
            };
            let side = |slot: Option<usize>, b: RigidBodyHandle| match slot {
                Some(i) => Side::Dynamic(st[i].mass, st[i].inertia_inv),
                // Velocity of a non-dynamic side (kinematic bodies; zero for fixed ones).
                None => {
                    let rb = &bodies[b];
                    Side::Moving(rb.linvel(), rb.angvel())
                }
            };
            let sides = [side(i1, e.body1), side(i2, e.body2)];
            let r0 = kkt.row_offset(k);
            let n = e.state.rows.len();
            let rows =
                jac[JAC_ROW_STRIDE * r0..JAC_ROW_STRIDE * (r0 + n)].chunks_exact(JAC_ROW_STRIDE);
            for ((r, row), jr) in (r0..).zip(&e.state.rows).zip(rows) {
                let k_pen = match row {
                    RowKind::Linear { .. } | RowKind::Screw { .. } | RowKind::Distance { .. } => kd,
                    RowKind::Drive { .. } | RowKind::Spin { .. } => None,
                    RowKind::Angular { .. } => kr,
                };
                // The row's effective inverse mass `a`, read by a hard row only: computed for
                // every row, since skipping it on penalty rows (a branch per side) cost the
                // hard rows more (callgrind: +0.1 % of the mixed scene's step).
                let (mut rate, mut a) = (0.0, 0.0);
                for (side, half) in sides.iter().zip(jr.chunks_exact(6)) {
                    let lin = Vector::new(half[0], half[1], half[2]);
                    let ang = Vector::new(half[3], half[4], half[5]);
                    match side {
                        Side::Dynamic(mass, inertia_inv) => {
                            a += lin.length_squared() / mass + ang.dot(*inertia_inv * ang);
                        }
                        Side::Moving(v, w) => rate += lin.dot(*v) + ang.dot(*w),
                    }
                }
                kin[r] = rate;
                penalty[r] = k_pen.is_some();
                kpen[r] = k_pen.unwrap_or(0.0);
                compliance[r] = match k_pen {
                    Some(k) => 1.0 / (k * h * h),
                    // A relative regularisation of the hard rows (`regularisation` times the
                    // row's own effective inverse mass): it bounds the multipliers in directions
                    // that become dependent at a singular pose (a parallelogram four-bar passing
                    // its aligned position) and changes the solution of a well-posed system by
                    // that relative amount only (see `REGULARISATION_LOOPS` and `_TREE`).
                    None => reg * a,
                };
            }
        }
        // Read from the flags just written: a penalty row's compliance depends on `h`, which a
        // composed step's stages change.
        self.terms_fresh = steady && !self.penalty.iter().any(|p| *p);
    }

    /// Mass blocks (with added inertia from the last substep's joint forces) and factorisation.
    pub(super) fn factor(
        &mut self,
        joints: &JointSet,
        bodies: &RigidBodySet,
        h: Real,
        time: Real,
    ) -> Result<(), Error> {
        self.mass_blocks(joints, bodies, h);
        self.factor_blocks(time)
    }

    /// The factorisation of the mass blocks ([`Island::mass_blocks`]), the Jacobian and the
    /// compliances, with its report.
    pub(super) fn factor_blocks(&mut self, time: Real) -> Result<(), Error> {
        let Some(kkt) = self.kkt.as_mut() else {
            return Ok(());
        };
        let report = kkt
            .factor(&self.mass, &self.jac, &self.compliance)
            .map_err(|e| kkt_err(e, time))?;
        self.note_factor(report, time);
        Ok(())
    }

    /// The mass blocks the factorisation reads: each body's mass and inertia, with the added
    /// inertia from the last substep's joint forces. Only the diagonal masses and the inertia
    /// block are written: the other entries are zero from the topology on (nothing else
    /// writes them), and clearing all 36 each substep cost 0.3 % of the chains' step.
    pub(super) fn mass_blocks(&mut self, joints: &JointSet, bodies: &RigidBodySet, h: Real) {
        self.added_inertia(joints, bodies, h);
        for (m, s) in self.mass.iter_mut().zip(&self.st) {
            for a in 0..3 {
                m[6 * a + a] = s.mass;
                for b in 0..3 {
                    m[6 * (3 + a) + 3 + b] = s.inertia.col(b)[a];
                }
                m[6 * (3 + a) + 3 + a] += s.added;
            }
        }
    }

    /// A factorisation's report into the island's: its redundant rows, with a warning.
    pub(super) fn note_factor(&mut self, report: FactorReport, time: Real) {
        // The topology check (unregularised) found the structural redundancy; a regularised
        // factorisation only sees rows that are dependent numerically as well.
        self.report.redundant_rows = report.redundant_rows.max(self.redundant_count);
        if report.redundant_rows > 0 {
            self.warn(
                Warning::Redundant,
                format!(
                    "t = {time}: {} redundant constraint row(s): the constraint Jacobian is rank \
                     deficient, the multipliers of the dependent rows are not unique (the solve \
                     regularises them; the motion is unaffected)",
                    report.redundant_rows
                ),
            );
        }
    }

    /// Geometric stiffness as added rotational inertia (see the module docs): each joint's
    /// force of the last substep, `F` on body 2 and `-F` on body 1, acts at frame 2's origin `p`;
    /// a body turning about its centre `c` against it has the stiffness `|F| |p - c|`, and
    /// takes the share of `h^2 |F| |p - c|` that its `(h omega)^2` gives (a smoothstep from 0
    /// at 1/4 to 1 at 1).
    fn added_inertia(&mut self, joints: &JointSet, bodies: &RigidBodySet, h: Real) {
        let Some(kkt) = self.kkt.as_ref() else { return };
        // Per body: the summed stiffness |F| r of its joints and the longest lever arm r.
        let mut load = core::mem::take(&mut self.load);
        load.clear();
        load.resize(self.st.len(), (0.0, 0.0));
        for (k, &j) in self.blocks.iter().enumerate() {
            let Some(e) = joints.get(j) else { continue };
            let r0 = kkt.row_offset(k);
            let mut force = Vector::ZERO;
            for r in r0..r0 + e.state.rows.len() {
                let jr = &self.jac[JAC_ROW_STRIDE * r..JAC_ROW_STRIDE * (r + 1)];
                force += Vector::new(jr[6], jr[7], jr[8]) * (self.impulse[r] / h);
            }
            let force = force.length();
            let slots = kkt.joint_specs()[k].bodies;
            let p = match slots[1] {
                Some(i) => (self.st[i].pose * e.low[1]).translation,
                None => (*bodies[e.body2].position() * e.low[1]).translation,
            };
            // A rigid link's force acts on body 1 at node I, the other end of the bar.
            let link = matches!(e.joint.kind, JointKind::RigidLink);
            for (side, i) in slots.into_iter().enumerate() {
                let Some(i) = i else { continue };
                let at = if link && side == 0 {
                    (self.st[i].pose * e.low[0]).translation
                } else {
                    p
                };
                let r = (at - self.st[i].com).length();
                load[i].0 += force * r;
                load[i].1 = load[i].1.max(r);
            }
        }
        let mut stiffened = 0;
        // Second order on a redundant structure: no added inertia. The multipliers of dependent
        // rows are set by the regularisation, not by the physics, and grow without bound where
        // the rows become nearly dependent (a parallelogram four-bar passing its singular pose),
        // so the force estimate is meaningless there; the added inertia it switched on cost
        // RATTLE 1e-3 of the four-bar's energy per passage at h = 1/240 s. (The first-order
        // scheme keeps it: its velocities live at half steps and it never tripped there.)
        let skip = self.second_any && self.redundant;
        for (s, &(kg, r)) in self.st.iter_mut().zip(&load) {
            if skip {
                s.added = 0.0;
                continue;
            }
            let omega2 = kg / (s.min_inertia + s.mass * r * r);
            // The ramp, not a step at 1/4: the force estimate moves by ~15 % between the
            // substeps of a step (the velocity projection is refined at its last one only), and
            // a switch the estimate crosses toggled the mass matrix and pumped energy.
            let t = ((omega2 * h * h - 0.25) / 0.75).clamp(0.0, 1.0);
            s.added = if t > 0.0 {
                stiffened += 1;
                t * t * (3.0 - 2.0 * t) * h * h * kg
            } else {
                0.0
            };
            // The composition keeps the mass matrix (its factorisation serves every stage
            // size); a body that needs the added inertia turns the island to RATTLE.
            if self.composed {
                s.added = 0.0;
            }
        }
        if self.composed {
            // Any positive stage of the step counts (see `Island::step_plain`).
            self.would_stiffen |= stiffened > 0 && h > 0.0;
            stiffened = 0;
        } else {
            self.would_stiffen = stiffened > 0;
        }
        self.report.stiffened_bodies = stiffened;
        self.load = load;
    }

    /// Counts the redundant hard rows once per topology: one factorisation without the
    /// regularisation (which otherwise keeps every pivot away from zero) and a warning.
    pub(super) fn redundancy_check(
        &mut self,
        joints: &JointSet,
        bodies: &RigidBodySet,
        h: Real,
        time: Real,
    ) -> Result<(), Error> {
        let saved = self.compliance.clone();
        for (c, &k) in self.compliance.iter_mut().zip(&self.kpen) {
            if k == 0.0 {
                *c = 0.0;
            }
        }
        self.redundant_count = 0;
        let result = self.factor(joints, bodies, h, time);
        self.compliance = saved;
        self.redundant_count = self.report.redundant_rows;
        self.redundant = self.report.redundant_rows > 0;
        if self.redundant && self.regularisation < REGULARISATION_LOOPS {
            // A tree with dependent rows (a joint's own rows at a singular pose): the
            // multipliers need the loops' regularisation.
            let scale = REGULARISATION_LOOPS / self.regularisation;
            self.regularisation = REGULARISATION_LOOPS;
            for (c, &k) in self.compliance.iter_mut().zip(&self.kpen) {
                if k == 0.0 {
                    *c *= scale;
                }
            }
        }
        result
    }
}

/// Stores one row's evaluation: its value into `value`, its Jacobian blocks (body 1 linear,
/// angular; body 2 linear, angular) into its slot `out` of the Jacobian arena.
#[inline(always)]
fn put_row(out: &mut [Real; JAC_ROW_STRIDE], value: &mut Real, ev: RowEval) {
    *value = ev.value;
    for (dst, b) in out
        .chunks_exact_mut(3)
        .zip([ev.j1[0], ev.j1[1], ev.j2[0], ev.j2[1]])
    {
        dst.copy_from_slice(&[b.x, b.y, b.z]);
    }
}
