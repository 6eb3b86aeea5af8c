//! Islands factored four at a time in SIMD lanes step exactly as they step alone. 17 arms of
//! the mixed scene (five beads on a revolute z, spherical, cylindrical z, revolute x and
//! translational joint), each with its own bead mass (so that the four lanes of a group carry
//! different values) and a different first impulse: arms 0-15 form four lane groups (one after
//! another in the world, one structure; the `parallel` build takes groups from four on), arm
//! 16 a unit of its own. Each arm is
//! stepped a second time alone in its own world (one island: the scalar path). Exact equality
//! is the tolerance: every lane runs the scalar factorisation's operations in the same order,
//! so any difference, in a body's pose or velocity or in a joint's output, is a lane leaking
//! into another or an operation out of order. The backend's counts show that the lanes ran:
//! sixteen islands' factorisations, four substeps per step, and their solves.

use rapier3d_mpc184::math::rapier::dynamics::RigidBodyHandle;
use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

const KINDS: [JointKind; 5] = [
    JointKind::Revolute { axis: Axis::Z },
    JointKind::Spherical,
    JointKind::Cylindrical { axis: Axis::Z },
    JointKind::Revolute { axis: Axis::X },
    JointKind::Translational,
];

fn world() -> Mpc184World {
    let mut world = Mpc184World::new(WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        ..Default::default()
    });
    world.physics.gravity = Vector::new(0.0, -9.81, 0.0);
    world
}

/// Arm `k` at `x = 0.5 k`: its beads and joints.
fn arm(world: &mut Mpc184World, k: usize) -> (Vec<RigidBodyHandle>, Vec<JointId>) {
    let x = k as Real * 0.5;
    let mass = 0.1 * (1.0 + 0.1 * k as Real);
    let (mut beads, mut joints) = (Vec::new(), Vec::new());
    let mut prev = None;
    for (j, kind) in KINDS.iter().enumerate() {
        let pivot = Vector::new(x, -0.2 * j as Real, 0.0);
        let at = pivot + Vector::new(0.02, -0.2, 0.01);
        let bead = world.physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .translation(at)
                .linvel(Vector::new(0.0, 0.0, 0.1 * k as Real))
                .additional_mass_properties(MassProperties::new(
                    Vector::ZERO,
                    mass,
                    Vector::splat(1e-3),
                ))
                .can_sleep(false),
        );
        joints.push(
            world
                .insert_joint(prev, Some(bead), Mpc184Joint::new(*kind, pivot))
                .unwrap(),
        );
        beads.push(bead);
        prev = Some(bead);
    }
    (beads, joints)
}

#[test]
fn islands_in_lanes_step_as_they_step_alone() {
    const ARMS: usize = 17;
    const STEPS: usize = 60;
    let mut many = world();
    let arms: Vec<_> = (0..ARMS).map(|k| arm(&mut many, k)).collect();
    let mut alone: Vec<(Mpc184World, Vec<RigidBodyHandle>, Vec<JointId>)> = (0..ARMS)
        .map(|k| {
            let mut w = world();
            let (b, j) = arm(&mut w, k);
            (w, b, j)
        })
        .collect();
    let (mut in_lanes, mut solves) = (0, 0);
    for _ in 0..STEPS {
        many.step().unwrap();
        in_lanes += many.lagrange_diagnostics().lane_factorisations;
        solves += many.lagrange_diagnostics().lane_solves;
        for (w, ..) in &mut alone {
            w.step().unwrap();
            assert_eq!(w.lagrange_diagnostics().lane_factorisations, 0);
        }
    }
    assert_eq!(in_lanes, 16 * 4 * STEPS);
    // Each substep's position projection takes a chord step at least, and the step's last two
    // substeps project the velocities: at least six solves per island and step.
    assert!(solves >= 16 * 6 * STEPS, "{solves} solves in lanes");
    for ((beads, joints), (w, beads1, joints1)) in arms.iter().zip(&alone) {
        for (a, b) in beads.iter().zip(beads1) {
            let (ra, rb) = (&many.physics.bodies[*a], &w.physics.bodies[*b]);
            assert_eq!(ra.position(), rb.position());
            assert_eq!(ra.linvel(), rb.linvel());
            assert_eq!(ra.angvel(), rb.angvel());
        }
        for (a, b) in joints.iter().zip(joints1) {
            let (oa, ob) = (many.output(*a).unwrap(), w.output(*b).unwrap());
            assert_eq!(oa, ob, "joint {a:?}");
        }
    }
}
