//! `cargo run --release --example joint_bench -- [--quick] [--model] [--cost]`
//!
//! The Lagrange backend side by side with Rapier's impulse and multibody joints on the scenes of
//! the solver issue (single thread, f64): the 90 deg pendulum, revolute chains of 10, 100 and
//! 1000 links with end-mass ratios 1:1 and 1:1000, the Bricard mechanism (IFToMM A04) and the
//! parallelogram four-bar (IFToMM A02, one window), and what parts of a scene that do nothing
//! cost (inactive stops, a sleeping island). Prints a table per scene; `--quick` skips the
//! 1000-link chains of the accuracy table and the multibody column of the cost table.
//!
//! The last table is the cost of every backend beside Rapier alone on the performance issue's
//! scenes ([`cost`]); the last line printed is `ratio_vs_rapier_max=<x>`, the largest
//! Lagrange / Rapier-alone ratio over those scenes. `--cost` prints only that table.

#[path = "../common/mod.rs"]
mod common;
mod cost;

use std::time::Instant;

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks::{self, Benchmark};
use rapier3d_mpc184::studies::metrics::pendulum_study_with;

const BACKENDS: [Backend; 3] = [
    Backend::Lagrange,
    Backend::RapierImpulse,
    Backend::RapierMultibody,
];

/// Lagrange backend vs Rapier impulse and multibody joints, and Rapier alone
#[derive(clap::Parser)]
struct Cli {
    /// Skip the 1000-link chains of the accuracy table and the multibody cost column
    #[arg(long)]
    quick: bool,
    /// Only the section on inactive stops and sleeping islands
    #[arg(long)]
    model: bool,
    /// Only the cost table (every backend beside Rapier alone)
    #[arg(long)]
    cost: bool,
}

fn main() {
    let Cli { quick, model, cost } = common::parse("joint_bench", &[]);
    if model {
        model_cost();
        return;
    }
    if cost {
        let worst = cost::cost_table(quick);
        println!("ratio_vs_rapier_max={worst:.2}");
        return;
    }
    pendulum();
    penalty();
    chains(quick);
    model_cost();
    let settings = |backend| WorldSettings {
        dt: 1.0 / 100.0,
        substeps: 4,
        backend,
        ..Default::default()
    };
    mechanism(
        "Bricard (A04), dt 1/100, 4 substeps, 10 s",
        |b| benchmarks::bricard(settings(b)),
        10.0,
    );
    let settings60 = |backend| WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        backend,
        ..Default::default()
    };
    mechanism(
        "parallelogram four-bar (A02, one window), dt 1/60, 4 substeps, 10 s",
        |b| benchmarks::four_bar_parallelogram(settings60(b)),
        10.0,
    );
    let worst = cost::cost_table(quick);
    println!("ratio_vs_rapier_max={worst:.2}");
}

fn pendulum() {
    println!(
        "\n## pendulum 1 m, 90 deg, 20 s, dt 1/60, 4 substeps (drift and oscillation / m g L)"
    );
    println!(
        "{:<30} {:>10} {:>11} {:>10} {:>10} {:>10} {:>9}",
        "backend", "T err", "drift", "osc", "tension", "gap m", "us/step"
    );
    let runs = BACKENDS
        .iter()
        .map(|b| (*b, Integrator::SymplecticEuler, 4))
        .chain([
            (Backend::Lagrange, Integrator::Rattle, 4),
            (Backend::Lagrange, Integrator::Rattle, 24),
        ]);
    for (backend, integrator, substeps) in runs {
        let name = if backend == Backend::Lagrange {
            format!("{} {} x{substeps}", backend.name(), integrator.name())
        } else {
            backend.name().to_string()
        };
        match pendulum_study_with(
            backend,
            integrator,
            Axis::Z,
            90f64.to_radians() as Real,
            1.0 / 60.0,
            substeps,
            20.0,
        ) {
            Ok(r) => println!(
                "{:<30} {:>10.2e} {:>+11.2e} {:>10.2e} {:>10.2e} {:>10.1e} {:>9.2}",
                name, r.period_err, r.drift, r.oscillation, r.tension_err, r.max_gap, r.us_per_step
            ),
            Err(e) => println!("{name:<30} {e}"),
        }
    }
}

/// The penalty method on the 90 deg pendulum (1 kg, 1 m, 5 s, dt 1/60, 4 substeps): the pivot
/// gap is the elastic deflection under the joint force, so gap * k must stay constant as k grows,
/// and no k may be unstable (the compliance is implicit).
fn penalty() {
    use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
    println!("\n## penalty (KEYOPT(2)=1) pendulum 1 m, 90 deg, 5 s, dt 1/60, 4 substeps");
    println!(
        "{:<18} {:>10} {:>11} {:>12} {:>11} {:>9}",
        "method", "k", "gap m", "gap*k", "E err", "us/step"
    );
    let ks: [Option<Real>; 8] = [
        Some(1e4),
        Some(1e5),
        Some(1e6),
        Some(1e7),
        Some(1e8),
        Some(1e9),
        Some(1e10),
        None,
    ];
    for k in ks {
        let method = match k {
            Some(k) => ConstraintMethod::Penalty { disp: -k, rot: -k },
            None => ConstraintMethod::Lagrange,
        };
        let mut world = Mpc184World::new(WorldSettings::default());
        let bob = world.physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .translation(Vector::new(1.0, 0.0, 0.0))
                .additional_mass_properties(MassProperties::new(
                    Vector::ZERO,
                    1.0,
                    Vector::splat(1e-4),
                ))
                .can_sleep(false),
        );
        let hinge = Mpc184Joint::revolute(Axis::Z, Vector::ZERO).with_method(method);
        let id = match world.insert_joint(None, Some(bob), hinge) {
            Ok(id) => id,
            Err(e) => {
                println!("{:<18} {e}", "penalty");
                continue;
            }
        };
        let e0 = world.kinetic_energy() + world.potential_energy();
        let (mut gap, mut e_err): (Real, Real) = (0.0, 0.0);
        let t0 = Instant::now();
        let mut status = String::new();
        for _ in 0..300 {
            if let Err(e) = world.step() {
                status = format!(" failed: {e}");
                break;
            }
            gap = gap.max(world.output(id).map_or(Real::NAN, |o| o.gap));
            let e = world.kinetic_energy() + world.potential_energy();
            e_err = e_err.max((e - e0).abs() / 9.81);
        }
        let us = t0.elapsed().as_secs_f64() * 1e6 / 300.0;
        let (name, kk) = match k {
            Some(k) => ("penalty", format!("{k:.0e}")),
            None => ("lagrange", "-".to_string()),
        };
        println!(
            "{:<18} {:>10} {:>11.3e} {:>12} {:>11.2e} {:>9.2}{status}",
            name,
            kk,
            gap,
            k.map_or("-".to_string(), |k| format!("{:.4e}", gap * k)),
            e_err,
            us
        );
    }
}

/// Runs a scene for `secs`, returning (max gap, secular drift, us per step, status). The drift
/// is the mean energy over the last 30 % of the run minus that over the first 30 %, / scale:
/// windows long enough to average out the first-order scheme's bounded O(h) oscillation, which
/// a one-second window does not (on the 100-link chain the one-second figure halves with every
/// halving of h, the three-second one is 7x smaller).
fn run(
    b: &mut Benchmark,
    secs: Real,
    mut each: impl FnMut(&Benchmark),
) -> (Real, Real, Real, String) {
    let dt = b.world.settings().dt;
    let steps = (secs / dt).round() as usize;
    let window = ((0.3 * secs / dt).round() as usize).max(1);
    let (mut gap, mut energies) = (0.0 as Real, Vec::with_capacity(steps));
    let mut busy = 0.0;
    let mut status = "ok".to_string();
    for s in 0..steps {
        let t0 = Instant::now();
        let r = b.world.step();
        busy += t0.elapsed().as_secs_f64();
        if let Err(e) = r {
            status = format!("failed at step {s}: {e}");
            break;
        }
        let g = b.max_gap().unwrap_or(Real::NAN);
        gap = gap.max(g);
        energies.push(b.energy());
        each(b);
        if !g.is_finite()
            || g > 10.0
            || (b.energy() - b.initial_energy).abs() > 100.0 * b.energy_scale
        {
            status = format!("blew up at t = {:.2} s", b.world.time());
            break;
        }
        if g > 0.1 && status == "ok" {
            status = format!("gap past 0.1 m at t = {:.2} s", b.world.time());
        }
    }
    let n = energies.len();
    let drift = if n == steps && n >= 2 * window {
        let first: Real = energies[..window].iter().sum::<Real>() / window as Real;
        let last: Real = energies[n - window..].iter().sum::<Real>() / window as Real;
        (last - first) / b.energy_scale
    } else {
        Real::NAN
    };
    (gap, drift, (busy * 1e6 / n.max(1) as f64) as Real, status)
}

fn chains(quick: bool) {
    println!(
        "\n## revolute chains, 0.1 m links of 0.01 kg, released at 20 deg, 10 s, dt 1/60, 4 substeps"
    );
    println!(
        "(drift: mean energy over the last 30 % of the run minus the first 30 %, / potential drop to the vertical)"
    );
    println!(
        "{:<18} {:>5} {:>6} {:>10} {:>11} {:>10}  status",
        "backend", "N", "ratio", "gap m", "drift", "us/step"
    );
    let sizes: &[usize] = if quick { &[10, 100] } else { &[10, 100, 1000] };
    for &n in sizes {
        for ratio in [1.0, 1000.0] {
            for backend in BACKENDS {
                // Multibody chains cost ~N^2 (exponent 2.1): skip them beyond 100 links.
                if backend == Backend::RapierMultibody && n > 100 {
                    continue;
                }
                let settings = WorldSettings {
                    dt: 1.0 / 60.0,
                    substeps: 4,
                    backend,
                    ..Default::default()
                };
                let secs = if n >= 1000 { 2.0 } else { 10.0 };
                match benchmarks::chain(settings, n, 0.1, 0.01, ratio, 20f64.to_radians() as Real) {
                    Ok(mut b) => {
                        let (gap, drift, us, status) = run(&mut b, secs, |_| {});
                        println!(
                            "{:<18} {n:>5} {ratio:>6} {gap:>10.1e} {drift:>+11.2e} {us:>10.1}  {status} ({secs} s)",
                            backend.name()
                        );
                    }
                    Err(e) => println!("{:<18} {n:>5} {ratio:>6} {e}", backend.name()),
                }
            }
            // Rapier's own cost for the same chain: impulse joints, its internal 4 substeps in one
            // call, no reaction recovery (the bar the Lagrange backend's cost is compared with).
            let settings = WorldSettings {
                dt: 1.0 / 60.0,
                substeps: 4,
                backend: Backend::RapierImpulse,
                ..Default::default()
            };
            if let Ok(mut b) =
                benchmarks::chain(settings, n, 0.1, 0.01, ratio, 20f64.to_radians() as Real)
            {
                benchmarks::rapier_alone(&mut b.world);
                let steps = 60;
                let t0 = Instant::now();
                for _ in 0..steps {
                    b.world.physics.step();
                }
                let us = t0.elapsed().as_secs_f64() * 1e6 / steps as f64;
                println!(
                    "{:<18} {n:>5} {ratio:>6} {:>10} {:>11} {us:>10.1}  Rapier alone, 1 s",
                    "rapier-raw", "-", "-"
                );
            }
        }
    }
}

fn mechanism(title: &str, build: impl Fn(Backend) -> Result<Benchmark, Error>, secs: Real) {
    println!("\n## {title}");
    println!(
        "{:<18} {:>10} {:>11} {:>10} {:>12} {:>12}  status",
        "backend", "gap m", "drift", "us/step", "last speed", "body-2 turn"
    );
    for backend in BACKENDS {
        match build(backend) {
            Ok(mut b) => {
                let second = b.bodies[1];
                let r0 = b.world.physics.bodies[second].rotation().to_owned();
                let mut turn: Real = 0.0;
                let (gap, drift, us, status) = run(&mut b, secs, |b| {
                    let r = b.world.physics.bodies[second].rotation();
                    turn = turn.max((r0.inverse() * *r).to_axis_angle().1.abs());
                });
                let speed = b.probe_velocity().length();
                println!(
                    "{:<18} {gap:>10.1e} {drift:>+11.2e} {us:>10.1} {speed:>12.3e} {turn:>12.2e}  {status}",
                    backend.name()
                );
            }
            Err(e) => println!("{:<18} {e}", backend.name()),
        }
    }
}

/// "Model no more than a scene needs": the per-step cost of the 100-link chain (Lagrange, ratio
/// 1, released at 20 deg) as built, with an inactive stop on every joint (limits at +-10 rad,
/// never reached), and with a second 100-link chain hanging at rest beside it whose bodies may
/// sleep (`can_sleep(true)`), against the same second chain kept awake. Each case runs 3 s
/// untimed (time for Rapier to put the resting island to sleep), then three 1 s windows are
/// timed and the fastest is kept (the machine's noise is +-30 %). Measured only: the solver is
/// not changed here.
fn model_cost() {
    println!(
        "\n## model no more than a scene needs: 100-link chain, Lagrange, dt 1/60, 4 substeps (best of three 1 s windows after 3 s)"
    );
    println!(
        "{:<44} {:>10} {:>8} {:>14}",
        "case", "us/step", "ratio", "asleep bodies"
    );
    let cases: [(&str, bool, Option<bool>); 4] = [
        ("chain as built", false, None),
        ("+ inactive stop on every joint (+-10 rad)", true, None),
        (
            "+ resting 100-link chain, can_sleep(true)",
            false,
            Some(true),
        ),
        ("+ resting 100-link chain, kept awake", false, Some(false)),
    ];
    let mut base = None;
    for (name, stops, resting) in cases {
        let mut b = match benchmarks::idle_chain(
            WorldSettings {
                dt: 1.0 / 60.0,
                substeps: 4,
                backend: Backend::Lagrange,
                ..Default::default()
            },
            stops,
            resting,
        ) {
            Ok(b) => b,
            Err(e) => {
                println!("{name:<44} {e}");
                continue;
            }
        };
        let best = match time_case(&mut b) {
            Ok(best) => best,
            Err(e) => {
                println!("{name:<44} failed: {e}");
                continue;
            }
        };
        let asleep = b
            .world
            .physics
            .bodies
            .iter()
            .filter(|(_, rb)| rb.is_sleeping())
            .count();
        let base_us = *base.get_or_insert(best);
        let gap = b.max_gap().unwrap_or(Real::NAN);
        println!(
            "{name:<44} {best:>10.1} {:>8.3} {asleep:>14}  (gap {gap:.1e} m)",
            best / base_us
        );
    }
}

/// 3 s untimed, then the fastest of three timed 1 s windows (us per step).
fn time_case(b: &mut Benchmark) -> Result<f64, Error> {
    for _ in 0..180 {
        b.world.step()?;
    }
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let t0 = Instant::now();
        for _ in 0..60 {
            b.world.step()?;
        }
        best = best.min(t0.elapsed().as_secs_f64() * 1e6 / 60.0);
    }
    Ok(best)
}
