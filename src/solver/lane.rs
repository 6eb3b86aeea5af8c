//! The arithmetic of the KKT kernels over one system or four at once: [`Real`] (one island)
//! and [`Lanes`] (four islands of the same structure, one per SIMD lane; `wide::f64x4`, the
//! type Rapier's own joint solver uses through simba, or `wide::f32x4` with the `f32` feature).
//!
//! Each lane runs the same IEEE operations in the same order as the scalar kernel (no fused
//! multiply-add: `wide` multiplies and adds separately), so a lane's result equals the scalar
//! one to the bit (`solver::kkt`'s test `lanes_factor_as_the_scalar_solver_does`).

use core::ops::{Add, AddAssign, Div, Mul, Neg, Sub, SubAssign};

use crate::math::Real;

/// Four [`Real`]s, one per island of a group (see the module docs).
#[cfg(not(feature = "f32"))]
pub type Lanes = wide::f64x4;
/// Four [`Real`]s, one per island of a group (see the module docs).
#[cfg(feature = "f32")]
pub type Lanes = wide::f32x4;

/// Islands in one [`Lanes`] value.
pub const LANES: usize = 4;

/// The operations the kernels need, on one system ([`Real`], its tests `bool`) or on four
/// ([`Lanes`], its tests a mask per lane).
pub trait Lane:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
{
    /// The outcome of a test, per lane.
    type Mask: Copy;
    /// A block is updated in place rather than through a copy: a copy of four-real entries
    /// costs more than it saves (measured on the mixed scene's Schur updates: -2.3 %
    /// instructions per step in lanes, +1.2 % on the 100-link chain in `Real`).
    const IN_PLACE: bool;
    /// Zero in every lane.
    const ZERO: Self;
    /// `x` in every lane.
    fn splat(x: Real) -> Self;
    /// Lane `l` is `f(l)`.
    fn gather(f: impl Fn(usize) -> Real) -> Self;
    /// `|x|` per lane.
    fn abs(self) -> Self;
    /// `self > other` (false where either is NaN).
    fn gt(self, other: Self) -> Self::Mask;
    /// `self == other` (false where either is NaN).
    fn eq(self, other: Self) -> Self::Mask;
    /// `self >= other` (false where either is NaN).
    fn ge(self, other: Self) -> Self::Mask;
    /// `self <= other` (false where either is NaN).
    fn le(self, other: Self) -> Self::Mask;
    /// Neither NaN nor infinite.
    fn finite(self) -> Self::Mask;
    /// Both tests hold.
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// The test holds in every lane.
    fn all(m: Self::Mask) -> bool;
    /// `a` where the test holds, else `b`.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
}

impl Lane for Real {
    type Mask = bool;
    const IN_PLACE: bool = false;
    const ZERO: Self = 0.0;
    #[inline(always)]
    fn splat(x: Real) -> Self {
        x
    }
    #[inline(always)]
    fn gather(f: impl Fn(usize) -> Real) -> Self {
        f(0)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Real::abs(self)
    }
    #[inline(always)]
    fn gt(self, other: Self) -> bool {
        self > other
    }
    #[inline(always)]
    fn eq(self, other: Self) -> bool {
        self == other
    }
    #[inline(always)]
    fn ge(self, other: Self) -> bool {
        self >= other
    }
    #[inline(always)]
    fn le(self, other: Self) -> bool {
        self <= other
    }
    #[inline(always)]
    fn finite(self) -> bool {
        self.is_finite()
    }
    #[inline(always)]
    fn and(a: bool, b: bool) -> bool {
        a && b
    }
    #[inline(always)]
    fn all(m: bool) -> bool {
        m
    }
    #[inline(always)]
    fn select(m: bool, a: Self, b: Self) -> Self {
        if m { a } else { b }
    }
}

impl Lane for Lanes {
    type Mask = Lanes;
    const IN_PLACE: bool = true;
    const ZERO: Self = Lanes::ZERO;
    #[inline(always)]
    fn splat(x: Real) -> Self {
        Lanes::splat(x)
    }
    #[inline(always)]
    fn gather(f: impl Fn(usize) -> Real) -> Self {
        Lanes::new([f(0), f(1), f(2), f(3)])
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Lanes::abs(self)
    }
    #[inline(always)]
    fn gt(self, other: Self) -> Lanes {
        self.simd_gt(other)
    }
    #[inline(always)]
    fn eq(self, other: Self) -> Lanes {
        self.simd_eq(other)
    }
    #[inline(always)]
    fn ge(self, other: Self) -> Lanes {
        self.simd_ge(other)
    }
    #[inline(always)]
    fn le(self, other: Self) -> Lanes {
        self.simd_le(other)
    }
    #[inline(always)]
    fn finite(self) -> Lanes {
        self.is_finite()
    }
    #[inline(always)]
    fn and(a: Lanes, b: Lanes) -> Lanes {
        a & b
    }
    #[inline(always)]
    fn all(m: Lanes) -> bool {
        m.all()
    }
    #[inline(always)]
    fn select(m: Lanes, a: Self, b: Self) -> Self {
        m.select(a, b)
    }
}
