//! The Lagrange-multiplier backend (KEYOPT(2) = 0) and its penalty variant (KEYOPT(2) = 1).
//!
//! Rapier keeps bodies, colliders, contacts and integration; this module owns the joints. Every
//! substep `h` it runs the constrained symplectic Euler scheme measured in
//! `reference/lagrange-on-rapier.md` (scheme B, the SHAKE/RATTLE-consistent projection):
//!
//! 1. `v* = v + h M^-1 f` (gravity, user forces, the gyroscopic torque `-w x Iw`);
//! 2. velocity solve at `q_n`: `(J M~^-1 J^T + C) lambda = -J v* - C_pen / h` (the last term
//!    for penalty rows only), `v' = v* + M~^-1 J^T lambda`, handed to Rapier for one substep
//!    (gravity and user forces held back so that Rapier integrates exactly `v'`; contacts act);
//! 3. position projection along the START-of-substep directions `M~^-1 J_n^T`: chord
//!    iterations on the same factorisation until `|C| < tol` on every Lagrange row, and the
//!    correction divided by `h` is fed into the velocity;
//! 4. rows at `q_(n+1)`, one factorisation (reused by the next substep's velocity solve), and
//!    the velocity projection `J v = 0`.
//!
//! With [`Integrator::Rattle`](crate::world::Integrator::Rattle) the same four stages form
//! RATTLE (second order): stage 1 kicks by `h/2` only (forces and the implicit-midpoint
//! gyroscopic term at `q_n`), stage 2 hands Rapier `w` scaled by `tan(|w| h/2) / (|w| h/2)` so
//! that its linearised quaternion update turns the body by exactly `|w| h`, and stage 4 adds
//! the second half kick with the forces at `q_(n+1)` before the velocity projection, so the
//! velocities live at whole steps. A stop that reflects in a substep is followed by the
//! energy-consistent velocity update of Laursen and Love (2002) (the outgoing rate along the
//! stop set so that the substep keeps its energy, see
//! `Mpc184World::effects_energy_fix`). An island with an active contact takes the first-order
//! step for that step (Rapier's contact solve is first order; mixing would lose the order
//! anyway), reported in [`LagrangeDiagnostics`]. Measured (`tests/rattle_*.rs`): observed order
//! 2.00 against 1.02, energy oscillation of the 90 deg pendulum at dt 1/60 x 4 6.4e-5 m g L
//! against 5.7e-3, a stop impact changing the energy by 3.7e-7 m g L against 2.3e-3.
//!
//! The linear algebra is the block-sparse `LDL^T` of the KKT system ([`crate::solver::kkt`]):
//! linear time for trees, a little fill for loops, redundant rows (the Bricard mechanism, planar
//! loops of 3D revolutes) dropped with their multipliers set to zero.
//!
//! `M~` is the mass matrix plus, for bodies whose rotation is driven by a tensioned joint at a
//! lever arm much faster than the substep can follow (`h omega > 1/2`, `omega^2 = |F| r /
//! (I_min + m r^2)`), the added rotational inertia `h^2 |F| r`: the geometric stiffness of the
//! joint force treated implicitly as added mass (Andrews, Teichmann, Kry 2017, "Geometric
//! stiffness for real-time constrained multibody dynamics"; the scheme of Tournier et al. 2015
//! with a diagonal approximation). It is zero on well-resolved bodies, so pendulums and slow
//! mechanisms are untouched, and it makes the 1:1000 chain stable at 4 substeps where the
//! explicit directions need 8.
//!
//! Reactions are the multipliers: the impulse of each row over the substep (velocity solve,
//! position correction / h, velocity projection) divided by `h`.

use std::collections::HashMap;

use crate::error::Error;
use crate::joint::ConstraintMethod;
use crate::math::rapier::dynamics::RigidBodyHandle;
use crate::math::{Matrix, Pose, Real, Rotation, Vector};
use crate::rows::RowKind;
use crate::solver::kkt::{JAC_ROW_STRIDE, JointBlockSpec, KktSolver};
use crate::world::{Mpc184World, frame_pair};

/// Default penalty stiffness on translations (N/m) for `SECJOINT,PNLT,DISP,val > 0` (scaled by
/// val) : stiff against typical machine loads (1 kN gives 10 um).
pub const DEFAULT_PENALTY_DISP: Real = 1e8;
/// Default penalty stiffness on rotations (N m/rad).
pub const DEFAULT_PENALTY_ROT: Real = 1e8;

/// Relative regularisation of hard (Lagrange) rows, see `lagrange_rows`.
const REGULARISATION: Real = 1e-8;

/// The position projection stops once every row's residual is below this (m or rad; f32
/// builds stop at their round-off, `10 Real::EPSILON`).
pub const PROJECTION_TOLERANCE: Real = 1e-10;

/// A warm start leaving a residual above this (m or rad) is undone.
const WARM_START_LIMIT: Real = 1e-3;

/// Fixed-point iterations of the implicit-midpoint gyroscopic term per body and substep.
const GYRO_ITERATIONS: usize = 4;

/// Largest number of chord iterations of the position projection per substep.
const MAX_PROJECTION_ITERATIONS: usize = 40;

#[derive(Clone, Copy, Debug, Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct BodyState {
    pub(crate) pose: Pose,
    pub(crate) com: Vector,
    pub(crate) mass: Real,
    pub(crate) inertia: Matrix,
    pub(crate) inertia_inv: Matrix,
    pub(crate) min_inertia: Real,
    pub(crate) linvel: Vector,
    pub(crate) angvel: Vector,
    pub(crate) force: Vector,
    pub(crate) torque: Vector,
    pub(crate) added: Real,
    pub(crate) principal: Vector,
    pub(crate) principal_inv: Vector,
    pub(crate) principal_frame: Rotation,
}

impl BodyState {
    /// World inertia tensor and its inverse at the current rotation.
    fn refresh_inertia(&mut self) {
        let r = Matrix::from_quat(self.pose.rotation * self.principal_frame);
        self.inertia = r * Matrix::from_diagonal(self.principal) * r.transpose();
        self.inertia_inv = r * Matrix::from_diagonal(self.principal_inv) * r.transpose();
    }
}

/// Diagnostics of the Lagrange backend.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LagrangeDiagnostics {
    /// Redundant constraint rows: those of the structure (found once per topology, without
    /// regularisation) or dropped by the last factorisation, whichever is more.
    pub redundant_rows: usize,
    /// Largest constraint residual left by the position projection in the last step (m or rad).
    pub projection_residual: Real,
    /// Chord iterations of the last substep's position projection.
    pub projection_iterations: usize,
    /// Bodies that received added (geometric-stiffness) inertia in the last substep.
    pub stiffened_bodies: usize,
    /// Bodies integrated by the first-order step in the last step although the world asked for
    /// [`Integrator::Rattle`](crate::world::Integrator::Rattle): their island had an active
    /// contact.
    pub first_order_bodies: usize,
    /// Steps so far in which some island fell back to the first-order step (contacts).
    pub first_order_steps: usize,
    /// Warnings issued once (redundant constraints, unconverged projections).
    pub warnings: Vec<String>,
}

/// Solver state and buffers (not part of the model data). A snapshot holds all of it but the
/// factorisation (`crate::snapshot`): a field added here is part of it.
#[derive(Default)]
#[cfg_attr(
    feature = "serde-snapshot",
    derive(serde::Serialize, serde::Deserialize)
)]
pub(crate) struct LagrangeState {
    pub(crate) dirty: bool,
    /// Number of colliders when the topology was built (a change rebuilds it).
    colliders: usize,
    pub(crate) bodies: Vec<RigidBodyHandle>,
    /// Rebuilt from `bodies` on restoring a snapshot (a hash map's order is not the same in two
    /// runs, and the snapshot's bytes should be).
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    pub(crate) index: HashMap<RigidBodyHandle, usize>,
    /// KKT block k -> world joint index, and back.
    blocks: Vec<usize>,
    block_of: Vec<Option<usize>>,
    #[cfg_attr(feature = "serde-snapshot", serde(skip))]
    pub(crate) kkt: Option<KktSolver>,
    pub(crate) st: Vec<BodyState>,
    #[cfg_attr(feature = "serde-snapshot", serde(with = "crate::snapshot::blocks36"))]
    pub(crate) mass: Vec<[Real; 36]>,
    pub(crate) jac: Vec<Real>,
    pub(crate) compliance: Vec<Real>,
    /// Per row: constraint value, kinematic-body velocity term, whether it is a penalty row.
    value: Vec<Real>,
    kin: Vec<Real>,
    penalty: Vec<bool>,
    /// Penalty stiffness per row (0 on Lagrange rows).
    pub(crate) kpen: Vec<Real>,
    /// Prescribed rate of each row over the current substep (drives; 0 elsewhere).
    pub(crate) rate: Vec<Real>,
    /// Scale of the hard rows' regularisation (raised by a failing projection).
    reg_scale: Real,
    /// The last projection step, to undo it: body states before it, its displacement and
    /// multipliers.
    backup: Vec<BodyState>,
    last_x: Vec<[Real; 6]>,
    last_lambda: Vec<Real>,
    /// The constraints were found redundant (rank deficient) at the last topology check.
    redundant: bool,
    /// The number of redundant rows that check found.
    redundant_count: usize,
    /// `value` holds the rows at the current body states (saves one evaluation).
    fresh_values: bool,
    /// The factorisation matches the states written back to Rapier at the end of the last
    /// substep (with this `h`), so the next step can start without refactorising.
    pub(crate) factor_valid: Option<Real>,
    written: Vec<(Pose, Vector, Vector)>,
    has_kinematic: bool,
    /// Position multipliers of this substep's projection (the displacement is `M~^-1 J^T mu`),
    /// the warm start of the next one.
    mu: Vec<Real>,
    pub(crate) rhs_b: Vec<[Real; 6]>,
    rhs_j: Vec<Real>,
    /// Applied impulse per row accumulated over the current substep (N s).
    pub(crate) impulse: Vec<Real>,
    shift: Vec<[Real; 6]>,
    saved: Vec<(Real, Vector, Vector)>,
    pub(crate) diagnostics: LagrangeDiagnostics,
    /// The velocity-level limit stage found every limit far away (the position stage skips).
    pub(crate) limits_clear: bool,
    /// Per joint, asleep when the topology was built (asleep joints have no rows).
    asleep: Vec<bool>,
    /// Per body: integrated by the second-order (RATTLE) step in the current step (the world
    /// asks for it and the body's island has no active contact).
    pub(crate) second: Vec<bool>,
    /// Some body is integrated by the second-order step in the current step.
    pub(crate) second_any: bool,
    warned_redundant: bool,
    warned_projection: bool,
    warned_fallback: bool,
}

impl LagrangeState {
    /// Joint `j` had all its bodies asleep at the last topology build (it has no rows).
    pub(crate) fn is_asleep(&self, j: usize) -> bool {
        self.asleep.get(j).copied().unwrap_or(false)
    }

    /// The row range of world joint `j` in the current block layout, if it has rows.
    pub(crate) fn rows_of(&self, j: usize) -> Option<core::ops::Range<usize>> {
        let kkt = self.kkt.as_ref()?;
        let k = (*self.block_of.get(j)?)?;
        let r0 = kkt.row_offset(k);
        Some(r0..r0 + kkt.joint_specs()[k].rows)
    }
}

fn kkt_err(e: crate::solver::kkt::KktError, time: Real) -> Error {
    Error::Diverged {
        time,
        joint: None,
        reason: format!("constraint solve failed: {e}"),
    }
}

impl Mpc184World {
    /// Rebuilds the body index and the KKT structure after joints (or colliders) were added or
    /// removed.
    fn lagrange_topology(&mut self) -> Result<(), Error> {
        // Rapier's own copy of a joint's rows rides along only where a contact can act (either
        // body has a collider): elsewhere it would cost a Rapier joint solve for nothing.
        for e in self.joints.iter().flatten() {
            let crate::world::RapierJoint::Impulse(handle) = e.rapier else {
                continue;
            };
            let touches = [e.body1, e.body2]
                .iter()
                .any(|b| !self.physics.bodies[*b].colliders().is_empty());
            let mask = match crate::lower::lower(
                &e.joint.kind,
                e.joint.method,
                crate::lower::Backend::RapierImpulse,
            ) {
                Ok(m) if touches => m,
                _ => crate::math::rapier::dynamics::JointAxesMask::empty(),
            };
            if let Some(j) = self.physics.impulse_joints.get_mut(handle, false)
                && j.data.locked_axes != mask
            {
                j.data.lock_axes(mask);
            }
        }
        self.lagrange.colliders = self.physics.colliders.len();
        let mut bodies = Vec::new();
        let mut index = HashMap::new();
        let mut specs = Vec::new();
        let mut blocks = Vec::new();
        let asleep = self.lagrange_asleep();
        for (j, e) in self.joints.iter().enumerate() {
            let Some(e) = e else { continue };
            // A joint whose island sleeps costs nothing: no rows, no bodies (Rapier keeps the
            // island asleep; it wakes as a whole, and the next step rebuilds with it).
            if asleep.get(j).copied().unwrap_or(false) {
                continue;
            }
            let mut slot = |b: RigidBodyHandle| -> Option<usize> {
                if !self.physics.bodies[b].is_dynamic() {
                    return None;
                }
                Some(*index.entry(b).or_insert_with(|| {
                    bodies.push(b);
                    bodies.len() - 1
                }))
            };
            let s = [slot(e.body1), slot(e.body2)];
            if e.rows.is_empty() {
                continue;
            }
            specs.push(JointBlockSpec {
                rows: e.rows.len(),
                bodies: s,
            });
            blocks.push(j);
        }
        let has_kinematic = self.joints.iter().flatten().any(|e| {
            self.physics.bodies[e.body1].is_kinematic()
                || self.physics.bodies[e.body2].is_kinematic()
        });
        let kkt = KktSolver::new(bodies.len(), &specs).map_err(|e| Error::Unsupported {
            what: format!("the constraint structure: {e}"),
            hint: "a joint carries at most 12 rows".into(),
        })?;
        let nr = kkt.num_rows();
        let ls = &mut self.lagrange;
        ls.has_kinematic = has_kinematic;
        ls.st = vec![BodyState::default(); bodies.len()];
        ls.mass = vec![[0.0; 36]; bodies.len()];
        ls.rhs_b = vec![[0.0; 6]; bodies.len()];
        ls.shift = vec![[0.0; 6]; bodies.len()];
        ls.saved = vec![(0.0, Vector::ZERO, Vector::ZERO); bodies.len()];
        ls.jac = vec![0.0; JAC_ROW_STRIDE * nr];
        ls.compliance = vec![0.0; nr];
        ls.value = vec![0.0; nr];
        ls.kin = vec![0.0; nr];
        ls.penalty = vec![false; nr];
        ls.kpen = vec![0.0; nr];
        ls.rate = vec![0.0; nr];
        ls.reg_scale = 1.0;
        ls.backup = vec![BodyState::default(); bodies.len()];
        ls.last_x = vec![[0.0; 6]; bodies.len()];
        ls.last_lambda = vec![0.0; nr];
        ls.mu = vec![0.0; nr];
        ls.fresh_values = false;
        ls.factor_valid = None;
        ls.written = vec![(Pose::IDENTITY, Vector::ZERO, Vector::ZERO); bodies.len()];

        ls.rhs_j = vec![0.0; nr];
        ls.impulse = vec![0.0; nr];
        ls.bodies = bodies;
        ls.index = index;
        ls.block_of = vec![None; self.joints.len()];
        for (k, &j) in blocks.iter().enumerate() {
            ls.block_of[j] = Some(k);
        }
        ls.blocks = blocks;
        ls.asleep = asleep;
        ls.kkt = Some(kkt);
        ls.dirty = false;
        Ok(())
    }

    /// Per joint: every dynamic body it connects is asleep in Rapier (and it has at least one).
    fn lagrange_asleep(&self) -> Vec<bool> {
        self.joints
            .iter()
            .map(|e| {
                e.as_ref().is_some_and(|e| {
                    let dynamic: Vec<_> = [e.body1, e.body2]
                        .into_iter()
                        .filter(|b| self.physics.bodies[*b].is_dynamic())
                        .collect();
                    !dynamic.is_empty()
                        && dynamic
                            .iter()
                            .all(|b| self.physics.bodies[*b].is_sleeping())
                })
            })
            .collect()
    }

    /// Picks the integrator of each body for this step: the world's, except that an island
    /// (bodies connected by joints) with an active contact takes the first-order step.
    fn lagrange_choose_order(&mut self) {
        let nb = self.lagrange.bodies.len();
        let rattle = self.settings().integrator == crate::world::Integrator::Rattle;
        let ls = &mut self.lagrange;
        ls.second.clear();
        ls.second.resize(nb, rattle);
        ls.second_any = rattle && nb > 0;
        ls.diagnostics.first_order_bodies = 0;
        if !rattle {
            return;
        }
        let mut touched = Vec::new();
        for pair in self.physics.contact_pairs() {
            if !pair.has_any_active_contact() {
                continue;
            }
            for c in [pair.collider1, pair.collider2] {
                if let Some(&i) = self
                    .physics
                    .colliders
                    .get(c)
                    .and_then(|col| col.parent())
                    .and_then(|b| ls.index.get(&b))
                {
                    touched.push(i);
                }
            }
        }
        if touched.is_empty() {
            return;
        }
        // Islands by union-find over the joint blocks.
        let mut parent: Vec<usize> = (0..nb).collect();
        fn root(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        if let Some(kkt) = ls.kkt.as_ref() {
            for spec in kkt.joint_specs() {
                if let [Some(a), Some(b)] = spec.bodies {
                    let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
                    parent[ra] = rb;
                }
            }
        }
        let mut contact_root = vec![false; nb];
        for i in touched {
            let r = root(&mut parent, i);
            contact_root[r] = true;
        }
        let mut fallback = 0;
        for i in 0..nb {
            if contact_root[root(&mut parent, i)] {
                ls.second[i] = false;
                fallback += 1;
            }
        }
        ls.second_any = ls.second.iter().any(|x| *x);
        ls.diagnostics.first_order_bodies = fallback;
        ls.diagnostics.first_order_steps += 1;
        if !ls.warned_fallback {
            ls.warned_fallback = true;
            ls.diagnostics.warnings.push(format!(
                "t = {}: {fallback} bod(ies) in islands with an active contact take the \
                 first-order step while the contact lasts (second order needs smooth forces)",
                self.time
            ));
        }
    }

    /// Kinetic energy of the solver's bodies plus the potential of their constant forces
    /// (gravity and user forces: `-f . c`), at the current body states (J).
    pub(crate) fn lagrange_body_energy(&self) -> Real {
        self.lagrange
            .st
            .iter()
            .map(|s| {
                0.5 * s.mass * s.linvel.length_squared() + 0.5 * s.angvel.dot(s.inertia * s.angvel)
                    - s.force.dot(s.com)
            })
            .sum()
    }

    /// Reads pose, mass and velocity of every jointed body from Rapier.
    fn lagrange_gather(&mut self) {
        let g = self.physics.gravity;
        for (i, b) in self.lagrange.bodies.iter().enumerate() {
            let rb = &self.physics.bodies[*b];
            let s = &mut self.lagrange.st[i];
            let mp = &rb.mass_properties().local_mprops;
            s.principal = mp.principal_inertia();
            s.principal_inv = mp.inv_principal_inertia;
            s.principal_frame = mp.principal_inertia_local_frame;
            s.min_inertia = s.principal.min_element();
            s.pose = *rb.position();
            s.refresh_inertia();
            let inertia = s.inertia;
            s.com = rb.center_of_mass();
            s.mass = rb.mass();
            s.linvel = rb.linvel();
            s.angvel = rb.angvel();
            s.force = rb.user_force() + g * (rb.mass() * rb.gravity_scale());
            // The gyroscopic torque is added in the velocity solve (implicit midpoint).
            let _ = inertia;
            s.torque = rb.user_torque();
        }
    }

    /// Evaluates every row at the bodies' current state (`st`); with `jacobian`, also fills the
    /// Jacobian arena, the compliances and the kinematic terms.
    fn lagrange_rows(&mut self, h: Real, jacobian: bool) {
        let ls = &mut self.lagrange;
        let Some(kkt) = ls.kkt.as_ref() else { return };
        for (k, &j) in ls.blocks.iter().enumerate() {
            let Some(e) = &self.joints[j] else { continue };
            let slots = kkt.joint_specs()[k].bodies;
            let side = |b: RigidBodyHandle, slot: Option<usize>| -> (Pose, Vector, Option<usize>) {
                match slot {
                    Some(i) => (ls.st[i].pose, ls.st[i].com, Some(i)),
                    None => {
                        let rb = &self.physics.bodies[b];
                        (*rb.position(), rb.center_of_mass(), None)
                    }
                }
            };
            let (p1, c1, i1) = side(e.body1, slots[0]);
            let (p2, c2, i2) = side(e.body2, slots[1]);
            let f = frame_pair(&e.low, (p1, c1), (p2, c2));
            let (kd, kr) = match e.joint.method {
                ConstraintMethod::Lagrange => (None, None),
                ConstraintMethod::Penalty { disp, rot } => (
                    Some(penalty_stiffness(disp, DEFAULT_PENALTY_DISP)),
                    Some(penalty_stiffness(rot, DEFAULT_PENALTY_ROT)),
                ),
            };
            let r0 = kkt.row_offset(k);
            for (n, row) in e.rows.iter().enumerate() {
                let r = r0 + n;
                let ev = row.eval(&f);
                ls.value[r] = ev.value;
                if !jacobian {
                    continue;
                }
                let out = &mut ls.jac[JAC_ROW_STRIDE * r..JAC_ROW_STRIDE * (r + 1)];
                for a in 0..3 {
                    out[a] = ev.j1[0][a];
                    out[3 + a] = ev.j1[1][a];
                    out[6 + a] = ev.j2[0][a];
                    out[9 + a] = ev.j2[1][a];
                }
                // Velocity of a non-dynamic side (kinematic bodies; zero for fixed ones).
                let mut kin = 0.0;
                for (slot, b, jb) in [(i1, e.body1, ev.j1), (i2, e.body2, ev.j2)] {
                    if slot.is_none() {
                        let rb = &self.physics.bodies[b];
                        kin += jb[0].dot(rb.linvel()) + jb[1].dot(rb.angvel());
                    }
                }
                ls.kin[r] = kin;
                let k_pen = match row {
                    RowKind::Linear { .. } | RowKind::Screw { .. } | RowKind::Distance { .. } => kd,
                    RowKind::Drive { .. } => None,
                    RowKind::Angular { .. } => kr,
                };
                ls.penalty[r] = k_pen.is_some();
                ls.kpen[r] = k_pen.unwrap_or(0.0);
                ls.compliance[r] = match k_pen {
                    Some(k) => 1.0 / (k * h * h),
                    // A relative regularisation of the hard rows (`REGULARISATION` times the
                    // row's own effective inverse mass): it bounds the multipliers in directions
                    // that become dependent at a singular pose (a parallelogram four-bar passing
                    // its aligned position) and changes the solution of a well-posed system by
                    // that relative amount only.
                    None => {
                        let mut a = 0.0;
                        for (slot, jb) in [(i1, ev.j1), (i2, ev.j2)] {
                            if let Some(i) = slot {
                                let s = &ls.st[i];
                                a += jb[0].length_squared() / s.mass
                                    + jb[1].dot(s.inertia_inv * jb[1]);
                            }
                        }
                        REGULARISATION * ls.reg_scale * a
                    }
                };
            }
        }
    }

    /// Mass blocks (with added inertia from the last substep's joint forces) and factorisation.
    fn lagrange_factor(&mut self, h: Real) -> Result<(), Error> {
        self.lagrange_added_inertia(h);
        let ls = &mut self.lagrange;
        for (i, s) in ls.st.iter().enumerate() {
            let m = &mut ls.mass[i];
            *m = [0.0; 36];
            for a in 0..3 {
                m[6 * a + a] = s.mass;
                for b in 0..3 {
                    m[6 * (3 + a) + 3 + b] = s.inertia.col(b)[a];
                }
                m[6 * (3 + a) + 3 + a] += s.added;
            }
        }
        let time = self.time;
        let Some(kkt) = ls.kkt.as_mut() else {
            return Ok(());
        };
        let report = kkt
            .factor(&ls.mass, &ls.jac, &ls.compliance)
            .map_err(|e| kkt_err(e, time))?;
        // The topology check (unregularised) found the structural redundancy; a regularised
        // factorisation only sees rows that are dependent numerically as well.
        ls.diagnostics.redundant_rows = report.redundant_rows.max(ls.redundant_count);
        if report.redundant_rows > 0 && !ls.warned_redundant {
            ls.warned_redundant = true;
            ls.diagnostics.warnings.push(format!(
                "t = {time}: {} redundant constraint row(s): the constraint Jacobian is rank \
                 deficient, the multipliers of the dependent rows are not unique (the solve \
                 regularises them; the motion is unaffected)",
                report.redundant_rows
            ));
        }
        Ok(())
    }

    /// Geometric stiffness as added rotational inertia (see the module docs): each joint's
    /// force of the last substep, `F` on body 2 and `-F` on body 1, acts at frame 2's origin `p`;
    /// a body turning about its centre `c` against it has the stiffness `|F| |p - c|`.
    fn lagrange_added_inertia(&mut self, h: Real) {
        let ls = &mut self.lagrange;
        let Some(kkt) = ls.kkt.as_ref() else { return };
        // Per body: the summed stiffness |F| r of its joints and the longest lever arm r.
        let mut load: Vec<(Real, Real)> = vec![(0.0, 0.0); ls.st.len()];
        for (k, &j) in ls.blocks.iter().enumerate() {
            let Some(e) = &self.joints[j] else { continue };
            let r0 = kkt.row_offset(k);
            let mut force = Vector::ZERO;
            for r in r0..r0 + e.rows.len() {
                let jr = &ls.jac[JAC_ROW_STRIDE * r..JAC_ROW_STRIDE * (r + 1)];
                force += Vector::new(jr[6], jr[7], jr[8]) * (ls.impulse[r] / h);
            }
            let force = force.length();
            let slots = kkt.joint_specs()[k].bodies;
            let p = match slots[1] {
                Some(i) => (ls.st[i].pose * e.low[1]).translation,
                None => (*self.physics.bodies[e.body2].position() * e.low[1]).translation,
            };
            // A rigid link's force acts on body 1 at node I, the other end of the bar.
            let link = matches!(e.joint.kind, crate::catalogue::JointKind::RigidLink);
            {
                for (side, i) in slots.into_iter().enumerate() {
                    let Some(i) = i else { continue };
                    let at = if link && side == 0 {
                        (ls.st[i].pose * e.low[0]).translation
                    } else {
                        p
                    };
                    let r = (at - ls.st[i].com).length();
                    load[i].0 += force * r;
                    load[i].1 = load[i].1.max(r);
                }
            }
        }
        let mut stiffened = 0;
        // Second order on a redundant structure: no added inertia. The multipliers of dependent
        // rows are set by the regularisation, not by the physics, and grow without bound where
        // the rows become nearly dependent (a parallelogram four-bar passing its singular pose),
        // so the force estimate is meaningless there; the added inertia it switched on cost
        // RATTLE 1e-3 of the four-bar's energy per passage at h = 1/240 s. (The first-order
        // scheme keeps it: its velocities live at half steps and it never tripped there.)
        let skip = ls.second_any && ls.redundant;
        for (s, (kg, r)) in ls.st.iter_mut().zip(load) {
            if skip {
                s.added = 0.0;
                continue;
            }
            let omega2 = kg / (s.min_inertia + s.mass * r * r);
            s.added = if omega2 * h * h > 0.25 {
                stiffened += 1;
                h * h * kg
            } else {
                0.0
            };
        }
        ls.diagnostics.stiffened_bodies = stiffened;
    }

    /// Starts the projection from the previous substep's position multipliers: the drift of
    /// successive substeps is nearly the same (O(h^2) centripetal terms), so the chord iteration
    /// then starts close to its solution (a long chain needs 3 iterations instead of 10-16).
    ///
    /// Skipped where the constraints are redundant (the multipliers of dependent rows are set by
    /// the regularisation and need not cancel under the new Jacobian), and undone if it leaves a
    /// gross constraint violation.
    fn lagrange_warm_start(&mut self, h: Real) {
        if self.lagrange.redundant || self.lagrange.mu.iter().all(|m| *m == 0.0) {
            self.lagrange.mu.iter_mut().for_each(|m| *m = 0.0);
            return;
        }
        let ls = &mut self.lagrange;
        let Some(kkt) = ls.kkt.as_ref() else { return };
        ls.backup.copy_from_slice(&ls.st);
        for b in ls.rhs_b.iter_mut() {
            *b = [0.0; 6];
        }
        // J^T mu per body.
        for k in 0..kkt.num_joints() {
            let spec = kkt.joint_specs()[k];
            let r0 = kkt.row_offset(k);
            for r in r0..r0 + spec.rows {
                let jr = &ls.jac[JAC_ROW_STRIDE * r..JAC_ROW_STRIDE * (r + 1)];
                for (slot, body) in spec.bodies.iter().enumerate() {
                    if let Some(i) = body {
                        for a in 0..6 {
                            ls.rhs_b[*i][a] += jr[6 * slot + a] * ls.mu[r];
                        }
                    }
                }
            }
        }
        for r in 0..ls.mu.len() {
            ls.impulse[r] += ls.mu[r] / h;
        }
        for i in 0..ls.st.len() {
            let g = ls.rhs_b[i];
            let s = &mut ls.st[i];
            let dx = Vector::new(g[0], g[1], g[2]) / s.mass;
            let ang = (s.inertia + Matrix::from_diagonal(Vector::splat(s.added))).inverse();
            let dth = ang * Vector::new(g[3], g[4], g[5]);
            displace(s, dx, dth);
            ls.shift[i] = [dx.x, dx.y, dx.z, dth.x, dth.y, dth.z];
        }
        // The warm-started point may have a larger residual than the plain start and still be
        // closer to the solution along the directions the chord iteration converges slowly in
        // (measured on the 1000-link chain: residual 3e-7 -> 5e-5, then 2 iterations instead
        // of 10); only a gross violation means the previous multipliers do not fit.
        let after = self.lagrange_residual(h);
        if !after.is_finite() || after > WARM_START_LIMIT {
            let ls = &mut self.lagrange;
            ls.fresh_values = false;
            ls.st.copy_from_slice(&ls.backup);
            for r in 0..ls.mu.len() {
                ls.impulse[r] -= ls.mu[r] / h;
                ls.mu[r] = 0.0;
            }
            ls.shift.iter_mut().for_each(|x| *x = [0.0; 6]);
        }
    }

    /// Largest deviation of any row from its projection target at the current state.
    fn lagrange_residual(&mut self, h: Real) -> Real {
        self.lagrange_rows(h, false);
        self.lagrange.fresh_values = true;
        let ls = &self.lagrange;
        let mut residual: Real = 0.0;
        for r in 0..ls.value.len() {
            let dev = if ls.kpen[r] > 0.0 {
                ls.value[r] + ls.impulse[r] / (h * ls.kpen[r])
            } else {
                ls.value[r]
            };
            residual = residual.max(dev.abs());
        }
        residual
    }

    /// One substep of the Lagrange backend. Requires the factorisation at the current state.
    pub(crate) fn lagrange_substep(&mut self, h: Real, t1: Real) -> Result<(), Error> {
        let time = self.time;
        let nb = self.lagrange.bodies.len();
        // 1-2. Velocity solve.
        {
            let ls = &mut self.lagrange;
            for i in 0..nb {
                let s = &ls.st[i];
                // First order: the whole kick now. Second order (RATTLE): half now with the
                // forces at q_n, half at the end with the forces at q_(n+1).
                let ha = if ls.second[i] { 0.5 * h } else { h };
                let v = s.linvel + s.force * (ha / s.mass);
                // Gyroscopic term by the implicit midpoint rule, `w_g = w - h I^-1 (w_m x I
                // w_m)` with `w_m = (w + w_g) / 2` (fixed-point iterations, contracting for
                // `h |w| < 1`): it keeps the rotational energy and the angular momentum of a
                // free body exactly, where the explicit `-w x I w` gains energy every step
                // (measured: the IFToMM slider-crank gained 7 % of its energy scale per second
                // at h = 1/240 s).
                let w = gyroscopic_kick(s, s.angvel, ha) + s.inertia_inv * s.torque * ha;
                let mw = s.inertia * w + w * s.added;
                let mv = v * s.mass;
                ls.rhs_b[i] = [mv.x, mv.y, mv.z, mw.x, mw.y, mw.z];
            }
            for r in 0..ls.rhs_j.len() {
                let pen = if ls.penalty[r] { ls.value[r] / h } else { 0.0 };
                ls.rhs_j[r] = ls.rate[r] - ls.kin[r] - pen;
            }
        }
        let effects = self.effects_any();
        // Energy-consistent stops of the second-order step need the energy the substep starts
        // with (kinetic + potential of constant forces here, springs after the first kick).
        let energy_fix = effects && self.lagrange.second_any && self.effects_has_elastic_stops();
        let mut start_energy = if energy_fix {
            self.lagrange_body_energy()
        } else {
            0.0
        };
        let start_ledger = self.ledger;
        if effects {
            self.effects_begin_substep();
            self.effects_kick(0.5 * h, t1 - h);
            if energy_fix {
                start_energy += self.effects_spring_energy();
            }
        }
        {
            let ls = &mut self.lagrange;
            let Some(kkt) = ls.kkt.as_ref() else {
                return Ok(());
            };
            kkt.solve(&mut ls.rhs_b, &mut ls.rhs_j)
                .map_err(|e| kkt_err(e, time))?;
            for r in 0..ls.rhs_j.len() {
                ls.impulse[r] = -ls.rhs_j[r];
            }
        }
        if effects {
            self.effects_limits_velocity(h)?;
            self.effects_friction(h)?;
        }
        // Hand v' to Rapier: gravity and user forces held back for this substep.
        for i in 0..nb {
            let b = self.lagrange.bodies[i];
            let x = self.lagrange.rhs_b[i];
            let rb = &mut self.physics.bodies[b];
            self.lagrange.saved[i] = (rb.gravity_scale(), rb.user_force(), rb.user_torque());
            rb.set_gravity_scale(0.0, false);
            rb.reset_forces(false);
            rb.reset_torques(false);
            rb.set_linvel(Vector::new(x[0], x[1], x[2]), false);
            let w = Vector::new(x[3], x[4], x[5]);
            let w = if self.lagrange.second[i] {
                w * rotation_scale(w, h)
            } else {
                w
            };
            rb.set_angvel(w, false);
        }
        self.physics.step();
        for i in 0..nb {
            let b = self.lagrange.bodies[i];
            let (gs, f, t) = self.lagrange.saved[i];
            let rb = &mut self.physics.bodies[b];
            rb.set_gravity_scale(gs, false);
            rb.add_force(f, false);
            rb.add_torque(t, false);
        }
        self.lagrange_gather();
        // Second-order bodies were handed `w` scaled so that Rapier's linearised quaternion
        // update (a turn by `2 atan(|w| h / 2)`) turns them by exactly `|w| h`: take the scale
        // back (unless a contact changed the velocity in Rapier's solve).
        if self.lagrange.second_any {
            let ls = &mut self.lagrange;
            for i in 0..nb {
                if !ls.second[i] {
                    continue;
                }
                let x = ls.rhs_b[i];
                let w = Vector::new(x[3], x[4], x[5]);
                let scale = rotation_scale(w, h);
                let s = &mut ls.st[i];
                s.angvel = if s.angvel == w * scale {
                    w
                } else {
                    s.angvel / scale
                };
            }
        }
        // 3. Position projection along the start-of-substep directions (chord iterations).
        let tol = PROJECTION_TOLERANCE.max(10.0 * Real::EPSILON);
        let mut residual = 0.0;
        let mut iterations = 0;
        for s in self.lagrange.shift.iter_mut() {
            *s = [0.0; 6];
        }
        self.lagrange_warm_start(h);
        // Chord iterations on the start-of-substep factorisation. Should one increase the
        // residual (near a singular pose, where the start-of-substep directions lose rank), it is
        // undone and the projection continues as damped Gauss-Newton: refactorised at the current
        // configuration with a regularisation raised tenfold at every further failure.
        let mut previous = Real::INFINITY;
        let mut newton = false;
        for it in 0..=MAX_PROJECTION_ITERATIONS {
            if !core::mem::take(&mut self.lagrange.fresh_values) {
                self.lagrange_rows(h, false);
            }
            let ls = &mut self.lagrange;
            residual = 0.0;
            for r in 0..ls.value.len() {
                // Lagrange rows are projected onto C = 0, penalty rows onto their elastic
                // deflection C = -f / k under the row force f of this substep so far (velocity
                // solve plus projection: the KKT compliance 1 / (k h^2) is exactly the
                // derivative of that target, so the chord iteration stays consistent).
                let dev = if ls.kpen[r] > 0.0 {
                    ls.value[r] + ls.impulse[r] / (h * ls.kpen[r])
                } else {
                    ls.value[r]
                };
                residual = Real::max(residual, dev.abs());
                ls.rhs_j[r] = -dev;
            }
            if residual <= tol || it == MAX_PROJECTION_ITERATIONS {
                iterations = it;
                break;
            }
            if residual > previous || !residual.is_finite() {
                // Undo the last step.
                ls.st.copy_from_slice(&ls.backup);
                for i in 0..nb {
                    for (acc, d) in ls.shift[i].iter_mut().zip(ls.last_x[i]) {
                        *acc -= d;
                    }
                }
                for r in 0..ls.impulse.len() {
                    ls.impulse[r] += ls.last_lambda[r] / h;
                    ls.mu[r] += ls.last_lambda[r];
                }
                ls.reg_scale = if newton { ls.reg_scale * 10.0 } else { 1.0 };
                newton = true;
                previous = Real::INFINITY;
                continue;
            }
            if newton {
                self.lagrange_rows(h, true);
                self.lagrange_factor(h)?;
                self.lagrange_rows(h, false);
            }
            let ls = &mut self.lagrange;
            for b in ls.rhs_b.iter_mut() {
                *b = [0.0; 6];
            }
            let Some(kkt) = ls.kkt.as_ref() else {
                return Ok(());
            };
            kkt.solve(&mut ls.rhs_b, &mut ls.rhs_j)
                .map_err(|e| kkt_err(e, time))?;
            ls.backup.copy_from_slice(&ls.st);
            ls.last_lambda.copy_from_slice(&ls.rhs_j);
            for r in 0..ls.rhs_j.len() {
                ls.impulse[r] -= ls.rhs_j[r] / h;
                ls.mu[r] -= ls.rhs_j[r];
            }
            for i in 0..nb {
                let x = ls.rhs_b[i];
                ls.last_x[i] = x;
                let s = &mut ls.st[i];
                let (dx, dth) = (Vector::new(x[0], x[1], x[2]), Vector::new(x[3], x[4], x[5]));
                displace(s, dx, dth);
                for (acc, d) in ls.shift[i].iter_mut().zip(x) {
                    *acc += d;
                }
            }
            previous = residual;
        }
        self.lagrange.reg_scale = 1.0;
        {
            let ls = &mut self.lagrange;
            ls.diagnostics.projection_iterations = iterations;
            ls.diagnostics.projection_residual = ls.diagnostics.projection_residual.max(residual);
            if residual > 1e3 * tol && !ls.warned_projection {
                ls.warned_projection = true;
                ls.diagnostics.warnings.push(format!(
                    "t = {time}: position projection stopped at residual {residual:.3e} after \
                     {iterations} iterations"
                ));
            }
            // Feed the correction into the velocity (constrained symplectic Euler).
            for i in 0..nb {
                let d = ls.shift[i];
                let s = &mut ls.st[i];
                s.linvel += Vector::new(d[0], d[1], d[2]) / h;
                s.angvel += Vector::new(d[3], d[4], d[5]) / h;
                s.refresh_inertia();
            }
        }
        if effects {
            self.effects_limits_position(h, tol)?;
        }
        // 4. Rows and factorisation at q_(n+1), velocity projection.
        self.lagrange_rows(h, true);
        self.lagrange_factor(h)?;
        {
            let ls = &mut self.lagrange;
            for i in 0..nb {
                let s = &ls.st[i];
                let (v, w) = if ls.second[i] {
                    // The second half kick of RATTLE, with the forces at q_(n+1).
                    let hh = 0.5 * h;
                    (
                        s.linvel + s.force * (hh / s.mass),
                        gyroscopic_kick(s, s.angvel, hh) + s.inertia_inv * s.torque * hh,
                    )
                } else {
                    (s.linvel, s.angvel)
                };
                let mv = v * s.mass;
                let mw = s.inertia * w + w * s.added;
                ls.rhs_b[i] = [mv.x, mv.y, mv.z, mw.x, mw.y, mw.z];
            }
        }
        if effects {
            self.effects_kick(0.5 * h, t1);
        }
        {
            let ls = &mut self.lagrange;
            for r in 0..ls.rhs_j.len() {
                ls.rhs_j[r] = ls.rate[r] - ls.kin[r];
            }
            let Some(kkt) = ls.kkt.as_ref() else {
                return Ok(());
            };
            // A penalty row is a spring, not a velocity constraint: the implicit velocity solve
            // above already gave it the force k times its end-of-substep deflection. Here it
            // keeps its current rate (target = its own J v, so with compliance 1 / (k h^2) it
            // takes almost no impulse), otherwise the projection would add a stiffening impulse
            // that the deflection does not show (measured: gap * k was 0.67 of the reported
            // force on the 90 deg pendulum).
            for k in 0..kkt.num_joints() {
                let spec = kkt.joint_specs()[k];
                let r0 = kkt.row_offset(k);
                for r in r0..r0 + spec.rows {
                    if !ls.penalty[r] {
                        continue;
                    }
                    let jr = &ls.jac[JAC_ROW_STRIDE * r..JAC_ROW_STRIDE * (r + 1)];
                    let mut jv = 0.0;
                    for (slot, body) in spec.bodies.iter().enumerate() {
                        if let Some(i) = body {
                            let s = &ls.st[*i];
                            let v = [
                                s.linvel.x, s.linvel.y, s.linvel.z, s.angvel.x, s.angvel.y,
                                s.angvel.z,
                            ];
                            for a in 0..6 {
                                jv += jr[6 * slot + a] * v[a];
                            }
                        }
                    }
                    ls.rhs_j[r] = jv;
                }
            }
            kkt.solve(&mut ls.rhs_b, &mut ls.rhs_j)
                .map_err(|e| kkt_err(e, time))?;
            for r in 0..ls.rhs_j.len() {
                ls.impulse[r] -= ls.rhs_j[r];
            }
            for i in 0..nb {
                let x = ls.rhs_b[i];
                ls.st[i].linvel = Vector::new(x[0], x[1], x[2]);
                ls.st[i].angvel = Vector::new(x[3], x[4], x[5]);
            }
        }
        self.effects_book_drive_work();
        if energy_fix {
            self.effects_energy_fix(h, start_energy, start_ledger)?;
        }
        // Write poses and velocities back to Rapier.
        for i in 0..nb {
            let b = self.lagrange.bodies[i];
            let s = self.lagrange.st[i];
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
            let rb = &mut self.physics.bodies[b];
            rb.set_position(s.pose, false);
            rb.set_linvel(s.linvel, false);
            rb.set_angvel(s.angvel, false);
            self.lagrange.written[i] = (s.pose, s.linvel, s.angvel);
        }
        self.lagrange.factor_valid = Some(h);
        self.update_screw_references();
        Ok(())
    }

    /// Sets every drive row's target to its value at `t1` (the end of the coming substep) and
    /// its rate to the change over the substep divided by h.
    fn update_drives(&mut self, t1: Real, h: Real) {
        let ls = &mut self.lagrange;
        let Some(kkt) = ls.kkt.as_ref() else { return };
        for (k, &j) in ls.blocks.iter().enumerate() {
            let Some(e) = self.joints[j].as_mut() else {
                continue;
            };
            let r0 = kkt.row_offset(k);
            for (n, row) in e.rows.iter_mut().enumerate() {
                if let RowKind::Drive { dof, target, .. } = row
                    && let Some(d) = e.drives.iter().find(|d| d.dof == *dof)
                {
                    let (v0, v1) = (d.value(t1 - h), d.value(t1));
                    *target = v1;
                    ls.rate[r0 + n] = (v1 - v0) / h;
                }
            }
        }
    }

    /// Moves every screw row's unwrapping reference to the current rotation (a screw may turn
    /// any number of times; each substep turns it by far less than pi).
    pub(crate) fn update_screw_references(&mut self) {
        for e in self.joints.iter_mut().flatten() {
            if !e
                .rows
                .iter()
                .any(|r| matches!(r, RowKind::Screw { .. } | RowKind::Drive { .. }))
            {
                continue;
            }
            let b1 = &self.physics.bodies[e.body1];
            let b2 = &self.physics.bodies[e.body2];
            let f = frame_pair(
                &e.low,
                (*b1.position(), b1.center_of_mass()),
                (*b2.position(), b2.center_of_mass()),
            );
            for r in e.rows.iter_mut() {
                match r {
                    RowKind::Screw { reference, .. } => {
                        *reference = crate::rows::screw_angle(&f, *reference);
                    }
                    RowKind::Drive { dof, reference, .. } => {
                        *reference = crate::rows::dof_measure(&f, *dof, *reference);
                    }
                    RowKind::Linear { .. } | RowKind::Angular { .. } | RowKind::Distance { .. } => {
                    }
                }
            }
        }
    }

    /// Counts the redundant hard rows once per topology: one factorisation without the
    /// regularisation (which otherwise keeps every pivot away from zero) and a warning.
    fn lagrange_redundancy_check(&mut self, h: Real) -> Result<(), Error> {
        let saved = self.lagrange.compliance.clone();
        for (c, &k) in self.lagrange.compliance.iter_mut().zip(&self.lagrange.kpen) {
            if k == 0.0 {
                *c = 0.0;
            }
        }
        self.lagrange.redundant_count = 0;
        let result = self.lagrange_factor(h);
        self.lagrange.compliance = saved;
        self.lagrange.redundant_count = self.lagrange.diagnostics.redundant_rows;
        self.lagrange.redundant = self.lagrange.diagnostics.redundant_rows > 0;
        result
    }

    /// Runs the Lagrange backend over one step of `n` substeps.
    pub(crate) fn lagrange_step(&mut self, h: Real, n: usize) -> Result<(), Error> {
        self.effects_apply_pending_locks();
        self.effects_begin_step();
        let sleep_changed = self.lagrange_asleep() != self.lagrange.asleep;
        let rebuilt = self.lagrange.dirty
            || sleep_changed
            || self.lagrange.kkt.is_none()
            || self.lagrange.colliders != self.physics.colliders.len();
        if rebuilt {
            self.lagrange_topology()?;
        }
        self.lagrange.diagnostics.projection_residual = 0.0;
        // The factorisation at the start of the step, unless the last substep's still holds:
        // same h, no kinematic body, and every body exactly as it was written back (the user
        // may have moved bodies or changed velocities between steps).
        self.lagrange_gather();
        let ls = &self.lagrange;
        let unchanged = !rebuilt
            && !ls.has_kinematic
            && ls.factor_valid == Some(h)
            && ls
                .st
                .iter()
                .zip(&ls.written)
                .all(|(s, w)| s.pose == w.0 && s.linvel == w.1 && s.angvel == w.2);
        if !unchanged {
            self.lagrange_rows(h, true);
            if rebuilt {
                self.lagrange_redundancy_check(h)?;
            }
            self.lagrange_factor(h)?;
        }
        self.lagrange_choose_order();
        for k in 0..n {
            let t1 = self.time + (k + 1) as Real * h;
            self.update_drives(t1, h);
            self.lagrange_substep(h, t1)?;
        }
        Ok(())
    }
}

/// Penalty stiffness from `SECJOINT,PNLT` (val > 0 scales the default, val < 0 is absolute).
pub fn penalty_stiffness(val: Real, default: Real) -> Real {
    if val < 0.0 {
        -val
    } else if val > 0.0 {
        val * default
    } else {
        default
    }
}

/// Moves a body's centre of mass by `dx` and turns it by the rotation vector `dth` about it.
/// [`displace`] by a 6-vector `[dx; dth]`, refreshing the world inertia.
pub(crate) fn displace_state(s: &mut BodyState, d: [Real; 6]) {
    displace(
        s,
        Vector::new(d[0], d[1], d[2]),
        Vector::new(d[3], d[4], d[5]),
    );
    s.refresh_inertia();
}

fn displace(s: &mut BodyState, dx: Vector, dth: Vector) {
    let local_com = s.pose.inverse_transform_point(s.com);
    s.com += dx;
    let rot: Rotation = (Rotation::from_scaled_axis(dth) * s.pose.rotation).normalize();
    s.pose.rotation = rot;
    s.pose.translation = s.com - rot * local_com;
}

/// The implicit-midpoint gyroscopic update over `dt`: `w' = w - dt I^-1 (w_m x I w_m)` with
/// `w_m = (w + w') / 2` (fixed-point iterations, contracting for `dt |w| < 1`). It keeps the
/// rotational energy and the angular momentum of a free body exactly, where the explicit
/// `-w x I w` gains energy every step (measured: the IFToMM slider-crank gained 7 % of its
/// energy scale per second at h = 1/240 s).
fn gyroscopic_kick(s: &BodyState, w: Vector, dt: Real) -> Vector {
    let mut wg = w;
    for _ in 0..GYRO_ITERATIONS {
        let wm = 0.5 * (w + wg);
        wg = w - s.inertia_inv * wm.cross(s.inertia * wm) * dt;
    }
    wg
}

/// The factor on `w` that makes Rapier's linearised quaternion update
/// (`q' = normalize((1 + w h / 2) q)`, a turn by `2 atan(|w| h / 2)`) turn a body by exactly
/// `|w| h`: `tan(|w| h / 2) / (|w| h / 2)`. One for tiny turns; capped below a half turn.
pub(crate) fn rotation_scale(w: Vector, h: Real) -> Real {
    let half = 0.5 * w.length() * h;
    if half < 1e-4 {
        // Series: 1 + x^2 / 3 (the next term, 2 x^4 / 15, is below round-off here).
        1.0 + half * half / 3.0
    } else if half < 1.5 {
        half.tan() / half
    } else {
        (1.5 as Real).tan() / 1.5
    }
}
