//! DJ by velocity and acceleration labels (`VELX..OMGZ`, `ACCX..DMGZ`) on the Lagrange backend.
//!
//! A 1 kg block on a grounded translational joint along X (gravity -Y is carried by the joint):
//! - `VELX` ramped from 0 to 0.5 m/s over 1 s, then held (KBC,0 ramp): `x = 0.25 t^2` for
//!   t <= 1, then `0.25 + 0.5 (t - 1)`;
//! - `ACCX` = 0.2 m/s^2 stepped on at t = 0.5 s, after the block was left at rest: `x = 0.1 (t -
//!   0.5)^2`;
//! - `OMGZ` = 2 rad/s on a revolute z wheel: `theta = 2 t`.
//!
//! The drive's target is the exact integral of the profile (piecewise polynomial) and the drive
//! row is projected like any constraint, so the DOF follows it to the projection tolerance:
//! checked within 1e-9 m (rad) over 3 s.
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

fn one_body(joint: Mpc184Joint) -> (Mpc184World, JointId) {
    let mut world = Mpc184World::new(WorldSettings::default());
    let b = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, Vector::splat(0.1)))
            .can_sleep(false),
    );
    let id = world.insert_joint(None, Some(b), joint).unwrap();
    (world, id)
}

#[test]
fn velocity_drive_follows_the_integral_of_its_ramp() {
    let (mut world, id) = one_body(Mpc184Joint::new(JointKind::Translational, Vector::ZERO));
    let ramp = DriveProfile {
        t0: 0.0,
        t1: 1.0,
        from: 0.0,
        to: 0.5,
        stepped: false,
        extend: false,
    };
    world
        .set_drive_level(id, Dof::Ux, DriveLevel::Velocity, ramp)
        .unwrap();
    let mut worst: Real = 0.0;
    for _ in 0..180 {
        world.step().unwrap();
        let t = world.time();
        let exact = if t <= 1.0 {
            0.25 * t * t
        } else {
            0.25 + 0.5 * (t - 1.0)
        };
        worst = worst.max((world.output(id).unwrap().displacement.x - exact).abs());
    }
    println!("VELX ramp: worst error {worst:.2e} m");
    assert!(worst <= 1e-9, "{worst:.3e}");
}

#[test]
fn acceleration_drive_set_mid_run_integrates_from_then() {
    let (mut world, id) = one_body(Mpc184Joint::new(JointKind::Translational, Vector::ZERO));
    for _ in 0..30 {
        world.step().unwrap();
    }
    let t_set = world.time();
    let step = DriveProfile {
        t0: 0.0,
        t1: 0.0,
        from: 0.2,
        to: 0.2,
        stepped: true,
        extend: false,
    };
    world
        .set_drive_level(id, Dof::Ux, DriveLevel::Acceleration, step)
        .unwrap();
    let mut worst: Real = 0.0;
    for _ in 0..150 {
        world.step().unwrap();
        let t = world.time() - t_set;
        let exact = 0.1 * t * t;
        worst = worst.max((world.output(id).unwrap().displacement.x - exact).abs());
    }
    println!("ACCX from t = {t_set:.3}: worst error {worst:.2e} m");
    assert!(worst <= 1e-9, "{worst:.3e}");
}

#[test]
fn angular_velocity_drive_turns_the_wheel_at_its_rate() {
    let (mut world, id) = one_body(Mpc184Joint::revolute(Axis::Z, Vector::ZERO));
    world
        .set_drive_level(
            id,
            Dof::RotZ,
            DriveLevel::Velocity,
            DriveProfile::constant(2.0),
        )
        .unwrap();
    let mut worst: Real = 0.0;
    for _ in 0..180 {
        world.step().unwrap();
        let t = world.time();
        worst = worst.max((world.output(id).unwrap().rotation.z - 2.0 * t).abs());
    }
    println!("OMGZ: worst error {worst:.2e} rad");
    assert!(worst <= 1e-9, "{worst:.3e}");
}
