//! The cost table: each scene's microseconds per step on every backend beside Rapier alone, in
//! one run, with the ratios.
//!
//! "Rapier alone" is the same bodies and joints (the `rapier-impulse` backend's lowering, no
//! extra rows, no reaction recovery) stepped by one `PhysicsPipeline::step` per step with
//! `dt = 1/60` and `num_solver_iterations = 4` (Rapier's own 4 substeps): what a game that uses
//! Rapier's joints directly pays. The crate's backends run `WorldSettings { dt: 1/60, substeps:
//! 4 }`. Each run is warmed up for 10 steps, then the fastest of three windows of about 0.1 s is
//! kept (this machine's noise is about +-10 % between runs, a window's minimum is stable to a
//! few %). Single thread unless the `parallel` feature is on (then the Lagrange backend steps
//! independent islands on rayon's pool; Rapier alone stays single-threaded, its `parallel`
//! feature is not enabled).

use std::time::Instant;

use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks::{self, Benchmark, MIXED_ARM_BODIES};

/// A scene of the cost table: its name, its joint count and its builder.
struct Scene {
    name: String,
    joints: usize,
    build: Box<dyn Fn(WorldSettings) -> Result<Benchmark, Error>>,
}

fn settings(backend: Backend) -> WorldSettings {
    WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        backend,
        ..Default::default()
    }
}

/// The scenes of the performance issue: the single pendulum, chains of 10, 100 and 1000 links
/// at end-mass ratios 1 and 1000, `mixed1000` (200 arms) and the mixed scene at 10 to 400 arms.
fn scenes() -> Vec<Scene> {
    let mut out = vec![Scene {
        name: "pendulum 1 m, 90 deg".into(),
        joints: 1,
        build: Box::new(|s| benchmarks::chain(s, 1, 1.0, 1.0, 1.0, 90f64.to_radians() as Real)),
    }];
    for n in [10, 100, 1000] {
        for ratio in [1.0 as Real, 1000.0] {
            out.push(Scene {
                name: format!("chain {n} 1:{ratio}"),
                joints: n,
                build: Box::new(move |s| {
                    benchmarks::chain(s, n, 0.1, 0.01, ratio, 20f64.to_radians() as Real)
                }),
            });
        }
    }
    for arms in [10, 25, 50, 100, 200, 400] {
        let name = if arms == 200 {
            "mixed1000 (200 arms)".to_string()
        } else {
            format!("mixed {arms} arms")
        };
        out.push(Scene {
            name,
            joints: arms * MIXED_ARM_BODIES,
            build: Box::new(move |s| benchmarks::mixed(s, arms)),
        });
    }
    out
}

/// A timed run: us per step, and the failure that cut it short (Rapier's backends blow up on
/// some scenes: their cost up to then is still reported).
struct Timed {
    us: Option<f64>,
    failure: Option<String>,
}

/// Times `step`: 3 warm-up steps, then each step on its own, up to 0.3 s or 600 steps. The
/// figure is the fastest of three equal consecutive windows (this machine's noise), or the mean
/// over the steps that ran before a failure.
fn time<E: std::fmt::Display>(mut step: impl FnMut() -> Result<(), E>) -> Timed {
    let mut failure = None;
    let mut steps = Vec::new();
    let budget = Instant::now();
    for k in 0..603 {
        let t0 = Instant::now();
        if let Err(e) = step() {
            failure = Some(format!("failed after {k} steps: {e}"));
            break;
        }
        if k >= 3 {
            steps.push(t0.elapsed().as_secs_f64() * 1e6);
        }
        if budget.elapsed().as_secs_f64() > 0.3 && steps.len() >= 30 {
            break;
        }
    }
    let us = if failure.is_none() {
        let w = steps.len() / 3;
        steps
            .chunks_exact(w.max(1))
            .map(|c| c.iter().sum::<f64>() / c.len() as f64)
            .reduce(f64::min)
    } else {
        (!steps.is_empty()).then(|| steps.iter().sum::<f64>() / steps.len() as f64)
    };
    Timed { us, failure }
}

/// One backend on one scene, at the output level `outputs`.
fn crate_backend(scene: &Scene, backend: Backend, outputs: Outputs) -> Timed {
    match (scene.build)(WorldSettings {
        outputs,
        ..settings(backend)
    }) {
        Ok(mut b) => time(|| b.world.step()),
        Err(e) => Timed {
            us: None,
            failure: Some(e.to_string()),
        },
    }
}

/// Rapier alone on one scene.
fn rapier_alone(scene: &Scene) -> Timed {
    let mut b = match (scene.build)(settings(Backend::RapierImpulse)) {
        Ok(b) => b,
        Err(e) => {
            return Timed {
                us: None,
                failure: Some(e.to_string()),
            };
        }
    };
    benchmarks::rapier_alone(&mut b.world);
    time(|| {
        b.world.physics.step();
        Ok::<(), String>(())
    })
}

/// Not run (the multibody column in `--quick` and beyond 100 joints).
const SKIPPED: Timed = Timed {
    us: None,
    failure: None,
};

/// Prints the cost table and returns the largest Lagrange / Rapier-alone ratio.
pub fn cost_table(quick: bool) -> f64 {
    println!(
        "\n## cost per step, dt 1/60, 4 substeps, f64, {} (us per step; ratio = backend / Rapier alone)",
        if cfg!(feature = "parallel") {
            "Lagrange islands in parallel (feature `parallel`)"
        } else {
            "single thread"
        }
    );
    println!(
        "(Lk, Ik: the Lagrange and rapier-impulse backends at `Outputs::Kinematics`, no reactions)"
    );
    println!(
        "{:<22} {:>6} {:>10} {:>10} {:>10} {:>10} {:>7} {:>7} {:>9} {:>10} {:>10} {:>7} {:>7}",
        "scene",
        "joints",
        "lagrange",
        "impulse",
        "multibody",
        "rapier",
        "L/R",
        "I/R",
        "L us/jnt",
        "Lk",
        "Ik",
        "Lk/R",
        "Ik/R"
    );
    let mut worst: f64 = 0.0;
    for scene in scenes() {
        let lagrange = crate_backend(&scene, Backend::Lagrange, Outputs::Full);
        let impulse = crate_backend(&scene, Backend::RapierImpulse, Outputs::Full);
        let lagrange_kin = crate_backend(&scene, Backend::Lagrange, Outputs::Kinematics);
        let impulse_kin = crate_backend(&scene, Backend::RapierImpulse, Outputs::Kinematics);
        // Multibody chains cost ~N^2 (measured exponent 2.1; and the 1000-link one minutes): run where cheap.
        let multibody = if quick || scene.joints > 100 {
            SKIPPED
        } else {
            crate_backend(&scene, Backend::RapierMultibody, Outputs::Full)
        };
        let rapier = rapier_alone(&scene);
        // `*`: the run failed after the timed steps (the figure is the cost up to then).
        let show = |r: &Timed| match (r.us, &r.failure) {
            (Some(us), None) => format!("{us:.1}"),
            (Some(us), Some(_)) => format!("{us:.1}*"),
            (None, None) => "-".to_string(),
            (None, Some(_)) => "fail".to_string(),
        };
        let ratio = |r: &Timed| match (r.us, rapier.us) {
            (Some(a), Some(b)) => Some(a / b),
            _ => None,
        };
        let (lr, ir) = (ratio(&lagrange), ratio(&impulse));
        if let Some(lr) = lr {
            worst = worst.max(lr);
        }
        let fmt = |x: Option<f64>| x.map_or("-".to_string(), |x| format!("{x:.2}"));
        println!(
            "{:<22} {:>6} {:>10} {:>10} {:>10} {:>10} {:>7} {:>7} {:>9} {:>10} {:>10} {:>7} {:>7}",
            scene.name,
            scene.joints,
            show(&lagrange),
            show(&impulse),
            show(&multibody),
            show(&rapier),
            fmt(lr),
            fmt(ir),
            lagrange.us.map_or("-".to_string(), |us| format!(
                "{:.2}",
                us / scene.joints as f64
            )),
            show(&lagrange_kin),
            show(&impulse_kin),
            fmt(ratio(&lagrange_kin)),
            fmt(ratio(&impulse_kin)),
        );
        for (name, r) in [
            ("lagrange", &lagrange),
            ("impulse", &impulse),
            ("multibody", &multibody),
        ] {
            if let Some(e) = &r.failure {
                println!("    {name}: {e}");
            }
        }
    }
    println!("(* the backend failed after these steps: the figure is its cost up to the failure)");
    worst
}
