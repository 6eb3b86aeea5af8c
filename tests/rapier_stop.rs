//! `SECSTOP` on Rapier's own joints: a 1 kg bob on a 1 m massless hinge about Z (bob rotary
//! inertia 1e-4 kg m^2), gravity -9.81 along Y, hanging at rest and started at 2 rad/s: its
//! energy (2.0 J above the bottom) would swing it to 37 deg, and stops at -/+20 deg
//! (`m g L (1 - cos 20) = 0.59 J`) send it back and forth, about 50 impacts in 18 s at
//! dt 1/60 s x 4 substeps.
//!
//! Expected on each Rapier backend, beside the Lagrange backend (energies per the 2 J of kinetic
//! energy at the start; measured 2026-11-25):
//! - at least 40 impacts (Lagrange 49, impulse 45, multibody 48): the stops are elastic (a
//!   plastic stop takes the 1.41 J of kinetic energy the bob has at the first stop);
//! - the hinge passes a stop by no more than Rapier's own limit slop: 6.1e-3 rad on the impulse
//!   backend (its soft limit at 1.9 rad/s), 1e-16 on the multibody one (the excursion is taken
//!   back at the impact), 0 on Lagrange; checked at 1e-2 rad;
//! - each impact step changes the energy as the exact backend's does, to 2e-3 (measured -1.14e-2
//!   Lagrange, -1.16e-2 multibody, -1.06e-2 impulse per impact step: the symplectic scheme's
//!   bounded energy oscillation over the step, not a loss);
//! - over the run, the energy changes no more than twice the backend's own drift without stops
//!   (at least 1e-2): multibody -3.5e-3 (+1.0e-3 without stops); impulse -18.5 % against -10 %
//!   without stops: its dissipation in free flight, which grows with speed, and the bouncing
//!   bob is always fast (+2.8e-4 per free step against Lagrange's +5.4e-4).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

const STOP: Real = 20.0 * rapier3d_mpc184::math::PI / 180.0;

fn pendulum(backend: Backend, stops: bool) -> (Mpc184World, JointId) {
    let mut world = Mpc184World::new(WorldSettings {
        backend,
        ..Default::default()
    });
    world.physics.gravity = Vector::new(0.0, -9.81, 0.0);
    let bob = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(0.0, -1.0, 0.0))
            .linvel(Vector::new(2.0, 0.0, 0.0))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, Vector::splat(1e-4)))
            .can_sleep(false),
    );
    let mut joint = Mpc184Joint::revolute(Axis::Z, Vector::ZERO);
    if stops {
        joint = joint.with_stop(Dof::RotZ, -STOP, STOP);
    }
    let id = world.insert_joint(None, Some(bob), joint).unwrap();
    (world, id)
}

/// What a run of 18 s shows.
struct Run {
    impacts: usize,
    /// Largest excursion past a stop (rad).
    overshoot: Real,
    /// Energy change over the run, per the initial kinetic energy (2 J).
    change: Real,
    /// Mean energy change over the steps with an impact, and over the others, per 2 J.
    at_impacts: Real,
    between: Real,
}

fn run(backend: Backend, stops: bool) -> Run {
    let (mut world, id) = pendulum(backend, stops);
    let e0 = world.energy().total;
    let (mut impacts, mut overshoot, mut prev) = (0, 0.0 as Real, 0.0 as Real);
    let (mut at, mut free, mut e_prev) = (0.0, 0.0, e0);
    for _ in 0..1080 {
        world.step().unwrap();
        let o = world.output(id).unwrap();
        let w = o.angular_velocity.z;
        let e = world.energy().total;
        // An impact reverses the rate near a stop.
        if prev * w < 0.0 && o.rotation.z.abs() > 0.9 * STOP {
            impacts += 1;
            at += e - e_prev;
        } else {
            free += e - e_prev;
        }
        (prev, e_prev) = (w, e);
        overshoot = overshoot.max(o.rotation.z.abs() - STOP);
    }
    Run {
        impacts,
        overshoot,
        change: (world.energy().total - e0) / 2.0,
        at_impacts: at / 2.0 / impacts.max(1) as Real,
        between: free / 2.0 / (1080 - impacts) as Real,
    }
}

#[test]
fn an_elastic_stop_bounces_and_keeps_the_energy_on_every_backend() {
    let exact = run(Backend::Lagrange, true);
    for backend in [
        Backend::Lagrange,
        Backend::RapierImpulse,
        Backend::RapierMultibody,
    ] {
        let r = run(backend, true);
        let free = run(backend, false);
        let name = backend.name();
        println!(
            "{name}: {} impacts, overshoot {:.2e} rad, energy {:+.2e} ({:+.2e} per impact step, \
             {:+.2e} per other step; without stops {:+.2e})",
            r.impacts, r.overshoot, r.change, r.at_impacts, r.between, free.change
        );
        assert!(r.impacts >= 40, "{name}: {} impacts", r.impacts);
        assert!(
            r.overshoot <= 1e-2,
            "{name}: overshoot {:.3e} rad",
            r.overshoot
        );
        let per_impact = (r.at_impacts - exact.at_impacts).abs();
        assert!(
            per_impact <= 2e-3,
            "{name}: impact energy off by {per_impact:.3e}"
        );
        let bound = (2.0 * free.change.abs()).max(1e-2);
        assert!(
            r.change.abs() <= bound,
            "{name}: energy change {:.3e}",
            r.change
        );
    }
}
