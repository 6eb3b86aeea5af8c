//! `cargo run --release --example step_schedule -- [--integrator second-order|first-order]`
//!
//! Why the adaptive step control cannot beat a uniform step on the spatial slider-crank
//! (`benchmarks::slider_crank_idle_removed`, the chart study's scene, 5 s): its error is a
//! cancellation between stretches.
//!
//! The adaptive control (`StepControl::Adaptive`, step doubling, RATTLE, 1e-2 m asked over the
//! step alone) marks the 1/30 s steps where it needs 40 or more substeps: the crank's fast
//! passages through its dead points, twice a turn (up to 26 rad/s against 5.5 between them; 49
//! of the 150 steps). This example then runs fixed schedules, `easy` substeps per 1/30 s on
//! the other steps and `hard` on the marked ones, and prints the slider's largest distance from
//! the reference (the fourth-order composition at 1/30 s x 128, within about 1e-7 m of the
//! chart study's reference), its signed distance along the slide at 5 s, and the largest
//! energy error over the energy scale.
//!
//! Measured (RATTLE, 2026-11-26):
//!
//! | easy | hard | largest error (m) | error along X at 5 s (m) | energy / scale |
//! |---|---|---|---|---|
//! | 8 | 8 | 1.79e-3 | -1.57e-3 | 4.0e-3 |
//! | 8 | 32 | 5.52e-3 | +5.01e-3 | 2.6e-3 |
//! | 32 | 8 | 1.24e-2 | -1.07e-2 | 7.1e-3 |
//! | 16 | 16 | 4.10e-4 | -3.62e-4 | 1.0e-3 |
//! | 16 | 32 | 1.22e-3 | +1.09e-3 | 8.7e-4 |
//! | 32 | 16 | 1.90e-3 | -1.68e-3 | 8.2e-4 |
//! | 32 | 32 | 1.00e-4 | -8.86e-5 | 2.6e-4 |
//!
//! The fast passages put the slider behind (their coarse steps alone: -1.07e-2 m), the slow
//! stretches ahead (+5.01e-3 m); a uniform step keeps both, and they cancel (-1.57e-3 m).
//! Refining only where the local error is largest, as any error-per-step control does, takes
//! one side of the cancellation away: 8 substeps with 32 in the passages is three times worse
//! than 8 everywhere, although its energy error is smaller. Symplectic Euler
//! (`--integrator first-order`) is worse
//! still with a changing step (8 with 32 in the passages: 5.2e-2 m against 1.8e-3 uniform; its
//! velocities live at half steps, so a change of step is itself a first-order error).
//!
//! Each schedule runs `n` steps of one substep for a 1/30 s step of `n` substeps: within 1 % of
//! one step of `n` substeps (uniform 8: 1.79e-3 m against 1.78e-3).

#[path = "common/mod.rs"]
mod common;

use std::process::ExitCode;

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks::{self, Benchmark};

/// Fixed step schedules on the spatial slider-crank: refining only the steps the adaptive
/// control refines
#[derive(clap::Parser)]
struct Cli {
    /// The scheme of the fixed schedules
    #[arg(long, value_enum, default_value = "second-order")]
    integrator: Scheme,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum Scheme {
    SecondOrder,
    FirstOrder,
}

const DT: Real = 1.0 / 30.0;
const SECS: Real = 5.0;

fn scene(integrator: Integrator, dt: Real, substeps: usize) -> Result<Benchmark, Error> {
    benchmarks::slider_crank_idle_removed(WorldSettings {
        dt,
        substeps,
        integrator,
        backend: Backend::Lagrange,
        ..Default::default()
    })
}

fn main() -> ExitCode {
    let cli: Cli = common::parse("step_schedule", &[]);
    let integrator = match cli.integrator {
        Scheme::SecondOrder => Integrator::Rattle,
        Scheme::FirstOrder => Integrator::SymplecticEuler,
    };
    match run(integrator) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("step_schedule: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(integrator: Integrator) -> Result<(), Error> {
    let steps = (SECS / DT).round() as usize;
    let mut reference = scene(Integrator::Composition4, DT, 128)?;
    let mut probe = Vec::with_capacity(steps);
    for _ in 0..steps {
        reference.world.step()?;
        probe.push(reference.probe_position());
    }
    // The steps the adaptive control refines.
    let mut adaptive = scene(Integrator::Rattle, DT, 1)?;
    adaptive.world.set_step_control(StepControl::Adaptive {
        tolerance: 1e-2 * DT / SECS,
        energy_tolerance: Real::INFINITY,
        max_substeps: 4096,
        horizon: 0.0,
        extrapolate: false,
    })?;
    let mut hard = Vec::with_capacity(steps);
    let mut before = 0;
    for _ in 0..steps {
        adaptive.world.step()?;
        let now = adaptive.world.step_stats().substeps;
        hard.push(now - before >= 40);
        before = now;
    }
    let marked = hard.iter().filter(|h| **h).count();
    println!(
        "{}: the adaptive control refines {marked} of the {steps} steps of 1/30 s",
        integrator.name()
    );
    println!("| easy | hard | largest error (m) | error along X at 5 s (m) | energy / scale |");
    println!("|---|---|---|---|---|");
    for (easy, fast) in [
        (8, 8),
        (8, 32),
        (32, 8),
        (16, 16),
        (16, 32),
        (32, 16),
        (32, 32),
    ] {
        let mut run = scene(integrator, DT / easy as Real, 1)?;
        let e0 = run.energy();
        let (mut largest, mut energy): (Real, Real) = (0.0, 0.0);
        for (k, &is_hard) in hard.iter().enumerate() {
            let n = if is_hard { fast } else { easy };
            run.world.set_dt(DT / n as Real);
            for _ in 0..n {
                run.world.step()?;
            }
            largest = largest.max((run.probe_position() - probe[k]).length());
            energy = energy.max((run.energy() - e0).abs() / run.energy_scale);
        }
        let along = (run.probe_position() - probe[steps - 1]).x;
        println!("| {easy} | {fast} | {largest:.2e} | {along:+.2e} | {energy:.1e} |");
    }
    Ok(())
}
