//! [`Mpc184World`]: Rapier's bodies, colliders and pipeline plus the MPC184 joint registry.
//!
//! `step()` advances one time step `dt` in `substeps` substeps of `h = dt / substeps`, driving
//! Rapier with one substep per call (`num_solver_iterations = 1`, `dt = h`), so that per-substep
//! forces and rows can be added around each call. After the step every joint's output (relative
//! DOFs in ANSYS terms, their rates, the reaction force and moment on node J in frame I) is
//! refreshed.
//!
//! Reactions on the Rapier backends are recovered from momentum balance over the last substep:
//! the constraint impulse on each body `p_b = M_b dv_b - h f_b` (gravity, user forces, the
//! gyroscopic torque) is split among the joints by the mass-weighted least-squares solve
//! `(J M^-1 J^T) mu = J M^-1 p`, with `J` the joints' own rows ([`crate::rows`]). This sidesteps
//! Rapier's `ImpulseJoint::impulses`, which are coefficients in a Gram-Schmidt-skewed basis of
//! the last substep only, and works for multibody joints, which write no impulses back.

use crate::dof::Dof;
pub use crate::drive::{Drive, DriveLevel, DriveProfile};
use crate::error::{Error, JointId};
use crate::joint::Mpc184Joint;
use crate::kinematics::{self, AngleUnwrap};
use crate::lagrange::{LagrangeDiagnostics, LagrangeState};
use crate::lower::{self, Backend};
use crate::math::rapier::dynamics::{
    GenericJointBuilder, ImpulseJointHandle, LockedAxes, MultibodyJointHandle, RigidBody,
    RigidBodyBuilder, RigidBodyHandle,
};
use crate::math::rapier::pipeline::PhysicsWorld;
use crate::math::{Matrix, Pose, Real, Vector};
pub use crate::output::JointOutput;
use crate::rows::{self, FramePair, RowKind};
pub use crate::settings::{Integrator, WorldSettings};
use crate::solver::dense;
use crate::solver::kkt::{JointBlockSpec, KktSolver};

#[derive(Clone, Copy, Debug)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) enum RapierJoint {
    Impulse(ImpulseJointHandle),
    Multibody(MultibodyJointHandle),
}

#[derive(Clone, Debug)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct JointEntry {
    pub(crate) joint: Mpc184Joint,
    pub(crate) body1: RigidBodyHandle,
    pub(crate) body2: RigidBodyHandle,
    /// Frame I in body 1's local coordinates, frame J in body 2's.
    pub(crate) ansys: [Pose; 2],
    /// The lowering frames (coincident at time 0) in each body's local coordinates.
    pub(crate) low: [Pose; 2],
    pub(crate) rapier: RapierJoint,
    pub(crate) rows: Vec<RowKind>,
    pub(crate) unwrap: [AngleUnwrap; 3],
    pub(crate) initial: [Real; 6],
    pub(crate) output: JointOutput,
    pub(crate) drives: Vec<Drive>,
    pub(crate) effects: crate::effects::EffectState,
}

#[derive(Clone, Copy, Debug, Default)]
struct BodyStart {
    pose: Pose,
    com: Vector,
    linvel: Vector,
    angvel: Vector,
    /// Non-constraint force and torque over the substep (N, N m).
    force: Vector,
    torque: Vector,
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
    pub(crate) settings: WorldSettings,
    pub(crate) ground: Option<RigidBodyHandle>,
    pub(crate) joints: Vec<Option<JointEntry>>,
    pub(crate) time: Real,
    pub(crate) lagrange: LagrangeState,
    pub(crate) last_h: Real,
    starts: Vec<(RigidBodyHandle, BodyStart)>,
    gyro_added: Vec<(RigidBodyHandle, Vector)>,
    pub(crate) started: bool,
    recovery: Option<KktSolver>,
    pub(crate) ledger: crate::effects::EnergyLedger,
    /// State of the static (position) analysis ([`crate::statics`]).
    pub(crate) statics: crate::statics::StaticState,
    /// What the current step changes, saved at its start ([`crate::divergence`]).
    pub(crate) checkpoint: crate::divergence::Checkpoint,
    pub(crate) limits: crate::divergence::DivergenceLimits,
    /// Measured at the first step after the joints changed.
    pub(crate) model_size: Option<Real>,
}

impl Mpc184World {
    /// An empty world with gravity -9.81 m/s^2 along Y.
    pub fn new(settings: WorldSettings) -> Self {
        let physics = PhysicsWorld {
            gravity: Vector::new(0.0, -9.81, 0.0),
            ..Default::default()
        };
        Self {
            physics,
            settings,
            ground: None,
            joints: Vec::new(),
            time: 0.0,
            last_h: settings.dt / settings.substeps.max(1) as Real,
            starts: Vec::new(),
            gyro_added: Vec::new(),
            started: false,
            recovery: None,
            ledger: crate::effects::EnergyLedger::default(),
            lagrange: LagrangeState::default(),
            statics: crate::statics::StaticState::default(),
            checkpoint: Default::default(),
            limits: Default::default(),
            model_size: None,
        }
    }

    /// The settings.
    pub fn settings(&self) -> &WorldSettings {
        &self.settings
    }

    /// Changes the time step of the following `step()` calls (a new `DELTIM` or `NSUBST` in a
    /// later load step); the substep count stays.
    pub fn set_dt(&mut self, dt: Real) {
        self.settings.dt = dt;
        self.lagrange.dirty = true;
    }

    /// Simulated time (s).
    pub fn time(&self) -> Real {
        self.time
    }

    /// The fixed body standing for the ground (created on first use).
    pub fn ground(&mut self) -> RigidBodyHandle {
        if let Some(g) = self.ground {
            return g;
        }
        let g = self.physics.bodies.insert(RigidBodyBuilder::fixed());
        self.ground = Some(g);
        g
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
    /// jointed to itself).
    pub fn insert_joint(
        &mut self,
        body1: Option<RigidBodyHandle>,
        body2: Option<RigidBodyHandle>,
        mut joint: Mpc184Joint,
    ) -> Result<JointId, Error> {
        let id = JointId(self.joints.len() as u32);
        validate_frames(id, &joint)?;
        validate_model(id, &joint, body1.is_some() && body2.is_some())?;
        joint
            .behaviour
            .validate(&joint.kind)
            .map_err(|(field, reason)| Error::InvalidBehaviour {
                joint: id,
                field,
                reason,
            })?;
        let friction_only = {
            let mut b = joint.behaviour.clone();
            let fr = b.friction.take();
            b.is_empty()
                && fr.is_some()
                && crate::behaviour::Friction::dofs(&joint.kind).is_some_and(|d| d.len() == 1)
                && !matches!(joint.kind, crate::catalogue::JointKind::Screw { .. })
        };
        if !joint.behaviour.is_empty()
            && self.settings.backend != Backend::Lagrange
            && !friction_only
        {
            return Err(Error::Unsupported {
                what: format!(
                    "stops, locks, springs and dampers (SECSTOP, SECLOCK, TB,JOIN) on the {} \
                     backend",
                    self.settings.backend.name()
                ),
                hint: "they run on the Lagrange backend (Backend::Lagrange, the default), with \
                       either constraint method; Rapier's own limits are perfectly plastic and \
                       its motors see only the body's own inertia (on the Rapier backends only \
                       friction on a revolute, slot or translational joint is approximated, by a \
                       force-capped velocity motor)"
                    .into(),
            });
        }
        for (which, b) in [(1u8, body1), (2, body2)] {
            if let Some(h) = b
                && self.physics.bodies.get(h).is_none()
            {
                return Err(Error::InvalidBody {
                    joint: id,
                    which,
                    reason: "no such body".into(),
                });
            }
        }
        for (which, b) in [(1u8, body1), (2, body2)] {
            if let Some(h) = b {
                let colliders = &self.physics.colliders;
                let rb = &mut self.physics.bodies[h];
                rb.recompute_mass_properties_from_colliders(colliders);
                if let Some(reason) = mass_defect(rb) {
                    return Err(Error::MassProperties {
                        joint: id,
                        which,
                        reason: format!("{h:?}: {reason}"),
                    });
                }
            }
        }
        match (body1, body2) {
            (None, None) => {
                return Err(Error::InvalidBody {
                    joint: id,
                    which: 2,
                    reason: "both nodes grounded: a joint needs at least one body".into(),
                });
            }
            (Some(a), Some(b)) if a == b => {
                return Err(Error::InvalidBody {
                    joint: id,
                    which: 2,
                    reason: "a joint between a body and itself".into(),
                });
            }
            _ => {}
        }
        let link = matches!(joint.kind, crate::catalogue::JointKind::RigidLink);
        // The grounded side is the fixed world at the other node's location (a rigid link's
        // grounded node stays where it is given: the bar's pin on the ground).
        if body1.is_none() && !link {
            joint.node1 = joint.node2;
        }
        if body2.is_none() && !link {
            joint.node2 = joint.node1;
        }
        if link {
            let length = (joint.node2 - joint.node1).length();
            let scale = joint
                .node1
                .abs()
                .max(joint.node2.abs())
                .max_element()
                .max(1.0);
            if length.is_nan() || length <= 1e3 * Real::EPSILON * scale {
                return Err(Error::DegenerateFrame {
                    joint: id,
                    node: 2,
                    reason: format!(
                        "a rigid link needs distinct nodes (length {length:e} m): its direction \
                         is undefined"
                    ),
                });
            }
        }
        // On the Lagrange backend the Rapier joint starts with no locked axis; where a contact
        // can act, the Lagrange topology pass gives it the joint's own rows: they do no work on
        // the velocities our solve already made consistent, but keep contact and joint
        // consistent inside Rapier's solver (otherwise the two alternate between our solve and
        // Rapier's and a body resting on a floor creeps).
        let mask = lower::lower(&joint.kind, joint.method, self.settings.backend)?;
        // On the multibody backend one shared ground body would make every grounded tree a
        // branch of one multibody rooted there, whose dense solve costs ~(total DOFs)^3 (200
        // independent five-body arms: seconds per step): each grounded multibody joint gets its
        // own fixed body instead, and a loop through the ground (a second grounded joint on a
        // tree that already holds a fixed body) is refused as before.
        let multibody = self.settings.backend == Backend::RapierMultibody;
        if multibody
            && let Some(h) = body1.xor(body2)
            && self.multibody_grounded(h)
        {
            return Err(Error::Unsupported {
                what: format!(
                    "{id}: a multibody joint that closes a loop through the ground (the tree of \
                     its body is grounded already)"
                ),
                hint: "multibody joints form trees with body 1 as the parent; use the impulse \
                       backend for loops"
                    .into(),
            });
        }
        let grounded = |me: &mut Self| {
            if multibody {
                me.physics.bodies.insert(RigidBodyBuilder::fixed())
            } else {
                me.ground()
            }
        };
        let b1 = match body1 {
            Some(h) => h,
            None => grounded(self),
        };
        let b2 = match body2 {
            Some(h) => h,
            None => grounded(self),
        };
        let pose1 = self.physics.bodies[b1].position().to_owned();
        let pose2 = self.physics.bodies[b2].position().to_owned();
        let ansys1 = pose1.inverse() * Pose::from_parts(joint.node1, joint.axes1);
        let ansys2 = pose2.inverse() * Pose::from_parts(joint.node2, joint.axes2());
        let low_world = Pose::from_parts(joint.node2, joint.axes1);
        // Rapier's frames coincide at time 0 (both with frame I's axes); our rows measure frame
        // 2 with the local system at J itself and hold each row's initial value (crate::rows).
        let rapier_frames = [pose1.inverse() * low_world, pose2.inverse() * low_world];
        // A rigid link measures its distance from node I itself.
        let low = [if link { ansys1 } else { rapier_frames[0] }, ansys2];
        let q = lower::principal_rotation(joint.kind.principal_axis());
        let generic = GenericJointBuilder::new(mask)
            .local_frame1(rapier_frames[0] * q)
            .local_frame2(rapier_frames[1] * q)
            .contacts_enabled(false)
            .build();
        let rapier = match self.settings.backend {
            // The Lagrange backend's Rapier joint has no locked axis: it only puts the two bodies
            // in one island (they sleep and wake together) and stops them colliding.
            Backend::Lagrange | Backend::RapierImpulse => {
                RapierJoint::Impulse(self.physics.impulse_joints.insert(b1, b2, generic, true))
            }
            Backend::RapierMultibody => {
                let h = self.physics.multibody_joints.insert(b1, b2, generic, true).ok_or_else(|| {
                    Error::Unsupported {
                        what: format!(
                            "{id}: a multibody joint that closes a loop or gives body 2 a second parent"
                        ),
                        hint: "multibody joints form trees with body 1 as the parent; use the \
                               impulse backend for loops"
                            .into(),
                    }
                })?;
                if let Some((mb, _)) = self.physics.multibody_joints.get_mut(h) {
                    // Rapier gives every free angular DOF a default damping of 0.1: not MPC184's.
                    mb.damping_mut().fill(0.0);
                }
                RapierJoint::Multibody(h)
            }
        };
        for h in [b1, b2] {
            let rb = &mut self.physics.bodies[h];
            // Rapier fills in mass properties lazily at the first step; the energies, the
            // reaction recovery and the initial output need them now.
            rb.recompute_mass_properties_from_colliders(&self.physics.colliders);
            if rb.is_dynamic() {
                // Our per-substep loop adds -w x Iw itself, so the momentum balance that recovers
                // reactions knows every non-constraint torque; no hidden angular-velocity cap.
                rb.enable_gyroscopic_forces(false);
                rb.set_allow_fast_rotation(true);
            }
        }
        self.lagrange.dirty = true;
        let mut rows = rows::joint_rows(&joint.kind);
        {
            let (b1r, b2r) = (&self.physics.bodies[b1], &self.physics.bodies[b2]);
            let f0 = frame_pair(
                &low,
                (pose1, b1r.center_of_mass()),
                (pose2, b2r.center_of_mass()),
            );
            for r in rows.iter_mut() {
                match r {
                    RowKind::Angular { .. } => {
                        let value = r.eval(&f0).value;
                        if let RowKind::Angular { target, .. } = r {
                            *target = value;
                        }
                    }
                    RowKind::Screw {
                        reference, theta0, ..
                    } => {
                        *theta0 = rows::screw_angle(&f0, 0.0);
                        *reference = *theta0;
                    }
                    RowKind::Distance { length } => {
                        *length = (f0.p2 - f0.p1).length();
                    }
                    RowKind::Linear { .. } | RowKind::Drive { .. } => {}
                }
            }
        }
        let mut entry = JointEntry {
            joint,
            body1: b1,
            body2: b2,
            ansys: [ansys1, ansys2],
            low,
            rapier,
            rows,
            unwrap: [AngleUnwrap::default(); 3],
            initial: [0.0; 6],
            output: JointOutput::default(),
            drives: Vec::new(),
            effects: crate::effects::EffectState::default(),
        };
        let (m, wrapped) = self.measures(&entry);
        entry.unwrap = wrapped.map(AngleUnwrap::new);
        entry.initial = m;
        self.joints.push(Some(entry));
        self.model_size = None;
        self.refresh_output(id.0 as usize);
        Ok(id)
    }

    /// True if `h` is a link of a multibody that holds a fixed body (a grounded tree).
    fn multibody_grounded(&self, h: RigidBodyHandle) -> bool {
        let mbs = &self.physics.multibody_joints;
        mbs.rigid_body_link(h)
            .and_then(|link| mbs.get_multibody(link.multibody))
            .is_some_and(|mb| {
                mb.links().any(|l| {
                    self.physics
                        .bodies
                        .get(l.rigid_body_handle())
                        .is_some_and(RigidBody::is_fixed)
                })
            })
    }

    /// Removes a joint (its Rapier joint too).
    pub fn remove_joint(&mut self, id: JointId) -> Result<Mpc184Joint, Error> {
        let entry = self
            .joints
            .get_mut(id.0 as usize)
            .and_then(Option::take)
            .ok_or(Error::UnknownJoint(id))?;
        self.lagrange.dirty = true;
        self.model_size = None;
        match entry.rapier {
            RapierJoint::Impulse(h) => {
                self.physics.impulse_joints.remove(h, true);
            }
            RapierJoint::Multibody(h) => {
                self.physics.multibody_joints.remove(h, true);
            }
        }
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
        let now = self.time;
        if self.settings.backend != Backend::Lagrange {
            return Err(Error::Unsupported {
                what: format!(
                    "a prescribed relative motion (DJ) on the {} backend",
                    self.settings.backend.name()
                ),
                hint: "drives are rows of the Lagrange backend".into(),
            });
        }
        let entry = self
            .joints
            .get_mut(id.0 as usize)
            .and_then(Option::as_mut)
            .ok_or(Error::UnknownJoint(id))?;
        if !entry.joint.kind.free().contains(dof) {
            return Err(Error::InvalidDof {
                joint: id,
                dof,
                reason: format!("not a free DOF of a {} joint", entry.joint.kind.name()),
            });
        }
        if !profile.is_finite() {
            return Err(Error::InvalidDof {
                joint: id,
                dof,
                reason: "non-finite drive profile".into(),
            });
        }
        entry.drives.retain(|d| d.dof != dof);
        let k = dof.index();
        let rate = if dof.is_rotation() {
            entry.output.angular_velocity[k - 3]
        } else {
            entry.output.velocity[k]
        };
        entry.drives.push(Drive {
            level,
            since: now,
            start_value: entry.output.measure[k] - entry.initial[k],
            start_rate: rate,
            ..Drive::new(dof, profile)
        });
        entry
            .rows
            .retain(|r| !matches!(r, RowKind::Drive { dof: d, .. } if *d == dof));
        // The row measures translations from node J's initial position (0 at time 0) and
        // rotations as the absolute Bryant angle; the reference is today's unwrapped angle.
        let (initial, reference) = if dof.is_rotation() {
            (
                entry.initial[dof.index()],
                entry.output.measure[dof.index()],
            )
        } else {
            (0.0, 0.0)
        };
        entry.rows.push(RowKind::Drive {
            dof,
            target: 0.0,
            initial,
            reference,
        });
        self.lagrange.dirty = true;
        Ok(())
    }

    /// Removes the drive of a DOF (ANSYS `DJDELE`); the DOF is free again.
    #[doc(alias = "DJDELE")]
    pub fn remove_drive(&mut self, id: JointId, dof: Dof) -> Result<(), Error> {
        let entry = self
            .joints
            .get_mut(id.0 as usize)
            .and_then(Option::as_mut)
            .ok_or(Error::UnknownJoint(id))?;
        entry.drives.retain(|d| d.dof != dof);
        entry
            .rows
            .retain(|r| !matches!(r, RowKind::Drive { dof: d, .. } if *d == dof));
        self.lagrange.dirty = true;
        Ok(())
    }

    /// Removes a body, every joint attached to it first, and its colliders. Returns the ids of
    /// the joints removed with it.
    pub fn remove_body(&mut self, body: RigidBodyHandle) -> Vec<JointId> {
        let attached: Vec<JointId> = self
            .joints
            .iter()
            .enumerate()
            .filter_map(|(i, e)| {
                e.as_ref()
                    .filter(|e| e.body1 == body || e.body2 == body)
                    .map(|_| JointId(i as u32))
            })
            .collect();
        for id in &attached {
            let _ = self.remove_joint(*id);
        }
        self.physics.remove_body_with_colliders(body, true);
        self.lagrange.dirty = true;
        attached
    }

    /// The joint description.
    pub fn joint(&self, id: JointId) -> Result<&Mpc184Joint, Error> {
        self.entry(id).map(|e| &e.joint)
    }

    /// The output of a joint after the last step.
    pub fn output(&self, id: JointId) -> Result<&JointOutput, Error> {
        self.entry(id).map(|e| &e.output)
    }

    /// Ids of all joints.
    pub fn joint_ids(&self) -> impl Iterator<Item = JointId> + '_ {
        self.joints
            .iter()
            .enumerate()
            .filter(|(_, e)| e.is_some())
            .map(|(i, _)| JointId(i as u32))
    }

    fn entry(&self, id: JointId) -> Result<&JointEntry, Error> {
        self.joints
            .get(id.0 as usize)
            .and_then(Option::as_ref)
            .ok_or(Error::UnknownJoint(id))
    }

    /// Linear and angular velocity of a body's centre of mass (world frame). Multibody links are
    /// read through the multibody Jacobian: their `RigidBody` velocities lag one substep.
    pub fn body_velocity(&self, h: RigidBodyHandle) -> (Vector, Vector) {
        let rb = &self.physics.bodies[h];
        if self.settings.backend == Backend::RapierMultibody
            && let Some(link) = self.physics.multibody_joints.rigid_body_link(h)
            && let Some(mb) = self.physics.multibody_joints.get_multibody(link.multibody)
        {
            let jac = mb.body_jacobian(link.id);
            let qd = mb.generalized_velocity();
            // Before the first step the Jacobians are not built yet (0 columns).
            if jac.ncols() == qd.len() && jac.nrows() == 6 {
                let v = jac * qd;
                return (Vector::new(v[0], v[1], v[2]), Vector::new(v[3], v[4], v[5]));
            }
        }
        (rb.linvel(), rb.angvel())
    }

    /// Kinetic energy of all dynamic bodies (J).
    pub fn kinetic_energy(&self) -> Real {
        let mut e = 0.0;
        for (h, rb) in self.physics.bodies.iter() {
            if !rb.is_dynamic() {
                continue;
            }
            let (v, w) = self.body_velocity(h);
            e += 0.5 * rb.mass() * v.length_squared() + 0.5 * w.dot(world_inertia(rb) * w);
        }
        e
    }

    /// Gravitational potential energy of all dynamic bodies, zero at the origin (J).
    pub fn potential_energy(&self) -> Real {
        let g = self.physics.gravity;
        self.physics
            .bodies
            .iter()
            .filter(|(_, rb)| rb.is_dynamic())
            .map(|(_, rb)| -rb.mass() * rb.gravity_scale() * g.dot(rb.center_of_mass()))
            .sum()
    }

    /// Advances one time step (`settings.dt`) in `settings.substeps` Rapier calls.
    ///
    /// # Errors
    /// [`Error::Diverged`] when the state turns non-finite or a joint's constraint error passes
    /// its bound ([`crate::DivergenceLimits`]); it names the joint and the time, and the world
    /// keeps its last good state, exactly as after the previous successful step (see
    /// [`crate::divergence`]). Any other error leaves the world as it was too.
    pub fn step(&mut self) -> Result<(), Error> {
        let n = self.settings.substeps;
        if n == 0 || self.settings.dt.is_nan() || self.settings.dt <= 0.0 {
            return Err(Error::InvalidSetting {
                field: "dt/substeps",
                value: self.settings.dt,
                reason: "dt must be positive and substeps at least 1",
            });
        }
        self.checkpoint_save();
        match self.step_unchecked(n) {
            Ok(()) => Ok(()),
            Err(e) => Err(self.roll_back(e)),
        }
    }

    /// [`Mpc184World::step`] without the checkpoint.
    fn step_unchecked(&mut self, n: usize) -> Result<(), Error> {
        if !self.started {
            self.started = true;
            if self.settings.backend == Backend::RapierMultibody {
                self.init_multibody_velocities();
            }
        }
        let h = self.settings.dt / n as Real;
        self.last_h = h;
        if self.settings.backend != Backend::Lagrange {
            self.rapier_friction_motors();
        }
        self.physics.integration_parameters.dt = h;
        self.physics.integration_parameters.num_solver_iterations = 1;
        if self.settings.backend == Backend::Lagrange {
            self.lagrange_step(h, n)?;
        } else {
            for s in 0..n {
                let last = s + 1 == n;
                self.begin_substep(last);
                self.physics.step();
                self.end_substep();
            }
        }
        self.time += self.settings.dt;
        for (h, rb) in self.physics.bodies.iter() {
            let p = rb.position();
            let ok = p.translation.is_finite()
                && p.rotation.is_finite()
                && rb.linvel().is_finite()
                && rb.angvel().is_finite();
            if !ok {
                return Err(Error::Diverged {
                    time: self.time,
                    joint: None,
                    reason: format!(
                        "body {:?} has a non-finite pose or velocity",
                        h.into_raw_parts()
                    ),
                });
            }
        }
        if self.settings.backend == Backend::Lagrange {
            self.lagrange_reactions();
        } else {
            self.recover_reactions();
        }
        for i in 0..self.joints.len() {
            self.refresh_output(i);
        }
        self.check_divergence()
    }

    /// Joint friction on the Rapier backends (an approximation): a velocity motor with target
    /// 0 on the friction axis, force-based, very high damping, its force capped at `mu N` with
    /// the normal force `N` from the joint's reactions of the previous step (recovered by
    /// momentum balance) and `mu` at the previous relative rate. Rapier's motor sees only the
    /// bodies' own inertia and the cap lags a step; `tests/friction_incline.rs` measures the
    /// difference to the exact stick/slip of the Lagrange backend.
    fn rapier_friction_motors(&mut self) {
        use crate::math::rapier::dynamics::{JointAxis, MotorModel};
        const AXES: [JointAxis; 6] = [
            JointAxis::LinX,
            JointAxis::LinY,
            JointAxis::LinZ,
            JointAxis::AngX,
            JointAxis::AngY,
            JointAxis::AngZ,
        ];
        for e in self.joints.iter().flatten() {
            let Some(fr) = &e.joint.behaviour.friction else {
                continue;
            };
            let Some(&[dof]) = crate::behaviour::Friction::dofs(&e.joint.kind) else {
                continue;
            };
            let o = &e.output;
            let l = [
                o.force.x, o.force.y, o.force.z, o.moment.x, o.moment.y, o.moment.z,
            ];
            let rate = if dof.is_rotation() {
                o.angular_velocity[dof.index() - 3]
            } else {
                o.velocity[dof.index()]
            };
            let mut cap = fr.law.mu(rate) * fr.normal(&e.joint.kind, &l);
            if let Some(m) = fr.max_force {
                cap = cap.min(m);
            }
            let principal = e.joint.kind.principal_axis();
            let base = if dof.is_rotation() { 3 } else { 0 };
            let axis = AXES[base + lower::rapier_axis(dof.axis(), principal)];
            let data = match e.rapier {
                RapierJoint::Impulse(h) => self
                    .physics
                    .impulse_joints
                    .get_mut(h, false)
                    .map(|j| &mut j.data),
                RapierJoint::Multibody(h) => self
                    .physics
                    .multibody_joints
                    .get_mut(h)
                    .and_then(|(mb, link)| mb.link_mut(link).map(|l| &mut l.joint.data)),
            };
            if let Some(data) = data {
                data.set_motor_model(axis, MotorModel::ForceBased);
                data.set_motor_velocity(axis, 0.0, 1e9);
                data.set_motor_max_force(axis, cap.max(0.0));
            }
        }
    }

    fn begin_substep(&mut self, record: bool) {
        self.starts.clear();
        let mut touched: Vec<RigidBodyHandle> = Vec::new();
        let mut seen = std::collections::HashSet::new();
        for e in self.joints.iter().flatten() {
            for b in [e.body1, e.body2] {
                if self.physics.bodies[b].is_dynamic() && seen.insert(b) {
                    touched.push(b);
                }
            }
        }
        let g = self.physics.gravity;
        let impulse_backend = self.settings.backend == Backend::RapierImpulse;
        for b in touched {
            let (v, w) = self.body_velocity(b);
            let rb = &mut self.physics.bodies[b];
            let inertia = world_inertia(rb);
            let gyro = -w.cross(inertia * w);
            let start = BodyStart {
                pose: *rb.position(),
                com: rb.center_of_mass(),
                linvel: v,
                angvel: w,
                force: rb.user_force() + g * (rb.mass() * rb.gravity_scale()),
                torque: rb.user_torque() + gyro,
            };
            if impulse_backend {
                // Rapier's own gyroscopic term is off on jointed bodies (see insert_joint).
                rb.add_torque(gyro, false);
            }
            if record {
                self.starts.push((b, start));
            }
            if impulse_backend {
                // Taken off again in end_substep (Rapier's forces persist across steps).
                self.gyro_added.push((b, gyro));
            }
        }
    }

    fn end_substep(&mut self) {
        for (b, gyro) in self.gyro_added.drain(..) {
            self.physics.bodies[b].add_torque(-gyro, false);
        }
    }

    /// Multibody links take their velocities from generalized velocities, which start at zero:
    /// set them to the mass-weighted least-squares fit of the bodies' own velocities
    /// (`q' = (J^T M J)^-1 J^T M V`, the momentum-consistent projection onto the joints).
    fn init_multibody_velocities(&mut self) {
        let mut seen = Vec::new();
        for e in self.joints.iter().flatten() {
            if let Some(link) = self.physics.multibody_joints.rigid_body_link(e.body2)
                && !seen.contains(&link.multibody)
            {
                seen.push(link.multibody);
            }
        }
        for mbi in seen {
            let bodies = &self.physics.bodies;
            let Some(mb) = self.physics.multibody_joints.get_multibody_mut(mbi) else {
                continue;
            };
            mb.forward_kinematics(bodies, true);
            let n = mb.ndofs();
            if n == 0 {
                continue;
            }
            let mut a = vec![0.0 as Real; n * n];
            let mut b = vec![0.0 as Real; n];
            for (li, link) in mb.links().enumerate() {
                let rb = &bodies[link.rigid_body_handle()];
                let jac = mb.body_jacobian(li);
                if jac.ncols() != n {
                    continue;
                }
                let m = rb.mass();
                let inertia = world_inertia(rb);
                let (v, w) = (rb.linvel(), rb.angvel());
                // M J column by column.
                for c in 0..n {
                    let jl = Vector::new(jac[(0, c)], jac[(1, c)], jac[(2, c)]);
                    let ja = Vector::new(jac[(3, c)], jac[(4, c)], jac[(5, c)]);
                    let (ml, ma) = (jl * m, inertia * ja);
                    b[c] += ml.dot(v) + ma.dot(w);
                    for r in 0..n {
                        let kl = Vector::new(jac[(0, r)], jac[(1, r)], jac[(2, r)]);
                        let ka = Vector::new(jac[(3, r)], jac[(4, r)], jac[(5, r)]);
                        a[r * n + c] += kl.dot(ml) + ka.dot(ma);
                    }
                }
            }
            dense::cholesky_solve_dropping(&mut a, &mut b, n);
            mb.generalized_velocity_mut().copy_from_slice(&b);
        }
    }

    /// Splits the constraint impulses of the last substep among the joints (see module docs).
    fn recover_reactions(&mut self) {
        let h = self.last_h;
        let starts = core::mem::take(&mut self.starts);
        let index: std::collections::HashMap<RigidBodyHandle, usize> = starts
            .iter()
            .enumerate()
            .map(|(i, (b, _))| (*b, i))
            .collect();
        // Body blocks: M_b and the impulse p_b.
        let nb = starts.len();
        let mut mass = vec![[0.0 as Real; 36]; nb];
        let mut impulse = vec![[0.0 as Real; 6]; nb];
        for (i, (b, s)) in starts.iter().enumerate() {
            let rb = &self.physics.bodies[*b];
            let m = rb.mass();
            let inertia = inertia_at(rb, &s.pose);
            for k in 0..3 {
                mass[i][6 * k + k] = m;
                for l in 0..3 {
                    mass[i][6 * (3 + k) + 3 + l] = inertia.col(l)[k];
                }
            }
            let (v, w) = self.body_velocity(*b);
            let p = (v - s.linvel) * m - s.force * h;
            let l = inertia * (w - s.angvel) - s.torque * h;
            impulse[i] = [p.x, p.y, p.z, l.x, l.y, l.z];
        }
        // Rows at the substep start, the configuration Rapier built its own rows at.
        let mut specs = Vec::new();
        let mut jac: Vec<Real> = Vec::new();
        let mut owner: Vec<(usize, rows::RowEval)> = Vec::new();
        for (ji, e) in self.joints.iter().enumerate() {
            let Some(e) = e else { continue };
            if e.rows.is_empty() {
                continue;
            }
            let pose_of = |b: RigidBodyHandle| match index.get(&b) {
                Some(&i) => (starts[i].1.pose, starts[i].1.com),
                None => {
                    let rb = &self.physics.bodies[b];
                    (*rb.position(), rb.center_of_mass())
                }
            };
            let f = frame_pair(&e.low, pose_of(e.body1), pose_of(e.body2));
            specs.push(JointBlockSpec {
                rows: e.rows.len(),
                bodies: [index.get(&e.body1).copied(), index.get(&e.body2).copied()],
            });
            for r in &e.rows {
                let ev = r.eval(&f);
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
            .is_none_or(|k| k.joint_specs() != specs.as_slice() || k.num_bodies() != nb);
        if rebuild {
            self.recovery = KktSolver::new(nb, &specs).ok();
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
        // Accumulate each joint's wrench on body 2 and express it at node J in frame I.
        let mut wrench: Vec<(Vector, Vector)> =
            vec![(Vector::ZERO, Vector::ZERO); self.joints.len()];
        for ((ji, ev), m) in owner.iter().zip(&mu) {
            wrench[*ji].0 += ev.j2[0] * (*m / h);
            wrench[*ji].1 += ev.j2[1] * (*m / h);
        }
        for (ji, e) in self.joints.iter_mut().enumerate() {
            let Some(e) = e else { continue };
            let rb2 = &self.physics.bodies[e.body2];
            let pose1 = self.physics.bodies[e.body1].position();
            let node_j = *rb2.position() * e.ansys[1].translation;
            let axes_i = Matrix::from_quat(pose1.rotation * e.ansys[0].rotation);
            let (f, tau) = wrench[ji];
            let moment = tau - (node_j - rb2.center_of_mass()).cross(f);
            e.output.force = axes_i.transpose() * f;
            e.output.moment = axes_i.transpose() * moment;
        }
        self.starts = starts;
    }

    /// Reactions from the Lagrange multipliers of the last substep.
    fn lagrange_reactions(&mut self) {
        let h = self.last_h;
        for (ji, e) in self.joints.iter_mut().enumerate() {
            let Some(e) = e else { continue };
            // An asleep island keeps the reactions it had when it fell asleep.
            if self.lagrange.is_asleep(ji) {
                continue;
            }
            let (mut f, mut tau) = (Vector::ZERO, Vector::ZERO);
            if let Some(rows) = self.lagrange.rows_of(ji) {
                let pose1 = *self.physics.bodies[e.body1].position();
                let pose2 = *self.physics.bodies[e.body2].position();
                let c1 = self.physics.bodies[e.body1].center_of_mass();
                let c2 = self.physics.bodies[e.body2].center_of_mass();
                let fp = frame_pair(&e.low, (pose1, c1), (pose2, c2));
                for (row, r) in e.rows.iter().zip(rows) {
                    let ev = row.eval(&fp);
                    let m = self.lagrange.impulse[r] / h;
                    f += ev.j2[0] * m;
                    tau += ev.j2[1] * m;
                }
            }
            // Springs, dampers, loads and limit impulses of the last substep.
            f += e.effects.on_body2.0;
            tau += e.effects.on_body2.1;
            let rb2 = &self.physics.bodies[e.body2];
            let pose1 = self.physics.bodies[e.body1].position();
            let node_j = *rb2.position() * e.ansys[1].translation;
            let axes_i = Matrix::from_quat(pose1.rotation * e.ansys[0].rotation);
            let moment = tau - (node_j - rb2.center_of_mass()).cross(f);
            e.output.force = axes_i.transpose() * f;
            e.output.moment = axes_i.transpose() * moment;
        }
    }

    /// Diagnostics of the Lagrange backend (redundant rows, projection residual, warnings).
    pub fn lagrange_diagnostics(&self) -> &LagrangeDiagnostics {
        &self.lagrange.diagnostics
    }

    /// Absolute measures of a joint now, and the three wrapped Bryant angles.
    fn measures(&self, e: &JointEntry) -> ([Real; 6], [Real; 3]) {
        let p1 = self.physics.bodies[e.body1].position();
        let p2 = self.physics.bodies[e.body2].position();
        let f1 = *p1 * e.ansys[0];
        let f2 = *p2 * e.ansys[1];
        let a1 = Matrix::from_quat(f1.rotation);
        let a2 = Matrix::from_quat(f2.rotation);
        let u = kinematics::relative_displacement(&a1, f1.translation, f2.translation);
        let rel = kinematics::relative_rotation(&a1, &a2);
        // The genb joint measures its rotations as 3-1-3 Euler angles (alpha about e3, beta
        // about the intermediate x, gamma about the final z), reported in the ROTX, ROTY, ROTZ
        // slots in that order (our reading: the text names the angles, not their slots);
        // every other kind uses Bryant angles.
        let ang = if matches!(e.joint.kind, crate::catalogue::JointKind::Genb { .. }) {
            kinematics::euler_313_angles(&rel)
        } else {
            kinematics::bryant_angles(&rel)
        };
        ([u.x, u.y, u.z, ang[0], ang[1], ang[2]], ang)
    }

    pub(crate) fn refresh_output(&mut self, i: usize) {
        let Some(e) = &self.joints[i] else { return };
        let (mut m, wrapped) = self.measures(e);
        let p1 = *self.physics.bodies[e.body1].position();
        let p2 = *self.physics.bodies[e.body2].position();
        let f1 = p1 * e.ansys[0];
        let f2 = p2 * e.ansys[1];
        let a1 = Matrix::from_quat(f1.rotation);
        let (v1, w1) = self.point_velocity(e.body1, f1.translation);
        let (v2, w2) = self.point_velocity(e.body2, f2.translation);
        let vel = kinematics::relative_velocity(&a1, f1.translation, f2.translation, v1, v2, w1);
        let omg = kinematics::relative_angular_velocity(&a1, w1, w2);
        let (gap, angular_gap) = self.joint_gaps(e);
        let Some(e) = &mut self.joints[i] else { return };
        e.output.gap = gap;
        e.output.angular_gap = angular_gap;
        for k in 0..3 {
            // psi and theta are unwrapped; phi = asin(..) never wraps.
            m[3 + k] = if k == 1 {
                wrapped[k]
            } else {
                e.unwrap[k].update(wrapped[k])
            };
        }
        let d: [Real; 6] = core::array::from_fn(|k| m[k] - e.initial[k]);
        e.output.measure = m;
        e.output.displacement = Vector::new(d[0], d[1], d[2]);
        e.output.rotation = Vector::new(d[3], d[4], d[5]);
        e.output.velocity = vel;
        e.output.angular_velocity = omg;
        let b = &e.joint.behaviour;
        e.output.stops = e.effects.at_stop.iter().filter(|x| **x).count() as u8;
        e.output.locks = e.effects.locked.iter().filter(|x| x.is_some()).count() as u8;
        e.output.element_force = e.effects.force;
        e.output.friction = e.effects.friction;
        e.output.spring_energy = if b.has_forces() {
            let x: [Real; 6] =
                core::array::from_fn(|k| m[k] - b.reference[k].unwrap_or(e.initial[k]));
            b.spring_energy(&x, e.joint.kind.free())
        } else {
            0.0
        };
    }

    /// Velocity of the material point at `x` of a body, and the body's angular velocity.
    fn point_velocity(&self, b: RigidBodyHandle, x: Vector) -> (Vector, Vector) {
        let rb = &self.physics.bodies[b];
        if !rb.is_dynamic() {
            return (rb.velocity_at_point(x), rb.angvel());
        }
        let (v, w) = self.body_velocity(b);
        (v + w.cross(x - rb.center_of_mass()), w)
    }
}

pub(crate) fn frame_pair(low: &[Pose; 2], b1: (Pose, Vector), b2: (Pose, Vector)) -> FramePair {
    let f1 = b1.0 * low[0];
    let f2 = b2.0 * low[1];
    FramePair {
        p1: f1.translation,
        r1: Matrix::from_quat(f1.rotation),
        c1: b1.1,
        p2: f2.translation,
        r2: Matrix::from_quat(f2.rotation),
        c2: b2.1,
    }
}

/// World inertia tensor of a body at its current pose (kg m^2).
fn world_inertia(rb: &RigidBody) -> Matrix {
    inertia_at(rb, rb.position())
}

/// World inertia tensor of a body at `pose` (kg m^2).
fn inertia_at(rb: &RigidBody, pose: &Pose) -> Matrix {
    let mp = &rb.mass_properties().local_mprops;
    let r = Matrix::from_quat(pose.rotation * mp.principal_inertia_local_frame);
    let ip = mp.principal_inertia();
    r * Matrix::from_diagonal(ip) * r.transpose()
}

/// Checks that the joint's nodes are finite and its axes proper rotations.
/// Checks of the joint against its kind that need no body: a screw's pitch, and the
/// coincidence of the nodes of a revolute or universal joint with a body on each side (a
/// grounded side is placed at the other node).
fn validate_model(id: JointId, j: &Mpc184Joint, two_bodies: bool) -> Result<(), Error> {
    use crate::catalogue::JointKind;
    if let JointKind::Screw { pitch } = j.kind
        && !(pitch.is_finite() && pitch != 0.0)
    {
        return Err(Error::InvalidPitch { joint: id, pitch });
    }
    if two_bodies && matches!(j.kind, JointKind::Revolute { .. } | JointKind::Universal) {
        let distance = (j.node2 - j.node1).length();
        let scale = j.node1.length().max(j.node2.length()).max(1.0);
        let tolerance = crate::joint::COINCIDENCE_TOLERANCE * scale;
        if distance > tolerance {
            return Err(Error::NodesApart {
                joint: id,
                kind: j.kind.name(),
                distance,
                tolerance,
            });
        }
    }
    Ok(())
}

/// Why a dynamic body cannot take part in a joint: no (or a non-finite) mass, or a singular
/// inertia, on axes that are not locked. Fixed and kinematic bodies are always fine.
fn mass_defect(rb: &RigidBody) -> Option<String> {
    if !rb.is_dynamic() {
        return None;
    }
    let locked = rb.locked_axes();
    let mp = &rb.mass_properties().local_mprops;
    let translations = LockedAxes::TRANSLATION_LOCKED_X
        | LockedAxes::TRANSLATION_LOCKED_Y
        | LockedAxes::TRANSLATION_LOCKED_Z;
    let has_mass = mp.inv_mass.is_finite() && mp.inv_mass > 0.0;
    if !(has_mass || locked.contains(translations)) {
        return Some(format!(
            "a dynamic body with mass {} kg: give it mass, or make it fixed",
            mp.mass()
        ));
    }
    let rotations = LockedAxes::ROTATION_LOCKED_X
        | LockedAxes::ROTATION_LOCKED_Y
        | LockedAxes::ROTATION_LOCKED_Z;
    let inv = mp.inv_principal_inertia;
    let regular = inv.is_finite() && inv.min_element() > 0.0;
    if !(regular || locked.intersects(rotations)) {
        return Some(format!(
            "a dynamic body with a singular inertia (principal moments {} kg m^2): give it \
             rotary inertia about every axis, lock the rotation, or make it fixed",
            mp.principal_inertia()
        ));
    }
    None
}

fn validate_frames(id: JointId, j: &Mpc184Joint) -> Result<(), Error> {
    for (node, x, q) in [(1u8, j.node1, j.axes1), (2, j.node2, j.axes2())] {
        if !x.is_finite() {
            return Err(Error::DegenerateFrame {
                joint: id,
                node,
                reason: format!("position {x} is not finite"),
            });
        }
        if !q.is_finite() || (q.length() - 1.0).abs() > 1e-6 {
            return Err(Error::DegenerateFrame {
                joint: id,
                node,
                reason: format!("axes {q} are not a unit quaternion (a proper rotation)"),
            });
        }
    }
    Ok(())
}
