//! Static (position) analysis of a kinematically driven mechanism: ANSYS `ANTYPE,STATIC` for a
//! mechanism with no free DOF left once its drives (`DJ`, nonzero `D`) are counted.
//!
//! `Mpc184World::static_step` advances the time by `dt` and solves the configuration from the
//! constraint equations alone, at the drives' values of the new time (masses play no part):
//!
//! 1. predictor: the last two solutions extrapolated linearly (translation and rotation);
//! 2. Newton on `C(q) = 0` with every row hard (penalty joints too: without dynamics their
//!    springs carry no load): the minimum-norm step `dq = W^-1 J^T (J W^-1 J^T)^-1 (-C)` in the
//!    metric `W = diag(1, 1, 1, l^2, l^2, l^2)` per body (`l` its size: the largest distance
//!    of its joint points from its centre), solved by the block-sparse KKT factorisation of the
//!    dynamics (the block-sparse KKT solver, redundant rows dropped); backtracking halves a step that
//!    does not reduce the residual; converged when every row is below `STATIC_TOLERANCE`;
//! 3. the mobility `6 n_bodies - rank(J)` (drives included) from the same factorisation: a
//!    positive mobility is [`Error::StaticEquilibrium`] (static equilibrium of a mechanism with
//!    free DOFs, which needs the loads and the stiffness, is not supported);
//! 4. reactions from statics: with `J` of full column rank, `J^T lambda = f` has a solution for
//!    the loads `f` on the bodies (gravity, the bodies' user forces and torques: the deck's
//!    `F`, the joints' `FJ` loads and springs), and every joint's force and moment on node J are
//!    its rows' share (redundant rows carry none, as in the dynamics). Dampers, friction,
//!    stops and locks do not act (no velocities: a driven mechanism's motion is fixed by its
//!    drives; a lock engaged before stays held).
//!
//! The bodies are left at rest (velocities 0, the output's rates 0, kinetic energy 0), as in an
//! ANSYS static analysis. The energy ledger books the work of the drives (their reaction
//! averaged over the step times the change of the prescribed value) and of the `FJ` loads (the
//! same with the DOF's change), so `energy()` balances to `O(dt^2)`.

use std::collections::BTreeMap;

use crate::backend::Sets;
use crate::dof::Dof;
use crate::error::{Error, JointId};
use crate::math::rapier::dynamics::RigidBodyHandle;
use crate::math::{Pose, Real, Rotation, Vector};
use crate::rows::{FramePair, RowEval, RowKind};
use crate::solver::kkt::{JointBlockSpec, KktError, KktSolver};

/// The Newton iteration stops when every constraint row is below this (m or rad; f32 builds
/// stop at `10 Real::EPSILON`).
pub const STATIC_TOLERANCE: Real = 1e-12;

/// Largest number of Newton iterations per static step.
const MAX_ITERATIONS: usize = 50;

/// Halvings of a Newton step that does not reduce the residual.
const MAX_BACKTRACKS: usize = 12;

/// What one static step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StaticReport {
    /// Newton iterations taken.
    pub iterations: usize,
    /// Largest constraint residual at the end (m or rad).
    pub residual: Real,
    /// Constraint rows found redundant (dropped) at the solution.
    pub redundant_rows: usize,
}

/// State kept between static steps (not model data).
#[derive(Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct StaticState {
    /// The last two solutions (older first), for the predictor.
    history: Vec<Vec<(RigidBodyHandle, Pose)>>,
    /// Per (joint, driven DOF): the drive's reaction multiplier and prescribed value at the
    /// last solution.
    drives: BTreeMap<(usize, Dof), (Real, Real)>,
    /// Per (joint, loaded DOF): the load and the DOF's measure at the last solution.
    loads: BTreeMap<(usize, Dof), (Real, Real)>,
    /// The factorisation (a workspace: rebuilt when the structure changes).
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    kkt: Option<KktSolver>,
}

/// One body of the static system.
#[derive(Clone, Copy, Debug)]
struct Unknown {
    handle: RigidBodyHandle,
    pose: Pose,
    local_com: Vector,
    /// The metric's rotational weight `l^2` (m^2).
    weight: Real,
}

impl Unknown {
    fn com(&self) -> Vector {
        self.pose * self.local_com
    }

    /// Moves the centre of mass by `dx` and turns the body by the rotation vector `dth` about it.
    fn displace(&mut self, dx: Vector, dth: Vector) {
        let c = self.com() + dx;
        let rot: Rotation = (Rotation::from_scaled_axis(dth) * self.pose.rotation).normalize();
        self.pose.rotation = rot;
        self.pose.translation = c - rot * self.local_com;
    }
}

/// The assembled rows: block specs, Jacobian arena, values, and per row (joint index, row index
/// in the joint or `None` for an extra drive row, its evaluation).
struct System {
    specs: Vec<JointBlockSpec>,
    jac: Vec<Real>,
    value: Vec<Real>,
    owner: Vec<(usize, Option<usize>, RowEval)>,
}

/// A solved static step, before its reactions: the new time, the bodies there, the rows at
/// the solution, the joints' measures at the step's start, and the Newton figures.
pub(crate) struct Solution {
    t1: Real,
    dt: Real,
    unknowns: Vec<Unknown>,
    sys: System,
    before: Vec<[Real; 6]>,
    iterations: usize,
    residual: Real,
}

impl Solution {
    /// The time the bodies were solved at (s).
    pub(crate) fn time(&self) -> Real {
        self.t1
    }
}

fn kkt_error(time: Real, e: KktError) -> Error {
    Error::Diverged {
        time,
        joint: None,
        reason: format!("static position solve: constraint factorisation failed: {e}"),
    }
}

fn residual_of(s: &System) -> Real {
    s.value.iter().fold(0.0 as Real, |m, v| m.max(v.abs()))
}

impl StaticState {
    /// Free DOFs of the mechanism at its current configuration (see
    /// `Mpc184World::mobility`).
    pub(crate) fn mobility(
        &mut self,
        sets: &Sets,
        extra: &[(JointId, Dof)],
    ) -> Result<usize, Error> {
        let unknowns = unknowns(sets);
        let sys = system(sets, &unknowns, extra);
        let redundant = self.factor(sets.time, &unknowns, &sys)?;
        let rank = sys.value.len() - redundant;
        Ok((6 * unknowns.len()).saturating_sub(rank))
    }

    /// Solves the positions at `time + dt` (the first half of a static step, see the module
    /// docs): the bodies are left at rest there and the rows' references follow them. The
    /// caller advances the time and refreshes the joints' outputs, then calls
    /// [`StaticState::finish`].
    pub(crate) fn solve(&mut self, sets: &mut Sets, dt: Real) -> Result<Solution, Error> {
        if let Some((id, _)) = sets.springs.iter().next() {
            return Err(Error::Unsupported {
                what: format!("{id} in a static analysis"),
                hint: "the static analysis solves the positions of a driven mechanism and takes \
                       its reactions from the joints' loads; spring-damper elements act in \
                       transient runs (ANTYPE,TRANS)"
                    .into(),
            });
        }
        let t1 = sets.time + dt;
        let before: Vec<[Real; 6]> = sets
            .joints
            .slots()
            .iter()
            .map(|e| e.as_ref().map_or([0.0; 6], |e| e.state.output.measure))
            .collect();
        set_drive_targets(sets, t1);
        let mut unknowns = unknowns(sets);
        // Mobility at the start pose, before anything moves.
        let sys = system(sets, &unknowns, &[]);
        let redundant = self.factor(sets.time, &unknowns, &sys)?;
        let free = (6 * unknowns.len()).saturating_sub(sys.value.len() - redundant);
        if free > 0 {
            return Err(Error::StaticEquilibrium { free_dofs: free });
        }
        self.predict(&mut unknowns);
        let (sys, iterations, residual) = self.newton(sets, &mut unknowns, t1)?;
        // The solution: bodies at rest there.
        for u in &unknowns {
            let rb = &mut sets.physics.bodies[u.handle];
            rb.set_position(u.pose, false);
            rb.set_linvel(Vector::ZERO, false);
            rb.set_angvel(Vector::ZERO, false);
        }
        self.history
            .push(unknowns.iter().map(|u| (u.handle, u.pose)).collect());
        if self.history.len() > 2 {
            self.history.remove(0);
        }
        sets.joints.update_row_references(&sets.physics.bodies);
        Ok(Solution {
            t1,
            dt,
            unknowns,
            sys,
            before,
            iterations,
            residual,
        })
    }

    /// The second half of a static step: the mobility at the solution, then the reactions
    /// from statics and the work of drives and loads (the joints' outputs refreshed at the
    /// solution).
    pub(crate) fn finish(&mut self, sets: &mut Sets, s: Solution) -> Result<StaticReport, Error> {
        let redundant = self.factor(s.t1, &s.unknowns, &s.sys)?;
        let free = (6 * s.unknowns.len()).saturating_sub(s.sys.value.len() - redundant);
        if free > 0 {
            return Err(Error::StaticEquilibrium { free_dofs: free });
        }
        self.reactions(sets, &s)?;
        Ok(StaticReport {
            iterations: s.iterations,
            residual: s.residual,
            redundant_rows: redundant,
        })
    }

    /// The predictor: the last two solutions extrapolated (translation and rotation).
    fn predict(&self, unknowns: &mut [Unknown]) {
        if let [older, newer] = self.history.as_slice()
            && older.len() == unknowns.len()
            && newer.len() == unknowns.len()
        {
            for ((u, (h0, p0)), (h1, p1)) in unknowns.iter_mut().zip(older).zip(newer) {
                if u.handle == *h0 && u.handle == *h1 && u.pose == *p1 {
                    let turn = (p1.rotation * p0.rotation.inverse()).normalize();
                    u.pose = Pose::from_parts(
                        p1.translation * 2.0 - p0.translation,
                        (turn * p1.rotation).normalize(),
                    );
                }
            }
        }
    }

    /// Newton on `C(q) = 0` from the predicted poses, with backtracking: the rows at the
    /// solution, the iterations taken and the residual.
    fn newton(
        &mut self,
        sets: &Sets,
        unknowns: &mut [Unknown],
        t1: Real,
    ) -> Result<(System, usize, Real), Error> {
        let tol = STATIC_TOLERANCE.max(10.0 * Real::EPSILON);
        let mut sys = system(sets, unknowns, &[]);
        let mut residual = residual_of(&sys);
        let mut iterations = 0;
        while residual > tol {
            if iterations == MAX_ITERATIONS {
                return Err(Error::Diverged {
                    time: t1,
                    joint: None,
                    reason: format!(
                        "static position solve: no convergence after {MAX_ITERATIONS} Newton \
                         iterations (residual {residual:.3e}): the drives ask for a pose the \
                         mechanism cannot reach, or it passes a singular position"
                    ),
                });
            }
            iterations += 1;
            self.factor(sets.time, unknowns, &sys)?;
            let mut rhs_b = vec![[0.0 as Real; 6]; unknowns.len()];
            let mut rhs_j: Vec<Real> = sys.value.iter().map(|v| -v).collect();
            if let Some(kkt) = self.kkt.as_ref() {
                kkt.solve(&mut rhs_b, &mut rhs_j)
                    .map_err(|e| kkt_error(t1, e))?;
            }
            (sys, residual) = backtrack(sets, unknowns, &rhs_b, residual);
            if !residual.is_finite() {
                return Err(Error::Diverged {
                    time: t1,
                    joint: None,
                    reason: "static position solve: non-finite residual".into(),
                });
            }
        }
        Ok((sys, iterations, residual))
    }

    /// Factorises the static system (metric `W`, hard rows) and returns the number of redundant
    /// rows.
    fn factor(&mut self, time: Real, unknowns: &[Unknown], sys: &System) -> Result<usize, Error> {
        let rebuild = self.kkt.as_ref().is_none_or(|k| {
            k.joint_specs() != sys.specs.as_slice() || k.num_bodies() != unknowns.len()
        });
        if rebuild {
            self.kkt = Some(KktSolver::new(unknowns.len(), &sys.specs).map_err(|e| {
                Error::Unsupported {
                    what: format!("the constraint structure: {e}"),
                    hint: "a joint carries at most 12 rows".into(),
                }
            })?);
        }
        let mass: Vec<[Real; 36]> = unknowns
            .iter()
            .map(|u| {
                let mut m = [0.0; 36];
                for a in 0..3 {
                    m[6 * a + a] = 1.0;
                    m[6 * (3 + a) + 3 + a] = u.weight;
                }
                m
            })
            .collect();
        let compliance = vec![0.0; sys.value.len()];
        let Some(kkt) = self.kkt.as_mut() else {
            return Ok(0);
        };
        let report = kkt
            .factor(&mass, &sys.jac, &compliance)
            .map_err(|e| kkt_error(time, e))?;
        Ok(report.redundant_rows)
    }

    /// Reactions from statics at the solution (the factorisation is current) and the energy
    /// ledger's work of drives and loads over the step (trapezoidal; the first step, with no
    /// earlier reaction, takes the present one over the whole step).
    fn reactions(&mut self, sets: &mut Sets, s: &Solution) -> Result<(), Error> {
        let (mut rhs_b, element) = loads(sets, &s.unknowns, s.t1);
        // J^T lambda = f (J has full column rank): the constraint forces are -J^T lambda.
        let mut lambda = vec![0.0 as Real; s.sys.value.len()];
        if let Some(kkt) = self.kkt.as_ref() {
            kkt.solve(&mut rhs_b, &mut lambda)
                .map_err(|e| kkt_error(s.t1, e))?;
        }
        let mut wrench: Vec<(Vector, Vector)> =
            vec![(Vector::ZERO, Vector::ZERO); sets.joints.len()];
        let mut work = self.drive_work(sets, s, &lambda, &mut wrench);
        let mut loads_now = BTreeMap::new();
        for (j, total, on2) in element {
            wrench[j].0 += on2.0;
            wrench[j].1 += on2.1;
            if let Some(e) = sets.joints.get_mut(j) {
                e.state.output.element_force = total;
                for d in &e.loads {
                    let (load, at) = (d.profile.value(s.t1), e.state.output.measure[d.dof.index()]);
                    let (l0, m0) = self.loads.get(&(j, d.dof)).copied().unwrap_or((
                        d.profile.value(s.t1 - s.dt),
                        s.before.get(j).map_or(at, |m| m[d.dof.index()]),
                    ));
                    work += 0.5 * (l0 + load) * (at - m0);
                    loads_now.insert((j, d.dof), (load, at));
                }
            }
        }
        self.loads = loads_now;
        sets.ledger.work += work;
        let bodies = &sets.physics.bodies;
        for (j, e) in sets.joints.slots_mut().iter_mut().enumerate() {
            if let Some(e) = e {
                e.set_reaction(bodies, wrench[j].0, wrench[j].1);
            }
        }
        Ok(())
    }

    /// Each row's share of the joint wrenches (`-J^T lambda` on body 2) into `wrench`, and the
    /// work of the drives over the step.
    fn drive_work(
        &mut self,
        sets: &Sets,
        s: &Solution,
        lambda: &[Real],
        wrench: &mut [(Vector, Vector)],
    ) -> Real {
        let mut work = 0.0;
        let mut drives_now = BTreeMap::new();
        for ((j, n, ev), l) in s.sys.owner.iter().zip(lambda) {
            let lc = -*l;
            wrench[*j].0 += ev.j2[0] * lc;
            wrench[*j].1 += ev.j2[1] * lc;
            if let (Some(n), Some(e)) = (n, sets.joints.get(*j))
                && let RowKind::Drive { dof, target, .. } = e.state.rows[*n]
                && e.drives.iter().any(|d| d.dof == dof)
            {
                let (l0, v0) = match self.drives.get(&(*j, dof)) {
                    Some(p) => *p,
                    None => {
                        let d = e.drives.iter().find(|d| d.dof == dof);
                        (lc, d.map_or(target, |d| d.value(s.t1 - s.dt)))
                    }
                };
                work += 0.5 * (l0 + lc) * (target - v0);
                drives_now.insert((*j, dof), (lc, target));
            }
        }
        self.drives = drives_now;
        work
    }
}

/// Sets every drive row's target to the drive's value at `t1`.
fn set_drive_targets(sets: &mut Sets, t1: Real) {
    for e in sets.joints.iter_mut() {
        for r in e.state.rows.iter_mut() {
            if let RowKind::Drive { dof, target, .. } = r
                && let Some(d) = e.drives.iter().find(|d| d.dof == *dof)
            {
                *target = d.value(t1);
            }
        }
    }
}

/// One Newton step `rhs_b` from `unknowns`, halved until it reduces the residual (or too
/// small to halve again): the rows and the residual there.
fn backtrack(
    sets: &Sets,
    unknowns: &mut [Unknown],
    rhs_b: &[[Real; 6]],
    residual: Real,
) -> (System, Real) {
    let start = unknowns.to_vec();
    let mut step = 1.0;
    loop {
        for (u, (s, x)) in unknowns.iter_mut().zip(start.iter().zip(rhs_b)) {
            *u = *s;
            u.displace(
                Vector::new(x[0], x[1], x[2]) * step,
                Vector::new(x[3], x[4], x[5]) * step,
            );
        }
        let trial = system(sets, unknowns, &[]);
        let r = residual_of(&trial);
        if (r.is_finite() && r < residual) || step < 0.5f64.powi(MAX_BACKTRACKS as i32) as Real {
            return (trial, r);
        }
        step *= 0.5;
    }
}

/// The dynamic bodies (every one is an unknown of the static system) at their poses now,
/// with the metric weights.
fn unknowns(sets: &Sets) -> Vec<Unknown> {
    let mut out: Vec<Unknown> = sets
        .physics
        .bodies
        .iter()
        .filter(|(_, rb)| rb.is_dynamic())
        .map(|(h, rb)| Unknown {
            handle: h,
            pose: *rb.position(),
            local_com: rb.mass_properties().local_mprops.local_com,
            weight: 0.0,
        })
        .collect();
    let index = index_of(&out);
    for e in sets.joints.iter() {
        for (side, b) in [e.body1, e.body2].into_iter().enumerate() {
            if let Some(&i) = index.get(&b) {
                let u = &mut out[i];
                for frame in [e.low[side], e.ansys[side]] {
                    let at = (u.pose * frame).translation;
                    u.weight = u.weight.max((at - u.com()).length_squared());
                }
            }
        }
    }
    let largest = out.iter().map(|u| u.weight).fold(0.0, Real::max);
    let floor = if largest > 0.0 { 1e-6 * largest } else { 1.0 };
    for u in &mut out {
        u.weight = u.weight.max(floor);
    }
    out
}

fn index_of(unknowns: &[Unknown]) -> std::collections::HashMap<RigidBodyHandle, usize> {
    unknowns
        .iter()
        .enumerate()
        .map(|(i, u)| (u.handle, i))
        .collect()
}

/// Evaluates every joint row (and `extra` drive rows) at the unknowns' poses.
fn system(sets: &Sets, unknowns: &[Unknown], extra: &[(JointId, Dof)]) -> System {
    let index = index_of(unknowns);
    let mut sys = System {
        specs: Vec::new(),
        jac: Vec::new(),
        value: Vec::new(),
        owner: Vec::new(),
    };
    for (j, e) in sets.joints.slots().iter().enumerate() {
        let Some(e) = e else { continue };
        let side = |b: RigidBodyHandle| -> ((Pose, Vector), Option<usize>) {
            match index.get(&b) {
                Some(&i) => ((unknowns[i].pose, unknowns[i].com()), Some(i)),
                None => (crate::body::pose_and_com(&sets.physics.bodies[b]), None),
            }
        };
        let (s1, i1) = side(e.body1);
        let (s2, i2) = side(e.body2);
        let f = FramePair::at(&e.low, s1, s2);
        let mut rows: Vec<(Option<usize>, RowKind)> = e
            .state
            .rows
            .iter()
            .copied()
            .enumerate()
            .map(|(n, r)| (Some(n), r))
            .collect();
        for (id, dof) in extra {
            if id.0 as usize == j && !e.drives.iter().any(|d| d.dof == *dof) {
                rows.push((
                    None,
                    RowKind::Drive {
                        dof: *dof,
                        target: 0.0,
                        initial: e.initial[dof.index()],
                        reference: e.state.output.measure[dof.index()],
                    },
                ));
            }
        }
        if rows.is_empty() || (i1.is_none() && i2.is_none()) {
            continue;
        }
        sys.specs.push(JointBlockSpec {
            rows: rows.len(),
            bodies: [i1, i2],
        });
        for (n, r) in rows {
            let ev = r.eval(&f);
            for half in [ev.j1, ev.j2] {
                sys.jac
                    .extend_from_slice(&[half[0].x, half[0].y, half[0].z]);
                sys.jac
                    .extend_from_slice(&[half[1].x, half[1].y, half[1].z]);
            }
            sys.value.push(ev.value);
            sys.owner.push((j, n, ev));
        }
    }
    sys
}

/// Per joint element (index, generalised force per DOF, wrench on body 2)
type Elements = Vec<(usize, [Real; 6], (Vector, Vector))>;

/// The loads on the bodies at `t1` (gravity, user force and torque about the centre of mass,
/// the joints' `FJ` loads and springs as generalised forces on the free DOFs), and each joint
/// element's forces.
fn loads(sets: &Sets, unknowns: &[Unknown], t1: Real) -> (Vec<[Real; 6]>, Elements) {
    let index = index_of(unknowns);
    let g = sets.physics.gravity;
    let bodies = &sets.physics.bodies;
    let mut rhs_b: Vec<[Real; 6]> = unknowns
        .iter()
        .map(|u| {
            let rb = &bodies[u.handle];
            let f = g * (rb.mass() * rb.gravity_scale()) + rb.user_force();
            let t = rb.user_torque();
            [f.x, f.y, f.z, t.x, t.y, t.z]
        })
        .collect();
    let mut element: Elements = Vec::new();
    for (j, e) in sets.joints.slots().iter().enumerate() {
        let Some(e) = e else { continue };
        let b = &e.joint.behaviour;
        if !b.has_forces() && e.loads.is_empty() {
            continue;
        }
        let f = FramePair::at(
            &e.ansys,
            crate::body::pose_and_com(&bodies[e.body1]),
            crate::body::pose_and_com(&bodies[e.body2]),
        );
        let o = &e.state.output;
        let (m, rows) = crate::behaviour::dof_rows(&f, [o.measure[3], o.measure[5]]);
        let free = e.joint.kind.free();
        let x: [Real; 6] = core::array::from_fn(|k| m[k] - b.reference[k].unwrap_or(e.initial[k]));
        let mut total = [0.0 as Real; 6];
        if let Some(kmat) = &b.stiffness {
            let kx = kmat.apply(&x, free);
            for k in 0..6 {
                total[k] -= kx[k];
            }
        }
        for k in 0..6 {
            if free.contains(Dof::ALL[k])
                && let Some(t) = &b.stiffness_tables[k]
            {
                total[k] -= t.eval(x[k]).0;
            }
        }
        for d in &e.loads {
            total[d.dof.index()] += d.profile.value(t1);
        }
        let (mut f2, mut t2) = (Vector::ZERO, Vector::ZERO);
        for (k, row) in rows.iter().enumerate() {
            if total[k] == 0.0 {
                continue;
            }
            f2 += row.j2[0] * total[k];
            t2 += row.j2[1] * total[k];
            for (b, jb) in [(e.body1, row.j1), (e.body2, row.j2)] {
                if let Some(&i) = index.get(&b) {
                    for a in 0..3 {
                        rhs_b[i][a] += jb[0][a] * total[k];
                        rhs_b[i][3 + a] += jb[1][a] * total[k];
                    }
                }
            }
        }
        element.push((j, total, (f2, t2)));
    }
    (rhs_b, element)
}
