//! Reference trajectories: RK4 for the 1-DOF scenes, a fine Lagrange run (with its own error
//! estimated from a second run at twice the step) for the others.

use super::*;
use rapier3d_mpc184::studies::metrics::rk4_step;

/// A reference trajectory: the probe point at every output step (index 0 = time 0).
pub(crate) struct Reference {
    pub(crate) points: Vec<[f64; 3]>,
    /// Estimated error of the reference itself (m).
    pub(crate) floor: f64,
    pub(crate) how: String,
}

/// RK4 on a 1-DOF `theta'' = f(theta)`, the probe point `pos(theta)` at each output step.
pub(crate) fn rk4_reference(
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
            (th, om) = rk4_step(&f, th, om, h);
        }
        out.push(pos(th));
    }
    out
}

/// A Lagrange run (`method`: first order or the composition) at substep `h` (one substep per
/// step), the probe at each output step.
pub(crate) fn lagrange_trajectory(
    scene: Scene,
    cfg: &Config,
    method: Method,
    h: f64,
    secs: f64,
) -> DynResult<Vec<[f64; 3]>> {
    let mut b = build(scene, cfg, method, h, 1).ok_or("reference scene")?;
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

pub(crate) fn max_deviation(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(p, q)| (0..3).map(move |i| (p[i] - q[i]).abs()))
        .fold(0.0, f64::max)
}

pub(crate) fn reference(scene: Scene, cfg: &Config) -> DynResult<Reference> {
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
            // The fourth-order composition at 4 h_ref (the Bricard mechanism and the
            // slider-crank), about the first-order run's cost at h_ref: its floor is orders of
            // magnitude lower. The 100-body chain takes RATTLE at h_ref: there the composition's
            // stages differ by the projection's tolerances more than by truncation error
            // (measured over 2 s: the composition at 1/3840 and 1/7680 s differ by 3.2e-9 m,
            // RATTLE at 1/15360 and 1/30720 s by 1.2e-9 m, RATTLE at 1/30720 and the composition
            // at 1/7680 by 2.7e-10 m). The first-order run this replaced had a floor of 5.7e-5 m,
            // which hid every error below it. (No added inertia at these steps: it starts only
            // where `omega^2 h^2 > 1/4`.)
            let (method, h) = match scene {
                Scene::A04 | Scene::SliderCrank => (Method::Order4, 4.0 * cfg.h_ref),
                _ => (Method::Rattle, cfg.h_ref),
            };
            let fine = lagrange_trajectory(scene, cfg, method, h, secs)?;
            let coarse = lagrange_trajectory(scene, cfg, method, 2.0 * h, secs)?;
            Reference {
                floor: max_deviation(&fine, &coarse),
                points: fine,
                how: format!(
                    "converged {} at h = 1/{:.0} s (floor: its deviation from h = 1/{:.0})",
                    method.name(),
                    1.0 / h,
                    0.5 / h
                ),
            }
        }
    })
}
