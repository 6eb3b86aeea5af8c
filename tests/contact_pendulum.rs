//! Contacts still act on jointed bodies (Lagrange backend): a pendulum bob (ball of radius 0.1 m,
//! 1 kg, on a 1 m rod from a grounded revolute z joint at the origin) released horizontally
//! swings down onto a floor whose top is at y = -0.5 m. The circle of the bob's centre dips below
//! y = -0.4 m, so the bob comes to rest on the floor at x = sqrt(1 - 0.4^2) = 0.9165 m.
//!
//! Statics there: the rod force is radial, so moments about the pivot give `x (N - m g) = 0`:
//! the floor carries the whole weight and the rod force vanishes. Checked after 5 s (dt 1/60,
//! 4 substeps): the bob is at rest (speed < 1e-3 m/s), on the floor (centre height -0.4 m within
//! Rapier's contact tolerance of 5 mm), the joint is intact (pivot gap <= 1e-9 m: the position
//! projection runs after Rapier's contact solve).
//!
//! The exact rod force at rest is 0; the reported one is printed, not asserted: while a contact
//! acts, Rapier's own copy of the joint rows (which keeps contact and joint consistent inside
//! Rapier's solver) carries part of the load, and that share is not yet added to the reaction.
#![cfg(feature = "f64")]

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::scenes;

#[test]
fn pendulum_bob_rests_on_the_floor_with_the_joint_intact() {
    let (mut world, bob, pin) = scenes::pendulum_onto_floor(WorldSettings::default()).unwrap();
    let mut max_gap: Real = 0.0;
    for _ in 0..300 {
        world.step().unwrap();
        max_gap = max_gap.max(world.output(pin).unwrap().gap);
    }
    let rb = &world.physics.bodies[bob];
    let (p, v) = (rb.translation(), rb.linvel());
    let force = world.output(pin).unwrap().force.length();
    println!(
        "bob at {p:?}, speed {:.2e} m/s, rod force {force:.3e} N, max gap {max_gap:.2e} m",
        v.length()
    );
    assert!(
        v.length() < 1e-3,
        "bob still moving at {:.3e} m/s",
        v.length()
    );
    assert!(
        (p.y + 0.4).abs() < 5e-3,
        "bob centre at y = {} (expected -0.4 on the floor)",
        p.y
    );
    assert!(
        (p.x - 0.84_f64.sqrt()).abs() < 1e-2,
        "bob at x = {} (expected 0.9165)",
        p.x
    );
    assert!(max_gap <= 1e-9, "pivot opened by {max_gap:.3e} m");
}
