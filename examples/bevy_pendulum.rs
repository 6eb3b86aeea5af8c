//! `cargo run --release --example bevy_pendulum -- [--secs S] [--theta0 DEG]`
//!
//! The crate in a headless bevy `App` with one plugin line: `Mpc184PhysicsPlugin` on bevy's
//! fixed clock (`FixedUpdate` at dt = 1/60 s), `TimePlugin` for that clock with a frame time of
//! 1/60 s set by hand (`TimeUpdateStrategy::ManualDuration`, so the run is the same on any
//! machine; a real App gets it from the frame rate). A 1 kg bob on a 1 m hinge about Z is
//! spawned with a `Transform`; every 0.25 s the example prints the bob's `Transform` (written back
//! by the plugin), the hinge angle, the energy error over m g L and the hinge's reaction beside
//! the exact radial balance `m g cos(theta) + m L omega^2` of that state. The same App with `DefaultPlugins` and a camera renders it; that
//! build (bevy's renderer) is not part of this crate's CI.

#[path = "common/mod.rs"]
mod common;

use std::process::ExitCode;
use std::time::Duration;

use bevy_app::App;
use bevy_time::{TimePlugin, TimeUpdateStrategy};
use bevy_transform::components::Transform;
use rapier3d_mpc184::ecs::*;
use rapier3d_mpc184::prelude::*;

/// A pendulum in a headless bevy App (`Mpc184PhysicsPlugin`, `Transform` written back)
#[derive(clap::Parser)]
struct Opts {
    /// Simulated time, s
    #[arg(long, value_name = "S", value_parser = common::real, default_value = "3")]
    secs: Real,
    /// Release angle from the downward vertical, deg
    #[arg(long, value_name = "DEG", value_parser = common::any_real, default_value = "90")]
    theta0: Real,
}

const DT: Real = 1.0 / 60.0;

fn main() -> ExitCode {
    common::main("bevy_pendulum", common::parse("bevy_pendulum", &[]), run)
}

fn run(o: Opts) -> common::RunResult {
    let mut app = App::new();
    app.add_plugins((
        TimePlugin,
        Mpc184PhysicsPlugin {
            settings: WorldSettings {
                dt: DT,
                substeps: 4,
                ..Default::default()
            },
            ..Default::default()
        },
    ));
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
        DT as f64,
    )));
    let th0 = o.theta0.to_radians();
    let (s, c) = (th0.sin() as f32, th0.cos() as f32);
    let bob = app
        .world_mut()
        .spawn((
            Transform::from_xyz(s, -c, 0.0),
            Mpc184Body::dynamic(Vector::ZERO, 1.0, Vector::splat(1e-4)),
        ))
        .id();
    let hinge = app
        .world_mut()
        .spawn(Mpc184JointSpec {
            joint: Mpc184Joint::revolute(Axis::Z, Vector::ZERO),
            body1: None,
            body2: Some(bob),
        })
        .id();
    println!(
        "{:>6} {:>24} {:>10} {:>11} {:>9} {:>9}",
        "t s", "Transform.translation m", "theta deg", "dE/(mgL)", "|F| N", "exact N"
    );
    // bevy's first frame has a zero delta (its clock starts there): one frame more.
    let frames = common::steps(o.secs, DT) + 1;
    let mut next = 0.25;
    let mut e0 = None;
    for _ in 0..frames {
        app.update();
        let sim = app.world().resource::<Mpc184Sim>();
        if let Some(e) = &sim.last_error {
            return Err(format!("step failed: {e}").into());
        }
        let t = sim.world.time();
        let energy = sim.world.kinetic_energy() + sim.world.potential_energy();
        // The energy at release (the first frame does not step: its delta is 0).
        let e0 = *e0.get_or_insert(if t == 0.0 {
            energy
        } else {
            -(9.81 as Real) * th0.cos()
        });
        if t + 1e-9 >= next {
            next += 0.25;
            let tr = app.world().get::<Transform>(bob).ok_or("no Transform")?;
            let out = app
                .world()
                .get::<JointState>(hinge)
                .ok_or("no JointState")?
                .0;
            let theta = th0 + out.rotation.z;
            let exact = 9.81 * theta.cos() + out.angular_velocity.z.powi(2);
            println!(
                "{t:>6.2} {:>7.4} {:>7.4} {:>8.4} {:>10.3} {:>+11.2e} {:>9.4} {exact:>9.4}",
                tr.translation.x,
                tr.translation.y,
                tr.translation.z,
                theta.to_degrees(),
                (energy - e0) / 9.81,
                out.force.length()
            );
        }
    }
    Ok(())
}
