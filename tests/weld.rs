//! A weld joint (KEYOPT(1) = 13) holds all six relative DOFs: a body welded at an offset to a
//! free, spinning, falling body keeps its initial relative pose.
//!
//! Body 1: 2 kg, principal inertia (0.1, 0.2, 0.3) kg m^2, spinning at (1, 2, 3) rad/s (so the
//! gyroscopic term is active) and falling under gravity. Body 2: 1 kg welded 0.5 m away along
//! x with a rotated local system. After 2 s at dt = 1/60 (4 substeps) the relative displacement
//! and Bryant angles of J from I must be unchanged.
//!
//! Multibody joints hold a weld exactly (reduced coordinates: no relative coordinates at all),
//! so 1e-9 (the bound) is round-off. Rapier impulse joints hold it only to the velocity
//! solver's error; their figure is printed and asserted at 1e-3 m / 1e-3 rad.
//!
//! Tolerances are f64 round-off bounds: the file runs in the default f64 build only
//! (`tests/f32_smoke.rs` covers the f32 build).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

fn run(backend: Backend) -> (Real, Real) {
    let mut world = Mpc184World::new(WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        backend,
        ..Default::default()
    });
    let b1 = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .angvel(Vector::new(1.0, 2.0, 3.0))
            .additional_mass_properties(MassProperties::new(
                Vector::ZERO,
                2.0,
                Vector::new(0.1, 0.2, 0.3),
            ))
            .can_sleep(false),
    );
    let b2 = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(0.5, 0.0, 0.0))
            .additional_mass_properties(MassProperties::new(
                Vector::ZERO,
                1.0,
                Vector::new(0.05, 0.05, 0.02),
            ))
            .can_sleep(false),
    );
    // Body 2 must start with the rigid-body velocity of body 1's motion at its position.
    let w = Vector::new(1.0, 2.0, 3.0);
    world.physics.bodies[b2].set_linvel(w.cross(Vector::new(0.5, 0.0, 0.0)), true);
    world.physics.bodies[b2].set_angvel(w, true);
    let weld = Mpc184Joint::new(JointKind::Weld, Vector::new(0.25, 0.0, 0.0))
        .with_axes(Rotation::from_euler(glam::EulerRot::ZYX, 0.3, -0.2, 0.1));
    let id = world.insert_joint(Some(b1), Some(b2), weld).unwrap();
    let (mut du, mut dr): (Real, Real) = (0.0, 0.0);
    for _ in 0..120 {
        world.step().unwrap();
        let out = world.output(id).unwrap();
        du = du.max(out.displacement.length());
        dr = dr.max(out.rotation.length());
    }
    (du, dr)
}

#[test]
fn weld_keeps_the_relative_pose() {
    let (du, dr) = run(Backend::RapierMultibody);
    println!("multibody: max |du| {du:.2e} m, max |drot| {dr:.2e} rad");
    assert!(
        du <= 1e-9 && dr <= 1e-9,
        "multibody weld moved: {du:.2e} m, {dr:.2e} rad"
    );
    let (du, dr) = run(Backend::RapierImpulse);
    println!("impulse: max |du| {du:.2e} m, max |drot| {dr:.2e} rad");
    assert!(
        du <= 1e-3 && dr <= 1e-3,
        "impulse weld moved: {du:.2e} m, {dr:.2e} rad"
    );
}
