//! `cargo run --release --features charts --example chart -- [--quick] [--out DIR]`
//!
//! The work-precision study (issue 7, item 3): for each scene (IFToMM A01 pendulum, A02
//! parallelogram four-bar, A04 Bricard, a 100-link chain with a 1:1000 end mass, the IFToMM
//! spatial slider-crank) and each method (Lagrange; penalty at k = 1e4, 1e6, 1e8; Rapier impulse;
//! Rapier multibody where it takes the scene), over a sweep of dt and substeps, it measures the
//! error against a reference and the CPU time per simulated second, and draws:
//!
//! - `runs.csv`: every run (scene, method, dt, substeps, `cpu_s_per_sim_s`, `traj_err`,
//!   `energy_drift`, `max_gap`, status);
//! - `wp_<scene>.{png,svg}` (trajectory error against CPU time) and `energy_<scene>.{png,svg}`
//!   (energy error against CPU time): log-log, one line per method through its own best runs,
//!   the Pareto front over all methods ringed, failed runs as crosses along the top, the IFToMM
//!   precision levels 1e-1 and 1e-3 and the real-time line (1 CPU second per simulated second);
//! - `stability_chain.{png,svg}`: the chain's end-mass ratio (1..1000) x substeps (1..8) at
//!   dt = 1/60 for each method, each cell ok / gap > 1 cm / blew up;
//! - `stability_penalty.{png,svg}` (and `.csv`): the A01 pendulum with a penalty revolute
//!   (KEYOPT(2) = 1), stiffness 1e2..1e10 (plus Lagrange, k = infinity) x dt 1/30..1/960 at one
//!   substep, 5 s against the exact pendulum: each cell blew up / joint gap > 0.1 m (the
//!   soft joint's deflection; the run stops there) / error > 1e-1 m / <= 1e-1 m / <= 1e-3 m (the
//!   IFToMM levels), labelled with the error;
//! - `stability_singular.{png,svg}` (and `.csv`): the A02 parallelogram four-bar released at
//!   rest at `delta` = 1e-4..1 rad above its singular pose (cranks collinear with the ground
//!   link), so that it crawls through that pose and through the opposite one (`theta = -pi`),
//!   x dt 1/30..1/960 at one substep, 4 s against the exact motion (RK4), per method: blew up /
//!   branch switch (the coupler turns by more than 0.5 rad: the anti-parallelogram branch) /
//!   error > 1e-1 m (stuck, turned back or out of phase) / <= 1e-1 m / <= 1e-3 m;
//! - `scaling_chain.{png,svg}`: cost per step against the number of links (10..1000), with
//!   Rapier alone (one pipeline call per step, its own 4 substeps) and MuJoCo where measured;
//! - `reference_<scene>.csv`: each scene's reference trajectory (`t,x,y,z` of the probe), which
//!   `scripts/mujoco_peer.py` scores MuJoCo's runs against; its `peer_runs.csv` and
//!   `peer_scaling.csv`, when present in the output directory, add MuJoCo's lines to the
//!   work-precision, energy and scaling charts and its rows to `summary.md` (see `peers.rs`);
//! - `summary.md`: per scene the Pareto front, the cheapest run of each method reaching 1e-1 and
//!   1e-3, and where each method fails;
//! - `wp_a03_andrews.{png,svg}`, `andrews.csv`, `andrews.md` (also alone with `--andrews`):
//!   IFToMM A03, Andrews' squeezer from its deck, against the published angles at 0.03 s, on
//!   its own steps (1e-4 s down to 1.25e-6 s; see `andrews.rs`).
//!
//! Metrics of a run (one world stepped at `dt` with `substeps`):
//! - `traj_err`: as IFToMM scores it, the largest deviation of any coordinate of the scene's
//!   probe point from the reference, over output steps every 1/30 s (m; absolute, the udc
//!   specifications compare the point's coordinates in metres);
//! - `energy_drift`: the largest `|E - E0|` over the output steps, divided by the scene's energy
//!   scale (`Benchmark::energy_scale`);
//! - `max_gap`: the largest translational joint gap seen at the output steps (m);
//! - `cpu_s_per_sim_s`: wall-clock time of the `step()` calls only (single thread), divided by
//!   the simulated time reached.
//!
//! A run fails (status `failed: ...`, a cross in the charts) on a step error, a non-finite value,
//! a gap above a tenth of the scene's length (`SceneSpec::length`), an energy error above 10 times
//! the scale, or (four-bar) the coupler turning by more than 0.5 rad: a branch switch at the
//! singular position. A run whose cost, estimated from its first steps, would exceed the per-run
//! budget is `skipped` (Rapier multibody on the long chain at small steps).
//!
//! References: A01 and A02 are 1-DOF problems integrated here by RK4 at h = 1/122880 s (the
//! pendulum `theta'' = -(m g L / I_p) sin theta` with the bob's own 1e-4 kg m^2 in `I_p`; the
//! four-bar `theta'' = -(6 g / 5) cos theta`). A04 and the slider-crank use the fourth-order
//! composition at the sweep's smallest substep, the chain RATTLE at a quarter of it; a second run
//! at twice that step estimates the reference's own error (printed as the "reference floor").

use std::error::Error;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use plotters::coord::Shift;
use plotters::prelude::*;
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks::{self, Benchmark, Probe};
use rapier3d_mpc184::studies::scenes::{self, G};

#[path = "../common/mod.rs"]
mod common;

mod andrews;
mod catalogue;
mod config;
mod maps;
mod measure;
mod peers;
mod plot;
mod reference;
mod summary;

use andrews::*;
use catalogue::*;
use config::*;
use maps::*;
use measure::*;
use peers::*;
use plot::*;
use reference::*;
use summary::*;

type DynResult<T> = Result<T, Box<dyn Error>>;

/// the work-precision study (error against CPU time) of every backend
///
/// Runs IFToMM A01 (pendulum), A02 (parallelogram four-bar), A04 (Bricard), a 100-link chain
/// with a 1:1000 end mass and the spatial slider-crank on Lagrange, penalty (k = 1e4, 1e6, 1e8),
/// Rapier impulse and Rapier multibody joints over dt = 1/30..1/960 and 1, 2, 4, 8 substeps; writes
/// runs.csv, work-precision charts, stability maps (chain end-mass ratio x substeps, penalty
/// stiffness x dt, four-bar start distance from its singular pose x dt), a cost-against-N chart
/// (PNG and SVG) and summary.md. The full sweep takes about 10 minutes on 2 cores.
#[derive(clap::Parser)]
struct Cli {
    /// A short sweep (2 step sizes, 2 substep counts, 1 s scenes, 20-link chain)
    #[arg(long)]
    quick: bool,
    /// Only the three stability maps (their charts, CSVs and summary sections)
    #[arg(long)]
    maps: bool,
    /// Only IFToMM A03, Andrews' squeezer (`wp_a03_andrews`, `andrews.csv`, `andrews.md`)
    #[arg(long)]
    andrews: bool,
    /// Output directory
    #[arg(long, value_name = "DIR", default_value = "docs/charts")]
    out: PathBuf,
}

/// Bundled font (`DejaVu` Sans, Bitstream Vera licence: `assets/fonts/DejaVuSans-LICENSE.txt`):
/// plotters renders text with `ab_glyph` from these bytes, no system font needed.
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Output steps of the trajectory comparison (s): every dt of the sweep divides it.
const OUTPUT_STEP: f64 = 1.0 / 30.0;

fn main() -> ExitCode {
    let Cli {
        quick,
        maps,
        andrews,
        out,
    } = common::parse("chart", &[]);
    let cfg = Config {
        maps_only: maps,
        ..Config::new(quick)
    };
    let result = if andrews {
        andrews_only(&cfg, &out)
    } else {
        run(&cfg, &out)
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("chart: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Progress and ETA on stderr (indicatif; drawn only on a terminal).
struct Progress {
    bar: indicatif::ProgressBar,
}

impl Progress {
    fn new(total: usize) -> Self {
        Progress {
            bar: common::progress(total, "runs"),
        }
    }

    fn tick(&mut self, what: &str) {
        self.bar.set_message(what.to_string());
        self.bar.inc(1);
    }

    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

fn run(cfg: &Config, out: &Path) -> DynResult<()> {
    plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
        .map_err(|_| "the bundled font does not load")?;
    std::fs::create_dir_all(out)?;
    let wp_runs = SCENES.len()
        * (METHODS.len() * cfg.rates.len() * cfg.substeps.len()
            + ADAPTIVE.len() * cfg.tolerances.len());
    let stab = METHODS.len() * cfg.stability_ratios.len() * cfg.substeps.len();
    let scal = 5 * cfg.scaling_n.len();
    let pen = (cfg.penalty_ks.len() + 1) * cfg.penalty_rates.len();
    let sing = METHODS.len() * cfg.singular_deltas.len() * cfg.singular_rates.len();
    let mut progress = Progress::new(if cfg.maps_only {
        stab + pen + sing
    } else {
        SCENES.len() + wp_runs + stab + scal + pen + sing + andrews_count(cfg)
    });
    if cfg.maps_only {
        return maps_only(cfg, out, &mut progress);
    }
    let (mut runs, refs) = sweep(cfg, out, &mut progress)?;
    // MuJoCo's runs, when `scripts/mujoco_peer.py` has written them (full sweep only: the
    // script runs the full study's settings).
    let peers = if cfg.quick {
        Vec::new()
    } else {
        peer_runs(out)?
    };
    runs.extend(peers);
    let stability = stability_map(cfg, &mut progress);
    let penalty = penalty_map(cfg, &mut progress);
    let singular = singular_map(cfg, &mut progress);
    let andrews = andrews_study(cfg, out, &mut progress)?;
    let mut scaling = scaling(cfg, &mut progress);
    if !cfg.quick {
        scaling.extend(peer_scaling(out)?);
    }
    progress.finish();
    let wall = progress.bar.elapsed().as_secs_f64();

    let mut files = Vec::new();
    write_csv(&out.join("runs.csv"), &runs)?;
    files.push("runs.csv".to_string());
    draw_work_precision(cfg, out, &runs, &mut files)?;
    Chart::Stability(cfg, &stability).save(out, "stability_chain", (1320, 680), &mut files)?;
    Chart::Penalty(cfg, &penalty).save(out, "stability_penalty", (900, 640), &mut files)?;
    Chart::Singular(cfg, &singular).save(out, "stability_singular", (1400, 720), &mut files)?;
    write_map_csv(&out.join("stability_penalty.csv"), &penalty)?;
    write_map_csv(&out.join("stability_singular.csv"), &singular)?;
    files.push("stability_penalty.csv".into());
    files.push("stability_singular.csv".into());
    Chart::Scaling(&scaling).save(out, "scaling_chain", (900, 600), &mut files)?;
    let mut summary = summary(cfg, &runs, &refs, &stability, &scaling, wall);
    map_summary(&mut summary, cfg, &penalty, &singular);
    summary.push('\n');
    summary.push_str(&andrews);
    std::fs::write(out.join("summary.md"), &summary)?;
    files.push("summary.md".into());
    println!("{summary}");
    println!(
        "wrote {} files to {}: {}",
        files.len(),
        out.display(),
        files.join(" ")
    );
    Ok(())
}

/// `--andrews`: A03 only.
fn andrews_only(cfg: &Config, out: &Path) -> DynResult<()> {
    plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
        .map_err(|_| "the bundled font does not load")?;
    std::fs::create_dir_all(out)?;
    let mut progress = Progress::new(andrews_count(cfg));
    andrews_study(cfg, out, &mut progress).map(|_| ())
}

/// `--maps`: the three stability maps only.
fn maps_only(cfg: &Config, out: &Path, progress: &mut Progress) -> DynResult<()> {
    let stability = stability_map(cfg, progress);
    let penalty = penalty_map(cfg, progress);
    let singular = singular_map(cfg, progress);
    progress.finish();
    let wall = progress.bar.elapsed().as_secs_f64();
    let mut files = Vec::new();
    Chart::Stability(cfg, &stability).save(out, "stability_chain", (1320, 680), &mut files)?;
    Chart::Penalty(cfg, &penalty).save(out, "stability_penalty", (900, 640), &mut files)?;
    Chart::Singular(cfg, &singular).save(out, "stability_singular", (1400, 720), &mut files)?;
    write_map_csv(&out.join("stability_penalty.csv"), &penalty)?;
    write_map_csv(&out.join("stability_singular.csv"), &singular)?;
    files.push("stability_penalty.csv".into());
    files.push("stability_singular.csv".into());
    let mut s = format!("# Stability maps\n\nWall time {wall:.0} s.\n");
    map_summary(&mut s, cfg, &penalty, &singular);
    println!("{s}");
    println!(
        "wrote {} files to {}: {}",
        files.len(),
        out.display(),
        files.join(" ")
    );
    Ok(())
}

/// How a scene's reference was made, and its own error (m).
type RefNote = (Scene, String, f64);

/// The work-precision sweep: every scene's reference, then every method, rate and substep
/// count on it.
fn sweep(cfg: &Config, out: &Path, progress: &mut Progress) -> DynResult<(Vec<Run>, Vec<RefNote>)> {
    let mut runs = Vec::new();
    let mut refs = Vec::new();
    for scene in SCENES {
        let r = reference(scene, cfg)?;
        write_reference(out, scene, &r.points)?;
        progress.tick(&format!("{} reference", scene.key()));
        for method in METHODS {
            for &rate in &cfg.rates {
                for &sub in &cfg.substeps {
                    let dt = 1.0 / rate as f64;
                    progress.tick(&format!(
                        "{} {} 1/{rate} x{sub}",
                        scene.key(),
                        method.name()
                    ));
                    let Some(b) = build(scene, cfg, method, dt, sub) else {
                        continue;
                    };
                    let secs = cfg.durations[scene.index()];
                    let (cpu, traj, energy, gap, status) = simulate(
                        scene,
                        b,
                        dt,
                        secs,
                        Some(&r.points),
                        cfg.budget,
                        0.1 * scene.length(),
                    );
                    runs.push(Run {
                        scene,
                        method,
                        dt,
                        substeps: sub,
                        cpu,
                        traj,
                        energy,
                        gap,
                        status,
                        tol: None,
                    });
                }
            }
        }
        for method in ADAPTIVE {
            for &tol in &cfg.tolerances {
                progress.tick(&format!("{} {} tol {tol:.0e}", scene.key(), method.name()));
                runs.extend(adaptive_run(scene, cfg, method, tol, &r.points));
            }
        }
        refs.push((scene, r.how, r.floor));
    }
    Ok((runs, refs))
}

/// One adaptive run: dt 1/30 (the frame clock, the output step: step doubling keeps at least two
/// substeps, so the finest fixed setting it can match is 1/60 x1), one substep to start with, the step control
/// asked for `tol` over the scene's duration as a position error per step of `tol dt /
/// duration` (error per unit step: the local errors of a smooth motion add up about
/// linearly), at most 4096 substeps per step.
fn adaptive_run(
    scene: Scene,
    cfg: &Config,
    method: Method,
    tol: f64,
    reference: &[[f64; 3]],
) -> Option<Run> {
    let dt = OUTPUT_STEP;
    let mut b = build(scene, cfg, method, dt, 1)?;
    let secs = cfg.durations[scene.index()];
    // A velocity error grows into a phase drift over the rest of the run, weighed over the
    // mean time left (`-local`, the step alone: A02's error reached 6.5 times the request).
    let horizon = match method {
        Method::Adaptive { horizon: true, .. } => (secs / 2.0) as Real,
        _ => 0.0,
    };
    let tolerance = (tol * dt / secs) as Real;
    let control = match method {
        Method::Adaptive { embedded: true, .. } => StepControl::Embedded {
            tolerance,
            max_substeps: 4096,
            horizon,
        },
        _ => StepControl::Adaptive {
            tolerance,
            energy_tolerance: Real::INFINITY,
            max_substeps: 4096,
            horizon,
            extrapolate: matches!(
                method,
                Method::Adaptive {
                    extrapolate: true,
                    ..
                }
            ),
        },
    };
    b.world.set_step_control(control).ok()?;
    let (cpu, traj, energy, gap, status) = simulate(
        scene,
        b,
        dt,
        secs,
        Some(reference),
        cfg.budget,
        0.1 * scene.length(),
    );
    Some(Run {
        scene,
        method,
        dt,
        substeps: 1,
        cpu,
        traj,
        energy,
        gap,
        status,
        tol: Some(tol),
    })
}

/// The work-precision, energy and order charts of every scene.
fn draw_work_precision(
    cfg: &Config,
    out: &Path,
    runs: &[Run],
    files: &mut Vec<String>,
) -> DynResult<()> {
    for scene in SCENES {
        let rs: Vec<&Run> = runs.iter().filter(|r| r.scene == scene).collect();
        let title = scene.title(cfg);
        for (kind, y_desc) in [
            ("wp", "trajectory error: max coordinate deviation (m)"),
            ("energy", "max |E - E0| / E_scale"),
        ] {
            let name = format!("{kind}_{}", scene.key());
            let caption = if kind == "wp" {
                title.clone()
            } else {
                format!("{}: energy error", title.split(',').next().unwrap_or(""))
            };
            let chart = Chart::WorkPrecision {
                caption: &caption,
                y_desc,
                runs: &rs,
                energy: kind == "energy",
            };
            chart.save(out, &name, (960, 640), files)?;
        }
    }
    for scene in [Scene::A01, Scene::Conical, Scene::A02] {
        let rs: Vec<&Run> = runs.iter().filter(|r| r.scene == scene).collect();
        let caption = format!(
            "{}: error against substep",
            scene.title(cfg).split(',').next().unwrap_or("")
        );
        Chart::Convergence {
            caption: &caption,
            runs: &rs,
        }
        .save(out, &format!("order_{}", scene.key()), (960, 640), files)?;
    }
    Ok(())
}
