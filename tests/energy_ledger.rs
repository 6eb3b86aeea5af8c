//! The energy ledger books every source of work, and the energy guard stops what it cannot
//! explain (`Mpc184World::energy`, `DivergenceLimits::energy_growth`).
//!
//! - Ramped gravity (`ACEL` under `KBC,0`): the 90 deg pendulum deck (1 kg, 1 m) with its
//!   gravity ramped from 0 over 20 s. The gravitational energy `-m g(t) . c` changes with `g`
//!   at fixed positions; `set_gravity` books that change as work. Checked: the balance stays
//!   within 1e-3 m g L of its start (RATTLE at 1/240 s x 4; the same deck with stepped gravity
//!   too, RATTLE's bounded O(h^2) oscillation; measured 5.3e-6 J ramped, 3.9e-5 J stepped).
//!   Before the booking the ramped deck drifted to -7.4 J (issue 19's measurement).
//! - A nodal force (`F`, stepped 3 N along X) on a 2 kg mass on a COMBIN14 spring (32 N/m):
//!   the force's work `F . (c_1 - c_0)` per step is exact for a force held over the step, so
//!   kinetic + spring - work stays at its start within 1e-4 of the largest spring energy
//!   (Verlet's `(omega h)^2 / 4` = 6.9e-5 with `omega h = 1/60`; measured 1.1e-6).
//! - A kinematic carriage moving at 1 m/s along X carries a 1 kg pendulum (1 m, revolute z)
//!   released at rest: the carriage's work through the joint (the joint's reaction on it times
//!   its velocity, per step) keeps kinetic + potential - work within 2e-3 m g L over 5 s at
//!   1/240 s x 4 (that power is the last substep's reaction times the step: first order in
//!   the step; measured 4.7e-4 m g L of the 1.99 J the carriage put in).
//! - An explicit spring past its stability limit (TB,JOIN STIF 1e6 N/m on a 2 kg block on a
//!   translational joint, `omega h = 2.95` at 1/240 s: its energy grows by a factor of about
//!   `(omega h)^4` per substep): the guard stops the first step that grows the balance by more
//!   than 0.25 of the energy scale, names the joint, and the world keeps the last good state,
//!   whose balance is within that bound of the start. With the guard off the same run keeps
//!   going past that step, still finite, its energy already many times the start: the other
//!   divergence bounds had not seen it.
#![cfg(feature = "f64")]

use rapier3d_mpc184::deck::{BuildOptions, DeckModel, parse_str};
use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

const PENDULUM: &str = include_str!("../assets/decks/pendulum_z.inp");

fn rattle() -> BuildOptions {
    BuildOptions {
        integrator: Integrator::Rattle,
        ..BuildOptions::default()
    }
}

/// The largest |balance| (J) over every step of a deck.
fn worst_balance(text: &str) -> (Real, DeckModel) {
    let deck = parse_str(text, "ledger.inp").unwrap();
    let mut m = DeckModel::build(&deck, rattle()).unwrap();
    let e0 = m.world.energy().total;
    let mut worst: Real = 0.0;
    for k in 0..m.steps.len() {
        m.begin_load_step(k).unwrap();
        for _ in 0..m.steps[k].steps {
            m.step().unwrap();
            worst = worst.max((m.world.energy().total - e0).abs());
        }
    }
    (worst, m)
}

#[test]
fn ramped_gravity_is_booked_as_work() {
    assert!(PENDULUM.contains("\nKBC,1\n") && PENDULUM.contains("\nTIME,2.0\n"));
    let stepped = PENDULUM.replace("\nTIME,2.0\n", "\nTIME,20\n");
    let ramped = stepped.replace("\nKBC,1\n", "\nKBC,0\n");
    let (w_stepped, _) = worst_balance(&stepped);
    let (w_ramped, m) = worst_balance(&ramped);
    println!("balance: stepped {w_stepped:.2e} J, ramped {w_ramped:.2e} J");
    let mgl = 9.81;
    assert!(w_stepped < 1e-3 * mgl, "{w_stepped}");
    assert!(w_ramped < 1e-3 * mgl, "{w_ramped}");
    // The ramp's work is booked (the sum of `-m dg . c` over the ramp's increments).
    assert!(m.world.energy().work.abs() > 0.1, "{:?}", m.world.energy());
}

#[test]
fn a_nodal_force_is_booked_as_work() {
    let text = "/PREP7\nET,1,COMBIN14\nET,2,MASS21,,,2\nR,1,32,0,0,0,0,1.0\nR,2,2.0\n\
                N,1,0,0,0\nN,2,1,0,0\nTYPE,1 $ REAL,1\nE,1,2\nTYPE,2 $ REAL,2\nE,2\nFINISH\n\
                /SOLU\nANTYPE,TRANS\nD,1,ALL,0\nF,2,FX,3\nKBC,1\nTIME,5\nDELTIM,1/240\nSOLVE\n";
    let (worst, m) = worst_balance(text);
    // The force stretches the spring to 2 F / k = 0.1875 m at most: spring energy 0.5625 J.
    let scale = 0.5 * 32.0 * (2.0 * 3.0 / 32.0_f64).powi(2);
    println!(
        "balance {worst:.2e} J of {scale} J; work {}",
        m.world.energy().work
    );
    assert!(worst < 1e-4 * scale, "{worst}");
    assert!(m.world.energy().work > 0.0);
}

#[test]
fn a_kinematic_carriage_works_through_its_joint() {
    let mut world = Mpc184World::new(WorldSettings {
        dt: 1.0 / 240.0,
        integrator: Integrator::Rattle,
        ..WorldSettings::default()
    });
    let carriage = world
        .physics
        .bodies
        .insert(RigidBodyBuilder::kinematic_velocity_based().linvel(Vector::new(1.0, 0.0, 0.0)));
    let bob = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(0.0, -1.0, 0.0))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, Vector::splat(1e-4)))
            .can_sleep(false),
    );
    world
        .insert_joint(
            Some(carriage),
            Some(bob),
            Mpc184Joint::revolute(Axis::Z, Vector::ZERO),
        )
        .unwrap();
    let e0 = world.energy().total;
    let mut worst: Real = 0.0;
    for _ in 0..(5.0 * 240.0) as usize {
        world.step().unwrap();
        worst = worst.max((world.energy().total - e0).abs());
    }
    let e = world.energy();
    println!(
        "balance {worst:.2e} J, work {} J, kinetic {} J",
        e.work, e.kinetic
    );
    assert!(e.work.abs() > 1e-2, "the carriage did no work: {e:?}");
    assert!(worst < 2e-3 * 9.81, "{worst}");
}

fn unstable_block(guard: bool) -> (Mpc184World, JointId) {
    let mut world = Mpc184World::new(WorldSettings::default());
    world.physics.gravity = Vector::ZERO;
    if !guard {
        let mut l = world.divergence_limits();
        l.energy_growth = Real::INFINITY;
        world.set_divergence_limits(l).unwrap();
    }
    let block = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(Vector::new(0.01, 0.0, 0.0))
            .additional_mass_properties(MassProperties::new(Vector::ZERO, 2.0, Vector::splat(0.1)))
            .can_sleep(false),
    );
    let mut k = [0.0; 6];
    k[0] = 1e6;
    let slide = Mpc184Joint::new(JointKind::Translational, Vector::new(0.01, 0.0, 0.0))
        .with_stiffness(Sym6::diagonal(k))
        .with_reference(Dof::Ux, -0.01);
    let id = world.insert_joint(None, Some(block), slide).unwrap();
    (world, id)
}

#[test]
fn the_energy_guard_stops_an_explicit_spring_past_its_limit() {
    let (mut world, id) = unstable_block(true);
    let e0 = world.energy().total;
    let mut good = 0;
    let err = loop {
        match world.step() {
            Ok(()) => good += 1,
            Err(e) => break e,
        }
        assert!(good < 100, "never stopped");
    };
    let Error::Diverged {
        joint,
        reason,
        time,
    } = &err
    else {
        panic!("{err}");
    };
    println!("after {good} good steps: {err}");
    assert_eq!(*joint, Some(id));
    assert!(reason.contains("energy guard"), "{reason}");
    assert_eq!(*time, world.time());
    let kept = world.energy().total;
    assert!(
        (kept - e0).abs() <= 0.25 * e0.max(1e-6) + 1e-9,
        "kept {kept} from {e0}"
    );
    // Without the guard the same run passes that step, finite, its energy grown past the bound.
    let (mut free, _) = unstable_block(false);
    for _ in 0..=good {
        free.step().unwrap();
    }
    let grown = free.energy().total;
    println!("without the guard: {grown:e} J from {e0:e} J");
    assert!(grown.is_finite() && grown > 1.25 * e0, "{grown}");
}

/// Contacts on a jointed body (Lagrange backend): the pendulum of `contact_pendulum.rs` (1 kg
/// ball of radius 0.1 m on a 1 m revolute, released horizontally) swings onto a floor at
/// y = -0.5 m and comes to rest there. A substep in which an island body has an active contact
/// books the island's energy change that nothing else booked as the contact's work (negative:
/// the inelastic contact dissipates). Checked over 5 s at 1/60 s x 4: kinetic + potential -
/// work stays at its start within 2e-2 m g L (before the impact the balance measures the
/// first-order step's own error over the 90 deg swing: measured 5.2e-3 m g L), while the work
/// booked is the energy the bob lost, m g 0.4 m = 3.92 J (measured 3.87 J) within 2 %.
#[test]
fn contacts_on_jointed_bodies_are_booked() {
    let (mut world, _, _) =
        rapier3d_mpc184::studies::scenes::pendulum_onto_floor(WorldSettings::default()).unwrap();
    let e0 = world.energy().total;
    let mut worst: Real = 0.0;
    for _ in 0..300 {
        world.step().unwrap();
        worst = worst.max((world.energy().total - e0).abs());
    }
    let e = world.energy();
    println!(
        "balance {worst:.2e} J; work {} J; kinetic {} J",
        e.work, e.kinetic
    );
    assert!(
        (e.work + 9.81 * 0.4).abs() < 0.02 * 9.81 * 0.4,
        "contact work {e:?}"
    );
    assert!(worst < 2e-2 * 9.81, "{worst}");
}
