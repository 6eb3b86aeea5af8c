//! Small dense solves (the initial multibody velocities).

use crate::math::Real;

/// In-place Cholesky solve (the solution overwrites `b`) of the SPD (or semidefinite) `a` (n x n, row-major); rows whose
/// pivot falls below a relative tolerance are treated as dependent and solved as zero. It does
/// not allocate: a dropped row is marked by a zero diagonal (a kept row's is `sqrt(d) > 0`).
pub fn cholesky_solve_dropping(a: &mut [Real], b: &mut [Real], n: usize) {
    for j in 0..n {
        // Relative to the row's own diagonal: rows of very different scale (forces on a 1 kg
        // body, moments on a 1e-4 kg m^2 one) share one matrix.
        let tol = a[j * n + j].abs() * 1e3 * Real::EPSILON;
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if d.is_nan() || d <= tol {
            for i in j..n {
                a[i * n + j] = 0.0;
            }
            continue;
        }
        let l = d.sqrt();
        a[j * n + j] = l;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / l;
        }
    }
    for i in 0..n {
        if a[i * n + i] == 0.0 {
            b[i] = 0.0;
            continue;
        }
        let mut s = b[i];
        for k in 0..i {
            s -= a[i * n + k] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
    for i in (0..n).rev() {
        if a[i * n + i] == 0.0 {
            b[i] = 0.0;
            continue;
        }
        let mut s = b[i];
        for k in i + 1..n {
            s -= a[k * n + i] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
}
