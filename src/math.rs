//! Scalar and vector types, switched between f64 (default, `rapier3d-f64`) and f32 (`rapier3d`).
//!
//! Everything physical in this crate is expressed with these aliases so that the precision is one
//! feature switch. SI units and radians throughout.

#[cfg(all(feature = "f32", feature = "f64"))]
compile_error!(
    "features `f32` and `f64` are exclusive: use `--no-default-features --features f32[,ecs]` for f32"
);
#[cfg(not(any(feature = "f32", feature = "f64")))]
compile_error!("enable exactly one of the features `f64` (default) or `f32`");

#[cfg(feature = "f32")]
pub use rapier3d as rapier;
#[cfg(feature = "f64")]
pub use rapier3d_f64 as rapier;

pub use rapier::math::{Matrix, Pose, Real, Rotation, Vector};

/// The constant pi in [`Real`] precision.
pub const PI: Real = core::f64::consts::PI as Real;

/// Two bodies' or two frames' quaternion and vector arithmetic at once, one per lane of a SIMD
/// register. Each lane runs glam's operations in glam's order (`DQuat::mul_quat`,
/// `DQuat::mul_vec3`, `DQuat::normalize`, `DMat3::from_quat`, `DVec3::dot` and `cross`), with
/// no fused multiply-add, so in `f64` the results are glam's to the bit. The compiler's own
/// vectorisation of the scalar code pairs the components of one quaternion, with shuffles
/// between them: `rows::FramePair::at` took 302 instructions that way and 201 in lanes.
pub(crate) mod pair {
    use super::{Matrix, Real, Rotation, Vector};

    /// The lane type: two lanes of `f64`, or the first two of four of `f32`.
    #[cfg(not(feature = "f32"))]
    pub(crate) type L = wide::f64x2;
    /// The lane type: two lanes of `f64`, or the first two of four of `f32`.
    #[cfg(feature = "f32")]
    pub(crate) type L = wide::f32x4;

    /// `a` in lane 0, `b` in lane 1.
    #[inline(always)]
    pub(crate) fn lanes(a: Real, b: Real) -> L {
        #[cfg(not(feature = "f32"))]
        return L::new([a, b]);
        #[cfg(feature = "f32")]
        return L::new([a, b, 0.0, 0.0]);
    }

    /// Lanes 0 and 1.
    #[inline(always)]
    pub(crate) fn split(v: L) -> [Real; 2] {
        let a = v.to_array();
        [a[0], a[1]]
    }

    /// Two vectors.
    #[derive(Clone, Copy)]
    pub(crate) struct V {
        pub(crate) x: L,
        pub(crate) y: L,
        pub(crate) z: L,
    }

    impl V {
        #[inline(always)]
        pub(crate) fn new(a: Vector, b: Vector) -> V {
            V {
                x: lanes(a.x, b.x),
                y: lanes(a.y, b.y),
                z: lanes(a.z, b.z),
            }
        }

        #[inline(always)]
        pub(crate) fn split(self) -> [Vector; 2] {
            let ([x0, x1], [y0, y1], [z0, z1]) = (split(self.x), split(self.y), split(self.z));
            [Vector::new(x0, y0, z0), Vector::new(x1, y1, z1)]
        }

        #[inline(always)]
        pub(crate) fn add(self, o: V) -> V {
            V {
                x: self.x + o.x,
                y: self.y + o.y,
                z: self.z + o.z,
            }
        }

        #[inline(always)]
        pub(crate) fn sub(self, o: V) -> V {
            V {
                x: self.x - o.x,
                y: self.y - o.y,
                z: self.z - o.z,
            }
        }

        /// Each component times `k`.
        #[inline(always)]
        pub(crate) fn scale(self, k: L) -> V {
            V {
                x: self.x * k,
                y: self.y * k,
                z: self.z * k,
            }
        }

        #[inline(always)]
        pub(crate) fn dot(self, o: V) -> L {
            self.x * o.x + self.y * o.y + self.z * o.z
        }

        #[inline(always)]
        pub(crate) fn cross(self, o: V) -> V {
            V {
                x: self.y * o.z - o.y * self.z,
                y: self.z * o.x - o.z * self.x,
                z: self.x * o.y - o.x * self.y,
            }
        }
    }

    /// Two quaternions.
    #[derive(Clone, Copy)]
    pub(crate) struct Q {
        pub(crate) x: L,
        pub(crate) y: L,
        pub(crate) z: L,
        pub(crate) w: L,
    }

    impl Q {
        #[inline(always)]
        pub(crate) fn new(a: Rotation, b: Rotation) -> Q {
            Q {
                x: lanes(a.x, b.x),
                y: lanes(a.y, b.y),
                z: lanes(a.z, b.z),
                w: lanes(a.w, b.w),
            }
        }

        #[inline(always)]
        pub(crate) fn split(self) -> [Rotation; 2] {
            let [x0, x1] = split(self.x);
            let [y0, y1] = split(self.y);
            let [z0, z1] = split(self.z);
            let [w0, w1] = split(self.w);
            [
                Rotation::from_xyzw(x0, y0, z0, w0),
                Rotation::from_xyzw(x1, y1, z1, w1),
            ]
        }

        /// [`super::turn`] of two rotation vectors by its series, or `None` where either is
        /// outside the series' range (then each takes `turn`).
        #[inline(always)]
        pub(crate) fn turn(dth: V) -> Option<Q> {
            let x2 = L::splat(0.25) * dth.dot(dth);
            let [xa, xb] = split(x2);
            if xa >= super::TURN_SERIES_LIMIT || xb >= super::TURN_SERIES_LIMIT {
                return None;
            }
            let (one, c) = (L::splat(1.0), |k: Real| L::splat(k));
            let s = c(0.5) * (one - x2 / c(6.0) * (one - x2 / c(20.0) * (one - x2 / c(42.0))));
            let w = one - x2 / c(2.0) * (one - x2 / c(12.0) * (one - x2 / c(30.0)));
            let v = dth.scale(s);
            Some(Q {
                x: v.x,
                y: v.y,
                z: v.z,
                w,
            })
        }

        /// `self * o` (`DQuat::mul_quat`).
        #[inline(always)]
        pub(crate) fn mul(self, o: Q) -> Q {
            let (x0, y0, z0, w0) = (self.x, self.y, self.z, self.w);
            let (x1, y1, z1, w1) = (o.x, o.y, o.z, o.w);
            Q {
                x: w0 * x1 + x0 * w1 + y0 * z1 - z0 * y1,
                y: w0 * y1 - x0 * z1 + y0 * w1 + z0 * x1,
                z: w0 * z1 + x0 * y1 - y0 * x1 + z0 * w1,
                w: w0 * w1 - x0 * x1 - y0 * y1 - z0 * z1,
            }
        }

        /// `self * v` (`DQuat::mul_vec3`).
        #[inline(always)]
        pub(crate) fn rotate(self, v: V) -> V {
            let two = L::splat(2.0);
            let b = V {
                x: self.x,
                y: self.y,
                z: self.z,
            };
            let b2 = b.dot(b);
            v.scale(self.w * self.w - b2)
                .add(b.scale(v.dot(b) * two))
                .add(b.cross(v).scale(self.w * two))
        }

        /// `DQuat::normalize`: each component times `1 / sqrt(x x + y y + z z + w w)`.
        #[inline(always)]
        pub(crate) fn normalize(self) -> Q {
            let len =
                (self.x * self.x + self.y * self.y + self.z * self.z + self.w * self.w).sqrt();
            let r = L::splat(1.0) / len;
            Q {
                x: self.x * r,
                y: self.y * r,
                z: self.z * r,
                w: self.w * r,
            }
        }

        /// The two rotation matrices (`DMat3::from_quat`).
        #[inline(always)]
        pub(crate) fn axes(self) -> [Matrix; 2] {
            let one = L::splat(1.0);
            let (x2, y2, z2) = (self.x + self.x, self.y + self.y, self.z + self.z);
            let (xx, xy, xz) = (self.x * x2, self.x * y2, self.x * z2);
            let (yy, yz, zz) = (self.y * y2, self.y * z2, self.z * z2);
            let (wx, wy, wz) = (self.w * x2, self.w * y2, self.w * z2);
            let cols = [
                split(one - (yy + zz)),
                split(xy + wz),
                split(xz - wy),
                split(xy - wz),
                split(one - (xx + zz)),
                split(yz + wx),
                split(xz + wy),
                split(yz - wx),
                split(one - (xx + yy)),
            ];
            let m = |k: usize| Matrix::from_cols_array(&core::array::from_fn(|e| cols[e][k]));
            [m(0), m(1)]
        }
    }
}

/// The rotation vector (axis times angle, rad, world frame) of the turn from `from` to `to`,
/// `to = exp(turn) from`: the shorter of the two arcs (a unit quaternion and its negative are
/// the same rotation), and exact for small turns (`Rotation::to_scaled_axis` returns zero
/// below 2e-8 rad, and the long way round when the quotient's scalar part is negative).
pub fn turn_between(from: Rotation, to: Rotation) -> Vector {
    let d = to * from.inverse();
    let d = if d.w < 0.0 { -d } else { d };
    let v = Vector::new(d.x, d.y, d.z);
    let s = v.length();
    if s > 0.0 {
        v * (2.0 * atan2(s, d.w) / s)
    } else {
        Vector::ZERO
    }
}

/// The squared half angle (rad^2) from which [`turn`] calls `Rotation::from_scaled_axis`
/// instead of its series: a turn of 0.01 rad. The series is also in `pair::Q::turn`, two
/// turns at a time, in the same operations.
pub(crate) const TURN_SERIES_LIMIT: Real = 2.5e-5;

/// The rotation by the rotation vector `dth` (axis times angle, rad): `Rotation::from_scaled_axis`,
/// with the half angle's sine and cosine from their series below 0.01 rad (the terms left out
/// are below 1e-20 of the result), which skips the square root, the division and the `sin_cos`
/// call that dominate it there. The position projection turns every body by such a small
/// correction at each chord step (`sincos` alone was 2.8 % of the 100-link chain's step).
#[inline]
pub(crate) fn turn(dth: Vector) -> Rotation {
    // x = angle / 2; sin(x) / (2 x) and cos(x) in powers of x^2.
    let x2 = 0.25 * dth.length_squared();
    if x2 >= TURN_SERIES_LIMIT {
        return Rotation::from_scaled_axis(dth);
    }
    let s = 0.5 * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0)));
    let c = 1.0 - x2 / 2.0 * (1.0 - x2 / 12.0 * (1.0 - x2 / 30.0));
    let v = dth * s;
    Rotation::from_xyzw(v.x, v.y, v.z, c)
}

/// `y.atan2(x)`, from the series of `atan(y / x)` where `x > 0` and `|y| <= 1e-3 x` (the terms
/// left out are below `(y / x)^6 / 7 <= 1.5e-19` of the result, under an ulp in `f64`), and
/// `Real::atan2` elsewhere (NaN and the infinities included). The angles a joint holds are of
/// that size (`1e-10` rad or less), and each step measures them for every joint's output
/// (`atan2` took 3.2 % of `perf`'s samples of the 400-arm mixed scene on `rapier-impulse`).
/// Measured: -0.5 to -0.8 % instructions per step there, -0.1 to -0.3 % on the Lagrange
/// backend; timed, the same within the noise.
#[inline]
pub(crate) fn atan2(y: Real, x: Real) -> Real {
    if x > 0.0 && y.abs() <= 1e-3 * x {
        let t = y / x;
        let t2 = t * t;
        return t * (1.0 - t2 * (1.0 / 3.0 - t2 / 5.0));
    }
    y.atan2(x)
}

/// `s.clamp(-1, 1).asin()`, from its series where `|s| <= 1e-3` (the terms left out are below
/// `5 s^6 / 112 <= 4.5e-20` of the result), as [`atan2`].
#[inline]
pub(crate) fn asin(s: Real) -> Real {
    if s.abs() <= 1e-3 {
        let s2 = s * s;
        return s * (1.0 + s2 * (1.0 / 6.0 + s2 * (3.0 / 40.0)));
    }
    s.clamp(-1.0, 1.0).asin()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The series agree with `Real::atan2` and `Real::asin` to 2 ulps over their whole range
    /// (the truncation is under an ulp, see [`atan2`]; the rest is the rounding of a few
    /// products: measured 1.0 ulp at most in `f64`, 0.9 in `f32`), and hand everything else
    /// (large angles, the other half-planes, zero, NaN, the infinities) to them unchanged.
    #[test]
    fn small_angle_series_match_the_library() {
        let ulps =
            |a: Real, b: Real| (a - b).abs() / (Real::EPSILON * b.abs().max(Real::MIN_POSITIVE));
        let mut worst: Real = 0.0;
        for k in 0..=2000 {
            let t = 1e-3 * (k as Real / 1000.0 - 1.0) * 1.0000001;
            for x in [1e-30, 1e-7, 0.3, 1.0, 7.0, 1e30] {
                let y = t * x;
                if y.is_finite() && y != 0.0 && (y / x).abs() <= 1e-3 {
                    worst = worst.max(ulps(atan2(y, x), y.atan2(x)));
                }
            }
            if t != 0.0 {
                worst = worst.max(ulps(asin(t), t.asin()));
            }
        }
        assert!(worst <= 2.0, "worst {worst} ulps");
        for (y, x) in [
            (1.0, 1.0),
            (0.5, -1.0),
            (-2.0, 0.0),
            (0.0, 1.0),
            (-0.0, 1.0),
            (0.0, -1.0),
        ] {
            assert_eq!(atan2(y, x).to_bits(), y.atan2(x).to_bits(), "({y}, {x})");
        }
        assert!(atan2(Real::NAN, 1.0).is_nan() && atan2(1e-9, Real::NAN).is_nan());
        assert_eq!(atan2(1.0, Real::INFINITY), 1.0 as Real / Real::INFINITY);
        assert_eq!(asin(0.5), (0.5 as Real).asin());
        assert_eq!(asin(2.0), (1.0 as Real).asin());
        assert!(asin(Real::NAN).is_nan());
    }

    /// A turn of 1e-9 rad comes back to round-off (it was zero through `to_scaled_axis`), and
    /// a turn of 3 rad stored with a negative scalar part comes back as 3 rad about the same
    /// axis, not as `2 pi - 3` the other way.
    #[test]
    fn turn_between_is_the_short_arc_and_exact_when_small() {
        let from = Rotation::from_scaled_axis(Vector::new(0.3, -0.2, 0.9));
        let axis = Vector::new(1.0, 2.0, -2.0) / 3.0;
        for angle in [1e-9, 0.5, 3.0] {
            let to = Rotation::from_scaled_axis(axis * angle) * from;
            for q in [to, -to] {
                let turn = turn_between(from, q);
                // f32 builds: 1e-9 rad is far below their round-off in the quaternions.
                let tol = if Real::EPSILON < 1e-10 {
                    1e-12 * angle.max(1e-3)
                } else {
                    1e-6
                };
                assert!(
                    (turn - axis * angle).length() <= tol,
                    "turn {turn:?} for {angle} rad"
                );
            }
        }
        if Real::EPSILON < 1e-10 {
            let small = Rotation::from_scaled_axis(axis * 1e-9) * from;
            assert_eq!((small * from.inverse()).to_scaled_axis(), Vector::ZERO);
        }
    }

    /// `turn` against `from_scaled_axis` on both sides of its series' bound (0.01 rad) and at
    /// zero: the series' first term left out is `x^8 / 9!` of the sine (`x` the half angle),
    /// below 1e-20 at the bound, so the two agree to round-off (a few `Real::EPSILON`).
    #[test]
    fn turn_matches_from_scaled_axis() {
        let axis = Vector::new(2.0, -1.0, 2.0) / 3.0;
        for angle in [0.0, 1e-12, 1e-6, 1e-3, 9.99e-3, 1.001e-2, 0.3, 2.0] {
            let a = turn(axis * angle);
            let b = Rotation::from_scaled_axis(axis * angle);
            let d = (a.x - b.x)
                .abs()
                .max((a.y - b.y).abs())
                .max((a.z - b.z).abs())
                .max((a.w - b.w).abs());
            assert!(d <= 4.0 * Real::EPSILON, "{angle} rad: {a:?} against {b:?}");
        }
    }
}
