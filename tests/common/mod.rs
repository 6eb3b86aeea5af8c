//! Shared measurement helpers for the analytic tests (the library's own metrics).
#![allow(unused_imports, reason = "each test file uses a subset of the helpers")]

pub use rapier3d_mpc184::studies::metrics::*;

/// A step of 1/60 s in 4 substeps on `backend`, every output written (the reactions too).
#[allow(dead_code, reason = "only the reaction tests use it")]
pub fn full_outputs(backend: Backend) -> WorldSettings {
    WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        backend,
        outputs: Outputs::Full,
        ..Default::default()
    }
}

/// The path of the example `name` (`examples/NAME.rs`), which `cargo test` builds beside the
/// test binaries (`target/<profile>/examples/`) before it runs any test.
#[allow(dead_code, reason = "only the tests that run examples use it")]
pub fn example(name: &str) -> std::path::PathBuf {
    let exe = std::env::current_exe().expect("the test binary's path");
    let profile = exe
        .parent()
        .and_then(std::path::Path::parent)
        .expect("target/<profile>/deps/<test>");
    profile
        .join("examples")
        .join(format!("{name}{}", std::env::consts::EXE_SUFFIX))
}

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::scenes;

/// The exact angle and rate of a pendulum `I_p theta'' = -m g L sin(theta)` released from rest
/// at `theta0`, at time `t` (RK4 with 20000 steps over `t`: for a period its error,
/// ~(T / 20000)^4, is below 1e-14).
#[allow(dead_code, reason = "only the convergence tests use it")]
pub fn pendulum_rk4(ip: Real, mgl: Real, theta0: Real, t: Real) -> (Real, Real) {
    let n = 20_000;
    let h = t as f64 / n as f64;
    let w2 = mgl as f64 / ip as f64;
    let (mut th, mut om) = (theta0 as f64, 0.0);
    for _ in 0..n {
        (th, om) = rk4_step(|x| -w2 * x.sin(), th, om, h);
    }
    (th as Real, om as Real)
}

/// A01-type revolute pendulum (1 kg bob, 1 m, isotropic inertia 1e-4 kg m^2) released from
/// rest at 90 deg, run over one period `T` at `h = T / n` (one substep, `n` a multiple of 8)
/// with `integrator`: the largest (angle error times L in m, rate error times L in m/s) over
/// the checkpoints `k T / 8` against [`pendulum_rk4`]. `check` sees the world at each
/// checkpoint.
#[allow(dead_code, reason = "only the convergence tests use it")]
pub fn one_period_errors(
    integrator: Integrator,
    n: usize,
    mut check: impl FnMut(&Mpc184World),
) -> (Real, Real) {
    let theta0 = core::f64::consts::FRAC_PI_2 as Real;
    let probe =
        scenes::pendulum(WorldSettings::default(), Axis::Z, 1.0, theta0, 1.0, 1e-4).unwrap();
    let ip = probe.pivot_inertia();
    let mgl = probe.mass * scenes::G * probe.length;
    let period = pendulum_period(ip, probe.mass, scenes::G, probe.length, theta0);
    let settings = WorldSettings {
        dt: period / n as Real,
        substeps: 1,
        integrator,
        ..WorldSettings::default()
    };
    let mut p = scenes::pendulum(settings, Axis::Z, 1.0, theta0, 1.0, 1e-4).unwrap();
    let (mut ep, mut ev): (Real, Real) = (0.0, 0.0);
    for k in 1..=8 {
        for _ in 0..n / 8 {
            p.world.step().unwrap();
        }
        check(&p.world);
        let (th, om) = pendulum_rk4(ip, mgl, theta0, k as Real * period / 8.0);
        let out = p.world.output(p.joint).unwrap();
        ep = ep.max((theta0 + out.dof(Dof::RotZ) - th).abs() * p.length);
        ev = ev.max((out.angular_velocity.z - om).abs() * p.length);
    }
    (ep, ev)
}

/// The stop pendulum: a 1 kg bob (inertia 1e-4 kg m^2) 1 m below a grounded revolute z,
/// started at 2 m/s (rotating with the rod, so the start is consistent) between SECSTOP limits
/// at -20 and +20 deg on ROTZ; gravity 9.81 m/s^2 along -Y.
#[allow(dead_code, reason = "only the stop tests use it")]
pub fn stop_pendulum(settings: WorldSettings) -> (Mpc184World, JointId) {
    let mut world = Mpc184World::new(settings);
    world.physics.gravity = Vector::new(0.0, -9.81, 0.0);
    let bob = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(0.0, -1.0, 0.0))
            .linvel(Vector::new(2.0, 0.0, 0.0))
            .angvel(Vector::new(0.0, 0.0, 2.0))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, Vector::splat(1e-4)))
            .can_sleep(false),
    );
    let lim = 20f64.to_radians() as Real;
    let hinge = Mpc184Joint::revolute(Axis::Z, Vector::ZERO).with_stop(Dof::RotZ, -lim, lim);
    let id = world.insert_joint(None, Some(bob), hinge).unwrap();
    (world, id)
}

/// The stop pendulum (`stop_pendulum`) for 10 s under `control` (RATTLE, 2 substeps to start,
/// `tol` its position tolerance per step), checked as `tests/event_location.rs` states: the
/// first impact located at the stop and its bracket holding the quadrature time `T1` within
/// the trajectory's own error before it (12 steps of at most `tol` at the impact speed), every
/// impact seen in the output one event (at least 20 of them). Returns the control's stats and
/// the impacts seen.
#[allow(dead_code, reason = "only the event location tests use it")]
pub fn stop_pendulum_impacts_located(control: StepControl, tol: Real) -> (StepStats, u64) {
    let (mut world, id) = stop_pendulum(WorldSettings {
        substeps: 2,
        integrator: Integrator::Rattle,
        control,
        ..WorldSettings::default()
    });
    let (g, inertia, w0) = (9.81 as Real, 1.0 + 1e-4, 2.0 as Real);
    let stop = (20.0f64).to_radians() as Real;
    let omega = |th: Real| (w0 * w0 - 2.0 * g * (1.0 - th.cos()) / inertia).sqrt();
    let t1 = stop_pendulum_quarter() as Real;
    let (mut impacts, mut was, mut first) = (0, false, None);
    while world.time() < 10.0 {
        world.step().unwrap();
        let at = world.output(id).unwrap().stops > 0;
        if at && !was {
            impacts += 1;
        }
        if first.is_none() {
            first = world.step_stats().last_event;
        }
        was = at;
    }
    let first: StepEvent = first.expect("the first impact was located");
    let slack = 12.0 * tol / omega(stop);
    let stats = world.step_stats();
    eprintln!(
        "first impact at {t1:.9} s, bracket ({:.9}, {:.9}]; {impacts} impacts, {} events; {stats:?}",
        first.time - first.width,
        first.time,
        stats.events
    );
    assert_eq!((first.joint, first.kind), (id, EventKind::Stop));
    assert!(
        first.time - first.width - slack < t1 && t1 <= first.time + slack,
        "bracket misses the impact time by more than the trajectory's error"
    );
    assert!(impacts >= 20, "{impacts} impacts");
    assert_eq!(stats.events, impacts);
    (stats, impacts)
}

/// The stop pendulum's time (s) from the bottom, where it starts at 2 rad/s, to the stop at
/// 20 deg: `T1 = int_0^20deg dtheta / sqrt(4 - 2 (m g L / I_p) (1 - cos theta))` with `I_p` =
/// 1.0001 kg m^2 and `m g L` = 9.81 J, by Simpson's rule on 4000 intervals (the swing's
/// amplitude, 37 deg, lies beyond the stop, so the integrand stays finite; error below 1e-13 s).
/// The motion between the elastic stops is that swing, reflected with period `4 T1`.
#[allow(dead_code, reason = "only the stop tests use it")]
pub fn stop_pendulum_quarter() -> f64 {
    let (mgl, inertia, rate) = (9.81, 1.0 + 1e-4, 2.0);
    let stop = 20f64.to_radians();
    let speed = |theta: f64| (rate * rate - 2.0 * mgl / inertia * (1.0 - theta.cos())).sqrt();
    simpson(|theta| 1.0 / speed(theta), 0.0, stop, 4000)
}

/// `int_a^b f` by Simpson's rule on `n` (even) intervals.
#[allow(dead_code, reason = "only the tests with a quadrature use it")]
pub fn simpson(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    let h = (b - a) / n as f64;
    let sum: f64 = (0..=n)
        .map(|i| {
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            w * f(a + i as f64 * h)
        })
        .sum();
    sum * h / 3.0
}

/// The SECLOCK wheel (VM179-like): `I_zz` = 0.1 kg m^2, centre on the axis, on a grounded
/// revolute z with `SECLOCK,6,-5 deg,5 deg`, driven from rest by a stepped joint moment
/// `moment` (N m, `FJ,MZ`).
#[allow(dead_code, reason = "only the lock tests use it")]
pub fn lock_wheel(settings: WorldSettings, moment: Real) -> (Mpc184World, JointId) {
    let mut world = Mpc184World::new(settings);
    let wheel = wheel(&mut world);
    let lock = (5.0f64).to_radians() as Real;
    let hinge = Mpc184Joint::revolute(Axis::Z, Vector::ZERO).with_lock(Dof::RotZ, -lock, lock);
    let id = world.insert_joint(None, Some(wheel), hinge).unwrap();
    world
        .set_load(id, Dof::RotZ, DriveProfile::constant(moment))
        .unwrap();
    (world, id)
}

/// A wheel of 2 kg with `I_zz` = 0.1 kg m^2 (0.05 about X and Y), its centre at the origin,
/// at rest and kept awake.
#[allow(dead_code, reason = "only the wheel tests use it")]
pub fn wheel(world: &mut Mpc184World) -> rapier3d_mpc184::math::rapier::dynamics::RigidBodyHandle {
    world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .additional_mass_properties(MassProperties::new(
                Vector::ZERO,
                2.0,
                Vector::new(0.05, 0.05, 0.1),
            ))
            .can_sleep(false),
    )
}

/// The wheel ([`wheel`]) on `joint` to the ground (its node at the wheel's centre), no
/// gravity: the world, the wheel and the joint.
#[allow(dead_code, reason = "only the wheel tests use it")]
pub fn free_wheel(
    settings: WorldSettings,
    joint: Mpc184Joint,
) -> (
    Mpc184World,
    rapier3d_mpc184::math::rapier::dynamics::RigidBodyHandle,
    JointId,
) {
    let mut world = Mpc184World::new(settings);
    world.physics.gravity = Vector::ZERO;
    let wheel = wheel(&mut world);
    let id = world.insert_joint(None, Some(wheel), joint).unwrap();
    (world, wheel, id)
}

/// The friction wheel of `tests/friction_revolute.rs`: 2 kg with isotropic inertia 0.1 kg m^2,
/// its centre on a grounded revolute z with joint friction `law` (`SECJOINT,FRIC` radii:
/// `R_outer` = 0.05 m, `R_inner` = 0.03 m), under `gravity`; no load yet.
#[allow(dead_code, reason = "only the friction tests use it")]
pub fn friction_wheel(
    settings: WorldSettings,
    gravity: Vector,
    law: FrictionLaw,
) -> (Mpc184World, JointId) {
    let mut world = Mpc184World::new(settings);
    world.physics.gravity = gravity;
    let b = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .additional_mass_properties(MassProperties::new(Vector::ZERO, 2.0, Vector::splat(0.1)))
            .can_sleep(false),
    );
    let mut fr = Friction::coulomb(0.2, [Some(0.05), Some(0.03), None]);
    fr.law = law;
    let joint = Mpc184Joint::revolute(Axis::Z, Vector::ZERO).with_friction(fr);
    let id = world.insert_joint(None, Some(b), joint).unwrap();
    (world, id)
}

/// A top in zero gravity: a 1 kg body of principal moments `inertia` (kg m^2, along its own
/// axes) centred at `centre`, on a spherical joint at the origin, spinning at `w0` from the
/// identity orientation, its centre moving at `w0 x centre` so that the pivot stays at rest (a
/// consistent start). Returns the world and the body.
#[allow(dead_code, reason = "only the rigid-body rotation tests use it")]
pub fn spherical_top(
    settings: WorldSettings,
    centre: Vector,
    w0: Vector,
    inertia: Vector,
) -> (
    Mpc184World,
    rapier3d_mpc184::math::rapier::dynamics::RigidBodyHandle,
) {
    let mut world = Mpc184World::new(settings);
    world.physics.gravity = Vector::ZERO;
    let body = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(centre)
            .angvel(w0)
            .linvel(w0.cross(centre))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, inertia))
            .can_sleep(false),
    );
    let joint = Mpc184Joint::new(JointKind::Spherical, Vector::ZERO);
    world.insert_joint(None, Some(body), joint).unwrap();
    (world, body)
}

/// The A02 four-bar's crank tip `(cos theta, sin theta)` at the end of every step of `dt`, by
/// RK4 (1024 substeps per step) on its 1-DOF equation `theta'' = -(6 g / 5) cos theta` from
/// `theta = pi / 2`, `theta' = -1` (crank and rocker `m L^2 / 3` about their pivots, the
/// coupler translating with the crank tip). At 1/30720 s RK4's error is far below 1e-8 m.
#[cfg(feature = "f64")]
#[allow(dead_code, reason = "only the A02 adaptive tests use it")]
pub fn four_bar_tips(dt: Real, steps: usize) -> Vec<Vector> {
    let g = 9.81;
    let f = |th: Real| -(6.0 * g / 5.0) * th.cos();
    let (mut th, mut w): (Real, Real) = (std::f64::consts::FRAC_PI_2, -1.0);
    let sub = 1024;
    let h = dt / sub as Real;
    let mut tips = Vec::with_capacity(steps);
    for _ in 0..steps {
        for _ in 0..sub {
            (th, w) = rk4_step(f, th, w, h);
        }
        tips.push(Vector::new(th.cos(), th.sin(), 0.0));
    }
    tips
}

/// The A02 four-bar at `dt`, one substep to start with, under the adaptive control as the
/// chart study asks a run of `seconds` for `requested` (m): `requested dt / seconds` per step,
/// at most 4096 substeps per step, the velocity difference weighed over `horizon` (s).
#[cfg(feature = "f64")]
#[allow(dead_code, reason = "only the A02 adaptive tests use it")]
pub fn four_bar_adaptive(
    integrator: Integrator,
    dt: Real,
    [requested, seconds, horizon]: [Real; 3],
    extrapolate: bool,
) -> rapier3d_mpc184::studies::benchmarks::Benchmark {
    let settings = WorldSettings {
        dt,
        substeps: 1,
        integrator,
        ..Default::default()
    };
    let mut b = rapier3d_mpc184::studies::benchmarks::four_bar_parallelogram(settings).unwrap();
    b.world
        .set_step_control(StepControl::Adaptive {
            tolerance: requested * dt / seconds,
            energy_tolerance: Real::INFINITY,
            max_substeps: 4096,
            horizon,
            extrapolate,
        })
        .unwrap();
    b
}

/// The 1:1000 bead chain of `tests/lagrange_chain.rs` (100 revolute links of 0.1 m, 0.01 kg
/// beads, a 10 kg end bead, released straight at 20 deg) run for 2 s at `1/rate` s with
/// `substeps` under `integrator`: the end bead every 1/30 s, and the largest energy error per
/// energy scale.
#[cfg(feature = "f64")]
#[allow(dead_code, reason = "only the chain's integrator tests use it")]
pub fn chain_run(integrator: Integrator, rate: Real, substeps: usize) -> (Vec<Vector>, Real) {
    let settings = WorldSettings {
        dt: 1.0 / rate,
        substeps,
        integrator,
        ..Default::default()
    };
    let mut b = rapier3d_mpc184::studies::benchmarks::chain(
        settings,
        100,
        0.1,
        0.01,
        1000.0,
        20f64.to_radians() as Real,
    )
    .unwrap();
    let per = (rate / 30.0).round() as usize;
    let (mut probe, mut worst) = (Vec::new(), 0.0 as Real);
    for _ in 0..60 {
        for _ in 0..per {
            b.world.step().unwrap();
        }
        probe.push(b.probe_position());
        worst = worst.max(b.energy_error().abs());
    }
    (probe, worst)
}

/// The largest distance between two runs' probe points, sample by sample.
#[allow(dead_code, reason = "only the chain's integrator tests use it")]
pub fn largest_apart(a: &[Vector], b: &[Vector]) -> Real {
    a.iter()
        .zip(b)
        .map(|(p, q)| (*p - *q).length())
        .fold(0.0, Real::max)
}

/// The mixed benchmark scene with one arm, released from rest, stepped at 1/60 s x 4 under
/// `integrator` for 60 steps: the chord steps of each step's last projection
/// (`LagrangeDiagnostics::projection_iterations`) per step over steps 4 to 23 (the arm
/// falling), and the largest gap over the run.
#[cfg(feature = "f64")]
#[allow(dead_code, reason = "only the warm start's tests use it")]
pub fn falling_arm_chord_steps(integrator: Integrator) -> (f64, Real) {
    let settings = WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        backend: Backend::Lagrange,
        integrator,
        ..Default::default()
    };
    let mut b = rapier3d_mpc184::studies::benchmarks::mixed(settings, 1).unwrap();
    let (mut sum, mut gap) = (0usize, 0.0 as Real);
    for k in 0..60 {
        b.world.step().unwrap();
        gap = gap.max(b.max_gap().unwrap());
        if (4..24).contains(&k) {
            sum += b.world.lagrange_diagnostics().projection_iterations;
        }
    }
    (sum as f64 / 20.0, gap)
}

/// The world's dynamic bodies, in handle order (the same list for two worlds built alike).
#[allow(
    dead_code,
    reason = "only the tests that compare two worlds body by body use it"
)]
pub fn dynamic_bodies(
    w: &Mpc184World,
) -> Vec<rapier3d_mpc184::math::rapier::dynamics::RigidBodyHandle> {
    let mut v: Vec<_> = w
        .physics
        .bodies
        .iter()
        .filter(|(_, rb)| rb.is_dynamic())
        .map(|(h, _)| h)
        .collect();
    v.sort_by_key(|h| h.into_raw_parts());
    v
}
