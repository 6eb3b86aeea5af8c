//! Reference results and measurements shared by tests, demos and the main job: exact pendulum
//! periods and the period / energy metrics the accuracy figures are quoted in.

use crate::math::{PI, Real};

/// One classical Runge-Kutta step of `h` for the one-DOF motion `theta'' = f(theta)` from
/// angle `theta` and rate `omega`: the new angle and rate. In `f64` whatever [`Real`] is: it
/// computes the references the accuracy figures are measured against.
pub fn rk4_step(f: impl Fn(f64) -> f64, theta: f64, omega: f64, h: f64) -> (f64, f64) {
    let (k1t, k1o) = (omega, f(theta));
    let (k2t, k2o) = (omega + 0.5 * h * k1o, f(theta + 0.5 * h * k1t));
    let (k3t, k3o) = (omega + 0.5 * h * k2o, f(theta + 0.5 * h * k2t));
    let (k4t, k4o) = (omega + h * k3o, f(theta + h * k3t));
    (
        theta + h / 6.0 * (k1t + 2.0 * k2t + 2.0 * k3t + k4t),
        omega + h / 6.0 * (k1o + 2.0 * k2o + 2.0 * k3o + k4o),
    )
}

/// Complete elliptic integral of the first kind K(k) by the arithmetic-geometric mean
/// (K = pi / (2 AGM(1, sqrt(1 - k^2))), converged to machine precision).
pub fn elliptic_k(k: Real) -> Real {
    let (mut a, mut b) = (1.0 as Real, (1.0 - k * k).sqrt());
    for _ in 0..60 {
        let (an, bn) = (0.5 * (a + b), (a * b).sqrt());
        a = an;
        b = bn;
        if (a - b).abs() <= Real::EPSILON * a {
            break;
        }
    }
    PI / (2.0 * a)
}

/// Exact large-amplitude period of a physical pendulum: `4 sqrt(I_p / (m g L)) K(sin(theta0/2))`
/// (for a point mass `I_p = m L^2` and this is `4 sqrt(L/g) K(...)`).
pub fn pendulum_period(
    pivot_inertia: Real,
    mass: Real,
    g: Real,
    length: Real,
    theta0: Real,
) -> Real {
    4.0 * (pivot_inertia / (mass * g * length)).sqrt() * elliptic_k((0.5 * theta0).sin())
}

/// Times of upward zero crossings of a sampled signal, linearly interpolated between samples.
pub fn upward_crossings(t: &[Real], x: &[Real]) -> Vec<Real> {
    let mut out = Vec::new();
    for i in 1..x.len() {
        if x[i - 1] < 0.0 && x[i] >= 0.0 {
            let f = x[i - 1] / (x[i - 1] - x[i]);
            out.push(t[i - 1] + f * (t[i] - t[i - 1]));
        }
    }
    out
}

/// Mean period from successive upward crossings (NaN with fewer than two).
pub fn mean_period(crossings: &[Real]) -> Real {
    assert!(
        crossings.len() >= 2,
        "fewer than two crossings: {crossings:?}"
    );
    (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as Real
}

/// Secular energy drift: mean of `e` over the last three whole periods minus the mean over the
/// first three (periods delimited by `crossings`), divided by `scale` (NaN with fewer than
/// seven crossings).
pub fn secular_drift(t: &[Real], e: &[Real], crossings: &[Real], scale: Real) -> Real {
    assert!(
        crossings.len() >= 7,
        "need six whole periods, got {} crossings",
        crossings.len()
    );
    let mean = |t0: Real, t1: Real| {
        let v: Vec<Real> = t
            .iter()
            .zip(e)
            .filter(|(t, _)| **t >= t0 && **t < t1)
            .map(|(_, e)| *e)
            .collect();
        v.iter().sum::<Real>() / v.len() as Real
    };
    let n = crossings.len();
    (mean(crossings[n - 4], crossings[n - 1]) - mean(crossings[0], crossings[3])) / scale
}

/// Largest `|e - e[0]| / scale`.
pub fn max_oscillation(e: &[Real], scale: Real) -> Real {
    e.iter().map(|x| (x - e[0]).abs()).fold(0.0, Real::max) / scale
}

/// Figures of one pendulum run (see [`pendulum_study`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PendulumReport {
    /// Simulated period: mean over all whole periods (s).
    pub period: Real,
    /// Exact large-amplitude period (s).
    pub exact_period: Real,
    /// |period - exact| / exact.
    pub period_err: Real,
    /// Secular energy drift over the run, / (m g L).
    pub drift: Real,
    /// Largest |E - E0| / (m g L).
    pub oscillation: Real,
    /// Largest relative error of the rod tension at the bottom crossings against the radial
    /// balance `m g cos(theta) + m L thetadot^2` of the simulated state.
    pub tension_err: Real,
    /// Largest pivot separation seen (m).
    pub max_gap: Real,
    /// Wall time per step of `dt` (microseconds).
    pub us_per_step: Real,
}

/// Runs a revolute pendulum (1 kg bob with isotropic inertia 1e-4 kg m^2, 1 m, released from rest
/// at `theta0`) for `duration` seconds at `dt` with `substeps`, sampling at every substep (the
/// world runs at `dt / substeps` with one substep per step: the same computation, since
/// `step()` calls Rapier once per substep). The wall time comes from a second, unsampled run at
/// the real `dt` and `substeps`.
pub fn pendulum_study(
    backend: crate::settings::Backend,
    axis: crate::catalogue::Axis,
    theta0: Real,
    dt: Real,
    substeps: usize,
    duration: Real,
) -> Result<PendulumReport, crate::error::Error> {
    pendulum_study_with(
        backend,
        crate::world::Integrator::default(),
        axis,
        theta0,
        dt,
        substeps,
        duration,
    )
}

/// [`pendulum_study`] with a chosen integrator (Lagrange backend; the Rapier backends ignore it).
pub fn pendulum_study_with(
    backend: crate::settings::Backend,
    integrator: crate::world::Integrator,
    axis: crate::catalogue::Axis,
    theta0: Real,
    dt: Real,
    substeps: usize,
    duration: Real,
) -> Result<PendulumReport, crate::error::Error> {
    use super::scenes::{self, G};
    use crate::catalogue::Axis;
    use crate::dof::Dof;
    use crate::world::WorldSettings;
    let h = dt / substeps as Real;
    let settings = WorldSettings {
        dt: h,
        substeps: 1,
        backend,
        integrator,
        ..WorldSettings::default()
    };
    let mut p = scenes::pendulum(settings, axis, 1.0, theta0, 1.0, 1e-4)?;
    let exact = pendulum_period(p.pivot_inertia(), p.mass, G, p.length, theta0);
    let dof = match axis {
        Axis::X => Dof::RotX,
        Axis::Z => Dof::RotZ,
    };
    let n = (duration / h).round() as usize;
    let (mut t, mut ang, mut e, mut tens) = (
        Vec::with_capacity(n + 1),
        Vec::with_capacity(n + 1),
        Vec::with_capacity(n + 1),
        Vec::with_capacity(n + 1),
    );
    let mut max_gap: Real = 0.0;
    let mut sample = |w: &crate::world::Mpc184World,
                      t: &mut Vec<Real>,
                      gap: &mut Real|
     -> Result<(), crate::error::Error> {
        let out = w.output(p.joint)?;
        t.push(w.time());
        ang.push(theta0 + out.dof(dof));
        e.push(w.kinetic_energy() + w.potential_energy());
        tens.push(out.force.length());
        *gap = gap.max(out.gap);
        Ok(())
    };
    sample(&p.world, &mut t, &mut max_gap)?;
    for _ in 0..n {
        p.world.step()?;
        sample(&p.world, &mut t, &mut max_gap)?;
    }
    // Wall time from a separate run at the real settings (dt with its substeps, no sampling).
    let mut timed = scenes::pendulum(
        WorldSettings {
            dt,
            substeps,
            backend,
            integrator,
            ..WorldSettings::default()
        },
        axis,
        1.0,
        theta0,
        1.0,
        1e-4,
    )?;
    let steps = (duration / dt).round() as usize;
    let t0 = std::time::Instant::now();
    for _ in 0..steps {
        timed.world.step()?;
    }
    let busy = t0.elapsed();
    let crossings = upward_crossings(&t, &ang);
    let period = mean_period(&crossings);
    let scale = p.mass * G * p.length;
    let mut tension_err: Real = 0.0;
    for i in 1..ang.len() {
        if ang[i - 1].signum() != ang[i].signum() {
            let om = (ang[i] - ang[i - 1]) / (t[i] - t[i - 1]);
            let th = 0.5 * (ang[i] + ang[i - 1]);
            let exact_t = p.mass * G * th.cos() + p.mass * p.length * om * om;
            let sim = 0.5 * (tens[i] + tens[i - 1]);
            tension_err = tension_err.max((sim - exact_t).abs() / exact_t);
        }
    }
    Ok(PendulumReport {
        period,
        exact_period: exact,
        period_err: (period - exact).abs() / exact,
        drift: secular_drift(&t, &e, &crossings, scale),
        oscillation: max_oscillation(&e, scale),
        tension_err,
        max_gap,
        us_per_step: busy.as_secs_f64() as Real * 1e6 / steps.max(1) as Real,
    })
}
