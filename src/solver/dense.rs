//! Small dense solves (reaction recovery on the Rapier backends).

use crate::math::Real;

/// Multipliers `mu` minimising `|J^T mu - p|` in the `M^-1` metric:
/// `(J M^-1 J^T) mu = J M^-1 p`. `jac[r]` is row r as `[body-a 6 | body-b 6]`, `cols[r]` the body
/// indices of the two halves (`None`: a fixed body). Rows that are linearly dependent on earlier
/// ones (tiny Cholesky pivots) get `mu = 0`.
pub fn least_squares_multipliers(
    mass: &[[[Real; 6]; 6]],
    impulse: &[[Real; 6]],
    jac: &[[Real; 12]],
    cols: &[[Option<usize>; 2]],
) -> Vec<Real> {
    let nb = mass.len();
    let inv: Vec<[[Real; 6]; 6]> = mass.iter().map(invert6).collect();
    // W = M^-1 J^T, per row: for each half, a 6-vector on its body.
    let n = jac.len();
    let mut w = vec![[[0.0 as Real; 6]; 2]; n];
    for r in 0..n {
        for s in 0..2 {
            if let Some(b) = cols[r][s] {
                for i in 0..6 {
                    w[r][s][i] = (0..6).map(|k| inv[b][i][k] * jac[r][6 * s + k]).sum();
                }
            }
        }
    }
    let dot = |r: usize, s: usize, x: &[Real; 6]| -> Real {
        (0..6).map(|k| jac[r][6 * s + k] * x[k]).sum()
    };
    let mut a = vec![0.0 as Real; n * n];
    let mut rhs = vec![0.0 as Real; n];
    for r in 0..n {
        for s in 0..2 {
            let Some(b) = cols[r][s] else { continue };
            let _ = nb;
            // (J M^-1 p)_r
            let mut mp = [0.0; 6];
            for i in 0..6 {
                mp[i] = (0..6).map(|k| inv[b][i][k] * impulse[b][k]).sum();
            }
            rhs[r] += dot(r, s, &mp);
            for c in 0..n {
                for t in 0..2 {
                    if cols[c][t] == Some(b) {
                        a[r * n + c] += dot(r, s, &w[c][t]);
                    }
                }
            }
        }
    }
    cholesky_solve_dropping(&mut a, &mut rhs, n);
    rhs
}

/// In-place Cholesky solve (the solution overwrites `b`) of the SPD (or semidefinite) `a` (n x n, row-major); rows whose
/// pivot falls below a relative tolerance are treated as dependent and solved as zero.
pub fn cholesky_solve_dropping(a: &mut [Real], b: &mut [Real], n: usize) {
    let mut dropped = vec![false; n];
    for j in 0..n {
        // Relative to the row's own diagonal: rows of very different scale (forces on a 1 kg
        // body, moments on a 1e-4 kg m^2 one) share one matrix.
        let tol = a[j * n + j].abs() * 1e3 * Real::EPSILON;
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if d.is_nan() || d <= tol {
            dropped[j] = true;
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
        if dropped[i] {
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
        if dropped[i] {
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

/// Inverse of a 6x6 SPD matrix by Gauss-Jordan (a zero row/column inverts to zero).
fn invert6(m: &[[Real; 6]; 6]) -> [[Real; 6]; 6] {
    let mut a = *m;
    let mut inv = [[0.0 as Real; 6]; 6];
    for (i, row) in inv.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for c in 0..6 {
        let p = (c..6)
            .max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))
            .unwrap_or(c);
        if a[p][c].abs() <= Real::MIN_POSITIVE {
            continue;
        }
        a.swap(c, p);
        inv.swap(c, p);
        let d = a[c][c];
        for k in 0..6 {
            a[c][k] /= d;
            inv[c][k] /= d;
        }
        for r in 0..6 {
            if r != c {
                let f = a[r][c];
                for k in 0..6 {
                    a[r][k] -= f * a[c][k];
                    inv[r][k] -= f * inv[c][k];
                }
            }
        }
    }
    inv
}
