//! The stability maps (chain end-mass ratio x substeps, penalty stiffness x dt, distance from
//! the singular four-bar pose x dt) and the scaling study.

use super::*;

/// Outcome of one cell of the chain stability map.
#[derive(Clone, Debug)]
pub(crate) struct Cell {
    pub(crate) method: Method,
    pub(crate) ratio: f64,
    pub(crate) substeps: usize,
    pub(crate) gap: f64,
    /// "ok", "gap" (> 1 cm), "blew up" or "skipped".
    pub(crate) class: &'static str,
    pub(crate) status: String,
}

/// The chain (`stability_links` links, released at 20 deg) at dt = 1/60 for each end-mass ratio
/// and substep count: ok, gap > 1 cm, or blew up (step error, non-finite, gap > 1 m or energy
/// error > 10 x the scale).
pub(crate) fn stability_map(cfg: &Config, progress: &mut Progress) -> Vec<Cell> {
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
pub(crate) struct Cost {
    pub(crate) method: Method,
    pub(crate) n: usize,
    pub(crate) us_per_step: f64,
}

pub(crate) fn scaling(cfg: &Config, progress: &mut Progress) -> Vec<Cost> {
    let methods = [
        Method::Lagrange,
        Method::Penalty(1e6),
        Method::Impulse,
        Method::Multibody,
        Method::RapierAlone,
    ];
    let min_wall = if cfg.quick { 0.05 } else { 0.5 };
    let mut out = Vec::new();
    for method in methods {
        for &n in &cfg.scaling_n {
            progress.tick(&format!("scaling {} N = {n}", method.name()));
            if method == Method::Multibody && n > 100 {
                continue;
            }
            let alone = method == Method::RapierAlone;
            let built = if alone {
                chain(settings(Method::Impulse, 1.0 / 60.0, 4), n, 1.0).ok()
            } else {
                chain(settings(method, 1.0 / 60.0, 4), n, 1.0)
                    .ok()
                    .and_then(|b| with_method(b, method))
            };
            let Some(mut b) = built else {
                continue;
            };
            // Rapier alone: the same bodies and joints, one pipeline call per step with its own
            // 4 substeps (the game's price).
            if alone {
                benchmarks::rapier_alone(&mut b.world);
            }
            let step = |b: &mut Benchmark| {
                if alone {
                    b.world.physics.step();
                    Ok(())
                } else {
                    b.world.step()
                }
            };
            // Two warm-up steps (first factorisation, Rapier's set-up), then timed steps.
            if (0..2).any(|_| step(&mut b).is_err()) {
                continue;
            }
            let (mut busy, mut steps) = (0.0, 0usize);
            while (busy < min_wall || steps < 3) && steps < 300 {
                let t0 = Instant::now();
                let r = step(&mut b);
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

/// One cell of the penalty or singular-pose map.
#[derive(Clone, Debug)]
pub(crate) struct MapCell {
    pub(crate) method: Method,
    /// Row value: penalty stiffness (infinity for the Lagrange row) or start distance (rad).
    pub(crate) row: f64,
    pub(crate) dt: f64,
    pub(crate) traj: f64,
    pub(crate) gap: f64,
    /// "<=1e-3", "<=1e-1", ">1e-1", "gap" (> 0.1 m), "branch switch", "blew up", "skipped".
    pub(crate) class: &'static str,
    pub(crate) status: String,
}

/// The accuracy class of a run: its status first, then the IFToMM levels of its error.
pub(crate) fn classify(status: &str, traj: f64) -> &'static str {
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

pub(crate) fn class_color(class: &str) -> RGBColor {
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
pub(crate) fn penalty_map(cfg: &Config, progress: &mut Progress) -> Vec<MapCell> {
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
pub(crate) fn four_bar_at(
    settings: WorldSettings,
    theta0: f64,
) -> Result<Benchmark, rapier3d_mpc184::Error> {
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
pub(crate) fn singular_map(cfg: &Config, progress: &mut Progress) -> Vec<MapCell> {
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

pub(crate) fn write_map_csv(path: &Path, cells: &[MapCell]) -> DynResult<()> {
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
