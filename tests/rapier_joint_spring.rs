//! `TB,JOIN` springs and dampers on Rapier's own joints (`rapier-impulse`, `rapier-multibody`),
//! beside the Lagrange backend on the same scene: a 2 kg block on a grounded translational joint
//! along e1 with `K11 = 32 N/m` (`omega = 4 rad/s`, period 1.5708 s), pulled 0.1 m from the
//! spring's zero and released, dt 1/60 s x 4 substeps.
//!
//! On the Rapier backends the spring is a force held over each Rapier call, taken at the
//! deflection a lead ahead (`src/backend/rapier/forces.rs`): the step map of a linear spring is
//! then area-preserving and its frequency is off by `(omega dt)^2 / 24` with `dt` the call: the
//! whole step on the impulse backend (`(4/60)^2 / 24 = 1.9e-4`), a substep on the multibody one
//! (1.2e-5). The bound, 1e-3 on the frequency, leaves that margin; and since the map
//! keeps areas, the amplitude does not drift (checked: the last period's maximum is the first's
//! to 1e-3) and the energy only oscillates, by the first-order kick's `omega h / 2` at most
//! (measured 9e-3 of the energy on both Rapier backends, 7e-5 with the Lagrange backend's
//! kick-drift-kick; checked at 2e-2).
//!
//! Damped (`C11 = 0.32 N s/m`, `zeta = 0.02`): successive maxima fall by the logarithmic
//! decrement `2 pi zeta / sqrt(1 - zeta^2)`; the explicit damper held over a call shifts the
//! decay by `zeta omega dt` = 1.3e-3 relative on the impulse backend, and maxima sampled every
//! step are low by up to `(omega dt)^2 / 2` = 2.2e-3 each: the 1e-2 covers both. The
//! energy balance `kinetic + spring + dissipated` (dissipation booked at the call's rates)
//! stays within 1 % of the initial energy.
//!
//! Hardening table (`JNS1`: 32 N/m to 0.05 m, 96 N/m beyond, released at 0.1 m): the period is
//! the quadrature `T = 4 int_0^A dx / sqrt(2 (U(A) - U(x)) / m)` of the table's energy `U`
//! (Simpson on 20000 intervals after the substitution `x = A sin(s)`, which removes the
//! endpoint singularity: 1e-9); the measured period, from up-crossings of zero over ten
//! periods, is checked within 1e-2 (the bound; the lead-ahead spring is second order in
//! the call: (omega dt)^2 ~ 1e-2 at the stiff branch's omega = 6.9 on the impulse backend).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

const M: Real = 2.0;
const K: Real = 32.0;
const X0: Real = 0.1;

const BACKENDS: [Backend; 3] = [
    Backend::Lagrange,
    Backend::RapierImpulse,
    Backend::RapierMultibody,
];

fn block(
    backend: Backend,
    spring: impl FnOnce(Mpc184Joint) -> Mpc184Joint,
) -> (Mpc184World, JointId) {
    let mut world = Mpc184World::new(WorldSettings {
        backend,
        ..Default::default()
    });
    let b = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(X0, 0.0, 0.0))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, M, Vector::splat(0.1)))
            .can_sleep(false),
    );
    // Node I (grounded) at node J, so the measure starts at 0; the spring's zero is X0 behind.
    let joint = spring(
        Mpc184Joint::new(JointKind::Translational, Vector::new(X0, 0.0, 0.0))
            .with_reference(Dof::Ux, -X0),
    );
    let id = world.insert_joint(None, Some(b), joint).unwrap();
    (world, id)
}

fn diagonal_x(v: Real) -> Sym6 {
    let mut d = [0.0; 6];
    d[0] = v;
    Sym6::diagonal(d)
}

/// Deflection from the spring's zero at every step for `secs` (with the energy balance's
/// largest deviation from the start, relative).
fn run(world: &mut Mpc184World, id: JointId, secs: Real) -> (Vec<Real>, Vec<Real>, Real) {
    let total0 = world.energy().total;
    let (mut t, mut x) = (vec![0.0], vec![X0]);
    let mut balance: Real = 0.0;
    for _ in 0..(secs * 60.0).round() as usize {
        world.step().unwrap();
        t.push(world.time());
        x.push(world.output(id).unwrap().measure[0] + X0);
        balance = balance.max((world.energy().total - total0).abs() / total0);
    }
    (t, x, balance)
}

/// Mean period from the up-crossings of zero (linear interpolation between steps).
fn period(t: &[Real], x: &[Real]) -> Real {
    let c: Vec<Real> = (1..x.len())
        .filter(|&i| x[i - 1] < 0.0 && x[i] >= 0.0)
        .map(|i| t[i - 1] + (t[i] - t[i - 1]) * (-x[i - 1]) / (x[i] - x[i - 1]))
        .collect();
    (c[c.len() - 1] - c[0]) / (c.len() - 1) as Real
}

/// The sampled maxima.
fn maxima(x: &[Real]) -> Vec<Real> {
    (1..x.len() - 1)
        .filter(|&i| x[i] > x[i - 1] && x[i] >= x[i + 1])
        .map(|i| x[i])
        .collect()
}

#[test]
fn linear_spring_keeps_its_frequency_on_every_backend() {
    let exact = 2.0 * rapier3d_mpc184::math::PI / (K / M).sqrt();
    for backend in BACKENDS {
        let (mut world, id) = block(backend, |j| j.with_stiffness(diagonal_x(K)));
        let (t, x, balance) = run(&mut world, id, 20.0 * exact);
        let err = (period(&t, &x) - exact).abs() / exact;
        let m = maxima(&x);
        let amp = (m[m.len() - 1] - X0).abs() / X0;
        println!(
            "{}: frequency error {err:.2e}, amplitude change {amp:.2e}, balance {balance:.2e}",
            backend.name()
        );
        assert!(err <= 1e-3, "{}: frequency error {err:.3e}", backend.name());
        assert!(
            amp <= 1e-3,
            "{}: amplitude after 20 periods {amp:.3e}",
            backend.name()
        );
        assert!(
            balance <= 2e-2,
            "{}: energy oscillation {balance:.3e}",
            backend.name()
        );
    }
}

#[test]
fn damper_gives_the_logarithmic_decrement_on_every_backend() {
    let c = 0.32;
    let omega = (K / M).sqrt();
    let zeta = c / (2.0 * M * omega);
    let delta = 2.0 * rapier3d_mpc184::math::PI * zeta / (1.0 - zeta * zeta).sqrt();
    for backend in BACKENDS {
        let (mut world, id) = block(backend, |j| {
            j.with_stiffness(diagonal_x(K)).with_damping(diagonal_x(c))
        });
        let (_, x, balance) = run(
            &mut world,
            id,
            10.0 * 2.0 * rapier3d_mpc184::math::PI / omega,
        );
        let m = maxima(&x);
        let k = m.len() - 1;
        let measured = (m[0] / m[k]).ln() / k as Real;
        let err = (measured - delta).abs() / delta;
        println!(
            "{}: decrement {measured:.5} vs {delta:.5} ({err:.2e}), balance {balance:.2e}",
            backend.name()
        );
        assert!(k >= 8);
        assert!(err <= 1e-2, "{}: decrement error {err:.3e}", backend.name());
        assert!(
            balance <= 1e-2,
            "{}: energy balance {balance:.3e}",
            backend.name()
        );
    }
}

#[test]
fn hardening_table_period_matches_the_quadrature() {
    let table = Table {
        points: vec![
            (-0.15, -11.2),
            (-0.05, -1.6),
            (0.0, 0.0),
            (0.05, 1.6),
            (0.15, 11.2),
        ],
    };
    // Quadrature: T = 4 int_0^A dx / sqrt(2 (U(A) - U(x)) / M), x = A sin s.
    let u = |x: Real| table.integral(x);
    let n = 20000;
    let f = |s: Real| {
        let x = X0 * s.sin();
        let d = 2.0 * (u(X0) - u(x)) / M;
        if d <= 0.0 {
            // s = pi/2: A cos(s) / sqrt(2 (U(A) - U(x)) / M) -> A / sqrt(A f(A) / M).
            return X0 / (X0 * table.eval(X0).0 / M).sqrt();
        }
        X0 * s.cos() / d.sqrt()
    };
    let h = rapier3d_mpc184::math::PI / 2.0 / n as Real;
    let mut sum = f(0.0) + f(rapier3d_mpc184::math::PI / 2.0);
    for i in 1..n {
        sum += f(i as Real * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    let exact = 4.0 * sum * h / 3.0;
    for backend in BACKENDS {
        let (mut world, id) = block(backend, |j| j.with_stiffness_table(Dof::Ux, table.clone()));
        let (t, x, _) = run(&mut world, id, 10.0 * exact);
        let err = (period(&t, &x) - exact).abs() / exact;
        println!(
            "{}: hardening period error {err:.2e} (T = {exact:.5} s)",
            backend.name()
        );
        assert!(err <= 1e-2, "{}: period error {err:.3e}", backend.name());
    }
}

/// A spring too stiff for a force held over a Rapier call (`K dt^2 > m`: here `K = 1e6 N/m`,
/// `m = 2 kg`, `K dt^2 / m = 139` on the impulse backend, 8.7 per multibody substep) becomes a
/// Rapier motor, force-based, with the joint's `K` and `C` in N/m and N s/m: a 2 kg block on a
/// translational joint along X with gravity -9.81 along X settles at `x = -m g / K =
/// -1.962e-5 m` (damping ratio 0.5: settled to 1e-6 of the deflection well within 2 s). Checked
/// within 1 % on both Rapier backends (the motor's implicit spring is exact at rest), and the
/// run stays finite (the explicit force would blow up at this stiffness).
#[test]
fn a_stiff_spring_becomes_a_motor_with_the_right_units() {
    let k = 1e6;
    let c = 2.0 * 0.5 * (k * M).sqrt();
    for backend in [Backend::RapierImpulse, Backend::RapierMultibody] {
        let mut world = Mpc184World::new(WorldSettings {
            backend,
            ..Default::default()
        });
        world.physics.gravity = Vector::new(-9.81, 0.0, 0.0);
        let b = world.physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .additional_mass_properties(MassProperties::new(
                    Vector::ZERO,
                    M,
                    Vector::splat(0.1),
                ))
                .can_sleep(false),
        );
        let joint = Mpc184Joint::new(JointKind::Translational, Vector::ZERO)
            .with_stiffness(diagonal_x(k))
            .with_damping(diagonal_x(c));
        let id = world.insert_joint(None, Some(b), joint).unwrap();
        for _ in 0..120 {
            world.step().unwrap();
        }
        let x = world.output(id).unwrap().displacement.x;
        let exact = -M * 9.81 / k;
        let err = (x - exact).abs() / exact.abs();
        println!(
            "{}: static deflection {x:.6e} m (exact {exact:.6e}, {err:.2e})",
            backend.name()
        );
        assert!(
            err <= 1e-2,
            "{}: deflection off by {err:.3e}",
            backend.name()
        );
    }
}
