//! Prescribed relative motion (`DJ`) and applied joint loads (`FJ`): their time profiles.
//!
//! Plain data: a [`Drive`] names the DOF, the [`DriveLevel`] (displacement, velocity or
//! acceleration) and the [`DriveProfile`] in time; the same profile type carries an `FJ` load.

use crate::dof::Dof;
use crate::math::Real;

/// A time profile of a prescribed value (m or rad): `from` until `t0`, linear to `to` at `t1`
/// (ANSYS `KBC,0`, ramped) or a jump at `t0` (`KBC,1`, stepped), `to` afterwards; with
/// `extend`, the ramp's slope continues past `t1` (a constant-speed drive).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DriveProfile {
    /// Start of the ramp (s).
    pub t0: Real,
    /// End of the ramp (s).
    pub t1: Real,
    /// Value until `t0`.
    pub from: Real,
    /// Value at `t1`.
    pub to: Real,
    /// A step at `t0` instead of a ramp.
    pub stepped: bool,
    /// Keep the ramp's slope after `t1`.
    pub extend: bool,
}

impl DriveProfile {
    /// A constant-rate drive: `rate * t` from time 0.
    pub fn constant_rate(rate: Real) -> Self {
        Self {
            t0: 0.0,
            t1: 1.0,
            from: 0.0,
            to: rate,
            stepped: false,
            extend: true,
        }
    }

    /// A constant value from time 0 (a load, or a velocity or acceleration drive).
    pub fn constant(value: Real) -> Self {
        Self {
            t0: 0.0,
            t1: 0.0,
            from: value,
            to: value,
            stepped: true,
            extend: false,
        }
    }

    /// The value at time `t`.
    pub fn value(&self, t: Real) -> Real {
        if t <= self.t0 {
            return self.from;
        }
        if self.stepped || self.t1 <= self.t0 {
            return self.to;
        }
        let s = (t - self.t0) / (self.t1 - self.t0);
        if s >= 1.0 && !self.extend {
            return self.to;
        }
        self.from + s * (self.to - self.from)
    }

    /// The value just after time `t` (the right limit): [`DriveProfile::value`] except at the
    /// jump of a stepped profile, where it is already `to`. A force held over a substep that
    /// starts at the jump is the new value (ANSYS `KBC,1`: the load step's value acts from its
    /// first substep), so the loads' kick at a substep's start reads this.
    pub fn value_after(&self, t: Real) -> Real {
        if self.stepped && t >= self.t0 {
            self.to
        } else {
            self.value(t)
        }
    }

    /// The times where the value or its slope jumps (s): the step or the ramp's start `t0`,
    /// and the ramp's end `t1` unless the slope goes on (`extend`).
    pub(crate) fn kinks(&self) -> impl Iterator<Item = Real> {
        let ramp_end = !self.stepped && self.t1 > self.t0 && !self.extend;
        core::iter::once(self.t0).chain(ramp_end.then_some(self.t1))
    }

    pub(crate) fn is_finite(&self) -> bool {
        self.t0.is_finite() && self.t1.is_finite() && self.from.is_finite() && self.to.is_finite()
    }
}

impl DriveProfile {
    /// The linear piece `c0 + c1 t` the profile follows around `t` (a point strictly inside
    /// one of its pieces).
    fn piece(&self, t: Real) -> (Real, Real) {
        let ramp = !self.stepped && self.t1 > self.t0;
        if t < self.t0 {
            return (self.from, 0.0);
        }
        if ramp && (t < self.t1 || self.extend) {
            let s = (self.to - self.from) / (self.t1 - self.t0);
            return (self.from - s * self.t0, s);
        }
        (self.to, 0.0)
    }

    /// The profile's kinks, for exact piecewise integration.
    fn breaks(&self) -> [Real; 2] {
        [self.t0, self.t1]
    }

    /// `int_a^b w(u) f(u) du` with the weight `w(u) = w0 + w1 u`, exact for the piecewise linear
    /// profile.
    fn weighted_integral(&self, a: Real, b: Real, w0: Real, w1: Real) -> Real {
        if b <= a {
            return 0.0;
        }
        let mut cuts = vec![a];
        for x in self.breaks() {
            if x > a && x < b {
                cuts.push(x);
            }
        }
        cuts.push(b);
        cuts.sort_by(Real::total_cmp);
        let mut sum = 0.0;
        for w in cuts.windows(2) {
            let (x, y) = (w[0], w[1]);
            let (c0, c1) = self.piece(0.5 * (x + y));
            // (w0 + w1 u)(c0 + c1 u) = p0 + p1 u + p2 u^2
            let (p0, p1, p2) = (w0 * c0, w0 * c1 + w1 * c0, w1 * c1);
            sum += p0 * (y - x) + p1 * (y * y - x * x) / 2.0 + p2 * (y * y * y - x * x * x) / 3.0;
        }
        sum
    }
}

/// What a drive prescribes (ANSYS `DJ` labels).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum DriveLevel {
    /// `UX..ROTZ`: the DOF's value relative to time 0 follows the profile.
    #[default]
    Displacement,
    /// `VELX..OMGZ`: the DOF's rate follows the profile from the moment the drive is set.
    Velocity,
    /// `ACCX..DMGZ`: the DOF's acceleration follows the profile from the moment the drive is
    /// set, starting from the rate it had then.
    Acceleration,
}

/// A drive attached to one DOF of a joint.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Drive {
    /// The driven DOF.
    pub dof: Dof,
    /// Its prescribed value over time.
    pub profile: DriveProfile,
    /// Displacement, velocity or acceleration.
    #[serde(default)]
    pub level: DriveLevel,
    /// Time the drive was set (s; velocity and acceleration levels integrate from it).
    #[serde(default)]
    pub since: Real,
    /// The DOF's value relative to time 0 when it was set (m or rad).
    #[serde(default)]
    pub start_value: Real,
    /// The DOF's rate when it was set (m/s or rad/s; acceleration level).
    #[serde(default)]
    pub start_rate: Real,
}

impl Drive {
    /// A displacement drive (and a joint load: the profile's value itself).
    pub fn new(dof: Dof, profile: DriveProfile) -> Self {
        Self {
            dof,
            profile,
            level: DriveLevel::Displacement,
            since: 0.0,
            start_value: 0.0,
            start_rate: 0.0,
        }
    }

    /// The prescribed value relative to time 0 at time `t` (m or rad): the profile itself, or
    /// its exact integral from `since` (velocity), or the double integral plus the starting
    /// rate (acceleration).
    pub fn value(&self, t: Real) -> Real {
        match self.level {
            DriveLevel::Displacement => self.profile.value(t),
            DriveLevel::Velocity => {
                self.start_value + self.profile.weighted_integral(self.since, t, 1.0, 0.0)
            }
            DriveLevel::Acceleration => {
                // int_s^t (t - u) a(u) du
                self.start_value
                    + self.start_rate * (t - self.since)
                    + self.profile.weighted_integral(self.since, t, t, -1.0)
            }
        }
    }
}
