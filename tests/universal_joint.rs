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
