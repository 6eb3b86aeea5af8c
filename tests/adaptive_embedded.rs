//! `StepControl::Embedded` (one RATTLE run per step, its error estimated from the velocities at
//! the ends of the last steps, `src/world/adaptive/embedded.rs`).
//!
//! 1. **A01 pendulum** (1 kg bob on a 1 m hinge about Z, rotary inertia 1e-4 kg m^2, released
//!    horizontally, dt 1/60 s, 1e-7 m per step, the setting `tests/adaptive_step.rs` gives step
//!    doubling): every step within the tolerance (`unmet = 0`), the period over 10 s within
//!    1e-5 of the elliptic-integral period (the deck target), and the bob within
//!    `0.5 * 600 * 1e-7` = 3e-5 m of a fourth-order run at 1/60/64 s (its error is below 1e-10
//!    m): the estimate overestimates RATTLE's error on this motion, so the achieved error over
//!    the summed per-step tolerance must stay below one half. Also fewer substeps than step
//!    doubling asked the same (its kept run alone has as many as this control's whole run
//!    would at the same substep; its coarse run adds half). Measured: 18 028 substeps with 22
//!    retries, 1.6e-5 m off and the period 5.9e-7 off; step doubling 32 266 substeps with 90
//!    retries, 7.9e-6 m off.
//! 2. **Stop pendulum** (`tests/event_location.rs`: 2 rad/s at the bottom, stops at +-20 deg,
//!    1e-9 m per step): the first impact is located as under step doubling, the bracket holding
//!    the quadrature time `T1` within the trajectory's own error before it (12 steps of at most
//!    the tolerance each, at the impact speed), and every impact of the 10 s is an event. An
//!    impact clears the samples; the run must take the embedded estimate again after it (more
//!    steps accepted than located events times the three steps of doubling that refill them).
//!    Measured: 27 impacts, 543 segments of 600 steps on the estimate, 147 612 substeps in
//!    all, where step doubling takes 270 140 (`tests/event_location.rs`'s run).
//! 3. **Not RATTLE**: the first-order integrator has no such estimate; the step stops with
//!    `Error::Unsupported` and the world is not moved.
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::metrics::{pendulum_period, upward_crossings};
use rapier3d_mpc184::studies::scenes;

fn settings(control: StepControl, integrator: Integrator, substeps: usize) -> WorldSettings {
    WorldSettings {
        dt: 1.0 / 60.0,
        substeps,
        integrator,
        control,
        ..Default::default()
    }
}

/// The A01 pendulum (see the header), released horizontally.
fn a01(settings: WorldSettings) -> scenes::Pendulum {
    let half = rapier3d_mpc184::math::PI / 2.0;
    scenes::pendulum(settings, Axis::Z, 1.0, half, 1.0, 1e-4).unwrap()
}

/// The bob's positions after each of `steps` steps, and the control's stats.
fn pendulum_run(settings: WorldSettings, steps: usize) -> (Vec<Vector>, Vec<Real>, StepStats) {
    let mut p = a01(settings);
    let (mut x, mut t) = (Vec::new(), Vec::new());
    for _ in 0..steps {
        p.world.step().unwrap();
        x.push(p.world.physics.bodies[p.bob].translation());
        t.push(p.world.time());
    }
    (x, t, p.world.step_stats())
}

#[test]
fn the_pendulum_holds_its_tolerance_with_one_run_per_step() {
    const TOL: Real = 1e-7;
    const STEPS: usize = 600;
    let embedded = StepControl::Embedded {
        tolerance: TOL,
        max_substeps: 4096,
        horizon: 0.0,
    };
    let (x, t, s) = pendulum_run(settings(embedded, Integrator::Rattle, 4), STEPS);
    let half = rapier3d_mpc184::math::PI / 2.0;
    let p = a01(settings(StepControl::Fixed, Integrator::Rattle, 1));
    let exact = pendulum_period(p.pivot_inertia(), p.mass, scenes::G, p.length, half);
    let c = upward_crossings(&t, &x.iter().map(|v| v.x).collect::<Vec<_>>());
    let measured = (c[c.len() - 1] - c[0]) / (c.len() - 1) as Real;
    let period_error = (measured - exact).abs() / exact;
    let (reference, _, _) = pendulum_run(
        settings(StepControl::Fixed, Integrator::Composition4, 64),
        STEPS,
    );
    let achieved = common::largest_apart(&x, &reference);
    let doubling = StepControl::Adaptive {
        tolerance: TOL,
        energy_tolerance: Real::INFINITY,
        max_substeps: 4096,
        horizon: 0.0,
        extrapolate: false,
    };
    let (y, _, d) = pendulum_run(settings(doubling, Integrator::Rattle, 4), STEPS);
    let achieved_doubling = common::largest_apart(&y, &reference);
    println!(
        "embedded: {} substeps, {} retries, 1/{:.0} to 1/{:.0} s, period error {period_error:.2e}, \
         {achieved:.2e} m off; doubling: {} substeps, {} retries, {achieved_doubling:.2e} m off",
        s.substeps,
        s.rejected,
        1.0 / s.largest_substep,
        1.0 / s.smallest_substep,
        d.substeps,
        d.rejected
    );
    assert_eq!(s.accepted, STEPS as u64);
    // The first three steps take step doubling (no samples yet), every other one run.
    assert_eq!(s.embedded, STEPS as u64 - 3);
    assert_eq!(s.unmet, 0);
    assert!(period_error <= 1e-5, "period error {period_error:.3e}");
    assert!(
        achieved <= 0.5 * STEPS as Real * TOL,
        "{achieved:.3e} m off the reference"
    );
    assert!(
        s.substeps < d.substeps,
        "{} substeps against step doubling's {}",
        s.substeps,
        d.substeps
    );
}

/// The position tolerance per step of the stop pendulum (m).
const STOP_TOL: Real = 1e-9;

#[test]
fn impacts_are_located_and_the_estimate_resumes_after_them() {
    let control = StepControl::Embedded {
        tolerance: STOP_TOL,
        max_substeps: 1 << 12,
        horizon: 0.0,
    };
    let (stats, _) = common::stop_pendulum_impacts_located(control, STOP_TOL);
    assert_eq!(stats.unmet, 0);
    // After each impact three segments take step doubling to refill the samples (and the
    // stretch before a bracket is a segment of its own); the rest run once.
    assert!(
        stats.embedded >= stats.accepted - 4 * stats.events - 3,
        "{} of {} steps on the embedded estimate",
        stats.embedded,
        stats.accepted
    );
}

#[test]
fn the_first_order_step_has_no_embedded_estimate() {
    let control = StepControl::Embedded {
        tolerance: 1e-6,
        max_substeps: 64,
        horizon: 0.0,
    };
    let mut p = a01(settings(control, Integrator::SymplecticEuler, 4));
    let before = p.world.physics.bodies[p.bob].translation();
    let err = p.world.step().unwrap_err();
    assert!(
        matches!(err, Error::Unsupported { ref what, .. } if what.contains("Embedded")),
        "{err}"
    );
    assert_eq!(p.world.time(), 0.0);
    assert_eq!(p.world.physics.bodies[p.bob].translation(), before);
}
