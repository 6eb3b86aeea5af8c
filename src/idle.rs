//! Idle modes: degrees of freedom a scene has but does not need.
//!
//! The known case is a connecting rod between two spherical joints (or a spherical joint and a
//! universal joint whose free axis lies along the rod): the joints leave the rod free to spin
//! about the line through them, a motion that moves no joint point and no other body. The
//! spin is carried only by the rod's inertia about that line, which for a point-mass body (a
//! deck's `MASS21` with a small rotary inertia) is tiny; joint forces with any small lever
//! arm then spin it up, and at coarse steps that fast idle spin is what breaks the spatial
//! slider-crank (`docs/charts/summary.md`).
//!
//! [`crate::Mpc184World::idle_modes`] looks for them at the current pose: for each dynamic body with two or more joints,
//! the angular velocities `w` it can take with its centre of mass held and every other body at
//! rest that satisfy all of its joints' rows (`J_w w = 0` on that body's angular columns: the
//! null space of the 3x3 matrix `sum_rows j_w j_w^T`, by Jacobi's eigenvalue method). Each
//! null direction is an idle mode: it moves no joint point, no other body, and not the body's
//! centre of mass (so gravity does no work on it either).
//!
//! | what | where |
//! |---|---|
//! | report | [`crate::Mpc184World::idle_modes`], `mpc184 check` |
//! | removal | [`crate::Mpc184World::remove_idle_modes`] (Lagrange backend): a velocity-level row `w . a = 0` on the body ([`crate::rows::RowKind::Spin`]) added to its first joint; decks do it by default (`BuildOptions::remove_idle_modes`) |
//!
//! Removing a mode changes nothing else in the motion where the body's inertia is symmetric
//! about the axis (the gyroscopic torque of the other rotations has no component along it):
//! measured on the spatial slider-crank in `tests/idle_modes.rs`.

use crate::error::JointId;
use crate::joint_set::JointSet;
use crate::math::rapier::dynamics::{RigidBodyHandle, RigidBodySet};
use crate::math::{Matrix, Real, Vector};

/// A null eigenvalue: below this fraction of the largest one.
const NULL_FRACTION: Real = 1e-9;

/// One idle mode.
#[derive(Clone, Debug, PartialEq)]
pub struct IdleMode {
    /// The body that spins.
    pub body: RigidBodyHandle,
    /// The spin axis (world frame, unit) through the body's centre of mass.
    pub axis: Vector,
    /// The body's moment of inertia about that axis (kg m^2).
    pub inertia: Real,
    /// `m r^2` with `r` the largest distance of the body's joint points from its centre of
    /// mass (kg m^2): the inertia a real spin would meet; a ratio `inertia / lever_inertia` far
    /// below one is the point-mass case that spins up.
    pub lever_inertia: Real,
    /// The joints on the body (the removal's row goes to the first).
    pub joints: Vec<JointId>,
}

impl IdleMode {
    /// One line for reports: body, axis, inertia, joints and why.
    pub fn describe(&self) -> String {
        let joints: Vec<String> = self.joints.iter().map(ToString::to_string).collect();
        format!(
            "body {:?}: free spin about [{:.4}, {:.4}, {:.4}] through its centre of mass, \
             inertia {:.3e} kg m^2 ({:.1e} of m r^2 at its joints); joints {} leave it free and \
             it moves no joint point, no other body and not the centre of mass",
            self.body.into_raw_parts(),
            self.axis.x,
            self.axis.y,
            self.axis.z,
            self.inertia,
            self.inertia / self.lever_inertia.max(Real::MIN_POSITIVE),
            joints.join(", "),
        )
    }
}

/// The idle modes of the scene at the bodies' current poses (see the module docs).
pub(crate) fn find(bodies: &RigidBodySet, joints: &JointSet) -> Vec<IdleMode> {
    let mut modes = Vec::new();
    for (h, rb) in bodies.iter() {
        if !rb.is_dynamic() {
            continue;
        }
        let ids = joints.attached_to(h);
        let entries: Vec<_> = ids
            .iter()
            .filter_map(|id| joints.get(id.0 as usize))
            .filter(|e| !e.state.rows.is_empty() && e.body1 != e.body2)
            .collect();
        if entries.len() < 2 {
            continue;
        }
        let com = rb.center_of_mass();
        let mut gram = Matrix::ZERO;
        let mut reach: Real = 0.0;
        for e in &entries {
            let f = e.low_frames(bodies);
            let point = if e.body1 == h { f.p1 } else { f.p2 };
            reach = reach.max((point - com).length());
            for row in &e.state.rows {
                let ev = row.eval(&f);
                let w = if e.body1 == h { ev.j1[1] } else { ev.j2[1] };
                gram += outer(w, w);
            }
        }
        let (values, vectors) = symmetric_eigen(gram);
        let largest = values.iter().copied().fold(0.0, Real::max);
        if largest <= 0.0 {
            continue;
        }
        let inertia_world = crate::body::world_inertia(rb);
        for (k, &value) in values.iter().enumerate() {
            if value > NULL_FRACTION * largest {
                continue;
            }
            let axis = vectors.col(k).normalize();
            modes.push(IdleMode {
                body: h,
                axis,
                inertia: axis.dot(inertia_world * axis),
                lever_inertia: rb.mass() * reach * reach,
                joints: ids.clone(),
            });
        }
    }
    modes
}

fn outer(a: Vector, b: Vector) -> Matrix {
    Matrix::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Eigenvalues and eigenvectors (columns) of a symmetric 3x3 matrix by cyclic Jacobi
/// rotations (converges quadratically; 16 sweeps reach round-off for any 3x3).
fn symmetric_eigen(m: Matrix) -> ([Real; 3], Matrix) {
    let mut a = [[0.0 as Real; 3]; 3];
    for (i, row) in a.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = m.col(j)[i];
        }
    }
    let mut v = [[0.0 as Real; 3]; 3];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for _ in 0..16 {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        let diag = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if off <= Real::EPSILON * Real::EPSILON * diag {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for row in a.iter_mut() {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (row_p, row_q) = (a[p], a[q]);
            for (k, (apk, aqk)) in row_p.into_iter().zip(row_q).enumerate() {
                a[p][k] = c * apk - s * aqk;
                a[q][k] = s * apk + c * aqk;
            }
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let col = |k: usize| Vector::new(v[0][k], v[1][k], v[2][k]);
    (
        [a[0][0], a[1][1], a[2][2]],
        Matrix::from_cols(col(0), col(1), col(2)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `A v = lambda v` for each pair, on a matrix with a known null direction.
    #[test]
    fn jacobi_finds_the_null_direction() {
        let n = Vector::new(1.0, 2.0, 2.0) / 3.0;
        let a = Vector::new(2.0, -1.0, 0.0).normalize();
        let b = n.cross(a);
        let m = outer(a, a) * 3.0 + outer(b, b) * 0.5;
        let (values, vectors) = symmetric_eigen(m);
        for (k, &value) in values.iter().enumerate() {
            let v = vectors.col(k);
            // Round-off of a few operations on O(1) entries (f32 or f64).
            assert!((m * v - v * value).length() < 100.0 * Real::EPSILON);
        }
        let k = (0..3)
            .min_by(|&i, &j| values[i].abs().total_cmp(&values[j].abs()))
            .unwrap();
        assert!(values[k].abs() < 100.0 * Real::EPSILON);
        assert!((vectors.col(k).dot(n).abs() - 1.0).abs() < 100.0 * Real::EPSILON);
    }
}
