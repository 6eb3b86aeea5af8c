//! `bevy_ecs` integration (feature `ecs`): [`Mpc184Plugin`] for a bare `World` and `Schedule`,
//! and (feature `bevy`) [`Mpc184PhysicsPlugin`], a `bevy_app::Plugin` with `Transform` sync and a
//! choice of schedule and time step.
//!
//! | component | written by | meaning |
//! |---|---|---|
//! | [`Mpc184Body`] | you | a rigid body: pose, mass, inertia, initial velocity (SI) |
//! | [`BodyHandle`] | sync | its Rapier handle |
//! | [`BodyState`] | write-back | its pose and velocity after each step |
//! | [`Mpc184JointSpec`] | you | an MPC184 joint between two body entities (`None`: ground) |
//! | [`JointHandle`] | sync | its id in the simulation |
//! | [`JointState`] | write-back | the joint output (relative DOFs, rates, reactions) |
//!
//! The systems run in the sets [`Mpc184Systems`] chained `Sync -> Step -> Writeback`: spawned
//! bodies and joints are created, changed joints re-created, despawned ones removed (a body's
//! joints with it); the simulation advances one `dt`; the states are written back. A failed step
//! keeps its error in [`Mpc184Sim::last_error`].
//!
//! ```
//! use bevy_ecs::prelude::*;
//! use rapier3d_mpc184::ecs::*;
//! use rapier3d_mpc184::prelude::*;
//!
//! let mut world = World::new();
//! let mut schedule = Schedule::default();
//! Mpc184Plugin::default().add_to(&mut world, &mut schedule);
//! let bob = world.spawn(Mpc184Body::dynamic(Vector::new(1.0, 0.0, 0.0), 1.0, Vector::splat(1e-4))).id();
//! let hinge = world
//!     .spawn(Mpc184JointSpec { joint: Mpc184Joint::revolute(Axis::Z, Vector::ZERO), body1: None, body2: Some(bob) })
//!     .id();
//! for _ in 0..30 {
//!     schedule.run(&mut world);
//! }
//! let out = world.get::<JointState>(hinge).unwrap();
//! assert!(out.0.rotation.z < 0.0);
//! ```

#[cfg(feature = "bevy")]
mod app;

use std::collections::HashMap;

use bevy_ecs::prelude::*;

use crate::error::{Error, JointId};
use crate::joint::Mpc184Joint;
use crate::math::rapier::dynamics::{MassProperties, RigidBodyBuilder, RigidBodyHandle};
use crate::math::{Real, Rotation, Vector};
use crate::world::{JointOutput, Mpc184World, WorldSettings};

#[cfg(feature = "bevy")]
pub use app::{Mpc184PhysicsPlugin, Mpc184Timestep};

/// The simulation as a resource.
#[derive(Resource)]
pub struct Mpc184Sim {
    /// The library world.
    pub world: Mpc184World,
    /// The error of the last failed sync or step, if any.
    pub last_error: Option<Error>,
    bodies: HashMap<Entity, RigidBodyHandle>,
    joints: HashMap<Entity, JointId>,
}

impl Mpc184Sim {
    /// The Rapier handle of a body entity.
    pub fn body(&self, e: Entity) -> Option<RigidBodyHandle> {
        self.bodies.get(&e).copied()
    }

    /// The joint id of a joint entity.
    pub fn joint(&self, e: Entity) -> Option<JointId> {
        self.joints.get(&e).copied()
    }
}

/// A rigid body to simulate (read once, when the entity is spawned).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Mpc184Body {
    /// Position of the centre of mass (m, global).
    pub translation: Vector,
    /// Orientation (global).
    pub rotation: Rotation,
    /// Mass (kg); ignored for fixed bodies.
    pub mass: Real,
    /// Principal inertia about the centre of mass in body axes (kg m^2).
    pub inertia: Vector,
    /// Initial velocity of the centre of mass (m/s).
    pub linvel: Vector,
    /// Initial angular velocity (rad/s).
    pub angvel: Vector,
    /// A fixed (grounded) body.
    pub fixed: bool,
}

impl Mpc184Body {
    /// A dynamic body at rest.
    pub fn dynamic(translation: Vector, mass: Real, inertia: Vector) -> Self {
        Self {
            translation,
            rotation: Rotation::IDENTITY,
            mass,
            inertia,
            linvel: Vector::ZERO,
            angvel: Vector::ZERO,
            fixed: false,
        }
    }
}

/// The Rapier handle of a body entity (written by the sync systems).
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
pub struct BodyHandle(pub RigidBodyHandle);

/// Pose and velocity of a body after the last step.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq)]
pub struct BodyState {
    /// Position of the body frame (m).
    pub translation: Vector,
    /// Orientation.
    pub rotation: Rotation,
    /// Velocity of the centre of mass (m/s).
    pub linvel: Vector,
    /// Angular velocity (rad/s).
    pub angvel: Vector,
}

/// An MPC184 joint between body entities (node I on `body1`, node J on `body2`; `None` is the
/// ground). Changing it re-creates the joint; removing or despawning it removes the joint.
#[derive(Component, Clone, Debug, PartialEq)]
pub struct Mpc184JointSpec {
    /// The joint.
    pub joint: Mpc184Joint,
    /// Body at node I.
    pub body1: Option<Entity>,
    /// Body at node J.
    pub body2: Option<Entity>,
}

/// The simulation id of a joint entity (written by the sync systems).
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
pub struct JointHandle(pub JointId);

/// The output of a joint after the last step.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq)]
pub struct JointState(pub JointOutput);

/// The plugin's system sets, chained in this order.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mpc184Systems {
    /// Bodies and joints spawned, changed or despawned since the last run are applied.
    Sync,
    /// The simulation advances one `dt`.
    Step,
    /// Body and joint states are written back to their components.
    Writeback,
}

/// Adds the simulation resource and its systems to a `World` and `Schedule`.
#[derive(Clone, Copy, Debug)]
pub struct Mpc184Plugin {
    /// World settings (time step, substeps, backend).
    pub settings: WorldSettings,
    /// Gravity (m/s^2; default -9.81 along Y).
    pub gravity: Vector,
}

impl Default for Mpc184Plugin {
    fn default() -> Self {
        Self {
            settings: WorldSettings::default(),
            gravity: Vector::new(0.0, -9.81, 0.0),
        }
    }
}

impl Mpc184Plugin {
    /// Inserts [`Mpc184Sim`] into `world` and the systems into `schedule`.
    pub fn add_to(&self, world: &mut World, schedule: &mut Schedule) {
        world.insert_resource(self.sim());
        Self::add_systems(schedule);
    }

    /// The simulation resource these settings describe.
    fn sim(&self) -> Mpc184Sim {
        let mut sim = Mpc184World::new(self.settings);
        sim.physics.gravity = self.gravity;
        Mpc184Sim {
            world: sim,
            last_error: None,
            bodies: HashMap::new(),
            joints: HashMap::new(),
        }
    }

    /// The sets, chained, and the systems in them.
    fn add_systems(schedule: &mut Schedule) {
        schedule.configure_sets(
            (
                Mpc184Systems::Sync,
                Mpc184Systems::Step,
                Mpc184Systems::Writeback,
            )
                .chain(),
        );
        schedule.add_systems(
            (sync_bodies, sync_joints)
                .chain()
                .in_set(Mpc184Systems::Sync),
        );
        schedule.add_systems(step_simulation.in_set(Mpc184Systems::Step));
        schedule
            .add_systems((write_body_states, write_joint_states).in_set(Mpc184Systems::Writeback));
    }
}

/// Creates spawned bodies, removes despawned ones (with their joints).
pub fn sync_bodies(
    mut commands: Commands,
    mut sim: ResMut<Mpc184Sim>,
    added: Query<(Entity, &Mpc184Body), Without<BodyHandle>>,
    mut removed: RemovedComponents<Mpc184Body>,
) {
    for e in removed.read() {
        if let Some(h) = sim.bodies.remove(&e) {
            let gone = sim.world.remove_body(h);
            sim.joints.retain(|_, id| !gone.contains(id));
        }
    }
    for (e, b) in &added {
        let builder = if b.fixed {
            RigidBodyBuilder::fixed()
        } else {
            RigidBodyBuilder::dynamic()
        };
        let h = sim.world.physics.bodies.insert(
            builder
                .translation(b.translation)
                .rotation(b.rotation.to_scaled_axis())
                .linvel(b.linvel)
                .angvel(b.angvel)
                .additional_mass_properties(MassProperties::new(Vector::ZERO, b.mass, b.inertia))
                .can_sleep(false),
        );
        sim.bodies.insert(e, h);
        commands
            .entity(e)
            .insert((BodyHandle(h), BodyState::default()));
    }
}

/// Creates spawned and changed joints, removes despawned ones.
pub fn sync_joints(
    mut commands: Commands,
    mut sim: ResMut<Mpc184Sim>,
    changed: Query<(Entity, &Mpc184JointSpec), Changed<Mpc184JointSpec>>,
    mut removed: RemovedComponents<Mpc184JointSpec>,
) {
    for e in removed.read() {
        if let Some(id) = sim.joints.remove(&e) {
            let _ = sim.world.remove_joint(id);
        }
    }
    for (e, spec) in &changed {
        if let Some(id) = sim.joints.remove(&e) {
            let _ = sim.world.remove_joint(id);
        }
        // None is the ground; an entity must be a synced body.
        let lookup = |b: Option<Entity>| -> Result<Option<RigidBodyHandle>, ()> {
            match b {
                None => Ok(None),
                Some(b) => sim.bodies.get(&b).copied().map(Some).ok_or(()),
            }
        };
        let (Ok(b1), Ok(b2)) = (lookup(spec.body1), lookup(spec.body2)) else {
            sim.last_error = Some(Error::Unsupported {
                what: format!("joint entity {e:?} refers to an entity without Mpc184Body"),
                hint: "spawn the bodies with Mpc184Body before (or with) the joint".into(),
            });
            continue;
        };
        match sim.world.insert_joint(b1, b2, spec.joint.clone()) {
            Ok(id) => {
                sim.joints.insert(e, id);
                commands
                    .entity(e)
                    .insert((JointHandle(id), JointState::default()));
            }
            Err(err) => sim.last_error = Some(err),
        }
    }
}

/// Advances the simulation one step.
pub fn step_simulation(mut sim: ResMut<Mpc184Sim>) {
    if let Err(e) = sim.world.step() {
        sim.last_error = Some(e);
    }
}

/// Writes body poses and velocities back.
pub fn write_body_states(sim: Res<Mpc184Sim>, mut q: Query<(&BodyHandle, &mut BodyState)>) {
    for (h, mut state) in &mut q {
        let Some(rb) = sim.world.physics.bodies.get(h.0) else {
            continue;
        };
        let Ok((linvel, angvel)) = sim.world.body_velocity(h.0) else {
            continue;
        };
        let pose = rb.position();
        *state = BodyState {
            translation: pose.translation,
            rotation: pose.rotation,
            linvel,
            angvel,
        };
    }
}

/// Writes joint outputs back.
pub fn write_joint_states(sim: Res<Mpc184Sim>, mut q: Query<(&JointHandle, &mut JointState)>) {
    for (h, mut state) in &mut q {
        if let Ok(out) = sim.world.output(h.0) {
            state.0 = *out;
        }
    }
}
