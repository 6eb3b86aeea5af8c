//! The screw coupling (KEYOPT(1) = 17) on Rapier's own joints, beside the Lagrange backend: a
//! 2 kg nut with 0.01 kg m^2 about the screw's axis on a grounded screw along global +Y (e3),
//! pitch 0.005 m/rad, gravity -9.81 along Y, released at rest; dt 1/60 s x 4 substeps, 1 s.
//!
//! Exact: travel and turn are one DOF with the inertia `m + I / p^2`, so the nut descends at
//! `a = -g / (1 + I / (m p^2)) = -0.048806 m/s^2` and `UZ = a t^2 / 2`, `ROTZ = UZ / p`.
//!
//! The Rapier backends see a cylindrical joint and the coupling is projected back in the mass
//! metric after every Rapier call (`src/backend/rapier/screw.rs`): exact in the velocities for
//! a constant load. `a` taken as `2 UZ / t^2` carries the symplectic Euler position's offset
//! `h / t` (substep `h` = 1/240 s: 4.2e-3 at 1 s), the same on all three backends (measured
//! 4.10e-3, 4.10e-3, 4.17e-3): checked at the 1e-2. The coupling `UZ - p ROTZ` and the
//! joint's gap stay at round-off (1e-11 m Lagrange, 1e-17 m Rapier): checked at 1e-6 m.
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

const M: Real = 2.0;
const I: Real = 0.01;
const P: Real = 0.005;

#[test]
fn the_nut_descends_at_the_coupled_acceleration_on_every_backend() {
    let a = -9.81 / (1.0 + I / (M * P * P));
    for backend in [
        Backend::Lagrange,
        Backend::RapierImpulse,
        Backend::RapierMultibody,
    ] {
        let mut world = Mpc184World::new(WorldSettings {
            backend,
            ..Default::default()
        });
        world.physics.gravity = Vector::new(0.0, -9.81, 0.0);
        let nut = world.physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .additional_mass_properties(MassProperties::new(Vector::ZERO, M, Vector::splat(I)))
                .can_sleep(false),
        );
        // e3 along global +Y.
        let axes = Rotation::from_rotation_x(-rapier3d_mpc184::math::PI / 2.0);
        let screw = Mpc184Joint::new(JointKind::Screw { pitch: P }, Vector::ZERO).with_axes(axes);
        let id = world.insert_joint(None, Some(nut), screw).unwrap();
        let mut gap: Real = 0.0;
        for _ in 0..60 {
            world.step().unwrap();
            gap = gap.max(world.output(id).unwrap().gap);
        }
        let o = world.output(id).unwrap();
        let t = world.time();
        let measured = 2.0 * o.displacement.z / (t * t);
        let err = (measured - a).abs() / a.abs();
        let coupling = (o.displacement.z - P * o.rotation.z).abs();
        println!(
            "{}: a = {measured:.6} m/s^2 (exact {a:.6}, {err:.2e}), coupling error {coupling:.2e} m, gap {gap:.2e} m",
            backend.name()
        );
        assert!(
            err <= 1e-2,
            "{}: acceleration off by {err:.3e}",
            backend.name()
        );
        assert!(
            coupling <= 1e-6,
            "{}: coupling error {coupling:.3e} m",
            backend.name()
        );
        assert!(gap <= 1e-6, "{}: gap {gap:.3e} m", backend.name());
    }
}
