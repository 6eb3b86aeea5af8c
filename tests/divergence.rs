//! Divergence with nothing lost: a step that blows up returns `Error::Diverged` naming the joint
//! and the time, and the world keeps the state it had after the previous successful step.
//!
//! - Unstable spring: a heavy link (100 kg, 10 kg m^2) pinned to the ground at the origin, with
//!   a stop and friction on its hinge, and a light bob (1 kg, 1e-2 kg m^2, 0.5 m further) on a
//!   second hinge carrying a rotational spring of 6.3e4 N m/rad. Springs are explicit
//!   (kick-drift-kick): with the bob's 0.26 kg m^2 about its hinge, `omega = 490 rad/s` and
//!   `omega h = 2.05` at `h = 1/240 s`, past the stability limit 2, so the bob's swing grows
//!   about sixfold per step: the energy guard (the balance may not grow by more than 0.25 of
//!   the energy scale in one step) stops it long before the joint turns by more than half a
//!   turn in one step (the older bound, which caught it before the guard existed): the
//!   spring's joint must be named (joint 1: of the joints on the fastest body, the one whose
//!   sides turn fastest against each other; the fastest body is the link or the bob depending
//!   on how the instability grows, and the hinge is on the link too).
//! - Huge load: the same link and hinge, and beside them a separate pendulum whose hinge
//!   (joint 1) gets a moment of 1e300 N m at t = 0.1 s: its bob turns non-finite within that
//!   step (the solve fails on it), and joint 1 must be named as the one on a non-finite body.
//!
//!   In both, the time given must be that of the last good state, and everything observable
//!   must equal, bit for bit, what it was after the last successful step: time, body poses,
//!   velocities and centres of mass, every joint output (relative motion, reactions, stop, lock
//!   and friction state) and the energy ledger.
//! - Too soft: a 1 kg bob on a 1 m penalty revolute of 20 N/m (absolute) hangs 0.5 m below
//!   its pin at rest, more than the default bound of 0.1 of the model size (1.035 m here: the
//!   pin, the bob and its radius of gyration): the step at which the stretch passes 0.1035 m
//!   fails naming the joint with the bound in the message, the state is kept as well, and with
//!   the bound switched off the same scene runs past that step.
//!
//! No tolerance: the kept state is compared exactly (`Debug` prints every float to the bit).

#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder, RigidBodyHandle};
use rapier3d_mpc184::prelude::*;

fn body(world: &mut Mpc184World, at: Vector, mass: Real, inertia: Real) -> RigidBodyHandle {
    world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(at)
            .additional_mass_properties(MassProperties::new(
                Vector::ZERO,
                mass,
                Vector::splat(inertia),
            ))
            .can_sleep(false),
    )
}

/// Everything observable, printed exactly.
fn state(world: &Mpc184World, bodies: &[RigidBodyHandle], joints: &[JointId]) -> String {
    let mut s = format!("t {:?}\n", world.time());
    for b in bodies {
        let rb = &world.physics.bodies[*b];
        s += &format!(
            "{:?} {:?} {:?} {:?}\n",
            rb.position(),
            rb.linvel(),
            rb.angvel(),
            rb.center_of_mass()
        );
    }
    for j in joints {
        s += &format!("{:?}\n", world.output(*j).unwrap());
    }
    s += &format!("{:?}\n", world.energy());
    s
}

/// Steps until an error (at most `limit` steps); returns it with the state after the last
/// successful step and the number of steps taken.
fn run_to_failure(
    world: &mut Mpc184World,
    bodies: &[RigidBodyHandle],
    joints: &[JointId],
    limit: usize,
) -> (Error, String, usize) {
    let mut last = state(world, bodies, joints);
    for n in 0..limit {
        match world.step() {
            Ok(()) => last = state(world, bodies, joints),
            Err(e) => return (e, last, n),
        }
    }
    panic!("no divergence in {limit} steps");
}

/// The unstable scenes. Spring: a heavy link on a hinge (stop, friction) and a light bob on a
/// second hinge with a rotational spring far too stiff for the step. Load (`load == true`): the
/// same hinge and link, and beside them a separate pendulum whose hinge gets a moment of
/// 1e300 N m at t = 0.1 s.
fn unstable(load: bool) -> (Mpc184World, [RigidBodyHandle; 2], [JointId; 2]) {
    let mut world = Mpc184World::new(WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        backend: Backend::Lagrange,
        ..Default::default()
    });
    let link = body(&mut world, Vector::new(0.5, 0.0, 0.0), 100.0, 10.0);
    let bob = body(&mut world, Vector::new(1.5, 0.0, 0.0), 1.0, 1e-2);
    let hinge = world
        .insert_joint(
            None,
            Some(link),
            Mpc184Joint::revolute(Axis::Z, Vector::ZERO)
                .with_stop(Dof::RotZ, -1.0, 1.0)
                .with_friction(Friction::coulomb(0.1, [Some(0.02), Some(0.01), None])),
        )
        .unwrap();
    let second = if load {
        let j = Mpc184Joint::revolute(Axis::Z, Vector::new(1.0, 0.0, 0.0));
        let j = world.insert_joint(None, Some(bob), j).unwrap();
        let kick = DriveProfile {
            t0: 0.1,
            t1: 0.1,
            from: 0.0,
            to: 1e300,
            stepped: true,
            extend: false,
        };
        world.set_load(j, Dof::RotZ, kick).unwrap();
        j
    } else {
        let j = Mpc184Joint::revolute(Axis::Z, Vector::new(1.0, 0.0, 0.0))
            .with_stiffness(Sym6::diagonal([0.0, 0.0, 0.0, 0.0, 0.0, 6.3e4]));
        world.insert_joint(Some(link), Some(bob), j).unwrap()
    };
    (world, [link, bob], [hinge, second])
}

#[test]
fn unstable_scenes_diverge_naming_their_joint_and_keep_the_last_good_state() {
    // The spring's joint spins past the bound; the load makes its bob non-finite within one
    // step (the joint is then found as the one on a non-finite body).
    for load in [false, true] {
        let (mut world, bodies, joints) = unstable(load);
        let (err, last, steps) = run_to_failure(&mut world, &bodies, &joints, 600);
        println!("load {load}: after {steps} good steps: {err}");
        let Error::Diverged {
            time,
            joint,
            reason,
        } = &err
        else {
            panic!("expected a divergence, got {err}");
        };
        assert!(steps >= 2, "the instability needs a few steps to grow");
        assert_eq!(*joint, Some(joints[1]), "{err}");
        assert_eq!(time.to_bits(), world.time().to_bits());
        assert_eq!(state(&world, &bodies, &joints), last);
        assert!(err.to_string().contains("at joint 1"), "{err}");
        let expected = if load { "non-finite" } else { "energy guard" };
        assert!(reason.contains(expected), "{reason}");
    }
}

#[test]
fn a_constraint_error_past_its_bound_diverges_and_keeps_the_last_good_state() {
    let build = || {
        let mut world = Mpc184World::new(WorldSettings::default());
        let bob = body(&mut world, Vector::new(1.0, 0.0, 0.0), 1.0, 1e-3);
        let pin =
            Mpc184Joint::revolute(Axis::Z, Vector::ZERO).with_method(ConstraintMethod::Penalty {
                disp: -20.0,
                rot: 0.0,
            });
        let id = world.insert_joint(None, Some(bob), pin).unwrap();
        (world, bob, id)
    };
    let (mut world, bob, id) = build();
    // Pin and bob 1 m apart, the bob's radius of gyration 0.0316 m either way: the box is
    // 1.0316 by 0.0632 by 0.0632 m, its diagonal 1.0355 m.
    let size = world.model_size();
    assert!((size - 1.0355).abs() < 1e-4, "model size {size}");
    let (err, last, steps) = run_to_failure(&mut world, &[bob], &[id], 600);
    println!("after {steps} good steps: {err}");
    let Error::Diverged {
        time,
        joint,
        reason,
    } = &err
    else {
        panic!("expected a divergence, got {err}");
    };
    assert_eq!(*joint, Some(id));
    assert_eq!(time.to_bits(), world.time().to_bits());
    assert!(reason.contains("past the divergence bound"), "{reason}");
    assert_eq!(state(&world, &[bob], &[id]), last);
    // The last good state is within the bound, and the bound was what stopped the run.
    let gap = world.output(id).unwrap().gap;
    assert!(gap <= 0.1 * size && gap > 0.05 * size, "gap {gap}");
    let (mut free, _, _) = build();
    free.set_divergence_limits(DivergenceLimits {
        gap_fraction: Real::INFINITY,
        ..Default::default()
    })
    .unwrap();
    for _ in 0..=steps {
        free.step().unwrap();
    }
    assert!(free.output(id).unwrap().gap > 0.1 * size);
}
