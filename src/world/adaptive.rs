//! The adaptive step control ([`StepControl::Adaptive`](crate::settings::StepControl::Adaptive), ANSYS `AUTOTS`): step doubling on the
//! smooth stretches, and each event located by bisection and taken in a substep of its own; a
//! run whose position projection fell back to Gauss-Newton (a singular pose), and a run that
//! diverged, are cut like an estimate over the tolerance.
//!
//! A step of `dt` is walked in segments. A segment runs from the current time to the step's
//! end by step doubling (the `n` and `2 n` runs from the segment's start, the segment
//! checkpoint restoring it bit for bit); with `extrapolate`, a kept doubling of a scheme of
//! order `p >= 2` moves the bodies by `1 / (2^p - 1)` of the two runs' difference and puts
//! them back onto the constraints (local extrapolation, see `Mpc184World::extrapolate`). When either run shows an *event*, an onset that was
//! not there at the segment's start:
//!
//! | event | seen as |
//! |---|---|
//! | [`EventKind::Stop`]: a stop (`SECSTOP`) starts to act | a stop bit of the joint's output set that was clear |
//! | [`EventKind::Lock`]: a lock (`SECLOCK`) engages | a DOF locked that was free |
//! | [`EventKind::StickSlip`]: joint friction sticks or starts to slip | the friction state's `slipping` changed |
//! | [`EventKind::Knee`]: a nonlinear spring or damper passes a table's knee | the table segment of the DOF's deflection (or rate) changed |
//!
//! A drive's or a load's profile kink ([`EventKind::Profile`]: a `DJ` or `FJ` step, a ramp's
//! start or end) is known in advance: a segment ends exactly there, and the rest of the step
//! is the next segment.
//!
//! the event time is bisected, as ANSYS bisects a step on a contact status change: runs from
//! the last state without the event (the probe checkpoint) to the middle of the bracket, at the
//! fine run's substep, until the bracket is narrower than the event time tolerance
//!
//! ```text
//! delta = min(tolerance / (2 v), energy_tolerance / (2 P))
//! ```
//!
//! with `v` the fastest body's speed (its angular speed times its reach included) and `P`
//! the largest rate of change of the kinetic energy seen between the probes: an impact or a
//! lock mislocated by `delta` moves the trajectory by about `2 v delta` and the energy by about
//! `P delta`; `h`, the fine run's substep, keeps the event's substep no coarser than its
//! neighbours. The stretch before the bracket is then taken by step doubling (no event in it),
//! the bracket by one substep (the event acts there: the limits act on the gap predicted at the
//! substep's end), and the rest of the step is the next segment. A step locates at most
//! [`MAX_EVENTS`] events (a contact chattering on a stop would otherwise cut it without end);
//! the step doubling alone takes any after them.
//!
//! Under [`StepControl::Embedded`](crate::settings::StepControl::Embedded) the smooth stretches
//! are taken by one run each, checked by an estimate from the velocities of the last segments
//! kept (`embedded`); events are located the same way.

use crate::error::{Error, JointId};
use crate::math::rapier::dynamics::RigidBodyHandle;
use crate::math::{Pose, Real, Rotation, Vector};
use crate::output::EnergyLedger;

use super::Mpc184World;

mod embedded;
pub(crate) use embedded::VelocityHistory;

/// What the adaptive control locates ([`StepControl::Adaptive`](crate::settings::StepControl::Adaptive)):
/// an onset in a run that was not there at the start of the stretch it integrates.
///
/// | event | seen as | located to |
/// |---|---|---|
/// | [`EventKind::Stop`] | a stop bit of the joint's output set that was clear | `tolerance / (2 v)` |
/// | [`EventKind::Lock`] | a DOF locked that was free | and `energy_tolerance / (2 P)` |
/// | [`EventKind::StickSlip`] | the friction state's `slipping` changed | whichever is smaller |
/// | [`EventKind::Knee`] | the table segment of a tabled DOF's deflection (stiffness) or rate (damping) changed | |
/// | [`EventKind::Profile`] | a drive's or load's profile kink falls inside the step | exactly (known in advance) |
///
/// `v`: the fastest body's speed (its angular speed times its reach included); `P`: the
/// largest rate of change of the kinetic energy seen while bisecting. An impact or a lock
/// mislocated by `delta` moves the trajectory by about `2 v delta` and the energy by about
/// `P delta`. The event is taken in a substep of its own (the limits act on the gap predicted at
/// a substep's end, so the event lies in that substep), the stretches before and after it by
/// step doubling.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub enum EventKind {
    /// A stop (`SECSTOP`) started to act.
    #[doc(alias = "SECSTOP")]
    Stop,
    /// A lock (`SECLOCK`) engaged.
    #[doc(alias = "SECLOCK")]
    Lock,
    /// Joint friction went from sticking to slipping or back.
    StickSlip,
    /// A nonlinear stiffness or damping table's interior point (`TB,JOIN` `JNS1..6`,
    /// `JND1..6`) was crossed: the law's slope jumps there.
    #[doc(alias = "TBPT")]
    Knee,
    /// A drive's or a joint load's profile jumps or changes its slope at this time (`DJ`,
    /// `FJ`: a step, or a ramp's start or end). Known in advance: the step is cut there
    /// exactly, no bisection.
    #[doc(alias = "DJ")]
    #[doc(alias = "FJ")]
    Profile,
}

/// Why the adaptive control last took a try again with more substeps
/// ([`StepStats::last_cut_reason`](crate::world::StepStats::last_cut_reason)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub enum CutReason {
    /// The error estimate (position, rotation and velocity differences of the two runs) was
    /// over `tolerance`.
    Estimate,
    /// The two runs booked dissipated energy or work that differed by more than
    /// `energy_tolerance`.
    Energy,
    /// A position projection did not converge by chord iterations (it fell back to damped
    /// Gauss-Newton near a singular pose, or hit its iteration limit).
    Projection,
    /// A run diverged (a blow-up, or a joint turned past its bound in one step).
    Divergence,
}

/// An event located by the adaptive control (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub struct StepEvent {
    /// The end of the substep that holds the event (s): the event lies in `(time - width,
    /// time]`.
    pub time: Real,
    /// The size of that substep (s), at most the event time tolerance; 0 for a profile kink
    /// ([`EventKind::Profile`]), which lies exactly at `time`.
    pub width: Real,
    /// The joint.
    pub joint: JointId,
    /// What happened.
    pub kind: EventKind,
}

/// Most events located in one step (see the module docs).
pub const MAX_EVENTS: usize = 8;

/// One joint's event state at a segment's start.
#[derive(Clone, Copy, PartialEq, Eq)]
struct Mark {
    /// Bit `k`: the stop or lock of DOF `k` acted in the last substeps.
    stops: u8,
    /// Bit `k`: DOF `k` is locked.
    locks: u8,
    /// The friction slips (`None`: no friction, or no friction state yet: before the first
    /// step, which is no event).
    slipping: Option<bool>,
    /// Per DOF, the segment of its stiffness table holding its deflection (`k`) and of its
    /// damping table holding its rate (`6 + k`); 0 without a table.
    knees: [u16; 12],
}

/// The tolerances of a step (see [`StepControl::Adaptive`](crate::settings::StepControl::Adaptive)).
#[derive(Clone, Copy)]
struct Control {
    tolerance: Real,
    energy_tolerance: Real,
    /// The time a velocity difference is weighed over (s; at least the span integrated).
    horizon: Real,
    /// The scheme's order (the estimate divides by `2^p - 1`).
    order: u32,
    /// Local extrapolation of each kept doubling.
    extrapolate: bool,
    /// Most substeps per `dt`.
    max: usize,
    dt: Real,
}

/// How a segment's step doubling ended.
enum Outcome {
    /// Kept; `n` (substeps per `dt`) for what follows.
    Kept(usize),
    /// A run showed an event: the world is back at the segment's start, and `h` is the
    /// substep the bisection runs at.
    Event(Real),
}

/// An event's bracket `(lo, hi]` from a stretch's start (s), and its joint and kind when a run
/// named it.
type Bracket = (Real, Real, Option<(JointId, EventKind)>);

/// A dynamic body's handle, centre of mass, orientation and velocities.
type BodyState = (RigidBodyHandle, Vector, Rotation, Vector, Vector);

/// Most the next step's `n` falls below a kept step's (see [`next_substeps`]).
const MAX_COARSENING: usize = 8;

/// The `n` the step after a kept whole step starts from, for that step's `n`, its error
/// estimate and its energy difference (each over its tolerance) and the scheme's order `p`:
/// halved as long as the halved step's fine run would still pass, predicted from the estimate
/// times `2^p` (the `n` run's error, whose substeps the halved step's `2 n` run takes) and the
/// energy difference times 2, by at most [`MAX_COARSENING`] in one step. Halving once per
/// step at most, as before, the slider-crank's steps came back from a hard stretch at 64
/// substeps by 96, 48, 24, 12 and 6 substeps a step; now by 96, 24 or 48, then 12 (at 1e-2 m,
/// `-local-x`: 4691 substeps instead of 5059 over the 5 s, the same error). A01, Bricard and
/// A02 with a 5 s horizon took the same steps; A02 with the step alone (the four-bar, through its
/// singular poses) took 4179 substeps instead of 5393 at 1e-5 m and landed at
/// 1.03e-5 m instead of 5.0e-5 (`tests/adaptive_extrapolation.rs`).
fn next_substeps(n: usize, estimate: Real, energy: Real, order: u32) -> usize {
    let gain = (1u32 << order) as Real;
    let (mut next, mut estimate, mut energy) = (n, estimate, energy);
    while next > 1 && next * MAX_COARSENING > n && estimate * gain <= 1.0 && 2.0 * energy <= 1.0 {
        next /= 2;
        estimate *= gain;
        energy *= 2.0;
    }
    next
}

/// The substeps that cover `span` at the substep of `n` per `dt` (at least one).
fn substeps_for(span: Real, dt: Real, n: usize) -> usize {
    // Round-off in `span` (a sum of parts of `dt`) must not add a substep.
    ((span / dt * n as Real) * (1.0 - 8.0 * Real::EPSILON))
        .ceil()
        .max(1.0) as usize
}

impl Mpc184World {
    /// One step of `dt` under the adaptive control (see the module docs).
    pub(super) fn step_adaptive(
        &mut self,
        dt: Real,
        [tolerance, energy_tolerance, horizon]: [Real; 3],
        max_substeps: usize,
        extrapolate: bool,
        embedded: bool,
    ) -> Result<(), Error> {
        if embedded {
            self.require_embedded()?;
        }
        let c = Control {
            tolerance,
            energy_tolerance,
            horizon,
            order: self.backend.order(self.core.settings.integrator),
            extrapolate,
            max: max_substeps.max(2),
            dt,
        };
        // Taken out for the step, put back when it is kept (a step that fails leaves none:
        // the next steps sample afresh).
        let mut history = embedded.then(|| std::mem::take(&mut self.core.history));
        // Under the embedded estimate `n` counts the run's substeps; under step doubling the
        // coarse run's.
        let most = if embedded { c.max } else { c.max / 2 };
        let stats = &self.core.stats;
        let mut n = if stats.next == 0 {
            self.core.settings.substeps
        } else {
            stats.next
        }
        .clamp(1, most);
        let t0 = self.time();
        let mut done: Real = 0.0;
        let mut events = 0;
        // The step was cut at a profile kink (taken in parts, like a located event).
        let mut split = false;
        // The stops that acted in the parts kept: the step's output reports them all, as after
        // a step in one part.
        let mut acted: Vec<u8> = Vec::new();
        loop {
            // A drive's or load's kink inside the rest of the step ends this segment exactly
            // there (a sliver below 1e-9 dt is left to the substep that holds it).
            let kink = self
                .core
                .joints
                .next_kink(t0 + done + 1e-9 * dt, t0 + dt - 1e-9 * dt);
            let span = kink.map_or(dt - done, |(t, _)| t - t0 - done);
            self.save_segment();
            let marks = self.event_marks();
            let watch = (events < MAX_EVENTS).then_some(marks.as_slice());
            match self.smooth(span, n, &c, watch, history.as_mut())? {
                Outcome::Kept(next) => {
                    n = next;
                    self.gather_acted(&mut acted);
                    let Some((time, joint)) = kink else { break };
                    split = true;
                    if let Some(history) = history.as_mut() {
                        history.clear();
                    }
                    let stats = &mut self.core.stats;
                    stats.events += 1;
                    stats.last_event = Some(StepEvent {
                        time,
                        width: 0.0,
                        joint,
                        kind: EventKind::Profile,
                    });
                    done += span;
                }
                Outcome::Event(h) => {
                    let (lo, hi, event) = self.locate(span, h, &marks, &c)?;
                    if lo > 0.0 {
                        // No event before the bracket: the stretch keeps its own `n`.
                        if let Outcome::Kept(next) =
                            self.smooth(lo, n, &c, None, history.as_mut())?
                        {
                            n = next;
                        }
                        self.gather_acted(&mut acted);
                    }
                    self.run_part(hi - lo, 1)?;
                    if let Some(history) = history.as_mut() {
                        history.clear();
                    }
                    self.gather_acted(&mut acted);
                    self.note_substep(hi - lo);
                    events += 1;
                    // The stretch before the bracket was taken again by the doubling, at its
                    // own substeps: the event can move by up to the tolerance over the speed
                    // and fall past the bracket. The next segment locates it then (from its
                    // start), and this substep is not counted as the event.
                    if let (Some((joint, kind)), Some(_)) = (event, self.onset(&marks)) {
                        self.core.stats.events += 1;
                        self.core.stats.last_event = Some(StepEvent {
                            time: t0 + done + hi,
                            width: hi - lo,
                            joint,
                            kind,
                        });
                    }
                    done += hi;
                    if dt - done <= 1e-9 * dt {
                        break;
                    }
                }
            }
        }
        // The parts add up to `dt` up to round-off: the step ends where a fixed step ends.
        self.core.progress.time = t0 + dt;
        if events > 0 || split {
            self.report_acted(acted);
        }
        let stats = &mut self.core.stats;
        stats.accepted += 1;
        stats.next = n;
        if let Some(history) = history {
            self.core.history = history;
        }
        Ok(())
    }

    /// After a step taken in parts: every stop that acted in a part kept (`acted`, one bit
    /// per DOF by slot) is in the step's output, as after a step in one part.
    fn report_acted(&mut self, acted: Vec<u8>) {
        for (slot, bits) in acted.into_iter().enumerate() {
            if let Some(e) = self.core.joints.get_mut(slot) {
                for (k, flag) in e.state.at_stop.iter_mut().enumerate() {
                    *flag |= bits & (1 << k) != 0;
                }
            }
        }
        self.refresh_outputs();
    }

    /// A segment's smooth stretch: step doubling, or with `history` the embedded estimate
    /// (see `embedded`).
    fn smooth(
        &mut self,
        span: Real,
        n: usize,
        c: &Control,
        watch: Option<&[Mark]>,
        history: Option<&mut VelocityHistory>,
    ) -> Result<Outcome, Error> {
        match history {
            Some(history) => self.embedded(span, n, c, watch, history),
            None => self.doubling(span, n, c, watch),
        }
    }

    /// Step doubling over `span` from the segment's start, `n` substeps per `dt` first (see
    /// [`StepControl::Adaptive`](crate::settings::StepControl::Adaptive)). With `watch`, a run that shows an event (against those marks)
    /// stops it: the world goes back to the segment's start.
    fn doubling(
        &mut self,
        span: Real,
        mut n: usize,
        c: &Control,
        watch: Option<&[Mark]>,
    ) -> Result<Outcome, Error> {
        let levers = self.levers();
        let mut m = substeps_for(span, c.dt, n);
        // After a rejection the fine run of the last try is the coarse run of the next (the
        // same substeps from the same state: the same result to the bit), so it is not run
        // again. A run is kept as its states, its ledger and its projection fallbacks.
        let mut reuse: Option<(Vec<BodyState>, EnergyLedger, usize)> = None;
        loop {
            let (coarse, coarse_ledger, coarse_fallbacks) = match reuse.take() {
                Some(kept) => kept,
                None => {
                    if let Err(e) = self.run_part(span, m) {
                        self.cut_after_divergence(e, span, c, &mut n, &mut m)?;
                        continue;
                    }
                    if self.event_seen(watch) {
                        return Ok(Outcome::Event(span / (2 * m) as Real));
                    }
                    let run = (
                        self.dynamic_states(),
                        self.core.progress.ledger,
                        self.backend.projection_fallbacks(),
                    );
                    self.restore_segment();
                    run
                }
            };
            if let Err(e) = self.run_part(span, 2 * m) {
                self.cut_after_divergence(e, span, c, &mut n, &mut m)?;
                continue;
            }
            if self.event_seen(watch) {
                return Ok(Outcome::Event(span / (2 * m) as Real));
            }
            let ledger = self.core.progress.ledger;
            let energy = (ledger.dissipated - coarse_ledger.dissipated).abs()
                + (ledger.work - coarse_ledger.work).abs();
            // Per body: the position difference, plus the velocity difference over the span or
            // the horizon (an event the control does not locate lands both runs on the same
            // position but not with the same velocity; this is how it refines the step then).
            let carried = c.horizon.max(span);
            let (diff, worst) = coarse
                .iter()
                .zip(self.dynamic_states())
                .zip(&levers)
                .map(|((a, b), &lever)| {
                    let d = (a.1 - b.1).length()
                        + lever * a.2.angle_between(b.2)
                        + carried * ((a.3 - b.3).length() + lever * (a.4 - b.4).length());
                    (d, a.0)
                })
                .fold((0.0 as Real, None), |acc, (d, h)| {
                    if d > acc.0 { (d, Some(h)) } else { acc }
                });
            let estimate = diff / ((1 << c.order) - 1) as Real;
            if !(estimate.is_finite() && energy.is_finite()) {
                return Err(Error::Diverged {
                    time: self.time(),
                    joint: None,
                    reason: "the step-doubling error estimate is not finite".into(),
                });
            }
            // A projection that fell back to Gauss-Newton (near a singular pose) is not the
            // integrator's: its error is not in the estimate (both runs can share it), so the
            // step is cut until both runs converge by chord iterations, as ANSYS bisects on a
            // convergence failure. The coarse run too: the difference estimates the fine run's
            // error only when both carry the scheme's own error. With the fine run alone
            // converged, the step that crosses the A02 four-bar's singular pose was kept at the
            // first substep the fine run got through, and lost 7.1e-7 J there in both runs
            // (their difference 3e-10 m): 4.7 times the request at 1e-6 m over 10 s, step alone.
            let fine_fallbacks = self.backend.projection_fallbacks();
            let converged = fine_fallbacks == 0 && coarse_fallbacks == 0;
            let met = estimate <= c.tolerance && energy <= c.energy_tolerance && converged;
            if met || 2 * n >= c.max {
                if met && c.extrapolate {
                    self.extrapolate(&coarse, c.order)?;
                }
                self.note_substep(span / (2 * m) as Real);
                let stats = &mut self.core.stats;
                stats.unmet += u64::from(!met);
                stats.last_estimate = estimate;
                // Not after a part of the step (before or after an event): its error is that
                // of a shorter stretch.
                let next = if span >= c.dt {
                    next_substeps(
                        n,
                        estimate / c.tolerance,
                        energy / c.energy_tolerance,
                        c.order,
                    )
                } else {
                    n
                };
                return Ok(Outcome::Kept(next));
            }
            let joint = worst.and_then(|h| self.core.joints.attached_to(h).first().copied());
            let fine = (self.dynamic_states(), ledger, fine_fallbacks);
            self.restore_segment();
            let reason = if !converged {
                CutReason::Projection
            } else if estimate > c.tolerance {
                CutReason::Estimate
            } else {
                CutReason::Energy
            };
            self.note_cut(joint, reason);
            // Twice the substeps, at most `max` per `dt` in the kept run.
            let doubled = (2 * n).min(c.max / 2);
            if doubled == 2 * n {
                reuse = Some(fine);
                m *= 2;
            } else {
                m = substeps_for(span, c.dt, doubled);
            }
            n = doubled;
        }
    }

    /// Local extrapolation of a kept doubling (see
    /// [`StepControl::Adaptive`](crate::settings::StepControl::Adaptive)'s `extrapolate`): each
    /// dynamic body moves from the fine run's state by `1 / (2^p - 1)` of the difference to the
    /// coarse run's (centre of mass, rotation as a turn, velocities), which takes out the fine
    /// run's leading error term, and the backend puts the bodies back onto the constraints.
    /// Only where every body took the scheme of order `p >= 2` in the fine run: first-order
    /// velocities live at half steps, and an island that fell back to a lower order (a
    /// contact, or the composition's fallback to RATTLE) would be over-corrected.
    fn extrapolate(&mut self, coarse: &[BodyState], order: u32) -> Result<(), Error> {
        let integrator = self.core.settings.integrator;
        if order < 2
            || self.backend.order(integrator) != order
            || self.backend.diagnostics().first_order_bodies > 0
        {
            return Ok(());
        }
        let k = 1.0 / ((1u32 << order) - 1) as Real;
        for (a, b) in coarse.iter().zip(self.dynamic_states()) {
            let rb = &mut self.physics.bodies[b.0];
            let com = b.1 + (b.1 - a.1) * k;
            let turn = crate::math::turn_between(a.2, b.2);
            let rotation = (Rotation::from_scaled_axis(turn * k) * b.2).normalize();
            let local_com = rb.mass_properties().local_mprops.local_com;
            rb.set_position(
                Pose::from_parts(com - rotation * local_com, rotation),
                false,
            );
            rb.set_linvel(b.3 + (b.3 - a.3) * k, false);
            rb.set_angvel(b.4 + (b.4 - a.4) * k, false);
        }
        self.backend
            .settle(&mut self.core.sets(&mut self.physics))?;
        self.refresh_outputs();
        Ok(())
    }

    /// A run of the doubling that diverged (a blow-up, or a joint turned past its bound in one
    /// step: a substep too long for the motion) is cut like an estimate over the tolerance, as
    /// ANSYS bisects a step that does not converge: the world goes back to the segment's start
    /// and `n` doubles. Any other error, or a divergence that `max_substeps` leaves no room to
    /// cut, stops the step (the world keeps its last good state, as after a fixed step).
    fn cut_after_divergence(
        &mut self,
        error: Error,
        span: Real,
        c: &Control,
        n: &mut usize,
        m: &mut usize,
    ) -> Result<(), Error> {
        let Error::Diverged { joint, .. } = error else {
            return Err(error);
        };
        if 2 * *n > c.max / 2 {
            return Err(error);
        }
        self.restore_segment();
        self.note_cut(joint, CutReason::Divergence);
        *n *= 2;
        *m = substeps_for(span, c.dt, *n);
        Ok(())
    }

    /// Bisects the event that a run over `span` from the segment's start showed (see the
    /// module docs), at substeps of at most `h`. Returns the bracket `(lo, hi]` (from the
    /// segment's start) and the event's joint and kind; the world is back at the segment's
    /// start.
    fn locate(
        &mut self,
        span: Real,
        h: Real,
        marks: &[Mark],
        c: &Control,
    ) -> Result<Bracket, Error> {
        let levers = self.levers();
        let speed = |w: &Self| {
            w.dynamic_states()
                .iter()
                .zip(&levers)
                .map(|(s, lever)| s.3.length() + lever * s.4.length())
                .fold(0.0 as Real, Real::max)
        };
        let mut v = speed(self);
        let mut kinetic = self.energy().kinetic;
        let mut power: Real = 0.0;
        let (mut lo, mut hi) = (0.0 as Real, span);
        let mut event = None;
        // A floor far below any tolerance a user asks for (the substep stays representable
        // beside the time).
        let floor = span * Real::EPSILON.sqrt();
        // The world is at `lo` (the probe, or the segment's start while `lo` is 0).
        let mut at_lo = true;
        loop {
            // Never wider than the substep the stretch is taken at: the event's substep must
            // not be coarser than its neighbours (a stuck joint breaking away has no speed yet
            // to bound the bracket by).
            let delta = (c.tolerance / (2.0 * v))
                .min(c.energy_tolerance / (2.0 * power))
                .min(h)
                .max(floor);
            if hi - lo <= delta {
                break;
            }
            if !at_lo {
                if lo > 0.0 {
                    self.core.progress = self.probe.restore(
                        &mut self.physics,
                        &mut self.core.joints,
                        &mut self.backend,
                    );
                } else {
                    self.restore_segment();
                }
            }
            let mid = 0.5 * (lo + hi);
            let m = substeps_for(mid - lo, h, 1);
            self.run_part(mid - lo, m)?;
            if let Some(found) = self.onset(marks) {
                event = Some(found);
                hi = mid;
                at_lo = false;
            } else {
                let k = self.energy().kinetic;
                power = power.max((k - kinetic).abs() / (mid - lo));
                kinetic = k;
                v = v.max(speed(self));
                lo = mid;
                at_lo = true;
                self.probe.save(
                    &self.physics,
                    &self.core.joints,
                    self.core.progress,
                    &self.backend,
                );
            }
        }
        if event.is_none() {
            // The first run's event, not seen again by the bisection's runs (a grazing contact
            // that a finer substep misses): name it from that run.
            self.restore_segment();
            self.step_unchecked(span, substeps_for(span, h, 1))?;
            event = self.onset(marks);
        }
        self.restore_segment();
        Ok((lo, hi, event))
    }

    /// Adds the stops that acted in the part just kept to `acted` (one bit per DOF, by slot).
    fn gather_acted(&self, acted: &mut Vec<u8>) {
        let marks = self.event_marks();
        acted.resize(marks.len(), 0);
        for (a, m) in acted.iter_mut().zip(marks) {
            *a |= m.stops;
        }
    }

    /// Integrates `span` in `m` substeps from the state now, counting them in the stats.
    fn run_part(&mut self, span: Real, m: usize) -> Result<(), Error> {
        self.step_unchecked(span, m)?;
        self.core.stats.substeps += m as u64;
        Ok(())
    }

    /// With `watch`, the run just taken shows an event against those marks: then the world is
    /// put back at the segment's start.
    fn event_seen(&mut self, watch: Option<&[Mark]>) -> bool {
        let seen = watch.is_some_and(|marks| self.onset(marks).is_some());
        if seen {
            self.restore_segment();
        }
        seen
    }

    /// Counts a try taken again from the segment's start (the world is back there), with the
    /// joint that cut it and why.
    fn note_cut(&mut self, joint: Option<JointId>, reason: CutReason) {
        let stats = &mut self.core.stats;
        stats.rejected += 1;
        stats.last_cut = Some((self.core.progress.time, joint));
        stats.last_cut_reason = Some(reason);
    }

    /// Records a kept substep in the smallest and largest.
    fn note_substep(&mut self, h: Real) {
        let stats = &mut self.core.stats;
        stats.smallest_substep = if stats.smallest_substep == 0.0 {
            h
        } else {
            stats.smallest_substep.min(h)
        };
        stats.largest_substep = stats.largest_substep.max(h);
    }

    /// Saves the segment's start.
    fn save_segment(&mut self) {
        self.segment.save(
            &self.physics,
            &self.core.joints,
            self.core.progress,
            &self.backend,
        );
    }

    /// Puts the segment's start back (the checkpoint stays for another try).
    fn restore_segment(&mut self) {
        self.core.progress =
            self.segment
                .restore(&mut self.physics, &mut self.core.joints, &mut self.backend);
    }

    /// Every joint slot's event state now.
    fn event_marks(&self) -> Vec<Mark> {
        self.core
            .joints
            .slots()
            .iter()
            .map(|e| match e {
                Some(e) => Mark {
                    stops: bits(&e.state.at_stop),
                    locks: bits(&e.state.locked.map(|l| l.is_some())),
                    slipping: e.state.friction.map(|f| f.slipping),
                    knees: knees(e),
                },
                None => Mark {
                    stops: 0,
                    locks: 0,
                    slipping: None,
                    knees: [0; 12],
                },
            })
            .collect()
    }

    /// The first joint (in slot order) with an event since `marks` were taken, and its kind.
    fn onset(&self, marks: &[Mark]) -> Option<(JointId, EventKind)> {
        let now = self.event_marks();
        marks
            .iter()
            .zip(&now)
            .enumerate()
            .find_map(|(slot, (a, b))| {
                let kind = if b.locks & !a.locks != 0 {
                    EventKind::Lock
                } else if b.stops & !a.stops != 0 {
                    EventKind::Stop
                } else if matches!((a.slipping, b.slipping), (Some(x), Some(y)) if x != y) {
                    EventKind::StickSlip
                } else if a.knees != b.knees {
                    EventKind::Knee
                } else {
                    return None;
                };
                Some((JointId(slot as u32), kind))
            })
    }

    /// Per dynamic body, in [`Self::dynamic_states`]' order, the lever (m) the estimate weighs
    /// its rotation and angular velocity differences with: the farthest of the body's own
    /// points from its centre of mass, that is its joints' nodes, its colliders (their bounding
    /// boxes) and its radius of gyration (the model size for a body with none of them). A
    /// rotation error `da` moves the body's points by at most `lever da`; where it moves
    /// another body, that body's own difference counts.
    ///
    /// The lever was the model size before, for every body: on the chart study's 1:1000 chain
    /// (100 beads on links of 0.1 m, a model of 10 m) the light beads' link rates, which
    /// vibrate at about 440 rad/s, were weighed 100 times over; RATTLE asked 1e-2 m over 2 s
    /// took 2.14 CPU s per simulated s there, 0.35 with the reach (2026-11-27). A far body
    /// no longer changes another's steps (`tests/adaptive_lever.rs`).
    fn levers(&self) -> Vec<Real> {
        let bodies = &self.physics.bodies;
        // The nodes' distances, by body slot.
        let mut nodes: Vec<Real> = Vec::new();
        for e in self.core.joints.iter() {
            for (b, frame) in [(e.body1, e.ansys[0]), (e.body2, e.ansys[1])] {
                let Some(rb) = bodies.get(b) else { continue };
                let d = (frame.translation - rb.mass_properties().local_mprops.local_com).length();
                let slot = b.into_raw_parts().0 as usize;
                if nodes.len() <= slot {
                    nodes.resize(slot + 1, 0.0);
                }
                if d.is_finite() {
                    nodes[slot] = nodes[slot].max(d);
                }
            }
        }
        bodies
            .iter()
            .filter(|(_, rb)| rb.is_dynamic())
            .map(|(h, rb)| {
                let c = rb.center_of_mass();
                let mut lever = nodes
                    .get(h.into_raw_parts().0 as usize)
                    .copied()
                    .unwrap_or(0.0);
                if let Some(r) = crate::body::gyration_radius(rb) {
                    lever = lever.max(r);
                }
                for co in rb
                    .colliders()
                    .iter()
                    .filter_map(|&ch| self.physics.colliders.get(ch))
                {
                    let aabb = co.compute_aabb();
                    lever = lever.max((aabb.mins - c).abs().max((aabb.maxs - c).abs()).length());
                }
                if lever.is_finite() && lever > 0.0 {
                    lever
                } else {
                    self.model_size()
                }
            })
            .collect()
    }

    /// The dynamic bodies' handles, centres of mass, orientations and velocities, in the body
    /// set's order.
    fn dynamic_states(&self) -> Vec<BodyState> {
        self.physics
            .bodies
            .iter()
            .filter(|(_, rb)| rb.is_dynamic())
            .map(|(h, rb)| {
                let (v, w) = self.velocity_of(h);
                (h, rb.center_of_mass(), rb.position().rotation, v, w)
            })
            .collect()
    }
}

/// A joint's table segments (see [`Mark::knees`]): the DOF's deflection (measure minus
/// reference) in its stiffness table, its rate (the output's relative velocity, frame I) in
/// its damping table. A table extends its end segments past its ends, so its first and last
/// points are no knees: the segment index counts the interior points below the value.
fn knees(e: &crate::joint_set::JointEntry) -> [u16; 12] {
    let b = &e.joint.behaviour;
    let mut out = [0; 12];
    if !b.has_forces() {
        return out;
    }
    let o = &e.state.output;
    let rate = [
        o.velocity.x,
        o.velocity.y,
        o.velocity.z,
        o.angular_velocity.x,
        o.angular_velocity.y,
        o.angular_velocity.z,
    ];
    let segment = |t: &crate::behaviour::Table, x: Real| {
        let p = &t.points;
        // (A table has at least two points once validated; a shorter one has no interior.)
        let interior = p.get(1..p.len().saturating_sub(1)).unwrap_or_default();
        (1 + interior.partition_point(|q| q.0 < x)).min(u16::MAX as usize) as u16
    };
    for k in 0..6 {
        if let Some(t) = &b.stiffness_tables[k] {
            out[k] = segment(t, o.measure[k] - b.reference[k].unwrap_or(e.initial[k]));
        }
        if let Some(t) = &b.damping_tables[k] {
            out[6 + k] = segment(t, rate[k]);
        }
    }
    out
}

/// One bit per DOF.
fn bits(flags: &[bool; 6]) -> u8 {
    flags
        .iter()
        .enumerate()
        .fold(0, |acc, (k, f)| acc | (u8::from(*f) << k))
}

#[cfg(test)]
mod tests {
    use super::next_substeps;

    /// The coarsening rule in numbers: RATTLE (`p = 2`) predicts a halved step's fine-run
    /// error as 4 times the estimate, the composition (`p = 4`) as 16 times.
    #[test]
    fn next_substeps_halves_while_the_prediction_passes() {
        // 4 * 0.2 = 0.8 passes, 16 * 0.2 = 3.2 does not: one halving.
        assert_eq!(next_substeps(32, 0.2, 0.0, 2), 16);
        // 0.01 * 4^2 = 0.16 passes, 0.01 * 4^3 = 0.64 too; the cap of 8 stops at 4.
        assert_eq!(next_substeps(32, 0.01, 0.0, 2), 4);
        // 0.01 * 16 = 0.16 passes, 0.01 * 256 does not.
        assert_eq!(next_substeps(32, 0.01, 0.0, 4), 16);
        // Over the tolerance after one halving: kept.
        assert_eq!(next_substeps(32, 0.3, 0.0, 2), 32);
        // The energy difference doubles with each halving: 0.2 -> 0.4 -> 0.8 -> 1.6.
        assert_eq!(next_substeps(32, 0.0, 0.2, 2), 8);
        // Never below one substep.
        assert_eq!(next_substeps(2, 0.0, 0.0, 2), 1);
        assert_eq!(next_substeps(1, 0.0, 0.0, 2), 1);
    }
}
