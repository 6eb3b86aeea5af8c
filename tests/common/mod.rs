//! Shared measurement helpers for the analytic tests: each returns one metric.
#![allow(dead_code, reason = "each test file uses a subset of the helpers")]

use rapier3d_mpc184::math::{PI, Real};

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

/// Mean period from successive upward crossings.
pub fn mean_period(crossings: &[Real]) -> Real {
    assert!(
        crossings.len() >= 2,
        "fewer than two crossings: {crossings:?}"
    );
    (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as Real
}

/// Secular energy drift: mean of `e` over the last three whole periods minus the mean over the
/// first three (periods delimited by `crossings`), divided by `scale`.
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

/// Largest |e - e[0]| / scale.
pub fn max_oscillation(e: &[Real], scale: Real) -> Real {
    e.iter().map(|x| (x - e[0]).abs()).fold(0.0, Real::max) / scale
}
