//! One substep of the Lagrange backend, stage by stage (see the parent module's docs).

use crate::error::Error;
use crate::joint_set::JointSet;
use crate::math::rapier::dynamics::{RigidBodyHandle, RigidBodySet};
use crate::math::rapier::pipeline::PhysicsWorld;
use crate::math::{Pose, Real, Rotation, Vector};
use crate::rows::{FramePair, RowKind};
use crate::solver::kkt::{JAC_ROW_STRIDE, KktSolver};

use crate::output::EnergyLedger;

use super::super::{OutputPass, Sets};
use super::effects::Effects;
#[cfg(feature = "parallel")]
use super::refresh_joint;
use super::{
    BodyState, Island, IslandStart, LagrangeBackend, MAX_VELOCITY_REFINEMENTS, free_rotor,
    gyroscopic_kick, kkt_err, lanes, projection_tolerance, rotation_scale, velocity_tolerance,
};

/// The free drift's running mean of chord steps (see [`Island::free_drift`]) is taken over
/// this many substeps, and judged once it has as many.
const FREE_WINDOW: u32 = 16;
/// Above this many chord steps per substep on that mean, an island goes back to the velocity
/// solve's form for [`FREE_PAUSE`] substeps, and then measures the free drift again. Measured
/// (callgrind, first order at 1/60 s x 4) against the velocity solve's form: the 1:1000 chain
/// of 10 links took 2.84 chord steps per substep drifting free against 1.91 (+6.2 %
/// instructions), the 1:1 chain of 100 links 2.00 against 1.70 and the 1:1000 chain of 100
/// 2.0 against 1.89 (-3.8 % and -7.4 %: the saved solve outweighs them), the 1:1 chain of 10
/// links 1.81 against 1.22 (+0.2 %). A bound of 2.0 sent the 100-link chains back, 3.0 kept
/// the 10-link 1:1000 chain free; 2.5 sits between.
const FREE_MAX: Real = 2.5;
const FREE_PAUSE: u32 = 256;

/// The stage sizes of the fourth-order composition, in units of the substep: Suzuki's
/// fractal `p, p, 1 - 4p, p, p` with `p = 1 / (4 - 4^(1/3))` (Suzuki 1990; Hairer, Lubich,
/// Wanner, "Geometric Numerical Integration", II.4). Measured on A01 and the conical
/// pendulum (`tests/composition4_order.rs`), its error is 1/72 to 1/76 of the triple jump's
/// (`a, 1 - 2a, a` with `a = 1 / (2 - 2^(1/3))`, whose middle stage is -1.7 h against -0.66 h
/// here) at the same substep, about 1/10 at the same cost (the triple jump has 3 stages).
pub(super) const SUZUKI: [Real; super::STAGES] = {
    // 4^(1/3) to round-off (a `const` cannot call `cbrt`).
    let c = 1.587_401_051_968_199_5_f64 as Real;
    let p = 1.0 / (4.0 - c);
    [p, p, 1.0 - 4.0 * p, p, p]
};

impl LagrangeBackend {
    /// One substep of `h` ending at `t1` for every island: each island's stages up to the
    /// velocity solve, one Rapier call for all (contacts act), each island's stages from the
    /// position projection on. Requires each island's factorisation at its current state.
    pub(super) fn substep(&mut self, sets: &mut Sets, h: Real, t1: Real) -> Result<(), Error> {
        let mut starts = Vec::with_capacity(self.islands.len());
        for island in &mut self.islands {
            starts.push(island.before_drift(&mut self.fx, sets, h, t1)?);
            // Rapier's pipeline is not made for non-finite velocities (it can panic on them):
            // a blow-up stops here, as a divergence.
            if let Some(i) =
                (0..island.bodies.len()).find(|&i| island.rhs_b[i].iter().any(|x| !x.is_finite()))
            {
                return Err(Error::Diverged {
                    time: sets.time,
                    joint: None,
                    reason: format!(
                        "body {:?}: non-finite velocity from the constraint solve",
                        island.bodies[i].into_raw_parts()
                    ),
                });
            }
            island.hand_to_rapier(sets.physics, h);
        }
        sets.physics.step();
        for (island, start) in self.islands.iter_mut().zip(starts) {
            island.take_from_rapier(sets.physics, h);
            island.after_drift(&mut self.fx, sets, h, t1, start, true)?;
            island.write_back(sets.physics, sets.time)?;
            island.factor_valid = Some(h);
            let ledger = core::mem::take(&mut island.ledger);
            sets.ledger.work += ledger.work;
            sets.ledger.dissipated += ledger.dissipated;
        }
        sets.joints.update_row_references(&sets.physics.bodies);
        Ok(())
    }

    /// One step of `n` substeps for every island, each integrating its bodies itself (see
    /// `integrates_alone`), from its start ([`Island::start_step`]) to its joints' outputs
    /// ([`Island::refresh_outputs`]) in one pass over the island, while its data is in cache.
    /// With the `parallel` feature every island starts on rayon's pool, and the plain ones (see
    /// [`Island::step_plain`]) step there too: they read the joint set and the bodies outside
    /// them (the ground, fixed bodies) and write only their own state, so the order does not
    /// matter and the result is the serial one to the bit. The first error in island
    /// order is returned (the world rolls the step back).
    pub(super) fn step_islands_alone(
        &mut self,
        sets: &mut Sets,
        start: &IslandStart,
        n: usize,
        out: &OutputPass,
    ) -> Result<(), Error> {
        let (h, roles, rebuilt) = (start.h, start.roles, start.rebuilt);
        #[cfg(feature = "parallel")]
        let mut done = {
            use rayon::prelude::*;
            // Each island's start reads the sets and writes only the island.
            let shared: &Sets = sets;
            let step = lanes::PlainStep {
                joints: shared.joints,
                bodies: &shared.physics.bodies,
                time: shared.time,
                h,
                n,
            };
            let units = lanes::units(&mut self.islands, &mut self.lanes);
            let sizes: Vec<usize> = units.iter().map(|(unit, _)| unit.len()).collect();
            let results: Vec<Result<u8, Error>> = units
                .into_par_iter()
                // One unit per task at least: with 4 islands, 10 to 50 islands stepped 6 to
                // 10 % slower in the median (paired probe runs; load imbalance).
                .with_min_len(1)
                .map(|(unit, lanes)| {
                    let start =
                        |island: &mut Island| island.start_step(shared, roles, h, rebuilt, true);
                    lanes::step_unit(unit, lanes, start, step)
                })
                .collect();
            // Per island, in island order: stepped on the pool, or the unit's error.
            let mut flags = Vec::with_capacity(self.islands.len());
            for (result, size) in results.into_iter().zip(sizes) {
                match result {
                    Ok(mask) => flags.extend((0..size).map(|d| Ok(mask & (1 << d) != 0))),
                    Err(e) => {
                        flags.push(Err(e));
                        flags.extend((1..size).map(|_| Ok(false)));
                    }
                }
            }
            flags.into_iter()
        };
        #[cfg(feature = "parallel")]
        for island in &mut self.islands {
            if done.next().transpose()? == Some(true) {
                island.write_back(sets.physics, sets.time)?;
                island.sleep_check(&mut sets.physics.bodies, h * n as Real);
                continue;
            }
            island.step_alone(&mut self.fx, sets, h, n)?;
            island.sleep_check(&mut sets.physics.bodies, h * n as Real);
            island.refresh_outputs(&self.fx, sets, roles, out, &mut self.refreshed);
        }
        #[cfg(not(feature = "parallel"))]
        {
            let (mut rest, mut groups) = (&mut self.islands[..], 0);
            while !rest.is_empty() {
                let len = lanes::unit_len(rest);
                let (unit, tail) = core::mem::take(&mut rest).split_at_mut(len);
                rest = tail;
                let lanes = (len > 1).then(|| {
                    if self.lanes.len() == groups {
                        self.lanes.push(crate::solver::kkt::KktLanes::default());
                    }
                    groups += 1;
                    &mut self.lanes[groups - 1]
                });
                let stepped = {
                    let shared: &Sets = sets;
                    let start =
                        |island: &mut Island| island.start_step(shared, roles, h, rebuilt, true);
                    let step = lanes::PlainStep {
                        joints: shared.joints,
                        bodies: &shared.physics.bodies,
                        time: shared.time,
                        h,
                        n,
                    };
                    lanes::step_unit(unit, lanes, start, step)?
                };
                for (d, island) in unit.iter_mut().enumerate() {
                    if stepped & (1 << d) != 0 {
                        island.write_back(sets.physics, sets.time)?;
                    } else {
                        island.step_alone(&mut self.fx, sets, h, n)?;
                    }
                    island.sleep_check(&mut sets.physics.bodies, h * n as Real);
                    island.refresh_outputs(&self.fx, sets, roles, out, &mut self.refreshed);
                }
            }
        }
        #[cfg(feature = "parallel")]
        self.refresh_plain_outputs(sets, out);
        Ok(())
    }

    /// With the `parallel` feature: the reactions and outputs of the plain islands' joints
    /// (stepped on the pool, written back in island order) on the pool, joint by joint, as
    /// [`Island::refresh_outputs`] writes them.
    #[cfg(feature = "parallel")]
    fn refresh_plain_outputs(&mut self, sets: &mut Sets, out: &OutputPass) {
        use rayon::prelude::*;
        let (islands, fx, block_of, island_of) =
            (&self.islands, &self.fx, &self.block_of, &self.island_of);
        let bodies = &sets.physics.bodies;
        sets.joints
            .slots_mut()
            .par_iter_mut()
            .zip(self.refreshed.par_iter_mut())
            .enumerate()
            .with_min_len(64)
            .for_each(|(ji, (e, r))| {
                let (Some(e), Some(i)) = (e, island_of.get(ji).copied().flatten()) else {
                    return;
                };
                let island = &islands[i];
                if !island.plain {
                    return;
                }
                let block = match block_of.get(ji) {
                    Some(&Some((_, k))) => Some((island, k)),
                    _ => None,
                };
                // A spring or damper (`Roles::springs`) gives its joint `Roles::EFFECTS`: its
                // island is never plain.
                *r = Some(refresh_joint(e, ji, fx, block, false, bodies, out));
            });
    }
}

impl Island {
    /// The substeps of a plain island (no behaviour, no screw or drive row: see
    /// `Island::plain`), all but the write-back: the kick and velocity solve, the drift, the
    /// position projection, the factorisation at `q_(n+1)` and the velocity projection, reading
    /// the joint set and the bodies outside the island only. The same stages as
    /// [`Island::step_alone`] with everything that cannot act on this island left out, so both
    /// give the same result to the bit.
    ///
    /// A composed step in which the factorisation of any positive stage finds a body that
    /// needs the geometric-stiffness added inertia (which the composition leaves out) is taken
    /// again with RATTLE from the step's start: the composition was chosen without knowing the
    /// force (the first step starts from zero multipliers) or before it grew. Kept, such a step
    /// put the light beads of the 1:1000 chain into motion at `h omega` ~ 2.6 without the added
    /// inertia, and the run at 1/30 x 4 ended 4.0e-3 m off where RATTLE alone is 1.2e-4 m
    /// (`tests/composition_fallback.rs`). Any positive stage, not the last one alone: on that
    /// chain the estimate swings between 0.04 and 2.2 times the threshold from stage to stage,
    /// so reading the last stage made the decision a matter of which stage came last (the
    /// test's runs 1.4e-6 m apart then, 2.4e-8 m now). The negative stage's estimate is left
    /// out: read too, it turned the slider-crank of `tests/adaptive_divergence.rs` to RATTLE
    /// more often, and its adaptive run asked 1e-2 m ended 1.3e-2 m off in 1630 substeps
    /// (2.4e-5 m in 1081 without).
    pub(super) fn step_plain(
        &mut self,
        joints: &JointSet,
        bodies: &RigidBodySet,
        time: Real,
        h: Real,
        n: usize,
    ) -> Result<(), Error> {
        if !self.composed {
            return self.plain_substeps(joints, bodies, time, h, n);
        }
        let mut start = core::mem::take(&mut self.step_start);
        start.clone_from(&self.st);
        self.would_stiffen = false;
        self.plain_substeps(joints, bodies, time, h, n)?;
        if self.would_stiffen {
            self.st.clone_from(&start);
            self.fresh_report();
            self.take_rattle();
            // The warm start's history holds the stages' multipliers (other sizes), and the
            // force estimate of the factorisation below reads the last stage's impulses.
            self.mu.fill(0.0);
            self.mu_depth = 0;
            self.vp_carry.fill(0.0);
            let scale = h / self.last_h;
            self.impulse.iter_mut().for_each(|x| *x *= scale);
            self.rows(joints, bodies, h, true);
            self.factor(joints, bodies, h, time)?;
            self.plain_substeps(joints, bodies, time, h, n)?;
        }
        self.step_start = start;
        Ok(())
    }

    /// The substeps of [`Island::step_plain`], composed or not.
    fn plain_substeps(
        &mut self,
        joints: &JointSet,
        bodies: &RigidBodySet,
        time: Real,
        h: Real,
        n: usize,
    ) -> Result<(), Error> {
        let stages: &[Real] = if self.composed { &SUZUKI } else { &[1.0] };
        for k in 0..n {
            for (stage, &gamma) in stages.iter().enumerate() {
                let hs = gamma * h;
                self.stage = (stage, h);
                self.before_factor(joints, bodies, hs, time)?;
                self.factor(joints, bodies, hs, time)?;
                let last = k + 1 == n && stage + 1 == stages.len();
                self.after_factor(hs, time, k + 2 >= n, last)?;
            }
            // A composed island's factorisation does not depend on the stage size (Lagrange
            // rows only, no added inertia): it holds for the next step's `h`.
            self.factor_valid = Some(h);
        }
        Ok(())
    }

    /// A plain substep's stages before its factorisation at `q_(n+1)`: the kick and velocity
    /// solve, the drift and the position projection.
    pub(super) fn before_factor(
        &mut self,
        joints: &JointSet,
        bodies: &RigidBodySet,
        hs: Real,
        time: Real,
    ) -> Result<(), Error> {
        self.kick_and_solve(hs, time, self.free_drift())?;
        self.drift(hs);
        self.project_positions(joints, bodies, hs, time)
    }

    /// A plain substep's stage after its factorisation: the velocity projection, or none
    /// (`ending`: the substep is one of the step's last two; `last`: the step's last stage,
    /// whose projection refines).
    pub(super) fn after_factor(
        &mut self,
        hs: Real,
        time: Real,
        ending: bool,
        last: bool,
    ) -> Result<(), Error> {
        // The velocity projection at `q_(n+1)` and the next substep's velocity solve share
        // this factorisation, and a projection is linear: with a kick between that is linear
        // in the velocities, `P(P(v) + a) = P(v + a)`, up to the hard rows' regularisation.
        // Such an island leaves the projection to that solve, but not in the step's last two
        // substeps: the reactions are the last substep's impulses, and its velocity solve
        // would carry the projection impulse of the substep before (the rigid link's bottom
        // tension came out 33 % high, `tests/rigid_link.rs`). Measured (callgrind, 1/60 x 4,
        // 100 steps, 50 on the chains): 3.3 to 4.5 % fewer instructions on the pendulum, the
        // mixed scene and the 100-link chain; the 1:1000 chain (added inertia) is unchanged.
        if ending || !self.merges_velocity_projection() {
            self.end_momenta(hs);
            self.project_velocities(time, last)?;
        } else {
            self.vp_carry.fill(0.0);
            if self.second_any {
                self.half_kick(hs);
            }
        }
        self.last_h = hs;
        Ok(())
    }

    /// The substep takes no velocity solve: the bodies drift at their kicked velocities plus
    /// the predicted constraint impulse ([`Island::predict_impulse`]), and the position
    /// projection corrects what the prediction missed. The velocity solve (`J_n v' = 0`)
    /// and the projection's displacements both act along `M~^-1 J_n^T` from the same
    /// factorisation, so on the translations the two forms reach the same point and the
    /// same velocities, whichever impulse the drift carried: `q_(n+1) = q_n + h v* + M~^-1
    /// J_n^T mu` with `C(q_(n+1)) = 0` (SHAKE's equation, `v*` the kicked velocities). On the
    /// rotations the drift's turn and the projection's compose, so the split moves the point
    /// by the product of the substep's turn and the predicted impulse's error, below the
    /// projection's tolerance where the prediction holds (and `O(h^3)`, the integrator's own
    /// local error, where it does not).
    ///
    /// Where: tree islands (a loop's redundant or nearly dependent rows take the
    /// regularisation's slow directions, see `REGULARISATION_LOOPS`) without penalty rows
    /// (their target is their own deflection), kinematic bodies (their rows' velocity terms
    /// are targets of the velocity solve) or the composition (its stages' histories are
    /// their own, see `Island::extrapolate_multipliers`). Plain islands have no drive rows,
    /// whose rates are targets too.
    pub(super) fn free_drift(&self) -> bool {
        self.free_pause == 0
            && !self.composed
            && !self.redundant
            && !self.has_kinematic
            && self.regularisation < super::REGULARISATION_LOOPS
            && !self.penalty.iter().any(|&p| p)
    }

    /// The island's kicks are linear in the velocities, so a substep's velocity projection
    /// can be left to the next substep's velocity solve (see [`Island::plain_substeps`]):
    /// isotropic bodies (no gyroscopic term), no penalty row (its projection target is its own
    /// rate, not a constraint) and no added inertia (it reads the substep's impulses as the
    /// joint forces); first order, or RATTLE where the island drifts free (see
    /// [`Island::free_drift`]): the next substep's position projection then takes the
    /// velocities' component along the rows with the rest (`P(v)` and `v` drift to the same
    /// point), and the skipped projection's second half kick still acts
    /// ([`Island::half_kick`]). (Should the next substep take the velocity solve instead, that
    /// solve projects the same way: the kicks between are linear on isotropic bodies.)
    pub(super) fn merges_velocity_projection(&self) -> bool {
        !self.composed
            && (!self.second_any || self.free_h > 0.0)
            && !self.penalty.iter().any(|&p| p)
            && self.st.iter().all(|s| s.added == 0.0 && s.isotropic())
    }

    /// One step of `n` substeps of `h` with the island integrating its bodies itself (see
    /// `integrates_alone`): the states stay in the solver from substep to substep and go
    /// back to Rapier once, at the end.
    pub(super) fn step_alone(
        &mut self,
        fx: &mut Effects,
        sets: &mut Sets,
        h: Real,
        n: usize,
    ) -> Result<(), Error> {
        if self.plain {
            self.step_plain(sets.joints, &sets.physics.bodies, sets.time, h, n)?;
            return self.write_back(sets.physics, sets.time);
        }
        for k in 0..n {
            let t1 = sets.time + (k + 1) as Real * h;
            self.update_drives(sets.joints, t1, h);
            let start = self.before_drift(fx, sets, h, t1)?;
            self.drift(h);
            self.after_drift(fx, sets, h, t1, start, k + 1 == n)?;
            if k + 1 == n {
                self.write_back(sets.physics, sets.time)?;
            }
            self.factor_valid = Some(h);
            let ledger = core::mem::take(&mut self.ledger);
            sets.ledger.work += ledger.work;
            sets.ledger.dissipated += ledger.dissipated;
            self.update_row_references(sets.joints, &sets.physics.bodies);
        }
        Ok(())
    }

    /// The drift of a substep, as Rapier's integration does it (so that a world gives the same
    /// motion to the bit whichever of the two integrates): the centre of mass moves by `v h`,
    /// the rotation by the linearised quaternion update `normalize((1, w h / 2) q)` (second-order
    /// bodies take `w` scaled so that it turns by exactly `|w| h`, see [`rotation_scale`]).
    ///
    /// A second-order body with unequal principal moments drifts as a free rotor instead
    /// ([`free_rotor`]): its angular momentum `I w` stays over the drift and its kicks have no
    /// gyroscopic term. Holding `w` over the drift and kicking with `-w x I w` at the
    /// unconstrained velocities was first order wherever a joint acts on such a body (the
    /// constraint impulse changes `w` by `O(h)` within the kick): measured on a heavy top and
    /// on the Bricard mechanism, the error halved, not quartered, with the substep.
    pub(super) fn drift(&mut self, h: Real) {
        let n = self.bodies.len();
        let mut i = 0;
        // Two bodies at a time in lanes where neither drifts as a rotor (see `drift_two`).
        while i + 1 < n {
            if self.drifts_as_rotor(i) || self.drifts_as_rotor(i + 1) {
                self.drift_one(i, h);
                self.drift_one(i + 1, h);
            } else {
                self.drift_two(i, h);
            }
            i += 2;
        }
        if i < n {
            self.drift_one(i, h);
        }
    }

    /// [`Island::drift`] of bodies `i` and `i + 1` (neither a rotor) in the two lanes of one
    /// register ([`crate::math::pair`]): the same operations as [`Island::drift_one`], the same
    /// results to the bit.
    fn drift_two(&mut self, i: usize, h: Real) {
        use crate::math::pair::{L, Q, V};
        let vel = |x: [Real; 6]| (Vector::new(x[0], x[1], x[2]), Vector::new(x[3], x[4], x[5]));
        let spin = |w: Vector, second: bool| if second { w * rotation_scale(w, h) } else { w };
        let ((va, wa), (vb, wb)) = (vel(self.rhs_b[i]), vel(self.rhs_b[i + 1]));
        let (sa, sb) = (spin(wa, self.second[i]), spin(wb, self.second[i + 1]));
        let (head, tail) = self.st.split_at_mut(i + 1);
        let (a, b) = (&mut head[i], &mut tail[0]);
        let pose = Q::new(a.pose.rotation, b.pose.rotation);
        let local = V::new(a.local_com, b.local_com);
        let com = V::new(a.pose.translation, b.pose.translation).add(pose.rotate(local));
        let hang = V::new(sa, sb).scale(L::splat(h * 0.5));
        let q = Q {
            x: hang.x,
            y: hang.y,
            z: hang.z,
            w: L::splat(1.0),
        };
        let rotation = q.mul(pose).normalize();
        let com = com.add(V::new(va, vb).scale(L::splat(h)));
        let neg = V::new(-a.local_com, -b.local_com);
        let at = com.add(rotation.rotate(neg));
        // `Pose * local_com`: the rotated point plus the translation.
        let centre = rotation.rotate(local).add(at);
        let ([ra, rb], [ta, tb], [ca, cb]) = (rotation.split(), at.split(), centre.split());
        for (s, r, t, c, v, w) in [(a, ra, ta, ca, va, wa), (b, rb, tb, cb, vb, wb)] {
            s.pose = Pose::from_parts(t, r);
            s.com = c;
            s.linvel = v;
            s.refresh_inertia();
            s.angvel = w;
        }
    }

    /// [`Island::drift`] of body `i`.
    fn drift_one(&mut self, i: usize, h: Real) {
        let x = self.rhs_b[i];
        let v = Vector::new(x[0], x[1], x[2]);
        let w = Vector::new(x[3], x[4], x[5]);
        let rotor = self.drifts_as_rotor(i);
        let second = self.second[i];
        let s = &mut self.st[i];
        let com = s.pose.translation + s.pose.rotation * s.local_com;
        // The rotation, and the angular momentum a free rotor keeps.
        let (rotation, momentum) = if rotor {
            let l = s.inertia * w;
            (free_rotor(s, l, h), Some(l))
        } else {
            let spin = if second { w * rotation_scale(w, h) } else { w };
            let hang = spin * (h * 0.5);
            let q = Rotation::from_xyzw(hang.x, hang.y, hang.z, 1.0) * s.pose.rotation;
            (q.normalize(), None)
        };
        let com = com + v * h;
        s.pose = Pose::from_parts(com + rotation * (-s.local_com), rotation);
        s.com = s.pose * s.local_com;
        s.linvel = v;
        s.refresh_inertia();
        s.angvel = momentum.map_or(w, |l| s.inertia_inv * l);
    }

    /// Puts the island to sleep, as Rapier would (its bodies all slower than their activation
    /// thresholds for `time_until_sleep`), after a step of `dt` integrated by the island itself.
    pub(super) fn sleep_check(&self, bodies: &mut RigidBodySet, dt: Real) {
        let mut all = !self.bodies.is_empty();
        for b in &self.bodies {
            let rb = &mut bodies[*b];
            let (v2, w2) = (rb.linvel().length_squared(), rb.angvel().length_squared());
            let act = rb.activation_mut();
            let lin = act.normalized_linear_threshold;
            let ang = act.angular_threshold;
            let still = lin >= 0.0 && ang >= 0.0 && v2 < lin * lin && w2 < ang * ang;
            act.time_since_can_sleep = if still {
                act.time_since_can_sleep + dt
            } else {
                0.0
            };
            all &= act.time_since_can_sleep >= act.time_until_sleep;
        }
        if all {
            for b in &self.bodies {
                bodies[*b].sleep();
            }
        }
    }

    /// Moves the unwrapping references of the island's screw and drive rows to the solver's
    /// current states (see `JointSet::update_row_references`).
    fn update_row_references(&self, joints: &mut JointSet, bodies: &RigidBodySet) {
        for &j in &self.members {
            let Some(e) = joints.get_mut(j) else { continue };
            if !e
                .state
                .rows
                .iter()
                .any(|r| matches!(r, RowKind::Screw { .. } | RowKind::Drive { .. }))
            {
                continue;
            }
            let side = |b: RigidBodyHandle| match self.index.get(&b) {
                Some(&i) => (self.st[i].pose, self.st[i].com),
                None => crate::body::pose_and_com(&bodies[b]),
            };
            let f = FramePair::at(&e.low, side(e.body1), side(e.body2));
            e.update_references(&f);
        }
    }
}

/// What an island's substep needs from before the drift to after it.
struct SubstepStart {
    /// The island has behaviour to evaluate.
    effects: bool,
    /// The energy the substep started with, for the energy-consistent impact of the
    /// second-order step (`None` without elastic stops or without RATTLE).
    energy: Option<Real>,
}

impl Island {
    /// The stages before the drift: the kick of the forces (and the behaviour's first half
    /// kick), the velocity solve, the limits and friction at velocity level.
    fn before_drift(
        &mut self,
        fx: &mut Effects,
        sets: &mut Sets,
        h: Real,
        t1: Real,
    ) -> Result<SubstepStart, Error> {
        self.ledger = EnergyLedger::default();
        let effects = self.has_effects;
        // Nothing but the joints acts on the island's bodies: the stages of the island's own
        // substep (`Island::plain_substeps`), the free drift among them, so that Rapier's
        // drift gives the same motion (`tests/outputs_per_island.rs`).
        if self.plain && !self.watch_contacts {
            self.kick_and_solve(h, sets.time, self.free_drift())?;
            self.contact_energy = None;
            return Ok(SubstepStart {
                effects,
                energy: None,
            });
        }
        if self.free_h > 0.0 {
            // The warm start's history holds the free drift's multipliers.
            self.free_h = 0.0;
            self.mu_depth = 0;
        }
        self.kick_momenta(h, true);
        if !self.springs.is_empty() {
            self.spring_kick(sets.springs, &sets.physics.bodies, h, false);
        }
        // Energy-consistent stops of the second-order step need the energy the substep starts
        // with (kinetic + potential of constant forces here, springs after the first kick).
        let energy_fix = effects && self.second_any && self.has_elastic_stops;
        let mut energy = energy_fix.then(|| self.body_energy());
        if effects {
            fx.begin_substep(&self.members);
            fx.kick(self, sets, 0.5 * h, t1 - h, false);
            if let Some(e) = &mut energy {
                *e += fx.spring_energy(&self.members)
                    + self.spring_element_energy(sets.springs, &sets.physics.bodies);
            }
        }
        self.contact_energy = self.watch_contacts.then(|| self.island_energy(fx, sets));
        self.solve_velocity(sets.time)?;
        if effects {
            fx.limits_velocity(self, sets, h)?;
            fx.friction(self, sets, h)?;
        }
        Ok(SubstepStart { effects, energy })
    }

    /// The stages after the drift: the position projection (and the limits at position
    /// level), the rows and factorisation at `q_(n+1)`, the second half kick, the velocity
    /// projection (`last`: the step's last substep, see [`Island::project_velocities`]), the
    /// work of the drives and the energy-consistent impact.
    fn after_drift(
        &mut self,
        fx: &mut Effects,
        sets: &mut Sets,
        h: Real,
        t1: Real,
        start: SubstepStart,
        last: bool,
    ) -> Result<(), Error> {
        let time = sets.time;
        // The projection leaves the rows evaluated at `q_(n+1)`; a limit projected back at
        // position level moves the bodies again.
        self.project_positions(sets.joints, &sets.physics.bodies, h, time)?;
        if start.effects && fx.limits_position(self, sets, h, projection_tolerance())? {
            self.rows(sets.joints, &sets.physics.bodies, h, true);
        }
        self.factor(sets.joints, &sets.physics.bodies, h, time)?;
        self.end_momenta(h);
        if !self.springs.is_empty() {
            self.spring_kick(sets.springs, &sets.physics.bodies, h, true);
        }
        if start.effects {
            fx.kick(self, sets, 0.5 * h, t1, true);
        }
        self.project_velocities(time, last)?;
        self.book_drive_work(sets.joints);
        self.book_contacts(fx, sets);
        if let Some(energy) = start.energy {
            fx.energy_fix(self, sets, h, energy)?;
        }
        Ok(())
    }

    /// Stage 1: the momenta after the kick of the forces (the whole substep first order, half
    /// of it second order) into `rhs_b`, and the velocity targets of the rows into `rhs_j`.
    fn kick_momenta(&mut self, h: Real, momenta: bool) {
        for i in 0..self.bodies.len() {
            let s = &self.st[i];
            // First order: the whole kick now. Second order (RATTLE): half now with the
            // forces at q_n, half at the end with the forces at q_(n+1).
            let ha = if self.second[i] { 0.5 * h } else { h };
            let v = s.linvel + s.force * (ha / s.mass);
            // Gyroscopic term by the implicit midpoint rule, `w_g = w - h I^-1 (w_m x I
            // w_m)` with `w_m = (w + w_g) / 2` (fixed-point iterations, contracting for
            // `h |w| < 1`): it keeps the rotational energy and the angular momentum of a
            // free body exactly, where the explicit `-w x I w` gains energy every step
            // (measured: the IFToMM slider-crank gained 7 % of its energy scale per second
            // at h = 1/240 s). A free rotor's drift holds that term itself (see `drift`).
            let w = if self.drifts_as_rotor(i) {
                s.angvel
            } else {
                gyroscopic_kick(s, s.angvel, ha)
            } + s.inertia_inv * s.torque * ha;
            if !momenta {
                self.rhs_b[i] = [v.x, v.y, v.z, w.x, w.y, w.z];
                continue;
            }
            let mw = s.inertia * w + w * s.added;
            let mv = v * s.mass;
            self.rhs_b[i] = [mv.x, mv.y, mv.z, mw.x, mw.y, mw.z];
        }
        if !momenta {
            return;
        }
        for r in 0..self.rhs_j.len() {
            let pen = if self.penalty[r] {
                self.value[r] / h
            } else {
                0.0
            };
            self.rhs_j[r] = self.rate[r] - self.kin[r] - pen;
        }
    }

    /// Notes the chord steps a free drift's projection took (see [`Island::free_drift`]).
    pub(super) fn free_measure(&mut self, chords: usize) {
        let n = self.free_count.min(FREE_WINDOW) as Real;
        self.free_chords = (self.free_chords * n + chords as Real) / (n + 1.0);
        self.free_count += 1;
        if self.free_count >= FREE_WINDOW && self.free_chords > FREE_MAX {
            self.free_pause = FREE_PAUSE;
            self.free_count = 0;
            self.free_chords = 0.0;
        }
    }

    /// Stages 1 and 2: the kick and the velocity solve, or with `free` (see
    /// [`Island::free_drift`]) the kicked velocities plus the predicted constraint impulse.
    /// The warm start's history holds one form's multipliers or the other's, and starts again
    /// where the island changes form.
    pub(super) fn kick_and_solve(&mut self, h: Real, time: Real, free: bool) -> Result<(), Error> {
        if free != (self.free_h > 0.0) {
            self.mu_depth = 0;
        }
        self.free_pause = self.free_pause.saturating_sub(1);
        self.free_h = if free { h } else { 0.0 };
        self.kick_momenta(h, !free);
        if free {
            self.predict_impulse(h);
            Ok(())
        } else {
            self.solve_velocity(time)
        }
    }

    /// Stage 2: the velocity solve at `q_n` (`v'` in `rhs_b`, the impulses in `impulse`).
    fn solve_velocity(&mut self, time: Real) -> Result<(), Error> {
        let Some(kkt) = self.kkt.as_ref() else {
            return Ok(());
        };
        kkt.solve(&mut self.rhs_b, &mut self.rhs_j)
            .map_err(|e| kkt_err(e, time))?;
        for r in 0..self.rhs_j.len() {
            self.impulse[r] = -self.rhs_j[r];
        }
        Ok(())
    }

    /// Hands `v'` to Rapier for the substep's drift (gravity and user forces held back, so that
    /// it integrates exactly `v'`; contacts act).
    fn hand_to_rapier(&mut self, physics: &mut PhysicsWorld, h: Real) {
        for i in 0..self.bodies.len() {
            let x = self.rhs_b[i];
            let rb = &mut physics.bodies[self.bodies[i]];
            self.saved[i] = (rb.gravity_scale(), rb.user_force(), rb.user_torque());
            rb.set_gravity_scale(0.0, false);
            rb.reset_forces(false);
            rb.reset_torques(false);
            rb.set_linvel(Vector::new(x[0], x[1], x[2]), false);
            let w = Vector::new(x[3], x[4], x[5]);
            let w = if self.second[i] {
                w * rotation_scale(w, h)
            } else {
                w
            };
            rb.set_angvel(w, false);
        }
    }

    /// Reads the bodies back after Rapier's drift (forces restored).
    fn take_from_rapier(&mut self, physics: &mut PhysicsWorld, h: Real) {
        for i in 0..self.bodies.len() {
            let (gs, f, t) = self.saved[i];
            let rb = &mut physics.bodies[self.bodies[i]];
            rb.set_gravity_scale(gs, false);
            rb.add_force(f, false);
            rb.add_torque(t, false);
        }
        self.gather(&physics.bodies, physics.gravity);
        // Second-order bodies were handed `w` scaled so that Rapier's linearised quaternion
        // update (a turn by `2 atan(|w| h / 2)`) turns them by exactly `|w| h`: take the scale
        // back (unless a contact changed the velocity in Rapier's solve).
        if self.second_any {
            for i in 0..self.bodies.len() {
                if !self.second[i] {
                    continue;
                }
                let x = self.rhs_b[i];
                let w = Vector::new(x[3], x[4], x[5]);
                let scale = rotation_scale(w, h);
                let s = &mut self.st[i];
                s.angvel = if s.angvel == w * scale {
                    w
                } else {
                    s.angvel / scale
                };
            }
        }
    }

    /// Some body of the island has an active contact (its own colliders' pairs only: no pass
    /// over every pair of the world per island).
    fn touches(&self, sets: &Sets) -> bool {
        let physics = &*sets.physics;
        self.bodies.iter().any(|b| {
            physics.bodies[*b].colliders().iter().any(|c| {
                physics
                    .contact_pairs_with(*c)
                    .any(|p| p.has_any_active_contact())
            })
        })
    }

    /// The island's mechanical energy now: kinetic, the potential of the constant forces
    /// (gravity, user forces), the joint springs at their last evaluation and the spring
    /// elements (J).
    fn island_energy(&self, fx: &Effects, sets: &Sets) -> Real {
        self.body_energy()
            + fx.spring_energy(&self.members)
            + self.spring_element_energy(sets.springs, &sets.physics.bodies)
    }

    /// The contacts' work in a substep where one acted (a contact pair of an island body has an
    /// active contact after Rapier's call): the island's energy change over the
    /// substep less what the substep booked (loads, drives, dampers, friction, locks). Rapier
    /// does not expose its contact impulses in a form whose work can be taken exactly (anchors
    /// frozen between narrow-phase updates, twist and warm-start shares), so the contact
    /// substep's residual is booked as the contact's work: it holds the integrator's own error
    /// of that substep too; elsewhere the balance measures the integrator alone.
    fn book_contacts(&mut self, fx: &Effects, sets: &Sets) {
        let Some(e0) = self.contact_energy.take() else {
            return;
        };
        if !self.touches(sets) {
            return;
        }
        let e1 = self.island_energy(fx, sets);
        self.ledger.work += e1 - e0 - (self.ledger.work - self.ledger.dissipated);
    }

    /// RATTLE's second half kick (the forces at `q_(n+1)`) on the bodies' velocities, where
    /// the velocity projection after it is left to the next substep (isotropic bodies: no
    /// gyroscopic term).
    pub(super) fn half_kick(&mut self, h: Real) {
        let hh = 0.5 * h;
        for (s, &second) in self.st.iter_mut().zip(&self.second) {
            if second {
                s.linvel += s.force * (hh / s.mass);
                s.angvel += s.inertia_inv * s.torque * hh;
            }
        }
    }

    /// Stage 4, first half: the momenta at `q_(n+1)` into `rhs_b`, with RATTLE's second half
    /// kick (the forces at `q_(n+1)`) on second-order bodies.
    pub(super) fn end_momenta(&mut self, h: Real) {
        for i in 0..self.bodies.len() {
            let s = &self.st[i];
            let (v, w) = if self.second[i] {
                // The second half kick of RATTLE, with the forces at q_(n+1).
                let hh = 0.5 * h;
                let w = if self.drifts_as_rotor(i) {
                    s.angvel
                } else {
                    gyroscopic_kick(s, s.angvel, hh)
                };
                (
                    s.linvel + s.force * (hh / s.mass),
                    w + s.inertia_inv * s.torque * hh,
                )
            } else {
                (s.linvel, s.angvel)
            };
            let mv = v * s.mass;
            let mw = s.inertia * w + w * s.added;
            self.rhs_b[i] = [mv.x, mv.y, mv.z, mw.x, mw.y, mw.z];
        }
    }

    /// Stage 4, second half: the velocity projection `J v = rate` at `q_(n+1)`; with `refine`
    /// (the last substep of a step), refined until the hard rows hold to
    /// [`velocity_tolerance`].
    ///
    /// The factorisation carries the hard rows' relative regularisation (`REGULARISATION_LOOPS`
    /// or `REGULARISATION_TREE` times each row's own effective inverse mass), so one solve
    /// leaves `J v - rate = c lambda`. Relative to the row's diagonal that is 1e-8 (1e-10 in a
    /// tree; the figures below are from before trees took it), but a row's diagonal can be far
    /// larger than the system's stiffness in the direction it constrains: the bob of the A01
    /// pendulum (1 kg, 1e-4 kg m^2, 1 m from the pin) has `1/m + L^2/I = 1e4` on a pin row,
    /// against `1/m = 1` along the rod, so the projection left the bob a radial velocity of
    /// 1e-4 of the impulse it took. That is an `O(h)` velocity error, invisible in the
    /// positions (each substep's position projection lands on the constraints anyway) but in
    /// every velocity output and in the adaptive control's velocity differences (measured: a
    /// step at `n` and at `2 n` substeps, RATTLE, bob inertia 1e-6 kg m^2: the velocities
    /// differed by `5.8e-4 m/s / n` instead of `O(1 / n^2)`; with the regularisation at 1e-14
    /// the radial velocity fell from 2e-6 to 2e-12 m/s). Each refinement solves the same
    /// factorisation for the hard rows' residual (iterative refinement towards the
    /// unregularised projection); penalty rows are springs whose compliance is physical, not
    /// a regularisation, and take no residual. It stops at the tolerance, after
    /// [`MAX_VELOCITY_REFINEMENTS`], or when a refinement does not halve the residual (rows
    /// dependent at a singular pose, where the regularisation is what bounds the multipliers).
    ///
    /// Only the step's last substep refines: its velocities are the ones the outputs, the
    /// energy and the next step see. Within a step the residual is moot: the next substep's
    /// position projection lands on the constraints whatever the velocity's component along
    /// them (the positions converged at orders 2.00 and 4.0 with the residual left in every
    /// substep), and refining every substep cost 10 % of the mixed scene's step.
    pub(super) fn project_velocities(&mut self, time: Real, refine: bool) -> Result<(), Error> {
        if self.kkt.is_none() {
            return Ok(());
        }
        self.velocity_rhs();
        self.solve_rhs(time)?;
        self.take_velocity_solve(false);
        let mut previous = Real::INFINITY;
        for _ in 0..if refine { MAX_VELOCITY_REFINEMENTS } else { 0 } {
            if !self.refinement_rhs(&mut previous) {
                break;
            }
            self.solve_rhs(time)?;
            self.take_velocity_solve(true);
        }
        Ok(())
    }

    /// The velocity projection's right-hand side (the momenta in `rhs_b` from
    /// [`Island::end_momenta`]): each hard row's prescribed rate, a penalty row's own.
    #[inline(always)]
    pub(super) fn velocity_rhs(&mut self) {
        let Some(kkt) = self.kkt.as_ref() else {
            return;
        };
        // A penalty row is a spring, not a velocity constraint: the implicit velocity solve
        // above already gave it the force k times its end-of-substep deflection. Here it
        // keeps its current rate (target = its own J v, so with compliance 1 / (k h^2) it
        // takes almost no impulse), otherwise the projection would add a stiffening impulse
        // that the deflection does not show (measured: gap * k was 0.67 of the reported
        // force on the 90 deg pendulum).
        if self.penalty.iter().any(|&p| p) {
            row_rates(kkt, &self.jac, &self.st, &mut self.rhs_j);
        }
        for r in 0..self.rhs_j.len() {
            if !self.penalty[r] {
                self.rhs_j[r] = self.rate[r] - self.kin[r];
            }
        }
    }

    /// A refinement's right-hand side: the hard rows' residual rates, the bodies' zero. Returns
    /// whether to take it: not when the residual is within [`velocity_tolerance`], NaN, or not
    /// halved since the last (`previous`, updated).
    #[inline(always)]
    pub(super) fn refinement_rhs(&mut self, previous: &mut Real) -> bool {
        let Some(kkt) = self.kkt.as_ref() else {
            return false;
        };
        row_rates(kkt, &self.jac, &self.st, &mut self.rhs_j);
        let mut worst: Real = 0.0;
        for r in 0..self.rhs_j.len() {
            self.rhs_j[r] = if self.penalty[r] {
                0.0
            } else {
                self.rate[r] - self.kin[r] - self.rhs_j[r]
            };
            worst = worst.max(self.rhs_j[r].abs());
        }
        if worst <= velocity_tolerance() || worst.is_nan() || worst > 0.5 * *previous {
            return false;
        }
        *previous = worst;
        for b in self.rhs_b.iter_mut() {
            *b = [0.0; 6];
        }
        true
    }

    /// Solves `rhs_b`, `rhs_j` in place on the island's factorisation.
    pub(super) fn solve_rhs(&mut self, time: Real) -> Result<(), Error> {
        let Some(kkt) = self.kkt.as_ref() else {
            return Ok(());
        };
        kkt.solve(&mut self.rhs_b, &mut self.rhs_j)
            .map_err(|e| kkt_err(e, time))
    }

    /// Books a velocity projection's multipliers (`rhs_j`) into the impulses and takes its
    /// velocities (`rhs_b`) as the bodies', or adds them (`add`: a refinement's correction).
    pub(super) fn take_velocity_solve(&mut self, add: bool) {
        if !add {
            self.vp_carry.fill(0.0);
        }
        for ((impulse, carry), l) in self
            .impulse
            .iter_mut()
            .zip(&mut self.vp_carry)
            .zip(&self.rhs_j)
        {
            *impulse -= l;
            *carry -= l;
        }
        for (s, x) in self.st.iter_mut().zip(&self.rhs_b) {
            let (v, w) = (Vector::new(x[0], x[1], x[2]), Vector::new(x[3], x[4], x[5]));
            if add {
                s.linvel += v;
                s.angvel += w;
            } else {
                s.linvel = v;
                s.angvel = w;
            }
        }
    }

    /// Writes poses and velocities back to Rapier (a non-finite state is a divergence).
    pub(super) fn write_back(
        &mut self,
        physics: &mut PhysicsWorld,
        time: Real,
    ) -> Result<(), Error> {
        for i in 0..self.bodies.len() {
            let b = self.bodies[i];
            let s = self.st[i];
            if !(s.pose.translation.is_finite() && s.linvel.is_finite() && s.angvel.is_finite()) {
                return Err(Error::Diverged {
                    time,
                    joint: None,
                    reason: format!(
                        "body {:?}: non-finite state in the constraint solve",
                        b.into_raw_parts()
                    ),
                });
            }
            let rb = &mut physics.bodies[b];
            rb.set_position(s.pose, false);
            rb.set_linvel(s.linvel, false);
            rb.set_angvel(s.angvel, false);
            self.written[i] = (s.pose, s.linvel, s.angvel);
        }
        Ok(())
    }
}

/// Each row's rate `J v` at the bodies' current velocities into `out` (one real per row).
fn row_rates(kkt: &KktSolver, jac: &[Real], st: &[BodyState], out: &mut [Real]) {
    for (k, spec) in kkt.joint_specs().iter().enumerate() {
        let r0 = kkt.row_offset(k);
        // Each side's velocities, read once per joint (the body states are large).
        let sides = spec.bodies.map(|b| {
            b.map(|i| {
                let (v, w) = (st[i].linvel, st[i].angvel);
                [v.x, v.y, v.z, w.x, w.y, w.z]
            })
        });
        let rows = &jac[JAC_ROW_STRIDE * r0..JAC_ROW_STRIDE * (r0 + spec.rows)];
        for (rate, jr) in out[r0..r0 + spec.rows]
            .iter_mut()
            .zip(rows.chunks_exact(JAC_ROW_STRIDE))
        {
            let mut jv = 0.0;
            // An absent side's entries may hold anything (see the KKT arena's docs).
            for (half, v) in jr.chunks_exact(6).zip(&sides) {
                if let Some(v) = v {
                    for (a, b) in half.iter().zip(v) {
                        jv += a * b;
                    }
                }
            }
            *rate = jv;
        }
    }
}
