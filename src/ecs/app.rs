//! [`Mpc184PhysicsPlugin`]: the ECS systems as a `bevy_app::Plugin` (feature `bevy`), with
//! `Transform` read at spawn and written back after every step, in a schedule and on a clock of
//! the App's choice ([`Mpc184Timestep`]), as `avian`'s `PhysicsPlugins` and `bevy_rapier`'s
//! `RapierPhysicsPlugin` offer.
//!
//! | `Transform` | when | what |
//! |---|---|---|
//! | read | the body's first `Sync` | an entity spawned with [`Mpc184Body`] and a `Transform` starts at the `Transform`'s translation and rotation (the body's own `translation` and `rotation` are replaced); one spawned without gets a `Transform` from the body |
//! | written | every `Writeback` | translation = the body frame's origin, rotation = its orientation (global: keep body entities unparented) |
//!
//! `Transform` is `f32` (bevy's `Vec3` and `Quat`). In the `f32` build it is the body's pose bit
//! for bit; in the default `f64` build it is that pose rounded to `f32` (half an ulp: 6e-8 m at
//! 1 m), while the simulation itself stays in `f64` ([`BodyState`] has the full values).
//! Changing a `Transform` by hand does not move its body: the body's pose is the simulation's.

use bevy_app::{App, FixedUpdate, Plugin};
use bevy_ecs::intern::Interned;
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::ScheduleLabel;
use bevy_time::{Fixed, Time};
use bevy_transform::components::Transform;

use super::{BodyHandle, BodyState, Mpc184Body, Mpc184Plugin, Mpc184Systems, sync_bodies};
use crate::math::{Rotation, Vector};
use crate::world::WorldSettings;

/// When the simulation steps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Mpc184Timestep {
    /// bevy's fixed clock (the default, as in `avian` and `bevy_rapier`): the plugin sets the
    /// period of `Time<Fixed>` to `settings.dt` and runs in `FixedUpdate`, which bevy runs as
    /// many times per frame as the elapsed virtual time asks, so simulated time follows real time
    /// at any frame rate. Needs bevy's `TimePlugin` (in `MinimalPlugins` and `DefaultPlugins`).
    #[default]
    Fixed,
    /// One step of `settings.dt` every time `schedule` runs, whatever time passed
    /// (frame-locked: deterministic, for headless runs, tests and replays).
    PerRun {
        /// The schedule the systems run in (`Update`, `PostUpdate`, ...).
        schedule: Interned<dyn ScheduleLabel>,
    },
}

/// The simulation in a bevy `App`: [`Mpc184Sim`](super::Mpc184Sim) as a resource, the systems of
/// [`Mpc184Plugin`] in the sets [`Mpc184Systems`] (`Sync -> Step -> Writeback`), and the
/// `Transform` of body entities synchronised.
///
/// ```no_run
/// use bevy_app::App;
/// use rapier3d_mpc184::ecs::Mpc184PhysicsPlugin;
///
/// App::new().add_plugins(Mpc184PhysicsPlugin::default()).run();
/// ```
#[derive(Clone, Copy, Debug)]
pub struct Mpc184PhysicsPlugin {
    /// World settings (time step, substeps, backend, integrator).
    pub settings: WorldSettings,
    /// Gravity (m/s^2, global; default -9.81 along Y, bevy's up axis).
    pub gravity: Vector,
    /// When the simulation steps (default: bevy's fixed clock at `settings.dt`).
    pub timestep: Mpc184Timestep,
}

impl Default for Mpc184PhysicsPlugin {
    fn default() -> Self {
        let inner = Mpc184Plugin::default();
        Self {
            settings: inner.settings,
            gravity: inner.gravity,
            timestep: Mpc184Timestep::default(),
        }
    }
}

impl Mpc184PhysicsPlugin {
    /// These settings, stepping once per run of `schedule` ([`Mpc184Timestep::PerRun`]).
    #[must_use]
    pub fn per_run(mut self, schedule: impl ScheduleLabel) -> Self {
        self.timestep = Mpc184Timestep::PerRun {
            schedule: schedule.intern(),
        };
        self
    }
}

impl Plugin for Mpc184PhysicsPlugin {
    fn build(&self, app: &mut App) {
        let inner = Mpc184Plugin {
            settings: self.settings,
            gravity: self.gravity,
        };
        app.insert_resource(inner.sim());
        let schedule = match self.timestep {
            Mpc184Timestep::Fixed => {
                app.insert_resource(Time::<Fixed>::from_seconds(self.settings.dt as f64));
                FixedUpdate.intern()
            }
            Mpc184Timestep::PerRun { schedule } => schedule,
        };
        app.edit_schedule(schedule, |schedule| {
            Mpc184Plugin::add_systems(schedule);
            schedule.add_systems(
                body_pose_from_transform
                    .in_set(Mpc184Systems::Sync)
                    .before(sync_bodies),
            );
            schedule.add_systems(
                transform_from_body_state
                    .in_set(Mpc184Systems::Writeback)
                    .after(super::write_body_states),
            );
        });
    }
}

/// Bodies not yet created that have no `Transform`.
type Unplaced = (Without<BodyHandle>, Without<Transform>);

/// A body spawned with a `Transform` starts there; one spawned without gets one.
pub fn body_pose_from_transform(
    mut commands: Commands,
    mut with: Query<(&Transform, &mut Mpc184Body), Without<BodyHandle>>,
    without: Query<(Entity, &Mpc184Body), Unplaced>,
) {
    for (t, mut body) in &mut with {
        body.translation = from_bevy_vec(t.translation);
        body.rotation = from_bevy_quat(t.rotation);
    }
    for (e, body) in &without {
        commands.entity(e).insert(Transform {
            translation: to_bevy_vec(body.translation),
            rotation: to_bevy_quat(body.rotation),
            ..Transform::IDENTITY
        });
    }
}

/// Writes every body's pose into its `Transform`.
pub fn transform_from_body_state(mut q: Query<(&BodyState, &mut Transform)>) {
    for (state, mut t) in &mut q {
        t.translation = to_bevy_vec(state.translation);
        t.rotation = to_bevy_quat(state.rotation);
    }
}

// bevy's `Vec3`/`Quat` are glam's, the same glam as Rapier's: the f32 build needs no
// conversion, the f64 build rounds to f32 (and widens exactly on the way in).
#[cfg(feature = "f64")]
fn to_bevy_vec(v: Vector) -> glam::Vec3 {
    v.as_vec3()
}
#[cfg(feature = "f64")]
fn to_bevy_quat(q: Rotation) -> glam::Quat {
    q.as_quat()
}
#[cfg(feature = "f64")]
fn from_bevy_vec(v: glam::Vec3) -> Vector {
    v.as_dvec3()
}
#[cfg(feature = "f64")]
fn from_bevy_quat(q: glam::Quat) -> Rotation {
    q.as_dquat().normalize()
}
#[cfg(feature = "f32")]
fn to_bevy_vec(v: Vector) -> glam::Vec3 {
    v
}
#[cfg(feature = "f32")]
fn to_bevy_quat(q: Rotation) -> glam::Quat {
    q
}
#[cfg(feature = "f32")]
fn from_bevy_vec(v: glam::Vec3) -> Vector {
    v
}
#[cfg(feature = "f32")]
fn from_bevy_quat(q: glam::Quat) -> Rotation {
    q.normalize()
}
