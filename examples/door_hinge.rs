//! `cargo run --release --example door_hinge -- [--mu MU] [--tilt DEG] [--push NM] [--pulse S] [--latch DEG] [--secs S] [--out DIR]`
//!
//! Scene: a door of 20 kg, 1 m wide, 2 m high, 40 mm thick on a grounded revolute joint (Lagrange
//! backend, revolute z) along its edge. The hinge axis leans `--tilt` degrees from the vertical
//! (towards the closed door's normal), so the door's weight has a moment about it: the closed
//! position (0) is the lowest for angles up to 90 deg, past 90 deg the door falls further open.
//! The hinge has Coulomb friction with the `SECJOINT,FRIC` geometry of a pin (outer radius 15 mm,
//! inner 8 mm, effective length 1.8 m between the two hinges): the normal moment is built from
//! the axial load (the weight), the radial force and the bending moment of the cantilevered door.
//! A stop holds ROTZ in [0, 100 deg] (`SECSTOP`: the frame at 0, the wall at 100 deg; elastic on
//! the Lagrange backend), and `--latch DEG` adds a lock (`SECLOCK`) that catches the door when it
//! opens past that angle. A moment pulse FJ on ROTZ (`--push` N m for `--pulse` s) pushes it open.
//!
//! Expected: the door swings open, hits the wall stop (or falls back before it), swings back and
//! bounces on the frame stop, friction slowing it until it sticks; the stops are never passed
//! (exact inequality) and the energy balance (kinetic + potential + spring + dissipated - work of
//! FJ, `Mpc184World::energy`) keeps its start value up to the integrator's error.
//!
//! Measured (defaults): the balance grows by about 4.1e-3 J per step while the pulse acts and
//! not after it, which is `M^2 h^2 / (4 I)` per substep for the 40 N m pulse on the door's
//! 6.67 kg m^2: the FJ work is booked without the kinetic energy of its own half-kicks, a
//! first-order (O(h)) ledger error of the load, not of the stops or the friction. With
//! `--latch`, the balance shows a one-step spike (the lock's landing is booked as dissipated in
//! the step where the output still carries the pre-landing rate).
//!
//! Prints one row per event (pulse end, stop hit, stick / slip change, latch) with time, angle,
//! rate, stop hits so far, slip state, dissipated energy and the energy balance, then a summary.
//! CSV (`out/door_hinge/door_hinge.csv`): every step.

#[path = "common/mod.rs"]
mod common;

use std::process::ExitCode;

use common::{Csv, RunResult};
use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
use rapier3d_mpc184::prelude::*;

const MASS: Real = 20.0;
const WIDTH: Real = 1.0;
const HEIGHT: Real = 2.0;
const THICKNESS: Real = 0.04;
/// The wall stop (rad).
const OPEN_STOP_DEG: Real = 100.0;

/// A door on a tilted hinge with friction, a stop and an optional latch
#[derive(clap::Parser)]
struct Opts {
    /// Hinge friction coefficient
    #[arg(long, value_name = "MU", value_parser = common::any_real, default_value = "0.2")]
    mu: Real,
    /// Hinge axis lean from the vertical, deg
    #[arg(long, value_name = "DEG", value_parser = common::any_real, default_value = "2")]
    tilt: Real,
    /// Opening moment of the pulse, N m
    #[arg(long, value_name = "NM", value_parser = common::any_real, default_value = "40")]
    push: Real,
    /// Pulse length, s
    #[arg(long, value_name = "S", value_parser = common::real, default_value = "0.25")]
    pulse: Real,
    /// Lock the door when it opens past DEG [default: no latch]
    #[arg(long, value_name = "DEG", value_parser = common::any_real)]
    latch: Option<Real>,
    /// Simulated time, s
    #[arg(long, value_name = "S", value_parser = common::real, default_value = "12")]
    secs: Real,
    /// CSV directory
    #[arg(long, value_name = "DIR")]
    out: std::path::PathBuf,
}

fn main() -> ExitCode {
    common::main("door_hinge", common::parse("door_hinge", &[]), run)
}

fn run(o: Opts) -> RunResult {
    let deg = |x: Real| x.to_degrees();
    let open = OPEN_STOP_DEG.to_radians();
    let tilt = o.tilt.to_radians();
    let half_pi = std::f64::consts::FRAC_PI_2 as Real;
    // Frame I: e1 along the closed door (global X), e3 the hinge axis (0, cos t, sin t).
    let axes = Rotation::from_rotation_x(tilt - half_pi);
    let settings = WorldSettings::default();
    let (mut world, id) = door(&o, axes)?;
    let e0 = world.energy().total;
    println!(
        "door {MASS} kg, {WIDTH} x {HEIGHT} m, hinge tilt {} deg, mu {}, stop [0, {OPEN_STOP_DEG}] deg, push {} N m for {} s{}, {} s at dt 1/60, 4 substeps",
        o.tilt,
        o.mu,
        o.push,
        o.pulse,
        o.latch
            .map_or(String::new(), |l| format!(", latch at {l} deg")),
        o.secs
    );
    let mut csv = Csv::create(&o.out, "door_hinge.csv", &COLUMNS)?;
    println!(
        "\n{:<26} {:>7} {:>9} {:>9} {:>5} {:>6} {:>10} {:>10} {:>11}",
        "event", "t s", "angle deg", "rate r/s", "hits", "slip", "dissip J", "work J", "balance J"
    );
    let mut tracker = Tracker {
        hits: 0,
        was_at_stop: false,
        was_slipping: true,
        was_locked: false,
        pulse_done: false,
    };
    let (mut past, mut worst, mut max_kin): (Real, Real, Real) = (0.0, 0.0, 0.0);
    let mut printed = 0usize;
    const MAX_ROWS: usize = 40;
    for _ in 0..common::steps(o.secs, settings.dt) {
        world.step()?;
        let t = world.time();
        let out = *world.output(id)?;
        let e = world.energy();
        let angle = out.measure[5];
        let rate = out.angular_velocity.z;
        let balance = e.total - e0;
        past = past.max(angle - open).max(-angle);
        worst = worst.max(balance.abs());
        max_kin = max_kin.max(e.kinetic);
        csv.row(&[
            t,
            angle,
            rate,
            Real::from(out.stops),
            Real::from(out.locks),
            Real::from(u8::from(out.friction.is_some_and(|f| f.slipping))),
            out.friction.map_or(0.0, |f| f.force),
            out.friction.map_or(0.0, |f| f.normal),
            e.kinetic,
            e.potential,
            e.dissipated,
            e.work,
            balance,
        ])?;
        let events = tracker.update(t, &out, o.pulse, open);
        let (hits, f) = (tracker.hits, out.friction.unwrap_or_default());
        for ev in events {
            printed += 1;
            if printed <= MAX_ROWS {
                println!(
                    "{ev:<26} {t:>7.3} {:>9.3} {rate:>9.4} {hits:>5} {:>6} {:>10.4} {:>10.4} {balance:>+11.2e}",
                    deg(angle),
                    if f.slipping { "slip" } else { "stick" },
                    e.dissipated,
                    e.work
                );
            } else if printed == MAX_ROWS + 1 {
                println!("... (further events in the CSV)");
            }
        }
    }
    println!("wrote {}", csv.finish()?.display());
    let extremes = Extremes {
        hits: tracker.hits,
        events: printed,
        balance: worst,
        kinetic: max_kin,
        past,
    };
    report(&world, id, e0, &extremes)?;
    Ok(())
}

/// The door on its tilted hinge (frame I `axes`), with friction, the stops, the latch if any,
/// and the push as an `FJ` pulse.
fn door(o: &Opts, axes: Rotation) -> Result<(Mpc184World, JointId), Error> {
    let open = OPEN_STOP_DEG.to_radians();
    let hinge = Vector::new(0.0, 1.0, 0.0);
    let mut world = Mpc184World::new(WorldSettings::default());
    // The door's local axes are frame I's: x along the width, z along the height (the hinge
    // axis), y through the thickness; the centre of mass half a width out from the hinge line.
    let inertia = Vector::new(
        MASS * (HEIGHT * HEIGHT + THICKNESS * THICKNESS) / 12.0,
        MASS * (WIDTH * WIDTH + HEIGHT * HEIGHT) / 12.0,
        MASS * (WIDTH * WIDTH + THICKNESS * THICKNESS) / 12.0,
    );
    let door = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(hinge + axes * Vector::new(0.5 * WIDTH, 0.0, 0.0))
            .rotation(axes.to_scaled_axis())
            .additional_mass_properties(MassProperties::new(Vector::ZERO, MASS, inertia))
            .can_sleep(false),
    );
    let mut joint = Mpc184Joint::revolute(Axis::Z, hinge)
        .with_axes(axes)
        .with_friction(Friction::coulomb(
            o.mu,
            [Some(0.015), Some(0.008), Some(1.8)],
        ))
        .with_stop(Dof::RotZ, 0.0, open);
    if let Some(l) = o.latch {
        joint = joint.with_lock(Dof::RotZ, Real::NEG_INFINITY, l.to_radians());
    }
    let id = world.insert_joint(None, Some(door), joint)?;
    // The pulse: `push` until `pulse`, then nothing.
    world.set_load(
        id,
        Dof::RotZ,
        DriveProfile {
            t0: o.pulse,
            t1: o.pulse,
            from: o.push,
            to: 0.0,
            stepped: true,
            extend: false,
        },
    )?;
    Ok((world, id))
}

/// The events of the run: stop hits, stick/slip changes, the latch, the end of the pulse.
struct Tracker {
    hits: u32,
    was_at_stop: bool,
    was_slipping: bool,
    was_locked: bool,
    pulse_done: bool,
}

impl Tracker {
    /// The events of the step that ended at `t`.
    fn update(&mut self, t: Real, out: &JointOutput, pulse: Real, open: Real) -> Vec<String> {
        let angle = out.measure[5];
        let f = out.friction.unwrap_or_default();
        let mut events = Vec::new();
        if !self.pulse_done && t >= pulse {
            self.pulse_done = true;
            events.push("pulse ends".to_string());
        }
        // A lock's landing and hold count among `stops` too; once latched, the friction state
        // of the held DOF flips between stick and slip at zero rate (not reported as events).
        let locked = out.locks > 0;
        let at_stop = out.stops > 0 && !locked;
        if at_stop && !self.was_at_stop {
            self.hits += 1;
            let side = if angle > 0.5 * open { "wall" } else { "frame" };
            events.push(format!("hits the {side} stop"));
        }
        self.was_at_stop = at_stop;
        if f.slipping != self.was_slipping && !locked {
            events.push(if f.slipping { "slips" } else { "sticks" }.to_string());
            self.was_slipping = f.slipping;
        }
        if locked && !self.was_locked {
            events.push("latched (lock)".to_string());
        }
        self.was_locked = locked;
        events
    }
}

/// The CSV's columns.
const COLUMNS: [&str; 13] = [
    "t",
    "angle",
    "rate",
    "stops",
    "locks",
    "slipping",
    "friction",
    "normal",
    "kinetic",
    "potential",
    "dissipated",
    "work",
    "balance",
];

/// What the run saw: stop hits, events printed, the largest energy balance error (J) and
/// kinetic energy (J), the deepest excursion past a stop (rad).
struct Extremes {
    hits: u32,
    events: usize,
    balance: Real,
    kinetic: Real,
    past: Real,
}

/// The end of the run: the door's state and the energy balance.
fn report(world: &Mpc184World, id: JointId, e0: Real, x: &Extremes) -> Result<(), Error> {
    let deg = |x: Real| x.to_degrees();
    let e = world.energy();
    let out = *world.output(id)?;
    println!(
        "\nend: t {:.2} s, angle {:.4} deg, rate {:.2e} rad/s, {} stop hits, {} events, {}",
        world.time(),
        deg(out.measure[5]),
        out.angular_velocity.z,
        x.hits,
        x.events,
        if out.friction.is_some_and(|f| f.slipping) {
            "slipping"
        } else {
            "sticking"
        }
    );
    println!(
        "energy: work of FJ {:.4} J, dissipated {:.4} J, kinetic {:.3e} J, potential {:+.4} J (start {:+.4} J)",
        e.work,
        e.dissipated,
        e.kinetic,
        e.potential,
        e.potential + e.kinetic + e.dissipated - e.work - (e.total - e0)
    );
    println!(
        "balance (kinetic + potential + spring + dissipated - work, minus its start): end {:+.3e} J, largest {:.3e} J = {:.2e} of the work",
        e.total - e0,
        x.balance,
        x.balance / e.work.abs().max(Real::MIN_POSITIVE)
    );
    println!(
        "largest kinetic energy {:.4} J; deepest excursion past a stop {:.2e} rad",
        x.kinetic, x.past
    );
    Ok(())
}
