//! Stops (`SECSTOP`) and locks (`SECLOCK`): the limits predicted active in a substep, solved
//! for non-negative impulses through the constrained system, at velocity level after the
//! velocity solve and at position level after the projection (see the parent module's docs).

use crate::behaviour::dof_rows;
use crate::catalogue::JointKind;
use crate::dof::Dof;
use crate::error::Error;
use crate::joint::ConstraintMethod;
use crate::math::{Real, Vector};
use crate::rows::RowEval;

use super::super::super::Sets;
use super::super::{Island, displace_state};
use super::{Effects, frames, responses};

/// Gap (m or rad) beyond which a limit is far enough for the position stage to skip it.
const LIMIT_MARGIN: Real = 1e-6;

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

/// Which stage asks, and with what.
#[derive(Clone, Copy)]
struct Stage {
    h: Real,
    /// Velocity level (`v'` in `rhs_b`, the gap after `h` predicted from it) or position level
    /// (the gap now, after the projection).
    velocity_level: bool,
    /// Position level: the violation a limit may keep (m or rad).
    tol: Real,
}

/// One limited joint as the stage sees it.
struct Limited {
    joint: usize,
    /// The DOFs' measures and rows (frame I).
    m: [Real; 6],
    rows: [RowEval; 6],
    slots: [Option<usize>; 2],
    /// The sides' velocities now (`v'` at velocity level) and at the substep's start.
    v: [[Vector; 2]; 2],
    v_start: [[Vector; 2]; 2],
    /// A stop that lands instead of reflecting (penalty method, screw joint).
    plastic: bool,
}

/// Collects the limits predicted active. `level`: velocity (`v` in `rhs_b`, the gap after `h`
/// predicted from it) or position (the gap now, after the projection).
fn active(ls: &mut Island, sets: &Sets, h: Real, velocity_level: bool, tol: Real) -> Vec<Active> {
    let stage = Stage {
        h,
        velocity_level,
        tol,
    };
    let mut out = Vec::new();
    // The smallest gap now or predicted after the substep (velocity level).
    let mut near = Real::INFINITY;
    for &j in &ls.members.clone() {
        let Some(e) = sets.joints.get(j) else {
            continue;
        };
        let b = &e.joint.behaviour;
        if b.stops.is_empty() && b.locks.is_empty() {
            continue;
        }
        let lim = limited(ls, sets, j, e, velocity_level);
        if velocity_level {
            hold_pending(&lim, &e.state.pending, h, &mut out);
        }
        let limits = b
            .stops
            .iter()
            .map(|l| (l, false))
            .chain(b.locks.iter().map(|l| (l, true)));
        for (l, is_lock) in limits {
            if e.state.locked[l.dof.index()].is_none() {
                near = near.min(limit_rows(&lim, l, is_lock, stage, &mut out));
            }
        }
    }
    if velocity_level {
        // Far from every limit (by more than the projection can move a DOF) and nothing
        // pending: the position stage has nothing to do this substep.
        let pending = (ls.members.iter())
            .filter_map(|&j| sets.joints.get(j))
            .any(|e| !e.state.pending.is_empty());
        ls.limits_clear = out.is_empty() && !pending && near > LIMIT_MARGIN;
    }
    out
}

/// Joint `j` as the limit stage sees it.
fn limited(
    ls: &Island,
    sets: &Sets,
    j: usize,
    e: &crate::joint_set::JointEntry,
    velocity_level: bool,
) -> Limited {
    let (f, slots, vel) = frames(ls, &sets.physics.bodies, e);
    let (m, rows) = dof_rows(&f, [e.state.output.measure[3], e.state.output.measure[5]]);
    let plastic = matches!(e.joint.method, ConstraintMethod::Penalty { .. })
        || matches!(e.joint.kind, JointKind::Screw { .. });
    // The velocity to predict with: the solved v' (rhs_b) for dynamic sides.
    let v_of = |slot: Option<usize>, fallback: [Vector; 2]| match slot {
        Some(i) if velocity_level => {
            let x = ls.rhs_b[i];
            [Vector::new(x[0], x[1], x[2]), Vector::new(x[3], x[4], x[5])]
        }
        _ => fallback,
    };
    Limited {
        joint: j,
        m,
        rows,
        slots,
        v: [v_of(slots[0], vel[0]), v_of(slots[1], vel[1])],
        v_start: vel,
        plastic,
    }
}

/// Locks engaged this step whose row joins at the next step: held at their value (landing
/// again at the end of the substep, the energy removed booked).
fn hold_pending(lim: &Limited, pending: &[(Dof, Real)], h: Real, out: &mut Vec<Active>) {
    for &(dof, value) in pending {
        let k = dof.index();
        let row = lim.rows[k];
        let rate = row.rate(lim.v[0], lim.v[1]);
        let target = -(lim.m[k] - value) / h;
        let side: Real = if rate > target { -1.0 } else { 1.0 };
        out.push(Active {
            joint: lim.joint,
            dof,
            side,
            row: RowEval {
                value: side * (lim.m[k] - value),
                j1: [row.j1[0] * side, row.j1[1] * side],
                j2: [row.j2[0] * side, row.j2[1] * side],
            },
            slots: lim.slots,
            change: side * (target - rate),
            before: side * rate,
            // Holding: the load's half kick put in what this takes out (both O(h^2) and booked
            // as neither).
            dissipative: false,
        });
    }
}

/// The sides of limit `l` (a stop, or a lock not yet engaged) predicted active; returns the
/// smallest gap now or predicted after the substep (velocity level; infinite otherwise).
fn limit_rows(
    lim: &Limited,
    l: &crate::behaviour::Limit,
    is_lock: bool,
    stage: Stage,
    out: &mut Vec<Active>,
) -> Real {
    let Stage {
        h,
        velocity_level,
        tol,
    } = stage;
    let mut near = Real::INFINITY;
    let k = l.dof.index();
    let row = lim.rows[k];
    let rate = row.rate(lim.v[0], lim.v[1]);
    // The rate at the start of the substep, before this substep's forces.
    let rate_n = row.rate(lim.v_start[0], lim.v_start[1]);
    for (side, limit) in [(1.0 as Real, l.min), (-1.0, l.max)] {
        if !limit.is_finite() {
            continue;
        }
        let gap = side * (lim.m[k] - limit);
        let g_rate = side * rate;
        if velocity_level {
            near = near.min(gap).min(gap + h * g_rate);
        }
        let (change, dissipative) = if velocity_level {
            if gap + h * g_rate >= 0.0 || g_rate >= 0.0 && gap >= 0.0 {
                continue;
            }
            let land = -gap / h;
            if lim.plastic || is_lock {
                (land.max(0.0) - g_rate, true)
            } else {
                // Elastic: the scheme's velocities are half-step velocities (positions advance
                // with the end-of-substep velocity), so the energy-consistent reflection at the
                // substep's start reverses the rate the substep started with: `g+ = -g_n` (the
                // velocity at `t_n`, the mean of the two half steps, changes sign exactly:
                // reversing `g'` instead gains `h |g'| |a|` per impact, measured as +2.4e-3
                // m g L per impact on the stop pendulum). Never left beyond the limit at the
                // substep's end.
                let bounce = -(side * rate_n).min(0.0);
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
        out.push(Active {
            joint: lim.joint,
            dof: l.dof,
            side,
            row: RowEval {
                value: gap,
                j1: [row.j1[0] * side, row.j1[1] * side],
                j2: [row.j2[0] * side, row.j2[1] * side],
            },
            slots: lim.slots,
            change,
            before: g_rate,
            dissipative,
        });
    }
    near
}

impl Effects {
    /// Solves for non-negative impulses on the active limits through the constrained system
    /// (current factorisation) and applies them: to the velocities in `rhs_b` (velocity level)
    /// or as displacements of the body states (position level, fed into the velocity as
    /// `dx / h`). Returns the impulses.
    fn resolve(
        &mut self,
        ls: &mut Island,
        sets: &mut Sets,
        active: &[Active],
        h: Real,
        velocity_level: bool,
    ) -> Result<Vec<Real>, Error> {
        let n = active.len();
        let nb = ls.bodies.len();
        let time = sets.time;
        let rows: Vec<(RowEval, [Option<usize>; 2])> =
            active.iter().map(|a| (a.row, a.slots)).collect();
        let responses = responses(ls, &rows, sets.time)?;
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
                    displace_state(s, d);
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
                    ls.ledger.dissipated -= p[a] * 0.5 * (act.before + after);
                    // A lock removes what is left of the approach at the next substep: book
                    // it now (`g+^2 / (2 W)` with `W` the DOF's effective inverse mass).
                    let is_lock = sets.joints.get(act.joint).is_some_and(|e| {
                        e.joint.behaviour.locks.iter().any(|l| l.dof == act.dof)
                            && e.state.locked[act.dof.index()].is_none()
                    });
                    if is_lock && w[a][a] > 0.0 {
                        ls.ledger.dissipated += 0.5 * after * after / w[a][a];
                    }
                }
            }
            let impulse = if velocity_level { p[a] } else { p[a] / h };
            if let Some(e) = sets.joints.get_mut(act.joint) {
                e.state.at_stop[act.dof.index()] = true;
                let scratch = &mut self.scratch[act.joint];
                if velocity_level && !act.dissipative {
                    scratch.bounced.push((act.dof, act.side));
                }
                let (f, t) = &mut scratch.on_body2;
                *f += act.row.j2[0] * (impulse / h);
                *t += act.row.j2[1] * (impulse / h);
            }
        }
        Ok(p)
    }

    /// The velocity-level limit stage, right after the velocity solve (`v'` in `rhs_b`).
    pub(crate) fn limits_velocity(
        &mut self,
        ls: &mut Island,
        sets: &mut Sets,
        h: Real,
    ) -> Result<(), Error> {
        let active = active(ls, sets, h, true, 0.0);
        if active.is_empty() {
            return Ok(());
        }
        self.resolve(ls, sets, &active, h, true)?;
        // Locks that acted engage now (held at their limit from here on).
        for a in &active {
            let Some(e) = sets.joints.get_mut(a.joint) else {
                continue;
            };
            let b = &e.joint.behaviour;
            let k = a.dof.index();
            if e.state.locked[k].is_some() {
                continue;
            }
            if let Some(l) = b.locks.iter().find(|l| l.dof == a.dof) {
                let value = if a.side > 0.0 { l.min } else { l.max };
                e.state.locked[k] = Some(value);
                e.state.pending.push((a.dof, value));
            }
        }
        Ok(())
    }

    /// The position-level limit stage after the projection: limits violated by more than
    /// `tol` are projected back; locks engaged this step are held at their values until their
    /// row joins at the next step. Returns whether it moved bodies.
    pub(crate) fn limits_position(
        &mut self,
        ls: &mut Island,
        sets: &mut Sets,
        h: Real,
        tol: Real,
    ) -> Result<bool, Error> {
        if ls.limits_clear {
            return Ok(false);
        }
        let mut active = active(ls, sets, h, false, tol);
        // Locked DOFs whose row is still pending: hold them at their value (both sides).
        for &j in &ls.members {
            let Some(e) = sets.joints.get(j) else {
                continue;
            };
            if e.state.pending.is_empty() {
                continue;
            }
            let (f, slots, _) = frames(ls, &sets.physics.bodies, e);
            let (m, rows) = dof_rows(&f, [e.state.output.measure[3], e.state.output.measure[5]]);
            for &(dof, value) in &e.state.pending {
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
            return Ok(false);
        }
        self.resolve(ls, sets, &active, h, false)?;
        Ok(true)
    }
}
