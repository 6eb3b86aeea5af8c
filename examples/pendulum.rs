//! `cargo run --release --example pendulum -- [--backend rapier-impulse|rapier-multibody] [--theta0 DEG] [--seconds S] [--csv FILE]`
//!
//! Headless revolute pendulum (1 kg bob, 1 m, grounded revolute z at the origin, dt = 1/60 s,
//! 4 substeps): prints every 0.5 s the joint angle, the energy error and the recovered rod
//! tension against the exact radial balance, and writes every step to a CSV file.

use std::io::Write;
use std::process::ExitCode;

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::scenes::{self, G};

const HELP: &str = "pendulum: a revolute pendulum on a Rapier backend, printed and written as CSV

OPTIONS:
    --backend NAME   rapier-impulse (default) or rapier-multibody
    --theta0 DEG     release angle from the downward vertical (default 90)
    --seconds S      simulated time (default 10)
    --csv FILE       CSV output (default out/pendulum.csv)
    --help           this text";

fn main() -> ExitCode {
    let mut backend = Backend::RapierImpulse;
    let (mut theta0_deg, mut seconds, mut csv): (Real, Real, String) =
        (90.0, 10.0, "out/pendulum.csv".into());
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = |name: &str| args.next().ok_or_else(|| format!("{name} needs a value"));
        let parsed: Result<(), String> = match a.as_str() {
            "--help" | "-h" => {
                println!("{HELP}");
                return ExitCode::SUCCESS;
            }
            "--backend" => value("--backend").and_then(|v| {
                backend = match v.as_str() {
                    "rapier-impulse" => Backend::RapierImpulse,
                    "rapier-multibody" => Backend::RapierMultibody,
                    other => return Err(format!("unknown backend `{other}`")),
                };
                Ok(())
            }),
            "--theta0" => value("--theta0").and_then(|v| {
                v.parse()
                    .map(|x| theta0_deg = x)
                    .map_err(|e| format!("--theta0: {e}"))
            }),
            "--seconds" => value("--seconds").and_then(|v| {
                v.parse()
                    .map(|x| seconds = x)
                    .map_err(|e| format!("--seconds: {e}"))
            }),
            "--csv" => value("--csv").map(|v| csv = v),
            other => Err(format!("unknown argument `{other}` (try --help)")),
        };
        if let Err(e) = parsed {
            eprintln!("pendulum: {e}");
            return ExitCode::from(2);
        }
    }
    match run(backend, theta0_deg.to_radians(), seconds, &csv) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("pendulum: {e}");
            ExitCode::from(3)
        }
    }
}

fn run(
    backend: Backend,
    theta0: Real,
    seconds: Real,
    csv: &str,
) -> Result<(), Box<dyn std::error::Error>> {
    let settings = WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        backend,
        ..Default::default()
    };
    let mut p = scenes::pendulum(settings, Axis::Z, 1.0, theta0, 1.0, 1e-4)?;
    if let Some(dir) = std::path::Path::new(csv).parent() {
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
    println!("wrote {csv}");
    Ok(())
}
