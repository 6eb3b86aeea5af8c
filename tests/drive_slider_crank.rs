//! Prescribed relative motion (ANSYS `DJ,elem,ROTZ,...`) on the Lagrange backend: a planar
//! slider-crank whose crank is driven at 1 rad/s. Crank r = 0.2 m on a grounded revolute z at the
//! origin, connecting rod L = 0.6 m, slider on a grounded translational joint along global X,
//! gravity on (the drive's multiplier supplies whatever moment the motion needs).
//!
//! The slider position is pure kinematics, `x = r cos(t) + sqrt(L^2 - r^2 sin^2(t))`; the drive is
//! a rheonomic constraint row projected with the others, so the slider follows it within 1e-6 m
//! (the bound; the projection tolerance is 1e-10) over 8 s (more than a turn), and the
//! crank angle follows `t` within 1e-9 rad. The energy balance (kinetic + potential - drive
//! work) stays within 2e-2 J after the impulsive start (the drive exchanges about 2 J with
//! gravity per turn; its work is booked per substep as impulse times prescribed rate, a
//! first-order quadrature: measured 8e-3 J).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

#[test]
fn driven_slider_crank_follows_the_exact_slider_position() {
    let (r, l) = (0.2, 0.6);
    let mut world = Mpc184World::new(WorldSettings::default());
    let body = |world: &mut Mpc184World, at: Vector, m: Real| {
        world.physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .translation(at)
                .additional_mass_properties(MassProperties::new(
                    Vector::ZERO,
                    m,
                    Vector::splat(0.01),
                ))
                .can_sleep(false),
        )
    };
    // At t = 0 the crank points along +X: crank pin at (r, 0), slider at (r + L, 0).
    let crank = body(&mut world, Vector::new(0.5 * r, 0.0, 0.0), 1.0);
    let rod = body(&mut world, Vector::new(r + 0.5 * l, 0.0, 0.0), 1.0);
    let slider = body(&mut world, Vector::new(r + l, 0.0, 0.0), 2.0);
    let pivot = world
        .insert_joint(
            None,
            Some(crank),
            Mpc184Joint::revolute(Axis::Z, Vector::ZERO),
        )
        .unwrap();
    world
        .insert_joint(
            Some(crank),
            Some(rod),
            Mpc184Joint::revolute(Axis::Z, Vector::new(r, 0.0, 0.0)),
        )
        .unwrap();
    world
        .insert_joint(
            Some(rod),
            Some(slider),
            Mpc184Joint::revolute(Axis::Z, Vector::new(r + l, 0.0, 0.0)),
        )
        .unwrap();
    let guide = world
        .insert_joint(
            None,
            Some(slider),
            Mpc184Joint::new(JointKind::Translational, Vector::new(r + l, 0.0, 0.0)),
        )
        .unwrap();
    world
        .set_drive(pivot, Dof::RotZ, DriveProfile::constant_rate(1.0))
        .unwrap();
    let (mut worst_x, mut worst_angle): (Real, Real) = (0.0, 0.0);
    // The drive starts the mechanism impulsively in the first step; the balance is taken from
    // the end of it.
    world.step().unwrap();
    let e1 = world.energy();
    let mut balance: Real = 0.0;
    for _ in 1..480 {
        world.step().unwrap();
        balance = balance.max((world.energy().total - e1.total).abs());
        let t = world.time();
        let x = world.physics.bodies[slider].translation().x;
        let exact = r * t.cos() + (l * l - r * r * t.sin() * t.sin()).sqrt();
        worst_x = worst_x.max((x - exact).abs());
        worst_angle = worst_angle.max((world.output(pivot).unwrap().rotation.z - t).abs());
    }
    let slide = world.output(guide).unwrap().displacement.x;
    let work = world.energy().work - e1.work;
    println!(
        "driven slider-crank: worst slider error {worst_x:.2e} m, crank angle error {worst_angle:.2e} rad, slide now {slide:.4} m, drive work {work:.4} J, balance {balance:.3e} J"
    );
    assert!(
        worst_x <= 1e-6,
        "slider off the exact position by {worst_x:.3e} m"
    );
    assert!(balance <= 2e-2, "energy balance off by {balance:.3e} J");
    assert!(
        worst_angle <= 1e-9,
        "crank off its drive by {worst_angle:.3e} rad"
    );
}
