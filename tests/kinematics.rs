//! Relative kinematics of node J with respect to node I (reference A.3): rotation measures and
//! rates, against rotation matrices built by hand.
//!
//! - Bryant (Cardan X-Y'-Z'') angles: for `R_rel = [e^I]^T [e^J] = Rx(psi) Ry(phi) Rz(theta)`,
//!   multiplying out gives `R_rel[1][2] = -sin(psi) cos(phi)`, `R_rel[2][2] = cos(psi) cos(phi)`,
//!   `R_rel[0][2] = sin(phi)`, `R_rel[0][1] = -cos(phi) sin(theta)`, `R_rel[0][0] = cos(phi)
//!   cos(theta)`, so the issue's `psi = -atan2(e3J.e2I, e3J.e3I)`, `phi = asin(e3J.e1I)`,
//!   `theta = -atan2(e2J.e1I, e1J.e1I)` recover the angles for |phi| < pi/2. Checked on a grid
//!   with |phi| <= pi/2 - 0.05, directly and with frames I and J given as separate global
//!   rotations. Tolerance 1e-12 rad: the matrices carry a few ulps (~1e-15) of rounding, and the
//!   angle derivatives amplify it by at most 1/cos(phi) <= 1/sin(0.05) ~ 20.
//! - 3-1-3 Euler angles (genb): `R = Rz(a) Rx(b) Rz(c)` has `R[2][2] = cos b`, `R[0][2] = sin a
//!   sin b`, `R[1][2] = -cos a sin b`, `R[2][0] = sin b sin c`, `R[2][1] = sin b cos c`; recovered
//!   to 1e-12 rad for b in [0.05, pi - 0.05] (same 1/sin(b) <= 20 amplification). At the singular
//!   b = 0 and b = pi only the product matters: the returned angles must rebuild R (1e-12).
//! - Unwrapping: a revolute-z rotation of 2.5 turns fed in steps of 0.3 rad (wrapped Bryant theta
//!   in (-pi, pi]) must read 5 pi, and return to 0 on the way back, and -5 pi the other way;
//!   every intermediate value must equal the angle fed. Tolerance 1e-9 rad (the angles are exact
//!   to ~1e-14 after up to 53 steps; 1e-9 is the bound).
//! - Rates: for two rigid bodies moving with constant linear and (spatial) angular velocity,
//!   `relative_velocity` must equal a central finite difference of `relative_displacement`,
//!   `relative_angular_velocity` along a single relative rotation axis must equal the finite
//!   difference of the Bryant angle about that axis (the other two rates ~0), and in general
//!   `relative_angular_velocity = psi' ex + phi' Rx(psi) ey + theta' Rx(psi) Ry(phi) ez` (the
//!   angular velocity of `R_rel = Rx Ry Rz` in frame I, since `dR_rel/dt R_rel^T =
//!   [R_I^T (w_J - w_I)]x`). Step h = 1e-5 s: the central difference errs by `h^2/6 |f'''|`
//!   (|f'''| <~ 100 with |w| <= 2 rad/s, levers <= 3 m: ~2e-9) plus rounding `eps |f| / h` (~1e-10),
//!   so the tolerance is 1e-7 (m/s or rad/s), 50x above the estimate; measured errors are <= 1.2e-9.
//!
//! All rotation matrices are built by hand from sines and cosines (and Rodrigues' formula for the
//! rigid-body motion); glam is column-major, `m.col(j)[i]` is entry (i, j). f64 only: the
//! tolerances are far below f32 precision.
#![cfg(feature = "f64")]

use rapier3d_mpc184::kinematics::{
    AngleUnwrap, bryant_angles, euler_313_angles, relative_angular_velocity, relative_displacement,
    relative_rotation, relative_velocity,
};
use rapier3d_mpc184::math::{Matrix, PI, Real, Vector};

const ANGLE_TOL: Real = 1e-12;
const UNWRAP_TOL: Real = 1e-9;
const FD_STEP: Real = 1e-5;
const FD_TOL: Real = 1e-7;

fn v(x: Real, y: Real, z: Real) -> Vector {
    Vector::new(x, y, z)
}

/// Rotation about x: rows [1 0 0; 0 c -s; 0 s c] (given here by columns).
fn rx(a: Real) -> Matrix {
    let (s, c) = a.sin_cos();
    Matrix::from_cols(v(1.0, 0.0, 0.0), v(0.0, c, s), v(0.0, -s, c))
}

/// Rotation about y: rows [c 0 s; 0 1 0; -s 0 c].
fn ry(a: Real) -> Matrix {
    let (s, c) = a.sin_cos();
    Matrix::from_cols(v(c, 0.0, -s), v(0.0, 1.0, 0.0), v(s, 0.0, c))
}

/// Rotation about z: rows [c -s 0; s c 0; 0 0 1].
fn rz(a: Real) -> Matrix {
    let (s, c) = a.sin_cos();
    Matrix::from_cols(v(c, s, 0.0), v(-s, c, 0.0), v(0.0, 0.0, 1.0))
}

/// Rodrigues: rotation by |r| about r/|r|, `I + sin t K + (1 - cos t) K^2`.
fn rodrigues(r: Vector) -> Matrix {
    let t = r.length();
    if t == 0.0 {
        return Matrix::IDENTITY;
    }
    let k = r / t;
    let kk = Matrix::from_cols(v(0.0, k.z, -k.y), v(-k.z, 0.0, k.x), v(k.y, -k.x, 0.0));
    Matrix::IDENTITY + kk * t.sin() + kk * kk * (1.0 - t.cos())
}

/// Entry (i, j).
fn at(m: &Matrix, i: usize, j: usize) -> Real {
    m.col(j)[i]
}

/// `a - b` wrapped to (-pi, pi].
fn wrap_diff(a: Real, b: Real) -> Real {
    let d = (a - b).rem_euclid(2.0 * PI);
    if d > PI { d - 2.0 * PI } else { d }
}

/// Some global orientations of frame I (none special).
fn frames_i() -> Vec<Matrix> {
    vec![
        Matrix::IDENTITY,
        rodrigues(v(0.3, -1.1, 0.7)),
        rodrigues(v(-2.0, 0.4, 1.9)),
        rodrigues(v(0.0, 2.9, -0.2)),
    ]
}

fn psi_theta_grid() -> Vec<Real> {
    vec![
        -PI + 1e-6,
        -3.0,
        -2.2,
        -1.3,
        -0.4,
        0.0,
        0.25,
        1.1,
        1.9,
        2.7,
        PI - 1e-6,
    ]
}

fn phi_grid() -> Vec<Real> {
    let lim = 0.5 * PI - 0.05;
    (0..=10)
        .map(|k| -lim + 2.0 * lim * k as Real / 10.0)
        .collect()
}

#[test]
fn bryant_angles_recover_rx_ry_rz() {
    let mut worst: Real = 0.0;
    for &psi in &psi_theta_grid() {
        for &phi in &phi_grid() {
            for &theta in &psi_theta_grid() {
                let r = rx(psi) * ry(phi) * rz(theta);
                let got = bryant_angles(&r);
                for (k, (g, w)) in got.iter().zip([psi, phi, theta]).enumerate() {
                    let err = (g - w).abs();
                    worst = worst.max(err);
                    assert!(
                        err <= ANGLE_TOL,
                        "Rx({psi}) Ry({phi}) Rz({theta}): angle {k} = {g} vs expected {w} \
                         (error {err:e})"
                    );
                }
            }
        }
    }
    println!("bryant_angles: worst error {worst:e} rad");
}

#[test]
fn bryant_angles_of_separate_global_frames() {
    let mut worst: Real = 0.0;
    for ri in frames_i() {
        for &psi in &psi_theta_grid() {
            for &phi in &phi_grid() {
                for &theta in &psi_theta_grid() {
                    let rj = ri * rx(psi) * ry(phi) * rz(theta);
                    let (e1i, e2i, e3i) = (ri.col(0), ri.col(1), ri.col(2));
                    let (e1j, e2j, e3j) = (rj.col(0), rj.col(1), rj.col(2));
                    // The formulas, from the global axes directly.
                    let by_hand = [
                        -(e3j.dot(e2i)).atan2(e3j.dot(e3i)),
                        e3j.dot(e1i).asin(),
                        -(e2j.dot(e1i)).atan2(e1j.dot(e1i)),
                    ];
                    let rel = relative_rotation(&ri, &rj);
                    let got = bryant_angles(&rel);
                    for k in 0..3 {
                        let want = [psi, phi, theta][k];
                        let e_hand = wrap_diff(by_hand[k], want).abs();
                        let e_lib = wrap_diff(got[k], want).abs();
                        worst = worst.max(e_hand).max(e_lib);
                        assert!(
                            e_hand <= ANGLE_TOL,
                            "issue formula, angle {k}: {} vs expected {want} (error {e_hand:e})",
                            by_hand[k]
                        );
                        assert!(
                            e_lib <= ANGLE_TOL,
                            "bryant_angles(R_I^T R_J), angle {k}: {} vs expected {want} \
                             (psi {psi}, phi {phi}, theta {theta}; error {e_lib:e})",
                            got[k]
                        );
                    }
                }
            }
        }
    }
    println!("separate frames: worst error {worst:e} rad");
}

#[test]
fn relative_rotation_is_ri_transpose_rj() {
    // Entry (i, j) must be e_i^I . e_j^J.
    let ri = rodrigues(v(0.3, -1.1, 0.7));
    let rj = rodrigues(v(-0.5, 0.2, 2.4));
    let rel = relative_rotation(&ri, &rj);
    for i in 0..3 {
        for j in 0..3 {
            let want = ri.col(i).dot(rj.col(j));
            let got = at(&rel, i, j);
            assert!(
                (got - want).abs() <= ANGLE_TOL,
                "R_rel[{i}][{j}] = {got} vs e{}I.e{}J = {want}",
                i + 1,
                j + 1
            );
        }
    }
}

/// Feeds angles `a0 + k step` (and finally `a1`) as a revolute-z rotation between two global
/// frames and returns the unwrapped readings paired with the angles fed.
fn unwrap_sweep(unwrap: &mut AngleUnwrap, a0: Real, a1: Real, step: Real) -> Vec<(Real, Real)> {
    let ri = rodrigues(v(0.4, 1.2, -0.8));
    let n = ((a1 - a0) / step).abs().floor() as usize;
    let mut angles: Vec<Real> = (1..=n).map(|k| a0 + step * k as Real).collect();
    angles.push(a1);
    angles
        .into_iter()
        .map(|a| {
            let rj = ri * rz(a);
            let theta = bryant_angles(&relative_rotation(&ri, &rj))[2];
            (a, unwrap.update(theta))
        })
        .collect()
}

fn check_sweep(what: &str, readings: &[(Real, Real)]) {
    for &(fed, read) in readings {
        assert!(
            (read - fed).abs() <= UNWRAP_TOL,
            "{what}: unwrapped {read} vs angle fed {fed} (error {:e})",
            (read - fed).abs()
        );
    }
}

#[test]
fn unwrap_two_and_a_half_turns_each_way() {
    let five_pi = 5.0 * PI;
    let mut u = AngleUnwrap::new(0.0);
    let fwd = unwrap_sweep(&mut u, 0.0, five_pi, 0.3);
    assert!(fwd.len() >= 53, "forward sweep has {} steps", fwd.len());
    check_sweep("0 -> 5 pi", &fwd);
    let end = fwd.last().unwrap().1;
    assert!(
        (end - five_pi).abs() <= UNWRAP_TOL,
        "after 2.5 turns: {end} vs 5 pi = {five_pi}"
    );
    // Back to 0 from there, with the same unwrapper.
    let back = unwrap_sweep(&mut u, five_pi, 0.0, -0.3);
    check_sweep("5 pi -> 0", &back);
    let end = back.last().unwrap().1;
    assert!(end.abs() <= UNWRAP_TOL, "back at the start: {end} vs 0");
    // The other way round from 0.
    let mut u = AngleUnwrap::new(0.0);
    let neg = unwrap_sweep(&mut u, 0.0, -five_pi, -0.3);
    check_sweep("0 -> -5 pi", &neg);
    let end = neg.last().unwrap().1;
    assert!(
        (end + five_pi).abs() <= UNWRAP_TOL,
        "after -2.5 turns: {end} vs -5 pi = {}",
        -five_pi
    );
}

#[test]
fn euler_313_recovers_rz_rx_rz() {
    let mut worst: Real = 0.0;
    let b_lim = (0.05, PI - 0.05);
    let bs: Vec<Real> = (0..=12)
        .map(|k| b_lim.0 + (b_lim.1 - b_lim.0) * k as Real / 12.0)
        .collect();
    for &a in &psi_theta_grid() {
        for &b in &bs {
            for &c in &psi_theta_grid() {
                let r = rz(a) * rx(b) * rz(c);
                let got = euler_313_angles(&r);
                for (k, want) in [a, b, c].into_iter().enumerate() {
                    let err = wrap_diff(got[k], want).abs();
                    worst = worst.max(err);
                    assert!(
                        err <= ANGLE_TOL,
                        "Rz({a}) Rx({b}) Rz({c}): 3-1-3 angle {k} = {} vs expected {want} \
                         (error {err:e})",
                        got[k]
                    );
                }
            }
        }
    }
    println!("euler_313_angles: worst error {worst:e} rad");
}

#[test]
fn euler_313_singular_poses_rebuild_the_rotation() {
    for b in [0.0, PI] {
        for (a, c) in [(0.3, 0.9), (-2.5, 1.7), (3.0, 3.0), (0.0, -1.0)] {
            let r = rz(a) * rx(b) * rz(c);
            let [ga, gb, gc] = euler_313_angles(&r);
            let back = rz(ga) * rx(gb) * rz(gc);
            let err = (back - r)
                .abs()
                .to_cols_array()
                .into_iter()
                .fold(0.0, Real::max);
            assert!(
                err <= ANGLE_TOL,
                "Rz({a}) Rx({b}) Rz({c}) -> ({ga}, {gb}, {gc}) rebuilds with error {err:e}"
            );
            assert!(
                (gb - b).abs() <= ANGLE_TOL,
                "singular beta: {gb} vs expected {b}"
            );
        }
    }
}

/// A rigid body moving with constant velocity `vel` of its centre and constant spatial angular
/// velocity `w`: at time t, centre `c0 + vel t`, orientation `rodrigues(w t) q0`.
#[derive(Clone, Copy)]
struct Body {
    c0: Vector,
    vel: Vector,
    q0: Matrix,
    w: Vector,
}

impl Body {
    fn rot(&self, t: Real) -> Matrix {
        rodrigues(self.w * t) * self.q0
    }
    /// Global position of the material point at body-frame offset `r`.
    fn point(&self, r: Vector, t: Real) -> Vector {
        self.c0 + self.vel * t + self.rot(t) * r
    }
    /// Velocity of that material point: `vel + w x (R r)`.
    fn point_vel(&self, r: Vector, t: Real) -> Vector {
        self.vel + self.w.cross(self.rot(t) * r)
    }
}

struct Pair {
    b1: Body,
    b2: Body,
    /// Node I and node J offsets in their body frames.
    r1: Vector,
    r2: Vector,
    /// Frame I and frame J axes in their body frames.
    a1: Matrix,
    a2: Matrix,
}

impl Pair {
    fn axes1(&self, t: Real) -> Matrix {
        self.b1.rot(t) * self.a1
    }
    fn axes2(&self, t: Real) -> Matrix {
        self.b2.rot(t) * self.a2
    }
    fn displacement(&self, t: Real) -> Vector {
        relative_displacement(
            &self.axes1(t),
            self.b1.point(self.r1, t),
            self.b2.point(self.r2, t),
        )
    }
    fn bryant(&self, t: Real) -> [Real; 3] {
        bryant_angles(&relative_rotation(&self.axes1(t), &self.axes2(t)))
    }
    /// Central difference of the Bryant angles at t.
    fn bryant_rates(&self, t: Real) -> [Real; 3] {
        let (p, m) = (self.bryant(t + FD_STEP), self.bryant(t - FD_STEP));
        [0, 1, 2].map(|k| wrap_diff(p[k], m[k]) / (2.0 * FD_STEP))
    }
}

/// Random-ish poses and velocities (|w| <= 2 rad/s, |v| <= 1 m/s, offsets <= 3 m).
fn random_pairs() -> Vec<Pair> {
    vec![
        Pair {
            b1: Body {
                c0: v(0.2, -0.5, 1.0),
                vel: v(0.3, 0.1, -0.4),
                q0: rodrigues(v(0.4, -0.9, 0.3)),
                w: v(0.7, -1.2, 0.5),
            },
            b2: Body {
                c0: v(1.5, 0.4, 0.2),
                vel: v(-0.6, 0.2, 0.5),
                q0: rodrigues(v(-1.3, 0.2, 0.8)),
                w: v(-0.4, 0.9, 1.4),
            },
            r1: v(0.8, 0.3, -0.6),
            r2: v(-1.1, 0.5, 0.9),
            a1: rodrigues(v(0.2, 0.6, -0.4)),
            a2: rodrigues(v(-0.7, 0.1, 0.3)),
        },
        Pair {
            b1: Body {
                c0: v(-2.0, 1.0, 0.5),
                vel: v(0.0, 0.8, 0.1),
                q0: rodrigues(v(2.1, 0.3, -0.5)),
                w: v(0.1, 0.2, -1.9),
            },
            b2: Body {
                c0: v(0.0, 0.0, -1.0),
                vel: v(0.5, -0.5, 0.5),
                q0: rodrigues(v(0.0, -2.4, 0.6)),
                w: v(1.1, 1.0, 0.2),
            },
            r1: v(2.5, -1.0, 0.4),
            r2: v(0.0, 1.8, -0.7),
            a1: rodrigues(v(-1.0, 0.5, 0.9)),
            a2: Matrix::IDENTITY,
        },
        Pair {
            b1: Body {
                c0: v(0.0, 0.0, 0.0),
                vel: v(0.0, 0.0, 0.0),
                q0: Matrix::IDENTITY,
                w: v(0.0, 0.0, 0.0),
            },
            b2: Body {
                c0: v(1.0, 2.0, 3.0),
                vel: v(-0.2, 0.9, 0.3),
                q0: rodrigues(v(0.5, 0.5, 0.5)),
                w: v(-1.5, 0.6, -0.9),
            },
            r1: v(0.0, 0.0, 0.0),
            r2: v(0.3, -0.2, 0.1),
            a1: Matrix::IDENTITY,
            a2: rodrigues(v(0.9, -0.3, 0.0)),
        },
        Pair {
            b1: Body {
                c0: v(3.0, -1.0, 2.0),
                vel: v(0.9, -0.1, 0.2),
                q0: rodrigues(v(-0.6, -0.6, 1.7)),
                w: v(1.3, 1.3, -0.6),
            },
            b2: Body {
                c0: v(3.5, -0.2, 1.1),
                vel: v(-0.1, -0.3, 0.7),
                q0: rodrigues(v(1.2, -1.8, 0.1)),
                w: v(0.2, -0.8, 0.4),
            },
            r1: v(-1.4, 2.2, 0.6),
            r2: v(0.7, -0.4, -2.1),
            a1: rodrigues(v(0.0, 0.0, 1.0)),
            a2: rodrigues(v(1.0, 0.0, 0.0)),
        },
    ]
}

const T0: Real = 0.37;

#[test]
fn relative_velocity_is_the_rate_of_relative_displacement() {
    let mut worst: Real = 0.0;
    for (n, p) in random_pairs().iter().enumerate() {
        let fd = (p.displacement(T0 + FD_STEP) - p.displacement(T0 - FD_STEP)) / (2.0 * FD_STEP);
        let got = relative_velocity(
            &p.axes1(T0),
            p.b1.point(p.r1, T0),
            p.b2.point(p.r2, T0),
            p.b1.point_vel(p.r1, T0),
            p.b2.point_vel(p.r2, T0),
            p.b1.w,
        );
        let err = (got - fd).abs().max_element();
        worst = worst.max(err);
        assert!(
            err <= FD_TOL,
            "pair {n}: relative_velocity {got:?} vs finite difference {fd:?} (error {err:e} m/s)"
        );
    }
    println!("relative_velocity: worst error {worst:e} m/s");
}

#[test]
fn single_axis_rotation_rate_is_the_bryant_angle_rate() {
    // Both bodies spin about the same global line, the `axis`-th axis of frame I, at different
    // rates; frame J starts turned about it by `start`. Then R_rel = R_axis(start + (wJ - wI) t)
    // and the one Bryant angle about that axis changes at wJ - wI, the other two stay put.
    let mut worst: Real = 0.0;
    let (w_i, w_j) = (0.7, -1.3);
    let rate = w_j - w_i;
    for (n, p) in random_pairs().iter().enumerate() {
        for axis in 0..3 {
            let turn = [rx, ry, rz][axis];
            let start = if axis == 1 { 0.6 } else { 2.8 };
            let frame_i0 = p.b1.q0 * p.a1;
            let line = frame_i0.col(axis);
            let b1 = Body {
                w: line * w_i,
                ..p.b1
            };
            let b2 = Body {
                w: line * w_j,
                ..p.b2
            };
            // Frame J at t = 0: frame I turned by `start` about the axis, fixed in body 2.
            let a2 = p.b2.q0.transpose() * frame_i0 * turn(start);
            let q = Pair {
                b1,
                b2,
                r1: p.r1,
                r2: p.r2,
                a1: p.a1,
                a2,
            };
            let angles = q.bryant(T0);
            let want_angle = start + rate * T0;
            let e_angle = wrap_diff(angles[axis], want_angle).abs();
            assert!(
                e_angle <= ANGLE_TOL,
                "pair {n}, axis e{}: Bryant angle {} vs expected {want_angle}",
                axis + 1,
                angles[axis]
            );
            let fd = q.bryant_rates(T0);
            let got = relative_angular_velocity(&q.axes1(T0), q.b1.w, q.b2.w);
            for k in 0..3 {
                let want = if k == axis { rate } else { 0.0 };
                let e_fd = (fd[k] - want).abs();
                let e_got = (got[k] - fd[k]).abs();
                worst = worst.max(e_got);
                assert!(
                    e_fd <= FD_TOL,
                    "pair {n}, axis e{}: finite-difference rate {k} = {} vs expected {want}",
                    axis + 1,
                    fd[k]
                );
                assert!(
                    e_got <= FD_TOL,
                    "pair {n}, axis e{}: relative_angular_velocity[{k}] = {} vs finite \
                     difference {} (error {e_got:e} rad/s)",
                    axis + 1,
                    got[k],
                    fd[k]
                );
            }
        }
    }
    println!("single-axis angular rate: worst error {worst:e} rad/s");
}

#[test]
fn relative_angular_velocity_matches_bryant_rates_in_general() {
    // R_rel = Rx(psi) Ry(phi) Rz(theta) turns at psi' ex + phi' Rx(psi) ey + theta' Rx Ry ez
    // in frame I, which must equal [e^I]^T (wJ - wI).
    let mut worst: Real = 0.0;
    for (n, p) in random_pairs().iter().enumerate() {
        let [psi, phi, _] = p.bryant(T0);
        assert!(
            phi.abs() < 0.5 * PI - 0.1,
            "pair {n}: phi = {phi} too close to the Bryant singularity for this check"
        );
        let [dpsi, dphi, dtheta] = p.bryant_rates(T0);
        let from_rates = v(1.0, 0.0, 0.0) * dpsi
            + rx(psi) * v(0.0, 1.0, 0.0) * dphi
            + rx(psi) * ry(phi) * v(0.0, 0.0, 1.0) * dtheta;
        let got = relative_angular_velocity(&p.axes1(T0), p.b1.w, p.b2.w);
        let err = (got - from_rates).abs().max_element();
        worst = worst.max(err);
        assert!(
            err <= FD_TOL,
            "pair {n}: relative_angular_velocity {got:?} vs from Bryant rates {from_rates:?} \
             (error {err:e} rad/s)"
        );
        // Not trivially zero: the bodies really turn relative to each other.
        assert!(
            got.length() > 0.5,
            "pair {n}: relative angular velocity {got:?} is too small to test anything"
        );
    }
    println!("general angular rate: worst error {worst:e} rad/s");
}
