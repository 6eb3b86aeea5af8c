//! Per-step cost of each backend (issue 7, item 5): `cargo bench --bench step`.
//!
//! - `chain100/<backend>`: the 100-link revolute chain of `benchmarks::chain` (0.1 m links,
//!   0.01 kg beads, released at 20 deg), end-mass ratio 1 so that every backend survives the
//!   timed steps (Rapier's backends blow up at 1:1000, see `docs/charts/stability_chain.png`);
//! - `chain100/rapier-alone`, `mixed1000/rapier-alone`: Rapier alone on the same bodies and
//!   joints (one pipeline call per step, its own 4 substeps): the bar;
//! - `mixed1000/<backend>`: 1000 joints of five kinds, 200 independent five-body arms hanging from
//!   the ground (`studies::benchmarks::mixed`): revolute z, spherical, cylindrical z, revolute x
//!   and translational (the kinds every backend takes), on 1000 bodies, every backend (Rapier multibody runs since each
//!   grounded multibody joint has its own fixed root: with one shared ground body the 200 arms
//!   were one multibody and a step took seconds);
//! - `idle100/<case>` ("model no more than a scene needs", Lagrange): the 100-link chain as built,
//!   with an inactive stop on every joint (limits at +-10 rad, never reached), and with a second
//!   100-link chain hanging at rest beside it, allowed to sleep (asleep after the 3 s run before
//!   timing) or kept awake. The ratios to the first case are the cost of an inactive stop and of
//!   a sleeping island (`cargo run --release --example joint_bench -- --model` prints the same table).
//!
//! One iteration is one `step()` at dt = 1/60 with 4 substeps on a world that keeps moving (no
//! reset between iterations). Single thread, f64 by default. criterion is built without its
//! default features (no rayon, no plotters: text reports only).
#![allow(
    missing_docs,
    reason = "criterion_group! generates an undocumented function"
)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks::{self, CHAIN_LINK_LENGTH, CHAIN_LINK_MASS};

const BACKENDS: [Backend; 3] = [
    Backend::Lagrange,
    Backend::RapierImpulse,
    Backend::RapierMultibody,
];

fn settings(backend: Backend) -> WorldSettings {
    WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        backend,
        ..Default::default()
    }
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("chain100");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    for backend in BACKENDS {
        let theta0 = 20f64.to_radians() as Real;
        let built = benchmarks::chain(
            settings(backend),
            100,
            CHAIN_LINK_LENGTH,
            CHAIN_LINK_MASS,
            1.0,
            theta0,
        );
        let Ok(mut b) = built else { continue };
        group.bench_function(backend.name(), |bench| {
            bench.iter(|| black_box(b.world.step().is_ok()));
        });
    }
    if let Ok(b) = benchmarks::chain(
        settings(Backend::RapierImpulse),
        100,
        CHAIN_LINK_LENGTH,
        CHAIN_LINK_MASS,
        1.0,
        20f64.to_radians() as Real,
    ) {
        rapier_alone(&mut group, b.world);
    }
    group.finish();

    let mut group = c.benchmark_group("mixed1000");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    for backend in BACKENDS {
        let mut world = match benchmarks::mixed(settings(backend), 200) {
            Ok(b) => b.world,
            Err(e) => {
                println!("mixed1000/{}: not run: {e}", backend.name());
                continue;
            }
        };
        group.bench_function(backend.name(), |bench| {
            bench.iter(|| black_box(world.step().is_ok()));
        });
    }
    if let Ok(b) = benchmarks::mixed(settings(Backend::RapierImpulse), 200) {
        rapier_alone(&mut group, b.world);
    }
    group.finish();

    let mut group = c.benchmark_group("idle100");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    for (name, stops, resting) in [
        ("chain", false, None),
        ("chain+inactive_stops", true, None),
        ("chain+sleeping_chain", false, Some(true)),
        ("chain+awake_chain", false, Some(false)),
    ] {
        let mut b = match benchmarks::idle_chain(settings(Backend::Lagrange), stops, resting) {
            Ok(b) => b,
            Err(e) => {
                println!("idle100/{name}: not run: {e}");
                continue;
            }
        };
        // 3 s untimed: time for Rapier to put the resting chain to sleep.
        if (0..180).any(|_| b.world.step().is_err()) {
            println!("idle100/{name}: failed during the untimed start");
            continue;
        }
        let asleep = b
            .world
            .physics
            .bodies
            .iter()
            .filter(|(_, rb)| rb.is_sleeping())
            .count();
        println!("idle100/{name}: {asleep} bodies asleep when timing starts");
        group.bench_function(name, |bench| {
            bench.iter(|| black_box(b.world.step().is_ok()));
        });
    }
    group.finish();
}

/// Rapier alone (`benchmarks::rapier_alone`) on a world built for the impulse backend: the bar
/// each backend is compared with (`joint_bench --cost` prints the ratios).
fn rapier_alone(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    mut world: Mpc184World,
) {
    benchmarks::rapier_alone(&mut world);
    let p = &mut world.physics;
    group.bench_function("rapier-alone", |bench| {
        bench.iter(|| {
            p.step();
            black_box(&p.bodies);
        });
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
