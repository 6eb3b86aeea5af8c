//! The `bevy_ecs` plugin (feature `ecs`): a pendulum spawned as entities gives bit-for-bit the
//! library's result (the plugin adds no physics of its own: same body, same joint, same steps);
//! the plugin's schedule has no system-order ambiguities (built with ambiguity detection set to
//! error); despawning a body removes its joints from the simulation and the next steps run.
#![cfg(all(feature = "ecs", feature = "f64"))]

use bevy_ecs::prelude::*;
use bevy_ecs::schedule::{LogLevel, ScheduleBuildSettings};
use rapier3d_mpc184::ecs::*;
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::scenes;

fn spawn_pendulum(world: &mut World) -> (Entity, Entity) {
    let theta0 = 60f64.to_radians() as Real;
    let bob = world
        .spawn(Mpc184Body::dynamic(
            Vector::new(theta0.sin(), -theta0.cos(), 0.0),
            1.0,
            Vector::splat(1e-4),
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
fn ecs_pendulum_matches_the_library_exactly() {
    let settings = WorldSettings::default();
    let mut world = World::new();
    let mut schedule = Schedule::default();
    Mpc184Plugin {
        settings,
        gravity: Vector::new(0.0, -scenes::G, 0.0),
    }
    .add_to(&mut world, &mut schedule);
    let (bob, hinge) = spawn_pendulum(&mut world);
    let mut lib = scenes::pendulum(
        settings,
        Axis::Z,
        1.0,
        60f64.to_radians() as Real,
        1.0,
        1e-4,
    )
    .unwrap();
    for _ in 0..120 {
        schedule.run(&mut world);
        lib.world.step().unwrap();
    }
    let ecs_out = world.get::<JointState>(hinge).unwrap().0;
    let lib_out = *lib.world.output(lib.joint).unwrap();
    let ecs_pos = world.get::<BodyState>(bob).unwrap().translation;
    let lib_pos = lib.world.physics.bodies[lib.bob].translation();
    println!(
        "ecs rotz {} lib rotz {}",
        ecs_out.rotation.z, lib_out.rotation.z
    );
    assert!(world.resource::<Mpc184Sim>().last_error.is_none());
    assert_eq!(ecs_out, lib_out, "joint output differs");
    assert_eq!(ecs_pos, lib_pos, "bob position differs");
}

#[test]
fn plugin_schedule_has_no_ambiguities() {
    let mut world = World::new();
    let mut schedule = Schedule::default();
    schedule.set_build_settings(ScheduleBuildSettings {
        ambiguity_detection: LogLevel::Error,
        ..Default::default()
    });
    Mpc184Plugin::default().add_to(&mut world, &mut schedule);
    let built = schedule.initialize(&mut world);
    assert!(built.is_ok(), "schedule ambiguities: {:?}", built.err());
}

#[test]
fn despawning_a_body_removes_its_joints() {
    let mut world = World::new();
    let mut schedule = Schedule::default();
    Mpc184Plugin::default().add_to(&mut world, &mut schedule);
    let (bob, hinge) = spawn_pendulum(&mut world);
    for _ in 0..10 {
        schedule.run(&mut world);
    }
    assert_eq!(world.resource::<Mpc184Sim>().world.joint_ids().count(), 1);
    assert!(world.resource::<Mpc184Sim>().joint(hinge).is_some());
    world.despawn(bob);
    for _ in 0..10 {
        schedule.run(&mut world);
    }
    let sim = world.resource::<Mpc184Sim>();
    assert_eq!(
        sim.world.joint_ids().count(),
        0,
        "the joint outlived its body"
    );
    assert!(sim.joint(hinge).is_none());
    assert!(
        sim.last_error.is_none(),
        "error after despawn: {:?}",
        sim.last_error
    );
    // Despawning the joint entity afterwards is harmless.
    world.despawn(hinge);
    schedule.run(&mut world);
    assert!(world.resource::<Mpc184Sim>().last_error.is_none());
}
