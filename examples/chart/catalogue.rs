//! The methods (backends, integrators, penalty stiffnesses) and scenes of the study, and how a
//! scene is built for a method.

use super::*;

#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Method {
    Lagrange,
    /// The Lagrange backend with the second-order integrator (RATTLE).
    Rattle,
    /// The Lagrange backend with the fourth-order composition of RATTLE substeps.
    Order4,
    /// The adaptive step control (step doubling, `StepControl::Adaptive`, or the embedded
    /// estimate, `StepControl::Embedded`) on RATTLE or on the fourth-order composition, at dt
    /// 1/30 over the study's tolerances (the work-precision charts only); `horizon`: the
    /// velocity difference weighed over half the run (the mean time left, the control the
    /// docs give for a trajectory tolerance), else over the step alone (`-local`: the per-step
    /// control a deck's `AUTOTS` gets); `extrapolate` (`-x`): each kept doubling extrapolated
    /// locally (`StepControl::Adaptive::extrapolate`, as a deck's `AUTOTS` does).
    Adaptive {
        order4: bool,
        horizon: bool,
        extrapolate: bool,
        /// `StepControl::Embedded` (`-e`, RATTLE only): one run per step, its error from the
        /// velocities of the last steps, instead of step doubling.
        embedded: bool,
    },
    Penalty(f64),
    Impulse,
    Multibody,
    /// Rapier's own pipeline on the impulse lowering, one `PhysicsPipeline::step` per step with
    /// `num_solver_iterations` = the substeps (the scaling chart only).
    RapierAlone,
    /// MuJoCo (PyPI `mujoco`, semi-implicit Euler or RK4; `tight`: loop-closing equality
    /// constraints at a tightened `solref`): runs read from `peer_runs.csv`, written by
    /// `scripts/mujoco_peer.py` (never stepped here).
    MuJoCo {
        rk4: bool,
        tight: bool,
    },
}

/// The MuJoCo variants, in the order the charts list them.
pub(crate) const PEERS: [Method; 4] = [
    Method::MuJoCo {
        rk4: false,
        tight: false,
    },
    Method::MuJoCo {
        rk4: true,
        tight: false,
    },
    Method::MuJoCo {
        rk4: false,
        tight: true,
    },
    Method::MuJoCo {
        rk4: true,
        tight: true,
    },
];

/// The adaptive variants, in the order the charts list them.
pub(crate) const ADAPTIVE: [Method; 8] = [
    Method::Adaptive {
        order4: false,
        horizon: true,
        extrapolate: false,
        embedded: false,
    },
    Method::Adaptive {
        order4: true,
        horizon: true,
        extrapolate: false,
        embedded: false,
    },
    Method::Adaptive {
        order4: true,
        horizon: false,
        extrapolate: false,
        embedded: false,
    },
    Method::Adaptive {
        order4: false,
        horizon: true,
        extrapolate: true,
        embedded: false,
    },
    Method::Adaptive {
        order4: true,
        horizon: true,
        extrapolate: true,
        embedded: false,
    },
    Method::Adaptive {
        order4: true,
        horizon: false,
        extrapolate: true,
        embedded: false,
    },
    Method::Adaptive {
        order4: false,
        horizon: true,
        extrapolate: false,
        embedded: true,
    },
    Method::Adaptive {
        order4: false,
        horizon: false,
        extrapolate: false,
        embedded: true,
    },
];

/// The methods with runs in `runs`: this crate's fixed-step ones ([`METHODS`]), then the
/// adaptive ones and the peers found.
pub(crate) fn methods_in(runs: &[&Run]) -> Vec<Method> {
    let mut out = METHODS.to_vec();
    out.extend(
        ADAPTIVE
            .iter()
            .chain(&PEERS)
            .filter(|p| runs.iter().any(|r| r.method == **p)),
    );
    out
}

pub(crate) const METHODS: [Method; 8] = [
    Method::Lagrange,
    Method::Rattle,
    Method::Order4,
    Method::Penalty(1e4),
    Method::Penalty(1e6),
    Method::Penalty(1e8),
    Method::Impulse,
    Method::Multibody,
];

impl Method {
    pub(crate) fn name(self) -> String {
        match self {
            Method::Lagrange => "lagrange".into(),
            Method::Rattle => "lagrange-rattle".into(),
            Method::Order4 => "lagrange-order4".into(),
            Method::Adaptive {
                order4,
                horizon,
                extrapolate,
                embedded,
            } => format!(
                "adaptive-{}{}{}{}",
                if order4 { "order4" } else { "rattle" },
                if horizon { "" } else { "-local" },
                if extrapolate { "-x" } else { "" },
                if embedded { "-e" } else { "" }
            ),
            Method::Penalty(k) => format!("penalty-{k:.0e}"),
            Method::Impulse => "rapier-impulse".into(),
            Method::Multibody => "rapier-multibody".into(),
            Method::RapierAlone => "rapier-alone".into(),
            Method::MuJoCo { rk4, tight } => format!(
                "mujoco-{}{}",
                if rk4 { "rk4" } else { "euler" },
                if tight { "-tight" } else { "" }
            ),
        }
    }

    /// The method named `name` (as [`Method::name`] writes it), for the CSVs read back.
    pub(crate) fn from_name(name: &str) -> Option<Method> {
        METHODS
            .iter()
            .chain(&PEERS)
            .chain(&ADAPTIVE)
            .chain(&[Method::RapierAlone])
            .copied()
            .find(|m| m.name() == name)
    }

    pub(crate) fn backend(self) -> Backend {
        match self {
            Method::Lagrange
            | Method::Rattle
            | Method::Order4
            | Method::Adaptive { .. }
            | Method::Penalty(_) => Backend::Lagrange,
            Method::Impulse | Method::RapierAlone | Method::MuJoCo { .. } => Backend::RapierImpulse,
            Method::Multibody => Backend::RapierMultibody,
        }
    }

    pub(crate) fn color(self) -> RGBColor {
        match self {
            Method::Lagrange => RGBColor(31, 119, 180),
            Method::Rattle => RGBColor(148, 103, 189),
            Method::Order4 => RGBColor(188, 189, 34),
            Method::Adaptive {
                embedded: true,
                horizon: true,
                ..
            } => RGBColor(255, 0, 255),
            Method::Adaptive {
                embedded: true,
                horizon: false,
                ..
            } => RGBColor(120, 60, 0),
            Method::Adaptive {
                order4: false,
                extrapolate: false,
                ..
            } => RGBColor(84, 39, 143),
            Method::Adaptive {
                order4: false,
                extrapolate: true,
                ..
            } => RGBColor(197, 27, 125),
            Method::Adaptive {
                order4: true,
                horizon: true,
                extrapolate: false,
                embedded: false,
            } => RGBColor(110, 112, 0),
            Method::Adaptive {
                order4: true,
                horizon: true,
                extrapolate: true,
                embedded: false,
            } => RGBColor(230, 97, 1),
            Method::Adaptive {
                order4: true,
                horizon: false,
                extrapolate: false,
                embedded: false,
            } => RGBColor(0, 128, 128),
            Method::Adaptive {
                order4: true,
                horizon: false,
                extrapolate: true,
                embedded: false,
            } => RGBColor(1, 102, 94),
            Method::Penalty(k) if k < 1e5 => RGBColor(255, 187, 120),
            Method::Penalty(k) if k < 1e7 => RGBColor(255, 127, 14),
            Method::Penalty(_) => RGBColor(140, 86, 75),
            Method::Impulse => RGBColor(214, 39, 40),
            Method::Multibody => RGBColor(44, 160, 44),
            Method::RapierAlone => RGBColor(227, 119, 194),
            Method::MuJoCo {
                rk4: false,
                tight: false,
            } => RGBColor(127, 127, 127),
            Method::MuJoCo {
                rk4: true,
                tight: false,
            } => RGBColor(0, 0, 0),
            Method::MuJoCo {
                rk4: false,
                tight: true,
            } => RGBColor(23, 190, 207),
            Method::MuJoCo {
                rk4: true,
                tight: true,
            } => RGBColor(0, 110, 120),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Scene {
    A01,
    Conical,
    A02,
    A04,
    Chain,
    SliderCrank,
    /// IFToMM A03, Andrews' squeezer: its own sweep (`andrews.rs`), not in [`SCENES`].
    A03,
}

pub(crate) const SCENES: [Scene; 6] = [
    Scene::A01,
    Scene::Conical,
    Scene::A02,
    Scene::A04,
    Scene::Chain,
    Scene::SliderCrank,
];

impl Scene {
    pub(crate) fn index(self) -> usize {
        SCENES.iter().position(|s| *s == self).unwrap_or(0)
    }

    pub(crate) fn key(self) -> &'static str {
        match self {
            Scene::A01 => "a01_pendulum",
            Scene::Conical => "conical_pendulum",
            Scene::A02 => "a02_four_bar",
            Scene::A04 => "a04_bricard",
            Scene::Chain => "chain",
            Scene::SliderCrank => "slider_crank",
            Scene::A03 => "a03_andrews",
        }
    }

    pub(crate) fn title(self, cfg: &Config) -> String {
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
                format!(
                    "slider-crank (spherical rod-slider, idle spin removed), {d} s, slider vs converged Lagrange"
                )
            }
            Scene::A03 => "A03 Andrews' squeezer, 0.03 s, angles vs published".into(),
        }
    }

    /// Characteristic length (m): a gap above a tenth of it is a failure.
    pub(crate) fn length(self) -> f64 {
        match self {
            Scene::A01 | Scene::Conical | Scene::A02 | Scene::A04 => 1.0,
            Scene::Chain => benchmarks::CHAIN_LINK_LENGTH as f64,
            Scene::SliderCrank => 0.08,
            Scene::A03 => 0.1,
        }
    }

    pub(crate) fn build(
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
            Scene::SliderCrank => benchmarks::slider_crank_idle_removed(settings),
            Scene::A03 => Err(rapier3d_mpc184::Error::Unsupported {
                what: "A03 as a Benchmark".into(),
                hint: "it runs from its deck in andrews.rs".into(),
            }),
        }
    }
}

/// Pendulum of A01 as a [`Benchmark`]: 1 kg bob (inertia 1e-4 kg m^2) 1 m from a revolute z
/// joint, released horizontally; energy scale m g L.
pub(crate) fn pendulum_benchmark(
    settings: WorldSettings,
) -> Result<Benchmark, rapier3d_mpc184::Error> {
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

pub(crate) const PENDULUM_INERTIA: f64 = 1e-4;

/// Half-angle of the conical pendulum (rad).
pub(crate) const CONICAL_ALPHA: f64 = std::f64::consts::FRAC_PI_4;

/// Conical pendulum: 1 kg bob (isotropic inertia 1e-4 kg m^2) 1 m from a grounded spherical
/// joint, 45 deg from the vertical, in its exact steady precession `Omega^2 = g / (L cos alpha)`
/// about +Y (the isotropic bob spins with the rod, so the point-mass rate holds exactly);
/// energy scale: its kinetic energy `m (Omega L sin alpha)^2 / 2`.
pub(crate) fn conical_benchmark(
    settings: WorldSettings,
) -> Result<Benchmark, rapier3d_mpc184::Error> {
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

pub(crate) fn chain(
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

pub(crate) fn settings(method: Method, dt: f64, substeps: usize) -> WorldSettings {
    WorldSettings {
        dt: dt as Real,
        substeps,
        backend: method.backend(),
        integrator: match method {
            Method::Rattle | Method::Adaptive { order4: false, .. } => Integrator::Rattle,
            Method::Order4 | Method::Adaptive { order4: true, .. } => Integrator::Composition4,
            _ => Integrator::SymplecticEuler,
        },
        ..WorldSettings::default()
    }
}

/// Builds `scene` for `method` (`None`: the method does not take the scene, or is a peer).
pub(crate) fn build(
    scene: Scene,
    cfg: &Config,
    method: Method,
    dt: f64,
    substeps: usize,
) -> Option<Benchmark> {
    if matches!(method, Method::MuJoCo { .. } | Method::RapierAlone) {
        return None;
    }
    with_method(
        scene.build(cfg, settings(method, dt, substeps)).ok()?,
        method,
    )
}

/// `b` with its joints turned into penalty joints when `method` is a penalty method (`None`
/// where that fails).
pub(crate) fn with_method(mut b: Benchmark, method: Method) -> Option<Benchmark> {
    if let Method::Penalty(k) = method {
        let k = -(k as Real);
        b.set_method(ConstraintMethod::Penalty { disp: k, rot: k })
            .ok()?;
    }
    Some(b)
}

pub(crate) fn probe(b: &Benchmark) -> [f64; 3] {
    let p = b.probe_position();
    [p.x as f64, p.y as f64, p.z as f64]
}
