//! The spring-damper element (COMBIN14) on a free 2 kg block, no gravity, spring to a ground
//! point along X with `k = 32 N/m`, released 0.1 m from its free length. Undamped:
//! `x = x0 cos(omega t)`, `omega = sqrt(k / m) = 4 rad/s`, energy `m v^2 / 2 + k x^2 / 2`
//! constant; the block has no joint, so it is an island of its own on the Lagrange backend.
//!
//! - Lagrange + RATTLE at dt 1/60 x 4 (`omega h = 1/60`): the element is kicked
//!   kick-drift-kick (velocity Verlet, second order), so after 10 periods the position is off
//!   by `x0 * 10 * 2 pi * (omega h)^2 / 24 = 7.3e-5 m` of phase at most, and the energy
//!   oscillates by `(omega h)^2 / 4 = 6.9e-5` relative: checked at 1e-4 m and 1e-4.
//! - Damped (`c = 0.32 N s/m`, `zeta = 0.02`): the amplitude after 10 periods is
//!   `x0 exp(-zeta omega t)` within 1 % (explicit half kicks of the damper shift the decay by
//!   O(zeta omega h) of itself), and `kinetic + spring + dissipated` stays at its start within
//!   5e-4 relative (the booked dissipation lags by O(zeta omega h) = 3.3e-4).
//! - A spring the substep cannot follow (`k = 1e9 N/m`, `h w = 5.8`) takes the implicit update:
//!   it stays finite, the energy never grows (backward Euler dissipates), and the diagnostics
//!   count it; the same spring kicked explicitly would grow by `(h w)^2` per substep.
//! - `rapier-impulse` applies the force explicitly once per step (`dt omega = 1/15`): the
//!   period holds to first order, x(10 periods) within `x0 (dt omega)` = 7e-3 m.
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder, RigidBodyHandle};
use rapier3d_mpc184::prelude::*;

const M: Real = 2.0;
const K: Real = 32.0;
const X0: Real = 0.1;

fn block(settings: WorldSettings, k: Real, c: Real) -> (Mpc184World, SpringId) {
    let mut world = Mpc184World::new(settings);
    world.physics.gravity = Vector::ZERO;
    let b = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(1.0 + X0, 0.0, 0.0))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, M, Vector::splat(0.1)))
            .can_sleep(false),
    );
    let spring = SpringDamper::new(Vector::ZERO, Vector::new(1.0 + X0, 0.0, 0.0), k)
        .with_rest_length(1.0)
        .with_damping(c);
    let id = world.insert_spring(None, Some(b), spring).unwrap();
    (world, id)
}

fn rattle() -> WorldSettings {
    WorldSettings {
        integrator: Integrator::Rattle,
        ..WorldSettings::default()
    }
}

fn run(world: &mut Mpc184World, seconds: Real) {
    let steps = (seconds / world.settings().dt).round() as usize;
    for _ in 0..steps {
        world.step().unwrap();
    }
}

#[test]
fn undamped_spring_keeps_period_and_energy() {
    let (mut world, id) = block(rattle(), K, 0.0);
    let omega = (K / M).sqrt();
    let e0 = world.energy();
    assert!((e0.spring - 0.5 * K * X0 * X0).abs() < 1e-12, "{e0:?}");
    // 10 periods = 5 pi s; run a whole number of steps close to it and compare at that time.
    run(&mut world, 5.0 * core::f64::consts::PI as Real);
    let t = world.time();
    let out = world.spring_output(id).unwrap();
    let x = out.length - 1.0;
    assert!(
        (x - X0 * (omega * t).cos()).abs() < 1e-4,
        "x = {x}, analytic {}",
        X0 * (omega * t).cos()
    );
    let e = world.energy();
    let rel = (e.kinetic + e.spring - e0.spring).abs() / e0.spring;
    assert!(rel < 1e-4, "energy off by {rel:e}: {e:?}");
    assert_eq!(world.lagrange_diagnostics().implicit_springs, 0);
}

#[test]
fn damped_spring_decays_and_books_its_dissipation() {
    let c = 0.32;
    let (mut world, id) = block(rattle(), K, c);
    let omega = (K / M).sqrt();
    let zeta = c / (2.0 * M * omega);
    let e0 = world.energy().total;
    let mut peak: Real = 0.0;
    let period = 2.0 * core::f64::consts::PI as Real / omega;
    let steps = (10.0 * period / world.settings().dt).round() as usize;
    for s in 0..steps {
        world.step().unwrap();
        if s + 1 >= steps - (period / world.settings().dt) as usize {
            peak = peak.max((world.spring_output(id).unwrap().length - 1.0).abs());
        }
    }
    // The last period's largest |x| against the envelope at its middle (the peak falls within
    // a period; the envelope changes by exp(-zeta omega T) = 0.88 over one, so compare with
    // the envelope at the sampled peak's time bracket: between the two ends).
    let t = world.time();
    let hi = X0 * (-zeta * omega * (t - period)).exp();
    let lo = X0 * (-zeta * omega * t).exp();
    assert!(
        peak <= hi * 1.01 && peak >= lo * 0.99,
        "peak {peak}, envelope {lo}..{hi}"
    );
    let e = world.energy();
    assert!(e.dissipated > 0.5 * e0, "{e:?}");
    assert!(
        (e.total - e0).abs() < 5e-4 * e0,
        "balance {e:?} against {e0}"
    );
}

#[test]
fn stiff_spring_takes_the_implicit_update_and_stays_bounded() {
    let (mut world, id) = block(rattle(), 1e9, 0.0);
    let e0 = world.energy().total;
    run(&mut world, 1.0);
    let e = world.energy();
    assert!(
        world.lagrange_diagnostics().implicit_springs > 0,
        "{:?}",
        world.lagrange_diagnostics()
    );
    assert!(
        e.total.is_finite() && e.total <= e0 * (1.0 + 1e-9),
        "{e:?} from {e0}"
    );
    let x = world.spring_output(id).unwrap().length - 1.0;
    assert!(x.abs() <= X0, "x = {x}");
}

#[test]
fn rapier_impulse_backend_applies_the_spring_explicitly() {
    let settings = WorldSettings {
        backend: Backend::RapierImpulse,
        ..WorldSettings::default()
    };
    let (mut world, id) = block(settings, K, 0.0);
    let omega = (K / M).sqrt();
    run(&mut world, 5.0 * core::f64::consts::PI as Real);
    let t = world.time();
    let x = world.spring_output(id).unwrap().length - 1.0;
    assert!(
        (x - X0 * (omega * t).cos()).abs() < 7e-3,
        "x = {x}, analytic {}",
        X0 * (omega * t).cos()
    );
}

#[test]
fn bad_spring_data_is_refused_with_the_field() {
    let (mut world, _) = block(rattle(), K, 0.0);
    let b = world
        .physics
        .bodies
        .iter()
        .find(|(_, rb)| rb.is_dynamic())
        .unwrap()
        .0;
    let p = Vector::new(1.0, 0.0, 0.0);
    let cases = [
        (SpringDamper::new(Vector::ZERO, p, -1.0), "K"),
        (
            SpringDamper::new(Vector::ZERO, p, 1.0).with_damping(Real::NAN),
            "CV1",
        ),
        (SpringDamper::new(p, p, 1.0), "nodes"),
        (
            SpringDamper::new(Vector::ZERO, p, 1.0).with_rest_length(-2.0),
            "ILEN",
        ),
    ];
    for (s, field) in cases {
        match world.insert_spring(None, Some(b), s) {
            Err(Error::InvalidSpring { field: f, .. }) => assert_eq!(f, field),
            other => panic!("{field}: {other:?}"),
        }
    }
    assert!(matches!(
        world.insert_spring(Some(b), Some(b), SpringDamper::new(Vector::ZERO, p, 1.0)),
        Err(Error::InvalidSpring {
            field: "body 2",
            ..
        })
    ));
    assert_eq!(world.spring_ids().count(), 1);
}

/// Two 1 kg pendulums (1 m, revolutes about Z 0.5 m apart, gravity) coupled by a spring between
/// their bobs (k = 20 N/m, free at 0.5 m), one released 0.2 rad out. The spring joins two joint
/// islands into one, kicked from both bodies' states. Small-angle solution: the normal modes
/// `w1^2 = g / L`, `w2^2 = g / L + 2 k / m`, `theta_1,2 = theta0 (cos w1 t +- cos w2 t) / 2`; so
/// the energy of the second pendulum (`m L^2 theta2'^2 / 2 + m g L theta2^2 / 2`) peaks near
/// half a beat, `pi / (w2 - w1)` = 0.80 s, at 0.82 of the initial excess energy (sampled at the
/// step times within 0.2 s of it). Checked:
/// - the total energy (kinetic, gravity, spring) constant to 3e-4 of the excess energy over
///   10 s under RATTLE at 1/60 x 4: Verlet's bounded oscillation `(w2 h)^2 / 4 = 2.2e-4`
///   (`w2 h = 0.029`); measured 1.9e-4;
/// - the second pendulum's largest share near half a beat within 2 % of the small-angle
///   prediction (0.2 rad: `sin` against its argument and the spring's geometry differ by
///   `theta^2 / 6` = 0.7 %; measured 0.2 %).
#[test]
fn spring_couples_two_pendulums_and_keeps_the_energy() {
    let g: Real = 9.81;
    let (k, m, l) = (20.0, 1.0, 1.0);
    let mut world = Mpc184World::new(rattle());
    let theta0: Real = 0.2;
    let mut bob = |x: Real, theta: Real| {
        let b = world.physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .translation(Vector::new(x + l * theta.sin(), -l * theta.cos(), 0.0))
                .additional_mass_properties(MassProperties::new(
                    Vector::ZERO,
                    m,
                    Vector::splat(1e-4),
                ))
                .can_sleep(false),
        );
        let pin = Mpc184Joint::revolute(Axis::Z, Vector::new(x, 0.0, 0.0));
        world.insert_joint(None, Some(b), pin).unwrap();
        b
    };
    let (b1, b2) = (bob(0.0, theta0), bob(0.5, 0.0));
    let p1 = world.physics.bodies[b1].translation();
    let p2 = world.physics.bodies[b2].translation();
    world
        .insert_spring(
            Some(b1),
            Some(b2),
            SpringDamper::new(p1, p2, k).with_rest_length(0.5),
        )
        .unwrap();
    let e0 = world.energy().total;
    // The energy above the rest state (both bobs hanging, spring free): 2 m g L below zero.
    let excess = e0 + 2.0 * m * g * l;
    let (w1, w2) = ((g / l).sqrt(), (g / l + 2.0 * k / m).sqrt());
    let half_beat = core::f64::consts::PI as Real / (w2 - w1);
    // The small-angle excess energy and the second pendulum's energy at `t`.
    let linear_excess = 0.5 * m * g * l * theta0 * theta0 + 0.5 * k * (l * theta0).powi(2);
    let linear_share = |t: Real| {
        let th = 0.5 * theta0 * ((w1 * t).cos() - (w2 * t).cos());
        let rate = 0.5 * theta0 * (w2 * (w2 * t).sin() - w1 * (w1 * t).sin());
        (0.5 * m * l * l * rate * rate + 0.5 * m * g * l * th * th) / linear_excess
    };
    let own_energy = |w: &Mpc184World, b: RigidBodyHandle| {
        let rb = &w.physics.bodies[b];
        0.5 * m * rb.linvel().length_squared() + m * g * (rb.translation().y + l)
    };
    let (mut share, mut predicted): (Real, Real) = (0.0, 0.0);
    let steps = (10.0 / world.settings().dt).round() as usize;
    let mut worst: Real = 0.0;
    for _ in 0..steps {
        world.step().unwrap();
        worst = worst.max((world.energy().total - e0).abs());
        let t = world.time();
        if (t - half_beat).abs() < 0.2 {
            share = share.max(own_energy(&world, b2) / excess);
            predicted = predicted.max(linear_share(t));
        }
    }
    println!(
        "energy off by {:.1e} of the excess; share {share:.4} against {predicted:.4}",
        worst / excess
    );
    assert!(worst < 3e-4 * excess, "energy off by {worst:e} of {excess}");
    assert!(
        (share / predicted - 1.0).abs() < 0.02,
        "second pendulum's share {share} against {predicted} near t = {half_beat}"
    );
}

/// The spring element's energy in the energy-consistent impact of RATTLE: the 2 kg block of
/// the first tests on a translational joint along X (no gravity) with an elastic stop at
/// UX = -0.15 m (SECSTOP on UX, Lagrange method; the free oscillation would reach -0.2 m): the
/// spring pulls it from rest at UX = 0 onto the stop, where it bounces back to UX = 0, again and
/// again, the spring still loaded (0.05 m) at each impact. The impact sets the
/// outgoing rate so that kinetic + spring energy at the substep's end is what it started with;
/// checked over 10 s (about 40 impacts): the energy within 1e-4 of its start at every step
/// (Verlet's bounded oscillation `(omega h)^2 / 4 = 6.9e-5`; measured 6.9e-5). Without the
/// element's energy in that balance the impact restored the wrong total: measured 0.12 of the
/// energy off after 10 s.
#[test]
fn elastic_stop_keeps_the_spring_elements_energy() {
    let (mut world, _) = block(rattle(), K, 0.0);
    let b = world
        .physics
        .bodies
        .iter()
        .find(|(_, rb)| rb.is_dynamic())
        .unwrap()
        .0;
    let node = world.physics.bodies[b].translation();
    let guide = Mpc184Joint::new(JointKind::Translational, node).with_stop(Dof::Ux, -0.15, 0.05);
    world.insert_joint(None, Some(b), guide).unwrap();
    let e0 = world.energy().total;
    let mut worst: Real = 0.0;
    let steps = (10.0 / world.settings().dt).round() as usize;
    for _ in 0..steps {
        world.step().unwrap();
        worst = worst.max((world.energy().total - e0).abs());
    }
    println!("energy off by {:.2e} of {e0}", worst / e0);
    assert!(worst < 1e-4 * e0, "energy off by {worst:e} of {e0}");
}
