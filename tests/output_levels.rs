//! Output levels (`WorldSettings::outputs`): `Outputs::Kinematics` skips the reactions and
//! changes nothing else.
//!
//! - On the mixed scene (10 five-body arms, `studies::benchmarks::mixed`), on the Lagrange and
//!   the `rapier-impulse` backends, 60 steps at each level give the same bodies and the same
//!   relative DOFs, gaps and status to the bit (the reactions feed nothing back into the
//!   motion), and at `Kinematics` no reaction is computed: every joint's force and moment stay
//!   zero, where at `Full` they carry the arms' weight (0.1 kg beads: the top joint holds about
//!   5 m g = 4.9 N, checked above 1 N).
//! - On `rapier-impulse` a joint with friction still gets its reactions at `Kinematics` (its
//!   normal force is the last reaction): the friction wheel's reaction equals the `Full` run's
//!   to the bit, and so does its motion.
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks;

fn run_mixed(backend: Backend, outputs: Outputs) -> (Vec<Vector>, Vec<JointOutput>) {
    let mut b = benchmarks::mixed(
        WorldSettings {
            backend,
            outputs,
            ..WorldSettings::default()
        },
        10,
    )
    .unwrap();
    for _ in 0..60 {
        b.world.step().unwrap();
    }
    let poses = b
        .bodies
        .iter()
        .map(|h| b.world.physics.bodies[*h].translation())
        .collect();
    let outs = b
        .joints
        .iter()
        .map(|j| *b.world.output(*j).unwrap())
        .collect();
    (poses, outs)
}

#[test]
fn kinematics_skips_only_the_reactions() {
    for backend in [Backend::Lagrange, Backend::RapierImpulse] {
        let (p_full, o_full) = run_mixed(backend, Outputs::Full);
        let (p_kin, o_kin) = run_mixed(backend, Outputs::Kinematics);
        assert_eq!(p_full, p_kin, "{backend:?}: the motion changed");
        for (a, b) in o_full.iter().zip(&o_kin) {
            assert_eq!(
                (a.displacement, a.rotation, a.velocity, a.gap, a.stops),
                (b.displacement, b.rotation, b.velocity, b.gap, b.stops),
                "{backend:?}: the kinematic outputs changed"
            );
            assert_eq!((b.force, b.moment), (Vector::ZERO, Vector::ZERO));
        }
        // The top joint of the first arm holds the arm.
        assert!(
            o_full[0].force.length() > 1.0,
            "{backend:?}: {:?}",
            o_full[0]
        );
    }
}

fn friction_wheel(outputs: Outputs) -> (Vector, JointOutput) {
    let mut world = Mpc184World::new(WorldSettings {
        backend: Backend::RapierImpulse,
        outputs,
        ..WorldSettings::default()
    });
    let b = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(0.1, 0.0, 0.0))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, 2.0, Vector::splat(0.1)))
            .can_sleep(false),
    );
    let joint = Mpc184Joint::revolute(Axis::Z, Vector::ZERO)
        .with_friction(Friction::coulomb(0.2, [Some(0.05), Some(0.03), None]));
    let id = world.insert_joint(None, Some(b), joint).unwrap();
    for _ in 0..60 {
        world.step().unwrap();
    }
    (
        world.physics.bodies[b].translation(),
        *world.output(id).unwrap(),
    )
}

#[test]
fn friction_keeps_its_reactions_on_rapier() {
    let (p_full, o_full) = friction_wheel(Outputs::Full);
    let (p_kin, o_kin) = friction_wheel(Outputs::Kinematics);
    assert_eq!(p_full, p_kin);
    assert_eq!((o_full.force, o_full.moment), (o_kin.force, o_kin.moment));
    assert!(o_kin.force.length() > 1.0, "{o_kin:?}");
}
