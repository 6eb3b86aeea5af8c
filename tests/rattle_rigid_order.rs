//! RATTLE and its fourth-order composition keep their order on jointed rigid bodies with
//! unequal principal moments that tumble in 3D (`Island::drift`: such a body drifts as a free
//! rotor, its angular momentum kept, by the splitting of Dullweber, Leimkuhler and McLachlan;
//! the projection's warm start moves along the factorisation's mass).
//!
//! Before, both schemes were first order there: the drift held `w` and the kicks took the
//! gyroscopic term at the unconstrained velocities, and the warm start of the position
//! projection moved the bodies along their inertia after the drift instead of the
//! factorisation's, each an `O(h^2)` velocity error per substep. Planar motions and bodies
//! with equal moments (A01, A02, the conical pendulum) never showed it.
//!
//! Self-convergence, since neither motion has a closed form: with the error of `n` substeps
//! per step `C / n^p`, the deviations from a run at `N` substeps satisfy
//! `d(n) / d(2 n) = (n^-p - N^-p) / ((2n)^-p - N^-p)`, 4.0 for `p = 2` and 2.0 for `p = 1`
//! at `N >> n`, and 5.0 (`p = 2`) or 17 (`p = 4`) for `n = N / 4`.
//!
//! 1. A heavy top without gravity: a 1 kg body with principal moments 0.1, 0.2, 0.35 kg m^2
//!    on a spherical joint 0.5 m from its centre, tumbling at (0, 1, 1) rad/s (a consistent
//!    start), 2 s at dt 1/30: RATTLE at x8, x16, x32 against x512. Measured 7.1e-6, 1.8e-6,
//!    4.4e-7 m, ratios 4.00, 4.01 (before: 5.1e-4, 2.5e-4, 1.2e-4 m, ratios 2.04, 2.07); a
//!    ratio above 3.5 is second order (first order cannot exceed 2.1 here).
//! 2. The IFToMM A04 Bricard mechanism, 2 s at dt 1/30: the composition at x64 and x128
//!    against x256. Measured 1.2e-10 and 5.5e-11 m (before 1.9e-5 and 6.4e-6 m: shrinking
//!    threefold, first order); at most 1e-8 m, and no larger at x128.
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks;

const DT: Real = 1.0 / 30.0;

fn settings(substeps: usize, integrator: Integrator) -> WorldSettings {
    WorldSettings {
        dt: DT,
        substeps,
        integrator,
        ..Default::default()
    }
}

/// A body point of the tumbling heavy top after every step of 2 s, at `n` substeps.
fn heavy_top(n: usize) -> Vec<Vector> {
    let (mut world, body) = common::spherical_top(
        settings(n, Integrator::Rattle),
        Vector::new(0.5, 0.0, 0.0),
        Vector::new(0.0, 1.0, 1.0),
        Vector::new(0.1, 0.2, 0.35),
    );
    (0..60)
        .map(|_| {
            world.step().unwrap();
            *world.physics.bodies[body].position() * Vector::new(0.3, 0.2, 0.1)
        })
        .collect()
}

/// The probe (P3) of the Bricard mechanism after every step of 2 s, at `n` substeps.
fn bricard(n: usize, integrator: Integrator) -> Vec<Vector> {
    let mut b = benchmarks::bricard(settings(n, integrator)).unwrap();
    (0..60)
        .map(|_| {
            b.world.step().unwrap();
            b.probe_position()
        })
        .collect()
}

fn deviation(a: &[Vector], b: &[Vector]) -> Real {
    a.iter()
        .zip(b)
        .map(|(p, q)| (*p - *q).length())
        .fold(0.0, Real::max)
}

#[test]
fn rattle_is_second_order_on_a_tumbling_heavy_top() {
    let fine = heavy_top(512);
    let d: Vec<Real> = [8, 16, 32]
        .iter()
        .map(|&n| deviation(&heavy_top(n), &fine))
        .collect();
    println!("heavy top, RATTLE x8, x16, x32 against x512: {d:?}");
    for pair in d.windows(2) {
        let ratio = pair[0] / pair[1];
        assert!(ratio > 3.5, "ratio {ratio:.2}: {d:?}");
    }
}

#[test]
fn the_composition_converges_on_the_bricard_mechanism() {
    let fine = bricard(256, Integrator::Composition4);
    let d64 = deviation(&bricard(64, Integrator::Composition4), &fine);
    let d128 = deviation(&bricard(128, Integrator::Composition4), &fine);
    println!("Bricard, order 4, x64 and x128 against x256: {d64:.3e} {d128:.3e} m");
    assert!(d64 <= 1e-8, "{d64:.3e} m");
    assert!(d128 <= d64, "{d128:.3e} > {d64:.3e}");
}
