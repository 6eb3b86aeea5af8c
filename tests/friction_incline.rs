//! Coulomb friction on a translational joint (`TB,JOIN,,,,MUS1`), the normal force taken from
//! the joint's own reactions: a 2 kg block on a grounded translational joint whose e1 points
//! down an incline of angle alpha (node at the block's centre, so the reaction is the pure
//! normal force `m g cos(alpha)` and no moment).
//!
//! - `tan(alpha) < mu`: it sticks: the friction force `m g sin(alpha)` is below `mu m g
//!   cos(alpha)`; the stick is an exact velocity-level impulse each substep, so the creep over
//!   10 s is round-off: checked <= 1e-9 m; the friction force equals `m g sin(alpha)` and
//!   the normal force `m g cos(alpha)` to 1e-6 relative (the solver's regularisation is 1e-8).
//! - `tan(alpha) > mu`: it slides with `a = g (sin(alpha) - mu cos(alpha))`: a constant force,
//!   integrated exactly in velocity by the symplectic step, so the velocity after 2 s is
//!   checked to 1e-4 relative (the bound; measured 1e-8). The dissipated energy is
//!   `mu m g cos(alpha) s` over the travel s, checked to 1e-6 (friction work is booked as the
//!   impulse times the travel it acted over); the balance `kinetic + potential + dissipated`
//!   closes within `h / t` of the potential drop: what remains is the first-order step's own
//!   energy error under a constant force, `m a h v / 2` per substep (2e-3 here; measured 1e-3).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

const M: Real = 2.0;
const G: Real = 9.81;

fn incline(alpha: Real, mu: Real) -> (Mpc184World, JointId) {
    incline_on(Backend::Lagrange, alpha, mu)
}

fn incline_on(backend: Backend, alpha: Real, mu: Real) -> (Mpc184World, JointId) {
    let mut world = Mpc184World::new(WorldSettings {
        backend,
        ..WorldSettings::default()
    });
    let block = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .additional_mass_properties(MassProperties::new(Vector::ZERO, M, Vector::splat(0.1)))
            .can_sleep(false),
    );
    let axes = Rotation::from_rotation_z(-alpha);
    let joint = Mpc184Joint::new(JointKind::Translational, Vector::ZERO)
        .with_axes(axes)
        .with_friction(Friction::coulomb(mu, [None, None, None]));
    let id = world.insert_joint(None, Some(block), joint).unwrap();
    (world, id)
}

#[test]
fn block_sticks_below_the_friction_angle() {
    let (alpha, mu) = (20f64.to_radians() as Real, 0.4);
    assert!(alpha.tan() < mu);
    let (mut world, id) = incline(alpha, mu);
    for _ in 0..600 {
        world.step().unwrap();
    }
    let out = world.output(id).unwrap();
    let fr = out.friction.unwrap();
    let creep = out.displacement.x.abs();
    println!(
        "stuck: creep {creep:.2e} m, friction {:.6} N (m g sin a = {:.6}), normal {:.6} N, slipping {}",
        fr.force,
        M * G * alpha.sin(),
        fr.normal,
        fr.slipping
    );
    assert!(creep <= 1e-9, "creep {creep:.3e} m");
    assert!(!fr.slipping);
    assert!((fr.force - M * G * alpha.sin()).abs() <= 1e-6 * M * G);
    // The reactions carry the solver's relative regularisation (1e-8).
    assert!((fr.normal - M * G * alpha.cos()).abs() <= 1e-6 * M * G);
}

#[test]
fn block_slides_above_the_friction_angle_at_the_coulomb_rate() {
    let (alpha, mu) = (30f64.to_radians() as Real, 0.3);
    assert!(alpha.tan() > mu);
    let (mut world, id) = incline(alpha, mu);
    let e0 = world.energy().total;
    for _ in 0..120 {
        world.step().unwrap();
    }
    let t = world.time();
    let a = G * (alpha.sin() - mu * alpha.cos());
    let out = world.output(id).unwrap();
    let v = out.velocity.x;
    let err = (v - a * t).abs() / (a * t);
    let e = world.energy();
    let drop = M * G * out.displacement.x * alpha.sin();
    let balance = (e.total - e0).abs() / drop;
    println!(
        "sliding: v {v:.9} vs {:.9} ({err:.2e}), dissipated {:.6} J vs mu m g cos(a) s = {:.6} J, balance {balance:.2e}",
        a * t,
        e.dissipated,
        mu * M * G * alpha.cos() * out.displacement.x
    );
    assert!(out.friction.unwrap().slipping);
    let exact_loss = mu * M * G * alpha.cos() * out.displacement.x;
    assert!(
        (e.dissipated - exact_loss).abs() <= 1e-6 * exact_loss,
        "dissipated {} vs {exact_loss}",
        e.dissipated
    );
    assert!(err <= 1e-4, "velocity error {err:.3e}");
    let h = world.settings().dt / world.settings().substeps as Real;
    assert!(balance <= h / t, "energy balance {balance:.3e}");
}

/// Rapier backends: friction approximated by a force-capped velocity motor whose cap `mu N`
/// uses the previous step's recovered reactions. Measured, not exact: the figures go to the
/// README; checked only that the approximation holds below the friction angle (creep below
/// 2 cm in 10 s: the first step has no reaction yet, so no friction, and the motor is a
/// velocity-level cap that lets the block creep) and slides above it with the acceleration
/// within 5 % of the Coulomb value.
#[test]
fn rapier_backends_approximate_friction_with_capped_motors() {
    for backend in [Backend::RapierImpulse, Backend::RapierMultibody] {
        let (alpha, mu) = (20f64.to_radians() as Real, 0.4);
        let (mut world, id) = incline_on(backend, alpha, mu);
        for _ in 0..600 {
            world.step().unwrap();
        }
        let creep = world.output(id).unwrap().displacement.x.abs();
        let (alpha2, mu2) = (30f64.to_radians() as Real, 0.3);
        let (mut world, id) = incline_on(backend, alpha2, mu2);
        for _ in 0..120 {
            world.step().unwrap();
        }
        let t = world.time();
        let a = G * (alpha2.sin() - mu2 * alpha2.cos());
        let v = world.output(id).unwrap().velocity.x;
        let err = (v - a * t) / (a * t);
        println!(
            "{}: stuck creep {creep:.2e} m in 10 s; sliding speed error {err:+.3e}",
            backend.name()
        );
        assert!(creep <= 2e-2, "{}: creep {creep:.3e}", backend.name());
        assert!(
            err.abs() <= 5e-2,
            "{}: speed error {err:.3e}",
            backend.name()
        );
    }
}
