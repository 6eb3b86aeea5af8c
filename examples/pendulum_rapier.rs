//! `cargo run --release --example pendulum_rapier -- [--backend NAME] [--theta0 DEG] [--secs S] [--out DIR]`
//!
//! Headless revolute pendulum (1 kg bob, 1 m, grounded revolute z at the origin, dt = 1/60 s,
//! 4 substeps): prints every 0.5 s the joint angle, the energy error and the recovered rod
//! tension against the exact radial balance, and writes every step to a CSV file.

#[path = "common/mod.rs"]
mod common;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::scenes::{self, G};

/// A revolute pendulum on one backend, printed and written as CSV
#[derive(clap::Parser)]
struct Opts {
    /// Backend: rapier-impulse, rapier-multibody or lagrange
    #[arg(long, value_name = "NAME", value_parser = common::backends, default_value = "rapier-impulse")]
    backend: common::Backends,
    /// Release angle from the downward vertical, deg
    #[arg(long, value_name = "DEG", value_parser = common::any_real, default_value = "90")]
    theta0: Real,
    /// Simulated time, s
    #[arg(long, value_name = "S", value_parser = common::real, default_value = "10")]
    secs: Real,
    /// CSV directory (writes pendulum.csv there)
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
}

fn main() -> ExitCode {
    let o: Opts = common::parse("pendulum_rapier", &[]);
    let backend = match o.backend.0.as_slice() {
        [b] => *b,
        _ => common::usage_error("--backend: one backend (not all)"),
    };
    common::main("pendulum_rapier", o, |o| {
        run(
            backend,
            o.theta0.to_radians(),
            o.secs,
            &o.out.join("pendulum.csv"),
        )
    })
}

fn run(backend: Backend, theta0: Real, seconds: Real, csv: &Path) -> common::RunResult {
    let settings = WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        backend,
        ..Default::default()
    };
    let mut p = scenes::pendulum(settings, Axis::Z, 1.0, theta0, 1.0, 1e-4)?;
    if let Some(dir) = csv.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let mut out = std::io::BufWriter::new(std::fs::File::create(csv)?);
    writeln!(out, "time,rotz,omgz,energy_err,tension,tension_exact,gap")?;
    let e0 = p.world.kinetic_energy() + p.world.potential_energy();
    println!(
        "{} backend, theta0 = {:.1} deg",
        backend.name(),
        theta0.to_degrees()
    );
    println!(
        "{:>6} {:>10} {:>12} {:>10} {:>10} {:>9}",
        "t s", "theta deg", "dE/(mgL)", "T N", "T exact", "gap m"
    );
    let steps = (seconds / settings.dt).round() as usize;
    for i in 1..=steps {
        p.world.step()?;
        let o = *p.world.output(p.joint)?;
        let theta = theta0 + o.rotation.z;
        let de =
            (p.world.kinetic_energy() + p.world.potential_energy() - e0) / (p.mass * G * p.length);
        // Radial balance of the bob at this state: T = m g cos(theta) + m L thetadot^2.
        let exact = p.mass * G * theta.cos() + p.mass * p.length * o.angular_velocity.z.powi(2);
        let t = p.world.time();
        writeln!(
            out,
            "{t},{},{},{de},{},{exact},{}",
            o.rotation.z,
            o.angular_velocity.z,
            o.force.length(),
            o.gap
        )?;
        if i % 30 == 0 {
            println!(
                "{t:>6.2} {:>10.3} {de:>+12.3e} {:>10.4} {exact:>10.4} {:>9.1e}",
                theta.to_degrees(),
                o.force.length(),
                o.gap
            );
        }
    }
    out.flush()?;
    println!("wrote {}", csv.display());
    Ok(())
}
