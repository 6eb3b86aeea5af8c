//! Event location under the adaptive step control (`StepControl::Adaptive`): a stop's impact
//! and a lock engaging are bisected to the event time tolerance and taken in a substep of
//! their own (`StepStats::last_event`).
//!
//! - **Lock** (the SECLOCK wheel of `tests/joint_lock.rs`: `I_zz` = 0.1 kg m^2 on a grounded
//!   revolute z, `FJ,MZ` = 0.5 N m from rest, locking at 5 deg, RATTLE): the angle is
//!   `M t^2 / (2 I)` until the lock, so it engages at `t_L = sqrt(2 I theta_L / M)` =
//!   0.186833 s. RATTLE integrates a constant moment exactly (to round-off), so the located
//!   bracket `(time - width, time]` must hold `t_L` up to round-off (1e-12 s), and its width
//!   must be within the event time tolerance `energy_tolerance / (2 P)` at the lock (`P = M
//!   omega_L` the power of the moment; the position term `tolerance / (2 v)` is looser here).
//!   The dissipated energy is `M theta_L` up to what the moment does over that bracket:
//!   `P * width`.
//! - **Stop** (the stop pendulum of `tests/rattle_stop.rs`: 1 kg bob 1 m below a revolute z,
//!   2 rad/s at the bottom, stops at +-20 deg, RATTLE at 1e-9 m per step): the first impact is
//!   at `T1 = integral_0^20deg dtheta / omega(theta)`, `omega^2 = omega_0^2 - 2 m g L (1 - cos
//!   theta) / I` (`I` = 1 + 1e-4 kg m^2 with the bob's own inertia; Simpson's rule with 2000
//!   intervals, error far below 1e-12 s on this smooth integrand). The bracket must hold `T1`
//!   within the trajectory's own error before it: 12 steps of at most 1e-6 m each (the
//!   tolerance) at the impact speed `omega(20 deg) L`, 7.2e-9 s (measured: 2e-9 s off, the
//!   bracket 8e-11 s wide; at 1e-6 m per step 1.9e-6 s off). Every impact in 10 s is located:
//!   as many events as impacts seen in the output (27).
//! - **Stick to slip** (the friction wheel of `tests/friction_revolute.rs`: 2 kg, `I` = 0.1 kg
//!   m^2, on a grounded revolute z with `mu` = 0.2 and `R_inner` = 0.03 m, gravity across the
//!   axis, first order): a joint moment ramped as `M = k t` (`k` = 0.3 N m/s) breaks it away
//!   when it reaches `mu m g R_i` = 0.11772 N m, at `t_b = mu m g R_i / k` = 0.3924 s; the wheel
//!   sticks exactly before that (an exact velocity-level impulse). The wheel has no speed
//!   before it slips, so the bracket is bounded by the stretch's substep (the doubling chose
//!   1/60/256 s: 6.5e-5 s). The bracket must lie within one width of `t_b`: the first-order
//!   step keeps its velocities at half steps, so where a bisection run's substep is shorter
//!   than the one before it the stick check sees `(h' + h) / 2` of the moment's impulse and
//!   breaks away a little early (measured: the bracket ends 1.7e-5 s, 0.27 widths, before
//!   `t_b`; a fixed step of the same substep breaks away 1.1e-4 s late, at 1/60/4096 s 7e-6 s
//!   late).
#![cfg(feature = "f64")]

mod common;

use rapier3d_mpc184::prelude::*;

#[test]
fn a_lock_is_located_to_its_exact_time() {
    let (moment, inertia, theta) = (0.5, 0.1, (5.0f64).to_radians() as Real);
    let energy_tolerance = 1e-4 * moment * theta;
    let (mut world, id) = common::lock_wheel(
        WorldSettings {
            substeps: 1,
            integrator: Integrator::Rattle,
            control: StepControl::Adaptive {
                tolerance: 1e-3,
                energy_tolerance,
                max_substeps: 1 << 14,
                horizon: 0.0,
                extrapolate: false,
            },
            ..WorldSettings::default()
        },
        moment,
    );
    for _ in 0..30 {
        world.step().unwrap();
    }
    let stats = world.step_stats();
    let event = stats.last_event.expect("the lock was located");
    let t_lock = (2.0 * inertia * theta / moment).sqrt();
    let power = moment * moment / inertia * t_lock;
    let dissipated = world.energy().dissipated;
    eprintln!(
        "lock at {t_lock:.9} s, bracket ({:.9}, {:.9}], width {:.2e} s (bound {:.2e}); \
         dissipated {dissipated:.9} J against {:.9} J; {stats:?}",
        event.time - event.width,
        event.time,
        event.width,
        energy_tolerance / (2.0 * power),
        moment * theta
    );
    assert_eq!((event.joint, event.kind), (id, EventKind::Lock));
    assert_eq!(stats.events, 1);
    assert!(
        event.time - event.width < t_lock + 1e-12 && t_lock <= event.time + 1e-12,
        "bracket misses the lock time"
    );
    assert!(event.width <= energy_tolerance / (2.0 * power));
    assert!((dissipated - moment * theta).abs() <= power * event.width);
}

/// The position tolerance per step (m).
const TOL: Real = 1e-9;

#[test]
fn every_impact_is_located_and_the_first_at_its_time() {
    let control = StepControl::Adaptive {
        tolerance: TOL,
        energy_tolerance: Real::INFINITY,
        max_substeps: 1 << 12,
        horizon: 0.0,
        extrapolate: false,
    };
    common::stop_pendulum_impacts_located(control, TOL);
}

#[test]
fn a_breakaway_is_located_at_the_friction_limit() {
    let (m, g, mu, ri, k) = (
        2.0 as Real,
        9.81 as Real,
        0.2 as Real,
        0.03 as Real,
        0.3 as Real,
    );
    let tolerance = 1e-6;
    let (mut world, id) = common::friction_wheel(
        WorldSettings {
            substeps: 1,
            control: StepControl::Adaptive {
                tolerance,
                energy_tolerance: Real::INFINITY,
                max_substeps: 1 << 12,
                horizon: 0.0,
                extrapolate: false,
            },
            ..WorldSettings::default()
        },
        Vector::new(0.0, -g, 0.0),
        FrictionLaw::Coulomb(mu),
    );
    let ramp = DriveProfile {
        t0: 0.0,
        t1: 1.0,
        from: 0.0,
        to: k,
        stepped: false,
        extend: true,
    };
    world.set_load(id, Dof::RotZ, ramp).unwrap();
    for _ in 0..30 {
        world.step().unwrap();
    }
    let stats = world.step_stats();
    let event = stats.last_event.expect("the breakaway was located");
    let t_b = mu * m * g * ri / k;
    eprintln!(
        "breakaway at {t_b:.9} s, bracket ({:.9}, {:.9}]; {stats:?}",
        event.time - event.width,
        event.time
    );
    assert_eq!((event.joint, event.kind), (id, EventKind::StickSlip));
    assert_eq!(stats.events, 1);
    // Within one event substep of the bracket (see the header).
    assert!(
        event.time - 2.0 * event.width < t_b && t_b <= event.time + event.width,
        "bracket misses the breakaway time by more than its width"
    );
    assert!(
        event.width <= 1.0 / 60.0 / 64.0,
        "width {:.3e} s",
        event.width
    );
    assert!(world.output(id).unwrap().friction.unwrap().slipping);
}
