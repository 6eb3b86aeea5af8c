//! [`Mpc184World`]: Rapier's bodies, colliders and pipeline plus the MPC184 joints.
//!
//! A thin facade: each method checks its arguments and hands the work to the layer that owns
//! it: the joint registry (`joint_set`), the checks (`validate`), the joint backend
//! (`backend`), the static analysis ([`crate::statics`]) and the divergence guard
//! ([`crate::divergence`]).
//!
//! `step()` advances one time step `dt` in `substeps` substeps of `h = dt / substeps`; the
//! backend drives Rapier with one substep per call, so that per-substep forces and rows can be
//! added around each call. After the step every joint's output (relative DOFs in ANSYS terms,
//! their rates, the reaction force and moment on node J in frame I) is refreshed.

use crate::backend::{Capability, JointBackend, LagrangeDiagnostics, OutputPass, Sets};
use crate::divergence::{Bounds, Checkpoint, DivergenceLimits, Progress};
use crate::dof::Dof;
pub use crate::drive::{Drive, DriveLevel, DriveProfile};
use crate::error::{Error, JointId};
use crate::joint::Mpc184Joint;
use crate::joint_set::{JointEntry, JointSet};
use crate::math::rapier::dynamics::RigidBodyHandle;
use crate::math::rapier::pipeline::PhysicsWorld;
use crate::math::{Real, Vector};
pub use crate::output::{EnergyReport, JointOutput};
pub use crate::settings::{Integrator, Outputs, StepControl, WorldSettings};
use crate::spring::{SpringDamper, SpringEntry, SpringId, SpringOutput, SpringSet};
use crate::statics::{StaticReport, StaticState};

mod adaptive;
pub use adaptive::{CutReason, EventKind, StepEvent};

/// Everything of a world but Rapier's physics and the backend's solver state: settings,
/// joints, progress. One value, so that the snapshot serialises it whole (no field can be
/// forgotten there); what a step changes inside it is [`Progress`] and the joints' states,
/// which the divergence checkpoint saves whole.
#[derive(Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct Core {
    pub(crate) settings: WorldSettings,
    pub(crate) limits: DivergenceLimits,
    pub(crate) ground: Option<RigidBodyHandle>,
    pub(crate) joints: JointSet,
    /// The spring-dampers (plain data: their output is computed from the bodies on request).
    pub(crate) springs: SpringSet,
    pub(crate) progress: Progress,
    /// Measured at the first step after the joints changed.
    pub(crate) model_size: Option<Real>,
    /// State of the static (position) analysis.
    pub(crate) statics: StaticState,
    /// What the adaptive step control did so far (outside [`Progress`]: a retry restores that).
    #[cfg_attr(feature = "serde-snapshot", serde(default))]
    pub(crate) stats: StepStats,
    /// The embedded error estimate's velocity samples ([`StepControl::Embedded`]).
    #[cfg_attr(feature = "serde-snapshot", serde(default))]
    pub(crate) history: adaptive::VelocityHistory,
}

/// What [`StepControl::Adaptive`] or [`StepControl::Embedded`] did so far
/// ([`Mpc184World::step_stats`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize),
    serde(default)
)]
pub struct StepStats {
    /// Steps taken (each with the `n` and `2 n` runs of its last try under step doubling, one
    /// run under the embedded estimate).
    pub accepted: u64,
    /// Tries taken again with more substeps (twice under step doubling; the error estimate was
    /// over the tolerance).
    pub rejected: u64,
    /// Steps kept at `max_substeps` with the estimate still over the tolerance.
    pub unmet: u64,
    /// The smallest and largest substep kept (s; 0 before the first step).
    pub smallest_substep: Real,
    /// See `smallest_substep`.
    pub largest_substep: Real,
    /// The error estimate of the last step (m).
    pub last_estimate: Real,
    /// Substeps integrated in all, every run of every try (the cost).
    pub substeps: u64,
    /// The start time of the last step that was cut (taken again with more substeps; s), and
    /// a joint on the body whose error estimate cut it (`None`: no cut yet, or a body without
    /// joints). An event (a stop's impact, a lock engaging, a stick/slip change) shows here:
    /// its velocity jump is part of the estimate.
    pub last_cut: Option<(Real, Option<JointId>)>,
    /// Why that step was cut (`None`: no cut yet).
    pub last_cut_reason: Option<CutReason>,
    /// Events located so far (each taken in a substep of its own, see
    /// [`StepControl::Adaptive`]), and the drives' and loads' profile kinks a step was cut at.
    pub events: u64,
    /// The last event located.
    pub last_event: Option<StepEvent>,
    /// Segments kept on the embedded estimate ([`StepControl::Embedded`]; the others took
    /// step doubling, which refills its samples).
    pub embedded: u64,
    /// The `n` the next step starts with (0: the settings' substeps).
    next: usize,
}

impl Core {
    /// The sets a backend or the static analysis works on: `physics` and this core's joints
    /// and ledger.
    fn sets<'a>(&'a mut self, physics: &'a mut PhysicsWorld) -> Sets<'a> {
        Sets {
            physics,
            joints: &mut self.joints,
            springs: &self.springs,
            ledger: &mut self.progress.ledger,
            time: self.progress.time,
            integrator: self.settings.integrator,
        }
    }
}

/// Rapier's physics world plus MPC184 joints.
///
/// ```
/// use rapier3d_mpc184::prelude::*;
/// use rapier3d_mpc184::math::rapier::prelude::{RigidBodyBuilder, MassProperties};
///
/// let mut world = Mpc184World::new(WorldSettings::default());
/// let bob = world.physics.bodies.insert(
///     RigidBodyBuilder::dynamic()
///         .translation(Vector::new(1.0, 0.0, 0.0))
///         .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, Vector::splat(1e-4))),
/// );
/// let pin = Mpc184Joint::revolute(Axis::Z, Vector::ZERO);
/// let id = world.insert_joint(None, Some(bob), pin).unwrap();
/// for _ in 0..30 {
///     world.step().unwrap();
/// }
/// let out = world.output(id).unwrap();
/// assert!(out.rotation.z < 0.0); // the bob swings down (clockwise about +Z)
/// ```
pub struct Mpc184World {
    /// Rapier's bodies, colliders, joints and pipeline. Add bodies and colliders here; add joints
    /// with [`Mpc184World::insert_joint`].
    pub physics: PhysicsWorld,
    core: Core,
    backend: JointBackend,
    /// What the current step changes, saved at its start ([`crate::divergence`]).
    checkpoint: Checkpoint,
    /// The adaptive control's segment start and bisection probe (see `adaptive`).
    segment: Checkpoint,
    probe: Checkpoint,
}

impl Mpc184World {
    /// An empty world with gravity -9.81 m/s^2 along Y.
    pub fn new(settings: WorldSettings) -> Self {
        let physics = PhysicsWorld {
            gravity: Vector::new(0.0, -9.81, 0.0),
            ..Default::default()
        };
        let core = Core {
            settings,
            progress: Progress {
                last_h: settings.dt / settings.substeps.max(1) as Real,
                ..Progress::default()
            },
            ..Core::default()
        };
        Self::from_parts(physics, core, settings.backend.into())
    }

    /// A world from its parts (a new one, or one read from a snapshot).
    fn from_parts(physics: PhysicsWorld, core: Core, backend: JointBackend) -> Self {
        Self {
            physics,
            core,
            backend,
            checkpoint: Checkpoint::default(),
            segment: Checkpoint::default(),
            probe: Checkpoint::default(),
        }
    }

    /// Serialises the world's complete state (between steps): Rapier's physics, the core and
    /// the backend's own state (see [`crate::snapshot`]). A world restored from it with
    /// [`Mpc184World::from_snapshot`] continues bit for bit as this one does.
    ///
    /// ```
    /// use rapier3d_mpc184::prelude::*;
    /// use rapier3d_mpc184::math::rapier::prelude::{RigidBodyBuilder, MassProperties};
    ///
    /// let mut world = Mpc184World::new(WorldSettings::default());
    /// let bob = world.physics.bodies.insert(
    ///     RigidBodyBuilder::dynamic()
    ///         .translation(Vector::new(1.0, 0.0, 0.0))
    ///         .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, Vector::splat(1e-4))),
    /// );
    /// world.insert_joint(None, Some(bob), Mpc184Joint::revolute(Axis::Z, Vector::ZERO)).unwrap();
    /// world.step().unwrap();
    /// let bytes = world.snapshot().unwrap().into_bytes();
    /// let mut copy = Mpc184World::from_snapshot(&Snapshot::from_bytes(bytes)).unwrap();
    /// world.step().unwrap();
    /// copy.step().unwrap();
    /// assert_eq!(world.physics.bodies[bob].position(), copy.physics.bodies[bob].position());
    /// ```
    ///
    /// # Errors
    /// [`Error::Snapshot`] if something cannot be serialised.
    #[cfg(feature = "serde-snapshot")]
    pub fn snapshot(&self) -> Result<crate::snapshot::Snapshot, Error> {
        crate::snapshot::encode(&(&self.physics, &self.core, &self.backend))
    }

    /// A world from a [`Mpc184World::snapshot`]: it continues exactly as the world the snapshot
    /// was taken from.
    ///
    /// # Errors
    /// [`Error::Snapshot`] if the bytes are not a snapshot of this format and precision, or
    /// are damaged.
    #[cfg(feature = "serde-snapshot")]
    pub fn from_snapshot(snapshot: &crate::snapshot::Snapshot) -> Result<Self, Error> {
        let (physics, core, mut backend): (PhysicsWorld, Core, JointBackend) =
            crate::snapshot::decode(snapshot)?;
        backend.after_restore()?;
        Ok(Self::from_parts(physics, core, backend))
    }

    /// The settings.
    pub fn settings(&self) -> &WorldSettings {
        &self.core.settings
    }

    /// Changes the time step of the following `step()` calls (a new `DELTIM` or `NSUBST` in a
    /// later load step); the substep count stays.
    pub fn set_dt(&mut self, dt: Real) {
        self.core.settings.dt = dt;
        self.backend.invalidate();
    }

    /// Simulated time (s).
    pub fn time(&self) -> Real {
        self.core.progress.time
    }

    /// The fixed body standing for the ground (created on first use).
    pub fn ground(&mut self) -> RigidBodyHandle {
        crate::backend::shared_ground(&mut self.physics, &mut self.core.ground)
    }

    /// Inserts a joint between body 1 (node I) and body 2 (node J); `None` is the ground.
    ///
    /// The model is validated first and the world is left unchanged on error:
    /// [`Error::DegenerateFrame`] (non-finite nodes, axes that are not a rotation),
    /// [`Error::InvalidPitch`] (a screw of zero pitch), [`Error::NodesApart`] (revolute or
    /// universal nodes further apart than [`crate::joint::COINCIDENCE_TOLERANCE`] allows),
    /// [`Error::InvalidBehaviour`] (a stop or lock on a constrained DOF or with min > max, a
    /// linear and a nonlinear law on one component, bad tables or friction),
    /// [`Error::MassProperties`] (a dynamic body without mass or with a singular inertia on an
    /// unlocked axis), [`Error::InvalidBody`] (no such body, both sides grounded, or a body
    /// jointed to itself), [`Error::Unsupported`] (what the backend cannot impose).
    pub fn insert_joint(
        &mut self,
        body1: Option<RigidBodyHandle>,
        body2: Option<RigidBodyHandle>,
        joint: Mpc184Joint,
    ) -> Result<JointId, Error> {
        let id = self.core.joints.next_id();
        crate::validate::joint(id, &joint, body1.is_some() && body2.is_some())?;
        self.backend.admit(&joint)?;
        let physics = &mut self.physics;
        crate::validate::bodies(id, &mut physics.bodies, &physics.colliders, [body1, body2])?;
        crate::validate::link_length(id, &joint)?;
        let joint = joint.grounded(body1.is_none(), body2.is_none());
        let attached =
            self.backend
                .attach(id, physics, &mut self.core.ground, &joint, [body1, body2])?;
        for h in attached.sides {
            crate::body::join(&mut physics.bodies, &physics.colliders, h);
        }
        let entry = JointEntry::new(
            joint,
            &physics.bodies,
            attached.sides,
            attached.frames,
            attached.rapier,
        );
        let id = self.core.joints.push(entry);
        self.core.model_size = None;
        self.refresh_output(id.0 as usize);
        Ok(id)
    }

    /// Removes a joint (its Rapier joint too).
    pub fn remove_joint(&mut self, id: JointId) -> Result<Mpc184Joint, Error> {
        let entry = self.core.joints.remove(id)?;
        self.core.model_size = None;
        self.backend.detach(&mut self.physics, &entry);
        Ok(entry.joint)
    }

    /// Prescribes the relative displacement or rotation of a free DOF (ANSYS `DJ,elem,UX..ROTZ`):
    /// the DOF's value relative to time 0 follows `profile` exactly (a rheonomic constraint row
    /// on the Lagrange backend; its multiplier is the driving force or moment). Replaces an
    /// earlier drive of the same DOF ("the last one set wins").
    #[doc(alias = "DJ")]
    pub fn set_drive(&mut self, id: JointId, dof: Dof, profile: DriveProfile) -> Result<(), Error> {
        self.set_drive_level(id, dof, DriveLevel::Displacement, profile)
    }

    /// Prescribes a free DOF's displacement, velocity (`DJ,elem,VELX..OMGZ`) or acceleration
    /// (`DJ,elem,ACCX..DMGZ`) by `profile`; velocity and acceleration drives integrate from
    /// now, from the DOF's current value and rate. "The last one set wins" per DOF.
    #[doc(alias = "DJ")]
    pub fn set_drive_level(
        &mut self,
        id: JointId,
        dof: Dof,
        level: DriveLevel,
        profile: DriveProfile,
    ) -> Result<(), Error> {
        self.backend.require(Capability::Drive)?;
        let now = self.time();
        self.core.joints.set_drive(id, dof, level, profile, now)
    }

    /// Removes the drive of a DOF (ANSYS `DJDELE`); the DOF is free again.
    #[doc(alias = "DJDELE")]
    pub fn remove_drive(&mut self, id: JointId, dof: Dof) -> Result<(), Error> {
        self.core.joints.remove_drive(id, dof)
    }

    /// Applies a force or moment along a free DOF (`FJ,elem,FX..MZ`; N or N m on node J, the
    /// reaction on node I) following `profile` in time. Replaces an earlier load on that DOF.
    /// On the Rapier backends it is a user force on the bodies held over each Rapier call (the
    /// generalised force at the call's start: first order in the call).
    #[doc(alias = "FJ")]
    pub fn set_load(&mut self, id: JointId, dof: Dof, profile: DriveProfile) -> Result<(), Error> {
        self.core.joints.set_load(id, dof, profile)
    }

    /// Removes the applied load on a DOF (`FJDELE`).
    #[doc(alias = "FJDELE")]
    pub fn remove_load(&mut self, id: JointId, dof: Dof) -> Result<(), Error> {
        self.core.joints.remove_load(id, dof)
    }

    /// Inserts a spring-damper (ANSYS `COMBIN14`) between a point of body 1 (node I) and a
    /// point of body 2 (node J); `None` is the ground (the point stays where it is). See
    /// [`crate::spring`] for the force law and how each backend applies it.
    ///
    /// # Errors
    /// [`Error::InvalidSpring`] (non-finite or negative data, coincident points, no such body,
    /// both sides grounded or one body twice); the world is left unchanged.
    #[doc(alias = "COMBIN14")]
    pub fn insert_spring(
        &mut self,
        body1: Option<RigidBodyHandle>,
        body2: Option<RigidBodyHandle>,
        spring: SpringDamper,
    ) -> Result<SpringId, Error> {
        let id = self.core.springs.next_id();
        spring.validate(id)?;
        let bad = |field: &'static str, reason: String| Error::InvalidSpring {
            spring: id,
            field,
            reason,
        };
        for (field, b) in [("body 1", body1), ("body 2", body2)] {
            if let Some(b) = b {
                let Some(rb) = self.physics.bodies.get_mut(b) else {
                    return Err(bad(field, format!("{b:?} is not in the world")));
                };
                rb.recompute_mass_properties_from_colliders(&self.physics.colliders);
                if let Some(reason) = crate::body::mass_defect(rb) {
                    return Err(bad(field, reason));
                }
            }
        }
        if body1 == body2 {
            return Err(bad(
                "body 2",
                "both points are on one body (or both on the ground): the spring would do \
                 nothing"
                    .into(),
            ));
        }
        let dynamic =
            |b: Option<RigidBodyHandle>| b.is_some_and(|b| self.physics.bodies[b].is_dynamic());
        if !dynamic(body1) && !dynamic(body2) {
            return Err(bad(
                "body 2",
                "neither side is a dynamic body: nothing can move".into(),
            ));
        }
        let mut side = |b: Option<RigidBodyHandle>| match b {
            Some(b) => b,
            None => crate::backend::shared_ground(&mut self.physics, &mut self.core.ground),
        };
        let bodies = [side(body1), side(body2)];
        let entry = SpringEntry::new(spring, bodies, &self.physics.bodies);
        self.backend.invalidate();
        Ok(self.core.springs.push(entry))
    }

    /// Removes a spring-damper.
    pub fn remove_spring(&mut self, id: SpringId) -> Result<SpringDamper, Error> {
        let e = self.core.springs.remove(id)?;
        self.backend.invalidate();
        Ok(e.spring)
    }

    /// A spring-damper's data.
    pub fn spring(&self, id: SpringId) -> Result<&SpringDamper, Error> {
        self.core.springs.entry(id).map(|e| &e.spring)
    }

    /// A spring-damper's length, rate, tension and elastic energy now (from the bodies' current
    /// states).
    pub fn spring_output(&self, id: SpringId) -> Result<SpringOutput, Error> {
        let e = self.core.springs.entry(id)?;
        Ok(e.eval(self.spring_sides(e)).output)
    }

    /// Ids of all spring-dampers.
    pub fn spring_ids(&self) -> impl Iterator<Item = SpringId> + '_ {
        self.core.springs.iter().map(|(id, _)| id)
    }

    /// The two sides of a spring now (velocities as [`Mpc184World::body_velocity`] reads them).
    fn spring_sides(&self, e: &SpringEntry) -> [crate::spring::Side; 2] {
        e.bodies.map(|h| {
            let mut s = crate::spring::Side::of(&self.physics.bodies, h);
            (s.linvel, s.angvel) = self.velocity_of(h);
            s
        })
    }

    /// Elastic energy of the spring-dampers now (J).
    fn spring_element_energy(&self) -> Real {
        self.core
            .springs
            .iter()
            .map(|(_, e)| e.eval(self.spring_sides(e)).output.energy)
            .sum()
    }

    /// Removes a body, every joint attached to it first, and its colliders. Returns the ids of
    /// the joints removed with it (its springs go too).
    pub fn remove_body(&mut self, body: RigidBodyHandle) -> Vec<JointId> {
        let attached = self.core.joints.attached_to(body);
        for id in &attached {
            let _ = self.remove_joint(*id);
        }
        for id in self.core.springs.attached_to(body) {
            let _ = self.remove_spring(id);
        }
        // The shared ground goes with it: the next grounded joint or spring makes a new one.
        if self.core.ground == Some(body) {
            self.core.ground = None;
        }
        self.physics.remove_body_with_colliders(body, true);
        self.backend.invalidate();
        attached
    }

    /// The joint description.
    pub fn joint(&self, id: JointId) -> Result<&Mpc184Joint, Error> {
        self.core.joints.entry(id).map(|e| &e.joint)
    }

    /// The output of a joint after the last step.
    pub fn output(&self, id: JointId) -> Result<&JointOutput, Error> {
        self.core.joints.entry(id).map(|e| &e.state.output)
    }

    /// Ids of all joints.
    pub fn joint_ids(&self) -> impl Iterator<Item = JointId> + '_ {
        self.core.joints.ids()
    }

    /// Linear and angular velocity of a body's centre of mass (world frame). Multibody links are
    /// read through the multibody Jacobian: their `RigidBody` velocities lag one substep.
    ///
    /// # Errors
    /// [`Error::UnknownBody`] for a handle that is not in the world (never was, or removed).
    pub fn body_velocity(&self, h: RigidBodyHandle) -> Result<(Vector, Vector), Error> {
        if self.physics.bodies.get(h).is_none() {
            return Err(Error::UnknownBody(h));
        }
        Ok(self.velocity_of(h))
    }

    /// [`Mpc184World::body_velocity`] of a body known to be in the world.
    fn velocity_of(&self, h: RigidBodyHandle) -> (Vector, Vector) {
        self.backend.body_velocity(&self.physics, h)
    }

    /// Kinetic energy of all dynamic bodies (J).
    pub fn kinetic_energy(&self) -> Real {
        self.body_energies().0
    }

    /// Gravitational potential energy of all dynamic bodies, zero at the origin (J).
    pub fn potential_energy(&self) -> Real {
        self.body_energies().1
    }

    /// The kinetic and gravitational energies of all dynamic bodies (J) and their weight (N,
    /// `m |gravity scale| |g|` summed: the energy guard's floor), in one pass over the bodies
    /// (the energy guard takes them twice per step).
    fn body_energies(&self) -> (Real, Real, Real) {
        let (g, g_length) = (self.physics.gravity, self.physics.gravity.length());
        let (mut kinetic, mut potential, mut weight) = (0.0, 0.0, 0.0);
        for (h, rb) in self.physics.bodies.iter() {
            if !rb.is_dynamic() {
                continue;
            }
            let (v, w) = self.velocity_of(h);
            kinetic += 0.5 * rb.mass() * v.length_squared() + crate::body::rotational_energy(rb, w);
            potential -= rb.mass() * rb.gravity_scale() * g.dot(rb.center_of_mass());
            weight += rb.mass() * rb.gravity_scale().abs() * g_length;
        }
        (kinetic, potential, weight)
    }

    /// The energy balance now: kinetic, gravitational, spring, dissipated and the work of
    /// loads and drives (see [`EnergyReport`]).
    pub fn energy(&self) -> EnergyReport {
        self.energy_and_weight().0
    }

    /// [`Mpc184World::energy`], and the bodies' weight (N, see `body_energies`).
    fn energy_and_weight(&self) -> (EnergyReport, Real) {
        let (kinetic, potential, weight) = self.body_energies();
        let spring = self.core.joints.spring_energy() + self.spring_element_energy();
        let ledger = self.core.progress.ledger;
        let report = EnergyReport {
            kinetic,
            potential,
            spring,
            dissipated: ledger.dissipated,
            work: ledger.work,
            total: kinetic + potential + spring + ledger.dissipated - ledger.work,
        };
        (report, weight)
    }

    /// Diagnostics of the Lagrange backend (redundant rows, projection residual, warnings;
    /// empty on the Rapier backends).
    pub fn lagrange_diagnostics(&self) -> &LagrangeDiagnostics {
        self.backend.diagnostics()
    }

    /// The bounds a step is checked against.
    pub fn divergence_limits(&self) -> DivergenceLimits {
        self.core.limits
    }

    /// Changes the bounds a step is checked against (see [`DivergenceLimits`]).
    ///
    /// # Errors
    /// [`Error::InvalidSetting`] unless every bound is positive (an infinite bound switches
    /// that check off).
    pub fn set_divergence_limits(&mut self, limits: DivergenceLimits) -> Result<(), Error> {
        limits.validate()?;
        self.core.limits = limits;
        Ok(())
    }

    /// The model size the translational bound is a fraction of (m): the diagonal of the box
    /// holding the joints' nodes and the jointed bodies' centres of mass, give or take their
    /// radii of gyration (1 m if that box is a point). Measured at the first step after the
    /// joints last changed (now, if no step was taken since), so that a body flying away does
    /// not widen its own bound.
    pub fn model_size(&self) -> Real {
        self.core
            .model_size
            .unwrap_or_else(|| crate::divergence::model_size(&self.physics, &self.core.joints))
    }

    /// Advances one time step (`settings.dt`) in `settings.substeps` substeps.
    ///
    /// # Errors
    /// [`Error::Diverged`] when the state turns non-finite or a joint's constraint error passes
    /// its bound ([`crate::DivergenceLimits`]); it names the joint and the time, and the world
    /// keeps its last good state, exactly as after the previous successful step (see
    /// [`crate::divergence`]). Any other error leaves the world as it was too.
    pub fn step(&mut self) -> Result<(), Error> {
        let (dt, n) = (self.core.settings.dt, self.core.settings.substeps);
        if n == 0 || dt.is_nan() || dt <= 0.0 {
            return Err(Error::InvalidSetting {
                field: "dt/substeps",
                value: dt,
                reason: "dt must be positive and substeps at least 1",
            });
        }
        check_control(self.core.settings.control)?;
        let g = self.physics.gravity;
        if !g.is_finite() {
            return Err(Error::InvalidSetting {
                field: "physics.gravity",
                value: g.x + g.y + g.z,
                reason: "the gravity must be finite",
            });
        }
        self.save_checkpoint();
        let guard = self.core.limits.energy_growth.is_finite();
        let before = guard.then(|| {
            let (e, weight) = self.energy_and_weight();
            let floor = self.load_scale(weight);
            self.core.progress.scale_with(&e, floor);
            (e, floor)
        });
        let stepped = match self.core.settings.control {
            StepControl::Fixed => self.step_unchecked(dt, n),
            StepControl::Adaptive {
                tolerance,
                energy_tolerance,
                max_substeps,
                horizon,
                extrapolate,
            } => self.step_adaptive(
                dt,
                [tolerance, energy_tolerance, horizon],
                max_substeps,
                extrapolate,
                false,
            ),
            StepControl::Embedded {
                tolerance,
                max_substeps,
                horizon,
            } => self.step_adaptive(
                dt,
                [tolerance, Real::INFINITY, horizon],
                max_substeps,
                false,
                true,
            ),
        };
        let result = stepped.and_then(|()| match before {
            Some((e, floor)) => self.energy_guard(&e, floor),
            None => Ok(()),
        });
        match result {
            Ok(()) => Ok(()),
            Err(e) => Err(self.roll_back(e)),
        }
    }

    /// The energy guard after a step (see [`crate::divergence`]): the balance may not have
    /// grown by more than `energy_growth` of the scale (taken with the state after the step
    /// too, so that a step from rest is measured against what it set in motion); the joint
    /// blamed is the one on the body with the largest kinetic energy now whose two sides turn
    /// fastest against each other (an unstable spring between two bodies, not the hinge that
    /// carries both).
    fn energy_guard(&mut self, before: &EnergyReport, floor: Real) -> Result<(), Error> {
        let after = self.energy();
        let scale = self.core.progress.scale_with(&after, floor);
        crate::divergence::check_energy(&self.core.limits, before, &after, scale).map_err(
            |reason| {
                let hottest = self
                    .physics
                    .bodies
                    .iter()
                    .filter(|(_, rb)| rb.is_dynamic())
                    .map(|(h, rb)| {
                        let (v, w) = self.velocity_of(h);
                        let ke = 0.5 * rb.mass() * v.length_squared()
                            + crate::body::rotational_energy(rb, w);
                        (h, ke)
                    })
                    .max_by(|a, b| a.1.total_cmp(&b.1))
                    .map(|(h, _)| h);
                let joint = hottest.and_then(|h| self.fastest_joint_on(h));
                let body = hottest.map_or_else(String::new, |h| {
                    format!(" (fastest body {:?})", h.into_raw_parts())
                });
                Error::Diverged {
                    time: self.time(),
                    joint,
                    reason: format!("{reason}{body}"),
                }
            },
        )
    }

    /// Of the joints on `body`, the one whose sides turn fastest against each other (the
    /// first one on ties).
    fn fastest_joint_on(&self, body: RigidBodyHandle) -> Option<JointId> {
        let spin = |h: RigidBodyHandle| match self.physics.bodies.get(h) {
            Some(rb) if rb.is_dynamic() => self.velocity_of(h).1,
            _ => Vector::ZERO,
        };
        let mut best: Option<(JointId, Real)> = None;
        for id in self.core.joints.attached_to(body) {
            let Some(e) = self.core.joints.get(id.0 as usize) else {
                continue;
            };
            let rate = (spin(e.body2) - spin(e.body1)).length();
            if best.is_none_or(|(_, r)| rate > r) {
                best = Some((id, rate));
            }
        }
        best.map(|(id, _)| id)
    }

    /// What the loads could put into the world at rest over the coming step (J; the energy
    /// guard's floor), with the bodies' weight `weight` (N).
    fn load_scale(&self, weight: Real) -> Real {
        let t = self.time();
        crate::divergence::load_scale(
            weight,
            &self.core.joints,
            self.model_size(),
            t,
            t + self.core.settings.dt,
        )
    }

    /// Sets the gravity (m/s^2) and books the work of the change: the gravitational energy
    /// `-m g . c` of every dynamic body jumps with `g` at fixed positions, and that jump is work
    /// done on the system (ANSYS `ACEL` varying in time, ramped by `KBC,0`). Writing
    /// `physics.gravity` directly changes the gravity without booking it (the balance then
    /// moves by the jump).
    ///
    /// # Errors
    /// [`Error::InvalidSetting`] for a non-finite gravity (the world is left unchanged).
    #[doc(alias = "ACEL")]
    pub fn set_gravity(&mut self, gravity: Vector) -> Result<(), Error> {
        if !gravity.is_finite() {
            return Err(Error::InvalidSetting {
                field: "gravity",
                value: gravity.x + gravity.y + gravity.z,
                reason: "the gravity must be finite",
            });
        }
        let dg = gravity - self.physics.gravity;
        if dg != Vector::ZERO {
            let jump: Real = self
                .physics
                .bodies
                .iter()
                .filter(|(_, rb)| rb.is_dynamic())
                .map(|(_, rb)| -rb.mass() * rb.gravity_scale() * dg.dot(rb.center_of_mass()))
                .sum();
            self.core.progress.ledger.work += jump;
        }
        self.physics.gravity = gravity;
        Ok(())
    }

    /// [`Mpc184World::step`] without the checkpoint: the backend's substeps, the reactions,
    /// the outputs, the divergence check.
    fn step_unchecked(&mut self, dt: Real, n: usize) -> Result<(), Error> {
        let h = dt / n as Real;
        self.core.progress.last_h = h;
        let start = crate::work::StepStart::record(&self.physics.bodies);
        let reactions = self.core.settings.outputs == Outputs::Full
            || self.backend.needs_reactions(&mut self.core.joints);
        let bounds = self.bounds();
        let out = OutputPass {
            reactions,
            ratio: &|o| bounds.ratio(o),
        };
        self.backend
            .step(&mut self.core.sets(&mut self.physics), h, n, &out)?;
        self.core.progress.time += dt;
        self.check_bodies_finite()?;
        // The joints the backend has not written already (`JointBackend::refreshed`).
        if reactions {
            self.backend
                .write_reactions(&mut self.core.sets(&mut self.physics), h);
        }
        let worst = self.refresh_step_outputs(&bounds);
        self.core.progress.ledger.work += start.work(&self.physics.bodies, &self.core.joints, dt);
        match worst {
            Some(j) => Err(bounds.error(&self.core.joints, j, self.time())),
            None => Ok(()),
        }
    }

    /// Sets how the coming steps choose their substeps (ANSYS `AUTOTS`; see [`StepControl`]).
    ///
    /// # Errors
    /// [`Error::InvalidSetting`] for a tolerance that is not positive and finite, or
    /// `max_substeps` outside 2..=2^20 (the world is left unchanged).
    #[doc(alias = "AUTOTS")]
    pub fn set_step_control(&mut self, control: StepControl) -> Result<(), Error> {
        check_control(control)?;
        self.core.settings.control = control;
        Ok(())
    }

    /// What the adaptive step control did so far (all zero with [`StepControl::Fixed`]).
    pub fn step_stats(&self) -> StepStats {
        self.core.stats
    }

    /// One static step (ANSYS `ANTYPE,STATIC`, see [`crate::statics`]): the time advances by
    /// `settings().dt`, the drives take their values there and the positions are solved from
    /// the constraint equations; the bodies are left at rest, and every joint's output
    /// (relative DOFs, reactions from statics) is refreshed.
    ///
    /// # Errors
    /// [`Error::Unsupported`] on the Rapier backends; [`Error::StaticEquilibrium`] when the
    /// mechanism has a free DOF (nothing is moved then); [`Error::Diverged`] when Newton does not
    /// converge (the drives ask for a pose the mechanism cannot reach).
    pub fn static_step(&mut self) -> Result<StaticReport, Error> {
        self.backend.require(Capability::Static)?;
        let dt = self.core.settings.dt;
        if dt.is_nan() || dt <= 0.0 || !dt.is_finite() {
            return Err(Error::InvalidSetting {
                field: "dt",
                value: dt,
                reason: "dt must be positive",
            });
        }
        let mut statics = core::mem::take(&mut self.core.statics);
        let result = self.static_stages(&mut statics, dt);
        self.core.statics = statics;
        result
    }

    /// The stages of a static step: solve, advance, refresh, reactions.
    fn static_stages(
        &mut self,
        statics: &mut StaticState,
        dt: Real,
    ) -> Result<StaticReport, Error> {
        let solution = statics.solve(&mut self.core.sets(&mut self.physics), dt)?;
        self.core.progress.time = solution.time();
        self.backend.invalidate();
        self.refresh_outputs();
        statics.finish(&mut self.core.sets(&mut self.physics), solution)
    }

    /// The idle modes of the scene at the bodies' current poses (see [`crate::idle`]): spins
    /// of one body about an axis through its centre of mass that its joints leave free and
    /// that move nothing else.
    #[doc(alias = "idle")]
    pub fn idle_modes(&self) -> Vec<crate::idle::IdleMode> {
        crate::idle::find(&self.physics.bodies, &self.core.joints)
    }

    /// Removes the idle modes found now: each gets a velocity-level row holding the body's
    /// spin about the axis at zero rate ([`crate::rows::RowKind::Spin`]), added to the first
    /// of the body's joints. Returns the modes removed (none: nothing changes). A spin the
    /// body had about the axis is taken out by the first step's velocity solve.
    ///
    /// # Errors
    /// [`Error::Unsupported`] on the Rapier backends (their joints are Rapier's; the modes are
    /// still reported by [`Mpc184World::idle_modes`]); a joint with no room for another row
    /// (world unchanged).
    pub fn remove_idle_modes(&mut self) -> Result<Vec<crate::idle::IdleMode>, Error> {
        self.backend.require(Capability::SpinRows)?;
        let modes = self.idle_modes();
        let saved = self.core.joints.clone();
        for m in &modes {
            let Some(&id) = m.joints.first() else {
                continue;
            };
            let bodies = &self.physics.bodies;
            let result = self.core.joints.entry_mut(id).and_then(|e| {
                let side = if e.body1 == m.body { 1 } else { 2 };
                e.add_spin_row(id, bodies, side, m.axis)
            });
            if let Err(e) = result {
                self.core.joints = saved;
                return Err(e);
            }
        }
        if !modes.is_empty() {
            self.core.joints.touch();
            self.backend.invalidate();
        }
        Ok(modes)
    }

    /// Free DOFs of the mechanism at its current configuration: `6` per dynamic body minus the
    /// rank of the constraint Jacobian (every joint row, drives and held locks included), plus
    /// drive rows on the `(joint, DOF)` pairs of `extra` (drives about to be set). Zero for a
    /// kinematically driven mechanism, whose positions [`Mpc184World::static_step`] can solve.
    pub fn mobility(&mut self, extra: &[(JointId, Dof)]) -> Result<usize, Error> {
        let mut statics = core::mem::take(&mut self.core.statics);
        let result = statics.mobility(&self.core.sets(&mut self.physics), extra);
        self.core.statics = statics;
        result
    }

    /// Every body's pose and velocity is finite, else [`Error::Diverged`] naming the body.
    fn check_bodies_finite(&self) -> Result<(), Error> {
        for (h, rb) in self.physics.bodies.iter() {
            if !crate::body::is_finite(rb) {
                return Err(Error::Diverged {
                    time: self.time(),
                    joint: None,
                    reason: format!(
                        "body {:?} has a non-finite pose or velocity",
                        h.into_raw_parts()
                    ),
                });
            }
        }
        Ok(())
    }

    /// Refreshes every joint's output from the bodies now.
    fn refresh_outputs(&mut self) {
        self.refresh_outputs_by(None, false);
    }

    /// The outputs after a step, each checked against `bounds` as it is written (one pass
    /// over the joints): the joint furthest past a bound, if any. The joints whose outputs the
    /// backend refreshed during the step ([`JointBackend::refreshed`]) keep them, with the
    /// ratio it took.
    fn refresh_step_outputs(&mut self, bounds: &Bounds) -> Option<usize> {
        self.refresh_outputs_by(Some(bounds), true)
    }

    /// See [`Mpc184World::refresh_outputs`] and [`Mpc184World::refresh_step_outputs`]
    /// (`after_step`: the latter).
    fn refresh_outputs_by(&mut self, bounds: Option<&Bounds>, after_step: bool) -> Option<usize> {
        let roles = self.core.joints.roles();
        // `roles.springs` is in joint order: merged with the loop.
        let mut springs = roles.springs.iter().peekable();
        let (physics, backend) = (&self.physics, &self.backend);
        let done = if after_step { backend.refreshed() } else { &[] };
        let mut worst: Option<(usize, Real)> = None;
        for i in 0..self.core.joints.len() {
            let spring = springs.next_if_eq(&&i).is_some();
            let r = if let Some(&Some(r)) = done.get(i) {
                r
            } else {
                let Some(e) = self.core.joints.get_mut(i) else {
                    continue;
                };
                e.refresh_output(
                    &physics.bodies,
                    |h| backend.body_velocity(physics, h),
                    spring,
                );
                bounds.map_or(0.0, |b| b.ratio(&e.state.output))
            };
            if r > 1.0 && worst.is_none_or(|(_, w)| r > w) {
                worst = Some((i, r));
            }
        }
        worst.map(|(j, _)| j)
    }

    /// Refreshes joint `i`'s output (kinematics and status) from the bodies now.
    fn refresh_output(&mut self, i: usize) {
        let (physics, backend) = (&self.physics, &self.backend);
        if let Some(e) = self.core.joints.get_mut(i) {
            let springs = e.joint.behaviour.has_forces();
            e.refresh_output(
                &physics.bodies,
                |h| backend.body_velocity(physics, h),
                springs,
            );
        }
    }

    /// The divergence bounds now.
    fn bounds(&self) -> Bounds {
        Bounds::new(self.core.limits, self.model_size(), self.core.settings.dt)
    }

    /// Saves what the coming step changes (see [`crate::divergence`]).
    fn save_checkpoint(&mut self) {
        if self.core.model_size.is_none() {
            self.core.model_size = Some(self.model_size());
        }
        let core = &self.core;
        self.checkpoint
            .save(&self.physics, &core.joints, core.progress, &self.backend);
    }

    /// Puts the checkpoint back after a failed step and returns the error, a divergence naming
    /// the joint and the time of the state kept.
    fn roll_back(&mut self, err: Error) -> Error {
        let culprit = match &err {
            Error::Diverged { joint: Some(j), .. } => Some(*j),
            Error::Diverged { joint: None, .. } => self.checkpoint.culprit(
                &self.physics,
                &self.core.joints,
                &self.backend,
                &self.bounds(),
            ),
            _ => None,
        };
        self.core.progress =
            self.checkpoint
                .restore(&mut self.physics, &mut self.core.joints, &mut self.backend);
        // The embedded estimate's samples may hold the end of the step undone.
        self.core.history.clear();
        match err {
            Error::Diverged { reason, .. } => Error::Diverged {
                time: self.time(),
                joint: culprit,
                reason,
            },
            other => other,
        }
    }
}

/// A step control's values are usable (see [`Mpc184World::set_step_control`]).
fn check_control(control: StepControl) -> Result<(), Error> {
    let (tolerance, energy_tolerance, max_substeps, horizon) = match control {
        StepControl::Fixed => return Ok(()),
        StepControl::Adaptive {
            tolerance,
            energy_tolerance,
            max_substeps,
            horizon,
            ..
        } => (tolerance, energy_tolerance, max_substeps, horizon),
        StepControl::Embedded {
            tolerance,
            max_substeps,
            horizon,
        } => (tolerance, Real::INFINITY, max_substeps, horizon),
    };
    if !(horizon.is_finite() && horizon >= 0.0) {
        return Err(Error::InvalidSetting {
            field: "control.horizon",
            value: horizon,
            reason: "the horizon must be finite and not negative (0: the step itself)",
        });
    }
    if energy_tolerance.is_nan() || energy_tolerance <= 0.0 {
        return Err(Error::InvalidSetting {
            field: "control.energy_tolerance",
            value: energy_tolerance,
            reason: "the energy tolerance must be positive (infinity: no energy control)",
        });
    }
    if !(tolerance.is_finite() && tolerance > 0.0) {
        return Err(Error::InvalidSetting {
            field: "control.tolerance",
            value: tolerance,
            reason: "the tolerance must be positive and finite",
        });
    }
    if !(2..=1 << 20).contains(&max_substeps) {
        return Err(Error::InvalidSetting {
            field: "control.max_substeps",
            value: max_substeps as Real,
            reason: "an adaptive control (step doubling or the embedded estimate) takes 2 to 2^20 substeps per step",
        });
    }
    Ok(())
}
