//! Relative kinematics of node J with respect to node I, in the terms MPC184 reports them.
//!
//! - Relative displacement `u = [e^I]^T (x_J - x_I)`: the position of node J from node I in
//!   frame I (m).
//! - Relative rotation: the Bryant (Cardan X-Y'-Z'') angles of `R_rel = [e^I]^T [e^J]`
//!   (`R_rel = Rx(psi) Ry(phi) Rz(theta)`):
//!   `psi = -atan2(e3J.e2I, e3J.e3I)` about e1, `phi = asin(e3J.e1I)` about e2,
//!   `theta = -atan2(e2J.e1I, e1J.e1I)` about e3 (rad). `psi` and `theta` are unwrapped
//!   continuously beyond +-pi by [`AngleUnwrap`]; `phi` is limited to +-pi/2 by definition.
//! - Relative velocity: the time derivative of `u` (m/s, frame I) and the relative angular
//!   velocity `[e^I]^T (w_J - w_I)` (rad/s, frame I; for a single free rotation axis it is the
//!   rate of that angle).

use crate::math::{Matrix, PI, Real, Vector, asin, atan2};

/// Bryant (Cardan X-Y'-Z'') angles `[psi, phi, theta]` of a relative rotation matrix
/// `r = [e^I]^T [e^J]` (entries `r[i][j] = e_i^I . e_j^J`), each in radians, wrapped to
/// (-pi, pi] for psi and theta and [-pi/2, pi/2] for phi.
pub fn bryant_angles(r: &Matrix) -> [Real; 3] {
    // glam matrices are column-major: r.col(j)[i] = r[i][j].
    let e = |i: usize, j: usize| r.col(j)[i];
    // A joint's held angles are tiny: their series (`math::atan2`, `math::asin`).
    let psi = -atan2(e(1, 2), e(2, 2));
    let phi = asin(e(0, 2));
    let theta = -atan2(e(0, 1), e(0, 0));
    [psi, phi, theta]
}

/// 3-1-3 Euler angles `[alpha, beta, gamma]` of `r = [e^I]^T [e^J]` (`R = Rz(alpha) Rx(beta)
/// Rz(gamma)`), the rotation measure of the genb joint (KEYOPT(1) = 19). At `beta = 0` the
/// split between alpha and gamma is arbitrary: alpha takes the whole angle.
pub fn euler_313_angles(r: &Matrix) -> [Real; 3] {
    let e = |i: usize, j: usize| r.col(j)[i];
    let beta = e(2, 2).clamp(-1.0, 1.0).acos();
    if beta.sin().abs() < 1e3 * Real::EPSILON {
        // Degenerate: R = Rz(alpha + gamma) (beta = 0) or Rz(alpha - gamma) Rx(pi).
        let alpha = e(1, 0).atan2(e(0, 0));
        return [alpha, beta, 0.0];
    }
    let alpha = e(0, 2).atan2(-e(1, 2));
    let gamma = e(2, 0).atan2(e(2, 1));
    [alpha, beta, gamma]
}

/// The relative rotation matrix `[e^I]^T [e^J]` from the two frames' axes (columns e1 e2 e3,
/// global components).
pub fn relative_rotation(axes1: &Matrix, axes2: &Matrix) -> Matrix {
    axes1.transpose() * *axes2
}

/// Continuous unwrapping of an angle that a wrapped formula returns in (-pi, pi]: each new value
/// is moved by whole turns to lie within pi of the previous unwrapped one, so that a joint
/// turning several times reports `2 pi n + ...` (the `u_r = phi - phi0 + m pi` of MPC184).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AngleUnwrap {
    /// The last unwrapped value (rad).
    pub last: Real,
}

impl AngleUnwrap {
    /// Starts from a wrapped value.
    pub fn new(initial: Real) -> Self {
        Self { last: initial }
    }

    /// Feeds the next wrapped value and returns the unwrapped one.
    pub fn update(&mut self, wrapped: Real) -> Real {
        let two_pi = 2.0 * PI;
        let mut d = wrapped - self.last;
        d -= two_pi * (d / two_pi).round();
        self.last += d;
        self.last
    }
}

/// Relative displacement of point `x2` from `x1` in the frame with axes `axes1` (m).
pub fn relative_displacement(axes1: &Matrix, x1: Vector, x2: Vector) -> Vector {
    axes1.transpose() * (x2 - x1)
}

/// Rate of [`relative_displacement`] in frame I: `[e^I]^T (v2 - v1 - w1 x (x2 - x1))`, with
/// `v1`, `v2` the velocities of the two material points and `w1` the angular velocity of frame
/// I (m/s).
pub fn relative_velocity(
    axes1: &Matrix,
    x1: Vector,
    x2: Vector,
    v1: Vector,
    v2: Vector,
    w1: Vector,
) -> Vector {
    axes1.transpose() * (v2 - v1 - w1.cross(x2 - x1))
}

/// Relative angular velocity `[e^I]^T (w2 - w1)` in frame I (rad/s).
pub fn relative_angular_velocity(axes1: &Matrix, w1: Vector, w2: Vector) -> Vector {
    axes1.transpose() * (w2 - w1)
}
