//! The embedded error estimate of
//! [`StepControl::Embedded`](crate::settings::StepControl::Embedded): one RATTLE run per
//! step, its error estimated from the trajectory's own derivatives, which the bodies'
//! velocities at the ends of the last segments kept give by divided differences.
//!
//! | samples kept before the run | the segment |
//! |---|---|
//! | fewer than [`SAMPLES`], or other bodies | step doubling (its fine run's end is sampled) |
//! | [`SAMPLES`] of the same bodies | one run, kept when its estimate is within the tolerance |
//!
//! With the samples `v(t0), v(t1), v(t2)` and the run's end `v(t3)` of a body:
//!
//! ```text
//! jerk = v''  ~ 2 v[t1, t2, t3]          (second divided difference)
//! snap = v''' ~ 6 v[t0, t1, t2, t3]      (third divided difference)
//! estimate = span h^2 / 6 |jerk| + max(horizon, span) span h^2 / 12 |snap|
//! ```
//!
//! for a run over `span` in substeps of `h`: RATTLE's local errors per substep are
//! `h^3 / 6 |jerk|` in the position and `h^3 / 12 |snap|` in the velocity (the Taylor
//! expansions of the velocity Verlet step and of the exact flow differ there first), and a run
//! takes `span / h` substeps. The rotation's terms are weighed by the body's reach, as the
//! step doubling weighs them. The samples need not be equally spaced (a segment that ends at an
//! event's bracket is shorter); an event's substep and a profile kink clear them, since the
//! velocity is not smooth across them.

use crate::error::{Error, JointId};
use crate::math::Real;
use crate::math::rapier::dynamics::RigidBodyHandle;
use crate::settings::Integrator;

use super::{
    BodyState, Control, CutReason, MAX_COARSENING, Mark, Mpc184World, Outcome, substeps_for,
};

/// The velocity samples the estimate needs before a run (the run's end is the fourth).
pub(crate) const SAMPLES: usize = 3;

/// A retry and the next step aim at this share of the tolerance.
const AIM: Real = 0.8;

/// Velocity samples of the dynamic bodies at the ends of the last segments kept (see the
/// module docs). Part of the world's state: a snapshot carries it, so a restored world takes
/// the same steps as the one it was taken from.
#[derive(Clone, Debug, Default, PartialEq)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct VelocityHistory {
    /// The dynamic bodies sampled (their handles' raw parts), in the body set's order.
    bodies: Vec<(u32, u32)>,
    /// Oldest first, at most [`SAMPLES`].
    samples: Vec<Sample>,
}

/// The bodies' velocities at one time.
#[derive(Clone, Debug, Default, PartialEq)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
struct Sample {
    /// Simulated time (s).
    time: Real,
    /// Per body: the centre of mass's velocity (m/s) and the angular velocity (rad/s), world
    /// frame.
    velocities: Vec<[Real; 6]>,
}

impl Sample {
    fn of(time: Real, states: &[BodyState]) -> Self {
        Self {
            time,
            velocities: states
                .iter()
                .map(|s| [s.3.x, s.3.y, s.3.z, s.4.x, s.4.y, s.4.z])
                .collect(),
        }
    }
}

impl VelocityHistory {
    /// Forgets the samples (the velocity is not smooth across an event or a kink).
    pub(crate) fn clear(&mut self) {
        self.samples.clear();
    }

    /// The samples are enough for an estimate of a run from `now` that ends in `states`:
    /// [`SAMPLES`] of the same bodies, none after `now` (a world put back to an earlier time
    /// by other means than the control's own checkpoints clears them).
    fn ready(&mut self, now: Real, states: &[BodyState]) -> bool {
        if self
            .samples
            .last()
            .is_some_and(|s| s.time > now || s.time.is_nan())
        {
            self.samples.clear();
        }
        self.samples.len() == SAMPLES && self.same_bodies(states)
    }

    fn same_bodies(&self, states: &[BodyState]) -> bool {
        self.bodies.len() == states.len()
            && self
                .bodies
                .iter()
                .zip(states)
                .all(|(b, s)| *b == s.0.into_raw_parts())
    }

    /// Keeps the state at `time` as the newest sample (the bodies changed: as the first).
    fn push(&mut self, time: Real, states: &[BodyState]) {
        if !self.same_bodies(states) {
            self.bodies = states.iter().map(|s| s.0.into_raw_parts()).collect();
            self.samples.clear();
        }
        if self.samples.len() == SAMPLES {
            self.samples.remove(0);
        }
        self.samples.push(Sample::of(time, states));
    }

    /// The largest estimate over the bodies of a run over `span` in substeps of `h` that
    /// ended at `time` in `states` (see the module docs), and the body it is on.
    fn estimate(
        &self,
        time: Real,
        states: &[BodyState],
        levers: &[Real],
        [span, h, carried]: [Real; 3],
    ) -> (Real, Option<RigidBodyHandle>) {
        let end = Sample::of(time, states);
        let s = [&self.samples[0], &self.samples[1], &self.samples[2], &end];
        let t = s.map(|s| s.time);
        let position = span * h * h / 6.0;
        let velocity = carried * span * h * h / 12.0;
        let mut worst = (0.0 as Real, None);
        for (i, (state, &lever)) in states.iter().zip(levers).enumerate() {
            // Per part (linear, angular): |jerk|^2 and |snap|^2.
            let mut sq = [[0.0 as Real; 2]; 2];
            for k in 0..6 {
                let f = s.map(|s| s.velocities[i][k]);
                let d = [0, 1, 2].map(|j| (f[j + 1] - f[j]) / (t[j + 1] - t[j]));
                let d2 = [0, 1].map(|j| (d[j + 1] - d[j]) / (t[j + 2] - t[j]));
                let d3 = (d2[1] - d2[0]) / (t[3] - t[0]);
                let (jerk, snap) = (2.0 * d2[1], 6.0 * d3);
                sq[k / 3][0] += jerk * jerk;
                sq[k / 3][1] += snap * snap;
            }
            let [lin, ang] = sq.map(|p| p.map(Real::sqrt));
            let e = position * (lin[0] + lever * ang[0]) + velocity * (lin[1] + lever * ang[1]);
            if e > worst.0 || e.is_nan() {
                worst = (e, Some(state.0));
            }
        }
        worst
    }
}

/// The `n` (substeps per `dt`) whose estimate would be [`AIM`] of the tolerance, for a run of
/// `n` whose estimate was `ratio` times the tolerance (the estimate scales as `1 / n^2`).
fn aimed(n: usize, ratio: Real) -> usize {
    let aimed = (n as Real * (ratio / AIM).sqrt()).ceil();
    if aimed.is_finite() && aimed >= 1.0 {
        aimed.min(usize::MAX as Real / 2.0) as usize
    } else {
        1
    }
}

impl Mpc184World {
    /// The embedded estimate is RATTLE's: any other scheme or backend is unsupported.
    pub(super) fn require_embedded(&self) -> Result<(), Error> {
        let integrator = self.core.settings.integrator;
        if integrator == Integrator::Rattle && self.backend.order(integrator) == 2 {
            return Ok(());
        }
        Err(Error::Unsupported {
            what: format!(
                "the embedded error estimate (StepControl::Embedded) with {integrator:?} on the \
                 {:?} backend",
                self.core.settings.backend
            ),
            hint: "it estimates RATTLE's error: use Integrator::Rattle on the Lagrange backend, \
                   or StepControl::Adaptive (step doubling) for any scheme"
                .into(),
        })
    }

    /// A segment's stretch over `span` under the embedded estimate: one run of `n` substeps per
    /// `dt` when the samples allow (see the module docs), else step doubling with the coarse
    /// run at half of `n` (its fine run is what is kept); either way the end is sampled.
    pub(super) fn embedded(
        &mut self,
        span: Real,
        n: usize,
        c: &Control,
        watch: Option<&[Mark]>,
        history: &mut VelocityHistory,
    ) -> Result<Outcome, Error> {
        // An island that took the first-order step (a contact) has no RATTLE error to
        // estimate: its velocities live at half steps.
        let ready = history.ready(self.time(), &self.dynamic_states())
            && self.backend.diagnostics().first_order_bodies == 0;
        if !ready {
            return Ok(match self.doubling(span, (n / 2).max(1), c, watch)? {
                Outcome::Kept(next) => {
                    history.push(self.time(), &self.dynamic_states());
                    Outcome::Kept((2 * next).min(c.max))
                }
                event => event,
            });
        }
        self.embedded_run(span, n, c, watch, history)
    }

    /// One run over `span`, taken again with more substeps until its estimate is within the
    /// tolerance (or `max` substeps per `dt`).
    fn embedded_run(
        &mut self,
        span: Real,
        mut n: usize,
        c: &Control,
        watch: Option<&[Mark]>,
        history: &mut VelocityHistory,
    ) -> Result<Outcome, Error> {
        let levers = self.levers();
        loop {
            let m = substeps_for(span, c.dt, n);
            if let Err(e) = self.run_part(span, m) {
                n = self.embedded_cut_after_divergence(e, n, c)?;
                continue;
            }
            if self.event_seen(watch) {
                return Ok(Outcome::Event(span / m as Real));
            }
            let states = self.dynamic_states();
            let h = span / m as Real;
            let (estimate, worst) = history.estimate(
                self.time(),
                &states,
                &levers,
                [span, h, c.horizon.max(span)],
            );
            if !estimate.is_finite() {
                return Err(Error::Diverged {
                    time: self.time(),
                    joint: None,
                    reason: "the embedded error estimate is not finite".into(),
                });
            }
            // A projection that fell back to Gauss-Newton (near a singular pose) carries an
            // error the estimate does not see: cut, as the step doubling does.
            let converged = self.backend.projection_fallbacks() == 0;
            let met = estimate <= c.tolerance && converged;
            if met || n >= c.max {
                self.note_substep(h);
                let stats = &mut self.core.stats;
                stats.unmet += u64::from(!met);
                stats.last_estimate = estimate;
                stats.embedded += 1;
                history.push(self.time(), &states);
                // Not after a part of the step: its estimate is that of a shorter stretch.
                let next = if span >= c.dt {
                    aimed(n, estimate / c.tolerance).clamp((n / MAX_COARSENING).max(1), c.max)
                } else {
                    n
                };
                return Ok(Outcome::Kept(next));
            }
            let joint: Option<JointId> =
                worst.and_then(|b| self.core.joints.attached_to(b).first().copied());
            self.restore_segment();
            let reason = if converged {
                CutReason::Estimate
            } else {
                CutReason::Projection
            };
            self.note_cut(joint, reason);
            n = if converged {
                aimed(n, estimate / c.tolerance).max(n + 1)
            } else {
                2 * n
            }
            .min(c.max);
        }
    }

    /// A run that diverged is cut to twice the substeps while `max` leaves room (see
    /// `cut_after_divergence`); returns the new `n`.
    fn embedded_cut_after_divergence(
        &mut self,
        error: Error,
        n: usize,
        c: &Control,
    ) -> Result<usize, Error> {
        let Error::Diverged { joint, .. } = error else {
            return Err(error);
        };
        if 2 * n > c.max {
            return Err(error);
        }
        self.restore_segment();
        self.note_cut(joint, CutReason::Divergence);
        Ok(2 * n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Rotation, Vector};

    /// A body whose velocity is the cubic `a + b t + c t^2 + d t^3` (per component) and whose
    /// angular velocity is `k` times it.
    fn state(t: Real, k: Real) -> BodyState {
        let [a, b, c, d] = [0.3, -1.0, 2.0, 0.5];
        let v = a + b * t + c * t * t + d * t * t * t;
        let v = Vector::new(v, -2.0 * v, 0.0);
        (
            RigidBodyHandle::from_raw_parts(0, 0),
            Vector::ZERO,
            Rotation::IDENTITY,
            v,
            v * k,
        )
    }

    #[test]
    fn the_estimate_takes_the_jerk_and_snap_of_a_cubic_exactly() {
        // Divided differences of a cubic are exact: over unequal spacings the third is `d`
        // (the snap `6 d`) and the second over `(t1, t2, t3)` is `c + d (t1 + t2 + t3)`, the
        // jerk `2 c + 6 d t` at the mean of the three times.
        let times = [0.0, 0.1, 0.25, 0.3];
        let (k, lever) = (0.5, 0.2);
        let mut history = VelocityHistory::default();
        for &t in &times[..3] {
            history.push(t, &[state(t, k)]);
        }
        let end = [state(times[3], k)];
        assert!(history.ready(times[2], &end));
        let [span, h, carried] = [0.05, 0.01, 2.0];
        let (estimate, body) = history.estimate(times[3], &end, &[lever], [span, h, carried]);
        let [c, d] = [2.0, 0.5];
        let jerk = 2.0 * (c + d * (times[1] + times[2] + times[3]));
        let snap = 6.0 * d;
        // Both components (1, -2) give the norm sqrt(5); the rotation adds `lever k` of it.
        let scale = (5.0 as Real).sqrt() * (1.0 + lever * k);
        let expected =
            (span * h * h / 6.0 * jerk.abs() + carried * span * h * h / 12.0 * snap) * scale;
        // Round-off: the third difference weighs the velocities' last bits (about 1 m/s) by
        // up to 1 / (0.05 * 0.15 * 0.3) s^-3, some 1e3 times the snap's share of the estimate
        // (6 d = 3 against a jerk of 5.3): 1e5 ulps, 1.2e-2 in f32 and 2.2e-11 in f64
        // (measured 2.3e-6 and 2.4e-15 relative), against an error of order one for a wrong
        // difference or factor.
        let off = (estimate - expected).abs() / expected;
        assert!(
            off <= 1e5 * Real::EPSILON,
            "{estimate:e} against {expected:e} ({off:.1e} relative)"
        );
        assert_eq!(body, Some(RigidBodyHandle::from_raw_parts(0, 0)));
    }

    #[test]
    fn other_bodies_clear_the_samples() {
        let mut history = VelocityHistory::default();
        for t in [0.0, 0.1, 0.2] {
            history.push(t, &[state(t, 1.0)]);
        }
        let mut other = state(0.3, 1.0);
        other.0 = RigidBodyHandle::from_raw_parts(1, 0);
        assert!(!history.ready(0.2, &[other]));
        history.push(0.3, &[other]);
        assert_eq!(history.samples.len(), 1);
    }

    #[test]
    fn samples_after_the_time_now_are_dropped() {
        // A world rolled back to 0.15 s (its last step undone) must not difference a sample
        // from 0.2 s against a run that ends there again.
        let mut history = VelocityHistory::default();
        for t in [0.0, 0.1, 0.2] {
            history.push(t, &[state(t, 1.0)]);
        }
        assert!(!history.ready(0.15, &[state(0.25, 1.0)]));
        assert!(history.samples.is_empty());
    }

    #[test]
    fn aimed_scales_as_the_square_root_of_the_ratio() {
        // 10 substeps at 3.2 times the tolerance: 10 sqrt(3.2 / 0.8) = 20.
        assert_eq!(aimed(10, 3.2), 20);
        // Far under it: fewer, never zero.
        assert_eq!(aimed(10, 0.0), 1);
        assert_eq!(aimed(10, Real::NAN), 1);
    }
}
