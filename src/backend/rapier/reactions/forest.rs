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
//! independent rows, exact when the impulses are consistent (Rapier's are up to its substeps'
//! pose changes and softness); otherwise a least-squares solve in some metric. Two are used:
//!
//! | rows | metric | why |
//! |---|---|---|
//! | every one a pure force or a pure moment at node J ([`crate::rows::RowKind::node_wrench`]: all but a screw's and an idle spin's) | Euclidean, forces and moments apart at node J ([`project_at_node`]) | the two groups decouple into least-squares problems of at most three directions (a translation row's axis is one of frame I's: its multiplier is a dot product); a free direction keeps nothing |
//! | otherwise | the child's mass, `(J_c M_c^-1 J_c^T) mu_k = J_c M_c^-1 w` ([`project`]) | the KKT solve's `(J M^-1 J^T) mu = J M^-1 p` on one joint |
//!
//! Either costs `O(m_k^3)` per joint instead of a block factorisation and two sweeps. At node
//! J the reaction is written as it was taken: the force and moment about node J in frame I
//! halfway through the span. With the mass metric the wrench on body 2's centre of mass goes
//! to node J and frame I at the step's end; that put up to 0.11 `m g L` about the free axis of
//! a swinging pendulum's pin (`tests/rapier_reaction_free_directions.rs`).

use arrayvec::ArrayVec;

use crate::math::{Matrix, Real, Vector};
use crate::rows::{NodeWrench, RowEval};
use crate::solver::dense;
use crate::solver::forest::{Edge, leaves_first};
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
    /// mass) and centres of mass `com`. Calls nothing when [`Self::update`] found no forest.
    pub(super) fn walk(
        &mut self,
        impulse: &[[Real; 6]],
        com: impl Fn(usize) -> Vector,
        mut joint: impl FnMut(&Edge, [Vector; 2]),
    ) {
        let Some(edges) = &self.edges else {
            return;
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

/// `mu` solving `J^T mu = w` for a joint whose rows are pure forces or pure moments at frame
/// 2's origin (`dirs`, per row: its wrench on body 2 there, see [`RowKind::node_wrench`]), in
/// the Euclidean metric of forces and of moments at that node. The two groups decouple, each a
/// least-squares problem over at most three directions; dependent rows get zero. This equals
/// [`project`] when the impulses are consistent, and leaves out the mass metric's coupling of
/// the forces with the moments through the lever arms (an error in a free direction of the
/// moment, which Rapier's substeps and soft joints leave, stays out of the forces). `side` is
/// the child's (0: body 1), `arm` the node less the child's centre of mass. Returns the wrench
/// on body 2 (force, moment about the node), or `None` when a group has more than three rows.
///
/// [`RowKind::node_wrench`]: crate::rows::RowKind::node_wrench
pub(super) fn project_at_node(
    dirs: &[NodeWrench],
    side: usize,
    arm: Vector,
    w: [Vector; 2],
    mu: &mut [Real],
) -> Option<[Vector; 2]> {
    // The subtree's impulse moved to the node, as body 2 takes it (body 1 takes the opposite).
    let s = if side == 1 { 1.0 } else { -1.0 };
    let force = w[0] * s;
    let moment = (w[1] - arm.cross(w[0])) * s;
    let mut forces = ArrayVec::<(usize, Vector), 3>::new();
    let mut moments = ArrayVec::<(usize, Vector), 3>::new();
    for (i, d) in dirs.iter().enumerate() {
        match *d {
            NodeWrench::Force(v) => forces.try_push((i, v)).ok()?,
            NodeWrench::Moment(v) => moments.try_push((i, v)).ok()?,
        }
    }
    Some([group(&forces, force, mu), group(&moments, moment, mu)])
}

/// One group of [`project_at_node`]: the multipliers of the directions `g` (row, direction)
/// whose combination comes closest to `target` (into `mu` at their rows); returns that
/// combination.
fn group(g: &[(usize, Vector)], target: Vector, mu: &mut [Real]) -> Vector {
    match g.len() {
        0 => Vector::ZERO,
        1 => group_n::<1>(g, target, mu),
        2 => group_n::<2>(g, target, mu),
        _ => group_n::<3>(g, target, mu),
    }
}

/// [`group`] for `N` directions.
#[inline(always)]
#[allow(
    clippy::needless_range_loop,
    reason = "index loops with compile-time bounds, fully unrolled"
)]
fn group_n<const N: usize>(g: &[(usize, Vector)], target: Vector, mu: &mut [Real]) -> Vector {
    let g = &g[..N];
    let mut l = [[0.0; N]; N];
    let mut b = [0.0; N];
    for i in 0..N {
        for k in 0..N {
            if k <= i {
                l[i][k] = g[i].1.dot(g[k].1);
            }
        }
        b[i] = g[i].1.dot(target);
    }
    ldl_solve(&mut l, &mut b);
    let mut sum = Vector::ZERO;
    for i in 0..N {
        mu[g[i].0] = b[i];
        sum += g[i].1 * b[i];
    }
    sum
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
    ldl_solve(&mut l, &mut b);
    mu.copy_from_slice(&b);
}

/// Solves `G x = b` in place (`x` into `b`) for the symmetric positive semidefinite `G` whose
/// lower triangle is in `l`: `L D L^T` in place, without square roots; a pivot below `1e3 eps`
/// of its diagonal marks a dependent row, whose unknown is zero (the same test as
/// [`dense::cholesky_solve_dropping`]).
#[inline(always)]
#[allow(
    clippy::needless_range_loop,
    reason = "index loops with compile-time bounds, fully unrolled"
)]
fn ldl_solve<const N: usize>(l: &mut [[Real; N]; N], b: &mut [Real; N]) {
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
