//! `cargo run --release --features charts --bin chart -- [--quick] [--out DIR]`
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
//! - `scaling_chain.{png,svg}`: cost per step against the number of links (10..1000);
//! - `summary.md`: per scene the Pareto front, the cheapest run of each method reaching 1e-1 and
//!   1e-3, and where each method fails.
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
//! four-bar `theta'' = -(6 g / 5) cos theta`). A04, the chain and the slider-crank use a Lagrange
//! run at a quarter of the sweep's smallest substep; a second run at twice that step estimates
//! the reference's own error (printed as the "reference floor").

use std::error::Error;
use std::fmt::Write as _;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use plotters::coord::Shift;
use plotters::prelude::*;
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks::{self, Benchmark, Probe, RodSliderJoint};
use rapier3d_mpc184::studies::scenes::{self, G};

type DynResult<T> = Result<T, Box<dyn Error>>;

const HELP: &str = "chart: the work-precision study (error against CPU time) of every backend

Runs IFToMM A01 (pendulum), A02 (parallelogram four-bar), A04 (Bricard), a 100-link chain
with a 1:1000 end mass and the spatial slider-crank on Lagrange, penalty (k = 1e4, 1e6, 1e8),
Rapier impulse and Rapier multibody joints over dt = 1/30..1/960 and 1, 2, 4, 8 substeps; writes
runs.csv, work-precision charts, stability maps (chain end-mass ratio x substeps, penalty
stiffness x dt, four-bar start distance from its singular pose x dt), a cost-against-N chart
(PNG and SVG) and summary.md. The full sweep takes about 10 minutes on 2 cores.

OPTIONS:
    --quick      a short sweep (2 step sizes, 2 substep counts, 1 s scenes, 20-link chain)
    --maps       only the three stability maps (their charts, CSVs and summary sections)
    --out DIR    output directory (default docs/charts)
    --help       this text";

/// Bundled font (`DejaVu` Sans, Bitstream Vera licence: `assets/fonts/DejaVuSans-LICENSE.txt`):
/// plotters renders text with `ab_glyph` from these bytes, no system font needed.
static FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

/// Output steps of the trajectory comparison (s): every dt of the sweep divides it.
const OUTPUT_STEP: f64 = 1.0 / 30.0;

fn main() -> ExitCode {
    let mut quick = false;
    let mut maps = false;
    let mut out = PathBuf::from("docs/charts");
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--help" | "-h" => {
                println!("{HELP}");
                return ExitCode::SUCCESS;
            }
            "--quick" => quick = true,
            "--maps" => maps = true,
            "--out" => match args.next() {
                Some(d) => out = PathBuf::from(d),
                None => return usage("--out needs a value"),
            },
            _ => return usage(&format!("unexpected argument `{a}`")),
        }
    }
    let cfg = Config {
        maps_only: maps,
        ..Config::new(quick)
    };
    match run(&cfg, &out) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("chart: {e}");
            ExitCode::FAILURE
        }
    }
}

fn usage(msg: &str) -> ExitCode {
    eprintln!("chart: {msg}\n\n{HELP}");
    ExitCode::from(2)
}

/// The sweep's extent.
struct Config {
    quick: bool,
    /// Only the three stability maps (`--maps`).
    maps_only: bool,
    /// Time steps as 1/x.
    rates: Vec<u32>,
    substeps: Vec<usize>,
    /// Simulated seconds per scene: A01, conical pendulum, A02, A04, chain, slider-crank.
    durations: [f64; 6],
    chain_links: usize,
    /// Reference substep (s).
    h_ref: f64,
    /// Largest estimated wall time of one run (s) before it is skipped.
    budget: f64,
    stability_links: usize,
    stability_ratios: Vec<f64>,
    stability_secs: f64,
    scaling_n: Vec<usize>,
    /// Penalty map: stiffnesses (N/m and N m/rad), step rates (1/dt) and simulated seconds.
    penalty_ks: Vec<f64>,
    penalty_rates: Vec<u32>,
    penalty_secs: f64,
    /// Singular four-bar map: start angles above the singular pose (rad), step rates, seconds.
    singular_deltas: Vec<f64>,
    singular_rates: Vec<u32>,
    singular_secs: f64,
}

impl Config {
    fn new(quick: bool) -> Self {
        if quick {
            Self {
                quick,
                maps_only: false,
                rates: vec![30, 60],
                substeps: vec![1, 2],
                durations: [1.0; 6],
                chain_links: 20,
                h_ref: 1.0 / 960.0,
                budget: 1.0,
                stability_links: 10,
                stability_ratios: vec![1.0, 1000.0],
                stability_secs: 0.5,
                scaling_n: vec![10, 30],
                penalty_ks: vec![1e3, 1e6, 1e9],
                penalty_rates: vec![30, 120],
                penalty_secs: 1.0,
                singular_deltas: vec![1e-3, 0.1],
                singular_rates: vec![30, 120],
                singular_secs: 1.5,
            }
        } else {
            Self {
                quick,
                maps_only: false,
                rates: vec![30, 60, 120, 240, 480, 960],
                substeps: vec![1, 2, 4, 8],
                durations: [10.0, 10.0, 10.0, 10.0, 2.0, 5.0],
                chain_links: 100,
                h_ref: 1.0 / (4.0 * 960.0 * 8.0),
                budget: 12.0,
                stability_links: 100,
                stability_ratios: vec![1.0, 10.0, 100.0, 1000.0],
                stability_secs: 2.0,
                scaling_n: vec![10, 30, 100, 300, 1000],
                penalty_ks: vec![1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10],
                penalty_rates: vec![30, 60, 120, 240, 480, 960],
                penalty_secs: 5.0,
                singular_deltas: vec![1e-4, 1e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0],
                singular_rates: vec![30, 60, 120, 240, 480, 960],
                singular_secs: 4.0,
            }
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Method {
    Lagrange,
    /// The Lagrange backend with the second-order integrator (RATTLE).
    Rattle,
    Penalty(f64),
    Impulse,
    Multibody,
}

const METHODS: [Method; 7] = [
    Method::Lagrange,
    Method::Rattle,
    Method::Penalty(1e4),
    Method::Penalty(1e6),
    Method::Penalty(1e8),
    Method::Impulse,
    Method::Multibody,
];

impl Method {
    fn name(self) -> String {
        match self {
            Method::Lagrange => "lagrange".into(),
            Method::Rattle => "lagrange-rattle".into(),
            Method::Penalty(k) => format!("penalty-{k:.0e}"),
            Method::Impulse => "rapier-impulse".into(),
            Method::Multibody => "rapier-multibody".into(),
        }
    }

    fn backend(self) -> Backend {
        match self {
            Method::Lagrange | Method::Rattle | Method::Penalty(_) => Backend::Lagrange,
            Method::Impulse => Backend::RapierImpulse,
            Method::Multibody => Backend::RapierMultibody,
        }
    }

    fn color(self) -> RGBColor {
        match self {
            Method::Lagrange => RGBColor(31, 119, 180),
            Method::Rattle => RGBColor(148, 103, 189),
            Method::Penalty(k) if k < 1e5 => RGBColor(255, 187, 120),
            Method::Penalty(k) if k < 1e7 => RGBColor(255, 127, 14),
            Method::Penalty(_) => RGBColor(140, 86, 75),
            Method::Impulse => RGBColor(214, 39, 40),
            Method::Multibody => RGBColor(44, 160, 44),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Scene {
    A01,
    Conical,
    A02,
    A04,
    Chain,
    SliderCrank,
}

const SCENES: [Scene; 6] = [
    Scene::A01,
    Scene::Conical,
    Scene::A02,
    Scene::A04,
    Scene::Chain,
    Scene::SliderCrank,
];

impl Scene {
    fn index(self) -> usize {
        SCENES.iter().position(|s| *s == self).unwrap_or(0)
    }

    fn key(self) -> &'static str {
        match self {
            Scene::A01 => "a01_pendulum",
            Scene::Conical => "conical_pendulum",
            Scene::A02 => "a02_four_bar",
            Scene::A04 => "a04_bricard",
            Scene::Chain => "chain",
            Scene::SliderCrank => "slider_crank",
        }
    }

    fn title(self, cfg: &Config) -> String {
        let d = cfg.durations[self.index()];
        match self {
            Scene::A01 => format!("A01 pendulum, {d} s (spec 2000 s), bob x, y vs exact"),
            Scene::Conical => format!("conical pendulum 45 deg (spherical), {d} s, bob vs exact"),
            Scene::A02 => format!("A02 four-bar N=1, {d} s (spec 20 s), B0 x, y vs exact"),
            Scene::A04 => format!("A04 Bricard, {d} s, P3 vs converged Lagrange"),
            Scene::Chain => format!(
                "chain {} links 1:1000, {d} s, end bead vs converged Lagrange",
                cfg.chain_links
            ),
            Scene::SliderCrank => {
                format!("slider-crank (spherical rod-slider), {d} s, slider vs converged Lagrange")
            }
        }
    }

    /// Characteristic length (m): a gap above a tenth of it is a failure.
    fn length(self) -> f64 {
        match self {
            Scene::A01 | Scene::Conical | Scene::A02 | Scene::A04 => 1.0,
            Scene::Chain => benchmarks::CHAIN_LINK_LENGTH as f64,
            Scene::SliderCrank => 0.08,
        }
    }

    fn build(
        self,
        cfg: &Config,
        settings: WorldSettings,
    ) -> Result<Benchmark, rapier3d_mpc184::Error> {
        match self {
            Scene::A01 => pendulum_benchmark(settings),
            Scene::Conical => conical_benchmark(settings),
            Scene::A02 => benchmarks::four_bar_parallelogram(settings),
            Scene::A04 => benchmarks::bricard(settings),
            Scene::Chain => chain(settings, cfg.chain_links, 1000.0),
            Scene::SliderCrank => {
                benchmarks::slider_crank_with(settings, RodSliderJoint::Spherical)
            }
        }
    }
}

/// Pendulum of A01 as a [`Benchmark`]: 1 kg bob (inertia 1e-4 kg m^2) 1 m from a revolute z
/// joint, released horizontally; energy scale m g L.
fn pendulum_benchmark(settings: WorldSettings) -> Result<Benchmark, rapier3d_mpc184::Error> {
    let p = scenes::pendulum(
        settings,
        Axis::Z,
        1.0,
        std::f64::consts::FRAC_PI_2 as Real,
        1.0,
        PENDULUM_INERTIA as Real,
    )?;
    let e0 = p.world.kinetic_energy() + p.world.potential_energy();
    Ok(Benchmark {
        world: p.world,
        bodies: vec![p.bob],
        joints: vec![p.joint],
        joint_bodies: vec![[None, Some(p.bob)]],
        initial_energy: e0,
        energy_scale: p.mass * G * p.length,
        probe: Probe {
            body: p.bob,
            local: Vector::ZERO,
        },
        duration: 10.0,
    })
}

const PENDULUM_INERTIA: f64 = 1e-4;

/// Half-angle of the conical pendulum (rad).
const CONICAL_ALPHA: f64 = std::f64::consts::FRAC_PI_4;

/// Conical pendulum: 1 kg bob (isotropic inertia 1e-4 kg m^2) 1 m from a grounded spherical
/// joint, 45 deg from the vertical, in its exact steady precession `Omega^2 = g / (L cos alpha)`
/// about +Y (the isotropic bob spins with the rod, so the point-mass rate holds exactly);
/// energy scale: its kinetic energy `m (Omega L sin alpha)^2 / 2`.
fn conical_benchmark(settings: WorldSettings) -> Result<Benchmark, rapier3d_mpc184::Error> {
    let (world, bob, joint) = scenes::conical_pendulum(
        settings,
        1.0,
        CONICAL_ALPHA as Real,
        1.0,
        PENDULUM_INERTIA as Real,
    )?;
    let e0 = world.kinetic_energy() + world.potential_energy();
    let omega2 = G / CONICAL_ALPHA.cos() as Real;
    let r = CONICAL_ALPHA.sin() as Real;
    Ok(Benchmark {
        world,
        bodies: vec![bob],
        joints: vec![joint],
        joint_bodies: vec![[None, Some(bob)]],
        initial_energy: e0,
        energy_scale: 0.5 * omega2 * r * r,
        probe: Probe {
            body: bob,
            local: Vector::ZERO,
        },
        duration: 10.0,
    })
}

fn chain(
    settings: WorldSettings,
    n: usize,
    ratio: f64,
) -> Result<Benchmark, rapier3d_mpc184::Error> {
    benchmarks::chain(
        settings,
        n,
        benchmarks::CHAIN_LINK_LENGTH,
        benchmarks::CHAIN_LINK_MASS,
        ratio as Real,
        20f64.to_radians() as Real,
    )
}

fn settings(method: Method, dt: f64, substeps: usize) -> WorldSettings {
    WorldSettings {
        dt: dt as Real,
        substeps,
        backend: method.backend(),
        integrator: if method == Method::Rattle {
            Integrator::Rattle
        } else {
            Integrator::SymplecticEuler
        },
    }
}

/// Builds `scene` for `method` (`None`: the method does not take the scene).
fn build(
    scene: Scene,
    cfg: &Config,
    method: Method,
    dt: f64,
    substeps: usize,
) -> Option<Benchmark> {
    with_method(
        scene.build(cfg, settings(method, dt, substeps)).ok()?,
        method,
    )
}

/// `b` with its joints turned into penalty joints when `method` is a penalty method (`None`
/// where that fails).
fn with_method(mut b: Benchmark, method: Method) -> Option<Benchmark> {
    if let Method::Penalty(k) = method {
        let k = -(k as Real);
        b.set_method(ConstraintMethod::Penalty { disp: k, rot: k })
            .ok()?;
    }
    Some(b)
}

fn probe(b: &Benchmark) -> [f64; 3] {
    let p = b.probe_position();
    [p.x as f64, p.y as f64, p.z as f64]
}

/// A reference trajectory: the probe point at every output step (index 0 = time 0).
struct Reference {
    points: Vec<[f64; 3]>,
    /// Estimated error of the reference itself (m).
    floor: f64,
    how: String,
}

/// RK4 on a 1-DOF `theta'' = f(theta)`, the probe point `pos(theta)` at each output step.
fn rk4_reference(
    f: impl Fn(f64) -> f64,
    pos: impl Fn(f64) -> [f64; 3],
    theta0: f64,
    omega0: f64,
    secs: f64,
) -> Vec<[f64; 3]> {
    let per_output = 4096;
    let h = OUTPUT_STEP / per_output as f64;
    let outputs = (secs / OUTPUT_STEP).round() as usize;
    let (mut th, mut om) = (theta0, omega0);
    let mut out = vec![pos(th)];
    for _ in 0..outputs {
        for _ in 0..per_output {
            let (k1t, k1o) = (om, f(th));
            let (k2t, k2o) = (om + 0.5 * h * k1o, f(th + 0.5 * h * k1t));
            let (k3t, k3o) = (om + 0.5 * h * k2o, f(th + 0.5 * h * k2t));
            let (k4t, k4o) = (om + h * k3o, f(th + h * k3t));
            th += h / 6.0 * (k1t + 2.0 * k2t + 2.0 * k3t + k4t);
            om += h / 6.0 * (k1o + 2.0 * k2o + 2.0 * k3o + k4o);
        }
        out.push(pos(th));
    }
    out
}

/// A Lagrange run at substep `h` (one substep per step), the probe at each output step.
fn lagrange_trajectory(scene: Scene, cfg: &Config, h: f64, secs: f64) -> DynResult<Vec<[f64; 3]>> {
    let mut b = build(scene, cfg, Method::Lagrange, h, 1).ok_or("reference scene")?;
    let per_output = (OUTPUT_STEP / h).round() as usize;
    let outputs = (secs / OUTPUT_STEP).round() as usize;
    let mut out = vec![probe(&b)];
    for _ in 0..outputs {
        for _ in 0..per_output {
            b.world.step()?;
        }
        out.push(probe(&b));
    }
    Ok(out)
}

fn max_deviation(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(p, q)| (0..3).map(move |i| (p[i] - q[i]).abs()))
        .fold(0.0, f64::max)
}

fn reference(scene: Scene, cfg: &Config) -> DynResult<Reference> {
    let secs = cfg.durations[scene.index()];
    Ok(match scene {
        Scene::A01 => {
            // Physical pendulum: I_p theta'' = -m g L sin(theta).
            let w2 = G as f64 / (1.0 + PENDULUM_INERTIA);
            let f = |t: f64| -w2 * t.sin();
            let pos = |t: f64| [t.sin(), -t.cos(), 0.0];
            let th0 = std::f64::consts::FRAC_PI_2;
            let fine = rk4_reference(f, pos, th0, 0.0, secs);
            Reference {
                floor: 0.0,
                points: fine,
                how: "exact: RK4 at h = 1/122880 s on I_p theta'' = -m g L sin theta".into(),
            }
        }
        Scene::Conical => {
            // Steady precession about +Y at Omega from (L sin a, -L cos a, 0): the bob at
            // (L sin a cos(Omega t), -L cos a, -L sin a sin(Omega t)).
            let (sa, ca) = CONICAL_ALPHA.sin_cos();
            let omega = (G as f64 / ca).sqrt();
            let outputs = (secs / OUTPUT_STEP).round() as usize;
            let points = (0..=outputs)
                .map(|k| {
                    let t = k as f64 * OUTPUT_STEP;
                    [sa * (omega * t).cos(), -ca, -sa * (omega * t).sin()]
                })
                .collect();
            Reference {
                floor: 0.0,
                points,
                how: "exact: steady precession, Omega^2 = g / (L cos alpha)".into(),
            }
        }
        Scene::A02 => {
            let f = |t: f64| -1.2 * G as f64 * t.cos();
            let pos = |t: f64| [t.cos(), t.sin(), 0.0];
            let fine = rk4_reference(f, pos, std::f64::consts::FRAC_PI_2, -1.0, secs);
            Reference {
                floor: 0.0,
                points: fine,
                how: "exact: RK4 at h = 1/122880 s on theta'' = -(6 g / 5) cos theta".into(),
            }
        }
        _ => {
            let fine = lagrange_trajectory(scene, cfg, cfg.h_ref, secs)?;
            let coarse = lagrange_trajectory(scene, cfg, 2.0 * cfg.h_ref, secs)?;
            Reference {
                floor: max_deviation(&fine, &coarse),
                points: fine,
                how: format!(
                    "converged Lagrange at h = 1/{:.0} s (floor: its deviation from h = 1/{:.0})",
                    1.0 / cfg.h_ref,
                    0.5 / cfg.h_ref
                ),
            }
        }
    })
}

/// One run's figures.
#[derive(Clone, Debug)]
struct Run {
    scene: Scene,
    method: Method,
    dt: f64,
    substeps: usize,
    cpu: f64,
    traj: f64,
    energy: f64,
    gap: f64,
    status: String,
}

impl Run {
    fn ok(&self) -> bool {
        self.status == "ok"
    }

    fn failed(&self) -> bool {
        self.status.starts_with("failed")
    }

    fn setting(&self) -> String {
        format!("1/{:.0} x{}", 1.0 / self.dt, self.substeps)
    }
}

/// Steps `b` for `secs`, comparing with `reference` every output step (if given).
fn simulate(
    scene: Scene,
    mut b: Benchmark,
    dt: f64,
    secs: f64,
    reference: Option<&[[f64; 3]]>,
    budget: f64,
    gap_limit: f64,
) -> (f64, f64, f64, f64, String) {
    let per_output = (OUTPUT_STEP / dt).round().max(1.0) as usize;
    let outputs = (secs / OUTPUT_STEP).round() as usize;
    let (mut busy, mut traj, mut energy, mut gap) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut status = "ok".to_string();
    let mut steps = 0usize;
    'run: for k in 1..=outputs {
        for _ in 0..per_output {
            let t0 = Instant::now();
            let r = b.world.step();
            busy += t0.elapsed().as_secs_f64();
            steps += 1;
            if let Err(e) = r {
                status = format!("failed: {e}");
                break 'run;
            }
        }
        if k == 1 {
            let estimate = busy / steps as f64 * (per_output * outputs) as f64;
            if estimate > budget {
                status = format!("skipped: est. {estimate:.0} s");
                break;
            }
        }
        let p = probe(&b);
        if let Some(r) = reference {
            traj = traj.max(max_deviation(&[p], &r[k..=k]));
        }
        energy = energy.max(((b.energy() - b.initial_energy) / b.energy_scale).abs() as f64);
        gap = gap.max(b.max_gap().map_or(f64::NAN, |g| g as f64));
        let finite = p.iter().all(|x| x.is_finite()) && energy.is_finite() && gap.is_finite();
        if !finite {
            status = "failed: not finite".into();
            break;
        }
        if gap > gap_limit {
            status = format!("failed: gap {gap:.2e} m");
            break;
        }
        if energy > 10.0 {
            status = format!("failed: energy error {energy:.1e}");
            break;
        }
        if scene == Scene::A02 {
            let rb = &b.world.physics.bodies[b.bodies[1]];
            let x = rb.position().rotation * Vector::X;
            let turn = (x.y as f64).atan2(x.x as f64).abs();
            if turn > 0.5 {
                status = format!("failed: branch switch (coupler {turn:.2} rad)");
                break;
            }
        }
    }
    let sim = steps as f64 * dt;
    (busy / sim.max(1e-12), traj, energy, gap, status)
}

/// Progress reporting: `\r` on a terminal, plain lines otherwise.
struct Progress {
    total: usize,
    done: usize,
    start: Instant,
    tty: bool,
}

impl Progress {
    fn tick(&mut self, what: &str) {
        self.done += 1;
        let line = format!(
            "[{:>4}/{}] {:>6.0} s  {what}",
            self.done,
            self.total,
            self.start.elapsed().as_secs_f64()
        );
        let mut err = std::io::stderr();
        if self.tty {
            let _ = write!(err, "\r{line:<100}");
            let _ = err.flush();
        } else {
            let _ = writeln!(err, "{line}");
        }
    }

    fn finish(&self) {
        if self.tty {
            eprintln!();
        }
    }
}

fn run(cfg: &Config, out: &Path) -> DynResult<()> {
    plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
        .map_err(|_| "the bundled font does not load")?;
    std::fs::create_dir_all(out)?;
    let wp_runs = SCENES.len() * METHODS.len() * cfg.rates.len() * cfg.substeps.len();
    let stab = METHODS.len() * cfg.stability_ratios.len() * cfg.substeps.len();
    let scal = 4 * cfg.scaling_n.len();
    let pen = (cfg.penalty_ks.len() + 1) * cfg.penalty_rates.len();
    let sing = METHODS.len() * cfg.singular_deltas.len() * cfg.singular_rates.len();
    let mut progress = Progress {
        total: if cfg.maps_only {
            stab + pen + sing
        } else {
            SCENES.len() + wp_runs + stab + scal + pen + sing
        },
        done: 0,
        start: Instant::now(),
        tty: std::io::stderr().is_terminal(),
    };
    if cfg.maps_only {
        return maps_only(cfg, out, &mut progress);
    }
    let mut runs = Vec::new();
    let mut refs = Vec::new();
    for scene in SCENES {
        let r = reference(scene, cfg)?;
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
                    });
                }
            }
        }
        refs.push((scene, r.how, r.floor));
    }
    let stability = stability_map(cfg, &mut progress);
    let penalty = penalty_map(cfg, &mut progress);
    let singular = singular_map(cfg, &mut progress);
    let scaling = scaling(cfg, &mut progress);
    progress.finish();
    let wall = progress.start.elapsed().as_secs_f64();

    write_csv(&out.join("runs.csv"), &runs)?;
    let mut files = vec!["runs.csv".to_string()];
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
            chart.save(out, &name, (960, 640), &mut files)?;
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
        .save(
            out,
            &format!("order_{}", scene.key()),
            (960, 640),
            &mut files,
        )?;
    }
    Chart::Stability(cfg, &stability).save(out, "stability_chain", (1000, 680), &mut files)?;
    Chart::Penalty(cfg, &penalty).save(out, "stability_penalty", (900, 640), &mut files)?;
    Chart::Singular(cfg, &singular).save(out, "stability_singular", (1100, 720), &mut files)?;
    write_map_csv(&out.join("stability_penalty.csv"), &penalty)?;
    write_map_csv(&out.join("stability_singular.csv"), &singular)?;
    files.push("stability_penalty.csv".into());
    files.push("stability_singular.csv".into());
    Chart::Scaling(&scaling).save(out, "scaling_chain", (900, 600), &mut files)?;
    let mut summary = summary(cfg, &runs, &refs, &stability, &scaling, wall);
    map_summary(&mut summary, cfg, &penalty, &singular);
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

/// `--maps`: the three stability maps only.
fn maps_only(cfg: &Config, out: &Path, progress: &mut Progress) -> DynResult<()> {
    let stability = stability_map(cfg, progress);
    let penalty = penalty_map(cfg, progress);
    let singular = singular_map(cfg, progress);
    progress.finish();
    let wall = progress.start.elapsed().as_secs_f64();
    let mut files = Vec::new();
    Chart::Stability(cfg, &stability).save(out, "stability_chain", (1000, 680), &mut files)?;
    Chart::Penalty(cfg, &penalty).save(out, "stability_penalty", (900, 640), &mut files)?;
    Chart::Singular(cfg, &singular).save(out, "stability_singular", (1100, 720), &mut files)?;
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

fn write_csv(path: &Path, runs: &[Run]) -> DynResult<()> {
    let mut s = String::from(
        "scene,method,dt,substeps,cpu_s_per_sim_s,traj_err,energy_drift,max_gap,status\n",
    );
    for r in runs {
        writeln!(
            s,
            "{},{},{:.8},{},{:.4e},{:.4e},{:.4e},{:.4e},{}",
            r.scene.key(),
            r.method.name(),
            r.dt,
            r.substeps,
            r.cpu,
            r.traj,
            r.energy,
            r.gap,
            r.status.replace(',', ";")
        )?;
    }
    std::fs::write(path, s)?;
    Ok(())
}

/// Outcome of one cell of the chain stability map.
#[derive(Clone, Debug)]
struct Cell {
    method: Method,
    ratio: f64,
    substeps: usize,
    gap: f64,
    /// "ok", "gap" (> 1 cm), "blew up" or "skipped".
    class: &'static str,
    status: String,
}

/// The chain (`stability_links` links, released at 20 deg) at dt = 1/60 for each end-mass ratio
/// and substep count: ok, gap > 1 cm, or blew up (step error, non-finite, gap > 1 m or energy
/// error > 10 x the scale).
fn stability_map(cfg: &Config, progress: &mut Progress) -> Vec<Cell> {
    let dt = 1.0 / 60.0;
    let mut cells = Vec::new();
    for method in METHODS {
        for &ratio in &cfg.stability_ratios {
            for &sub in &cfg.substeps {
                progress.tick(&format!("stability {} 1:{ratio} x{sub}", method.name()));
                let built = chain(settings(method, dt, sub), cfg.stability_links, ratio);
                let Some(b) = built.ok().and_then(|b| with_method(b, method)) else {
                    continue;
                };
                let (_, _, _, gap, status) = simulate(
                    Scene::Chain,
                    b,
                    dt,
                    cfg.stability_secs,
                    None,
                    cfg.budget,
                    1.0,
                );
                let class = if status.starts_with("skipped") {
                    "skipped"
                } else if status != "ok" {
                    "blew up"
                } else if gap > 0.01 {
                    "gap"
                } else {
                    "ok"
                };
                cells.push(Cell {
                    method,
                    ratio,
                    substeps: sub,
                    gap,
                    class,
                    status,
                });
            }
        }
    }
    cells
}

/// Cost per step (dt 1/60, 4 substeps) of a chain of `n` links, ratio 1.
#[derive(Clone, Debug)]
struct Cost {
    method: Method,
    n: usize,
    us_per_step: f64,
}

fn scaling(cfg: &Config, progress: &mut Progress) -> Vec<Cost> {
    let methods = [
        Method::Lagrange,
        Method::Penalty(1e6),
        Method::Impulse,
        Method::Multibody,
    ];
    let min_wall = if cfg.quick { 0.05 } else { 0.5 };
    let mut out = Vec::new();
    for method in methods {
        for &n in &cfg.scaling_n {
            progress.tick(&format!("scaling {} N = {n}", method.name()));
            if method == Method::Multibody && n > 100 {
                continue;
            }
            let Some(mut b) = chain(settings(method, 1.0 / 60.0, 4), n, 1.0)
                .ok()
                .and_then(|b| with_method(b, method))
            else {
                continue;
            };
            // Two warm-up steps (first factorisation, Rapier's set-up), then timed steps.
            if (0..2).any(|_| b.world.step().is_err()) {
                continue;
            }
            let (mut busy, mut steps) = (0.0, 0usize);
            while (busy < min_wall || steps < 3) && steps < 300 {
                let t0 = Instant::now();
                let r = b.world.step();
                busy += t0.elapsed().as_secs_f64();
                steps += 1;
                if r.is_err() {
                    break;
                }
            }
            out.push(Cost {
                method,
                n,
                us_per_step: busy * 1e6 / steps as f64,
            });
        }
    }
    out
}

/// The charts, each drawn on any plotters backend.
enum Chart<'a> {
    WorkPrecision {
        caption: &'a str,
        y_desc: &'a str,
        runs: &'a [&'a Run],
        /// Energy error instead of the trajectory error (no IFToMM levels).
        energy: bool,
    },
    Stability(&'a Config, &'a [Cell]),
    Penalty(&'a Config, &'a [MapCell]),
    Singular(&'a Config, &'a [MapCell]),
    Scaling(&'a [Cost]),
    /// Trajectory error against the substep h (the order of each method).
    Convergence {
        caption: &'a str,
        runs: &'a [&'a Run],
    },
}

impl Chart<'_> {
    /// Draws `name.png` and `name.svg` into `out`.
    fn save(
        &self,
        out: &Path,
        name: &str,
        size: (u32, u32),
        files: &mut Vec<String>,
    ) -> DynResult<()> {
        let png = out.join(format!("{name}.png"));
        self.draw(BitMapBackend::new(&png, size).into_drawing_area())?;
        let svg = out.join(format!("{name}.svg"));
        self.draw(SVGBackend::new(&svg, size).into_drawing_area())?;
        files.push(format!("{name}.png"));
        files.push(format!("{name}.svg"));
        Ok(())
    }

    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> DynResult<()>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        match self {
            Chart::WorkPrecision {
                caption,
                y_desc,
                runs,
                energy,
            } => work_precision(&root, caption, y_desc, runs, *energy)?,
            Chart::Stability(cfg, cells) => draw_stability(&root, cfg, cells)?,
            Chart::Penalty(cfg, cells) => draw_penalty(&root, cfg, cells)?,
            Chart::Singular(cfg, cells) => draw_singular(&root, cfg, cells)?,
            Chart::Scaling(costs) => draw_scaling(&root, costs)?,
            Chart::Convergence { caption, runs } => draw_convergence(&root, caption, runs)?,
        }
        root.present()?;
        Ok(())
    }
}

/// Per method, the smallest trajectory error at each substep size `h = dt / substeps` (ok runs).
fn by_substep(runs: &[&Run], method: Method) -> Vec<(f64, f64)> {
    let mut pts: Vec<(f64, f64)> = Vec::new();
    for r in runs.iter().filter(|r| r.method == method && r.ok()) {
        let h = r.dt / r.substeps as f64;
        let e = r.traj.max(ERR_FLOOR);
        match pts.iter_mut().find(|(x, _)| (x / h - 1.0).abs() < 1e-9) {
            Some(p) => p.1 = p.1.min(e),
            None => pts.push((h, e)),
        }
    }
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    pts
}

/// Observed order: the least-squares slope of log(error) against log(h) over the points with
/// an error above `floor` (NaN with fewer than two).
fn observed_order(pts: &[(f64, f64)], floor: f64) -> f64 {
    let p: Vec<(f64, f64)> = pts
        .iter()
        .filter(|(_, e)| *e > floor)
        .map(|(h, e)| (h.ln(), e.ln()))
        .collect();
    if p.len() < 2 {
        return f64::NAN;
    }
    let n = p.len() as f64;
    let (mx, my) = (
        p.iter().map(|q| q.0).sum::<f64>() / n,
        p.iter().map(|q| q.1).sum::<f64>() / n,
    );
    let sxy: f64 = p.iter().map(|q| (q.0 - mx) * (q.1 - my)).sum();
    let sxx: f64 = p.iter().map(|q| (q.0 - mx) * (q.0 - mx)).sum();
    sxy / sxx
}

fn draw_convergence<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    caption: &str,
    runs: &[&Run],
) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let all: Vec<(Method, Vec<(f64, f64)>)> = METHODS
        .iter()
        .map(|m| (*m, by_substep(runs, *m)))
        .filter(|(_, p)| !p.is_empty())
        .collect();
    let hs = all.iter().flat_map(|(_, p)| p.iter().map(|q| q.0));
    let (x0, x1) = hs.fold((f64::INFINITY, 0.0f64), |(a, b), h| (a.min(h), b.max(h)));
    let (x0, x1) = (x0 / 1.5, x1 * 1.5);
    let es: Vec<f64> = all
        .iter()
        .flat_map(|(_, p)| p.iter().map(|q| q.1))
        .collect();
    let y0 = es.iter().copied().fold(1e-4, f64::min) / 3.0;
    let y1 = es.iter().copied().fold(1.0, f64::max) * 5.0;
    let mut chart = ChartBuilder::on(root)
        .caption(caption, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("substep h (s)")
        .y_desc("trajectory error (m), best run at each h")
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    // Slope guides through the coarsest point of the first- and second-order Lagrange runs.
    let gray = RGBColor(120, 120, 120);
    for (method, slope) in [(Method::Lagrange, 1.0), (Method::Rattle, 2.0)] {
        if let Some((_, p)) = all.iter().find(|(m, _)| *m == method)
            && let Some(&(h, e)) = p.last()
        {
            let at = |x: f64| e * 2.0 * (x / h).powf(slope);
            chart.draw_series(LineSeries::new(
                [(x0, at(x0).max(y0)), (h, at(h))],
                gray.stroke_width(1),
            ))?;
            chart.draw_series(std::iter::once(Text::new(
                format!("slope {slope:.0}"),
                (h / 1.4, at(h) * 1.6),
                ("sans-serif", 13).into_font().color(&gray),
            )))?;
        }
    }
    for (method, pts) in &all {
        let c = method.color();
        let order = observed_order(pts, 1e-9);
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2)))?
            .label(format!("{} (order {order:.2})", method.name()))
            .legend(move |(x, yy)| PathElement::new([(x, yy), (x + 20, yy)], c.stroke_width(3)));
        chart.draw_series(pts.iter().map(|&q| Circle::new(q, 3, c.filled())))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()?;
    Ok(())
}

/// Runs on the Pareto front (no other run both cheaper and more accurate), by CPU time.
fn pareto<'a>(runs: impl Iterator<Item = &'a Run>, y: impl Fn(&Run) -> f64) -> Vec<&'a Run> {
    let mut ok: Vec<&Run> = runs.filter(|r| r.ok() && y(r).is_finite()).collect();
    ok.sort_by(|a, b| a.cpu.total_cmp(&b.cpu));
    let mut best = f64::INFINITY;
    let mut front = Vec::new();
    for r in ok {
        if y(r) < best {
            best = y(r);
            front.push(r);
        }
    }
    front
}

/// Floor of plotted errors (a run can hit zero to rounding).
const ERR_FLOOR: f64 = 1e-13;

fn work_precision<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    caption: &str,
    y_desc: &str,
    runs: &[&Run],
    energy: bool,
) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let y = |r: &Run| (if energy { r.energy } else { r.traj }).max(ERR_FLOOR);
    let shown: Vec<&Run> = runs
        .iter()
        .copied()
        .filter(|r| !r.status.starts_with("skipped"))
        .collect();
    let cpus: Vec<f64> = shown.iter().map(|r| r.cpu).filter(|c| *c > 0.0).collect();
    let (x0, x1) = cpus
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), c| (a.min(*c), b.max(*c)));
    let (x0, x1) = ((x0.min(0.5) / 2.0).max(1e-4), (x1.max(2.0) * 2.0));
    let ok_errs: Vec<f64> = shown.iter().filter(|r| r.ok()).map(|r| y(r)).collect();
    let y0 = ok_errs.iter().copied().fold(1e-4, f64::min) / 3.0;
    let y_top_data = ok_errs.iter().copied().fold(1.0, f64::max);
    let y1 = y_top_data * 30.0;
    let fail_y = y_top_data * 10.0;
    let mut chart = ChartBuilder::on(root)
        .caption(caption, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("CPU s per simulated s (single thread, stepping loop only)")
        .y_desc(y_desc)
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    let gray = RGBColor(110, 110, 110);
    if !energy {
        for (level, label) in [
            (1e-1, "IFToMM low precision 1e-1 m"),
            (1e-3, "IFToMM high precision 1e-3 m"),
        ] {
            if level > y0 && level < y1 {
                chart.draw_series(LineSeries::new(
                    [(x0, level), (x1, level)],
                    gray.stroke_width(1),
                ))?;
                chart.draw_series(std::iter::once(Text::new(
                    label,
                    (x0 * 1.1, level * 1.25),
                    ("sans-serif", 13).into_font().color(&gray),
                )))?;
            }
        }
    }
    if 1.0 > x0 && 1.0 < x1 {
        chart.draw_series(LineSeries::new(
            [(1.0, y0), (1.0, y1)],
            BLACK.stroke_width(1),
        ))?;
        chart.draw_series(std::iter::once(Text::new(
            "real time",
            (1.08, y0 * 2.0),
            ("sans-serif", 13).into_font(),
        )))?;
    }
    // Failed runs: crosses along the top at their CPU time.
    chart.draw_series(LineSeries::new(
        [(x0, fail_y / 1.6), (x1, fail_y / 1.6)],
        RGBColor(220, 220, 220).stroke_width(1),
    ))?;
    chart.draw_series(std::iter::once(Text::new(
        "failed runs (x)",
        (x0 * 1.1, fail_y * 1.35),
        ("sans-serif", 13).into_font().color(&gray),
    )))?;
    for method in METHODS {
        let mine: Vec<&Run> = shown
            .iter()
            .copied()
            .filter(|r| r.method == method)
            .collect();
        if mine.is_empty() {
            continue;
        }
        let c = method.color();
        let front = pareto(mine.iter().copied(), y);
        chart
            .draw_series(LineSeries::new(
                front.iter().map(|r| (r.cpu, y(r))),
                c.stroke_width(2),
            ))?
            .label(method.name())
            .legend(move |(x, yy)| PathElement::new([(x, yy), (x + 20, yy)], c.stroke_width(3)));
        chart.draw_series(
            mine.iter()
                .filter(|r| r.ok())
                .map(|r| Circle::new((r.cpu, y(r)), 3, c.filled())),
        )?;
        chart.draw_series(
            mine.iter()
                .filter(|r| r.failed())
                .map(|r| Cross::new((r.cpu.max(x0), fail_y), 5, c.stroke_width(2))),
        )?;
    }
    let front = pareto(shown.iter().copied(), y);
    chart
        .draw_series(
            front
                .iter()
                .map(|r| Circle::new((r.cpu, y(r)), 7, BLACK.stroke_width(1))),
        )?
        .label("Pareto front (all methods)")
        .legend(|(x, yy)| Circle::new((x + 10, yy), 6, BLACK.stroke_width(1)));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()?;
    Ok(())
}

fn draw_stability<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    cfg: &Config,
    cells: &[Cell],
) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let title = format!(
        "chain of {} links, dt 1/60, {} s: end-mass ratio x substeps (green ok, orange gap > 1 cm, red blew up, grey skipped)",
        cfg.stability_links, cfg.stability_secs
    );
    let (top, body) = root.split_vertically(40);
    top.draw(&Text::new(title, (10, 12), ("sans-serif", 15).into_font()))?;
    let panels = body.split_evenly((2, 3));
    let nr = cfg.stability_ratios.len() as i32;
    let ns = cfg.substeps.len() as i32;
    for (panel, method) in panels.iter().zip(METHODS) {
        let mut chart = ChartBuilder::on(panel)
            .caption(method.name(), ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(35)
            .y_label_area_size(55)
            .build_cartesian_2d(0f64..ns as f64, 0f64..nr as f64)?;
        let subs = cfg.substeps.clone();
        let ratios = cfg.stability_ratios.clone();
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(ns as usize * 2 + 1)
            .y_labels(nr as usize * 2 + 1)
            .x_label_formatter(&|x| {
                let i = (x - 0.5).round();
                if (x - 0.5 - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < subs.len() {
                    format!("{}", subs[i as usize])
                } else {
                    String::new()
                }
            })
            .y_label_formatter(&|y| {
                let i = (y - 0.5).round();
                if (y - 0.5 - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < ratios.len() {
                    format!("1:{}", ratios[i as usize])
                } else {
                    String::new()
                }
            })
            .x_desc("substeps")
            .label_style(("sans-serif", 12))
            .axis_desc_style(("sans-serif", 12))
            .draw()?;
        for (i, &sub) in cfg.substeps.iter().enumerate() {
            for (j, &ratio) in cfg.stability_ratios.iter().enumerate() {
                let cell = cells
                    .iter()
                    .find(|c| c.method == method && c.ratio == ratio && c.substeps == sub);
                let (color, label) = match cell {
                    None => (RGBColor(240, 240, 240), "n/a".to_string()),
                    Some(c) => match c.class {
                        "ok" => (RGBColor(120, 200, 120), format!("{:.0e}", c.gap)),
                        "gap" => (RGBColor(250, 170, 70), format!("{:.0e}", c.gap)),
                        "blew up" => (RGBColor(220, 70, 60), "blew up".into()),
                        _ => (RGBColor(190, 190, 190), "skipped".into()),
                    },
                };
                let (x, y) = (i as f64, j as f64);
                chart.draw_series(std::iter::once(Rectangle::new(
                    [(x + 0.03, y + 0.03), (x + 0.97, y + 0.97)],
                    color.filled(),
                )))?;
                chart.draw_series(std::iter::once(Text::new(
                    label,
                    (x + 0.12, y + 0.6),
                    ("sans-serif", 12).into_font(),
                )))?;
            }
        }
    }
    Ok(())
}

fn draw_scaling<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, costs: &[Cost]) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let n1 = costs.iter().map(|c| c.n).max().unwrap_or(10) as f64;
    let (y0, y1) = costs.iter().fold((f64::INFINITY, 0.0f64), |(a, b), c| {
        (a.min(c.us_per_step), b.max(c.us_per_step))
    });
    let mut chart = ChartBuilder::on(root)
        .caption(
            "chain cost per step (dt 1/60, 4 substeps, ratio 1, single thread)",
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(
            (8.0..n1 * 1.3).log_scale(),
            ((y0 / 2.0).max(0.1)..y1 * 3.0).log_scale(),
        )?;
    chart
        .configure_mesh()
        .x_desc("links N")
        .y_desc("us per step")
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()?;
    for method in [
        Method::Lagrange,
        Method::Penalty(1e6),
        Method::Impulse,
        Method::Multibody,
    ] {
        let pts: Vec<(f64, f64)> = costs
            .iter()
            .filter(|c| c.method == method)
            .map(|c| (c.n as f64, c.us_per_step))
            .collect();
        if pts.is_empty() {
            continue;
        }
        let c = method.color();
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2)))?
            .label(method.name())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], c.stroke_width(3)));
        chart.draw_series(pts.iter().map(|p| Circle::new(*p, 4, c.filled())))?;
    }
    // Slope guides from the smallest Lagrange point: N and N^3.
    if let Some(base) = costs.iter().find(|c| c.method == Method::Lagrange) {
        let (nb, yb) = (base.n as f64, base.us_per_step / 3.0);
        for (p, label) in [(1.0, "~N"), (3.0, "~N^3")] {
            let end = (n1.min(nb * 10f64.powf(3.0 / p)), 0.0);
            let end = (end.0, yb * (end.0 / nb).powf(p));
            chart.draw_series(LineSeries::new(
                [(nb, yb), end],
                BLACK.mix(0.4).stroke_width(1),
            ))?;
            chart.draw_series(std::iter::once(Text::new(
                label,
                end,
                ("sans-serif", 13).into_font(),
            )))?;
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()?;
    Ok(())
}

/// One cell of the penalty or singular-pose map.
#[derive(Clone, Debug)]
struct MapCell {
    method: Method,
    /// Row value: penalty stiffness (infinity for the Lagrange row) or start distance (rad).
    row: f64,
    dt: f64,
    traj: f64,
    gap: f64,
    /// "<=1e-3", "<=1e-1", ">1e-1", "gap" (> 0.1 m), "branch switch", "blew up", "skipped".
    class: &'static str,
    status: String,
}

/// The accuracy class of a run: its status first, then the IFToMM levels of its error.
fn classify(status: &str, traj: f64) -> &'static str {
    if status.starts_with("skipped") {
        "skipped"
    } else if status.contains("branch switch") {
        "branch switch"
    } else if status.starts_with("failed: gap") {
        "gap"
    } else if status != "ok" {
        "blew up"
    } else if traj <= 1e-3 {
        "<=1e-3"
    } else if traj <= 1e-1 {
        "<=1e-1"
    } else {
        ">1e-1"
    }
}

fn class_color(class: &str) -> RGBColor {
    match class {
        "<=1e-3" => RGBColor(110, 190, 110),
        "<=1e-1" => RGBColor(200, 225, 120),
        ">1e-1" => RGBColor(250, 170, 70),
        "branch switch" => RGBColor(170, 120, 210),
        "gap" => RGBColor(205, 130, 90),
        "blew up" => RGBColor(220, 70, 60),
        _ => RGBColor(190, 190, 190),
    }
}

/// The A01 pendulum (released horizontally) with a penalty revolute of stiffness `k` (N/m and
/// N m/rad; infinity: the Lagrange method) at one substep of `dt`, for `cfg.penalty_secs`
/// against the exact pendulum.
fn penalty_map(cfg: &Config, progress: &mut Progress) -> Vec<MapCell> {
    let secs = cfg.penalty_secs;
    let w2 = G as f64 / (1.0 + PENDULUM_INERTIA);
    let exact = rk4_reference(
        |t| -w2 * t.sin(),
        |t| [t.sin(), -t.cos(), 0.0],
        std::f64::consts::FRAC_PI_2,
        0.0,
        secs,
    );
    let mut cells = Vec::new();
    let rows: Vec<f64> = cfg
        .penalty_ks
        .iter()
        .copied()
        .chain([f64::INFINITY])
        .collect();
    for &k in &rows {
        let method = if k.is_finite() {
            Method::Penalty(k)
        } else {
            Method::Lagrange
        };
        for &rate in &cfg.penalty_rates {
            let dt = 1.0 / rate as f64;
            progress.tick(&format!("penalty map k = {k:.0e} 1/{rate}"));
            let Some(b) = build(Scene::A01, cfg, method, dt, 1) else {
                continue;
            };
            let (_, traj, _, gap, status) = simulate(
                Scene::A01,
                b,
                dt,
                secs,
                Some(&exact),
                cfg.budget,
                0.1 * Scene::A01.length(),
            );
            cells.push(MapCell {
                method,
                row: k,
                dt,
                traj,
                gap,
                class: classify(&status, traj),
                status,
            });
        }
    }
    cells
}

/// The A02 parallelogram four-bar (three 1 m, 1 kg bars; `benchmarks::four_bar_parallelogram`)
/// released at rest with the cranks at `theta0` from +X: the singular pose is `theta0 = 0`
/// (cranks collinear with the ground link).
fn four_bar_at(settings: WorldSettings, theta0: f64) -> Result<Benchmark, rapier3d_mpc184::Error> {
    use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder};
    let (m, l) = (1.0 as Real, 1.0 as Real);
    let it = m * l * l / 12.0;
    let axial = benchmarks::FOUR_BAR_AXIAL_INERTIA;
    let th = theta0 as Real;
    let dir = Vector::new(th.cos(), th.sin(), 0.0);
    let mut world = Mpc184World::new(settings);
    world.physics.gravity = Vector::new(0.0, -G, 0.0);
    let mut body = |centre: Vector, angle: Real, inertia: Vector| {
        world.physics.bodies.insert(
            RigidBodyBuilder::dynamic()
                .translation(centre)
                .rotation(Vector::new(0.0, 0.0, angle))
                .additional_mass_properties(MassProperties::new(Vector::ZERO, m, inertia))
                .can_sleep(false),
        )
    };
    // Crank and rocker lie along their local Y (as in the benchmark), turned by theta0 - pi/2.
    let turn = th - std::f64::consts::FRAC_PI_2 as Real;
    let crank = body(dir * (0.5 * l), turn, Vector::new(it, axial, it));
    let coupler = body(
        dir * l + Vector::new(0.5 * l, 0.0, 0.0),
        0.0,
        Vector::new(axial, it, it),
    );
    let o1 = Vector::new(l, 0.0, 0.0);
    let rocker = body(o1 + dir * (0.5 * l), turn, Vector::new(it, axial, it));
    let mut joints = Vec::new();
    let mut joint_bodies = Vec::new();
    for (b1, b2, at) in [
        (None, Some(crank), Vector::ZERO),
        (Some(crank), Some(coupler), dir * l),
        (Some(coupler), Some(rocker), o1 + dir * l),
        (None, Some(rocker), o1),
    ] {
        joints.push(world.insert_joint(b1, b2, Mpc184Joint::revolute(Axis::Z, at))?);
        joint_bodies.push([b1, b2]);
    }
    // Heights of the centres: (L/2, L, L/2) sin theta; lowest 2 m g L below the pivots.
    let potential = 2.0 * m * G * l * th.sin();
    Ok(Benchmark {
        world,
        bodies: vec![crank, coupler, rocker],
        joints,
        joint_bodies,
        initial_energy: potential,
        energy_scale: potential + 2.0 * m * G * l,
        probe: Probe {
            body: crank,
            local: Vector::new(0.0, 0.5 * l, 0.0),
        },
        duration: 4.0,
    })
}

/// The four-bar released at `delta` above its singular pose, per method and dt (one substep),
/// for `cfg.singular_secs` against RK4 on `theta'' = -(6 g / 5) cos theta`.
fn singular_map(cfg: &Config, progress: &mut Progress) -> Vec<MapCell> {
    let secs = cfg.singular_secs;
    let mut cells = Vec::new();
    for &delta in &cfg.singular_deltas {
        let exact = rk4_reference(
            |t| -1.2 * G as f64 * t.cos(),
            |t| [t.cos(), t.sin(), 0.0],
            delta,
            0.0,
            secs,
        );
        for method in METHODS {
            for &rate in &cfg.singular_rates {
                let dt = 1.0 / rate as f64;
                progress.tick(&format!(
                    "singular map {} delta {delta:.0e} 1/{rate}",
                    method.name()
                ));
                let Some(b) = four_bar_at(settings(method, dt, 1), delta)
                    .ok()
                    .and_then(|b| with_method(b, method))
                else {
                    continue;
                };
                let (_, traj, _, gap, status) = simulate(
                    Scene::A02,
                    b,
                    dt,
                    secs,
                    Some(&exact),
                    cfg.budget,
                    0.1 * Scene::A02.length(),
                );
                cells.push(MapCell {
                    method,
                    row: delta,
                    dt,
                    traj,
                    gap,
                    class: classify(&status, traj),
                    status,
                });
            }
        }
    }
    cells
}

fn write_map_csv(path: &Path, cells: &[MapCell]) -> DynResult<()> {
    let mut s = String::from("method,row,dt,traj_err,max_gap,class,status\n");
    for c in cells {
        writeln!(
            s,
            "{},{:.4e},{:.8},{:.4e},{:.4e},{},{}",
            c.method.name(),
            c.row,
            c.dt,
            c.traj,
            c.gap,
            c.class,
            c.status.replace(',', ";")
        )?;
    }
    std::fs::write(path, s)?;
    Ok(())
}

/// One grid panel: columns `xs` (labels), rows `ys` (labels, bottom up), each cell a colour and
/// a label.
fn draw_grid<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    caption: &str,
    x_desc: &str,
    xs: &[String],
    ys: &[String],
    cell: impl Fn(usize, usize) -> Option<(RGBColor, String)>,
    font: u32,
) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let (nx, ny) = (xs.len() as i32, ys.len() as i32);
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 16))
        .margin(8)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(0f64..nx as f64, 0f64..ny as f64)?;
    let label = |v: f64, names: &[String]| {
        let i = (v - 0.5).round();
        if (v - 0.5 - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < names.len() {
            names[i as usize].clone()
        } else {
            String::new()
        }
    };
    chart
        .configure_mesh()
        .disable_mesh()
        .x_labels(nx as usize * 2 + 1)
        .y_labels(ny as usize * 2 + 1)
        .x_label_formatter(&|x| label(*x, xs))
        .y_label_formatter(&|y| label(*y, ys))
        .x_desc(x_desc)
        .label_style(("sans-serif", 12))
        .axis_desc_style(("sans-serif", 12))
        .draw()?;
    for i in 0..xs.len() {
        for j in 0..ys.len() {
            let (color, text) = cell(i, j).unwrap_or((RGBColor(240, 240, 240), "n/a".to_string()));
            let (x, y) = (i as f64, j as f64);
            chart.draw_series(std::iter::once(Rectangle::new(
                [(x + 0.03, y + 0.03), (x + 0.97, y + 0.97)],
                color.filled(),
            )))?;
            chart.draw_series(std::iter::once(Text::new(
                text,
                (x + 0.08, y + 0.62),
                ("sans-serif", font).into_font(),
            )))?;
        }
    }
    Ok(())
}

fn map_label(c: &MapCell) -> String {
    match c.class {
        "blew up" => "blew up".into(),
        "branch switch" => "branch".into(),
        "gap" => format!("gap {:.0e}", c.gap),
        "skipped" => "skipped".into(),
        _ => format!("{:.0e}", c.traj),
    }
}

const MAP_LEGEND: &str = "green <= 1e-3 m, light green <= 1e-1 m, orange > 1e-1 m, brown joint gap > 0.1 m (stopped there), violet branch switch, red blew up, grey n/a";

/// Draws a map's title (at `size` points) and the class legend on a 50-pixel band at the top of
/// `root`; returns the area below for the grid.
fn map_header<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    size: u32,
) -> DynResult<DrawingArea<DB, Shift>>
where
    DB::ErrorType: 'static,
{
    let (top, body) = root.split_vertically(50);
    top.draw(&Text::new(title, (10, 8), ("sans-serif", size).into_font()))?;
    top.draw(&Text::new(
        MAP_LEGEND,
        (10, 28),
        ("sans-serif", 12).into_font(),
    ))?;
    Ok(body)
}

fn draw_penalty<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    cfg: &Config,
    cells: &[MapCell],
) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let title = format!(
        "penalty pendulum (A01, 90 deg, {} s, 1 substep): stiffness x dt, max bob error vs exact",
        cfg.penalty_secs
    );
    let body = map_header(root, &title, 15)?;
    let xs: Vec<String> = cfg.penalty_rates.iter().map(|r| format!("1/{r}")).collect();
    let rows: Vec<f64> = cfg
        .penalty_ks
        .iter()
        .copied()
        .chain([f64::INFINITY])
        .collect();
    let ys: Vec<String> = rows
        .iter()
        .map(|k| {
            if k.is_finite() {
                format!("k {k:.0e}")
            } else {
                "lagrange".into()
            }
        })
        .collect();
    draw_grid(
        &body,
        "k (N/m, N m/rad) against dt (s)",
        "dt (s)",
        &xs,
        &ys,
        |i, j| {
            let dt = 1.0 / cfg.penalty_rates[i] as f64;
            cells
                .iter()
                .find(|c| c.row == rows[j] && (c.dt - dt).abs() < 1e-12)
                .map(|c| (class_color(c.class), map_label(c)))
        },
        13,
    )
}

fn draw_singular<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    cfg: &Config,
    cells: &[MapCell],
) -> DynResult<()>
where
    DB::ErrorType: 'static,
{
    let title = format!(
        "parallelogram four-bar (A02) released at rest delta above its singular pose, {} s, 1 substep: delta x dt, max crank-tip error vs exact",
        cfg.singular_secs
    );
    let body = map_header(root, &title, 14)?;
    let xs: Vec<String> = cfg
        .singular_rates
        .iter()
        .map(|r| format!("1/{r}"))
        .collect();
    let ys: Vec<String> = cfg
        .singular_deltas
        .iter()
        .map(|d| format!("{d:.0e}"))
        .collect();
    for (panel, method) in body.split_evenly((2, 3)).iter().zip(METHODS) {
        draw_grid(
            panel,
            &method.name(),
            "dt (s)",
            &xs,
            &ys,
            |i, j| {
                let dt = 1.0 / cfg.singular_rates[i] as f64;
                cells
                    .iter()
                    .find(|c| {
                        c.method == method
                            && c.row == cfg.singular_deltas[j]
                            && (c.dt - dt).abs() < 1e-12
                    })
                    .map(|c| (class_color(c.class), map_label(c)))
            },
            10,
        )?;
    }
    Ok(())
}

/// Appends the two maps' findings to the summary: per row or method, the cells in each class.
fn map_summary(s: &mut String, cfg: &Config, penalty: &[MapCell], singular: &[MapCell]) {
    let line = |cells: &[&MapCell]| -> String {
        cells
            .iter()
            .map(|c| {
                format!(
                    "1/{:.0} {}{}",
                    1.0 / c.dt,
                    c.class,
                    match c.class {
                        "blew up" | "branch switch" | "skipped" => String::new(),
                        "gap" => format!(" ({:.1e} m)", c.gap),
                        _ => format!(" ({:.1e} m)", c.traj),
                    }
                )
            })
            .collect::<Vec<_>>()
            .join("; ")
    };
    let _ = writeln!(
        s,
        "\n## Penalty stiffness x dt (A01 pendulum, 90 deg, {} s, 1 substep)\n\n| k | cells by dt |\n|---|---|",
        cfg.penalty_secs
    );
    let mut rows: Vec<f64> = penalty.iter().map(|c| c.row).collect();
    rows.dedup();
    for k in rows {
        let mine: Vec<&MapCell> = penalty.iter().filter(|c| c.row == k).collect();
        let name = if k.is_finite() {
            format!("{k:.0e}")
        } else {
            "lagrange".into()
        };
        let _ = writeln!(s, "| {name} | {} |", line(&mine));
    }
    let _ = writeln!(
        s,
        "\n## Four-bar released delta above its singular pose x dt ({} s, 1 substep)\n\n| method | delta (rad) | cells by dt |\n|---|---|---|",
        cfg.singular_secs
    );
    for method in METHODS {
        for &d in &cfg.singular_deltas {
            let mine: Vec<&MapCell> = singular
                .iter()
                .filter(|c| c.method == method && c.row == d)
                .collect();
            if mine.is_empty() {
                continue;
            }
            let _ = writeln!(s, "| {} | {d:.0e} | {} |", method.name(), line(&mine));
        }
    }
}

fn fmt_run(r: &Run, y: f64) -> String {
    format!(
        "{} {} ({:.2e} s/s, {y:.1e})",
        r.method.name(),
        r.setting(),
        r.cpu
    )
}

fn summary(
    cfg: &Config,
    runs: &[Run],
    refs: &[(Scene, String, f64)],
    cells: &[Cell],
    costs: &[Cost],
    wall: f64,
) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Work-precision summary{}\n\nSweep wall time {wall:.0} s ({} runs). Trajectory error in m, energy error per E_scale, \
         CPU in s per simulated s.\n",
        if cfg.quick { " (--quick)" } else { "" },
        runs.len()
    );
    for scene in SCENES {
        let rs: Vec<&Run> = runs.iter().filter(|r| r.scene == scene).collect();
        let _ = writeln!(s, "## {}\n", scene.title(cfg));
        if let Some((_, how, floor)) = refs.iter().find(|(sc, _, _)| *sc == scene) {
            let _ = writeln!(s, "Reference: {how}; floor {floor:.1e} m.\n");
        }
        let front = pareto(rs.iter().copied(), |r| r.traj);
        let _ = writeln!(s, "Pareto front (trajectory):");
        for r in &front {
            let _ = writeln!(s, "- {}", fmt_run(r, r.traj));
        }
        let _ = writeln!(
            s,
            "\n| method | runs ok/failed/skipped | cheapest <= 1e-1 m | cheapest <= 1e-3 m | cheapest <= 1e-5 m | order in h | best error | failures |\n|---|---|---|---|---|---|---|---|"
        );
        for method in METHODS {
            let mine: Vec<&Run> = rs.iter().copied().filter(|r| r.method == method).collect();
            if mine.is_empty() {
                continue;
            }
            let cheapest = |lim: f64| {
                mine.iter()
                    .filter(|r| r.ok() && r.traj <= lim)
                    .min_by(|a, b| a.cpu.total_cmp(&b.cpu))
                    .map_or("never".to_string(), |r| {
                        format!("{} ({:.2e} s/s)", r.setting(), r.cpu)
                    })
            };
            let best = mine
                .iter()
                .filter(|r| r.ok())
                .min_by(|a, b| a.traj.total_cmp(&b.traj))
                .map_or("-".to_string(), |r| {
                    format!("{:.1e} at {}", r.traj, r.setting())
                });
            let fails: Vec<String> = mine
                .iter()
                .filter(|r| r.failed())
                .map(|r| {
                    format!(
                        "{} {}",
                        r.setting(),
                        r.status.trim_start_matches("failed: ")
                    )
                })
                .collect();
            let n = |f: &dyn Fn(&Run) -> bool| mine.iter().filter(|r| f(r)).count();
            let order = observed_order(&by_substep(&rs, method), 1e-9);
            let _ = writeln!(
                s,
                "| {} | {}/{}/{} | {} | {} | {} | {order:.2} | {best} | {} |",
                method.name(),
                n(&|r| r.ok()),
                n(&|r| r.failed()),
                n(&|r| r.status.starts_with("skipped")),
                cheapest(1e-1),
                cheapest(1e-3),
                cheapest(1e-5),
                if fails.is_empty() {
                    "none".into()
                } else {
                    fails.join("; ")
                }
            );
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(
        s,
        "## Chain stability (dt 1/60, {} links)\n",
        cfg.stability_links
    );
    let _ = writeln!(
        s,
        "| method | ratio | substeps | class | max gap m | status |\n|---|---|---|---|---|---|"
    );
    for c in cells {
        let _ = writeln!(
            s,
            "| {} | 1:{} | {} | {} | {:.1e} | {} |",
            c.method.name(),
            c.ratio,
            c.substeps,
            c.class,
            c.gap,
            c.status
        );
    }
    let _ = writeln!(
        s,
        "\n## Chain cost per step (dt 1/60, 4 substeps)\n\n| method | N | us/step |\n|---|---|---|"
    );
    for c in costs {
        let _ = writeln!(
            s,
            "| {} | {} | {:.0} |",
            c.method.name(),
            c.n,
            c.us_per_step
        );
    }
    s
}
