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
        v * (2.0 * s.atan2(d.w) / s)
    } else {
        Vector::ZERO
    }
}

/// The rotation by the rotation vector `dth` (axis times angle, rad): `Rotation::from_scaled_axis`,
/// with the half angle's sine and cosine from their series below 0.01 rad (the terms left out
/// are below 1e-20 of the result), which skips the square root, the division and the `sin_cos`
/// call that dominate it there. The position projection turns every body by such a small
/// correction at each chord step (`sincos` alone was 2.8 % of the 100-link chain's step).
#[inline]
pub(crate) fn turn(dth: Vector) -> Rotation {
    // x = angle / 2; sin(x) / (2 x) and cos(x) in powers of x^2.
    let x2 = 0.25 * dth.length_squared();
    if x2 >= 2.5e-5 {
        return Rotation::from_scaled_axis(dth);
    }
    let s = 0.5 * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0)));
    let c = 1.0 - x2 / 2.0 * (1.0 - x2 / 12.0 * (1.0 - x2 / 30.0));
    let v = dth * s;
    Rotation::from_xyzw(v.x, v.y, v.z, c)
}

#[cfg(test)]
mod tests {
    use super::*;

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
