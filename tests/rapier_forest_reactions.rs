//! Reactions recovered joint by joint on the Rapier backends when the joints form a forest
//! (`src/backend/rapier/reactions/forest.rs`): each joint carries exactly the bodies beyond it.
//!
//! - A chain of three bodies (1, 2 and 3 kg) hangs at rest from the ground on revolute joints
//!   about z; on the impulse backend the middle joint's nodes are swapped (its child is node I,
//!   so the recovery reads that joint's Jacobian on body 1). Statics: each joint's force is the
//!   weight below it, `(6, 5, 3) kg * g`, vertical, and its moment is zero (the joints are in
//!   line with the weights). At rest the bodies' momentum changes are what Rapier's soft joints
//!   leave moving: measured 3.7e-8 of the weight on the impulse backend, round-off on the
//!   multibody one. 1e-6 leaves a factor 27 and still fails on a joint given one body too many
//!   or too few (17 % at least).
//! - A floating pair (no ground, zero gravity) spins at 2 rad/s about its centre of mass,
//!   joined by a spherical joint at that centre: 1 kg at 0.75 m and 3 kg at 0.25 m. The joint
//!   carries the centripetal force of the state, `mu w^2 d` (reduced mass 0.75 kg, `d` the
//!   distance of the bodies, `w` their spin; 3 N at the start). Rapier's solver slows the spin
//!   (to 1.985 rad/s in 1 s), so the force is judged against the state at each step's end; the
//!   recovered force is the step's mean, `O(h)` away from it: measured 8.4e-4, asserted within
//!   5e-3, which a force taken from the wrong body's lever (a factor 3) fails. The first step is
//!   left out: in Rapier's first step, without a warm start, the bodies' momenta change by 0.75
//!   of the centripetal impulse (2.25 N recovered).
//! - A loop keeps the KKT split: a 2 kg bar hung from the ground by spherical joints at both
//!   ends closes a loop through the ground. By symmetry each joint carries half the weight,
//!   `g` N upwards on the bar (the minimum-norm split leaves no axial force). Measured 2.4e-9
//!   of it; 1e-6 as above.
#![cfg(feature = "f64")]

mod common;

use common::full_outputs;

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder, RigidBodyHandle};
use rapier3d_mpc184::prelude::*;

const G: Real = 9.81;

fn body(world: &mut Mpc184World, at: Vector, mass: Real, v: Vector, w: Vector) -> RigidBodyHandle {
    world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(at)
            .linvel(v)
            .angvel(w)
            .additional_mass_properties(MassProperties::new(
                Vector::ZERO,
                mass,
                Vector::splat(0.01 * mass),
            ))
            .can_sleep(false),
    )
}

#[test]
fn hanging_chain_joints_carry_the_weight_below() {
    for backend in [Backend::RapierImpulse, Backend::RapierMultibody] {
        let mut world = Mpc184World::new(full_outputs(backend));
        world.physics.gravity = Vector::new(0.0, -G, 0.0);
        let at = |y: Real| Vector::new(0.0, y, 0.0);
        let a = body(&mut world, at(-0.5), 1.0, Vector::ZERO, Vector::ZERO);
        let b = body(&mut world, at(-1.5), 2.0, Vector::ZERO, Vector::ZERO);
        let c = body(&mut world, at(-2.5), 3.0, Vector::ZERO, Vector::ZERO);
        let rev = |y| Mpc184Joint::revolute(Axis::Z, at(y));
        // On the impulse backend the middle joint's nodes are swapped, so that its child `b`
        // is node I; a multibody joint needs its parent at node I.
        let middle = match backend {
            Backend::RapierImpulse => world.insert_joint(Some(b), Some(a), rev(-1.0)),
            _ => world.insert_joint(Some(a), Some(b), rev(-1.0)),
        };
        let joints = [
            world.insert_joint(None, Some(a), rev(0.0)).unwrap(),
            middle.unwrap(),
            world.insert_joint(Some(b), Some(c), rev(-2.0)).unwrap(),
        ];
        for _ in 0..30 {
            world.step().unwrap();
        }
        for (j, below) in joints.iter().zip([6.0, 5.0, 3.0]) {
            let o = world.output(*j).unwrap();
            let weight = below * G;
            println!(
                "{}: force {:?} N, moment {:?} N m (weight {weight} N)",
                backend.name(),
                o.force,
                o.moment
            );
            assert!(
                (o.force.length() - weight).abs() <= 1e-6 * weight,
                "{}: |F| {} against {weight}",
                backend.name(),
                o.force.length()
            );
            assert!(o.force.y.abs() >= (1.0 - 1e-6) * weight, "not vertical");
            assert!(o.moment.length() <= 1e-6 * weight, "moment {:?}", o.moment);
        }
    }
}

#[test]
fn floating_pair_joint_carries_the_centripetal_force() {
    let mut world = Mpc184World::new(full_outputs(Backend::RapierImpulse));
    world.physics.gravity = Vector::ZERO;
    let omega = Vector::new(0.0, 0.0, 2.0);
    let x1 = Vector::new(-0.75, 0.0, 0.0);
    let x2 = Vector::new(0.25, 0.0, 0.0);
    let b1 = body(&mut world, x1, 1.0, omega.cross(x1), omega);
    let b2 = body(&mut world, x2, 3.0, omega.cross(x2), omega);
    let joint = Mpc184Joint::new(JointKind::Spherical, Vector::ZERO);
    let j = world.insert_joint(Some(b1), Some(b2), joint).unwrap();
    let (mut worst, mut slowest): (Real, Real) = (0.0, 2.0);
    for step in 0..60 {
        world.step().unwrap();
        let f = world.output(j).unwrap().force.length();
        // The centripetal force of the pair's state: reduced mass times w^2 d.
        let bodies = &world.physics.bodies;
        let d = (bodies[b2].translation() - bodies[b1].translation()).length();
        let w = bodies[b1].angvel().z;
        let state = 0.75 * w * w * d;
        if step == 0 {
            println!("floating pair: first step {f:.4} N, state {state:.4} N");
            continue;
        }
        worst = worst.max((f - state).abs() / state);
        slowest = slowest.min(w);
    }
    println!("floating pair: worst relative force error {worst:.3e} over 1 s, w down to {slowest}");
    assert!(worst <= 5e-3, "force error {worst:.3e}");
    // The state itself stays near the spin it started with (Rapier's solver loses some).
    assert!(slowest >= 0.95 * 2.0, "w {slowest}");
}

#[test]
fn loop_through_the_ground_shares_the_weight() {
    let mut world = Mpc184World::new(full_outputs(Backend::RapierImpulse));
    world.physics.gravity = Vector::new(0.0, -G, 0.0);
    let bar = body(&mut world, Vector::ZERO, 2.0, Vector::ZERO, Vector::ZERO);
    let joints = [-0.5, 0.5].map(|x| {
        let joint = Mpc184Joint::new(JointKind::Spherical, Vector::new(x, 0.0, 0.0));
        world.insert_joint(None, Some(bar), joint).unwrap()
    });
    for _ in 0..30 {
        world.step().unwrap();
    }
    for j in joints {
        let o = world.output(j).unwrap();
        println!("loop: force {:?} N, moment {:?} N m", o.force, o.moment);
        assert!((o.force.y - G).abs() <= 1e-6 * G, "force {:?}", o.force);
        assert!(
            o.force.x.abs() + o.force.z.abs() <= 1e-6 * G,
            "force {:?}",
            o.force
        );
    }
}
