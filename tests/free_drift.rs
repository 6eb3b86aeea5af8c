//! The free drift (the Lagrange backend's module docs, `Island::free_drift`): a tree island that
//! only joints act on skips the velocity solve, drifts at its kicked velocities plus the
//! constraint impulse extrapolated from the last substeps, and lets the position projection
//! take what the extrapolation missed. On the translations that is the same equation as the
//! velocity solve's form (`q_(n+1) = q_n + h v* + M~^-1 J_n^T mu`, `C(q_(n+1)) = 0`), so the two
//! forms reach the same motion up to the projection's tolerance and the rotations' composition;
//! with RATTLE the free drift also leaves the velocity projection of a step's first substeps to
//! the next substep, whose second half kick must still act.
//!
//! The two forms side by side: the same scene with and without a sensor collider of zero
//! density on every body (it adds no mass and touches nothing, but a body with a collider can
//! meet a contact, so its island keeps the velocity solve). Scenes: the pendulum (one 1 m
//! revolute link, 1 kg bob, released horizontal) and the 1:1 chain of 10 links of 0.1 m and
//! 0.01 kg (released at 20 deg); dt 1/60 s x 4, 10 s, first order and RATTLE. Compared: every
//! body's position at the end.
//!
//! Measured: the two forms 4.8e-11 and 7.3e-11 m apart on the pendulum (first order, RATTLE;
//! 2.1e-11 and 7.5e-11 m before a plain island's constraint terms were taken once per step),
//! 1.0e-9 and 5.3e-10 m on the chain, where each form's own error against the same run at 64
//! substeps is 9.3e-3, 1.0e-3, 2.6e-3 and 4.7e-4 m. Asserted: within 1e-8 m, ten times the
//! largest measured and 5e4 times below the smallest of the integrators' own errors. With the
//! merged projection's second half kick left out, the RATTLE runs ended 0.57 and 0.11 m apart.
//! The two runs must differ at all (the collider's run took the other form): measured above
//! 1e-12 m in every case.
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::ColliderBuilder;
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks;

mod common;
use common::dynamic_bodies;

/// The dynamic bodies' positions after 10 s, with sensor colliders on them or without.
fn run(links: usize, integrator: Integrator, collider: bool) -> Vec<Vector> {
    let settings = WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        integrator,
        ..Default::default()
    };
    let mut b = if links == 1 {
        benchmarks::chain(settings, 1, 1.0, 1.0, 1.0, 90f64.to_radians() as Real)
    } else {
        benchmarks::chain(settings, links, 0.1, 0.01, 1.0, 20f64.to_radians() as Real)
    }
    .unwrap();
    let dynamic = dynamic_bodies(&b.world);
    if collider {
        let w = &mut b.world.physics;
        for &h in &dynamic {
            let c = ColliderBuilder::ball(1e-3)
                .density(0.0)
                .sensor(true)
                .build();
            w.colliders.insert_with_parent(c, h, &mut w.bodies);
        }
    }
    for _ in 0..600 {
        b.world.step().unwrap();
    }
    dynamic
        .iter()
        .map(|&h| b.world.physics.bodies[h].translation())
        .collect()
}

#[test]
fn the_free_drift_moves_the_bodies_as_the_velocity_solve_does() {
    for links in [1, 10] {
        for integrator in [Integrator::SymplecticEuler, Integrator::Rattle] {
            let free = run(links, integrator, false);
            let solved = run(links, integrator, true);
            let apart = free
                .iter()
                .zip(&solved)
                .map(|(a, b)| (*a - *b).length())
                .fold(0.0 as Real, Real::max);
            println!("{links} links, {integrator:?}: the two forms {apart:.2e} m apart");
            assert!(apart <= 1e-8, "{links} links, {integrator:?}: {apart:e} m");
            assert!(apart > 1e-12, "{links} links, {integrator:?}: the same run");
        }
    }
}
