//! Divergence with nothing lost.
//!
//! [`Mpc184World::step`] saves at its start what a step changes (a checkpoint: every
//! non-fixed body's pose, velocities and user force and torque; every joint's rows (screw and
//! drive references, lock rows), behaviour state (stops, locks, friction), output and angle
//! unwrapping; the energy ledger and the time; on the multibody backend the multibody set). It
//! then steps and checks the result. On any error it finds the joint to blame, puts the
//! checkpoint back and returns [`Error::Diverged`] naming the joint and the time of that last
//! good state: the world is exactly as it was after the last successful step (bit for bit), so
//! that a caller can write its results up to there, or change the time step and go on. Solver
//! caches are not part of that state and start afresh at the next step: the Lagrange backend's
//! factorisation and warm starts (rebuilt from the restored state), Rapier's contact and
//! impulse-joint warm starts; nor are the bodies' sleep flags (a step that blows up does not put
//! bodies to sleep).
//!
//! The check after each step ([`DivergenceLimits`]) is a guard against blow-up, not an accuracy
//! test:
//!
//! - every body's pose and velocity, and every joint's output, is finite;
//! - every joint's translational constraint error ([`JointOutput::gap`]: the largest `|C|` of
//!   its linear and screw rows) is at most `gap_fraction` (default 0.1) of the model size, the
//!   diagonal of the box holding the joints' nodes and the jointed bodies' centres of mass give
//!   or take their radii of gyration;
//! - every joint's rotational constraint error ([`JointOutput::angular_gap`], the largest
//!   `|e_a . f_b - target|` of its angular rows, about the sine of the angle error) is at most
//!   `angular_gap` (default 0.5, about 30 degrees);
//! - no joint turns by more than `turn_per_step` (default pi, half a turn) in one step: its
//!   relative angular velocity ([`JointOutput::angular_velocity`]) times the step `dt`.
//!
//! A working Lagrange joint holds its rows to the projection tolerance (1e-10); a penalty joint
//! deflects by its load over its stiffness (10 um for 1 kN at the default 1e8 N/m); Rapier's
//! impulse joints open by centimetres under heavy loads. A joint ten percent of the model apart,
//! or turned 30 degrees off its constraint, is no longer that joint: the run has blown up
//! (an unstable step grows the error by orders of magnitude per step, so the bound's exact value
//! hardly changes the step at which it trips). A joint turning half a turn per step is past
//! what the output can follow: its rotations are unwrapped once per step, from the nearest
//! branch of the angle, so the reported angle would be wrong by whole turns (the screw's and
//! the drives' references are unwrapped per substep, four times finer). A blow-up that keeps
//! every constraint, such as an explicit spring far too stiff for the step (`omega h` past 2:
//! its swing grows each substep), shows here: the joint spins faster and faster.
//!
//! The cost is the checkpoint's copies (about 100 bytes per body and 700 per joint per step) and
//! one pass over the joints' outputs: 0.3 % of a step of the 10-link chain and 0.5 to 1 % of
//! the 100-link chain (Lagrange, 4 substeps; measured 20 to 40 us of a 3.7 to 4.7 ms step on a
//! loaded machine).
//!
//! The joint blamed: the one whose bound was passed (the largest ratio of error to bound); when
//! a solve failed or a body turned non-finite inside the step, a joint on a non-finite body
//! (among them the one nearest to a bound at the last good state), else the joint with the
//! largest constraint error relative to its bound at the failed state.

use crate::effects::{EffectState, EnergyLedger};
use crate::error::{Error, JointId};
use crate::kinematics::AngleUnwrap;
use crate::lower::Backend;
use crate::math::rapier::dynamics::{MultibodyJointSet, RigidBodyHandle};
use crate::math::{Pose, Real, Vector};
use crate::rows::RowKind;
use crate::world::{JointEntry, JointOutput, Mpc184World};

/// Bounds past which a step counts as diverged (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DivergenceLimits {
    /// Largest translational constraint error of a joint, as a fraction of the model size
    /// (default 0.1).
    pub gap_fraction: Real,
    /// Largest rotational constraint error of a joint (about the sine of the angle error;
    /// default 0.5).
    pub angular_gap: Real,
    /// Largest relative rotation of a joint in one step, its relative angular velocity times
    /// `dt` (rad; default pi).
    pub turn_per_step: Real,
}

impl Default for DivergenceLimits {
    fn default() -> Self {
        Self {
            gap_fraction: 0.1,
            angular_gap: 0.5,
            turn_per_step: crate::math::PI,
        }
    }
}

/// The limits in absolute terms for one check.
struct Bounds {
    size: Real,
    gap: Real,
    angular: Real,
    /// Largest relative angular velocity (rad/s).
    rate: Real,
}

impl Bounds {
    /// Each measure of a joint's output over its bound: translational error, rotational
    /// error, rotation per step (infinite for a non-finite output).
    fn ratios(&self, o: &JointOutput) -> [Real; 3] {
        if !output_finite(o) {
            return [Real::INFINITY; 3];
        }
        [
            o.gap / self.gap,
            o.angular_gap / self.angular,
            o.angular_velocity.length() / self.rate,
        ]
    }
}

/// One body's state at a step's start.
#[derive(Clone, Copy, Debug)]
struct BodySave {
    handle: RigidBodyHandle,
    pose: Pose,
    linvel: Vector,
    angvel: Vector,
    force: Vector,
    torque: Vector,
}

/// One joint's state at a step's start.
#[derive(Clone, Debug, Default)]
struct JointSave {
    rows: Vec<RowKind>,
    effects: EffectState,
    output: JointOutput,
    unwrap: [AngleUnwrap; 3],
}

/// What a step changes, saved at its start (buffers reused from step to step).
#[derive(Default)]
pub(crate) struct Checkpoint {
    time: Real,
    last_h: Real,
    started: bool,
    ledger: EnergyLedger,
    bodies: Vec<BodySave>,
    joints: Vec<Option<JointSave>>,
    multibody: Option<MultibodyJointSet>,
}

impl Mpc184World {
    /// The bounds a step is checked against.
    pub fn divergence_limits(&self) -> DivergenceLimits {
        self.limits
    }

    /// Changes the bounds a step is checked against (see [`DivergenceLimits`]).
    ///
    /// # Errors
    /// [`Error::InvalidSetting`] unless both bounds are positive (an infinite bound switches
    /// that check off).
    pub fn set_divergence_limits(&mut self, limits: DivergenceLimits) -> Result<(), Error> {
        for (field, value) in [
            ("gap_fraction", limits.gap_fraction),
            ("angular_gap", limits.angular_gap),
            ("turn_per_step", limits.turn_per_step),
        ] {
            if value.is_nan() || value <= 0.0 {
                return Err(Error::InvalidSetting {
                    field,
                    value,
                    reason: "a divergence bound must be positive",
                });
            }
        }
        self.limits = limits;
        Ok(())
    }

    /// The model size the translational bound is a fraction of (m): the diagonal of the box
    /// holding the joints' nodes and the jointed bodies' centres of mass, give or take their
    /// radii of gyration (1 m if that box is a point). Measured at the first step after the
    /// joints last changed (now, if no step was taken since), so that a body flying away does
    /// not widen its own bound.
    pub fn model_size(&self) -> Real {
        self.model_size.unwrap_or_else(|| self.measure_model_size())
    }

    /// Measures the model size now (see [`Mpc184World::model_size`]).
    fn measure_model_size(&self) -> Real {
        let (mut lo, mut hi) = (
            Vector::splat(Real::INFINITY),
            Vector::splat(-Real::INFINITY),
        );
        let mut add = |p: Vector| {
            if p.is_finite() {
                lo = lo.min(p);
                hi = hi.max(p);
            }
        };
        for e in self.joints.iter().flatten() {
            for (b, frame) in [(e.body1, e.ansys[0]), (e.body2, e.ansys[1])] {
                let rb = &self.physics.bodies[b];
                add(*rb.position() * frame.translation);
                if rb.is_dynamic() && rb.mass() > 0.0 {
                    let c = rb.center_of_mass();
                    let ip = rb.mass_properties().local_mprops.principal_inertia();
                    let r = (ip.max_element() / rb.mass()).sqrt();
                    add(c - Vector::splat(r));
                    add(c + Vector::splat(r));
                }
            }
        }
        let d = (hi - lo).length();
        if d.is_finite() && d > 0.0 { d } else { 1.0 }
    }

    /// Saves what the coming step changes (at its start).
    pub(crate) fn checkpoint_save(&mut self) {
        if self.model_size.is_none() {
            self.model_size = Some(self.measure_model_size());
        }
        let cp = &mut self.checkpoint;
        cp.time = self.time;
        cp.last_h = self.last_h;
        cp.started = self.started;
        cp.ledger = self.ledger;
        cp.bodies.clear();
        for (handle, rb) in self.physics.bodies.iter() {
            if rb.is_fixed() {
                continue;
            }
            cp.bodies.push(BodySave {
                handle,
                pose: *rb.position(),
                linvel: rb.linvel(),
                angvel: rb.angvel(),
                force: rb.user_force(),
                torque: rb.user_torque(),
            });
        }
        cp.joints.truncate(self.joints.len());
        cp.joints.resize_with(self.joints.len(), || None);
        for (slot, e) in cp.joints.iter_mut().zip(&self.joints) {
            let Some(e) = e else {
                *slot = None;
                continue;
            };
            let s = slot.get_or_insert_with(JointSave::default);
            s.rows.clone_from(&e.rows);
            s.effects.clone_from(&e.effects);
            s.output = e.output;
            s.unwrap = e.unwrap;
        }
        cp.multibody = (self.settings.backend == Backend::RapierMultibody)
            .then(|| self.physics.multibody_joints.clone());
    }

    /// Puts the checkpoint back after a failed step and returns the error, a divergence naming
    /// the joint and the time of the state kept.
    pub(crate) fn roll_back(&mut self, err: Error) -> Error {
        let culprit = match &err {
            Error::Diverged { joint: Some(j), .. } => Some(*j),
            Error::Diverged { joint: None, .. } => self.culprit(),
            _ => None,
        };
        let cp = &mut self.checkpoint;
        self.time = cp.time;
        self.last_h = cp.last_h;
        self.started = cp.started;
        self.ledger = cp.ledger;
        for s in &cp.bodies {
            let Some(rb) = self.physics.bodies.get_mut(s.handle) else {
                continue;
            };
            rb.set_position(s.pose, false);
            rb.set_linvel(s.linvel, false);
            rb.set_angvel(s.angvel, false);
            rb.reset_forces(false);
            rb.reset_torques(false);
            rb.add_force(s.force, false);
            rb.add_torque(s.torque, false);
        }
        for (e, s) in self.joints.iter_mut().zip(&cp.joints) {
            if let (Some(e), Some(s)) = (e, s) {
                e.rows.clone_from(&s.rows);
                e.effects.clone_from(&s.effects);
                e.output = s.output;
                e.unwrap = s.unwrap;
            }
        }
        if let Some(mb) = cp.multibody.take() {
            self.physics.multibody_joints = mb;
        }
        // The solver's factorisation and warm starts belong to the failed step: rebuilt from
        // the restored state at the next step.
        self.lagrange.dirty = true;
        match err {
            Error::Diverged { reason, .. } => Error::Diverged {
                time: self.time,
                joint: culprit,
                reason,
            },
            other => other,
        }
    }

    fn bounds(&self) -> Bounds {
        let size = self.model_size();
        Bounds {
            size,
            gap: self.limits.gap_fraction * size,
            angular: self.limits.angular_gap,
            rate: self.limits.turn_per_step / self.settings.dt,
        }
    }

    /// Checks the state after a step against the limits (see the module docs).
    pub(crate) fn check_divergence(&self) -> Result<(), Error> {
        let b = self.bounds();
        let mut worst: Option<(usize, Real)> = None;
        for (j, e) in self.joints.iter().enumerate() {
            let Some(e) = e else { continue };
            let r = b.ratios(&e.output).into_iter().fold(0.0, Real::max);
            if r > 1.0 && worst.is_none_or(|(_, w)| r > w) {
                worst = Some((j, r));
            }
        }
        let Some((j, _)) = worst else {
            return Ok(());
        };
        let Some(e) = &self.joints[j] else {
            return Ok(());
        };
        let o = &e.output;
        let [g, a, t] = b.ratios(o);
        let reason = if !output_finite(o) {
            "non-finite joint output (relative motion or reaction)".to_string()
        } else if g >= a && g >= t {
            format!(
                "translational constraint error {:.3e} m past the divergence bound {:.3e} m \
                 ({} of the model size {:.3e} m)",
                o.gap, b.gap, self.limits.gap_fraction, b.size
            )
        } else if a >= t {
            format!(
                "rotational constraint error {:.3e} past the divergence bound {:.3e}",
                o.angular_gap, b.angular
            )
        } else {
            let w = o.angular_velocity.length();
            format!(
                "relative angular velocity {w:.3e} rad/s turns the joint {:.3e} rad in one step, \
                 past the divergence bound {:.3e} rad (a blow-up, or a step too long for the \
                 joint's speed)",
                w * self.settings.dt,
                self.limits.turn_per_step
            )
        };
        Err(Error::Diverged {
            time: self.time,
            joint: Some(JointId(j as u32)),
            reason,
        })
    }

    /// The joint to blame for a failure found without one (see the module docs).
    fn culprit(&self) -> Option<JointId> {
        let b = self.bounds();
        let mut best: Option<(usize, (bool, Real))> = None;
        for (j, e) in self.joints.iter().enumerate() {
            let Some(e) = e else { continue };
            let broken = !(self.body_finite(e.body1) && self.body_finite(e.body2));
            let r = if broken {
                // Rank the joints on broken bodies by how near they were to a bound at the last
                // good state (a force element blowing up drives its own DOF hardest; its
                // neighbours only feel its reactions through the bodies' inertia), with the
                // relative translation per step over the translational bound as a fourth
                // measure.
                let dt = self.settings.dt;
                self.checkpoint
                    .joints
                    .get(j)
                    .and_then(Option::as_ref)
                    .map_or(0.0, |s| {
                        let o = &s.output;
                        b.ratios(o)
                            .into_iter()
                            .fold(o.velocity.length() * dt / b.gap, Real::max)
                    })
            } else {
                let (gap, angular) = self.joint_gaps(e);
                (gap / b.gap).max(angular / b.angular)
            };
            let r = if r.is_nan() { Real::INFINITY } else { r };
            if best.is_none_or(|(_, x)| (broken, r) > x) {
                best = Some((j, (broken, r)));
            }
        }
        best.map(|(j, _)| JointId(j as u32))
    }

    /// A body's pose and velocity are finite, in Rapier and in the Lagrange solver's copy.
    fn body_finite(&self, b: RigidBodyHandle) -> bool {
        let rb = &self.physics.bodies[b];
        let p = rb.position();
        let rapier = p.translation.is_finite()
            && p.rotation.is_finite()
            && rb.linvel().is_finite()
            && rb.angvel().is_finite();
        let solver = self
            .lagrange
            .index
            .get(&b)
            .and_then(|&i| self.lagrange.st.get(i))
            .is_none_or(|s| {
                s.pose.translation.is_finite()
                    && s.pose.rotation.is_finite()
                    && s.linvel.is_finite()
                    && s.angvel.is_finite()
            });
        rapier && solver
    }

    /// Translational and rotational constraint errors of a joint's rows at the bodies' current
    /// poses in Rapier (m, ~rad; drives excluded).
    pub(crate) fn joint_gaps(&self, e: &JointEntry) -> (Real, Real) {
        let p1 = *self.physics.bodies[e.body1].position();
        let p2 = *self.physics.bodies[e.body2].position();
        let fp = crate::world::frame_pair(&e.low, (p1, Vector::ZERO), (p2, Vector::ZERO));
        let (mut gap, mut angular_gap): (Real, Real) = (0.0, 0.0);
        for r in &e.rows {
            let c = r.eval(&fp).value.abs();
            match r {
                RowKind::Linear { .. } | RowKind::Screw { .. } | RowKind::Distance { .. } => {
                    gap = gap.max(c);
                }
                // A drive's error is a tracking error, not a gap.
                RowKind::Drive { .. } => {}
                RowKind::Angular { .. } => angular_gap = angular_gap.max(c),
            }
        }
        (gap, angular_gap)
    }
}

fn output_finite(o: &JointOutput) -> bool {
    o.gap.is_finite()
        && o.angular_gap.is_finite()
        && o.displacement.is_finite()
        && o.rotation.is_finite()
        && o.velocity.is_finite()
        && o.angular_velocity.is_finite()
        && o.force.is_finite()
        && o.moment.is_finite()
}
