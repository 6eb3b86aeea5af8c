//! Islands do not interact: an arm of the mixed scene (five beads on a revolute z, spherical,
//! cylindrical z, revolute x and translational joint) moves the same to the bit whether it is
//! alone in the world or one of 12 arms, one of which has a stop on its first joint (an island
//! with behaviour, stepped by the general path beside the plain ones). Exact equality is the
//! right tolerance: each island has its own solver state and reads nothing of the others, so any
//! difference is a leak between islands. The arm's joints' outputs (reactions included) are
//! compared the same way. With the `parallel` feature (CI runs it with the f32 set) the plain
//! islands step on rayon's pool and their joints' outputs are written there, so this also
//! checks that the parallel step is the serial one.

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks::{self, MIXED_ARM_BODIES};

fn settings() -> WorldSettings {
    WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        ..Default::default()
    }
}

#[test]
fn an_arm_moves_the_same_alone_and_among_others() {
    let mut alone = benchmarks::mixed(settings(), 1).unwrap();
    let mut many = benchmarks::mixed(settings(), 12).unwrap();
    // Arm 5's first joint gets a stop at +-0.01 rad (reached: the arm swings further).
    let k = 5 * MIXED_ARM_BODIES;
    let [b1, b2] = many.joint_bodies[k];
    let j = many.world.remove_joint(many.joints[k]).unwrap();
    many.joints[k] = many
        .world
        .insert_joint(b1, b2, j.with_stop(Dof::RotZ, -0.01, 0.01))
        .unwrap();
    let mut stop_hit = false;
    for _ in 0..120 {
        alone.world.step().unwrap();
        many.world.step().unwrap();
        let out = many.world.output(many.joints[k]).unwrap();
        stop_hit |= out.stops > 0;
    }
    assert!(stop_hit, "the stop on arm 5 never engaged");
    for (a, b) in alone.bodies.iter().zip(&many.bodies) {
        let (ra, rb) = (
            &alone.world.physics.bodies[*a],
            &many.world.physics.bodies[*b],
        );
        assert_eq!(ra.position(), rb.position());
        assert_eq!(ra.linvel(), rb.linvel());
        assert_eq!(ra.angvel(), rb.angvel());
    }
    // Its joints' outputs too, reactions included: each island writes its own joints' (the
    // serial step as each island ends, the parallel one joint by joint on the pool).
    for (a, b) in alone.joints.iter().zip(&many.joints) {
        let (oa, ob) = (
            alone.world.output(*a).unwrap(),
            many.world.output(*b).unwrap(),
        );
        assert_eq!(oa, ob, "joint {a:?}");
        assert!(oa.force.length() > 0.0, "joint {a:?} carries no reaction");
    }
    // The arm with the stop moved differently (the stop acted).
    let (first, stopped) = (many.bodies[0], many.bodies[k]);
    let dx = many.world.physics.bodies[first].translation().y
        - many.world.physics.bodies[stopped].translation().y;
    assert!(dx.abs() > 1e-6, "the stopped arm moved as the free one");
}
