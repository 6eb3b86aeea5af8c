//! Universal joint (KEYOPT(1) = 7) on the Lagrange backend: the Cardan relation.
//!
//! Input shaft A along global X, output shaft B in the X-Y plane at the shaft angle beta = 30
//! deg, each on a grounded revolute about its own axis, joined at the origin by a universal
//! joint whose frame I has e2 along A and e1 (the input yoke's pin) along Y, in the plane of the
//! shafts, and whose frame J has e2 along B and e3 (the output pin) along Z. MPC184 holds the
//! angle between e1 of I and e3 of J (the Bryant ROTY row `e1I . e3J`), which makes the cross.
//!
//! With both angles measured from that start (the input yoke in the plane of the shafts) the
//! classical Cardan relation is `tan(alpha2) = tan(alpha1) / cos(beta)`. A is heavy (100 kg m^2
//! about its axis) and spun at 2 rad/s, B light (0.01 kg m^2), no gravity: over 4 s (more than a
//! turn) the relation must hold within 1e-6 rad at every step (the constraints are projected to
//! 1e-10; the bound). The speed ratio then oscillates between cos(beta) and 1/cos(beta).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::Matrix;
use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

#[test]
fn single_universal_joint_follows_the_cardan_relation() {
    let beta = 30f64.to_radians() as Real;
    let mut world = Mpc184World::new(WorldSettings::default());
    world.physics.gravity = Vector::ZERO;
    let dir_b = Vector::new(beta.cos(), beta.sin(), 0.0);
    let shaft_a = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(-0.5, 0.0, 0.0))
            .angvel(Vector::new(2.0, 0.0, 0.0))
            .additional_mass_properties(MassProperties::new(
                Vector::ZERO,
                1.0,
                Vector::new(100.0, 1.0, 1.0),
            ))
            .can_sleep(false),
    );
    let shaft_b = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(dir_b * 0.5)
            .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, Vector::splat(0.01)))
            .can_sleep(false),
    );
    // Revolute x joints: e1 along each shaft.
    let along = |d: Vector| Rotation::from_rotation_arc(Vector::X, d);
    let rev_a = world
        .insert_joint(
            None,
            Some(shaft_a),
            Mpc184Joint::revolute(Axis::X, Vector::new(-0.5, 0.0, 0.0)),
        )
        .unwrap();
    let rev_b = world
        .insert_joint(
            None,
            Some(shaft_b),
            Mpc184Joint::revolute(Axis::X, dir_b * 0.5).with_axes(along(dir_b)),
        )
        .unwrap();
    // Universal: frame I columns (Y, X, -Z), frame J columns (e2 x Z, B, Z).
    let axes_i = Rotation::from_mat3(&Matrix::from_cols(Vector::Y, Vector::X, -Vector::Z));
    let axes_j = Rotation::from_mat3(&Matrix::from_cols(dir_b.cross(Vector::Z), dir_b, Vector::Z));
    let cross = Mpc184Joint::new(JointKind::Universal, Vector::ZERO)
        .with_axes(axes_i)
        .with_axes2(axes_j);
    let uj = world
        .insert_joint(Some(shaft_a), Some(shaft_b), cross)
        .unwrap();
    let mut worst: Real = 0.0;
    let mut turned: Real = 0.0;
    for _ in 0..240 {
        world.step().unwrap();
        let a1 = world.output(rev_a).unwrap().rotation.x;
        let a2 = world.output(rev_b).unwrap().rotation.x;
        let predicted = (a1.sin() / beta.cos()).atan2(a1.cos());
        let mut d = a2 - predicted;
        d -=
            2.0 * std::f64::consts::PI as Real * (d / (2.0 * std::f64::consts::PI as Real)).round();
        worst = worst.max(d.abs());
        turned = a1;
    }
    let gap = world.output(uj).unwrap().angular_gap;
    println!(
        "cardan: input turned {turned:.3} rad, worst |alpha2 - atan(tan(alpha1)/cos(beta))| = {worst:.2e} rad, cross gap {gap:.1e}"
    );
    assert!(
        turned > 2.0 * std::f64::consts::PI as Real,
        "the input shaft turned only {turned} rad"
    );
    assert!(worst <= 1e-6, "Cardan relation off by {worst:.3e} rad");
}

/// Double Cardan shaft: input A along X, intermediate C at beta = 25 deg in the X-Y plane, output
/// B parallel to A (a "Z" arrangement: equal angles), the two yokes of C in one plane (both its
/// pins along Z). The two Cardan errors cancel: B turns exactly with A (constant-velocity
/// transmission), checked to 1e-6 rad over more than a turn while the intermediate shaft's speed
/// oscillates.
#[test]
fn double_cardan_shaft_transmits_constant_speed() {
    let beta = 25f64.to_radians() as Real;
    let mut world = Mpc184World::new(WorldSettings::default());
    world.physics.gravity = Vector::ZERO;
    let dir_c = Vector::new(beta.cos(), beta.sin(), 0.0);
    let p = dir_c; // second universal joint, 1 m along C
    let body = |world: &mut Mpc184World, at: Vector, w: Vector, inertia: Vector| {
        world.physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .translation(at)
                .angvel(w)
                .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, inertia))
                .can_sleep(false),
        )
    };
    let a = body(
        &mut world,
        Vector::new(-0.5, 0.0, 0.0),
        Vector::new(2.0, 0.0, 0.0),
        Vector::new(100.0, 1.0, 1.0),
    );
    let c = body(&mut world, dir_c * 0.5, Vector::ZERO, Vector::splat(0.01));
    let b = body(
        &mut world,
        p + Vector::new(0.5, 0.0, 0.0),
        Vector::ZERO,
        Vector::splat(0.01),
    );
    let along = |d: Vector| Rotation::from_rotation_arc(Vector::X, d);
    let rev_a = world
        .insert_joint(
            None,
            Some(a),
            Mpc184Joint::revolute(Axis::X, Vector::new(-0.5, 0.0, 0.0)),
        )
        .unwrap();
    world
        .insert_joint(
            None,
            Some(c),
            Mpc184Joint::revolute(Axis::X, dir_c * 0.5).with_axes(along(dir_c)),
        )
        .unwrap();
    let rev_b = world
        .insert_joint(
            None,
            Some(b),
            Mpc184Joint::revolute(Axis::X, p + Vector::new(0.5, 0.0, 0.0)),
        )
        .unwrap();
    let frame =
        |e1: Vector, e2: Vector| Rotation::from_mat3(&Matrix::from_cols(e1, e2, e1.cross(e2)));
    // First cross: A's pin along Y (in the plane), C's pin along Z.
    let u1 = Mpc184Joint::new(JointKind::Universal, Vector::ZERO)
        .with_axes(frame(Vector::Y, Vector::X))
        .with_axes2(frame(dir_c.cross(Vector::Z), dir_c));
    world.insert_joint(Some(a), Some(c), u1).unwrap();
    // Second cross: C's pin along Z (in phase with its first yoke), B's pin along Y.
    let u2 = Mpc184Joint::new(JointKind::Universal, p)
        .with_axes(frame(Vector::Z, dir_c))
        .with_axes2(frame(Vector::Z, Vector::X));
    world.insert_joint(Some(c), Some(b), u2).unwrap();
    let (mut worst, mut turned): (Real, Real) = (0.0, 0.0);
    for _ in 0..240 {
        world.step().unwrap();
        let (aa, ab) = (
            world.output(rev_a).unwrap().rotation.x,
            world.output(rev_b).unwrap().rotation.x,
        );
        worst = worst.max((ab - aa).abs());
        turned = aa;
    }
    println!(
        "double cardan: input turned {turned:.3} rad, worst |alpha_out - alpha_in| = {worst:.2e} rad"
    );
    assert!(
        turned > 2.0 * std::f64::consts::PI as Real,
        "the input shaft turned only {turned} rad"
    );
    assert!(
        worst <= 1e-6,
        "output lags the input by up to {worst:.3e} rad"
    );
}
