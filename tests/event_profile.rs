//! The adaptive control ends a segment exactly at a drive's or a load's kink
//! (`EventKind::Profile`: an `FJ` or `DJ` step, a ramp's start or end), as ANSYS starts a load
//! step at its time.
//!
//! The wheel (`I_zz` = 0.1 kg m^2, its centre on a grounded revolute z, no gravity, at 1 rad/s),
//! RATTLE at dt = 1/30 s, one substep per step. RATTLE kicks a load half at a substep's start
//! and half at its end: exact for a load linear in time over the substep, off by `O(h^2)`
//! times the slope jump where a substep straddles a ramp's kink, and by up to `h M / (2 I)`
//! where it straddles a step. Cut at the kinks, the rate is exact to round-off.
//!
//! 1. `FJ,MZ` ramped from 0 at 0.1234 s to 0.5 N m at 0.2345 s, held after. Exact:
//!    `w = w0 + (M / I) (t - t0)^2 / (2 (t1 - t0))` on the ramp, `w0 + (M / I) ((t1 - t0) / 2 +
//!    t - t1)` after. Adaptive: within 1e-12 rad/s of it at every step's end (round-off on rates of
//!    order 1; measured 1.9e-14), both kinks recorded. Fixed, for contrast: off by more than
//!    1e-4 rad/s (measured 5.2e-3).
//! 2. `FJ,MZ` stepped to 0.5 N m at 0.1234 s: `w = w0 + (M / I) (t - t0)`. Adaptive: within 1e-12
//!    (measured 1.2e-14); fixed: off by more than 1e-2 (measured 3.4e-2).
//! 3. `DJ,ROTZ` ramped from 0 at 0.1234 s to 0.5 rad at 0.2345 s: the joint angle on the
//!    profile at every step's end within 1e-10 rad (the projection tolerance; measured
//!    5.6e-17), both kinks recorded.
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::math::rapier::dynamics::RigidBodyHandle;
use rapier3d_mpc184::prelude::*;

const INERTIA: Real = 0.1;
const MOMENT: Real = 0.5;
const T0: Real = 0.1234;
const T1: Real = 0.2345;
/// The wheel's initial rate (rad/s): spinning, so that the rates compared are of order 1
/// from the start.
const W0: Real = 1.0;

/// The wheel on its revolute, RATTLE at 1/30 s x 1, adaptive (1e-6 m per step) or fixed.
fn wheel(adaptive: bool) -> (Mpc184World, RigidBodyHandle, JointId) {
    let control = if adaptive {
        StepControl::Adaptive {
            tolerance: 1e-6,
            energy_tolerance: Real::INFINITY,
            max_substeps: 64,
            horizon: 0.0,
            extrapolate: false,
        }
    } else {
        StepControl::Fixed
    };
    common::free_wheel(
        WorldSettings {
            dt: 1.0 / 30.0,
            substeps: 1,
            integrator: Integrator::Rattle,
            control,
            ..WorldSettings::default()
        },
        Mpc184Joint::revolute(Axis::Z, Vector::ZERO),
    )
}

/// The largest deviation of the wheel's rate from `exact` over 0.5 s, with the last event.
fn run(
    profile: DriveProfile,
    exact: impl Fn(Real) -> Real,
    adaptive: bool,
) -> (Real, StepStats, JointId) {
    let (mut world, wheel, id) = wheel(adaptive);
    world.physics.bodies[wheel].set_angvel(Vector::Z * W0, true);
    world.set_load(id, Dof::RotZ, profile).unwrap();
    let mut worst: Real = 0.0;
    for _ in 0..15 {
        world.step().unwrap();
        let w = world.output(id).unwrap().angular_velocity.z;
        worst = worst.max((w - exact(world.time())).abs());
    }
    (worst, world.step_stats(), id)
}

#[test]
fn a_ramp_kink_is_a_substep_boundary() {
    let ramp = DriveProfile {
        t0: T0,
        t1: T1,
        from: 0.0,
        to: MOMENT,
        stepped: false,
        extend: false,
    };
    let exact = |t: Real| {
        let a = MOMENT / INERTIA;
        W0 + if t <= T0 {
            0.0
        } else if t <= T1 {
            a * (t - T0) * (t - T0) / (2.0 * (T1 - T0))
        } else {
            a * (0.5 * (T1 - T0) + t - T1)
        }
    };
    let (adaptive, stats, id) = run(ramp, exact, true);
    let (fixed, _, _) = run(ramp, exact, false);
    println!("ramp: adaptive {adaptive:.2e} rad/s, fixed {fixed:.2e}; {stats:?}");
    assert!(adaptive <= 1e-12, "adaptive off by {adaptive:e} rad/s");
    assert!(
        fixed > 1e-4,
        "the fixed step straddles the kinks: {fixed:e}"
    );
    assert_eq!(stats.events, 2);
    let last = stats.last_event.expect("the kinks are recorded");
    assert_eq!(
        (last.joint, last.kind, last.time),
        (id, EventKind::Profile, T1)
    );
}

#[test]
fn a_load_step_is_a_substep_boundary() {
    let step = DriveProfile {
        t0: T0,
        t1: T0,
        from: 0.0,
        to: MOMENT,
        stepped: true,
        extend: false,
    };
    let exact = |t: Real| W0 + (MOMENT / INERTIA) * (t - T0).max(0.0);
    let (adaptive, stats, id) = run(step, exact, true);
    let (fixed, _, _) = run(step, exact, false);
    println!("step: adaptive {adaptive:.2e} rad/s, fixed {fixed:.2e}; {stats:?}");
    assert!(adaptive <= 1e-12, "adaptive off by {adaptive:e} rad/s");
    assert!(fixed > 1e-2, "the fixed step straddles the jump: {fixed:e}");
    assert_eq!(stats.events, 1);
    let last = stats.last_event.expect("the step is recorded");
    assert_eq!(
        (last.joint, last.kind, last.time),
        (id, EventKind::Profile, T0)
    );
}

#[test]
fn a_drive_kink_is_a_substep_boundary() {
    // `DJ,ROTZ` ramped from 0 at T0 to 0.5 rad at T1: the rows land on the profile at every
    // substep's end (1e-10 rad, the projection tolerance); the kinks are recorded as the
    // loads' are.
    let ramp = DriveProfile {
        t0: T0,
        t1: T1,
        from: 0.0,
        to: 0.5,
        stepped: false,
        extend: false,
    };
    let (mut world, _, id) = wheel(true);
    world.set_drive(id, Dof::RotZ, ramp).unwrap();
    let mut worst: Real = 0.0;
    for _ in 0..15 {
        world.step().unwrap();
        let angle = world.output(id).unwrap().rotation.z;
        worst = worst.max((angle - ramp.value(world.time())).abs());
    }
    let stats = world.step_stats();
    println!("drive: worst {worst:.2e} rad; {stats:?}");
    assert!(worst <= 1e-10, "off the profile by {worst:e} rad");
    assert_eq!(stats.events, 2);
    let last = stats.last_event.expect("the kinks are recorded");
    assert_eq!(
        (last.joint, last.kind, last.time),
        (id, EventKind::Profile, T1)
    );
}
