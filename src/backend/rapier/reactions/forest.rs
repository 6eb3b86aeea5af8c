//! The reaction recovery on joints that form a forest (no closed loop, no two joints between
//! one pair of bodies): each joint's impulse from the impulses of the bodies it carries, leaves
//! first, instead of a KKT factorisation.
//!
//! A joint `k` of a forest separates its child's subtree `S` from the rest (the ground, a fixed
//! or kinematic body, or the floating tree's root). The joints inside `S` act on two bodies of
//! `S` with equal and opposite wrenches, so the constraint impulses on `S`'s bodies sum, about
//! a common point, to joint `k`'s alone: `J_c^T mu_k = sum_{b in S} (p_b, l_b + (x_b - x_c) x
//! p_b)`, with `J_c` the joint's Jacobian block on its child `c` and `x` the centres of mass
//! halfway through the span (where the rows are evaluated). That is 6 equations for `m_k <= 6`
//! independent rows; they are solved in the child's mass metric,
//! `(J_c M_c^-1 J_c^T) mu_k = J_c M_c^-1 w`, which is the KKT solve's
//! `(J M^-1 J^T) mu = J M^-1 p` when the impulses are consistent (Rapier's are up to its
//! substeps' pose changes and softness) and costs `O(m_k^3)` per joint instead of a block
//! factorisation and two sweeps.

use crate::math::{Matrix, Real, Vector};
use crate::rows::RowEval;
use crate::solver::dense;
pub(super) use crate::solver::forest::Edge;
use crate::solver::forest::leaves_first;
use crate::solver::kkt::{JointBlockSpec, MAX_JOINT_ROWS};

/// The recovery's joints ordered from the leaves to the roots, or `None` when they do not
/// form a forest; rebuilt when the joints' bodies or row counts change.
#[derive(Default)]
pub(super) struct Forest {
    specs: Vec<JointBlockSpec>,
    nb: usize,
    edges: Option<Vec<Edge>>,
    /// Per body: the impulse of the subtree it tops, linear and angular about its centre of
    /// mass.
    acc: Vec<[Vector; 2]>,
}

impl Forest {
    /// The forest for `specs` over `nb` recorded bodies (kept from the last call when they are
    /// the same); whether the joints form one.
    pub(super) fn update(&mut self, specs: &[JointBlockSpec], nb: usize) -> bool {
        if self.nb != nb || self.specs != specs {
            self.specs.clear();
            self.specs.extend_from_slice(specs);
            self.nb = nb;
            self.edges = leaves_first(specs, nb);
        }
        self.edges.is_some()
    }

    /// Walks the joints from the leaves to the roots, handing `joint` each joint's edge and the
    /// impulse of the subtree it carries (linear, then angular about the child's centre of
    /// mass), from the bodies' impulses (`impulse[b]`: linear, then angular about the centre of
    /// mass) and centres of mass `com`. Returns `false`, calling nothing, when
    /// [`Self::update`] found no forest.
    pub(super) fn walk(
        &mut self,
        impulse: &[[Real; 6]],
        com: impl Fn(usize) -> Vector,
        mut joint: impl FnMut(&Edge, [Vector; 2]),
    ) -> bool {
        let Some(edges) = &self.edges else {
            return false;
        };
        // Each subtree's impulse about its top body's centre of mass (about the origin would
        // lose digits far from it).
        self.acc.clear();
        self.acc.extend(
            impulse
                .iter()
                .map(|p| [Vector::new(p[0], p[1], p[2]), Vector::new(p[3], p[4], p[5])]),
        );
        for e in edges {
            let w = self.acc[e.child];
            joint(e, w);
            if let Some(p) = e.parent {
                let arm = com(e.child) - com(p);
                self.acc[p][0] += w[0];
                self.acc[p][1] += w[1] + arm.cross(w[0]);
            }
        }
        true
    }
}

/// `mu` solving `J^T mu = w` in the metric of the inverse mass `(inv_m, inv_i)`, with `J` the
/// rows' blocks on `side`; dependent rows get zero. The common sizes (1 to 6 rows) run on
/// fixed-size arrays; more rows are dependent anyway and go to
/// [`dense::cholesky_solve_dropping`].
pub(super) fn project(
    rows: &[RowEval],
    side: usize,
    inv: (Real, Matrix),
    w: [Vector; 2],
    mu: &mut [Real],
) {
    match rows.len() {
        1 => project_n::<1>(rows, side, inv, w, mu),
        2 => project_n::<2>(rows, side, inv, w, mu),
        3 => project_n::<3>(rows, side, inv, w, mu),
        4 => project_n::<4>(rows, side, inv, w, mu),
        5 => project_n::<5>(rows, side, inv, w, mu),
        6 => project_n::<6>(rows, side, inv, w, mu),
        m => {
            let mut a = [0.0; MAX_JOINT_ROWS * MAX_JOINT_ROWS];
            let mut mj = [[Vector::ZERO; 2]; MAX_JOINT_ROWS];
            for (t, r) in mj.iter_mut().zip(rows) {
                *t = scaled(r, side, inv);
            }
            for (i, r) in rows.iter().enumerate() {
                let j = block(r, side);
                for (k, t) in mj[..=i].iter().enumerate() {
                    let v = j[0].dot(t[0]) + j[1].dot(t[1]);
                    a[i * m + k] = v;
                    a[k * m + i] = v;
                }
                mu[i] = mj[i][0].dot(w[0]) + mj[i][1].dot(w[1]);
            }
            dense::cholesky_solve_dropping(&mut a[..m * m], mu, m);
        }
    }
}

/// A row's Jacobian block on `side` (0: body 1).
#[inline(always)]
fn block(r: &RowEval, side: usize) -> [Vector; 2] {
    if side == 0 { r.j1 } else { r.j2 }
}

/// `M^-1 J_i^T` for one row.
#[inline(always)]
fn scaled(r: &RowEval, side: usize, (inv_m, inv_i): (Real, Matrix)) -> [Vector; 2] {
    let j = block(r, side);
    [j[0] * inv_m, inv_i * j[1]]
}

/// [`project`] for `N` rows: the Gram matrix `J M^-1 J^T` factored as `L D L^T` in place,
/// without square roots; a pivot below `1e3 eps` of its diagonal marks a dependent row, whose
/// multiplier is zero (the same test as [`dense::cholesky_solve_dropping`]).
#[inline(always)]
#[allow(
    clippy::needless_range_loop,
    reason = "index loops with compile-time bounds, fully unrolled"
)]
fn project_n<const N: usize>(
    rows: &[RowEval],
    side: usize,
    inv: (Real, Matrix),
    w: [Vector; 2],
    mu: &mut [Real],
) {
    let (rows, mu) = (&rows[..N], &mut mu[..N]);
    let mut j = [[Vector::ZERO; 2]; N];
    let mut mj = [[Vector::ZERO; 2]; N];
    for i in 0..N {
        j[i] = block(&rows[i], side);
        mj[i] = scaled(&rows[i], side, inv);
    }
    let mut l = [[0.0; N]; N];
    let mut b = [0.0; N];
    for i in 0..N {
        for k in 0..N {
            if k <= i {
                l[i][k] = j[i][0].dot(mj[k][0]) + j[i][1].dot(mj[k][1]);
            }
        }
        b[i] = mj[i][0].dot(w[0]) + mj[i][1].dot(w[1]);
    }
    // L D L^T, L unit lower (below the diagonal in `l`), D^+ in `dinv`.
    let mut d = [0.0; N];
    let mut dinv = [0.0; N];
    for c in 0..N {
        let tol = l[c][c].abs() * 1e3 * Real::EPSILON;
        let mut p = l[c][c];
        for k in 0..N {
            if k < c {
                p -= l[c][k] * l[c][k] * d[k];
            }
        }
        let kept = p > tol;
        d[c] = if kept { p } else { 0.0 };
        dinv[c] = if kept { 1.0 / p } else { 0.0 };
        for i in 0..N {
            if i > c {
                let mut v = l[i][c];
                for k in 0..N {
                    if k < c {
                        v -= l[i][k] * l[c][k] * d[k];
                    }
                }
                l[i][c] = v * dinv[c];
            }
        }
    }
    for i in 0..N {
        for k in 0..N {
            if k < i {
                b[i] -= l[i][k] * b[k];
            }
        }
    }
    for i in 0..N {
        b[i] *= dinv[i];
    }
    for i in (0..N).rev() {
        for k in 0..N {
            if k > i {
                b[i] -= l[k][i] * b[k];
            }
        }
    }
    mu.copy_from_slice(&b);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(lin: [Real; 3], ang: [Real; 3]) -> RowEval {
        let j = [Vector::from_array(lin), Vector::from_array(ang)];
        RowEval {
            value: 0.0,
            j1: j.map(|v| -v),
            j2: j,
        }
    }

    /// Consistent impulses come back exactly whatever the metric: five independent rows
    /// (fixed-size kernel) and the same five plus two copies (more than six rows: the dense
    /// fallback, the copies dependent and zero). Round-off bound: the rows are O(1) and the
    /// Gram matrix's condition number is in the tens, so `1e4 eps` leaves a factor 100 (f32 and
    /// f64 alike).
    #[test]
    fn projection_recovers_consistent_multipliers() {
        let rows = vec![
            row([1.0, 0.0, 0.0], [0.0, 0.2, -0.1]),
            row([0.0, 1.0, 0.0], [0.3, 0.0, 0.5]),
            row([0.0, 0.0, 1.0], [-0.2, 0.1, 0.0]),
            row([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]),
            row([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        ];
        let truth = [0.7, -1.3, 2.1, 0.4, -0.9];
        let inv = (0.5, Matrix::from_diagonal(Vector::new(3.0, 4.0, 5.0)));
        for side in [0, 1] {
            let block = |r: &RowEval| if side == 0 { r.j1 } else { r.j2 };
            let mut w = [Vector::ZERO; 2];
            for (r, m) in rows.iter().zip(truth) {
                w[0] += block(r)[0] * m;
                w[1] += block(r)[1] * m;
            }
            let mut mu = [0.0; 5];
            project(&rows, side, inv, w, &mut mu);
            let tol = 1e4 * Real::EPSILON;
            for (a, b) in mu.iter().zip(truth) {
                assert!((a - b).abs() <= tol, "{mu:?}");
            }
            let mut more = rows.clone();
            more.push(rows[1]);
            more.push(rows[3]);
            let mut mu = [0.0; 7];
            project(&more, side, inv, w, &mut mu);
            for (a, b) in mu.iter().zip(truth.iter().chain(&[0.0, 0.0])) {
                assert!((a - b).abs() <= tol, "{mu:?}");
            }
        }
    }
}
