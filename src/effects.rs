//! The solver side of joint behaviour on the Lagrange backend (the physics and the data are in
//! [`crate::behaviour`]).
//!
//! - Springs, dampers and applied loads (`FJ`) act as generalised forces on the free DOFs,
//!   half an impulse at the start of each substep (from the state there) and half at its end
//!   (from the new state) — kick-drift-kick, second order for the force element.
//! - Stops and locks cost nothing while inactive: each substep reads the limited DOFs' measures
//!   and predicted rates, and only a DOF predicted to pass a limit gets a row. That row does
//!   not enter the KKT structure: its response through the constrained system is one more
//!   solve with the substep's existing factorisation (a Schur complement over the active
//!   limits, solved with non-negative impulses), so the joints' own rows keep their rates.
//!   - Lagrange method, transient: energy-momentum consistent elastic impact: the approach rate
//!     `g-` becomes `-g-` (the impulse `p` changes the kinetic energy by `p (g- + g+) / 2 = 0`).
//!   - Penalty method or a screw joint: plain inequality: the DOF lands on the limit
//!     (`g+ = -gap / h`) and stays while pushed; the kinetic energy lost is dissipated.
//!   - Locks land the same way and are then held by a permanent row from the next step on.
//!
//!   After the position projection a limit still violated by more than the projection
//!   tolerance is projected back the same way (position level, start-of-substep directions).

use serde::{Deserialize, Serialize};

use crate::behaviour::dof_rows;
use crate::dof::Dof;
use crate::error::Error;
use crate::joint::ConstraintMethod;
use crate::math::{Real, Vector};
pub use crate::output::{EnergyLedger, EnergyReport, FrictionState};
use crate::rows::{FramePair, RowEval, RowKind};
use crate::world::{Drive, Mpc184World, frame_pair};

/// A joint's ANSYS frame pair, the dynamic-body slots of its two sides and each side's velocity
/// (linear at the centre of mass, angular).
type EffectFrames = (FramePair, [Option<usize>; 2], [[Vector; 2]; 2]);

/// A row's rate `J1 (v1, w1) + J2 (v2, w2)` for the two sides' velocities.
fn row_rate(row: &RowEval, v1: [Vector; 2], v2: [Vector; 2]) -> Real {
    row.j1[0].dot(v1[0]) + row.j1[1].dot(v1[1]) + row.j2[0].dot(v2[0]) + row.j2[1].dot(v2[1])
}

/// Gap (m or rad) beyond which a limit is far enough for the position stage to skip it.
const LIMIT_MARGIN: Real = 1e-6;

/// Per row: the body velocity changes and the joint rows' multiplier changes of a unit impulse.
type Responses = Vec<(Vec<[Real; 6]>, Vec<Real>)>;

/// Per-joint solver state of the behaviour (not model data).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub(crate) struct EffectState {
    /// Locked DOFs and the value they are held at (absolute measure).
    pub(crate) locked: [Option<Real>; 6],
    /// Locks engaged during the current step whose hold rows are added at the next step.
    pending: Vec<(Dof, Real)>,
    /// DOFs at a stop during the last step.
    pub(crate) at_stop: [bool; 6],
    /// Applied loads (FJ) per DOF.
    pub(crate) loads: Vec<Drive>,
    /// Generalised spring + damper + load force of the last evaluation (per DOF).
    pub(crate) force: [Real; 6],
    /// World force and torque on body 2 (about its centre of mass) from the elements and the
    /// limit impulses of the last substep (N, N m).
    pub(crate) on_body2: (Vector, Vector),
    /// Spring energy at the last evaluation (J).
    pub(crate) spring_energy: Real,
    /// Friction state of the last substep.
    pub(crate) friction: Option<FrictionState>,
    /// Stops that reflected elastically in the current substep (DOF, side: +1 lower, -1 upper).
    bounced: Vec<(Dof, Real)>,
}

/// One limit row predicted active.
struct Active {
    joint: usize,
    dof: Dof,
    /// +1: lower limit (gap = m - min), -1: upper (gap = max - m).
    side: Real,
    /// The DOF row (value = measure) with the side applied to the Jacobian.
    row: RowEval,
    slots: [Option<usize>; 2],
    /// Desired change of the gap rate (velocity level) or of the gap (position level).
    change: Real,
    /// The gap rate before (velocity level).
    before: Real,
    dissipative: bool,
}

impl Mpc184World {
    /// The ANSYS frame pair of joint `j` at the solver's current body states, the dynamic-body
    /// slots of its two sides, and each side's velocity (linear at the centre of mass, angular).
    fn effect_frames(&self, j: usize) -> Option<EffectFrames> {
        let e = self.joints.get(j)?.as_ref()?;
        let ls = &self.lagrange;
        let side = |b| match ls.index.get(&b) {
            Some(&i) => {
                let s = &ls.st[i];
                (s.pose, s.com, Some(i), [s.linvel, s.angvel])
            }
            None => {
                let rb = &self.physics.bodies[b];
                (
                    *rb.position(),
                    rb.center_of_mass(),
                    None,
                    [rb.linvel(), rb.angvel()],
                )
            }
        };
        let (p1, c1, i1, v1) = side(e.body1);
        let (p2, c2, i2, v2) = side(e.body2);
        Some((frame_pair(&e.ansys, (p1, c1), (p2, c2)), [i1, i2], [v1, v2]))
    }

    /// Adds locks engaged during the last step as permanent rows (called at a step's start).
    pub(crate) fn effects_apply_pending_locks(&mut self) {
        for e in self.joints.iter_mut().flatten() {
            for (dof, value) in core::mem::take(&mut e.effects.pending) {
                let k = dof.index();
                let (initial, reference) = if dof.is_rotation() {
                    (e.initial[k], e.output.measure[k])
                } else {
                    (0.0, 0.0)
                };
                e.rows
                    .retain(|r| !matches!(r, RowKind::Drive { dof: d, .. } if *d == dof));
                e.rows.push(RowKind::Drive {
                    dof,
                    target: value - e.initial[k],
                    initial,
                    reference,
                });
                self.lagrange.dirty = true;
            }
        }
    }

    /// True when some joint has behaviour the substep must look at.
    pub(crate) fn effects_any(&self) -> bool {
        self.joints
            .iter()
            .flatten()
            .any(|e| !e.joint.behaviour.is_empty() || !e.effects.loads.is_empty())
    }

    /// Half a kick of the springs, dampers and loads: adds `(h/2) J^T f` to the momentum
    /// buffer `rhs_b` (dynamic bodies by slot) and books the dampers' and loads' work.
    pub(crate) fn effects_kick(&mut self, half: Real, time: Real) {
        for j in 0..self.joints.len() {
            let Some(e) = &self.joints[j] else { continue };
            let b = &e.joint.behaviour;
            if !b.has_forces() && e.effects.loads.is_empty() {
                continue;
            }
            let Some((f, slots, vel)) = self.effect_frames(j) else {
                continue;
            };
            let free = e.joint.kind.free();
            let reference = [e.output.measure[3], e.output.measure[5]];
            let (m, rows) = dof_rows(&f, reference);
            let rate: [Real; 6] = core::array::from_fn(|k| row_rate(&rows[k], vel[0], vel[1]));
            let x: [Real; 6] =
                core::array::from_fn(|k| m[k] - b.reference[k].unwrap_or(e.initial[k]));
            let mut spring = [0.0; 6];
            let mut damper = [0.0; 6];
            let mut energy = 0.0;
            if let Some(kmat) = &b.stiffness {
                let kx = kmat.apply(&x, free);
                for k in 0..6 {
                    spring[k] -= kx[k];
                    energy += 0.5 * x[k] * kx[k];
                }
            }
            if let Some(cmat) = &b.damping {
                let cv = cmat.apply(&rate, free);
                for k in 0..6 {
                    damper[k] -= cv[k];
                }
            }
            for k in 0..6 {
                if !free.contains(Dof::ALL[k]) {
                    continue;
                }
                if let Some(t) = &b.stiffness_tables[k] {
                    spring[k] -= t.eval(x[k]).0;
                    energy += t.integral(x[k]);
                }
                if let Some(t) = &b.damping_tables[k] {
                    damper[k] -= t.eval(rate[k]).0;
                }
            }
            let mut load = [0.0; 6];
            for d in &e.effects.loads {
                load[d.dof.index()] += d.profile.value(time);
            }
            let total: [Real; 6] = core::array::from_fn(|k| spring[k] + damper[k] + load[k]);
            let mut work = 0.0;
            let mut dissipated = 0.0;
            for k in 0..6 {
                dissipated -= damper[k] * rate[k] * half;
                // A locked DOF does not move: the load's kick there is taken straight back by
                // the lock (neither booked).
                if e.effects.locked[k].is_none() {
                    work += load[k] * rate[k] * half;
                }
            }
            let (mut f2, mut t2) = (Vector::ZERO, Vector::ZERO);
            for (k, row) in rows.iter().enumerate() {
                if total[k] == 0.0 {
                    continue;
                }
                f2 += row.j2[0] * total[k];
                t2 += row.j2[1] * total[k];
                for (slot, jb) in [(slots[0], row.j1), (slots[1], row.j2)] {
                    if let Some(i) = slot {
                        let p = &mut self.lagrange.rhs_b[i];
                        for a in 0..3 {
                            p[a] += jb[0][a] * total[k] * half;
                            p[3 + a] += jb[1][a] * total[k] * half;
                        }
                    }
                }
            }
            self.ledger.dissipated += dissipated;
            self.ledger.work += work;
            let Some(e) = &mut self.joints[j] else {
                continue;
            };
            e.effects.force = total;
            e.effects.spring_energy = energy;
            e.effects.on_body2 = (f2, t2);
        }
    }

    /// Collects the limits predicted active. `level`: velocity (`v` in `rhs_b`, the gap after
    /// `h` predicted from it) or position (the gap now, after the projection).
    fn effects_active(&mut self, h: Real, velocity_level: bool, tol: Real) -> Vec<Active> {
        let mut out = Vec::new();
        // The smallest gap now or predicted after the substep (velocity level).
        let mut near = Real::INFINITY;
        for j in 0..self.joints.len() {
            let Some(e) = &self.joints[j] else { continue };
            let b = &e.joint.behaviour;
            if b.stops.is_empty() && b.locks.is_empty() {
                continue;
            }
            let Some((f, slots, vel)) = self.effect_frames(j) else {
                continue;
            };
            let (m, rows) = dof_rows(&f, [e.output.measure[3], e.output.measure[5]]);
            let plastic = matches!(e.joint.method, ConstraintMethod::Penalty { .. })
                || matches!(e.joint.kind, crate::catalogue::JointKind::Screw { .. });
            // The velocity to predict with: the solved v' (rhs_b) for dynamic sides.
            let v_of = |slot: Option<usize>, fallback: [Vector; 2]| match slot {
                Some(i) if velocity_level => {
                    let x = self.lagrange.rhs_b[i];
                    [Vector::new(x[0], x[1], x[2]), Vector::new(x[3], x[4], x[5])]
                }
                _ => fallback,
            };
            let v1 = v_of(slots[0], vel[0]);
            let v2 = v_of(slots[1], vel[1]);
            // Locks engaged this step whose row joins at the next step: held at their value
            // (landing again at the end of the substep, the energy removed booked).
            if velocity_level {
                for &(dof, value) in &e.effects.pending {
                    let k = dof.index();
                    let row = rows[k];
                    let rate = row_rate(&row, v1, v2);
                    let target = -(m[k] - value) / h;
                    let side: Real = if rate > target { -1.0 } else { 1.0 };
                    out.push(Active {
                        joint: j,
                        dof,
                        side,
                        row: RowEval {
                            value: side * (m[k] - value),
                            j1: [row.j1[0] * side, row.j1[1] * side],
                            j2: [row.j2[0] * side, row.j2[1] * side],
                        },
                        slots,
                        change: side * (target - rate),
                        before: side * rate,
                        // Holding: the load's half kick put in what this takes out (both
                        // O(h^2) and booked as neither).
                        dissipative: false,
                    });
                }
            }
            let limits = b
                .stops
                .iter()
                .map(|l| (l, false))
                .chain(b.locks.iter().map(|l| (l, true)));
            for (l, is_lock) in limits {
                let k = l.dof.index();
                if e.effects.locked[k].is_some() {
                    continue;
                }
                let row = rows[k];
                let rate = row_rate(&row, v1, v2);
                // The rate at the start of the substep, before this substep's forces.
                let rate_n = row_rate(&row, vel[0], vel[1]);
                for (side, limit) in [(1.0 as Real, l.min), (-1.0, l.max)] {
                    if !limit.is_finite() {
                        continue;
                    }
                    let gap = side * (m[k] - limit);
                    let g_rate = side * rate;
                    if velocity_level {
                        near = near.min(gap).min(gap + h * g_rate);
                    }
                    let (change, dissipative) = if velocity_level {
                        if gap + h * g_rate >= 0.0 || g_rate >= 0.0 && gap >= 0.0 {
                            continue;
                        }
                        let land = -gap / h;
                        if plastic || is_lock {
                            (land.max(0.0) - g_rate, true)
                        } else {
                            // Elastic: the scheme's velocities are half-step velocities
                            // (positions advance with the end-of-substep velocity), so the
                            // energy-consistent reflection at the substep's start reverses the
                            // rate the substep started with: `g+ = -g_n` (the velocity at
                            // `t_n`, the mean of the two half steps, changes sign exactly:
                            // reversing `g'` instead gains `h |g'| |a|` per impact, measured as
                            // +2.4e-3 m g L per impact on the stop pendulum). Never left beyond
                            // the limit at the substep's end.
                            let approach = (side * rate_n).min(0.0);
                            let bounce = -approach;
                            if bounce >= land {
                                (bounce - g_rate, false)
                            } else {
                                (land - g_rate, true)
                            }
                        }
                    } else {
                        if gap >= -tol {
                            continue;
                        }
                        (-gap, false)
                    };
                    let signed = RowEval {
                        value: gap,
                        j1: [row.j1[0] * side, row.j1[1] * side],
                        j2: [row.j2[0] * side, row.j2[1] * side],
                    };
                    out.push(Active {
                        joint: j,
                        dof: l.dof,
                        side,
                        row: signed,
                        slots,
                        change,
                        before: g_rate,
                        dissipative,
                    });
                    let _ = is_lock;
                }
            }
        }
        if velocity_level {
            // Far from every limit (by more than the projection can move a DOF) and nothing
            // pending: the position stage has nothing to do this substep.
            let pending = self
                .joints
                .iter()
                .flatten()
                .any(|e| !e.effects.pending.is_empty());
            self.lagrange.limits_clear = out.is_empty() && !pending && near > LIMIT_MARGIN;
        }
        out
    }

    /// The response of the constrained system to a unit impulse along each row: the body
    /// velocity changes and the joint rows' multiplier changes (`-impulse`), from the current
    /// factorisation with two steps of iterative refinement towards the unregularised hard
    /// rows (the relative regularisation otherwise lets a response to a large torque on a small
    /// inertia leak through the joint's own rows: measured 3e-4 of the impact energy lost per
    /// bounce with a bob of inertia 1e-4 kg m^2 on 1 m; the second pass takes a 1e-6 kg m^2 bob
    /// from 4e-5 to round-off). Empty when there is no factorisation.
    fn effects_responses(
        &self,
        rows: &[(RowEval, [Option<usize>; 2])],
    ) -> Result<Responses, Error> {
        let ls = &self.lagrange;
        let nb = ls.bodies.len();
        let time = self.time;
        let Some(kkt) = ls.kkt.as_ref() else {
            return Ok(Vec::new());
        };
        let fail = |e| Error::Diverged {
            time,
            joint: None,
            reason: format!("joint stop/friction solve failed: {e}"),
        };
        let mut out = Vec::with_capacity(rows.len());
        for (row, slots) in rows {
            let mut rb = vec![[0.0; 6]; nb];
            let mut rj = vec![0.0; kkt.num_rows()];
            for (slot, jb) in [(slots[0], row.j1), (slots[1], row.j2)] {
                if let Some(i) = slot {
                    for c in 0..3 {
                        rb[i][c] += jb[0][c];
                        rb[i][3 + c] += jb[1][c];
                    }
                }
            }
            kkt.solve(&mut rb, &mut rj).map_err(fail)?;
            let mut last = rj.clone();
            for _ in 0..2 {
                let mut rb2 = vec![[0.0; 6]; nb];
                let mut rj2: Vec<Real> = last
                    .iter()
                    .zip(&ls.compliance)
                    .zip(&ls.kpen)
                    .map(|((m, c), k)| if *k > 0.0 { 0.0 } else { -c * m })
                    .collect();
                kkt.solve(&mut rb2, &mut rj2).map_err(fail)?;
                for (x, y) in rb.iter_mut().zip(&rb2) {
                    for c in 0..6 {
                        x[c] += y[c];
                    }
                }
                for (x, y) in rj.iter_mut().zip(&rj2) {
                    *x += y;
                }
                last = rj2;
            }
            out.push((rb, rj));
        }
        Ok(out)
    }

    /// Solves for non-negative impulses on the active limits through the constrained system
    /// (current factorisation) and applies them: to the velocities in `rhs_b` (velocity level)
    /// or as displacements of the body states (position level, fed into the velocity as
    /// `dx / h`). Returns the impulses.
    fn effects_resolve(
        &mut self,
        active: &[Active],
        h: Real,
        velocity_level: bool,
    ) -> Result<Vec<Real>, Error> {
        let n = active.len();
        let nb = self.lagrange.bodies.len();
        let time = self.time;
        let rows: Vec<(RowEval, [Option<usize>; 2])> =
            active.iter().map(|a| (a.row, a.slots)).collect();
        let responses = self.effects_responses(&rows)?;
        if responses.len() != n {
            return Ok(vec![0.0; n]);
        }
        let dot = |a: &Active, dv: &[[Real; 6]]| -> Real {
            let mut s = 0.0;
            for (slot, jb) in [(a.slots[0], a.row.j1), (a.slots[1], a.row.j2)] {
                if let Some(i) = slot {
                    for c in 0..3 {
                        s += jb[0][c] * dv[i][c] + jb[1][c] * dv[i][3 + c];
                    }
                }
            }
            s
        };
        let w: Vec<Vec<Real>> = active
            .iter()
            .map(|a| responses.iter().map(|r| dot(a, &r.0)).collect())
            .collect();
        // Projected Gauss-Seidel on the small Delassus system, p >= 0.
        let mut p = vec![0.0; n];
        for _ in 0..if n == 1 { 1 } else { 100 } {
            for a in 0..n {
                if w[a][a] <= 0.0 {
                    continue;
                }
                let mut r = active[a].change;
                for b in 0..n {
                    if b != a {
                        r -= w[a][b] * p[b];
                    }
                }
                p[a] = (r / w[a][a]).max(0.0);
            }
        }
        if p.iter().any(|x| !x.is_finite()) {
            return Err(Error::Diverged {
                time,
                joint: None,
                reason: "non-finite joint stop impulse".into(),
            });
        }
        let ls = &mut self.lagrange;
        for (a, (dv, dmu)) in responses.iter().enumerate() {
            if p[a] == 0.0 {
                continue;
            }
            for (i, dvi) in dv.iter().enumerate().take(nb) {
                if velocity_level {
                    for (rhs, d) in ls.rhs_b[i].iter_mut().zip(dvi) {
                        *rhs += p[a] * d;
                    }
                } else {
                    let d = dvi.map(|x| x * p[a]);
                    let s = &mut ls.st[i];
                    crate::lagrange::displace_state(s, d);
                    s.linvel += Vector::new(d[0], d[1], d[2]) / h;
                    s.angvel += Vector::new(d[3], d[4], d[5]) / h;
                }
            }
            // The joints' rows took -dmu with it.
            let scale = if velocity_level { 1.0 } else { 1.0 / h };
            for (r, m) in dmu.iter().enumerate() {
                ls.impulse[r] -= p[a] * m * scale;
            }
        }
        // Energy of the velocity-level impulses and the output.
        for (a, act) in active.iter().enumerate() {
            if p[a] == 0.0 {
                continue;
            }
            let after = act.before + (0..n).map(|b| w[a][b] * p[b]).sum::<Real>();
            if velocity_level {
                // A plastic landing removes `p (g- + g+) / 2`; an elastic reversal keeps the
                // kinetic energy the substep started with (nothing to book).
                if act.dissipative {
                    self.ledger.dissipated -= p[a] * 0.5 * (act.before + after);
                    // A lock removes what is left of the approach at the next substep: book
                    // it now (`g+^2 / (2 W)` with `W` the DOF's effective inverse mass).
                    let is_lock = self.joints[act.joint].as_ref().is_some_and(|e| {
                        e.joint.behaviour.locks.iter().any(|l| l.dof == act.dof)
                            && e.effects.locked[act.dof.index()].is_none()
                    });
                    if is_lock && w[a][a] > 0.0 {
                        self.ledger.dissipated += 0.5 * after * after / w[a][a];
                    }
                }
            }
            let impulse = if velocity_level { p[a] } else { p[a] / h };
            if let Some(e) = &mut self.joints[act.joint] {
                if velocity_level && !act.dissipative {
                    e.effects.bounced.push((act.dof, act.side));
                }
                e.effects.at_stop[act.dof.index()] = true;
                let (f, t) = &mut e.effects.on_body2;
                *f += act.row.j2[0] * (impulse / h);
                *t += act.row.j2[1] * (impulse / h);
            }
            let _ = act.side;
        }
        Ok(p)
    }

    /// The velocity-level limit stage, right after the velocity solve (`v'` in `rhs_b`).
    pub(crate) fn effects_limits_velocity(&mut self, h: Real) -> Result<(), Error> {
        let active = self.effects_active(h, true, 0.0);
        if active.is_empty() {
            return Ok(());
        }
        self.effects_resolve(&active, h, true)?;
        // Locks that acted engage now (held at their limit from here on).
        for a in &active {
            let Some(e) = &mut self.joints[a.joint] else {
                continue;
            };
            let b = &e.joint.behaviour;
            let k = a.dof.index();
            if e.effects.locked[k].is_some() {
                continue;
            }
            if let Some(l) = b.locks.iter().find(|l| l.dof == a.dof) {
                let value = if a.side > 0.0 { l.min } else { l.max };
                e.effects.locked[k] = Some(value);
                e.effects.pending.push((a.dof, value));
            }
        }
        Ok(())
    }

    /// The position-level limit stage after the projection: limits violated by more than
    /// `tol` are projected back; locks engaged this step are held at their values until their
    /// row joins at the next step.
    pub(crate) fn effects_limits_position(&mut self, h: Real, tol: Real) -> Result<(), Error> {
        if self.lagrange.limits_clear {
            return Ok(());
        }
        let mut active = self.effects_active(h, false, tol);
        // Locked DOFs whose row is still pending: hold them at their value (both sides).
        for j in 0..self.joints.len() {
            let Some(e) = &self.joints[j] else { continue };
            if e.effects.pending.is_empty() {
                continue;
            }
            let Some((f, slots, _)) = self.effect_frames(j) else {
                continue;
            };
            let (m, rows) = dof_rows(&f, [e.output.measure[3], e.output.measure[5]]);
            for &(dof, value) in &e.effects.pending {
                let k = dof.index();
                let d = m[k] - value;
                if d.abs() <= tol {
                    continue;
                }
                let side = if d < 0.0 { 1.0 } else { -1.0 };
                let row = rows[k];
                active.push(Active {
                    joint: j,
                    dof,
                    side,
                    row: RowEval {
                        value: side * d,
                        j1: [row.j1[0] * side, row.j1[1] * side],
                        j2: [row.j2[0] * side, row.j2[1] * side],
                    },
                    slots,
                    change: d.abs(),
                    before: 0.0,
                    dissipative: true,
                });
            }
        }
        if active.is_empty() {
            return Ok(());
        }
        self.effects_resolve(&active, h, false)?;
        Ok(())
    }

    /// The reactions of joint `j` in this substep so far (forces then moments on node J, frame
    /// I; N and N m) from its rows' impulses, and the screw coupling row's multiplier.
    fn effects_reactions(&self, j: usize, f: &FramePair, h: Real) -> ([Real; 6], Real) {
        let ls = &self.lagrange;
        let Some(e) = &self.joints[j] else {
            return ([0.0; 6], 0.0);
        };
        let Some(range) = ls.rows_of(j) else {
            return ([0.0; 6], 0.0);
        };
        let (mut force, mut torque, mut screw) = (Vector::ZERO, Vector::ZERO, 0.0);
        for (row, r) in e.rows.iter().zip(range) {
            let jr = &ls.jac[crate::solver::kkt::JAC_ROW_STRIDE * r..];
            let m = ls.impulse[r] / h;
            force += Vector::new(jr[6], jr[7], jr[8]) * m;
            torque += Vector::new(jr[9], jr[10], jr[11]) * m;
            if matches!(row, RowKind::Screw { .. }) {
                screw = m;
            }
        }
        let moment = torque - (f.p2 - f.c2).cross(force);
        let (fl, ml) = (f.r1.transpose() * force, f.r1.transpose() * moment);
        ([fl.x, fl.y, fl.z, ml.x, ml.y, ml.z], screw)
    }

    /// The friction stage, after the limits (`v'` in `rhs_b`): per joint with friction, the
    /// bounded impulse on its free DOF(s) that sticks it if `|p| <= mu(V) N h` allows, else
    /// slides at the bound; `N` from the joint's reactions of this substep, recomputed after
    /// each of three passes (the friction impulse changes the reactions through the constrained
    /// system: the screw jack's normal force depends on the friction itself).
    pub(crate) fn effects_friction(&mut self, h: Real) -> Result<(), Error> {
        const PASSES: usize = 3;
        for j in 0..self.joints.len() {
            let Some(e) = &self.joints[j] else { continue };
            let Some(fr) = e.joint.behaviour.friction.clone() else {
                continue;
            };
            let kind = e.joint.kind;
            let Some(dofs) = crate::behaviour::Friction::dofs(&kind) else {
                continue;
            };
            let Some((f, slots, _)) = self.effect_frames(j) else {
                continue;
            };
            let (_, rows) = dof_rows(&f, [e.output.measure[3], e.output.measure[5]]);
            let mut frows: Vec<(RowEval, [Option<usize>; 2])> =
                dofs.iter().map(|d| (rows[d.index()], slots)).collect();
            // The screw's thread friction acts along the helix at the mean radius r, not as a
            // pure moment: the row `(p J_uz + r^2 J_theta) / (r^2 + p^2)` reads the screw rate
            // on the constraint manifold and applies (axial force, moment / r) in the ratio
            // (p, r), tangent to the thread, so that it leaves the thread's normal force alone
            // (a pure moment would load the thread and change N).
            if let crate::catalogue::JointKind::Screw { pitch } = kind {
                let r = fr.geometry[0].unwrap_or(1.0);
                let l2 = r * r + pitch * pitch;
                let lin = RowKind::Linear { axis: 2 }.eval(&f);
                let ang = rows[5];
                let mix = |a: [Vector; 2], b: [Vector; 2]| {
                    [
                        a[0] * (pitch / l2) + b[0] * (r * r / l2),
                        a[1] * (pitch / l2) + b[1] * (r * r / l2),
                    ]
                };
                frows[0].0 = RowEval {
                    value: ang.value,
                    j1: mix(lin.j1, ang.j1),
                    j2: mix(lin.j2, ang.j2),
                };
            }
            let responses = self.effects_responses(&frows)?;
            let n = frows.len();
            if responses.len() != n {
                continue;
            }
            let nb = self.lagrange.bodies.len();
            let rate_of = |ls: &crate::lagrange::LagrangeState, row: &RowEval| -> Real {
                let mut g = 0.0;
                for (slot, jb) in [(slots[0], row.j1), (slots[1], row.j2)] {
                    if let Some(i) = slot {
                        let x = ls.rhs_b[i];
                        g += jb[0].dot(Vector::new(x[0], x[1], x[2]))
                            + jb[1].dot(Vector::new(x[3], x[4], x[5]));
                    }
                }
                g
            };
            let w: Vec<Vec<Real>> = frows
                .iter()
                .map(|(row, _)| {
                    responses
                        .iter()
                        .map(|(dv, _)| {
                            let mut s = 0.0;
                            for (slot, jb) in [(slots[0], row.j1), (slots[1], row.j2)] {
                                if let Some(i) = slot {
                                    for c in 0..3 {
                                        s += jb[0][c] * dv[i][c] + jb[1][c] * dv[i][3 + c];
                                    }
                                }
                            }
                            s
                        })
                        .collect()
                })
                .collect();
            let g0: Vec<Real> = frows
                .iter()
                .map(|(r, _)| rate_of(&self.lagrange, r))
                .collect();
            let speed = g0.iter().map(|g| g * g).sum::<Real>().sqrt();
            let mu = fr.law.mu(speed);
            let mut total = vec![0.0; n];
            let mut stick = true;
            let mut normal = 0.0;
            for _ in 0..PASSES {
                let (l, screw) = self.effects_reactions(j, &f, h);
                normal = match kind {
                    crate::catalogue::JointKind::Screw { pitch } => {
                        let r = fr.geometry[0].unwrap_or(1.0);
                        fr.interference
                            + screw.abs()
                                * (1.0 + pitch * pitch / (r * r)).sqrt()
                                * (r * r + pitch * pitch).sqrt()
                    }
                    _ => fr.normal(&kind, &l),
                };
                let mut bound = mu * normal;
                if let Some(cap) = fr.max_force {
                    bound = bound.min(cap);
                }
                let bound = bound * h;
                // Impulse that sticks: total - W^-1 g (Gauss-Seidel on the small system).
                let g: Vec<Real> = frows
                    .iter()
                    .map(|(r, _)| rate_of(&self.lagrange, r))
                    .collect();
                let mut target = total.clone();
                let mut delta = vec![0.0; n];
                for _ in 0..if n == 1 { 1 } else { 30 } {
                    for a in 0..n {
                        if w[a][a] <= 0.0 {
                            continue;
                        }
                        let mut r = -g[a];
                        for b in 0..n {
                            if b != a {
                                r -= w[a][b] * delta[b];
                            }
                        }
                        delta[a] = r / w[a][a];
                    }
                }
                for a in 0..n {
                    target[a] += delta[a];
                }
                let size = target.iter().map(|x| x * x).sum::<Real>().sqrt();
                stick = size <= bound;
                if !stick && size > 0.0 {
                    for x in target.iter_mut() {
                        *x *= bound / size;
                    }
                }
                let ls = &mut self.lagrange;
                for a in 0..n {
                    let d = target[a] - total[a];
                    if d == 0.0 {
                        continue;
                    }
                    let (dv, dmu) = &responses[a];
                    for (rhs, dvi) in ls.rhs_b.iter_mut().zip(dv).take(nb) {
                        for (x, y) in rhs.iter_mut().zip(dvi) {
                            *x += d * y;
                        }
                    }
                    for (r, m) in dmu.iter().enumerate() {
                        ls.impulse[r] -= d * m;
                    }
                }
                total = target;
            }
            let g1: Vec<Real> = frows
                .iter()
                .map(|(r, _)| rate_of(&self.lagrange, r))
                .collect();
            let mut lost = 0.0;
            for a in 0..n {
                // Work = force times the DOF's actual travel in the substep (positions advance
                // with the rate after the impulse): on the sliding incline this books exactly
                // `mu N s` (measured to 4e-8), where the mean of the rates before and after
                // (the impulse's kinetic-energy change) overbooks by `p^2 / 2m` per substep.
                lost -= total[a] * g1[a];
            }
            self.ledger.dissipated += lost;
            let (mut f2, mut t2) = (Vector::ZERO, Vector::ZERO);
            for (a, (row, _)) in frows.iter().enumerate() {
                f2 += row.j2[0] * (total[a] / h);
                t2 += row.j2[1] * (total[a] / h);
            }
            let slip_rate = g1.iter().map(|g| g * g).sum::<Real>().sqrt();
            if let Some(e) = &mut self.joints[j] {
                e.effects.on_body2.0 += f2;
                e.effects.on_body2.1 += t2;
                e.effects.friction = Some(FrictionState {
                    slipping: !stick,
                    slip_rate,
                    force: total.iter().map(|x| x * x).sum::<Real>().sqrt() / h,
                    normal,
                    mu,
                });
            }
        }
        Ok(())
    }

    /// Some joint has an elastic stop (Lagrange method, not a screw).
    pub(crate) fn effects_has_elastic_stops(&self) -> bool {
        self.joints.iter().flatten().any(|e| {
            !e.joint.behaviour.stops.is_empty()
                && !matches!(e.joint.method, ConstraintMethod::Penalty { .. })
                && !matches!(e.joint.kind, crate::catalogue::JointKind::Screw { .. })
        })
    }

    /// Elastic energy of the joint springs at their last evaluation (J).
    pub(crate) fn effects_spring_energy(&self) -> Real {
        self.joints
            .iter()
            .flatten()
            .map(|e| e.effects.spring_energy)
            .sum()
    }

    /// The energy-consistent impact of the second-order step (the velocity update of Laursen
    /// and Love, 2002): after a substep in which a stop reflected, the post-impact rate along
    /// that stop is set so that kinetic + potential + spring energy at the substep's end equals
    /// the energy it started with plus the work booked in it (loads, drives) minus what was
    /// dissipated (dampers, friction, plastic landings). The impulse acts along the stop's row
    /// through the constrained system (the joints' velocity constraints hold and the momentum
    /// changes only as the joint reactions allow). Where no separating rate reaches the energy
    /// (the reflection left less kinetic energy along the stop than must go), the rate is set to
    /// zero and the rest booked as dissipated.
    pub(crate) fn effects_energy_fix(
        &mut self,
        h: Real,
        start: Real,
        ledger0: EnergyLedger,
    ) -> Result<(), Error> {
        let Some((j, dof, side)) = self.joints.iter().enumerate().find_map(|(j, e)| {
            e.as_ref()
                .and_then(|e| e.effects.bounced.first().map(|&(d, s)| (j, d, s)))
        }) else {
            return Ok(());
        };
        let Some((f, slots, vel)) = self.effect_frames(j) else {
            return Ok(());
        };
        let Some(e) = &self.joints[j] else {
            return Ok(());
        };
        let (_, rows) = dof_rows(&f, [e.output.measure[3], e.output.measure[5]]);
        let row = rows[dof.index()];
        let signed = RowEval {
            value: 0.0,
            j1: [row.j1[0] * side, row.j1[1] * side],
            j2: [row.j2[0] * side, row.j2[1] * side],
        };
        let responses = self.effects_responses(&[(signed, slots)])?;
        let Some((dv, dmu)) = responses.first() else {
            return Ok(());
        };
        let now = self.lagrange_body_energy() + self.effects_spring_energy();
        let expected = start + (self.ledger.work - ledger0.work)
            - (self.ledger.dissipated - ledger0.dissipated);
        let ls = &self.lagrange;
        // Kinetic energy along the response: KE(v + p u) = KE(v) + a1 p + a2 p^2, with the
        // bodies' true inertia.
        let (mut a1, mut a2) = (0.0, 0.0);
        for (s, d) in ls.st.iter().zip(dv) {
            let du = Vector::new(d[0], d[1], d[2]);
            let dw = Vector::new(d[3], d[4], d[5]);
            a1 += s.mass * s.linvel.dot(du) + s.angvel.dot(s.inertia * dw);
            a2 += 0.5 * (s.mass * du.length_squared() + dw.dot(s.inertia * dw));
        }
        if a2 <= 0.0 || !now.is_finite() || !expected.is_finite() {
            return Ok(());
        }
        let g = row_rate(&signed, vel[0], vel[1]);
        let mut w = 0.0;
        for (slot, jb) in [(slots[0], signed.j1), (slots[1], signed.j2)] {
            if let Some(i) = slot {
                let d = dv[i];
                w += jb[0].dot(Vector::new(d[0], d[1], d[2]))
                    + jb[1].dot(Vector::new(d[3], d[4], d[5]));
            }
        }
        let c = now - expected;
        let disc = a1 * a1 - 4.0 * a2 * c;
        let mut p = if disc >= 0.0 {
            (-a1 + disc.sqrt()) / (2.0 * a2)
        } else {
            -a1 / (2.0 * a2)
        };
        // Never leave the stop approaching it again.
        if w > 0.0 && g + p * w < 0.0 {
            p = -g / w;
        }
        if !p.is_finite() || p == 0.0 {
            return Ok(());
        }
        let ls = &mut self.lagrange;
        for (s, d) in ls.st.iter_mut().zip(dv) {
            s.linvel += Vector::new(d[0], d[1], d[2]) * p;
            s.angvel += Vector::new(d[3], d[4], d[5]) * p;
        }
        for (r, m) in dmu.iter().enumerate() {
            ls.impulse[r] -= p * m;
        }
        let after = self.lagrange_body_energy() + self.effects_spring_energy();
        // What could not be kept (clamped cases only; round-off otherwise).
        self.ledger.dissipated += expected - after;
        if let Some(e) = &mut self.joints[j] {
            let (f2, t2) = &mut e.effects.on_body2;
            *f2 += signed.j2[0] * (p / h);
            *t2 += signed.j2[1] * (p / h);
        }
        Ok(())
    }

    /// Books the work of the prescribed motions (DJ) over the substep just taken: each drive
    /// row's impulse times its prescribed rate (`lambda . J v` with `J v` = the rate).
    pub(crate) fn effects_book_drive_work(&mut self) {
        let mut work = 0.0;
        for (j, e) in self.joints.iter().enumerate() {
            let Some(e) = e else { continue };
            if e.drives.is_empty() {
                continue;
            }
            let Some(range) = self.lagrange.rows_of(j) else {
                continue;
            };
            for (row, r) in e.rows.iter().zip(range) {
                if let RowKind::Drive { dof, .. } = row
                    && e.drives.iter().any(|d| d.dof == *dof)
                {
                    work += self.lagrange.impulse[r] * self.lagrange.rate[r];
                }
            }
        }
        self.ledger.work += work;
    }

    /// Resets the per-step limit flags (called at a step's start).
    pub(crate) fn effects_begin_step(&mut self) {
        for e in self.joints.iter_mut().flatten() {
            e.effects.at_stop = [false; 6];
        }
    }

    /// Resets the per-substep force accumulators (called before a substep's first kick).
    pub(crate) fn effects_begin_substep(&mut self) {
        for e in self.joints.iter_mut().flatten() {
            e.effects.on_body2 = (Vector::ZERO, Vector::ZERO);
            e.effects.bounced.clear();
        }
    }

    /// Applies a force or moment along a free DOF (`FJ,elem,FX..MZ`; N or N m on node J, the
    /// reaction on node I) following `profile` in time. Replaces an earlier load on that DOF.
    #[doc(alias = "FJ")]
    pub fn set_load(
        &mut self,
        id: crate::error::JointId,
        dof: Dof,
        profile: crate::world::DriveProfile,
    ) -> Result<(), Error> {
        if self.settings().backend != crate::lower::Backend::Lagrange {
            return Err(Error::Unsupported {
                what: format!(
                    "an applied joint load (FJ) on the {} backend",
                    self.settings().backend.name()
                ),
                hint: "joint loads act on the Lagrange backend".into(),
            });
        }
        let entry = self
            .joints
            .get_mut(id.0 as usize)
            .and_then(Option::as_mut)
            .ok_or(Error::UnknownJoint(id))?;
        if !entry.joint.kind.free().contains(dof) {
            return Err(Error::InvalidDof {
                joint: id,
                dof,
                reason: format!("not a free DOF of a {} joint", entry.joint.kind.name()),
            });
        }
        if !(profile.t0.is_finite()
            && profile.t1.is_finite()
            && profile.from.is_finite()
            && profile.to.is_finite())
        {
            return Err(Error::InvalidDof {
                joint: id,
                dof,
                reason: "non-finite load profile".into(),
            });
        }
        entry.effects.loads.retain(|d| d.dof != dof);
        entry.effects.loads.push(Drive::new(dof, profile));
        Ok(())
    }

    /// Removes the applied load on a DOF (`FJDELE`).
    #[doc(alias = "FJDELE")]
    pub fn remove_load(&mut self, id: crate::error::JointId, dof: Dof) -> Result<(), Error> {
        let entry = self
            .joints
            .get_mut(id.0 as usize)
            .and_then(Option::as_mut)
            .ok_or(Error::UnknownJoint(id))?;
        entry.effects.loads.retain(|d| d.dof != dof);
        Ok(())
    }

    /// The energy balance now: kinetic, gravitational, spring, dissipated and the work of
    /// loads and drives (see [`EnergyReport`]).
    pub fn energy(&self) -> EnergyReport {
        let kinetic = self.kinetic_energy();
        let potential = self.potential_energy();
        let spring: Real = self
            .joints
            .iter()
            .flatten()
            .map(|e| e.output.spring_energy)
            .sum();
        let EnergyLedger { dissipated, work } = self.ledger;
        EnergyReport {
            kinetic,
            potential,
            spring,
            dissipated,
            work,
            total: kinetic + potential + spring + dissipated - work,
        }
    }
}
