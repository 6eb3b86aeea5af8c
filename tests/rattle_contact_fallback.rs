//! The second-order integrator falls back to the first-order step for an island while it has
//! an active contact: a pendulum bob (ball of radius 0.1 m, 1 kg, on a 1 m revolute rod at the
//! origin) released horizontally swings onto a floor whose top is at y = -0.5 m (the bob's
//! centre circle dips to y = -1). Run beside an identical world without the floor, both with
//! `Integrator::Rattle`.
//!
//! Checked: (a) until the first contact (a step that ends with no active contact pair, before
//! any fallback), no body falls back and the two worlds agree bit for bit (the fallback costs nothing where there is no contact, and the floor's collider does
//! not perturb the second-order step); (b) once the bob touches, the diagnostics report one
//! first-order body in that step, count the steps, and warn once; (c) the run stays finite and
//! the joint intact (pivot gap <= 1e-9 m) while Rapier's contact acts.
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{ColliderBuilder, MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

fn world(floor: bool) -> (Mpc184World, JointId, RigidBodyHandle) {
    let mut w = Mpc184World::new(WorldSettings {
        integrator: Integrator::Rattle,
        ..WorldSettings::default()
    });
    w.physics.gravity = Vector::new(0.0, -9.81, 0.0);
    let bob = w.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(1.0, 0.0, 0.0))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, Vector::splat(4e-3)))
            .can_sleep(false),
    );
    let ball = ColliderBuilder::ball(0.1).density(0.0).build();
    w.physics
        .colliders
        .insert_with_parent(ball, bob, &mut w.physics.bodies);
    if floor {
        let base = w
            .physics
            .bodies
            .insert(RigidBodyBuilder::fixed().translation(Vector::new(0.0, -1.0, 0.0)));
        let slab = ColliderBuilder::cuboid(3.0, 0.5, 3.0).build();
        w.physics
            .colliders
            .insert_with_parent(slab, base, &mut w.physics.bodies);
    }
    let pin = w
        .insert_joint(
            None,
            Some(bob),
            Mpc184Joint::revolute(Axis::Z, Vector::ZERO),
        )
        .unwrap();
    (w, pin, bob)
}

use rapier3d_mpc184::math::rapier::dynamics::RigidBodyHandle;

#[test]
fn islands_in_contact_take_the_first_order_step() {
    let (mut a, pin, bob_a) = world(true);
    let (mut b, _, bob_b) = world(false);
    let mut first_contact = None;
    let mut max_gap: Real = 0.0;
    for step in 0..180 {
        a.step().unwrap();
        b.step().unwrap();
        let fallback = a.lagrange_diagnostics().first_order_bodies;
        if fallback > 0 && first_contact.is_none() {
            first_contact = Some(step);
            assert_eq!(fallback, 1);
        }
        let touching = a
            .physics
            .contact_pairs()
            .any(|c| c.has_any_active_contact());
        if !touching && first_contact.is_none() {
            let (ra, rb) = (&a.physics.bodies[bob_a], &b.physics.bodies[bob_b]);
            assert_eq!(
                ra.position(),
                rb.position(),
                "step {step}: differs before contact"
            );
            assert_eq!(
                ra.linvel(),
                rb.linvel(),
                "step {step}: differs before contact"
            );
        }
        let p = a.physics.bodies[bob_a].translation();
        assert!(p.is_finite());
        max_gap = max_gap.max(a.output(pin).unwrap().gap);
    }
    let d = a.lagrange_diagnostics();
    println!(
        "first contact at step {first_contact:?}, fallback steps {}, warnings {:?}, gap {max_gap:.1e}",
        d.first_order_steps, d.warnings
    );
    let first = first_contact.expect("the bob never touched the floor");
    assert!(first > 5, "contact from the start: the scene is wrong");
    assert!(d.first_order_steps >= 1);
    assert_eq!(
        d.warnings
            .iter()
            .filter(|w| w.contains("first-order step"))
            .count(),
        1
    );
    assert!(max_gap <= 1e-9, "pivot gap {max_gap:.3e}");
}
