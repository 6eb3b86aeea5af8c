//! `cargo run --release --example a01_long -- [--secs S] [--target M] [--max-rate R]`
//!
//! IFToMM benchmark A01 (simple pendulum: 1 kg bob on 1 m, released horizontally, gravity
//! 9.81 m/s^2) over its full 2000 s, at the benchmark's high precision: the bob's position
//! within 1e-3 m of the exact motion at every output step (1/30 s). For each integrator of the
//! Lagrange backend (fourth, second and first order) the substep rate doubles from 60 /s until
//! the run stays within the target;
//! a run stops as soon as it leaves it. The exact motion is RK4 on
//! `I_p theta'' = -m g L sin(theta)` at 1/1920 s (its error over 2000 s is below 1e-8 m; the
//! bob carries 1e-4 kg m^2 of rotary inertia, included in `I_p`).
//!
//! Prints, per run: substeps per second, the largest error (or where it left the target), the
//! energy drift and the CPU time of the process (user + system from `/proc/self/stat`, so a
//! loaded machine does not inflate it; the wall time where that file is missing).

#[path = "common/mod.rs"]
mod common;

use std::process::ExitCode;
use std::time::Instant;

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::metrics::rk4_step;
use rapier3d_mpc184::studies::scenes::{self, G};

/// IFToMM A01 pendulum over 2000 s at high precision (1e-3 m)
#[derive(clap::Parser)]
struct Cli {
    /// Simulated time, s (the benchmark's 2000)
    #[arg(long, value_name = "S", value_parser = common::real, default_value = "2000")]
    secs: f64,
    /// Precision to reach, m
    #[arg(long, value_name = "M", value_parser = common::real, default_value = "1e-3")]
    target: f64,
    /// Largest substep rate tried, 1/s (at least 60)
    #[arg(long, value_name = "R", default_value = "30720", value_parser = clap::value_parser!(u32).range(60..))]
    max_rate: u32,
}

const OUTPUT: f64 = 1.0 / 30.0;
const INERTIA: f64 = 1e-4;

fn main() -> ExitCode {
    let Cli {
        secs: seconds,
        target,
        max_rate,
    } = common::parse("a01_long", &[]);
    println!(
        "IFToMM A01 pendulum, {seconds} s, target {target:.0e} m (bob position, every 1/30 s), \
         Lagrange backend, dt = 1/60 s"
    );
    println!(
        "{:<13} {:>10} {:>9} {:>13} {:>12} {:>13} {:>9}",
        "integrator", "substeps/s", "substeps", "max err m", "within to s", "energy drift", "CPU s"
    );
    for integrator in [
        Integrator::Composition4,
        Integrator::Rattle,
        Integrator::SymplecticEuler,
    ] {
        let mut rate = 60;
        loop {
            match run(integrator, rate, seconds, target) {
                Ok(r) => {
                    println!(
                        "{:<13} {:>10} {:>9} {:>13.3e} {:>12.1} {:>13.2e} {:>9.2}",
                        integrator.name(),
                        rate,
                        rate / 60,
                        r.max_err,
                        r.reached,
                        r.drift,
                        r.cpu
                    );
                    if r.reached >= seconds - 1e-9 {
                        println!(
                            "  -> {} reaches {target:.0e} m over {seconds} s at h = 1/{rate} s \
                             ({:.2} s CPU)",
                            integrator.name(),
                            r.cpu
                        );
                        break;
                    }
                }
                Err(e) => {
                    eprintln!("a01_long: {e}");
                    return ExitCode::from(3);
                }
            }
            rate *= 2;
            if rate > max_rate {
                println!(
                    "  -> {} did not reach {target:.0e} m by 1/{max_rate} s",
                    integrator.name()
                );
                break;
            }
        }
    }
    ExitCode::SUCCESS
}

struct Outcome {
    max_err: f64,
    /// Simulated time up to which the error stayed within the target (s).
    reached: f64,
    drift: f64,
    cpu: f64,
}

fn run(integrator: Integrator, rate: u32, seconds: f64, target: f64) -> Result<Outcome, Error> {
    let theta0 = std::f64::consts::FRAC_PI_2;
    let substeps = (rate / 60) as usize;
    let settings = WorldSettings {
        dt: 1.0 / 60.0,
        substeps,
        integrator,
        ..WorldSettings::default()
    };
    let mut p = scenes::pendulum(settings, Axis::Z, 1.0, theta0 as Real, 1.0, INERTIA as Real)?;
    let e0 = (p.world.kinetic_energy() + p.world.potential_energy()) as f64;
    let scale = (p.mass * G * p.length) as f64;
    // Exact motion by RK4 on theta'' = -w2 sin(theta), 64 steps per output.
    let w2 = G as f64 / (1.0 + INERTIA);
    let f = |t: f64| -w2 * t.sin();
    let (mut th, mut om) = (theta0, 0.0f64);
    let hr = OUTPUT / 64.0;
    let outputs = (seconds / OUTPUT).round() as usize;
    let (mut max_err, mut reached) = (0.0f64, seconds);
    let mut drift = 0.0;
    let (wall0, cpu0) = (Instant::now(), process_cpu());
    let bar = common::progress(outputs, "outputs");
    bar.set_message(format!("{} at 1/{rate} s", integrator.name()));
    for k in 1..=outputs {
        if k % 300 == 0 {
            bar.set_position(k as u64);
        }
        p.world.step()?;
        p.world.step()?;
        for _ in 0..64 {
            (th, om) = rk4_step(f, th, om, hr);
        }
        let x = p.world.physics.bodies[p.bob].translation();
        let err = (x.x as f64 - th.sin())
            .abs()
            .max((x.y as f64 + th.cos()).abs());
        max_err = max_err.max(err);
        drift = ((p.world.kinetic_energy() + p.world.potential_energy()) as f64 - e0) / scale;
        if err > target {
            reached = (k - 1) as f64 * OUTPUT;
            break;
        }
    }
    bar.finish_and_clear();
    // The reference RK4 costs about a tenth of the stepping; it is included.
    let cpu = match (cpu0, process_cpu()) {
        (Some(a), Some(b)) => b - a,
        _ => wall0.elapsed().as_secs_f64(),
    };
    Ok(Outcome {
        max_err,
        reached,
        drift,
        cpu,
    })
}

/// User + system CPU time of this process (s), from `/proc/self/stat` (Linux; clock ticks of
/// 1/100 s, the kernel's fixed `USER_HZ`).
fn process_cpu() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which is in parentheses and may hold spaces).
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = f.get(11)?.parse().ok()?;
    let stime: f64 = f.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}
