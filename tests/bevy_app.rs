//! `Mpc184PhysicsPlugin` in a headless bevy `App` (no window, no renderer): a 1 kg bob on a
//! 1 m massless hinge about Z, released horizontally, gravity -9.81 along Y.
//!
//! - Frame-locked (`per_run(Update)`): every `app.update()` is one step of 1/60 s x 4 substeps,
//!   so the body must follow a plain `Mpc184World` built with the same calls step for step. Both
//!   run the same f64 arithmetic in the same order, so they agree to round-off; 1e-9 m is the
//!   issue's bound and leaves that far behind. The bob's `Transform` must be the body's position
//!   rounded to f32 (bevy's `Vec3`), exactly: the plugin writes `as_vec3()` of it, nothing else
//!   (in the f32 build the rounding is the identity). The pendulum must swing: released at
//!   90 deg it passes the bottom (x < 0) after a quarter of its 2.37 s period.
//! - Bevy's fixed clock (the default): with a virtual frame time of 1/120 s fixed by
//!   `TimeUpdateStrategy::ManualDuration`, `FixedUpdate` runs once per two frames, so 240 frames
//!   advance the simulation by 2 s less what bevy's first frame does not count (its delta is 0:
//!   the clock starts there), i.e. 239 frames of 1/120 s = 119 steps of 1/60 s.
//! - A body spawned with a `Transform` starts at the `Transform`, one spawned without gets one.
#![cfg(feature = "bevy")]

use std::time::Duration;

use bevy_app::{App, Update};
use bevy_ecs::prelude::*;
use bevy_time::{TimePlugin, TimeUpdateStrategy};
use bevy_transform::components::Transform;
use rapier3d_mpc184::ecs::*;
use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

const DT: Real = 1.0 / 60.0;

fn settings() -> WorldSettings {
    WorldSettings {
        dt: DT,
        substeps: 4,
        ..Default::default()
    }
}

/// Spawns the bob (at its `Transform`, with a dummy pose in `Mpc184Body`) and the hinge.
fn spawn_pendulum(app: &mut App) -> (Entity, Entity) {
    let world = app.world_mut();
    let bob = world
        .spawn((
            Transform::from_xyz(1.0, 0.0, 0.0),
            Mpc184Body::dynamic(Vector::new(5.0, 5.0, 5.0), 1.0, Vector::splat(1e-4)),
        ))
        .id();
    let hinge = world
        .spawn(Mpc184JointSpec {
            joint: Mpc184Joint::revolute(Axis::Z, Vector::ZERO),
            body1: None,
            body2: Some(bob),
        })
        .id();
    (bob, hinge)
}

#[test]
fn transform_follows_the_bob_step_for_step() {
    let mut app = App::new();
    app.add_plugins(
        Mpc184PhysicsPlugin {
            settings: settings(),
            ..Default::default()
        }
        .per_run(Update),
    );
    let (bob, hinge) = spawn_pendulum(&mut app);

    // The same pendulum on a plain world.
    let mut reference = Mpc184World::new(settings());
    reference.physics.gravity = Vector::new(0.0, -9.81, 0.0);
    let h = reference.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(1.0, 0.0, 0.0))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, Vector::splat(1e-4)))
            .can_sleep(false),
    );
    let id = reference
        .insert_joint(None, Some(h), Mpc184Joint::revolute(Axis::Z, Vector::ZERO))
        .unwrap();

    let (mut worst, mut passed_bottom) = (0.0 as Real, false);
    for _ in 0..120 {
        app.update();
        reference.step().unwrap();
        let expected = reference.physics.bodies[h].position().translation;
        let state = *app.world().get::<BodyState>(bob).unwrap();
        worst = worst.max((state.translation - expected).length());
        let t = app.world().get::<Transform>(bob).unwrap();
        assert_eq!(
            t.translation,
            glam::Vec3::new(expected.x as f32, expected.y as f32, expected.z as f32)
        );
        passed_bottom |= expected.x < 0.0;
    }
    let sim = app.world().resource::<Mpc184Sim>();
    assert!(sim.last_error.is_none(), "{:?}", sim.last_error);
    assert!(worst <= 1e-9, "body off the reference by {worst:e} m");
    assert!(passed_bottom, "the bob never passed the bottom in 2 s");
    let rot = app.world().get::<JointState>(hinge).unwrap().0.rotation.z;
    let expected = reference.output(id).unwrap().rotation.z;
    assert!((rot - expected).abs() <= 1e-9, "{rot} vs {expected}");
}

#[test]
fn bevys_fixed_clock_steps_at_dt() {
    let mut app = App::new();
    app.add_plugins((
        TimePlugin,
        Mpc184PhysicsPlugin {
            settings: settings(),
            ..Default::default()
        },
    ));
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
        1.0 / 120.0,
    )));
    spawn_pendulum(&mut app);
    for _ in 0..240 {
        app.update();
    }
    let t = app.world().resource::<Mpc184Sim>().world.time();
    let steps = (t / DT).round();
    // The clock sums dt once per step: each sum rounds by at most half an ulp of 2 s
    // (EPSILON of 2), 119 of them.
    assert!(
        (t - steps * DT).abs() <= steps * 2.0 * Real::EPSILON,
        "t = {t} is not a whole number of steps"
    );
    assert_eq!(steps, 119.0, "t = {t} s");
}

#[test]
fn a_body_without_transform_gets_one_from_its_pose() {
    let mut app = App::new();
    app.add_plugins(Mpc184PhysicsPlugin::default().per_run(Update));
    let body = app
        .world_mut()
        .spawn(Mpc184Body {
            fixed: true,
            ..Mpc184Body::dynamic(Vector::new(0.5, 2.0, -1.0), 1.0, Vector::splat(1.0))
        })
        .id();
    app.update();
    let t = app
        .world()
        .get::<Transform>(body)
        .expect("a Transform was inserted");
    assert_eq!(t.translation, glam::Vec3::new(0.5, 2.0, -1.0));
    assert_eq!(t.rotation, glam::Quat::IDENTITY);
}
