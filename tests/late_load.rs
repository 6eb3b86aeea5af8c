//! A joint load set, changed or removed between steps acts from the next step on, on every
//! backend. The per-step passes visit only the joints that have loads, springs, limits, drives
//! or friction (`JointSet::roles`); those lists must be made again when a load changes, which
//! leaves the joint's rows alone. A list kept from before the change would skip the load, or
//! keep a removed one.
//!
//! The scene is a wheel with `I_zz` = 0.1 kg m^2, its centre on a grounded revolute z, no
//! gravity, at rest. Six stretches of 30 steps at dt = 1/60 s (4 substeps each): no load, then
//! `FJ,MZ` of 0.5 N m, then none (`FJDELE`), then -0.25 N m, then none again.
//!
//! Exact: a constant moment about the free axis gives `w = M t / I`, 0.5 * 0.5 / 0.1 = 2.5 rad/s
//! after the first loaded half second, back to 2.5 - 0.25 * 0.5 / 0.1 = 1.25 rad/s after the
//! second. Every backend here integrates a constant moment on a free rotation exactly in the
//! velocity (a kick of `h M / I` per substep), so the tolerance is round-off over 120 steps and
//! Rapier's joint solve, which only acts on the constrained DOFs (1e-9 rad/s). The reference
//! is the rate the output reports, `OMGZ`.
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;

/// The wheel's rate at the end of each stretch on `backend`.
fn rates(backend: Backend) -> Vec<Real> {
    let (mut world, _, id) = common::free_wheel(
        WorldSettings {
            dt: 1.0 / 60.0,
            substeps: 4,
            backend,
            ..WorldSettings::default()
        },
        Mpc184Joint::revolute(Axis::Z, Vector::ZERO),
    );
    let mut out = Vec::new();
    for load in [None, Some(0.5), None, Some(-0.25), None] {
        match load {
            Some(m) => world
                .set_load(id, Dof::RotZ, DriveProfile::constant(m))
                .unwrap(),
            None => world.remove_load(id, Dof::RotZ).unwrap(),
        }
        for _ in 0..30 {
            world.step().unwrap();
        }
        out.push(world.output(id).unwrap().angular_velocity.z);
    }
    out
}

#[test]
fn a_load_set_or_removed_between_steps_acts_from_the_next_step() {
    let exact = [0.0, 2.5, 2.5, 1.25, 1.25];
    for backend in [
        Backend::Lagrange,
        Backend::RapierImpulse,
        Backend::RapierMultibody,
    ] {
        let got = rates(backend);
        println!("{backend:?}: {got:?}");
        for (k, (g, e)) in got.iter().zip(exact).enumerate() {
            assert!(
                (g - e).abs() <= 1e-9,
                "{backend:?}, stretch {k}: {g} rad/s against {e}"
            );
        }
    }
}
