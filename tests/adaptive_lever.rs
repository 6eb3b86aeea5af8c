//! The adaptive control weighs a body's rotation by the body's own reach, not by the model's
//! size (`StepControl::Adaptive`, `src/world/adaptive.rs`, `levers`).
//!
//! A rotation error `da` of a body moves its own points (its joints' nodes, its colliders) by
//! at most `r da`, with `r` their farthest distance from its centre of mass; where it moves
//! another body, that body's own difference counts. So the substeps a swinging pendulum needs
//! cannot depend on how far away another, unrelated part of the model lies.
//!
//! Scene: IFToMM A01 (1 kg bob, rotary inertia 1e-4 kg m^2, on a 1 m hinge about Z, released
//! horizontally), RATTLE, dt 1/60 s, 1 s, asked 1e-7 m per step over the step alone; then the
//! same with a second pendulum hanging at rest 100 m away (its own island: it stays in its
//! equilibrium, and both runs of each doubling agree on it to round-off), which makes the model
//! about 100 m across. Expected: the same kept substeps and the same bob trajectory, to the bit
//! (the swinging island's steps do not read the resting one). With the model size as every
//! body's lever (before 2026-11-27) the far pendulum multiplied the bob's rotation terms by 100
//! and the run took 12 956 substeps instead of 3 749: this test fails then.
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::scenes;

fn run(far_pendulum: bool) -> (u64, Vec<Vector>, Real) {
    let settings = WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 1,
        integrator: Integrator::Rattle,
        control: StepControl::Adaptive {
            tolerance: 1e-7,
            energy_tolerance: Real::INFINITY,
            max_substeps: 4096,
            horizon: 0.0,
            extrapolate: false,
        },
        ..Default::default()
    };
    let half = rapier3d_mpc184::math::PI / 2.0;
    let mut p = scenes::pendulum(settings, Axis::Z, 1.0, half, 1.0, 1e-4).unwrap();
    if far_pendulum {
        let pivot = Vector::new(100.0, 0.0, 0.0);
        let bob = p.world.physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .translation(pivot - Vector::Y)
                .additional_mass_properties(MassProperties::new(
                    Vector::ZERO,
                    1.0,
                    Vector::splat(1e-4),
                ))
                .can_sleep(false),
        );
        p.world
            .insert_joint(None, Some(bob), Mpc184Joint::revolute(Axis::Z, pivot))
            .unwrap();
    }
    let size = p.world.model_size();
    let mut path = Vec::new();
    for _ in 0..60 {
        p.world.step().unwrap();
        path.push(p.world.physics.bodies[p.bob].translation());
    }
    let stats = p.world.step_stats();
    assert_eq!(stats.unmet, 0, "{stats:?}");
    (stats.substeps, path, size)
}

#[test]
fn a_far_resting_body_does_not_change_the_steps() {
    let (alone, path_alone, size_alone) = run(false);
    let (with_far, path_far, size_far) = run(true);
    println!(
        "substeps: {alone} alone (model {size_alone:.2} m), {with_far} with the far pendulum \
         (model {size_far:.1} m)"
    );
    // The far pendulum makes the model about 100 times larger: the comparison means something.
    assert!(size_far > 50.0 * size_alone, "{size_alone} {size_far}");
    assert_eq!(alone, with_far);
    assert_eq!(path_alone, path_far);
}
