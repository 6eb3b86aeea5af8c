//! `DJ` drives on Rapier's own joints, beside the Lagrange backend.
//!
//! 1. The planar slider-crank of `tests/drive_slider_crank.rs` (crank r = 0.2 m driven at
//!    1 rad/s about a grounded revolute z, rod L = 0.6 m, slider on a grounded translational
//!    joint along X, gravity on; 1 kg, 1 kg, 2 kg, 0.01 kg m^2 each), 8 s, dt 1/60 s x 4, on the
//!    impulse backend (multibody joints cannot close its loop): the slider follows the exact
//!    kinematics `x = r cos t + sqrt(L^2 - r^2 sin^2 t)` within 1e-3 m (the bound): the
//!    drive is a stiff velocity motor during each Rapier call and is put on its value at the
//!    call's end, so the slider's error is Rapier's own joint error around the loop (measured
//!    8.9e-4 m; Lagrange 2.7e-11 m). The energy balance with the drive's work booked (its
//!    recovered multiplier times the prescribed rate) stays within the Lagrange test's 2e-2 J
//!    (measured 4.5e-3 J; Lagrange 8.2e-3 J) while the drive exchanges about 2 J per turn.
//! 2. A driven hinge on the multibody backend (a 1 kg bob on 1 m, gravity on, the hinge driven
//!    at 2 rad/s through several turns): the hinge angle is the drive's `2 t` to 1e-9 rad at
//!    every step (the correction sets the joint's own coordinate), and the energy balance with
//!    the drive's work booked stays within 2 % of `2 m g L` (the gravity work the drive trades
//!    each turn; measured 0.245 J, 1.2 %: on this backend the drive's force is the multiplier
//!    of the step's last substep, held over the step, first order in the step).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

fn body(world: &mut Mpc184World, at: Vector, m: Real) -> RigidBodyHandle {
    world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(at)
            .additional_mass_properties(MassProperties::new(Vector::ZERO, m, Vector::splat(0.01)))
            .can_sleep(false),
    )
}

use rapier3d_mpc184::math::rapier::prelude::RigidBodyHandle;

/// (largest slider error, largest crank angle error, largest energy balance change after the
/// first step).
fn slider_crank_error(backend: Backend) -> (Real, Real, Real) {
    let (r, l) = (0.2, 0.6);
    let mut world = Mpc184World::new(WorldSettings {
        backend,
        ..Default::default()
    });
    world.physics.gravity = Vector::new(0.0, -9.81, 0.0);
    let crank = body(&mut world, Vector::new(0.5 * r, 0.0, 0.0), 1.0);
    let rod = body(&mut world, Vector::new(r + 0.5 * l, 0.0, 0.0), 1.0);
    let slider = body(&mut world, Vector::new(r + l, 0.0, 0.0), 2.0);
    let z = |at: Vector| Mpc184Joint::revolute(Axis::Z, at);
    let pivot = world
        .insert_joint(None, Some(crank), z(Vector::ZERO))
        .unwrap();
    world
        .insert_joint(Some(crank), Some(rod), z(Vector::new(r, 0.0, 0.0)))
        .unwrap();
    world
        .insert_joint(Some(rod), Some(slider), z(Vector::new(r + l, 0.0, 0.0)))
        .unwrap();
    let guide = Mpc184Joint::new(JointKind::Translational, Vector::new(r + l, 0.0, 0.0));
    world.insert_joint(None, Some(slider), guide).unwrap();
    world
        .set_drive(pivot, Dof::RotZ, DriveProfile::constant_rate(1.0))
        .unwrap();
    let (mut worst_x, mut worst_angle): (Real, Real) = (0.0, 0.0);
    // The drive starts the mechanism impulsively in the first step; the balance from its end.
    world.step().unwrap();
    let e1 = world.energy().total;
    let mut balance: Real = 0.0;
    for _ in 1..480 {
        world.step().unwrap();
        balance = balance.max((world.energy().total - e1).abs());
        let t = world.time();
        let x = world.physics.bodies[slider].translation().x;
        let exact = r * t.cos() + (l * l - r * r * t.sin() * t.sin()).sqrt();
        worst_x = worst_x.max((x - exact).abs());
        worst_angle = worst_angle.max((world.output(pivot).unwrap().rotation.z - t).abs());
    }
    (worst_x, worst_angle, balance)
}

#[test]
fn driven_slider_crank_follows_the_kinematics_on_the_impulse_backend() {
    for backend in [Backend::Lagrange, Backend::RapierImpulse] {
        let (x, angle, balance) = slider_crank_error(backend);
        println!(
            "{}: slider error {x:.2e} m, crank angle error {angle:.2e} rad, energy balance {balance:.2e} J",
            backend.name()
        );
        assert!(x <= 1e-3, "{}: slider error {x:.3e} m", backend.name());
        assert!(
            angle <= 1e-6,
            "{}: crank angle error {angle:.3e} rad",
            backend.name()
        );
        assert!(
            balance <= 2e-2,
            "{}: energy balance {balance:.3e} J",
            backend.name()
        );
    }
}

#[test]
fn a_driven_hinge_turns_with_its_drive_on_the_multibody_backend() {
    let mut world = Mpc184World::new(WorldSettings {
        backend: Backend::RapierMultibody,
        ..Default::default()
    });
    world.physics.gravity = Vector::new(0.0, -9.81, 0.0);
    let bob = body(&mut world, Vector::new(1.0, 0.0, 0.0), 1.0);
    let hinge = world
        .insert_joint(
            None,
            Some(bob),
            Mpc184Joint::revolute(Axis::Z, Vector::ZERO),
        )
        .unwrap();
    world
        .set_drive(hinge, Dof::RotZ, DriveProfile::constant_rate(2.0))
        .unwrap();
    let mut worst: Real = 0.0;
    world.step().unwrap();
    let e1 = world.energy().total;
    let mut balance: Real = 0.0;
    for _ in 1..300 {
        world.step().unwrap();
        let o = world.output(hinge).unwrap();
        worst = worst.max((o.rotation.z - 2.0 * world.time()).abs());
        balance = balance.max((world.energy().total - e1).abs());
    }
    println!(
        "multibody driven hinge: angle error {worst:.2e} rad over 5 s (10 rad), energy balance {balance:.2e} J"
    );
    assert!(worst <= 1e-9, "angle error {worst:.3e} rad");
    assert!(
        balance <= 2e-2 * 2.0 * 9.81,
        "energy balance {balance:.3e} J"
    );
}
