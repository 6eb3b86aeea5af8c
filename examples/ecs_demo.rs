//! `cargo run --release --example ecs_demo -- [--frames N] [--despawn-at FRAME] [--every N] [--backend NAME] [--out DIR]`
//!
//! Scene, as `bevy_ecs` entities driven by `Mpc184Plugin` (a bare `World` + `Schedule`, one
//! `schedule.run` per frame of 1/60 s, 4 substeps, gravity -Y): a pendulum (1 kg bob with
//! inertia 1e-4 kg m^2, 1 m, grounded revolute z at the origin, released at rest at 60 deg) and,
//! 2 m behind it, a two-link chain (0.5 m links, 0.5 kg beads with inertia 5e-5 kg m^2,
//! released straight at 45 deg). At frame `--despawn-at` the entity of the chain's second joint
//! is despawned: the plugin removes the joint, the first link swings on as a simple pendulum and
//! the second bead flies free.
//!
//! Expected: the pendulum's `JointState` reaction is the rod tension, `m g cos(theta) + m L
//! theta'^2` of its state (printed side by side, within O(h)); the despawned joint's entity is
//! gone and no error is raised; the freed bead falls with g: its vertical velocity changes by
//! `-g t` after the despawn (printed against the simulation).
//!
//! CSV (`out/ecs_demo/ecs_demo.csv`): one row per frame (the despawned joint's columns NaN after).

#[path = "common/mod.rs"]
mod common;

use std::process::ExitCode;

use bevy_ecs::prelude::*;
use common::{Csv, RunResult};
use rapier3d_mpc184::ecs::*;
use rapier3d_mpc184::math::PI;
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::scenes::G;

/// A pendulum and a two-link chain as `bevy_ecs` entities (`Mpc184Plugin`)
#[derive(clap::Parser)]
struct Cli {
    /// Frames of 1/60 s
    #[arg(long, value_name = "N", value_parser = common::count, default_value = "240")]
    frames: usize,
    /// Frame at which the chain's second joint is despawned [default: frames/2]
    #[arg(long, value_name = "F", value_parser = common::count)]
    despawn_at: Option<usize>,
    /// Print every N frames
    #[arg(long, value_name = "N", value_parser = common::count, default_value = "20")]
    every: usize,
    /// Backend: lagrange, rapier-impulse or rapier-multibody
    #[arg(long, value_name = "NAME", value_parser = common::backends, default_value = "lagrange")]
    backend: common::Backends,
    /// CSV directory
    #[arg(long, value_name = "DIR")]
    out: std::path::PathBuf,
}

struct Opts {
    frames: usize,
    despawn_at: usize,
    every: usize,
    backend: Backend,
    out: std::path::PathBuf,
}

fn main() -> ExitCode {
    let cli: Cli = common::parse("ecs_demo", &[]);
    let backend = match cli.backend.0.as_slice() {
        [b] => *b,
        _ => common::usage_error("--backend: one backend (not all)"),
    };
    if cli.frames < 2 {
        common::usage_error("--frames: at least 2");
    }
    let o = Opts {
        frames: cli.frames,
        despawn_at: cli.despawn_at.unwrap_or(cli.frames / 2),
        every: cli.every,
        backend,
        out: cli.out,
    };
    common::main("ecs_demo", o, run)
}

fn hinge(world: &mut World, at: Vector, body1: Option<Entity>, body2: Entity) -> Entity {
    world
        .spawn(Mpc184JointSpec {
            joint: Mpc184Joint::revolute(Axis::Z, at),
            body1,
            body2: Some(body2),
        })
        .id()
}

fn run(o: Opts) -> RunResult {
    let settings = WorldSettings {
        backend: o.backend,
        ..Default::default()
    };
    let mut world = World::new();
    let mut schedule = Schedule::default();
    Mpc184Plugin {
        settings,
        gravity: Vector::new(0.0, -G, 0.0),
    }
    .add_to(&mut world, &mut schedule);

    let Scene {
        pend,
        link1,
        link2,
        bead2,
    } = spawn_scene(&mut world);
    let (m, l, th0) = (PENDULUM_MASS, PENDULUM_LENGTH, PENDULUM_START);
    let mut csv = Csv::create(&o.out, "ecs_demo.csv", &COLUMNS)?;
    println!(
        "{} backend: pendulum + two-link chain as entities; chain joint 2 despawned at frame {}",
        o.backend.name(),
        o.despawn_at
    );
    println!(
        "{:>5} {:>6} {:>10} {:>9} {:>9} {:>10} {:>9} {:>10} {:>9} {:>9}",
        "frame",
        "t s",
        "pend rotz",
        "T N",
        "T exact",
        "link1 rotz",
        "F1 N",
        "link2 rotz",
        "F2 N",
        "bead2 vy"
    );
    let mut freed: Option<(Real, Real)> = None;
    let (mut t, mut vy) = (0.0, 0.0);
    for frame in 1..=o.frames {
        if frame == o.despawn_at {
            world.despawn(link2);
        }
        schedule.run(&mut world);
        let sim = world.resource::<Mpc184Sim>();
        if let Some(e) = &sim.last_error {
            return Err(format!("frame {frame}: {e}").into());
        }
        t = sim.world.time();
        let joint = |e: Entity| world.get::<JointState>(e).map(|s| s.0);
        let p = joint(pend).ok_or("the pendulum joint has no state")?;
        let c1 = joint(link1).ok_or("the first chain joint has no state")?;
        let c2 = joint(link2);
        let (rot2, f2) = c2.map_or((Real::NAN, Real::NAN), |s| (s.rotation.z, s.force.length()));
        // Radial balance of the bob: T = m g cos(theta) + m L theta'^2.
        let th = th0 + p.rotation.z;
        let exact = m * G * th.cos() + m * l * p.angular_velocity.z.powi(2);
        vy = world
            .get::<BodyState>(bead2)
            .map_or(Real::NAN, |s| s.linvel.y);
        if c2.is_none() && freed.is_none() {
            freed = Some((t, vy));
        }
        let (fp, f1) = (p.force.length(), c1.force.length());
        let row = [
            frame as Real,
            t,
            p.rotation.z,
            fp,
            exact,
            c1.rotation.z,
            f1,
            rot2,
            f2,
            vy,
        ];
        csv.row(&row)?;
        if frame % o.every == 0 || frame == o.despawn_at {
            println!(
                "{frame:>5} {t:>6.3} {:>10.4} {fp:>9.4} {exact:>9.4} {:>10.4} {f1:>9.4} {rot2:>10.4} {f2:>9.4} {vy:>9.4}",
                p.rotation.z, c1.rotation.z
            );
        }
    }
    println!("wrote {}", csv.finish()?.display());
    let sim = world.resource::<Mpc184Sim>();
    println!(
        "joints in the simulation: {} (3 spawned, 1 despawned); chain joint 2 entity alive: {}",
        sim.world.joint_ids().count(),
        world.get_entity(link2).is_ok()
    );
    if let Some((t1, vy1)) = freed {
        println!(
            "freed bead 2: vy changed by {:+.6} m/s over {:.4} s, free fall -g t = {:+.6} m/s",
            vy - vy1,
            t - t1,
            -G * (t - t1)
        );
    }
    Ok(())
}

/// The pendulum bob (kg), its distance from the pivot (m) and starting angle from the vertical
/// (rad).
const PENDULUM_MASS: Real = 1.0;
const PENDULUM_LENGTH: Real = 1.0;
const PENDULUM_START: Real = PI / 3.0;

/// The CSV's columns.
const COLUMNS: [&str; 10] = [
    "frame",
    "t",
    "pend_rotz",
    "pend_force",
    "pend_force_exact",
    "link1_rotz",
    "link1_force",
    "link2_rotz",
    "link2_force",
    "bead2_vy",
];

/// The entities the demo reads.
struct Scene {
    pend: Entity,
    link1: Entity,
    link2: Entity,
    bead2: Entity,
}

/// Spawns the pendulum and, 2 m behind (+Z), the two-link chain.
fn spawn_scene(world: &mut World) -> Scene {
    // The pendulum.
    let (m, l, th0) = (PENDULUM_MASS, PENDULUM_LENGTH, PENDULUM_START);
    let bob = world
        .spawn(Mpc184Body::dynamic(
            Vector::new(l * th0.sin(), -l * th0.cos(), 0.0),
            m,
            Vector::splat(1e-4),
        ))
        .id();
    let pend = hinge(world, Vector::ZERO, None, bob);
    // The two-link chain, 2 m behind (+Z).
    let (mc, lc, a0) = (0.5 as Real, 0.5 as Real, PI / 4.0);
    let base = Vector::new(0.0, 0.0, 2.0);
    let dir = Vector::new(a0.sin(), -a0.cos(), 0.0);
    let bead = |k: Real| Mpc184Body::dynamic(base + dir * (k * lc), mc, Vector::splat(mc * 1e-4));
    let bead1 = world.spawn(bead(1.0)).id();
    let bead2 = world.spawn(bead(2.0)).id();
    let link1 = hinge(world, base, None, bead1);
    let link2 = hinge(world, base + dir * lc, Some(bead1), bead2);

    Scene {
        pend,
        link1,
        link2,
        bead2,
    }
}
