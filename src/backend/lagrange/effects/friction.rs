//! Joint friction on the Lagrange backend: per joint with friction, the bounded impulse on its
//! free DOF(s) that sticks it if `|p| <= mu(V) N h` allows, else slides at the bound; `N` from
//! the joint's reactions of this substep (`Friction::normal`), recomputed after each of three
//! passes (the friction impulse changes the reactions through the constrained system: the
//! screw jack's normal force depends on the friction itself).

use crate::behaviour::{Friction, dof_rows};
use crate::catalogue::JointKind;
use crate::error::Error;
use crate::joint_set::{JointEntry, JointSet};
use crate::math::{Real, Vector};
use crate::output::FrictionState;
use crate::rows::{FramePair, RowEval, RowKind};
use crate::solver::kkt::JAC_ROW_STRIDE;

use super::super::super::Sets;
use super::super::Island;
use super::{Effects, Responses, frames, responses};

/// Passes of the friction solve per substep (each with the normal force updated).
const PASSES: usize = 3;

/// The friction rows of one joint and the body slots they act on.
type FrictionRows = Vec<(RowEval, [Option<usize>; 2])>;

/// What the friction solve of one joint found.
struct Outcome {
    /// The friction impulse on each row (N s or N m s).
    total: Vec<Real>,
    stick: bool,
    normal: Real,
    mu: Real,
}

impl Effects {
    /// The friction stage, after the limits (`v'` in `rhs_b`; see the module docs).
    pub(crate) fn friction(
        &mut self,
        ls: &mut Island,
        sets: &mut Sets,
        h: Real,
    ) -> Result<(), Error> {
        for &j in &ls.members.clone() {
            let Some(e) = sets.joints.get(j) else {
                continue;
            };
            let Some(fr) = e.joint.behaviour.friction.clone() else {
                continue;
            };
            let Some(dofs) = Friction::dofs(&e.joint.kind) else {
                continue;
            };
            let (f, slots, _) = frames(ls, &sets.physics.bodies, e);
            let frows = friction_rows(e, &fr, dofs, &f, slots);
            let responses = responses(ls, &frows, sets.time)?;
            if responses.len() != frows.len() {
                continue;
            }
            let out = solve(ls, sets.joints, j, &fr, &f, &frows, &responses, h);
            let g1: Vec<Real> = frows.iter().map(|(r, s)| rate(ls, r, *s)).collect();
            let mut lost = 0.0;
            for (p, g) in out.total.iter().zip(&g1) {
                // Work = force times the DOF's actual travel in the substep (positions advance
                // with the rate after the impulse): on the sliding incline this books exactly
                // `mu N s` (measured to 4e-8), where the mean of the rates before and after
                // (the impulse's kinetic-energy change) overbooks by `p^2 / 2m` per substep.
                lost -= p * g;
            }
            ls.ledger.dissipated += lost;
            let (mut f2, mut t2) = (Vector::ZERO, Vector::ZERO);
            for (a, (row, _)) in frows.iter().enumerate() {
                f2 += row.j2[0] * (out.total[a] / h);
                t2 += row.j2[1] * (out.total[a] / h);
            }
            let scratch = &mut self.scratch[j];
            scratch.on_body2.0 += f2;
            scratch.on_body2.1 += t2;
            if let Some(e) = sets.joints.get_mut(j) {
                e.state.friction = Some(FrictionState {
                    slipping: !out.stick,
                    slip_rate: g1.iter().map(|g| g * g).sum::<Real>().sqrt(),
                    force: out.total.iter().map(|x| x * x).sum::<Real>().sqrt() / h,
                    normal: out.normal,
                    mu: out.mu,
                });
            }
        }
        Ok(())
    }
}

/// The rows friction acts along: the friction DOFs' rows; for the screw, the helix.
///
/// The screw's thread friction acts along the helix at the mean radius r, not as a pure
/// moment: the row `(p J_uz + r^2 J_theta) / (r^2 + p^2)` reads the screw rate on the
/// constraint manifold and applies (axial force, moment / r) in the ratio (p, r), tangent to
/// the thread, so that it leaves the thread's normal force alone (a pure moment would load the
/// thread and change N).
fn friction_rows(
    e: &JointEntry,
    fr: &Friction,
    dofs: &[crate::dof::Dof],
    f: &FramePair,
    slots: [Option<usize>; 2],
) -> FrictionRows {
    let o = &e.state.output;
    let (_, rows) = dof_rows(f, [o.measure[3], o.measure[5]]);
    let mut frows: FrictionRows = dofs.iter().map(|d| (rows[d.index()], slots)).collect();
    if let JointKind::Screw { pitch } = e.joint.kind {
        let r = fr.geometry[0].unwrap_or(1.0);
        let l2 = r * r + pitch * pitch;
        let lin = RowKind::Linear { axis: 2 }.eval(f);
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
    frows
}

/// A row's rate for the velocities in `rhs_b`.
fn rate(ls: &Island, row: &RowEval, slots: [Option<usize>; 2]) -> Real {
    let mut g = 0.0;
    for (slot, jb) in [(slots[0], row.j1), (slots[1], row.j2)] {
        if let Some(i) = slot {
            let x = ls.rhs_b[i];
            g +=
                jb[0].dot(Vector::new(x[0], x[1], x[2])) + jb[1].dot(Vector::new(x[3], x[4], x[5]));
        }
    }
    g
}

/// The friction impulses of one joint (see the module docs): applied to `rhs_b` and to the
/// joint rows' impulses as they are found.
#[expect(
    clippy::too_many_arguments,
    reason = "the inner kernel of the friction stage, called once; the arguments are the \
              pieces the stage has already computed"
)]
fn solve(
    ls: &mut Island,
    joints: &JointSet,
    j: usize,
    fr: &Friction,
    f: &FramePair,
    frows: &FrictionRows,
    responses: &Responses,
    h: Real,
) -> Outcome {
    let n = frows.len();
    let nb = ls.bodies.len();
    let w = delassus(frows, responses);
    let g0: Vec<Real> = frows.iter().map(|(r, s)| rate(ls, r, *s)).collect();
    let speed = g0.iter().map(|g| g * g).sum::<Real>().sqrt();
    let mu = fr.law.mu(speed);
    let mut total = vec![0.0; n];
    let mut stick = true;
    let mut normal = 0.0;
    for _ in 0..PASSES {
        normal = normal_force(ls, joints, j, fr, f, h);
        let mut bound = mu * normal;
        if let Some(cap) = fr.max_force {
            bound = bound.min(cap);
        }
        let bound = bound * h;
        // Impulse that sticks: total - W^-1 g (Gauss-Seidel on the small system).
        let g: Vec<Real> = frows.iter().map(|(r, s)| rate(ls, r, *s)).collect();
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
    Outcome {
        total,
        stick,
        normal,
        mu,
    }
}

/// The friction rows' Delassus matrix `W = J_f (response to a unit impulse on each row)`.
fn delassus(frows: &FrictionRows, responses: &Responses) -> Vec<Vec<Real>> {
    frows
        .iter()
        .map(|(row, slots)| {
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
        .collect()
}

/// The normal force (or moment) of joint `j` from its reactions in this substep so far; the
/// screw's from its thread load.
fn normal_force(
    ls: &Island,
    joints: &JointSet,
    j: usize,
    fr: &Friction,
    f: &FramePair,
    h: Real,
) -> Real {
    let Some(e) = joints.get(j) else { return 0.0 };
    let (l, screw) = reactions(ls, e, j, f, h);
    match e.joint.kind {
        JointKind::Screw { pitch } => {
            let r = fr.geometry[0].unwrap_or(1.0);
            fr.interference
                + screw.abs()
                    * (1.0 + pitch * pitch / (r * r)).sqrt()
                    * (r * r + pitch * pitch).sqrt()
        }
        kind => fr.normal(&kind, &l),
    }
}

/// The reactions of joint `j` in this substep so far (forces then moments on node J, frame I;
/// N and N m) from its rows' impulses, and the screw coupling row's multiplier.
///
/// The impulses so far answer the kick before the velocity solve: the whole substep's forces
/// in the first-order step, half of them in RATTLE (its first half kick), so they are divided
/// by `h` or by `h / 2`. (Dividing RATTLE's by `h` halved the normal force: a friction wheel
/// broke away at half its limit moment.)
fn reactions(ls: &Island, e: &JointEntry, j: usize, f: &FramePair, h: Real) -> ([Real; 6], Real) {
    let Some((k, range)) =
        (ls.blocks.binary_search(&j).ok()).and_then(|k| Some((k, ls.block_rows(k)?)))
    else {
        return ([0.0; 6], 0.0);
    };
    let half = (ls.kkt.as_ref())
        .and_then(|kkt| kkt.joint_specs().get(k))
        .is_some_and(|spec| spec.bodies.iter().flatten().any(|&i| ls.second[i]));
    let span = if half { 0.5 * h } else { h };
    let (mut force, mut torque, mut screw) = (Vector::ZERO, Vector::ZERO, 0.0);
    for (row, r) in e.state.rows.iter().zip(range) {
        let jr = &ls.jac[JAC_ROW_STRIDE * r..];
        let m = ls.impulse[r] / span;
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
