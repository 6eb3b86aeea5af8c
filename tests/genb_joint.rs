//! The genb joint (KEYOPT(1) = 19) measures its rotations as 3-1-3 Euler angles
//! (`R = Rz(alpha) Rx(beta) Rz(gamma)`, reported in the ROTX, ROTY, ROTZ slots in that order).
//! A body on a grounded genb joint with the translations locked and the rotations released
//! (`SECJOINT,RDOF` fixing UX UY UZ), its local system at J turned by (alpha0, beta0, gamma0) =
//! (0.3, 0.5, 0.2) rad against I, spun about the fixed e3 of I at 2 rad/s (gravity off, a
//! spherical inertia: the spin stays about e3): a rotation about e3 of I adds to alpha only, so
//! the measure is `(0.3 + phi(t), 0.5, 0.2)` and the relative rotation output `(phi(t), 0, 0)`
//! with `phi` the angle the body has turned. Rapier's quaternion update turns a body spinning at
//! `w` by `2 atan(w h / 2)` per substep (normalised `q + h/2 w q`), so `phi = 4 n atan(h)` after
//! n substeps (`(w h)^3 / 12` short of `w h` each: 1.2e-5 rad after 1 s). Checked to 1e-9 rad
//! over 1 s: the 3-1-3 measure itself is exact.
//! Behaviour on the genb rotations is an error naming GENB (the 3-1-3 angles are singular at
//! an aligned start).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

#[test]
fn genb_reports_3_1_3_euler_angles() {
    let mut world = Mpc184World::new(WorldSettings::default());
    world.physics.gravity = Vector::ZERO;
    let b = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .angvel(Vector::new(0.0, 0.0, 2.0))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, Vector::splat(0.1)))
            .can_sleep(false),
    );
    let (a0, b0, g0) = (0.3, 0.5, 0.2);
    let axes2 = Rotation::from_rotation_z(a0)
        * Rotation::from_rotation_x(b0)
        * Rotation::from_rotation_z(g0);
    let kind = JointKind::Genb {
        released: DofMask::of(&[Dof::RotX, Dof::RotY, Dof::RotZ]),
        translations_only: false,
    };
    let joint = Mpc184Joint::new(kind, Vector::ZERO).with_axes2(axes2);
    let id = world.insert_joint(None, Some(b), joint.clone()).unwrap();
    let m0 = world.output(id).unwrap().measure;
    let mut worst: Real = 0.0;
    for _ in 0..60 {
        world.step().unwrap();
        let t = world.time();
        let o = world.output(id).unwrap();
        let h = world.settings().dt / world.settings().substeps as Real;
        let phi = (t / h).round() * 2.0 * (2.0 * h / 2.0).atan();
        worst = worst
            .max((o.measure[3] - (a0 + phi)).abs())
            .max((o.measure[4] - b0).abs())
            .max((o.measure[5] - g0).abs())
            .max((o.rotation.x - phi).abs());
    }
    println!(
        "initial measure {:?}, worst deviation {worst:.2e} rad",
        &m0[3..]
    );
    assert!((m0[3] - a0).abs() < 1e-12 && (m0[4] - b0).abs() < 1e-12 && (m0[5] - g0).abs() < 1e-12);
    assert!(worst <= 1e-9, "{worst:.3e}");
    let e = world
        .insert_joint(None, Some(b), joint.with_stop(Dof::RotZ, -1.0, 1.0))
        .unwrap_err();
    assert!(e.to_string().contains("GENB"), "{e}");
}
