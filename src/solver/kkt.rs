//! Block-sparse `LDLᵀ` factorisation of the quasi-definite KKT system of jointed rigid bodies.
//!
//! For `nb` dynamic bodies (6 velocity DOFs each: linear then angular, world frame) and `nj`
//! joints (joint `k` has `m_k <= MAX_JOINT_ROWS` rows and touches zero, one or two bodies) the
//! solver handles
//!
//! ```text
//! [ M    Jᵀ ] [ x      ]   [ f ]
//! [ J    -C ] [ lambda ] = [ g ]
//! ```
//!
//! with `M = blockdiag(M_b)` (each `M_b` a symmetric positive definite 6×6), `J` the stacked joint
//! Jacobians and `C = diag(c_i) >= 0` the per-row compliance. Eliminating `x` gives
//! `(J M⁻¹ Jᵀ + C) lambda = J M⁻¹ f - g`, so `lambda` are the constraint multipliers.
//!
//! # Elimination order
//!
//! The nodes of the elimination graph are the bodies and the joints (with at least one row); its
//! edges are the joint–body incidences. [`KktSolver::new`] plays the elimination game once
//! (greedy minimum current degree, ties broken by node index, bodies numbered before joints)
//! with an eligibility rule that keeps every joint pivot meaningful:
//!
//! * a body is always eligible;
//! * a joint is eligible when it has no remaining body neighbour in the filled graph (all the
//!   bodies it is coupled to were eliminated), or when one of its bodies was eliminated as a
//!   *leaf*, i.e. with this joint as its only remaining neighbour (Baraff's step: the joint's
//!   rows then see the whole articulated inertia of that body).
//!
//! For trees (chains, stars, branching) this is Baraff's linear-time ordering with no fill at all;
//! loops (a four-bar, the Bricard mechanism) get a little joint–joint fill.
//!
//! The weaker rule "a joint is eligible once any of its bodies is gone" is not used: in a loop,
//! a body eliminated with two joints leaves both joints sharing its 6 DOFs, and the second joint's
//! pivot can be singular although its rows are independent (they still act on a body that is not
//! eliminated yet); dropping those rows would silently give a wrong answer.
//!
//! # Pivots and redundancy
//!
//! Body pivots are symmetric positive definite. Joint pivots are negative semidefinite and are
//! factored by a dense `LDLᵀ` with symmetric diagonal pivoting, largest scaled `|d|` first (each row
//! is scaled by the accumulated magnitude of its diagonal, see below). A pivot with
//! `|d| <= tol * s`, where `s` is the sum of the absolute values of everything that was added to
//! that diagonal entry (its compliance and every Schur update), marks the row as *redundant*: the
//! row is dropped from the system and its multiplier is zero. Since the pivot is the largest
//! remaining one, all remaining rows of the block are then dropped too. The default `tol` is
//! `2 Real::EPSILON^(2/3)` (about `7e-11` in `f64`, `5e-5` in `f32`), see
//! [`KktSolver::set_redundancy_tolerance`].
//!
//! Dropping is exact for consistent right-hand sides: `x` is unchanged and the multipliers of the
//! dropped rows are carried by the rows they depend on (a basic solution: the dropped multipliers
//! are zero, which is not the minimum-norm `lambda` in general).
//!
//! # Data layout
//!
//! * Masses: `mass[b]` is the 6×6 row-major matrix of body `b` (only its symmetric part is used).
//! * Rows: joint `k` owns the global rows `row_offset(k) .. row_offset(k) + rows_k` (joint-major).
//! * Jacobian arena: one slice of [`JAC_ROW_STRIDE`]` = 12` reals per global row `r`:
//!   `jac[12 r .. 12 r + 6]` is the derivative of the row with respect to the velocity of the
//!   joint's first body (`bodies[0]`), `jac[12 r + 6 .. 12 r + 12]` with respect to the second
//!   (`bodies[1]`). Entries of absent bodies (`None`) are ignored (they may hold anything).
//! * Compliance and the joint right-hand side: one real per global row.
//!
//! All storage is allocated in [`KktSolver::new`]; [`KktSolver::factor`] and [`KktSolver::solve`]
//! do not allocate (except for the first growth of the list of dropped rows).

use std::collections::{BTreeSet, HashMap};

use crate::math::Real;

/// Velocity DOFs of one body (linear then angular).
pub const BODY_DOFS: usize = 6;
/// The largest number of rows one joint block may have.
pub const MAX_JOINT_ROWS: usize = 12;
/// Reals per global row in the Jacobian arena (6 for each of the two body slots).
pub const JAC_ROW_STRIDE: usize = 2 * BODY_DOFS;

/// Largest pivot block dimension (bodies have 6, joints at most [`MAX_JOINT_ROWS`]).
const MAX_DIM: usize = if MAX_JOINT_ROWS > BODY_DOFS {
    MAX_JOINT_ROWS
} else {
    BODY_DOFS
};

/// Runs `$body` with the constant `$N` equal to the runtime dimension `$n` (`1..=MAX_DIM`), so
/// that small dense kernels get compile-time loop bounds.
macro_rules! by_dim {
    ($n:expr, $N:ident => $body:expr) => {
        match $n {
            1 => {
                const $N: usize = 1;
                $body
            }
            2 => {
                const $N: usize = 2;
                $body
            }
            3 => {
                const $N: usize = 3;
                $body
            }
            4 => {
                const $N: usize = 4;
                $body
            }
            5 => {
                const $N: usize = 5;
                $body
            }
            6 => {
                const $N: usize = 6;
                $body
            }
            7 => {
                const $N: usize = 7;
                $body
            }
            8 => {
                const $N: usize = 8;
                $body
            }
            9 => {
                const $N: usize = 9;
                $body
            }
            10 => {
                const $N: usize = 10;
                $body
            }
            11 => {
                const $N: usize = 11;
                $body
            }
            _ => {
                const $N: usize = MAX_DIM;
                $body
            }
        }
    };
}

/// Structure of one joint block: its number of rows and the (up to two) bodies it acts on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JointBlockSpec {
    /// Number of constraint rows, `0..=MAX_JOINT_ROWS`. A joint without rows is ignored.
    pub rows: usize,
    /// The bodies acted on, in Jacobian slot order; `None` is the ground (a fixed body).
    pub bodies: [Option<usize>; 2],
}

/// A node of the elimination graph.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum KktNode {
    /// Body index.
    Body(usize),
    /// Joint index.
    Joint(usize),
}

/// Errors of the KKT solver.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum KktError {
    /// A joint has more than [`MAX_JOINT_ROWS`] rows or a body index out of range.
    #[error("joint {joint}: too many rows or body index out of range")]
    InvalidJoint {
        /// The offending joint.
        joint: usize,
    },
    /// An input slice has the wrong length.
    #[error("{what}: expected length {expected}, got {got}")]
    LengthMismatch {
        /// Which input.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Actual length.
        got: usize,
    },
    /// A NaN or infinity in the mass of a body or in the Jacobian or compliance of a joint.
    #[error("non-finite input at {at:?}")]
    NonFinite {
        /// Where it was found.
        at: KktNode,
    },
    /// A negative compliance.
    #[error("joint {joint}: negative compliance")]
    NegativeCompliance {
        /// The offending joint.
        joint: usize,
    },
    /// The (effective) mass of a body is not positive definite.
    #[error("body {body}: mass not positive definite")]
    NotPositiveDefinite {
        /// The offending body.
        body: usize,
    },
    /// A joint whose rows are dependent on an eliminated body but not redundant: some row
    /// combination acts on one of its bodies only. The fixed elimination order cannot pivot on it.
    #[error("joint {joint}: rows dependent on one body but not redundant (one-sided rows)")]
    OneSidedRows {
        /// The offending joint.
        joint: usize,
    },
    /// Overflow during the factorisation (finite but huge input).
    #[error("numerical breakdown at {at:?}")]
    Breakdown {
        /// The pivot where it happened.
        at: KktNode,
    },
    /// [`KktSolver::solve`] without a successful [`KktSolver::factor`].
    #[error("solve without a successful factorisation")]
    NotFactored,
}

/// Summary of one numeric factorisation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FactorReport {
    /// Number of rows dropped as redundant (listed by [`KktSolver::dropped_rows`]).
    pub redundant_rows: usize,
}

/// A row dropped as redundant by the last factorisation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DroppedRow {
    /// The joint.
    pub joint: usize,
    /// The row inside the joint, `0..rows`.
    pub row: usize,
}

/// Where a node's right-hand side lives.
#[derive(Clone, Copy, Debug)]
struct RhsLoc {
    /// In the joint vector (else in the flattened body vector).
    joint: bool,
    /// Offset in that vector.
    off: usize,
}

/// One pivot, in elimination order.
#[derive(Clone, Copy, Debug)]
struct Pivot {
    node: KktNode,
    dim: usize,
    /// Offset of the `dim × dim` diagonal block (pseudo-inverse after factorisation).
    diag_off: usize,
    /// Offset of the `dim` diagonal reference scales.
    scale_off: usize,
    rhs: RhsLoc,
    /// Range of this pivot's off-diagonal blocks in `blocks`.
    blk_start: usize,
    blk_end: usize,
    /// Range of this pivot's pair updates in `ops`.
    op_start: usize,
    op_end: usize,
}

/// Off-diagonal block between a pivot `p` and a later node `j`: `dim(j) × dim(p)`, row-major.
#[derive(Clone, Copy, Debug)]
struct Block {
    off: usize,
    /// `dim(j)`.
    rows: usize,
    /// Pivot index of `j`.
    tgt: usize,
    /// Whether `j` is a body.
    tgt_body: bool,
    /// Right-hand side of `j`.
    rhs: RhsLoc,
}

/// Schur update of pivot `p` on the block between two of its later neighbours `j` (earlier) and
/// `k` (later): `A_kj -= (W_k P⁺) W_jᵀ`.
#[derive(Clone, Copy, Debug)]
struct PairOp {
    /// Block of `k` in `p`'s list.
    k_blk: usize,
    /// Block of `j` in `p`'s list.
    j_blk: usize,
    /// Block of `k` in `j`'s list (the destination).
    dst_blk: usize,
}

/// Where a Jacobian slot is assembled.
#[derive(Clone, Copy, Debug)]
struct JacTarget {
    off: usize,
    /// Stored as `6 × m` (body eliminated after the joint) rather than `m × 6`.
    transposed: bool,
}

/// Why a pivot block could not be factored.
enum PivotFail {
    NonFinite,
    NotPositive,
}

/// Block-sparse `LDLᵀ` solver for the KKT system of jointed rigid bodies.
///
/// Create it with [`KktSolver::new`] when the topology changes, then call
/// [`KktSolver::factor`] once per new set of values and [`KktSolver::solve`] once per
/// right-hand side.
#[derive(Clone, Debug)]
pub struct KktSolver {
    nb: usize,
    specs: Vec<JointBlockSpec>,
    row_off: Vec<usize>,
    pivots: Vec<Pivot>,
    blocks: Vec<Block>,
    ops: Vec<PairOp>,
    jac_targets: Vec<[Option<JacTarget>; 2]>,
    /// Pivot index of each body.
    body_pivot: Vec<usize>,
    /// Pivot index of each joint (`usize::MAX` for joints without rows).
    joint_pivot: Vec<usize>,
    incidences: usize,
    diag: Vec<Real>,
    scale: Vec<Real>,
    offd: Vec<Real>,
    tmp: Vec<Real>,
    dropped: Vec<DroppedRow>,
    tol: Real,
    factored: bool,
}

impl KktSolver {
    /// Symbolic phase: elimination order and fill pattern for `nb` bodies and the given joints.
    /// Call it only when the topology changes.
    ///
    /// # Errors
    /// [`KktError::InvalidJoint`] if a joint has more than [`MAX_JOINT_ROWS`] rows or a body index
    /// `>= nb`.
    pub fn new(nb: usize, joints: &[JointBlockSpec]) -> Result<Self, KktError> {
        let nj = joints.len();
        for (k, s) in joints.iter().enumerate() {
            if s.rows > MAX_JOINT_ROWS || s.bodies.iter().flatten().any(|&b| b >= nb) {
                return Err(KktError::InvalidJoint { joint: k });
            }
        }
        let mut row_off = Vec::with_capacity(nj + 1);
        let mut acc = 0;
        for s in joints {
            row_off.push(acc);
            acc += s.rows;
        }
        row_off.push(acc);

        let n_nodes = nb + nj;
        let dim = |v: usize| {
            if v < nb {
                BODY_DOFS
            } else {
                joints[v - nb].rows
            }
        };
        let active = |v: usize| v < nb || joints[v - nb].rows > 0;

        // Elimination game.
        let mut adj: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); n_nodes];
        let mut incidences = 0;
        for (k, s) in joints.iter().enumerate() {
            if s.rows == 0 {
                continue;
            }
            for &b in s.bodies.iter().flatten() {
                if adj[nb + k].insert(b) {
                    adj[b].insert(nb + k);
                    incidences += 1;
                }
            }
        }
        let mut leaf_ok = vec![false; nj];
        let eligible = |v: usize, adj: &[BTreeSet<usize>], leaf_ok: &[bool]| {
            v < nb || leaf_ok[v - nb] || adj[v].range(..nb).next().is_none()
        };
        let mut key: Vec<Option<usize>> = vec![None; n_nodes];
        let mut done = vec![false; n_nodes];
        let mut queue = BTreeSet::new();
        for v in (0..n_nodes).filter(|&v| active(v)) {
            if eligible(v, &adj, &leaf_ok) {
                queue.insert((adj[v].len(), v));
                key[v] = Some(adj[v].len());
            }
        }
        let n_active = (0..n_nodes).filter(|&v| active(v)).count();
        let mut order = Vec::with_capacity(n_active);
        let mut nbr_lists: Vec<Vec<usize>> = Vec::with_capacity(n_active);
        while order.len() < n_active {
            let p = match queue.pop_first() {
                Some((_, p)) => p,
                // Unreachable (a body is always eligible and joints become eligible once all
                // bodies are gone); kept so that a logic error cannot loop or panic.
                None => match (0..n_nodes).find(|&v| active(v) && !done[v]) {
                    Some(v) => v,
                    None => break,
                },
            };
            key[p] = None;
            done[p] = true;
            let nbrs: Vec<usize> = std::mem::take(&mut adj[p]).into_iter().collect();
            for &j in &nbrs {
                adj[j].remove(&p);
            }
            for (a, &i) in nbrs.iter().enumerate() {
                for &l in &nbrs[a + 1..] {
                    adj[i].insert(l);
                    adj[l].insert(i);
                }
            }
            if p < nb && nbrs.len() == 1 && nbrs[0] >= nb {
                leaf_ok[nbrs[0] - nb] = true;
            }
            for &j in &nbrs {
                if let Some(d) = key[j].take() {
                    queue.remove(&(d, j));
                }
                if eligible(j, &adj, &leaf_ok) {
                    queue.insert((adj[j].len(), j));
                    key[j] = Some(adj[j].len());
                }
            }
            order.push(p);
            nbr_lists.push(nbrs);
        }

        // Numbering and storage.
        let mut pos = vec![usize::MAX; n_nodes];
        for (t, &v) in order.iter().enumerate() {
            pos[v] = t;
        }
        let rhs_of = |v: usize| {
            if v < nb {
                RhsLoc {
                    joint: false,
                    off: BODY_DOFS * v,
                }
            } else {
                RhsLoc {
                    joint: true,
                    off: row_off[v - nb],
                }
            }
        };
        let mut pivots = Vec::with_capacity(order.len());
        let mut blocks = Vec::new();
        let mut edge: HashMap<(usize, usize), usize> = HashMap::new();
        let (mut diag_len, mut scale_len, mut offd_len, mut tmp_len) = (0, 0, 0, 0);
        for (t, &v) in order.iter().enumerate() {
            let n = dim(v);
            let nbrs = &mut nbr_lists[t];
            nbrs.sort_unstable_by_key(|&j| pos[j]);
            let blk_start = blocks.len();
            let off_start = offd_len;
            for &j in nbrs.iter() {
                edge.insert((v, j), blocks.len());
                blocks.push(Block {
                    off: offd_len,
                    rows: dim(j),
                    tgt: pos[j],
                    tgt_body: j < nb,
                    rhs: rhs_of(j),
                });
                offd_len += dim(j) * n;
            }
            tmp_len = tmp_len.max(offd_len - off_start);
            pivots.push(Pivot {
                node: if v < nb {
                    KktNode::Body(v)
                } else {
                    KktNode::Joint(v - nb)
                },
                dim: n,
                diag_off: diag_len,
                scale_off: scale_len,
                rhs: rhs_of(v),
                blk_start,
                blk_end: blocks.len(),
                op_start: 0,
                op_end: 0,
            });
            diag_len += n * n;
            scale_len += n;
        }
        let mut ops = Vec::new();
        for (t, &v) in order.iter().enumerate() {
            let nbrs = &nbr_lists[t];
            let start = ops.len();
            for (a, &j) in nbrs.iter().enumerate() {
                for &k in &nbrs[a + 1..] {
                    ops.push(PairOp {
                        k_blk: edge[&(v, k)],
                        j_blk: edge[&(v, j)],
                        // `j` and `k` are adjacent from `v`'s elimination on and `j` goes first.
                        dst_blk: edge[&(j, k)],
                    });
                }
            }
            pivots[t].op_start = start;
            pivots[t].op_end = ops.len();
        }
        let mut jac_targets = vec![[None; 2]; nj];
        for (k, s) in joints.iter().enumerate() {
            if s.rows == 0 {
                continue;
            }
            let vj = nb + k;
            for (slot, body) in s.bodies.iter().enumerate() {
                if let Some(b) = *body {
                    let (first, second, transposed) = if pos[b] < pos[vj] {
                        (b, vj, false)
                    } else {
                        (vj, b, true)
                    };
                    let off = blocks[edge[&(first, second)]].off;
                    jac_targets[k][slot] = Some(JacTarget { off, transposed });
                }
            }
        }
        let body_pivot = (0..nb).map(|b| pos[b]).collect();
        let joint_pivot = (0..nj).map(|k| pos[nb + k]).collect();
        Ok(Self {
            nb,
            specs: joints.to_vec(),
            row_off,
            pivots,
            blocks,
            ops,
            jac_targets,
            body_pivot,
            joint_pivot,
            incidences,
            diag: vec![0.0; diag_len],
            scale: vec![0.0; scale_len],
            offd: vec![0.0; offd_len],
            tmp: vec![0.0; tmp_len],
            dropped: Vec::new(),
            tol: Self::default_redundancy_tolerance(),
            factored: false,
        })
    }

    /// The default relative tolerance of the redundancy test, `2 Real::EPSILON^(2/3)`.
    pub fn default_redundancy_tolerance() -> Real {
        2.0 * Real::EPSILON.powf(2.0 / 3.0)
    }

    /// The relative tolerance of the redundancy test.
    pub fn redundancy_tolerance(&self) -> Real {
        self.tol
    }

    /// Sets the relative tolerance of the redundancy test (a joint pivot `|d| <= tol * s` drops
    /// its row). Non-finite or negative values are ignored.
    pub fn set_redundancy_tolerance(&mut self, tol: Real) {
        if tol.is_finite() && tol >= 0.0 {
            self.tol = tol;
        }
    }

    /// Number of bodies.
    pub fn num_bodies(&self) -> usize {
        self.nb
    }

    /// Number of joints (including those without rows).
    pub fn num_joints(&self) -> usize {
        self.specs.len()
    }

    /// Total number of constraint rows.
    pub fn num_rows(&self) -> usize {
        self.row_off[self.specs.len()]
    }

    /// First global row of `joint` (its rows are `row_offset(joint) .. row_offset(joint + 1)`;
    /// `joint == num_joints()` gives [`Self::num_rows`]).
    pub fn row_offset(&self, joint: usize) -> usize {
        self.row_off[joint.min(self.specs.len())]
    }

    /// Length of the Jacobian arena: [`JAC_ROW_STRIDE`]` * num_rows()`.
    pub fn jacobian_len(&self) -> usize {
        JAC_ROW_STRIDE * self.num_rows()
    }

    /// The joint structure given to [`Self::new`].
    pub fn joint_specs(&self) -> &[JointBlockSpec] {
        &self.specs
    }

    /// Number of stored off-diagonal blocks (joint–body incidences plus fill).
    pub fn stored_offdiag_blocks(&self) -> usize {
        self.blocks.len()
    }

    /// Number of fill blocks (stored off-diagonal blocks that are not joint–body incidences).
    pub fn fill_blocks(&self) -> usize {
        self.blocks.len() - self.incidences
    }

    /// The elimination order.
    pub fn elimination_order(&self) -> impl Iterator<Item = KktNode> + '_ {
        self.pivots.iter().map(|p| p.node)
    }

    /// Position of a node in the elimination order (`None` for a joint without rows or an index
    /// out of range).
    pub fn elimination_position(&self, node: KktNode) -> Option<usize> {
        let p = match node {
            KktNode::Body(b) => *self.body_pivot.get(b)?,
            KktNode::Joint(k) => *self.joint_pivot.get(k)?,
        };
        (p < self.pivots.len()).then_some(p)
    }

    /// The rows dropped as redundant by the last factorisation.
    pub fn dropped_rows(&self) -> &[DroppedRow] {
        &self.dropped
    }

    /// Numeric factorisation.
    ///
    /// * `mass[b]`: 6×6 row-major mass matrix of body `b` (symmetric positive definite).
    /// * `jac`: the Jacobian arena, [`JAC_ROW_STRIDE`] reals per global row (see the module docs).
    /// * `compliance`: one non-negative real per global row.
    ///
    /// # Errors
    /// Length mismatches, non-finite input, negative compliance, a mass that is not positive
    /// definite, one-sided rank-deficient joint rows, overflow. After an error
    /// [`Self::solve`] refuses to run until the next successful factorisation.
    pub fn factor(
        &mut self,
        mass: &[[Real; 36]],
        jac: &[Real],
        compliance: &[Real],
    ) -> Result<FactorReport, KktError> {
        self.factored = false;
        self.dropped.clear();
        let rows = self.num_rows();
        check_len("mass", self.nb, mass.len())?;
        check_len("jac", JAC_ROW_STRIDE * rows, jac.len())?;
        check_len("compliance", rows, compliance.len())?;
        for (b, m) in mass.iter().enumerate() {
            if m.iter().any(|v| !v.is_finite()) {
                return Err(KktError::NonFinite {
                    at: KktNode::Body(b),
                });
            }
        }
        for (k, s) in self.specs.iter().enumerate() {
            let (r0, r1) = (self.row_off[k], self.row_off[k + 1]);
            let at = KktNode::Joint(k);
            for &c in &compliance[r0..r1] {
                if !c.is_finite() {
                    return Err(KktError::NonFinite { at });
                }
                if c < 0.0 {
                    return Err(KktError::NegativeCompliance { joint: k });
                }
            }
            for (slot, body) in s.bodies.iter().enumerate() {
                if body.is_some() {
                    for r in r0..r1 {
                        let o = JAC_ROW_STRIDE * r + BODY_DOFS * slot;
                        if jac[o..o + BODY_DOFS].iter().any(|v| !v.is_finite()) {
                            return Err(KktError::NonFinite { at });
                        }
                    }
                }
            }
        }

        // Assembly.
        for pv in &self.pivots {
            let n = pv.dim;
            let d = &mut self.diag[pv.diag_off..pv.diag_off + n * n];
            let s = &mut self.scale[pv.scale_off..pv.scale_off + n];
            match pv.node {
                KktNode::Body(b) => {
                    let m = &mass[b];
                    for i in 0..n {
                        for j in 0..n {
                            d[i * n + j] = 0.5 * (m[i * 6 + j] + m[j * 6 + i]);
                        }
                        s[i] = d[i * n + i].abs();
                    }
                }
                KktNode::Joint(k) => {
                    d.fill(0.0);
                    let c = &compliance[self.row_off[k]..self.row_off[k] + n];
                    for (i, &ci) in c.iter().enumerate() {
                        d[i * n + i] = -ci;
                        s[i] = ci;
                    }
                }
            }
        }
        self.offd.fill(0.0);
        for (k, targets) in self.jac_targets.iter().enumerate() {
            let (r0, m) = (self.row_off[k], self.specs[k].rows);
            for (slot, t) in targets.iter().enumerate() {
                let Some(t) = t else { continue };
                for i in 0..m {
                    let o = JAC_ROW_STRIDE * (r0 + i) + BODY_DOFS * slot;
                    for (c, &v) in jac[o..o + BODY_DOFS].iter().enumerate() {
                        let idx = if t.transposed { c * m + i } else { i * 6 + c };
                        self.offd[t.off + idx] += v;
                    }
                }
            }
        }

        // Right-looking block elimination.
        let mut work = PivotWork::default();
        for pi in 0..self.pivots.len() {
            let pv = self.pivots[pi];
            let n = pv.dim;
            let body = matches!(pv.node, KktNode::Body(_));
            let thresh = if body { 64.0 * Real::EPSILON } else { self.tol };
            let dblk = &mut self.diag[pv.diag_off..pv.diag_off + n * n];
            let sblk = &self.scale[pv.scale_off..pv.scale_off + n];
            let rank = match work.factor(dblk, sblk, n, thresh, body) {
                Ok(r) => r,
                Err(PivotFail::NonFinite) => return Err(KktError::Breakdown { at: pv.node }),
                Err(PivotFail::NotPositive) => {
                    return Err(match pv.node {
                        KktNode::Body(b) => KktError::NotPositiveDefinite { body: b },
                        KktNode::Joint(_) => KktError::Breakdown { at: pv.node },
                    });
                }
            };
            if let (KktNode::Joint(k), true) = (pv.node, rank < n) {
                self.check_dropped(&work, &pv, rank, k)?;
                for q in rank..n {
                    self.dropped.push(DroppedRow {
                        joint: k,
                        row: work.perm[q],
                    });
                }
            }
            if pv.blk_start == pv.blk_end {
                continue;
            }
            by_dim!(n, N => self.schur_update::<N>(pv));
        }
        self.factored = true;
        Ok(FactorReport {
            redundant_rows: self.dropped.len(),
        })
    }

    /// Schur-complement updates of pivot `pv` (dimension `N`, already factored) on its later
    /// neighbours.
    fn schur_update<const N: usize>(&mut self, pv: Pivot) {
        let n = N;
        // Later pivots' diagonal blocks lie after this one.
        let split = pv.diag_off + n * n;
        let (head, tail) = self.diag.split_at_mut(split);
        let pinv = &head[pv.diag_off..];
        let base = self.blocks[pv.blk_start].off;
        // T_j = W_j P⁺ (P⁺ is symmetric, so this is W_j P⁺ᵀ).
        for blk in &self.blocks[pv.blk_start..pv.blk_end] {
            let len = blk.rows * n;
            let w = &self.offd[blk.off..blk.off + len];
            let t = &mut self.tmp[blk.off - base..blk.off - base + len];
            for (trow, wrow) in t.chunks_exact_mut(n).zip(w.chunks_exact(n)) {
                for (tv, prow) in trow.iter_mut().zip(pinv.chunks_exact(n)) {
                    *tv = dot_n::<N>(wrow, prow);
                }
            }
        }
        // Diagonal updates D_j -= T_j W_jᵀ (symmetric: lower triangle, mirrored), with the
        // reference scales.
        for blk in &self.blocks[pv.blk_start..pv.blk_end] {
            let tgt = self.pivots[blk.tgt];
            let (m, len) = (blk.rows, blk.rows * n);
            let w = &self.offd[blk.off..blk.off + len];
            let t = &self.tmp[blk.off - base..blk.off - base + len];
            let d = &mut tail[tgt.diag_off - split..tgt.diag_off - split + m * m];
            let s = &mut self.scale[tgt.scale_off..tgt.scale_off + m];
            for (a, (ta, wa)) in t.chunks_exact(n).zip(w.chunks_exact(n)).enumerate() {
                for (b, wb) in w.chunks_exact(n).take(a).enumerate() {
                    let v = d[a * m + b] - dot_n::<N>(ta, wb);
                    d[a * m + b] = v;
                    d[b * m + a] = v;
                }
                let v = dot_n::<N>(ta, wa);
                d[a * m + a] -= v;
                s[a] += v.abs();
            }
        }
        // Off-diagonal (fill) updates A_kj -= T_k W_jᵀ.
        for op in &self.ops[pv.op_start..pv.op_end] {
            let (bk, bj, bd) = (
                self.blocks[op.k_blk],
                self.blocks[op.j_blk],
                self.blocks[op.dst_blk],
            );
            // The destination belongs to a later pivot, so it lies after `p`'s blocks.
            let (lo, hi) = self.offd.split_at_mut(bd.off);
            let w = &lo[bj.off..bj.off + bj.rows * n];
            let t = &self.tmp[bk.off - base..bk.off - base + bk.rows * n];
            sub_mul_nt(&mut hi[..bk.rows * bj.rows], t, w, n);
        }
    }

    /// For a joint pivot that dropped rows while still coupled to a body: each dropped direction
    /// `v` must also vanish on that body (`W v ≈ 0`), else the rows were not redundant.
    fn check_dropped(
        &self,
        work: &PivotWork,
        pv: &Pivot,
        rank: usize,
        joint: usize,
    ) -> Result<(), KktError> {
        let n = pv.dim;
        let loose = self.tol.sqrt();
        for q in rank..n {
            let v = work.null_vector(n, rank, q);
            let vnorm: Real = v[..n].iter().map(|x| x.abs()).sum();
            for blk in &self.blocks[pv.blk_start..pv.blk_end] {
                if !blk.tgt_body {
                    continue;
                }
                let w = &self.offd[blk.off..blk.off + blk.rows * n];
                let wmax = w.iter().fold(0.0, |a: Real, &x| a.max(x.abs()));
                for wrow in w.chunks_exact(n) {
                    if dot(wrow, &v[..n]).abs() > loose * wmax * vnorm {
                        return Err(KktError::OneSidedRows { joint });
                    }
                }
            }
        }
        Ok(())
    }

    /// Solves the factored system in place for one right-hand side: on input `rhs_bodies[b]` is
    /// `f_b` and `rhs_joints` is `g` (one real per global row), on output they hold `x_b` and
    /// `lambda` (zero on dropped rows). NaN in the right-hand side propagates as NaN.
    ///
    /// # Errors
    /// [`KktError::NotFactored`] without a successful factorisation,
    /// [`KktError::LengthMismatch`] for slices of the wrong length.
    pub fn solve(
        &self,
        rhs_bodies: &mut [[Real; 6]],
        rhs_joints: &mut [Real],
    ) -> Result<(), KktError> {
        if !self.factored {
            return Err(KktError::NotFactored);
        }
        check_len("rhs_bodies", self.nb, rhs_bodies.len())?;
        check_len("rhs_joints", self.num_rows(), rhs_joints.len())?;
        let bodies = rhs_bodies.as_flattened_mut();
        // Forward: z_p final, then rhs_j -= W_j P⁺ z_p.
        for pv in &self.pivots {
            by_dim!(pv.dim, N => self.forward_step::<N>(pv, bodies, rhs_joints));
        }
        // Backward: x_p = P⁺ (z_p - Σ W_jᵀ x_j).
        for pv in self.pivots.iter().rev() {
            by_dim!(pv.dim, N => self.backward_step::<N>(pv, bodies, rhs_joints));
        }
        Ok(())
    }
}

impl KktSolver {
    /// Forward substitution of pivot `pv` (dimension `N`).
    fn forward_step<const N: usize>(&self, pv: &Pivot, bodies: &mut [Real], joints: &mut [Real]) {
        let pinv = &self.diag[pv.diag_off..pv.diag_off + N * N];
        let mut u = [0.0; N];
        let z = seg(pv.rhs, N, bodies, joints);
        for (ui, prow) in u.iter_mut().zip(pinv.chunks_exact(N)) {
            *ui = dot_n::<N>(prow, z);
        }
        for blk in &self.blocks[pv.blk_start..pv.blk_end] {
            let w = &self.offd[blk.off..blk.off + blk.rows * N];
            let r = seg(blk.rhs, blk.rows, bodies, joints);
            for (ri, wrow) in r.iter_mut().zip(w.chunks_exact(N)) {
                *ri -= dot_n::<N>(wrow, &u);
            }
        }
    }

    /// Backward substitution of pivot `pv` (dimension `N`).
    fn backward_step<const N: usize>(&self, pv: &Pivot, bodies: &mut [Real], joints: &mut [Real]) {
        let pinv = &self.diag[pv.diag_off..pv.diag_off + N * N];
        let mut t = [0.0; N];
        t.copy_from_slice(seg(pv.rhs, N, bodies, joints));
        for blk in &self.blocks[pv.blk_start..pv.blk_end] {
            let w = &self.offd[blk.off..blk.off + blk.rows * N];
            let x = seg(blk.rhs, blk.rows, bodies, joints);
            for (wrow, &xa) in w.chunks_exact(N).zip(x.iter()) {
                for (tc, &wc) in t.iter_mut().zip(wrow) {
                    *tc -= wc * xa;
                }
            }
        }
        let out = seg(pv.rhs, N, bodies, joints);
        for (o, prow) in out.iter_mut().zip(pinv.chunks_exact(N)) {
            *o = dot_n::<N>(prow, &t);
        }
    }
}

fn check_len(what: &'static str, expected: usize, got: usize) -> Result<(), KktError> {
    if expected == got {
        Ok(())
    } else {
        Err(KktError::LengthMismatch {
            what,
            expected,
            got,
        })
    }
}

/// The right-hand-side segment of a node.
fn seg<'a>(
    loc: RhsLoc,
    len: usize,
    bodies: &'a mut [Real],
    joints: &'a mut [Real],
) -> &'a mut [Real] {
    if loc.joint {
        &mut joints[loc.off..loc.off + len]
    } else {
        &mut bodies[loc.off..loc.off + len]
    }
}

/// Dot product of the first `N` entries (a compile-time length, so the loop is unrolled).
#[inline]
fn dot_n<const N: usize>(a: &[Real], b: &[Real]) -> Real {
    a[..N].iter().zip(&b[..N]).map(|(x, y)| x * y).sum()
}

#[inline]
fn dot(a: &[Real], b: &[Real]) -> Real {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `dst (m×n) -= a (m×k) · bᵀ` with `b` of shape `n×k`, all row-major.
#[inline]
fn sub_mul_nt(dst: &mut [Real], a: &[Real], b: &[Real], k: usize) {
    let n = b.len() / k;
    for (drow, arow) in dst.chunks_exact_mut(n).zip(a.chunks_exact(k)) {
        for (d, brow) in drow.iter_mut().zip(b.chunks_exact(k)) {
            *d -= dot(arow, brow);
        }
    }
}

/// Row stride of the pivot scratch matrices.
const STRIDE: usize = MAX_DIM;

/// Scratch of the dense pivoted `LDLᵀ` of one pivot block (row stride [`STRIDE`]).
struct PivotWork {
    /// Unit lower `L` (strictly below the diagonal) and `D` (diagonal), permuted order; only the
    /// lower triangle is used.
    w: [Real; STRIDE * STRIDE],
    /// `L11⁻¹` of the kept part (lower triangle).
    x: [Real; STRIDE * STRIDE],
    /// `1 / d_i` of the kept pivots.
    inv_d: [Real; STRIDE],
    /// `perm[i]` is the original index of permuted row `i`.
    perm: [usize; STRIDE],
}

impl Default for PivotWork {
    fn default() -> Self {
        Self {
            w: [0.0; STRIDE * STRIDE],
            x: [0.0; STRIDE * STRIDE],
            inv_d: [0.0; STRIDE],
            perm: [0; STRIDE],
        }
    }
}

impl PivotWork {
    /// Factors the symmetric `n×n` block `a` (its lower triangle is read) by `LDLᵀ` with
    /// symmetric diagonal pivoting (largest `|d_i| / s_i` first, first index on ties) and
    /// overwrites it with the pseudo-inverse that drops the rows whose scaled pivot is
    /// `<= thresh`. Returns the rank.
    fn factor(
        &mut self,
        a: &mut [Real],
        scale: &[Real],
        n: usize,
        thresh: Real,
        body: bool,
    ) -> Result<usize, PivotFail> {
        // Dispatch on the size so that every loop has a compile-time bound.
        by_dim!(n, N => self.factor_n::<N>(a, scale, thresh, body))
    }

    /// [`Self::factor`] for `n = N`.
    fn factor_n<const N: usize>(
        &mut self,
        a: &mut [Real],
        scale: &[Real],
        thresh: Real,
        body: bool,
    ) -> Result<usize, PivotFail> {
        let n = N;
        let a = &mut a[..n * n];
        let w = &mut self.w;
        let mut inv_s = [0.0; STRIDE];
        for i in 0..n {
            self.perm[i] = i;
            inv_s[i] = if scale[i] > 0.0 { 1.0 / scale[i] } else { 0.0 };
            w[i * STRIDE..i * STRIDE + i + 1].copy_from_slice(&a[i * n..i * n + i + 1]);
        }
        let mut rank = n;
        for k in 0..n {
            let mut best = k;
            let mut best_ratio = -1.0;
            for i in k..n {
                let d = w[i * STRIDE + i];
                if !d.is_finite() {
                    return Err(PivotFail::NonFinite);
                }
                let r = d.abs() * inv_s[i];
                if r > best_ratio {
                    best = i;
                    best_ratio = r;
                }
            }
            if best_ratio.is_nan() || best_ratio <= thresh {
                rank = k;
                break;
            }
            if best != k {
                // Symmetric swap of rows/columns `k < best` in lower-triangle storage.
                for j in 0..k {
                    w.swap(k * STRIDE + j, best * STRIDE + j);
                }
                for i in k + 1..best {
                    w.swap(i * STRIDE + k, best * STRIDE + i);
                }
                for i in best + 1..n {
                    w.swap(i * STRIDE + k, i * STRIDE + best);
                }
                w.swap(k * STRIDE + k, best * STRIDE + best);
                self.perm.swap(k, best);
                inv_s.swap(k, best);
            }
            let d = w[k * STRIDE + k];
            if body && d <= 0.0 {
                return Err(PivotFail::NotPositive);
            }
            let id = 1.0 / d;
            self.inv_d[k] = id;
            // Rows in increasing order: for `j < i` the column entry `w[j][k]` is already `l_j`,
            // and `A_ij - l_i d l_j = A_ij - A_ik l_j`.
            for i in k + 1..n {
                let aik = w[i * STRIDE + k];
                let li = aik * id;
                for j in k + 1..i {
                    w[i * STRIDE + j] -= aik * w[j * STRIDE + k];
                }
                w[i * STRIDE + i] -= aik * li;
                w[i * STRIDE + k] = li;
            }
        }
        if body && rank < n {
            return Err(PivotFail::NotPositive);
        }
        // X = L11⁻¹ (unit lower), then P⁺ = Πᵀ (Xᵀ D⁻¹ X ⊕ 0) Π.
        let x = &mut self.x;
        for i in 0..rank {
            x[i * STRIDE + i] = 1.0;
            for j in 0..i {
                let mut acc = -w[i * STRIDE + j];
                for k in j + 1..i {
                    acc -= w[i * STRIDE + k] * x[k * STRIDE + j];
                }
                x[i * STRIDE + j] = acc;
            }
        }
        a.fill(0.0);
        for p in 0..rank {
            for q in 0..=p {
                let mut v = 0.0;
                for i in p..rank {
                    v += x[i * STRIDE + p] * x[i * STRIDE + q] * self.inv_d[i];
                }
                let (pp, pq) = (self.perm[p], self.perm[q]);
                a[pp * n + pq] = v;
                a[pq * n + pp] = v;
            }
        }
        if a.iter().any(|v| !v.is_finite()) {
            return Err(PivotFail::NonFinite);
        }
        Ok(rank)
    }

    /// Null vector (original row order) of the factored block for the dropped permuted row `q`:
    /// `y = [-L11⁻ᵀ l; e_q]` with `l` the kept part of row `q` of `L`.
    fn null_vector(&self, n: usize, rank: usize, q: usize) -> [Real; MAX_DIM] {
        let mut y = [0.0; MAX_DIM];
        y[q] = 1.0;
        for (a, ya) in y[..rank].iter_mut().enumerate() {
            let mut acc = 0.0;
            for i in a..rank {
                acc += self.x[i * STRIDE + a] * self.w[q * STRIDE + i];
            }
            *ya = -acc;
        }
        let mut v = [0.0; MAX_DIM];
        for (i, &yi) in y[..n].iter().enumerate() {
            v[self.perm[i]] = yi;
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Relative tolerance for comparisons with the dense reference. Both solvers are backward
    /// stable, so they agree to about `cond(K) * eps`: the largest difference measured on the
    /// random systems below is 4e-13 in `f64` (about 2000 eps) and 7e-4 in `f32`. `1e7 eps`
    /// (2.2e-9 in `f64`) leaves a margin of 5000; in `f32` the bound is capped at 1e-2.
    fn rel_tol() -> Real {
        (1.0e7 * Real::EPSILON).min(1.0e-2)
    }

    /// Deterministic 64-bit LCG (Knuth's MMIX constants).
    struct Lcg(u64);

    impl Lcg {
        /// Uniform in `[-1, 1)`.
        fn next(&mut self) -> Real {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (self.0 >> 11) as Real / (1u64 << 53) as Real * 2.0 - 1.0
        }
    }

    #[derive(Clone)]
    struct Problem {
        nb: usize,
        specs: Vec<JointBlockSpec>,
        mass: Vec<[Real; 36]>,
        jac: Vec<Real>,
        comp: Vec<Real>,
        f: Vec<[Real; 6]>,
        g: Vec<Real>,
    }

    fn random_spd(rng: &mut Lcg) -> [Real; 36] {
        let a: Vec<Real> = (0..36).map(|_| rng.next()).collect();
        let mut m = [0.0; 36];
        for i in 0..6 {
            for j in 0..6 {
                m[i * 6 + j] = (0..6).map(|k| a[i * 6 + k] * a[j * 6 + k]).sum::<Real>();
            }
            m[i * 6 + i] += 0.5;
        }
        m
    }

    /// Random problem; `joints` are `(rows, body0, body1)`; absent slots are filled with NaN to
    /// check that they are ignored.
    fn random_problem(
        rng: &mut Lcg,
        nb: usize,
        joints: &[(usize, Option<usize>, Option<usize>)],
        comp: Real,
    ) -> Problem {
        let specs: Vec<JointBlockSpec> = joints
            .iter()
            .map(|&(rows, a, b)| JointBlockSpec {
                rows,
                bodies: [a, b],
            })
            .collect();
        let rows: usize = specs.iter().map(|s| s.rows).sum();
        let mut jac = vec![0.0; JAC_ROW_STRIDE * rows];
        // Each block is a dominant ±1.5 entry per row (distinct columns) plus uniform noise in
        // ±0.5: random but safely full rank, so that no row is close to the redundancy test.
        let mut r = 0;
        for s in &specs {
            for li in 0..s.rows {
                for slot in 0..2 {
                    let sign = if slot == 0 { 1.5 } else { -1.5 };
                    for c in 0..6 {
                        let dominant = if c == (li + 3 * slot) % 6 { sign } else { 0.0 };
                        jac[JAC_ROW_STRIDE * r + 6 * slot + c] = if s.bodies[slot].is_some() {
                            dominant + 0.5 * rng.next()
                        } else {
                            Real::NAN
                        };
                    }
                }
                r += 1;
            }
        }
        Problem {
            nb,
            mass: (0..nb).map(|_| random_spd(rng)).collect(),
            comp: (0..rows).map(|_| comp * (1.0 + rng.next())).collect(),
            f: (0..nb)
                .map(|_| std::array::from_fn(|_| rng.next()))
                .collect(),
            g: (0..rows).map(|_| rng.next()).collect(),
            specs,
            jac,
        }
    }

    impl Problem {
        fn rows(&self) -> usize {
            self.g.len()
        }

        /// Iterates `(joint, global row, slot, body)` over present Jacobian slots.
        fn slots(&self) -> Vec<(usize, usize, usize, usize)> {
            let mut out = Vec::new();
            let mut r = 0;
            for (k, s) in self.specs.iter().enumerate() {
                for _ in 0..s.rows {
                    for (slot, b) in s.bodies.iter().enumerate() {
                        if let Some(b) = *b {
                            out.push((k, r, slot, b));
                        }
                    }
                    r += 1;
                }
            }
            out
        }

        /// Dense solution `(x, lambda)` of the full KKT matrix.
        fn dense_solve(&self) -> (Vec<[Real; 6]>, Vec<Real>) {
            let nx = 6 * self.nb;
            let n = nx + self.rows();
            let mut a = vec![0.0; n * n];
            let mut b = vec![0.0; n];
            for (bi, m) in self.mass.iter().enumerate() {
                for i in 0..6 {
                    for j in 0..6 {
                        a[(6 * bi + i) * n + 6 * bi + j] = m[i * 6 + j];
                    }
                    b[6 * bi + i] = self.f[bi][i];
                }
            }
            for (_, r, slot, body) in self.slots() {
                for c in 0..6 {
                    let v = self.jac[JAC_ROW_STRIDE * r + 6 * slot + c];
                    a[(nx + r) * n + 6 * body + c] += v;
                    a[(6 * body + c) * n + nx + r] += v;
                }
            }
            for r in 0..self.rows() {
                a[(nx + r) * n + nx + r] = -self.comp[r];
                b[nx + r] = self.g[r];
            }
            let sol = dense_gauss(n, a, b);
            let x = (0..self.nb)
                .map(|bi| std::array::from_fn(|i| sol[6 * bi + i]))
                .collect();
            (x, sol[nx..].to_vec())
        }

        fn sparse_solve(&self) -> (KktSolver, FactorReport, Vec<[Real; 6]>, Vec<Real>) {
            let mut s = KktSolver::new(self.nb, &self.specs).unwrap();
            let rep = s.factor(&self.mass, &self.jac, &self.comp).unwrap();
            let mut x = self.f.clone();
            let mut l = self.g.clone();
            s.solve(&mut x, &mut l).unwrap();
            (s, rep, x, l)
        }

        /// Max-norm residuals `(M x + Jᵀ λ - f, J x - C λ - g)` relative to the largest term.
        fn residual(&self, x: &[[Real; 6]], l: &[Real]) -> (Real, Real) {
            let mut rb: Vec<[Real; 6]> = vec![[0.0; 6]; self.nb];
            let mut rj: Vec<Real> = vec![0.0; self.rows()];
            let mut scale: Real = 0.0;
            for (bi, m) in self.mass.iter().enumerate() {
                for i in 0..6 {
                    let mx: Real = (0..6).map(|j| m[i * 6 + j] * x[bi][j]).sum();
                    rb[bi][i] = mx - self.f[bi][i];
                    scale = scale.max(mx.abs()).max(self.f[bi][i].abs());
                }
            }
            for (_, r, slot, body) in self.slots() {
                for c in 0..6 {
                    let v = self.jac[JAC_ROW_STRIDE * r + 6 * slot + c];
                    rb[body][c] += v * l[r];
                    rj[r] += v * x[body][c];
                    scale = scale.max((v * l[r]).abs()).max((v * x[body][c]).abs());
                }
            }
            for r in 0..self.rows() {
                rj[r] -= self.comp[r] * l[r] + self.g[r];
            }
            let eb = rb.iter().flatten().fold(0.0, |a: Real, v| a.max(v.abs()));
            let ej = rj.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
            (eb / scale, ej / scale)
        }
    }

    /// Gaussian elimination with partial pivoting on a dense `n×n` row-major matrix.
    fn dense_gauss(n: usize, mut a: Vec<Real>, mut b: Vec<Real>) -> Vec<Real> {
        for k in 0..n {
            let p = (k..n)
                .max_by(|&i, &j| a[i * n + k].abs().total_cmp(&a[j * n + k].abs()))
                .unwrap();
            if p != k {
                for j in 0..n {
                    a.swap(k * n + j, p * n + j);
                }
                b.swap(k, p);
            }
            let d = a[k * n + k];
            for i in k + 1..n {
                let l = a[i * n + k] / d;
                if l != 0.0 {
                    for j in k..n {
                        a[i * n + j] -= l * a[k * n + j];
                    }
                    b[i] -= l * b[k];
                }
            }
        }
        let mut x = vec![0.0; n];
        for i in (0..n).rev() {
            let s: Real = (i + 1..n).map(|j| a[i * n + j] * x[j]).sum();
            x[i] = (b[i] - s) / a[i * n + i];
        }
        x
    }

    /// Max-norm relative difference of `(x, lambda)` pairs.
    fn rel_diff(a: &(Vec<[Real; 6]>, Vec<Real>), b: &(Vec<[Real; 6]>, Vec<Real>)) -> Real {
        let va: Vec<Real> = a.0.iter().flatten().chain(&a.1).copied().collect();
        let vb: Vec<Real> = b.0.iter().flatten().chain(&b.1).copied().collect();
        let scale = vb.iter().fold(0.0, |m: Real, v| m.max(v.abs()));
        let diff = va
            .iter()
            .zip(&vb)
            .fold(0.0, |m: Real, (x, y)| m.max((x - y).abs()));
        if diff.is_nan() {
            Real::INFINITY
        } else {
            diff / scale
        }
    }

    fn chain_joints(
        nb: usize,
        rows: impl Fn(usize) -> usize,
    ) -> Vec<(usize, Option<usize>, Option<usize>)> {
        (0..nb)
            .map(|k| (rows(k), if k == 0 { None } else { Some(k - 1) }, Some(k)))
            .collect()
    }

    fn tree_joints() -> Vec<(usize, Option<usize>, Option<usize>)> {
        vec![
            (6, None, Some(0)),
            (5, Some(0), Some(1)),
            (3, Some(2), Some(0)),
            (4, Some(1), Some(3)),
            (1, Some(4), Some(1)),
            (5, Some(2), Some(5)),
            (6, Some(6), Some(2)),
            (2, Some(6), Some(7)),
        ]
    }

    /// Three bodies closed to the ground at both ends: j0 ground–b0, j1 b0–b1, j2 b1–b2,
    /// j3 b2–ground (17 rows on 18 DOFs).
    fn loop_joints() -> Vec<(usize, Option<usize>, Option<usize>)> {
        vec![
            (5, None, Some(0)),
            (4, Some(0), Some(1)),
            (4, Some(2), Some(1)),
            (4, Some(2), None),
        ]
    }

    fn check_against_dense(p: &Problem) -> Real {
        let (_, rep, x, l) = p.sparse_solve();
        assert_eq!(rep.redundant_rows, 0);
        let err = rel_diff(&(x, l), &p.dense_solve());
        assert!(err < rel_tol(), "relative error {err}");
        err
    }

    #[test]
    fn random_systems_match_dense() {
        let mut rng = Lcg(1);
        for _ in 0..20 {
            let chain = chain_joints(6, |k| 1 + (k * 7 + 3) % 6);
            check_against_dense(&random_problem(&mut rng, 6, &chain, 0.0));
            check_against_dense(&random_problem(&mut rng, 8, &tree_joints(), 0.0));
            check_against_dense(&random_problem(&mut rng, 3, &loop_joints(), 0.0));
        }
    }

    #[test]
    fn orders_are_baraff_for_trees_and_fill_loops_a_little() {
        let specs = |j: &[(usize, Option<usize>, Option<usize>)]| -> Vec<JointBlockSpec> {
            j.iter()
                .map(|&(rows, a, b)| JointBlockSpec {
                    rows,
                    bodies: [a, b],
                })
                .collect()
        };
        let s = KktSolver::new(3, &specs(&chain_joints(3, |_| 5))).unwrap();
        use KktNode::{Body, Joint};
        assert_eq!(
            s.elimination_order().collect::<Vec<_>>(),
            [Body(2), Joint(2), Body(1), Joint(1), Body(0), Joint(0)]
        );
        assert_eq!(s.fill_blocks(), 0);
        let s = KktSolver::new(8, &specs(&tree_joints())).unwrap();
        assert_eq!(s.fill_blocks(), 0);
        // The loop: one joint–joint fill block per body eliminated with two joints.
        let s = KktSolver::new(3, &specs(&loop_joints())).unwrap();
        assert_eq!(s.fill_blocks(), 3);
    }

    #[test]
    fn compliance_matches_dense_and_converges_to_rigid() {
        let mut rng = Lcg(2);
        for joints in [chain_joints(5, |k| 2 + k % 5), loop_joints(), tree_joints()] {
            let nb = joints
                .iter()
                .flat_map(|j| [j.1, j.2])
                .flatten()
                .max()
                .unwrap()
                + 1;
            let p = random_problem(&mut rng, nb, &joints, 0.25);
            check_against_dense(&p);
            let mut rigid = p.clone();
            rigid.comp.iter_mut().for_each(|c| *c = 0.0);
            let (_, _, x0, l0) = rigid.sparse_solve();
            let reference = (x0, l0);
            let mut last = Real::INFINITY;
            for e in [2, 4, 6] {
                let ten: Real = 10.0;
                let s = ten.powi(-e);
                let mut q = p.clone();
                q.comp.iter_mut().for_each(|c| *c *= s);
                let (_, _, x, l) = q.sparse_solve();
                let err = rel_diff(&(x, l), &reference);
                // The solution is smooth in C, so err = K |C| + rounding. Measured K is 0.6 (chain),
                // 1.3 (tree) and 140 (loop, whose rigid system is the worst conditioned), so
                // 1e3 * s bounds it with margin, and each 100x smaller C must cut the error by at
                // least 10x (it is cut by 100x in f64) until the rounding floor is reached.
                assert!(err < 1.0e3 * s + rel_tol(), "s = {s}: {err}");
                assert!(
                    err < 0.1 * last || err < rel_tol(),
                    "s = {s}: {err} vs {last}"
                );
                last = err;
            }
        }
    }

    #[test]
    fn duplicate_joint_rows_are_dropped() {
        let mut rng = Lcg(3);
        let single = random_problem(
            &mut rng,
            2,
            &[(3, None, Some(0)), (5, Some(0), Some(1))],
            0.0,
        );
        // Duplicate joint 1 (same Jacobian, same consistent g).
        let mut dup = single.clone();
        dup.specs.push(single.specs[1]);
        dup.jac.extend_from_slice(&single.jac[JAC_ROW_STRIDE * 3..]);
        dup.g.extend_from_slice(&single.g[3..]);
        dup.comp.extend_from_slice(&single.comp[3..]);
        let (s, rep, x, l) = dup.sparse_solve();
        assert_eq!(rep.redundant_rows, 5);
        assert_eq!(s.dropped_rows().len(), 5);
        assert!(x.iter().flatten().chain(&l).all(|v| v.is_finite()));
        // Both equations (incl. J x = g) hold to rounding: measured residuals ~1e-15 in f64.
        let (eb, ej) = dup.residual(&x, &l);
        assert!(eb < rel_tol() && ej < rel_tol(), "{eb} {ej}");
        let (xs, ls) = single.dense_solve();
        let merged: Vec<Real> = (0..3)
            .map(|r| l[r])
            .chain((3..8).map(|r| l[r] + l[r + 5]))
            .collect();
        assert!(rel_diff(&(x, merged), &(xs, ls)) < rel_tol());
    }

    /// Revolute rows at world point `p` about `z` between bodies centred at `ca` and `cb`
    /// (`cb = None`: ground); returns the 5 rows of 12 reals.
    fn revolute_z(p: [Real; 3], ca: [Real; 3], cb: Option<[Real; 3]>) -> Vec<Real> {
        let cross = |a: [Real; 3], b: [Real; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let mut out = Vec::new();
        let e = |i: usize| std::array::from_fn::<Real, 3, _>(|j| if i == j { 1.0 } else { 0.0 });
        for i in 0..5 {
            for (slot, c) in [Some(ca), cb].into_iter().enumerate() {
                let sign = if slot == 0 { 1.0 } else { -1.0 };
                match c {
                    None => out.extend([0.0; 6]),
                    Some(c) if i < 3 => {
                        let r = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
                        let rc = cross(r, e(i));
                        out.extend(e(i).iter().chain(&rc).map(|v| sign * v));
                    }
                    Some(_) => {
                        let mut row = [0.0; 6];
                        row[i] = sign; // angular x (i = 3) or y (i = 4)
                        out.extend(row);
                    }
                }
            }
        }
        out
    }

    #[test]
    fn planar_four_bar_of_3d_revolutes_has_three_redundant_rows() {
        let mut rng = Lcg(4);
        let (g1, p1, p2, g2) = (
            [0.0, 0.0, 0.0],
            [1.0, 2.0, 0.0],
            [3.5, 2.5, 0.0],
            [4.0, 0.0, 0.0],
        );
        let mid = |a: [Real; 3], b: [Real; 3]| std::array::from_fn(|i| 0.5 * (a[i] + b[i]));
        let (c0, c1, c2) = (mid(g1, p1), mid(p1, p2), mid(p2, g2));
        let mut p = random_problem(
            &mut rng,
            3,
            &[
                (5, Some(0), None),
                (5, Some(0), Some(1)),
                (5, Some(1), Some(2)),
                (5, Some(2), None),
            ],
            0.0,
        );
        p.jac = [
            revolute_z(g1, c0, None),
            revolute_z(p1, c0, Some(c1)),
            revolute_z(p2, c1, Some(c2)),
            revolute_z(g2, c2, None),
        ]
        .concat();
        // Consistent g = J x0.
        let x0: Vec<[Real; 6]> = (0..3)
            .map(|_| std::array::from_fn(|_| rng.next()))
            .collect();
        p.g = vec![0.0; 20];
        for (_, r, slot, b) in p.slots() {
            let row = &p.jac[JAC_ROW_STRIDE * r + 6 * slot..][..6];
            p.g[r] += row.iter().zip(&x0[b]).map(|(a, v)| a * v).sum::<Real>();
        }
        let (_, rep, x, l) = p.sparse_solve();
        // 20 rows, 18 DOFs, mobility 1: rank 17.
        assert_eq!(rep.redundant_rows, 3);
        let (eb, ej) = p.residual(&x, &l);
        assert!(eb < rel_tol() && ej < rel_tol(), "{eb} {ej}");
    }

    #[test]
    fn one_sided_dependent_rows_are_an_error_not_a_wrong_answer() {
        let mut rng = Lcg(5);
        let mut p = random_problem(
            &mut rng,
            2,
            &[(6, None, Some(0)), (2, Some(1), Some(0))],
            0.0,
        );
        // Row 1 of joint 1 does not act on body 1 (the leaf eliminated first).
        let r = 6 + 1;
        p.jac[JAC_ROW_STRIDE * r..JAC_ROW_STRIDE * r + 6].fill(0.0);
        let mut s = KktSolver::new(2, &p.specs).unwrap();
        assert_eq!(
            s.factor(&p.mass, &p.jac, &p.comp),
            Err(KktError::OneSidedRows { joint: 1 })
        );
    }

    #[test]
    fn fill_is_linear_for_long_chains_and_stars() {
        let mut rng = Lcg(6);
        let chain = random_problem(&mut rng, 1000, &chain_joints(1000, |_| 5), 0.0);
        let (s, rep, x, l) = chain.sparse_solve();
        assert!(s.stored_offdiag_blocks() <= 3 * (1000 + 1000));
        assert_eq!(s.fill_blocks(), 0);
        assert_eq!(rep.redundant_rows, 0);
        let (eb, ej) = chain.residual(&x, &l);
        // Residuals relative to the largest term: measured 5e-13 (bodies) and 1e-15 (rows) in
        // f64 for this 1000-body chain (the backward error grows mildly with the length).
        assert!(eb < rel_tol() && ej < rel_tol(), "{eb} {ej}");

        let star: Vec<_> = (0..50).map(|k| (4, Some(0), Some(k + 1))).collect();
        let star = random_problem(&mut rng, 51, &star, 0.0);
        let (s, _, x, l) = star.sparse_solve();
        assert!(s.stored_offdiag_blocks() <= 3 * (51 + 50));
        assert_eq!(s.fill_blocks(), 0);
        let (eb, ej) = star.residual(&x, &l);
        assert!(eb < rel_tol() && ej < rel_tol(), "{eb} {ej}");
    }

    #[test]
    fn non_finite_input_is_an_error() {
        let mut rng = Lcg(7);
        let p = random_problem(&mut rng, 3, &loop_joints(), 0.0);
        let mut s = KktSolver::new(3, &p.specs).unwrap();
        let mut mass = p.mass.clone();
        mass[1][7] = Real::NAN;
        assert_eq!(
            s.factor(&mass, &p.jac, &p.comp),
            Err(KktError::NonFinite {
                at: KktNode::Body(1)
            })
        );
        let mut jac = p.jac.clone();
        jac[JAC_ROW_STRIDE * 6 + 7] = Real::INFINITY; // joint 1, row 1, slot 1
        assert_eq!(
            s.factor(&p.mass, &jac, &p.comp),
            Err(KktError::NonFinite {
                at: KktNode::Joint(1)
            })
        );
        let mut comp = p.comp.clone();
        comp[16] = Real::NAN;
        assert_eq!(
            s.factor(&p.mass, &p.jac, &comp),
            Err(KktError::NonFinite {
                at: KktNode::Joint(3)
            })
        );
        comp[16] = -1.0;
        assert_eq!(
            s.factor(&p.mass, &p.jac, &comp),
            Err(KktError::NegativeCompliance { joint: 3 })
        );
        let mut x = p.f.clone();
        let mut l = p.g.clone();
        assert_eq!(s.solve(&mut x, &mut l), Err(KktError::NotFactored));
        // Huge finite input overflows: an error, not a panic.
        let mut mass = p.mass.clone();
        mass[0] = [Real::MAX; 36];
        assert!(s.factor(&mass, &p.jac, &p.comp).is_err());
        // An indefinite mass.
        let mut mass = p.mass.clone();
        mass[2] = [0.0; 36];
        assert_eq!(
            s.factor(&mass, &p.jac, &p.comp),
            Err(KktError::NotPositiveDefinite { body: 2 })
        );
        // NaN in the right-hand side propagates.
        s.factor(&p.mass, &p.jac, &p.comp).unwrap();
        x[0][0] = Real::NAN;
        s.solve(&mut x, &mut l).unwrap();
        assert!(x.iter().flatten().any(|v| v.is_nan()));
        assert_eq!(
            KktSolver::new(
                2,
                &[JointBlockSpec {
                    rows: 3,
                    bodies: [Some(2), None]
                }]
            )
            .err(),
            Some(KktError::InvalidJoint { joint: 0 })
        );
    }

    #[test]
    #[ignore = "timing, run with --ignored --nocapture"]
    fn kkt_chain_timing() {
        // Best of 20 short batches, so that other processes on the machine do not inflate it.
        fn best_us(reps: usize, mut f: impl FnMut()) -> f64 {
            (0..20)
                .map(|_| {
                    let t = std::time::Instant::now();
                    for _ in 0..reps {
                        f();
                    }
                    t.elapsed().as_secs_f64() * 1e6 / reps as f64
                })
                .fold(f64::INFINITY, f64::min)
        }
        let mut rng = Lcg(8);
        for n in [10, 100, 1000] {
            let p = random_problem(&mut rng, n, &chain_joints(n, |_| 5), 0.0);
            let mut s = KktSolver::new(n, &p.specs).unwrap();
            let (mut x, mut l) = (p.f.clone(), p.g.clone());
            let reps = 20_000 / n;
            let us = best_us(reps, || {
                s.factor(&p.mass, &p.jac, &p.comp).unwrap();
                x.copy_from_slice(&p.f);
                l.copy_from_slice(&p.g);
                s.solve(&mut x, &mut l).unwrap();
            });
            let us_solve = best_us(reps, || {
                x.copy_from_slice(&p.f);
                l.copy_from_slice(&p.g);
                s.solve(&mut x, &mut l).unwrap();
            });
            println!(
                "chain {n:5} joints ({:5} rows): factor+solve {us:9.2} us ({:.3} us/row), solve alone {us_solve:8.2} us",
                5 * n,
                us / (5 * n) as f64
            );
        }
    }
}
