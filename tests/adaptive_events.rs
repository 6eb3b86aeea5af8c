//! Events under the adaptive step control (`StepControl::Adaptive`): the step that contains a
//! lock engaging or a stop's impact meets the energy targets at fewer substeps than the
//! fixed steps that reach them (the event's time itself: `tests/event_location.rs`).
//!
//! The scene is the SECLOCK wheel of `tests/joint_lock.rs`: `I_zz` = 0.1 kg m^2 on a grounded
//! revolute z, driven from rest by `FJ,MZ = 0.5 N m`, locking at 5 deg. It dissipates exactly
//! `M theta_L` = 0.043633 J. With a fixed step the lock lands at a substep boundary and the
//! dissipated energy is off by O(h): 1.5 % at 1/60 x 4. The adaptive control bisects the lock
//! to the event time tolerance and takes it in a substep of its own.
//!
//! Checked, with the first-order integrator:
//! - asked for 1e-4 of `M theta_L` per step, the dissipated energy is within 1e-4 relative
//!   (the target). Measured 1.8e-5, the lock located in a substep of 4.1e-6 s.
//! - the cost is counted in substeps integrated: every run of every try and of the bisection,
//!   from `StepStats::substeps`. The adaptive run integrated 197 substeps in all (6285 when
//!   the step doubling alone refined the lock's step, cut 9 times). The cheapest fixed step
//!   reaching the target needs 1024 substeps per step, 61 440 in all (x4: 1.5e-2, x64: 1.7e-4,
//!   x256: 1.8e-4, x1024: 8.3e-5; the error depends on where a substep boundary falls; the
//!   adaptive run's 1.8e-5 takes x4096). The adaptive run must integrate fewer substeps in
//!   all than that fixed run.
//! - the event is reported with the wheel's joint, as a lock.
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;

const M: Real = 0.5;

fn lock_angle() -> Real {
    (5.0f64).to_radians() as Real
}

/// Runs the wheel for 1 s (60 steps); returns the relative error of the dissipated energy, the
/// substeps integrated and the world.
fn wheel(substeps: usize, control: StepControl) -> (Real, u64, Mpc184World, JointId) {
    let (mut world, id) = common::lock_wheel(
        WorldSettings {
            substeps,
            control,
            ..WorldSettings::default()
        },
        M,
    );
    for _ in 0..60 {
        world.step().unwrap();
    }
    assert_eq!(world.output(id).unwrap().locks, 1, "locked");
    let expected = M * lock_angle();
    let err = (world.energy().dissipated - expected).abs() / expected;
    let cost = match control {
        StepControl::Fixed => 60 * substeps as u64,
        StepControl::Adaptive { .. } | StepControl::Embedded { .. } => world.step_stats().substeps,
    };
    (err, cost, world, id)
}

#[test]
fn the_lock_step_is_refined_to_the_energy_tolerance() {
    let target = 1e-4;
    let control = StepControl::Adaptive {
        // Loose on positions: the motion before the lock is a constant acceleration, which
        // the position estimate passes at a few substeps.
        tolerance: 1e-3,
        energy_tolerance: target * M * lock_angle(),
        max_substeps: 1 << 14,
        horizon: 0.0,
        extrapolate: false,
    };
    let (err, cost, world, id) = wheel(1, control);
    let stats = world.step_stats();
    eprintln!("adaptive: dissipation error {err:.2e}, {cost} substeps, {stats:?}");
    assert!(err <= target, "dissipation error {err:.3e}");
    let event = stats.last_event.expect("the lock was located");
    assert_eq!((event.joint, event.kind), (id, EventKind::Lock));
    // The cheapest fixed step reaching the target.
    let mut fixed = None;
    for substeps in [4, 16, 64, 256, 1024, 4096] {
        let (e, c, _, _) = wheel(substeps, StepControl::Fixed);
        eprintln!("fixed x{substeps}: dissipation error {e:.2e}, {c} substeps");
        if e <= target {
            fixed = Some(c);
            break;
        }
    }
    let fixed = fixed.expect("a fixed step reaching the target");
    assert!(cost < fixed, "adaptive {cost} substeps, fixed {fixed}");
}

/// The stop pendulum of `tests/rattle_stop.rs` (1 kg bob 1 m below a revolute z, 2 m/s between
/// stops at +-20 deg) under RATTLE with the adaptive control at 1e-6 m per step. Each impact is
/// located and taken in a substep of its own. Checked: as many events as impacts in 10 s (each
/// reported with the hinge), and across every impact step the energy changes by at most 1e-6 m g
/// L (the target; RATTLE's energy-consistent impact). Measured: 27 impacts, 27 events,
/// 1.2e-7 m g L at most across an impact (the fixed step at 1/60 x 4: 3.7e-7), for 8650
/// substeps in 600 steps (the fixed x4: 2400; the adaptive run also holds the trajectory to
/// 1e-6 m per step, which x4 does not).
#[test]
fn stop_impacts_are_located() {
    let (mut world, id) = common::stop_pendulum(WorldSettings {
        substeps: 2,
        integrator: Integrator::Rattle,
        control: StepControl::Adaptive {
            tolerance: 1e-6,
            energy_tolerance: Real::INFINITY,
            max_substeps: 1 << 12,
            horizon: 0.0,
            extrapolate: false,
        },
        ..WorldSettings::default()
    });
    let scale = 9.81;
    let (mut impacts, mut jump, mut was, mut prev) = (0, 0.0 as Real, false, world.energy().total);
    while world.time() < 10.0 {
        world.step().unwrap();
        let at = world.output(id).unwrap().stops > 0;
        let e = world.energy().total;
        if at && !was {
            impacts += 1;
            jump = jump.max((e - prev).abs() / scale);
        }
        if let Some(event) = world.step_stats().last_event {
            assert_eq!((event.joint, event.kind), (id, EventKind::Stop));
        }
        was = at;
        prev = e;
    }
    let s = world.step_stats();
    eprintln!(
        "{impacts} impacts, {} events, largest energy change across an impact step {jump:.2e} m g L; {s:?}",
        s.events
    );
    assert!(impacts >= 20, "{impacts} impacts");
    assert_eq!(s.events, impacts as u64);
    assert!(
        jump <= 1e-6,
        "energy change across an impact {jump:.3e} m g L"
    );
}
