//! Sleeping islands cost nothing on the Lagrange backend: a joint whose bodies all sleep in
//! Rapier has no rows until the island wakes. A 1 kg pendulum hanging at rest (1 m, revolute z)
//! is left to fall asleep; while asleep its reported reaction stays the static tension `m g`
//! (to 1e-6: the solver's regularisation) and it does not move. Woken with a sideways speed of
//! 0.5 m/s it swings as a pendulum again: the joint closed (gap <= 1e-9 m) and the energy
//! `m v^2 / 2` turned into height `v^2 / (2 g)` at the turning point (to 1e-3 relative: the first-order
//! scheme's energy oscillation at this 9 deg amplitude is ~1e-4, measured 8e-5).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

#[test]
fn asleep_pendulum_costs_nothing_and_wakes_correctly() {
    let mut world = Mpc184World::new(WorldSettings::default());
    let bob = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(0.0, -1.0, 0.0))
            .additional_mass_properties(MassProperties::new(
                Vector::ZERO,
                1.0,
                Vector::splat(1e-4),
            )),
    );
    let id = world
        .insert_joint(
            None,
            Some(bob),
            Mpc184Joint::revolute(Axis::Z, Vector::ZERO),
        )
        .unwrap();
    let mut slept = false;
    for _ in 0..600 {
        world.step().unwrap();
        if world.physics.bodies[bob].is_sleeping() {
            slept = true;
            break;
        }
    }
    assert!(slept, "the pendulum never fell asleep");
    let y0 = world.physics.bodies[bob].translation().y;
    for _ in 0..60 {
        world.step().unwrap();
    }
    let out = *world.output(id).unwrap();
    let moved = (world.physics.bodies[bob].translation().y - y0).abs();
    println!(
        "asleep: tension {:.9} N, moved {moved:.2e} m",
        out.force.length()
    );
    assert!(world.physics.bodies[bob].is_sleeping());
    assert!((out.force.length() - 9.81).abs() <= 1e-6 * 9.81);
    assert!(moved == 0.0);
    let v = 0.5;
    world.physics.bodies[bob].set_linvel(Vector::new(v, 0.0, 0.0), true);
    let (mut top, mut gap): (Real, Real) = (Real::NEG_INFINITY, 0.0);
    for _ in 0..60 {
        world.step().unwrap();
        top = top.max(world.physics.bodies[bob].translation().y);
        gap = gap.max(world.output(id).unwrap().gap);
    }
    let rise = top - y0;
    let expected = v * v / (2.0 * 9.81);
    println!("woken: rise {rise:.6} m vs {expected:.6} m, gap {gap:.2e} m");
    assert!(gap <= 1e-9);
    assert!((rise - expected).abs() <= 1e-3 * expected, "rise {rise}");
}
