//! Divergence with nothing lost.
//!
//! `Mpc184World::step` saves at its start what a step changes (a checkpoint: every
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
//! - every joint's translational constraint error ([`JointOutput::gap`](crate::output::JointOutput::gap): the largest `|C|` of
//!   its linear and screw rows) is at most `gap_fraction` (default 0.1) of the model size, the
//!   diagonal of the box holding the joints' nodes and the jointed bodies' centres of mass give
//!   or take their radii of gyration;
//! - every joint's rotational constraint error ([`JointOutput::angular_gap`](crate::output::JointOutput::angular_gap), the largest
//!   `|e_a . f_b - target|` of its angular rows, about the sine of the angle error) is at most
//!   `angular_gap` (default 0.5, about 30 degrees);
//! - no joint turns by more than `turn_per_step` (default pi, half a turn) in one step: its
//!   relative angular velocity ([`JointOutput::angular_velocity`](crate::output::JointOutput::angular_velocity)) times the step `dt`;
//! - the energy guard: the step creates at most `energy_growth` (default 0.25) of the energy
//!   scale that the ledger does not explain: the balance `kinetic + potential + spring +
//!   dissipated - work` ([`EnergyReport::total`]) may not grow by more than that in one step.
//!   The scale is the largest `kinetic + spring + |work| + dissipated` seen so far, the state
//!   after the step included, plus the range of gravitational energy seen, and at least what
//!   the loads could do over the model size (every body's weight and every joint load times
//!   the model size, at least 1 m or 1 rad) and at least [`GUARD_FLOOR`] (1 uJ):
//!   a step that multiplies the energy by `r` creates `(r - 1) / r` of the scale after it, so
//!   the guard trips for any growth faster than 1.33 per step. Every source of work is booked
//!   (joint loads and drives, springs and dampers, user forces and torques, gravity changed
//!   with `Mpc184World::set_gravity`, kinematic bodies through their joints; not yet the
//!   contacts, whose impulses dissipate, and velocities or gravity changed between steps, which
//!   the guard does not see), so a working step moves the balance by its integration error
//!   only (`tests/energy_ledger.rs`: 5.3e-6 J of 9.81 J over the 20 s ramped-gravity
//!   pendulum). An explicit spring past
//!   its stability limit gains a factor `(omega h)^2` of its energy per substep and trips the
//!   guard in the first step that does so; the joint named is one on the body with the largest
//!   kinetic energy after the step.
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

use crate::backend::{BackendSave, JointBackend};
use crate::error::{Error, JointId};
use crate::joint_set::{JointSet, SavedStates};
use crate::math::rapier::dynamics::RigidBodyHandle;
use crate::math::rapier::pipeline::PhysicsWorld;
use crate::math::{Pose, Real, Vector};
use crate::output::{EnergyLedger, EnergyReport, JointOutput};

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
    /// Largest energy one step may create beyond what the ledger books (loads, drives, user
    /// forces, gravity changes, kinematic bodies), as a fraction of the run's energy scale
    /// (default 0.25; see the module docs).
    pub energy_growth: Real,
}

impl Default for DivergenceLimits {
    fn default() -> Self {
        Self {
            gap_fraction: 0.1,
            angular_gap: 0.5,
            turn_per_step: crate::math::PI,
            energy_growth: 0.25,
        }
    }
}

impl DivergenceLimits {
    /// `Ok` if every bound is positive (an infinite bound switches that check off), else
    /// [`Error::InvalidSetting`] naming the field.
    pub fn validate(&self) -> Result<(), Error> {
        for (field, value) in [
            ("gap_fraction", self.gap_fraction),
            ("angular_gap", self.angular_gap),
            ("turn_per_step", self.turn_per_step),
            ("energy_growth", self.energy_growth),
        ] {
            if value.is_nan() || value <= 0.0 {
                return Err(Error::InvalidSetting {
                    field,
                    value,
                    reason: "a divergence bound must be positive",
                });
            }
        }
        Ok(())
    }
}

/// How far a world has run: what a step advances besides the bodies and the joints.
#[derive(Clone, Copy, Debug, Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct Progress {
    /// Simulated time (s).
    pub(crate) time: Real,
    /// The substep of the last step (s).
    pub(crate) last_h: Real,
    /// Energy dissipated and work done so far.
    pub(crate) ledger: EnergyLedger,
    /// The energy guard's scale so far (J): the largest `kinetic + spring + |work| +
    /// dissipated` seen, plus the range of the gravitational energy seen.
    pub(crate) energy_scale: Real,
    pub(crate) potential_range: Option<(Real, Real)>,
}

impl Progress {
    /// Takes an energy report into the guard's scale and returns the scale (J; see
    /// [`check_energy`]; `floor` is the scale the loads give a world at rest).
    pub(crate) fn scale_with(&mut self, e: &EnergyReport, floor: Real) -> Real {
        let own = e.kinetic + e.spring.abs() + e.work.abs() + e.dissipated.abs();
        if own.is_finite() {
            self.energy_scale = self.energy_scale.max(own);
        }
        if e.potential.is_finite() {
            let (lo, hi) = self.potential_range.unwrap_or((e.potential, e.potential));
            self.potential_range = Some((lo.min(e.potential), hi.max(e.potential)));
        }
        let range = self.potential_range.map_or(0.0, |(lo, hi)| hi - lo);
        (self.energy_scale + range).max(floor).max(GUARD_FLOOR)
    }
}

/// The smallest energy scale of the guard (J): a world at rest with nothing to move has no
/// scale of its own, and its round-off must not trip the guard.
pub const GUARD_FLOOR: Real = 1e-6;

/// The energy the loads could put into a world at rest over the step from `time` to `end`
/// (J): every dynamic body's weight (N, `weight`: the sum of `m |gravity scale| |g|`) over the
/// model size, and every joint load (N or N m, the largest it takes in the step: a load that
/// steps up within it counts) over the model size or 1 rad.
pub(crate) fn load_scale(
    weight: Real,
    joints: &JointSet,
    size: Real,
    time: Real,
    end: Real,
) -> Real {
    (weight + joints.load_magnitude(time, end)) * size.max(1.0)
}

/// The energy guard: a step whose balance (`EnergyReport::total`) grew by more than
/// `energy_growth` of the scale `scale` (J, with the states before and after the step: an
/// unstable step that multiplies the energy by `r` creates `(r - 1) / r` of the scale after it,
/// so the guard trips for any growth faster than 1 / (1 - 0.25) = 1.33 per step) created energy
/// that nothing booked: a blow-up even while everything stays finite (an explicit spring past its stability
/// limit gains a factor `(omega h)^2` of its energy per substep).
pub(crate) fn check_energy(
    limits: &DivergenceLimits,
    before: &EnergyReport,
    after: &EnergyReport,
    scale: Real,
) -> Result<(), String> {
    let growth = after.total - before.total;
    let bound = limits.energy_growth * scale;
    if growth.is_nan() || growth > bound {
        return Err(format!(
            "the step created {growth:.3e} J that no load, drive, force or spring booked, past \
             the energy guard's bound {bound:.3e} J ({} of the energy scale {scale:.3e} J): an \
             unstable step (for example an explicit spring too stiff for it)",
            limits.energy_growth
        ));
    }
    Ok(())
}

/// The limits in absolute terms for one check.
pub(crate) struct Bounds {
    size: Real,
    gap: Real,
    angular: Real,
    /// Largest relative angular velocity (rad/s).
    rate: Real,
    limits: DivergenceLimits,
    dt: Real,
}

impl Bounds {
    /// The bounds of `limits` for a model of size `size` (m) stepped at `dt` (s).
    pub(crate) fn new(limits: DivergenceLimits, size: Real, dt: Real) -> Bounds {
        Bounds {
            size,
            gap: limits.gap_fraction * size,
            angular: limits.angular_gap,
            rate: limits.turn_per_step / dt,
            limits,
            dt,
        }
    }

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

    /// The largest of a joint's output measures over its bound (above 1: past it; infinite
    /// for a non-finite output). The world takes it as it refreshes each output, and the
    /// joint with the largest one over 1 fails the step ([`Bounds::error`]).
    pub(crate) fn ratio(&self, o: &JointOutput) -> Real {
        self.ratios(o).into_iter().fold(0.0, Real::max)
    }

    /// The divergence of joint `j`, whose output passed a bound after the step that ended at
    /// `time` (see the module docs).
    pub(crate) fn error(&self, joints: &JointSet, j: usize, time: Real) -> Error {
        Error::Diverged {
            time,
            joint: Some(JointId(j as u32)),
            reason: joints
                .get(j)
                .map_or_else(String::new, |e| self.reason(&e.state.output)),
        }
    }

    /// Which bound a joint's output passed, in words.
    fn reason(&self, o: &JointOutput) -> String {
        let [g, a, t] = self.ratios(o);
        if !output_finite(o) {
            "non-finite joint output (relative motion or reaction)".to_string()
        } else if g >= a && g >= t {
            format!(
                "translational constraint error {:.3e} m past the divergence bound {:.3e} m \
                 ({} of the model size {:.3e} m)",
                o.gap, self.gap, self.limits.gap_fraction, self.size
            )
        } else if a >= t {
            format!(
                "rotational constraint error {:.3e} past the divergence bound {:.3e}",
                o.angular_gap, self.angular
            )
        } else {
            let w = o.angular_velocity.length();
            format!(
                "relative angular velocity {w:.3e} rad/s turns the joint {:.3e} rad in one step, \
                 past the divergence bound {:.3e} rad (a blow-up, or a step too long for the \
                 joint's speed)",
                w * self.dt,
                self.limits.turn_per_step
            )
        }
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

/// What a step changes, saved at its start (buffers reused from step to step): the world's
/// [`Progress`], every joint's [`JointState`], every non-fixed body's pose, velocities and user
/// force and torque, and the backend's own part.
#[derive(Default)]
pub(crate) struct Checkpoint {
    progress: Progress,
    bodies: Vec<BodySave>,
    joints: SavedStates,
    backend: BackendSave,
}

impl Checkpoint {
    /// Saves what the coming step changes.
    pub(crate) fn save(
        &mut self,
        physics: &PhysicsWorld,
        joints: &JointSet,
        progress: Progress,
        backend: &JointBackend,
    ) {
        self.progress = progress;
        self.bodies.clear();
        for (handle, rb) in physics.bodies.iter() {
            if rb.is_fixed() {
                continue;
            }
            self.bodies.push(BodySave {
                handle,
                pose: *rb.position(),
                linvel: rb.linvel(),
                angvel: rb.angvel(),
                force: rb.user_force(),
                torque: rb.user_torque(),
            });
        }
        joints.save_states(&mut self.joints);
        backend.save(physics, &mut self.backend);
    }

    /// Puts the checkpoint back; returns the progress saved.
    pub(crate) fn restore(
        &mut self,
        physics: &mut PhysicsWorld,
        joints: &mut JointSet,
        backend: &mut JointBackend,
    ) -> Progress {
        for s in &self.bodies {
            let Some(rb) = physics.bodies.get_mut(s.handle) else {
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
        joints.restore_states(&self.joints);
        // The solver's factorisation and warm starts belong to the failed step: rebuilt from
        // the restored state at the next step.
        backend.restore(physics, &mut self.backend);
        self.progress
    }

    /// The joint to blame for a failure found without one (see the module docs).
    pub(crate) fn culprit(
        &self,
        physics: &PhysicsWorld,
        joints: &JointSet,
        backend: &JointBackend,
        bounds: &Bounds,
    ) -> Option<JointId> {
        let body_finite = |b: RigidBodyHandle| {
            crate::body::is_finite(&physics.bodies[b]) && backend.body_finite(b)
        };
        let mut best: Option<(usize, (bool, Real))> = None;
        for (j, e) in joints.slots().iter().enumerate() {
            let Some(e) = e else { continue };
            let broken = !(body_finite(e.body1) && body_finite(e.body2));
            let r = if broken {
                // Rank the joints on broken bodies by how near they were to a bound at the last
                // good state (a force element blowing up drives its own DOF hardest; its
                // neighbours only feel its reactions through the bodies' inertia), with the
                // relative translation per step over the translational bound as a fourth
                // measure.
                self.joints.output(j).map_or(0.0, |o| {
                    bounds
                        .ratios(o)
                        .into_iter()
                        .fold(o.velocity.length() * bounds.dt / bounds.gap, Real::max)
                })
            } else {
                let (gap, angular) = e.gaps(&physics.bodies);
                (gap / bounds.gap).max(angular / bounds.angular)
            };
            let r = if r.is_nan() { Real::INFINITY } else { r };
            if best.is_none_or(|(_, x)| (broken, r) > x) {
                best = Some((j, (broken, r)));
            }
        }
        best.map(|(j, _)| JointId(j as u32))
    }
}

/// The model size the translational bound is a fraction of (m): the diagonal of the box
/// holding the joints' nodes and the jointed bodies' centres of mass, give or take their radii
/// of gyration (1 m if that box is a point).
pub(crate) fn model_size(physics: &PhysicsWorld, joints: &JointSet) -> Real {
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
    for e in joints.iter() {
        for (b, frame) in [(e.body1, e.ansys[0]), (e.body2, e.ansys[1])] {
            let rb = &physics.bodies[b];
            add(*rb.position() * frame.translation);
            if let Some(r) = crate::body::gyration_radius(rb).filter(|_| rb.is_dynamic()) {
                let c = rb.center_of_mass();
                add(c - Vector::splat(r));
                add(c + Vector::splat(r));
            }
        }
    }
    let d = (hi - lo).length();
    if d.is_finite() && d > 0.0 { d } else { 1.0 }
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
