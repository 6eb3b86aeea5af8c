//! The position projection of a substep: chord iterations on the start-of-substep
//! factorisation (along the directions `M~^-1 J_n^T`), warm-started from the previous substep's
//! multipliers, continued as damped Gauss-Newton where a chord step fails (near a singular
//! pose); the correction divided by `h` is fed into the velocity.

use crate::error::Error;
use crate::joint_set::JointSet;
use crate::math::rapier::dynamics::{RigidBodyHandle, RigidBodySet};
use crate::math::rapier::pipeline::PhysicsWorld;
use crate::math::{Matrix, Real, Vector};
use crate::rows::RowKind;
use crate::solver::kkt::JAC_ROW_STRIDE;

use super::assemble::Eval;
use super::substep::SUZUKI;
use super::{
    BACKTRACKS, CHORD_MARGIN, Island, MAX_PROJECTION_ITERATIONS, MU_HISTORY, REGULARISATION_LOOPS,
    SMOOTH, STAGES, WARM_AXES_TOLERANCE, WARM_START_LIMIT, WarmAxes, Warning, angular_block,
    displace, displace_all, projection_tolerance,
};

/// A position projection between its steps (see [`Island::project_positions`]): its
/// tolerances and the iteration's state.
pub(super) struct Projection {
    nominal: Real,
    tol: Real,
    far: Real,
    residual: Real,
    iterations: usize,
    jac_behind: bool,
    /// The largest contraction of the residual per chord step seen in this projection.
    rate: Real,
    predicted: bool,
    previous: Real,
    newton: bool,
    backtracks: usize,
    it: usize,
}

impl Projection {
    /// A step was taken: the residual it started from is the one to beat.
    pub(super) fn stepped(&mut self) {
        self.previous = self.residual;
        self.it += 1;
    }
}

impl Island {
    /// The free drift's velocity (see [`Island::free_drift`]): the position multipliers
    /// extrapolated from the last substeps ([`Island::extrapolate_multipliers`]) act as the
    /// impulse `M~^-1 J^T mu / h` on the kicked velocities in `rhs_b` before the drift.
    ///
    /// The history holds each substep's whole multiplier as it would have been from the
    /// velocities before the last velocity projection: the projection's multipliers plus `h`
    /// times that velocity projection's impulse (`vp_carry`, zero where the substep before
    /// left its projection to this one). A projection is linear along the same directions,
    /// so the history runs smoothly across the substeps that project their velocities and
    /// those that do not (the first-order step projects in a step's last two substeps only).
    /// The carry of the substep before is taken off the extrapolation.
    ///
    /// Tried first: the extrapolated multipliers as a displacement after the drift (SHAKE's
    /// own warm start). That displacement is about `h^2 g`, and along the start-of-substep
    /// directions it leaves the rows' curvature: 2.4e-8 to 6.4e-8 m on one arm of the mixed
    /// scene (first order, 1/60 s x 4), alternating from substep to substep, where the
    /// velocity solve's warm start leaves about 2e-10 m; as an impulse before the drift,
    /// 2.3e-9 to 2.8e-9 m. The mixed scene then took 1.68 chord steps per substep instead of
    /// 0.98 (+10 % instructions).
    pub(super) fn predict_impulse(&mut self, h: Real) {
        self.impulse.fill(0.0);
        if self.mu.iter().all(|m| *m == 0.0) {
            return;
        }
        self.turn_warm_axes(true);
        self.extrapolate_multipliers();
        self.turn_warm_axes(false);
        self.carry_into_mu(-h);
        let Some(kkt) = self.kkt.as_ref() else { return };
        for (b, s) in self.backup.iter_mut().zip(&self.st) {
            *b = (s.pose, s.com);
        }
        for (impulse, &m) in self.impulse.iter_mut().zip(&self.mu) {
            *impulse = m / h;
        }
        jt_mu(kkt, &self.jac, &self.mu, &mut self.shift);
        self.shift_velocities(h, 1.0);
    }

    /// Adds `h` times the last velocity projection's impulse (`vp_carry`) to `mu`: the
    /// history's form of a free drift's multipliers (see [`Island::predict_impulse`]), and
    /// with `-h` back.
    fn carry_into_mu(&mut self, h: Real) {
        for (m, c) in self.mu.iter_mut().zip(&self.vp_carry) {
            *m += h * c;
        }
    }

    /// Adds `sign M~^-1 shift / h` to the velocities in `rhs_b` (the factorisation's mass, as
    /// the velocity solve's), and empties `shift`.
    fn shift_velocities(&mut self, h: Real, sign: Real) {
        for i in 0..self.st.len() {
            let g = core::mem::take(&mut self.shift[i]);
            let ang = angular_block(&self.mass[i]).inverse();
            let dv = Vector::new(g[0], g[1], g[2]) * (sign / (self.st[i].mass * h));
            let dw = ang * Vector::new(g[3], g[4], g[5]) * (sign / h);
            let x = &mut self.rhs_b[i];
            for (acc, d) in x.iter_mut().zip([dv.x, dv.y, dv.z, dw.x, dw.y, dw.z]) {
                *acc += d;
            }
        }
    }

    /// A free drift's start of the projection (see [`Island::predict_impulse`]): the rows'
    /// values after the drift, and where they leave a gross violation, the drift again without
    /// the predicted impulse.
    fn check_predicted(&mut self, joints: &JointSet, bodies: &RigidBodySet, h: Real) {
        let after = self.residual(joints, bodies, h);
        if (after.is_finite() && after <= WARM_START_LIMIT) || self.mu.iter().all(|m| *m == 0.0) {
            return;
        }
        let Some(kkt) = self.kkt.as_ref() else { return };
        jt_mu(kkt, &self.jac, &self.mu, &mut self.shift);
        self.shift_velocities(h, -1.0);
        for (s, b) in self.st.iter_mut().zip(&self.backup) {
            (s.pose, s.com) = *b;
            s.refresh_inertia();
        }
        self.drift(h);
        self.mu.fill(0.0);
        self.impulse.fill(0.0);
        self.fresh_values = false;
    }

    /// Projects the bodies onto the position constraints (see the module docs) and feeds the
    /// correction into the velocity.
    pub(super) fn project_positions(
        &mut self,
        joints: &JointSet,
        bodies: &RigidBodySet,
        h: Real,
        time: Real,
    ) -> Result<(), Error> {
        let mut p = self.begin_projection(joints, bodies, h);
        while self.projection_round(&mut p, joints, bodies, h, time)? {
            self.projection_step(h, time)?;
            p.stepped();
        }
        self.end_projection(&p, joints, bodies, h, time);
        Ok(())
    }

    /// A position projection's start: its tolerances and the warm start.
    #[inline(always)]
    pub(super) fn begin_projection(
        &mut self,
        joints: &JointSet,
        bodies: &RigidBodySet,
        h: Real,
    ) -> Projection {
        let nominal = projection_tolerance();
        let tol = if self.warm_axes.as_ref().is_some_and(|w| !w.is_empty()) {
            WARM_AXES_TOLERANCE * nominal
        } else {
            nominal
        };
        for s in self.shift.iter_mut() {
            *s = [0.0; 6];
        }
        self.warm_start(joints, bodies, h);
        Projection {
            nominal,
            tol,
            // Where the residual is this far above the tolerance, a slow or failed step is the
            // constraints' curvature over a long step, which a refactorisation or a shorter
            // step mends; near the tolerance it is round-off on ill-conditioned rows (a spin of
            // tiny inertia), where they only move the result (see `BACKTRACKS`).
            far: 1e3 * nominal,
            residual: 0.0,
            iterations: 0,
            // Whether the Jacobian arena is behind the bodies: the warm start evaluated the
            // rows' values alone (see `Island::residual`), and so does a chord iteration that
            // expects another step to follow. Only the Jacobian at `q_(n+1)` is read (the chord
            // steps take their directions from the factorisation), so it is evaluated where
            // the projection stops.
            jac_behind: self.fresh_values,
            rate: 0.0,
            // A stage's own extrapolation (see `Island::extrapolate_multipliers`) takes at
            // least one chord step, and converges to the warm axes' tolerance where it starts
            // within `far` of the tolerance.
            predicted: !self.stage_pred.is_empty(),
            previous: Real::INFINITY,
            newton: false,
            backtracks: 0,
            it: 0,
        }
    }

    /// The projection's iterations up to its next step: `true` when a step is to be taken
    /// (its right-hand side in `rhs_j`; the caller solves it, [`Island::apply_projection_step`]
    /// and [`Projection::stepped`]), `false` when the projection is done.
    ///
    /// Chord iterations on the start-of-substep factorisation. Should one increase the residual
    /// (near a singular pose, where the start-of-substep directions lose rank), it is undone
    /// and the projection continues as damped Gauss-Newton: refactorised at the current
    /// configuration, each step halved while it raises the residual far from the tolerance (up
    /// to `BACKTRACKS` times), and otherwise undone with a regularisation raised tenfold. Far
    /// from the tolerance, the chord iteration also hands over to Gauss-Newton where it
    /// converges too slowly to reach the tolerance within the iteration limit at its last rate.
    #[inline(always)]
    pub(super) fn projection_round(
        &mut self,
        p: &mut Projection,
        joints: &JointSet,
        bodies: &RigidBodySet,
        h: Real,
        time: Real,
    ) -> Result<bool, Error> {
        while p.it <= MAX_PROJECTION_ITERATIONS {
            let it = p.it;
            // The rows at the iterate: with the Jacobian, unless the step to it is expected to
            // have left the residual far above the tolerance (at the contraction of the last
            // projection's slowest chord step), so that another step follows and this
            // Jacobian would not be read (see `Projection::jac_behind`).
            if !core::mem::take(&mut self.fresh_values) {
                p.jac_behind = !p.newton
                    && p.previous.is_finite()
                    && p.previous * self.chord_rate > CHORD_MARGIN * p.tol;
                let what = if p.jac_behind {
                    Eval::Values
                } else {
                    Eval::Geometry
                };
                self.eval_rows(joints, bodies, what);
            }
            p.residual = self.projection_targets(h);
            if !p.newton && p.previous.is_finite() && p.residual < p.previous {
                p.rate = p.rate.max(p.residual / p.previous);
            }
            if it == 0 && p.predicted && p.residual <= p.far {
                p.tol = p.tol.min(WARM_AXES_TOLERANCE * p.nominal);
            }
            if (p.residual <= p.tol && (it > 0 || !p.predicted)) || it == MAX_PROJECTION_ITERATIONS
            {
                if p.jac_behind {
                    self.eval_rows(joints, bodies, Eval::Geometry);
                }
                p.iterations = it;
                return Ok(false);
            }
            if p.residual > p.previous || !p.residual.is_finite() {
                p.it += 1;
                if p.newton && p.backtracks < BACKTRACKS && p.previous > p.far {
                    p.backtracks += 1;
                    self.scale_projection_step(h, 0.5);
                    continue;
                }
                p.backtracks = 0;
                self.undo_projection_step(h, p.newton);
                p.newton = true;
                p.previous = Real::INFINITY;
                continue;
            }
            p.newton = p.newton
                || (it >= 2
                    && p.residual > p.far
                    && chord_too_slow(p.residual, p.previous, p.tol, it));
            if p.newton {
                self.rows(joints, bodies, h, true);
                self.factor(joints, bodies, h, time)?;
            }
            p.backtracks = 0;
            return Ok(true);
        }
        // The last iteration returns above.
        Ok(false)
    }

    /// The projection's end: its report, the correction fed into the velocity, the rows'
    /// terms at `q_(n+1)`.
    #[inline(always)]
    pub(super) fn end_projection(
        &mut self,
        p: &Projection,
        joints: &JointSet,
        bodies: &RigidBodySet,
        h: Real,
        time: Real,
    ) {
        let (residual, iterations) = (p.residual, p.iterations);
        self.reg_scale = 1.0;
        if p.rate > 0.0 {
            self.chord_rate = p.rate;
        }
        if self.free_h > 0.0 {
            self.free_measure(iterations);
            self.carry_into_mu(self.free_h);
        }
        self.report.projection_iterations = iterations;
        if p.newton || iterations == MAX_PROJECTION_ITERATIONS {
            self.report.projection_fallbacks += 1;
        }
        self.report.projection_residual = self.report.projection_residual.max(residual);
        if residual > p.far {
            self.warn(
                Warning::Projection,
                format!(
                    "t = {time}: position projection stopped at residual {residual:.3e} after \
                     {iterations} iterations"
                ),
            );
        }
        self.feed_correction(h);
        // The rows' values and Jacobian are those at `q_(n+1)` now; their compliances with the
        // inertia there.
        self.constraint_terms(joints, bodies, h);
        self.record_warm_axes(joints, bodies);
    }

    /// Feeds the projection's correction into the velocity (constrained symplectic Euler). A
    /// free rotor (see `Island::drift`) takes it into its angular momentum: the correction's
    /// impulse `M~ d / h` (the factorisation's mass, `d = M~^-1 J^T mu`), and `w = I^-1 L` at
    /// the projected pose.
    fn feed_correction(&mut self, h: Real) {
        for i in 0..self.st.len() {
            let d = self.shift[i];
            let dth = Vector::new(d[3], d[4], d[5]);
            let rotor = self.drifts_as_rotor(i);
            let m = &self.mass[i];
            let s = &mut self.st[i];
            s.linvel += Vector::new(d[0], d[1], d[2]) / h;
            if rotor {
                let momentum = s.inertia * s.angvel + angular_block(m) * dth / h;
                s.refresh_inertia();
                s.angvel = s.inertia_inv * momentum;
            } else {
                s.angvel += dth / h;
                s.refresh_inertia();
            }
        }
    }

    /// Records frame 2's axes relative to frame 1's at the state now (the substep's end) for
    /// the joints whose warm start extrapolates in them, listed at the island's first
    /// projection: every joint of a tree island without penalty rows (the others do not
    /// extrapolate at every substep, see [`Island::extrapolate_multipliers`]) where each joint
    /// has three linear rows (along frame 1's axes) and a rotation constrained by some angular
    /// row.
    fn record_warm_axes(&mut self, joints: &JointSet, bodies: &RigidBodySet) {
        // Not where bodies take added inertia, from the first such substep on (the history,
        // in mixed axes then, starts again): there it saved no chord step (1:1000 chain of 100
        // links at 1/60 s x 4: 7.96 -> 7.86 per step; 1:1 chain of 1000 links: 8.0 both) and
        // cost the bookkeeping (+1.5 % and +1.9 % instructions per step). The island's rows
        // change only with a rebuild (a new island): the list is made once.
        let stiff = self.report.stiffened_bodies > 0 || self.would_stiffen;
        if stiff && self.warm_axes.as_ref().is_some_and(|w| !w.is_empty()) {
            self.warm_axes = Some(Vec::new());
            self.mu_depth = 0;
            return;
        }
        let fresh = self.warm_axes.is_none();
        if fresh {
            let Some(kkt) = self.kkt.as_ref() else { return };
            let plain =
                self.regularisation < REGULARISATION_LOOPS && self.kpen.iter().all(|k| *k == 0.0);
            // Only where every joint takes it: the tighter tolerance costs every joint of the
            // island chord steps, and a joint left in frame 1's axes keeps the warm start's
            // error (the mixed scene, whose arms also hold spherical, cylindrical and
            // translational joints: 1.71 -> 2.28 chord steps per substep, +10 % instructions).
            let listed: Option<Vec<WarmAxes>> = self
                .blocks
                .iter()
                .enumerate()
                .map(|(k, &j)| {
                    let e = joints.get(j).filter(|_| plain)?;
                    let r0 = kkt.row_offset(k);
                    let mut rows = [usize::MAX; 3];
                    let mut angular = false;
                    for (n, row) in e.state.rows.iter().enumerate() {
                        match row {
                            RowKind::Linear { axis } => rows[*axis] = r0 + n,
                            RowKind::Angular { .. } => angular = true,
                            _ => {}
                        }
                    }
                    let [s1, s2] = kkt.joint_specs()[k].bodies;
                    (angular && !rows.contains(&usize::MAX)).then_some(WarmAxes {
                        rows,
                        sides: [(s1, e.body1), (s2, e.body2)],
                        frames: [e.low[0].rotation.inverse(), e.low[1].rotation],
                        turn: [Matrix::IDENTITY; 2],
                    })
                })
                .collect();
            self.warm_axes = Some(listed.unwrap_or_default());
        }
        let Some(listed) = self.warm_axes.as_mut() else {
            return;
        };
        let st = &self.st;
        let rot = |(slot, b): (Option<usize>, RigidBodyHandle)| match slot {
            Some(i) => st[i].pose.rotation,
            None => bodies[b].position().rotation,
        };
        for w in listed.iter_mut() {
            let q = w.frames[0] * rot(w.sides[0]).inverse() * rot(w.sides[1]) * w.frames[1];
            let now = Matrix::from_quat(q);
            w.turn = [if fresh { now } else { w.turn[1] }, now];
        }
    }

    /// Turns each listed joint's three linear-row multipliers from frame 1's axes into frame
    /// 2's (`into_frame2`, with the turn before the last substep) or back (with the turn after
    /// it).
    fn turn_warm_axes(&mut self, into_frame2: bool) {
        let Some(listed) = self.warm_axes.as_ref() else {
            return;
        };
        let mu = &mut self.mu[..];
        for w in listed {
            let [x, y, z] = w.rows;
            let m = Vector::new(mu[x], mu[y], mu[z]);
            let v = if into_frame2 {
                w.turn[0].transpose() * m
            } else {
                w.turn[1] * m
            };
            (mu[x], mu[y], mu[z]) = (v.x, v.y, v.z);
        }
    }

    /// Each row's deviation from its projection target into `rhs_j` (negated); returns the
    /// largest. Lagrange rows are projected onto `C = 0`, penalty rows onto their elastic
    /// deflection `C = -f / k` under the row force `f` of this substep so far (velocity solve
    /// plus projection: the KKT compliance `1 / (k h^2)` is exactly the derivative of that
    /// target, so the chord iteration stays consistent).
    fn projection_targets(&mut self, h: Real) -> Real {
        let mut residual: Real = 0.0;
        for r in 0..self.value.len() {
            let dev = if self.kpen[r] > 0.0 {
                self.value[r] + self.impulse[r] / (h * self.kpen[r])
            } else {
                self.value[r]
            };
            residual = Real::max(residual, dev.abs());
            self.rhs_j[r] = -dev;
        }
        residual
    }

    /// One chord step: solves for the correction of the current deviation and displaces the
    /// bodies, remembering the step so that it can be undone.
    fn projection_step(&mut self, h: Real, time: Real) -> Result<(), Error> {
        self.clear_projection_rhs();
        self.solve_rhs(time)?;
        self.apply_projection_step(h);
        Ok(())
    }

    /// A projection step's body right-hand side: zero (the displacement solves
    /// `[M~ Jᵀ; J -C] (d, mu) = (0, -C(q))`).
    pub(super) fn clear_projection_rhs(&mut self) {
        for b in self.rhs_b.iter_mut() {
            *b = [0.0; 6];
        }
    }

    /// A projection step's solution ([`Island::solve_rhs`]: the displacement in `rhs_b`, the
    /// multipliers in `rhs_j`) applied: the bodies
    /// displaced, the multipliers booked, the step kept to be undone.
    #[inline(always)]
    pub(super) fn apply_projection_step(&mut self, h: Real) {
        if self.kkt.is_none() {
            return;
        }
        for (b, s) in self.backup.iter_mut().zip(&self.st) {
            *b = (s.pose, s.com);
        }
        self.last_lambda.copy_from_slice(&self.rhs_j);
        for ((impulse, mu), &l) in self.impulse.iter_mut().zip(&mut self.mu).zip(&self.rhs_j) {
            *impulse -= l / h;
            *mu -= l;
        }
        let n = self.bodies.len();
        displace_all(&mut self.st[..n], &self.rhs_b[..n]);
        for ((last, shift), &x) in self
            .last_x
            .iter_mut()
            .zip(&mut self.shift)
            .zip(&self.rhs_b[..n])
        {
            *last = x;
            for (acc, d) in shift.iter_mut().zip(x) {
                *acc += d;
            }
        }
    }

    /// Scales the last step by `f`: a Gauss-Newton step's backtracking, and with 0 its undoing.
    fn scale_projection_step(&mut self, h: Real, f: Real) {
        for (s, b) in self.st.iter_mut().zip(&self.backup) {
            (s.pose, s.com) = *b;
        }
        for r in 0..self.impulse.len() {
            let l = self.last_lambda[r];
            self.impulse[r] += l * (1.0 - f) / h;
            self.mu[r] += l * (1.0 - f);
            self.last_lambda[r] = l * f;
        }
        for i in 0..self.bodies.len() {
            let mut x = self.last_x[i];
            for (acc, d) in self.shift[i].iter_mut().zip(x.iter_mut()) {
                *acc -= *d * (1.0 - f);
                *d *= f;
            }
            self.last_x[i] = x;
            if f != 0.0 {
                let s = &mut self.st[i];
                displace(
                    s,
                    Vector::new(x[0], x[1], x[2]),
                    Vector::new(x[3], x[4], x[5]),
                );
            }
        }
    }

    /// Undoes the last chord step, and raises the regularisation for the Gauss-Newton steps
    /// that follow (tenfold at every further failure).
    fn undo_projection_step(&mut self, h: Real, newton: bool) {
        self.scale_projection_step(h, 0.0);
        self.reg_scale = if newton { self.reg_scale * 10.0 } else { 1.0 };
    }

    /// Starts the projection from the previous substep's position multipliers: the drift of
    /// successive substeps is nearly the same (O(h^2) centripetal terms), so the chord iteration
    /// then starts close to its solution (a long chain needs 3 iterations instead of 10-16).
    ///
    /// Skipped where the constraints are redundant (the multipliers of dependent rows are set by
    /// the regularisation and need not cancel under the new Jacobian), and undone if it leaves a
    /// gross constraint violation.
    fn warm_start(&mut self, joints: &JointSet, bodies: &RigidBodySet, h: Real) {
        if self.free_h > 0.0 {
            self.check_predicted(joints, bodies, h);
            return;
        }
        if self.redundant || self.mu.iter().all(|m| *m == 0.0) {
            self.mu.iter_mut().for_each(|m| *m = 0.0);
            return;
        }
        self.turn_warm_axes(true);
        self.extrapolate_multipliers();
        self.turn_warm_axes(false);
        let Some(kkt) = self.kkt.as_ref() else { return };
        for (b, s) in self.backup.iter_mut().zip(&self.st) {
            *b = (s.pose, s.com);
        }
        jt_mu(kkt, &self.jac, &self.mu, &mut self.rhs_b);
        for (impulse, &m) in self.impulse.iter_mut().zip(&self.mu) {
            *impulse += m / h;
        }
        let n = self.st.len();
        let sides = self.rhs_b.iter().zip(&self.mass).zip(&self.st);
        for (shift, ((g, m), s)) in self.shift[..n].iter_mut().zip(sides) {
            // Along the chord steps' directions `M~^-1 J^T`, with the factorisation's mass (at
            // the substep's start): the bodies' own inertia has turned with the drift, and a
            // displacement along it feeds an `O(h^2)` error into the velocities every substep
            // (measured: RATTLE first order on a tumbling heavy top, its velocity error halving
            // with the substep; the first substep, not warm-started, was third order locally).
            let ang = angular_block(m).inverse();
            let dx = Vector::new(g[0], g[1], g[2]) / s.mass;
            let dth = ang * Vector::new(g[3], g[4], g[5]);
            *shift = [dx.x, dx.y, dx.z, dth.x, dth.y, dth.z];
        }
        displace_all(&mut self.st, &self.shift[..n]);
        // The warm-started point may have a larger residual than the plain start and still be
        // closer to the solution along the directions the chord iteration converges slowly in
        // (measured on the 1000-link chain: residual 3e-7 -> 5e-5, then 2 iterations instead
        // of 10); only a gross violation means the previous multipliers do not fit.
        let after = self.residual(joints, bodies, h);
        if !after.is_finite() || after > WARM_START_LIMIT {
            self.fresh_values = false;
            for (s, b) in self.st.iter_mut().zip(&self.backup) {
                (s.pose, s.com) = *b;
            }
            for r in 0..self.mu.len() {
                self.impulse[r] -= self.mu[r] / h;
                self.mu[r] = 0.0;
            }
            self.shift.iter_mut().for_each(|x| *x = [0.0; 6]);
        }
    }

    /// The warm start's multipliers: polynomial extrapolation from the last substeps (they vary
    /// smoothly with time), up to quartic from the last five (see `MU_HISTORY`; measured on the
    /// mixed scene with the cubic: the residual the chord iteration starts from fell from
    /// 3.4e-7 to 1.7e-9 against linear extrapolation, and the chord steps per substep from 2.3
    /// to 1.14), except where they do not vary smoothly: on penalty rows (their projection
    /// target moves with their own impulse: the k = 1e10 pendulum's gap * k moved by 1 %),
    /// where the run starts again.
    ///
    /// A composed island's stages differ in size (and their multipliers with it, as the square
    /// of the stage), so from one stage to the next the sequence is not smooth. On a tree, each
    /// stage extrapolates from its own multipliers at the substeps before
    /// ([`Island::record_stage`]): the quadratic through its last three, where their
    /// differences fall, plus the deviation of the stage just projected from its own quadratic
    /// (scaled by the squared ratio of the stage sizes: the newest multipliers carry what the
    /// stage histories have not seen yet). Elsewhere (no smooth history, a new substep size, a
    /// loop) it extrapolates linearly from the stage before. Measured (fourth order, 1/60 s,
    /// callgrind instructions per step and six interleaved timed runs): the mixed scene of 20
    /// arms -20 % (timed -11 to -15 %), the 10- and 100-link chains at 1:1 -14 % and -8 %
    /// (timed -13 % and -11 %), the pendulum -8 %; the 1:1000 chain of 100 links +0.9 % at 8
    /// substeps and +4.8 % at 1/30 s x 8 (timed -6 % at 1/60 s), where its light beads ring at
    /// some 5e3 rad/s, faster than a stage. Not on loops: there the warm start moves where a
    /// projection near a singular pose lands (its chord iteration stops early or falls back to
    /// Gauss-Newton), and the adaptive slider-crank of `tests/adaptive_divergence.rs` asked
    /// 1e-2 m ended 5.6e-2 m off instead of 2.4e-5 m, in the same 1081 substeps (2.2e-2
    /// against 3.2e-4 m while the fallback to RATTLE read the last stage alone).
    ///
    /// Such a warm start takes one chord step at least, and where it leaves the rows within
    /// 1e3 times the tolerance it converges to a tenth of it (as the warm axes do,
    /// [`WARM_AXES_TOLERANCE`](super::WARM_AXES_TOLERANCE)). With its start this close, the
    /// projection stopped within the tolerance after the warm start or one chord step, and the
    /// residual it left had the same sign from stage to stage. Measured on the conical
    /// pendulum (spherical joint: no warm axes), fourth order over 10 s, error / energy drift:
    ///
    /// | | 1/480 s x 4 | 1/240 s x 4 |
    /// |---|---|---|
    /// | stage to stage (before) | 1.0e-12 m / -3.9e-13 J | 1.3e-11 m / -8.4e-13 J |
    /// | own stage, stopped at the tolerance | 6.0e-11 m / 3.5e-11 J | |
    /// | own stage, one chord step at least | 5.7e-13 m / -3.5e-14 J | 1.2e-10 m / -2.0e-10 J |
    /// | the same, a tenth of the tolerance where the start is close (now) | 5.7e-13 m / -3.5e-14 J | 1.4e-11 m / -2.5e-11 J |
    ///
    /// A tenth of the tolerance everywhere would cost the 1:1000 chain of 100 links at 1/30 s x
    /// 8 +9.9 % instructions: its light beads ring, the warm start leaves some 2e-5 m there (the
    /// beads turn far in a stage) and two chord steps land between the two tolerances. Where the
    /// start is close only: the mixed scene of 20 arms (1/60 s x 4) +1.0 %, the chains and the
    /// pendulum -0.2 to +0.03 %.
    ///
    /// An island with a loop also starts again while it has bodies given added inertia (the
    /// 1:1000 chain needed 5 iterations instead of 2 when trees took the loops'
    /// regularisation). That was the regularisation of 1e-8, whose slow directions the chord
    /// steps could not take out (see `REGULARISATION_TREE`): with the tree's 1e-10 the
    /// extrapolation is as good there as elsewhere (1:1000 chains of 10, 100 and 1000 links at
    /// 1/60 s x 4: 4.58 -> 4.18, 4.28 -> 4.25 and 4.50 -> 4.50 solves per substep; RATTLE at
    /// 1/30 s x 2: 14.6 -> 12.9; never more), so trees extrapolate. Loops keep the rule as it
    /// was, reading the step's report, which starts each step at zero (so their first
    /// substep of a step extrapolates); without it the chart study's slider-crank at 1/30 s
    /// x 2 (RATTLE) diverged at t = 2.8 s where it ran to the end.
    ///
    /// On a tree island without penalty rows whose joints all have three linear rows and some
    /// angular row (revolute, universal, weld; not a spherical joint, whose frame 2 spins with
    /// the child), the linear rows' multipliers are extrapolated in frame 2's axes
    /// ([`Island::turn_warm_axes`]): a joint's force turns with the child body (a pendulum's
    /// rod force, a chain link's tension), and extrapolated in frame 1's the turning vector's
    /// error lands on the stiff directions (the pendulum's point-mass bob). The warm start then
    /// leaves 1.1e-9 m instead of 1e-5 on the pendulum and 8.6e-8 instead of 4e-5 on the
    /// 100-link chain, and the island converges to a tenth of the tolerance
    /// ([`WARM_AXES_TOLERANCE`](super::WARM_AXES_TOLERANCE)). Measured (callgrind, 1/60 s x
    /// 4): chord steps per substep 2.03 -> 1.19 on the pendulum, 2.61 -> 2.08 and 2.54 -> 2.00
    /// on the 10- and 100-link chains at 1:1, instructions per step -10.9 %, -5.8 % and
    /// -5.9 %. Not where bodies take added inertia ([`Island::record_warm_axes`]). Tried first
    /// without that exclusion, its landing was backed out twice for gaps of up to 1.7e-5 m in
    /// the chart study's 1:1000 chain at one coarse substep; the projection left those gaps
    /// with and without this warm start (the runs are chaotic: 1.4e-9 to 1.6e-5 m with the
    /// start angle moved by 0.01 deg), and no longer does (`tests/lagrange_chain_coarse.rs`).
    fn extrapolate_multipliers(&mut self) {
        let tree = self.regularisation < REGULARISATION_LOOPS;
        let smooth =
            (tree || self.report.stiffened_bodies == 0) && self.kpen.iter().all(|k| *k == 0.0);
        let n = self.mu.len();
        let held = &self.mu_history[..self.mu_depth];
        if !smooth || held.iter().any(|h| h.len() != n) {
            self.mu_depth = 0;
        }
        if self.composed {
            if self.record_stage(n) {
                self.extrapolate_stage(n);
                return;
            }
            self.stage_pred.clear();
        }
        // A composed island's stages differ in size (and their multipliers with it): from one
        // stage to the next it extrapolates linearly, where its stage has no smooth history.
        let depth = if self.composed {
            self.mu_depth.min(1)
        } else {
            self.extrapolation_order()
        };
        // The history moves down one place: the front buffer holds the oldest entry now, read
        // before the last substep's multipliers overwrite it.
        self.mu_history.rotate_right(1);
        let [front, a, b, c] = &mut self.mu_history;
        front.resize(n, 0.0);
        // Newton's backward differences through the last `depth + 1` substeps, one loop per
        // depth (zipped: no bounds checks, no branch per row); each row's newest multipliers
        // go to the front, whose oldest entry the quartic reads first.
        let rows = self.mu[..n].iter_mut().zip(front.iter_mut());
        match depth {
            0 => rows.for_each(|(m, f)| *f = *m),
            1 => {
                for ((m, f), &a) in rows.zip(&a[..n]) {
                    let x = *m;
                    *m = 2.0 * x - a;
                    *f = x;
                }
            }
            2 => {
                for (((m, f), &a), &b) in rows.zip(&a[..n]).zip(&b[..n]) {
                    let x = *m;
                    *m = 3.0 * x - 3.0 * a + b;
                    *f = x;
                }
            }
            3 => {
                for ((((m, f), &a), &b), &c) in rows.zip(&a[..n]).zip(&b[..n]).zip(&c[..n]) {
                    let x = *m;
                    *m = 4.0 * x - 6.0 * a + 4.0 * b - c;
                    *f = x;
                }
            }
            _ => {
                for ((((m, f), &a), &b), &c) in rows.zip(&a[..n]).zip(&b[..n]).zip(&c[..n]) {
                    let x = *m;
                    *m = 5.0 * x - 10.0 * a + 10.0 * b - 5.0 * c + *f;
                    *f = x;
                }
            }
        }
        self.mu_depth = (self.mu_depth + 1).min(MU_HISTORY);
    }

    /// A composed stage's warm start from its own history (see
    /// [`Island::extrapolate_multipliers`]): the quadratic through the stage's last three
    /// substeps, plus the last stage's deviation from its own quadratic (the newest
    /// multipliers; scaled to this stage's size, as a position multiplier goes with the square
    /// of the step). The history of the last substeps moves down one place as in
    /// [`Island::extrapolate_multipliers`].
    fn extrapolate_stage(&mut self, n: usize) {
        self.mu_history.rotate_right(1);
        let front = &mut self.mu_history[0];
        front.resize(n, 0.0);
        let carry = self.stage_pred.len() == n;
        self.stage_pred.resize(n, 0.0);
        let (j, _) = self.stage;
        let scale = (SUZUKI[j] / SUZUKI[(j + STAGES - 1) % STAGES]).powi(2);
        let [x, y, z] = &self.stage_mu[j].mu;
        for r in 0..n {
            let m = self.mu[r];
            let quadratic = 3.0 * x[r] - 3.0 * y[r] + z[r];
            let deviation = if carry {
                scale * (m - self.stage_pred[r])
            } else {
                0.0
            };
            self.stage_pred[r] = quadratic;
            self.mu[r] = quadratic + deviation;
            front[r] = m;
        }
        self.mu_depth = (self.mu_depth + 1).min(MU_HISTORY);
    }

    /// A composed tree island's warm start per stage (see [`Island::extrapolate_multipliers`]):
    /// records the last stage's multipliers (`mu`, converged) in that stage's history, and
    /// returns whether the stage projected now has three substeps of history at the same
    /// substep whose second backward difference is below the first (weighed as in
    /// [`Island::extrapolation_order`]): the quadratic through them is then its warm start.
    /// A loop or a warm start that starts again empties the histories (as a step the island
    /// takes with RATTLE does, [`Island::forget_stages`]), and a substep of another size (the
    /// adaptive control's runs) a stage's own.
    fn record_stage(&mut self, n: usize) -> bool {
        let tree = self.regularisation < REGULARISATION_LOOPS;
        if !tree || self.mu_depth == 0 {
            self.forget_stages();
            return false;
        }
        let (j, substep) = self.stage;
        let last = &mut self.stage_mu[(j + STAGES - 1) % STAGES];
        if last.h != self.projected {
            last.depth = 0;
            last.h = self.projected;
        }
        self.projected = substep;
        last.mu.rotate_right(1);
        last.mu[0].clear();
        last.mu[0].extend_from_slice(&self.mu);
        last.depth = (last.depth + 1).min(3);
        let now = &self.stage_mu[j];
        if now.depth < 3 || now.h != substep || now.mu.iter().any(|m| m.len() != n) {
            return false;
        }
        let [a, b, c] = &now.mu;
        let (mut d1, mut d2): (Real, Real) = (0.0, 0.0);
        for (r, &w) in self.compliance.iter().enumerate().take(n) {
            d1 = d1.max(w * (a[r] - b[r]).abs());
            d2 = d2.max(w * (a[r] - 2.0 * b[r] + c[r]).abs());
        }
        d2 < SMOOTH * d1
    }

    /// Empties the composition's stage histories (see [`Island::record_stage`]) and the last
    /// stage's own extrapolation.
    pub(super) fn forget_stages(&mut self) {
        for s in &mut self.stage_mu {
            s.depth = 0;
        }
        self.stage_pred.clear();
    }

    /// The order of the warm start's extrapolation: linear where the history allows, and one
    /// order more while the island's backward differences of the multipliers (largest over
    /// the rows, each weighed by its row's effective inverse mass: the residual it stands for)
    /// keep falling by the factor [`SMOOTH`] or more. Multipliers that vary fast against the
    /// substep, or oscillate (a body spinning up on a tiny inertia), keep the linear
    /// extrapolation: there a higher order extrapolates the noise.
    fn extrapolation_order(&self) -> usize {
        let depth = self.mu_depth;
        if depth < 2 {
            return depth;
        }
        let [a, b, c, d] = &self.mu_history;
        let n = self.mu.len();
        // A hard row's compliance is the regularisation times its effective inverse mass, a
        // factor common to the island that the test's ratios do not see (the test runs only
        // without penalty rows, see `extrapolate_multipliers`).
        let rows = self
            .mu
            .iter()
            .zip(&self.compliance[..n])
            .zip(&a[..n])
            .zip(&b[..n]);
        let mut diff = [0.0 as Real; MU_HISTORY];
        // Per depth (zipped: no bounds checks, no branch per row), the same differences.
        match depth {
            2 => rows.for_each(|(((&m, &w), &a), &b)| {
                let d1 = m - a;
                let d2 = d1 - (a - b);
                widen(&mut diff, w, [d1, d2, 0.0, 0.0]);
            }),
            3 => rows.zip(&c[..n]).for_each(|((((&m, &w), &a), &b), &c)| {
                let d1 = m - a;
                let d2 = d1 - (a - b);
                let d3 = d2 - (a - 2.0 * b + c);
                widen(&mut diff, w, [d1, d2, d3, 0.0]);
            }),
            _ => rows
                .zip(&c[..n])
                .zip(&d[..n])
                .for_each(|(((((&m, &w), &a), &b), &c), &d)| {
                    let d1 = m - a;
                    let d2 = d1 - (a - b);
                    let d3 = d2 - (a - 2.0 * b + c);
                    let d4 = d3 - (a - 3.0 * b + 3.0 * c - d);
                    widen(&mut diff, w, [d1, d2, d3, d4]);
                }),
        }
        let mut order = 1;
        while order < depth && diff[order] < SMOOTH * diff[order - 1] {
            order += 1;
        }
        order
    }

    /// Largest deviation of any row from its projection target at the current state, from the
    /// rows' values alone: the chord step that mostly follows takes its directions from the
    /// factorisation, and the Jacobian is needed only where the projection stops here (see
    /// [`Island::project_positions`]).
    fn residual(&mut self, joints: &JointSet, bodies: &RigidBodySet, h: Real) -> Real {
        self.eval_rows(joints, bodies, Eval::Values);
        self.fresh_values = true;
        let mut residual: Real = 0.0;
        for r in 0..self.value.len() {
            let dev = if self.kpen[r] > 0.0 {
                self.value[r] + self.impulse[r] / (h * self.kpen[r])
            } else {
                self.value[r]
            };
            residual = residual.max(dev.abs());
        }
        residual
    }
}

/// `J^T mu` per body into `out` (through local slices: stores into a vector of `self` would
/// otherwise make every access reload the vectors' pointers). Each joint's two sides are
/// summed in registers first: adding row by row into `out` made every row wait for the store
/// of the one before (2-3 % of the mixed scene's step).
fn jt_mu(kkt: &crate::solver::kkt::KktSolver, jac: &[Real], mu: &[Real], out: &mut [[Real; 6]]) {
    for b in out.iter_mut() {
        *b = [0.0; 6];
    }
    for (k, spec) in kkt.joint_specs().iter().enumerate() {
        let r0 = kkt.row_offset(k);
        let rows = &jac[JAC_ROW_STRIDE * r0..JAC_ROW_STRIDE * (r0 + spec.rows)];
        let mut sides = [[0.0 as Real; 6]; 2];
        for (jr, &m) in rows
            .chunks_exact(JAC_ROW_STRIDE)
            .zip(&mu[r0..r0 + spec.rows])
        {
            for (side, half) in sides.iter_mut().zip(jr.chunks_exact(6)) {
                for (acc, &x) in side.iter_mut().zip(half) {
                    *acc += x * m;
                }
            }
        }
        for (side, body) in sides.iter().zip(spec.bodies) {
            if let Some(i) = body {
                for (acc, &x) in out[i].iter_mut().zip(side) {
                    *acc += x;
                }
            }
        }
    }
}

/// Whether a chord iteration that went from `previous` to `residual` at iteration `it` would,
/// at that rate, not reach `tol` within [`MAX_PROJECTION_ITERATIONS`]: it then hands over to
/// Gauss-Newton. Only an iteration that would fail at its last rate changes (the chord iteration's limit point
/// is the projection along the start-of-substep directions; Gauss-Newton's is not, and counts
/// as a fallback). The chart study's 1:1000 bead chain at one substep of 1/60 s met chord
/// iterations contracting by 0.7 to 0.96 where the beads turned far in the substep, and left
/// gaps of up to 1.6e-5 m at the limit.
///
/// A composed step hands over too. It kept its chord iterations while its fallback to RATTLE
/// read the last stage's force estimate alone: the handover then changed which way the first
/// step fell (`tests/composition_fallback.rs` ended 2.9e-3 m from RATTLE's run; see
/// [`Island::step_plain`]).
fn chord_too_slow(residual: Real, previous: Real, tol: Real, it: usize) -> bool {
    let rate = residual / previous;
    let left = (MAX_PROJECTION_ITERATIONS - it) as Real;
    rate >= 1.0 || (tol / residual).ln() / rate.ln() > left
}

impl Island {
    /// Puts the island's bodies back onto the constraints after something outside the
    /// integrator moved them (the adaptive control's local extrapolation, see
    /// [`StepControl::Adaptive`](crate::settings::StepControl::Adaptive)), and writes them
    /// back: the positions by chord steps along `M~^-1 J^T` at the moved state until every
    /// hard row holds to the projection tolerance (penalty rows keep their deflection: it is
    /// physical), then the velocities by the refined projection `J v = rate`. Nothing is fed
    /// into the velocities and nothing is booked: the substep's impulses (the reactions and
    /// the added inertia read them), the warm start's multipliers and the energy ledger stay
    /// as the last substep left them. An island that sleeps is left alone.
    pub(super) fn settle(
        &mut self,
        joints: &JointSet,
        physics: &mut PhysicsWorld,
        time: Real,
    ) -> Result<(), Error> {
        if self.kkt.is_none() || self.bodies.iter().all(|b| physics.bodies[*b].is_sleeping()) {
            return Ok(());
        }
        let h = self.last_h;
        // The chord steps below book into these like the projection's; they are put back.
        let (impulse, mu, carry) = (self.impulse.clone(), self.mu.clone(), self.vp_carry.clone());
        self.gather(&physics.bodies, physics.gravity);
        self.rows(joints, &physics.bodies, h, true);
        self.factor(joints, &physics.bodies, h, time)?;
        let tol = projection_tolerance();
        // `previous` stays infinite until a chord step moves the bodies.
        let mut previous = Real::INFINITY;
        for it in 0..MAX_PROJECTION_ITERATIONS {
            // The rows above evaluated the values at the moved state already.
            if it > 0 {
                self.eval_rows(joints, &physics.bodies, Eval::Values);
            }
            let mut residual: Real = 0.0;
            for r in 0..self.value.len() {
                let dev = if self.penalty[r] { 0.0 } else { self.value[r] };
                residual = residual.max(dev.abs());
                self.rhs_j[r] = -dev;
            }
            if residual <= tol {
                break;
            }
            // A chord step that does not shrink the residual is undone and stops it (a
            // singular pose: the next substep's projection, with its fallback, takes over).
            if residual >= previous || residual.is_nan() {
                if previous.is_finite() {
                    self.undo_projection_step(h, false);
                }
                break;
            }
            previous = residual;
            self.projection_step(h, time)?;
        }
        // The rows and factorisation at the settled state (those above hold if nothing moved).
        if previous.is_finite() {
            for s in self.st.iter_mut() {
                s.refresh_inertia();
            }
            self.rows(joints, &physics.bodies, h, true);
            self.factor(joints, &physics.bodies, h, time)?;
        }
        for (x, s) in self.rhs_b.iter_mut().zip(&self.st) {
            let (mv, mw) = (s.linvel * s.mass, s.inertia * s.angvel + s.angvel * s.added);
            *x = [mv.x, mv.y, mv.z, mw.x, mw.y, mw.z];
        }
        self.project_velocities(time, true)?;
        (self.impulse, self.mu, self.vp_carry) = (impulse, mu, carry);
        self.fresh_values = false;
        self.write_back(physics, time)
    }
}

/// `diff[k] = max(diff[k], w |d[k]|)`: the largest weighed backward differences of
/// [`Island::extrapolation_order`].
#[inline(always)]
fn widen(diff: &mut [Real; MU_HISTORY], w: Real, d: [Real; MU_HISTORY]) {
    for (x, y) in diff.iter_mut().zip(d) {
        *x = x.max(w * y.abs());
    }
}
