//! A world under `StepControl::Embedded` snapshotted mid-run and restored continues bit for bit
//! as the original does: the velocity samples the estimate differences are part of the
//! world's state (`Mpc184World::snapshot`). Without them the restored world would take its
//! next three steps by step doubling (other substeps, other states), so every step's bob pose
//! and velocity and the control's stats after the snapshot must be equal to the bit.
//!
//! Scene: the A01 pendulum (1 kg bob on a 1 m hinge about Z, rotary inertia 1e-4 kg m^2,
//! released horizontally), RATTLE, dt 1/60 s, 1e-7 m per step; snapshot after 30 steps, 60
//! steps compared. No tolerance: exact comparison.
#![cfg(all(feature = "serde-snapshot", feature = "f64"))]

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::scenes;

/// The bob's pose and velocities and the control's stats, printed to the bit.
fn state(
    world: &Mpc184World,
    bob: rapier3d_mpc184::math::rapier::prelude::RigidBodyHandle,
) -> String {
    let rb = &world.physics.bodies[bob];
    format!(
        "{:?} {:?} {:?} {:?} {:?}",
        rb.position(),
        rb.linvel(),
        rb.angvel(),
        world.time(),
        world.step_stats()
    )
}

#[test]
fn a_restored_world_takes_the_same_embedded_steps() {
    let settings = WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        integrator: Integrator::Rattle,
        control: StepControl::Embedded {
            tolerance: 1e-7,
            max_substeps: 4096,
            horizon: 0.0,
        },
        ..Default::default()
    };
    let half = rapier3d_mpc184::math::PI / 2.0;
    let mut p = scenes::pendulum(settings, Axis::Z, 1.0, half, 1.0, 1e-4).unwrap();
    for _ in 0..30 {
        p.world.step().unwrap();
    }
    let embedded_before = p.world.step_stats().embedded;
    let bytes = p.world.snapshot().unwrap().into_bytes();
    let mut reference = Vec::new();
    for _ in 0..60 {
        p.world.step().unwrap();
        reference.push(state(&p.world, p.bob));
    }
    // The window ran on the estimate, not on step doubling (else it would test nothing).
    assert_eq!(p.world.step_stats().embedded, embedded_before + 60);
    let mut restored = Mpc184World::from_snapshot(&Snapshot::from_bytes(bytes)).unwrap();
    for (k, want) in reference.iter().enumerate() {
        restored.step().unwrap();
        let got = state(&restored, p.bob);
        assert!(
            got == *want,
            "step {k} after the snapshot:\n{got}\n!=\n{want}"
        );
    }
}
