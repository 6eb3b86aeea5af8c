//! Block-sparse LDLᵀ factorisation of the quasi-definite KKT system of jointed rigid bodies.
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
//! factored by a dense LDLᵀ with symmetric diagonal pivoting, largest scaled `|d|` first (each row
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

/// Block-sparse LDLᵀ solver for the KKT system of jointed rigid bodies.
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
            let mut pinv = [0.0; MAX_DIM * MAX_DIM];
            pinv[..n * n].copy_from_slice(&self.diag[pv.diag_off..pv.diag_off + n * n]);
            let pinv = &pinv[..n * n];
            let base = self.blocks[pv.blk_start].off;
            // T_j = W_j P⁺ (P⁺ is symmetric, so this is W_j P⁺ᵀ).
            for blk in &self.blocks[pv.blk_start..pv.blk_end] {
                let len = blk.rows * n;
                let w = &self.offd[blk.off..blk.off + len];
                let t = &mut self.tmp[blk.off - base..blk.off - base + len];
                for (trow, wrow) in t.chunks_exact_mut(n).zip(w.chunks_exact(n)) {
                    for (tv, prow) in trow.iter_mut().zip(pinv.chunks_exact(n)) {
                        *tv = dot(wrow, prow);
                    }
                }
            }
            // Diagonal updates D_j -= T_j W_jᵀ, with the reference scales.
            for blk in &self.blocks[pv.blk_start..pv.blk_end] {
                let tgt = self.pivots[blk.tgt];
                let (m, len) = (blk.rows, blk.rows * n);
                let w = &self.offd[blk.off..blk.off + len];
                let t = &self.tmp[blk.off - base..blk.off - base + len];
                sub_mul_nt(
                    &mut self.diag[tgt.diag_off..tgt.diag_off + m * m],
                    t,
                    w,
                    n,
                );
                let s = &mut self.scale[tgt.scale_off..tgt.scale_off + m];
                for ((sv, trow), wrow) in s.iter_mut().zip(t.chunks_exact(n)).zip(w.chunks_exact(n))
                {
                    *sv += dot(trow, wrow).abs();
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
        self.factored = true;
        Ok(FactorReport {
            redundant_rows: self.dropped.len(),
        })
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
                let wmax = w.iter().fold(0.0 as Real, |a, &x| a.max(x.abs()));
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
            let n = pv.dim;
            let pinv = &self.diag[pv.diag_off..pv.diag_off + n * n];
            let mut u = [0.0; MAX_DIM];
            let z = seg(pv.rhs, n, bodies, rhs_joints);
            for (ui, prow) in u[..n].iter_mut().zip(pinv.chunks_exact(n)) {
                *ui = dot(prow, z);
            }
            for blk in &self.blocks[pv.blk_start..pv.blk_end] {
                let w = &self.offd[blk.off..blk.off + blk.rows * n];
                let r = seg(blk.rhs, blk.rows, bodies, rhs_joints);
                for (ri, wrow) in r.iter_mut().zip(w.chunks_exact(n)) {
                    *ri -= dot(wrow, &u[..n]);
                }
            }
        }
        // Backward: x_p = P⁺ (z_p - Σ W_jᵀ x_j).
        for pv in self.pivots.iter().rev() {
            let n = pv.dim;
            let pinv = &self.diag[pv.diag_off..pv.diag_off + n * n];
            let mut t = [0.0; MAX_DIM];
            t[..n].copy_from_slice(seg(pv.rhs, n, bodies, rhs_joints));
            for blk in &self.blocks[pv.blk_start..pv.blk_end] {
                let w = &self.offd[blk.off..blk.off + blk.rows * n];
                let x = seg(blk.rhs, blk.rows, bodies, rhs_joints);
                for (wrow, &xa) in w.chunks_exact(n).zip(x.iter()) {
                    for (tc, &wc) in t[..n].iter_mut().zip(wrow) {
                        *tc -= wc * xa;
                    }
                }
            }
            let out = seg(pv.rhs, n, bodies, rhs_joints);
            for (o, prow) in out.iter_mut().zip(pinv.chunks_exact(n)) {
                *o = dot(prow, &t[..n]);
            }
        }
        Ok(())
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
fn seg<'a>(loc: RhsLoc, len: usize, bodies: &'a mut [Real], joints: &'a mut [Real]) -> &'a mut [Real] {
    if loc.joint {
        &mut joints[loc.off..loc.off + len]
    } else {
        &mut bodies[loc.off..loc.off + len]
    }
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

/// Scratch of the dense pivoted LDLᵀ of one pivot block.
struct PivotWork {
    /// Unit lower `L` (strictly below the diagonal) and `D` (diagonal), permuted order.
    w: [Real; MAX_DIM * MAX_DIM],
    /// `L11⁻¹` of the kept part.
    x: [Real; MAX_DIM * MAX_DIM],
    /// `perm[i]` is the original index of permuted row `i`.
    perm: [usize; MAX_DIM],
}

impl Default for PivotWork {
    fn default() -> Self {
        Self {
            w: [0.0; MAX_DIM * MAX_DIM],
            x: [0.0; MAX_DIM * MAX_DIM],
            perm: [0; MAX_DIM],
        }
    }
}

impl PivotWork {
    /// Factors the symmetric `n×n` block `a` by LDLᵀ with diagonal pivoting (largest
    /// `|d_i| / s_i` first, first index on ties) and overwrites it with the pseudo-inverse that
    /// drops the rows whose scaled pivot is `<= thresh`. Returns the rank.
    fn factor(
        &mut self,
        a: &mut [Real],
        scale: &[Real],
        n: usize,
        thresh: Real,
        body: bool,
    ) -> Result<usize, PivotFail> {
        let w = &mut self.w;
        let mut s = [0.0; MAX_DIM];
        for i in 0..n {
            self.perm[i] = i;
            s[i] = scale[i];
            for j in 0..n {
                w[i * n + j] = 0.5 * (a[i * n + j] + a[j * n + i]);
            }
        }
        let mut rank = n;
        for k in 0..n {
            let mut best = k;
            let mut best_ratio = -1.0;
            for i in k..n {
                let d = w[i * n + i];
                if !d.is_finite() {
                    return Err(PivotFail::NonFinite);
                }
                let r = if s[i] > 0.0 { d.abs() / s[i] } else { 0.0 };
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
                for j in 0..n {
                    w.swap(k * n + j, best * n + j);
                }
                for i in 0..n {
                    w.swap(i * n + k, i * n + best);
                }
                self.perm.swap(k, best);
                s.swap(k, best);
            }
            let d = w[k * n + k];
            if body && d <= 0.0 {
                return Err(PivotFail::NotPositive);
            }
            for i in k + 1..n {
                w[i * n + k] /= d;
            }
            for i in k + 1..n {
                let lid = w[i * n + k] * d;
                for j in k + 1..=i {
                    let v = w[i * n + j] - lid * w[j * n + k];
                    w[i * n + j] = v;
                    w[j * n + i] = v;
                }
            }
        }
        if body && rank < n {
            return Err(PivotFail::NotPositive);
        }
        // X = L11⁻¹ (unit lower), then P⁺ = Πᵀ (Xᵀ D⁻¹ X ⊕ 0) Π.
        let x = &mut self.x;
        for i in 0..rank {
            x[i * n + i] = 1.0;
            for j in 0..i {
                let mut acc = 0.0;
                for k in j..i {
                    acc -= w[i * n + k] * x[k * n + j];
                }
                x[i * n + j] = acc;
            }
        }
        a[..n * n].fill(0.0);
        for p in 0..rank {
            for q in 0..=p {
                let mut v = 0.0;
                for i in p..rank {
                    v += x[i * n + p] * x[i * n + q] / w[i * n + i];
                }
                let (pp, pq) = (self.perm[p], self.perm[q]);
                a[pp * n + pq] = v;
                a[pq * n + pp] = v;
            }
        }
        if a[..n * n].iter().any(|v| !v.is_finite()) {
            return Err(PivotFail::NonFinite);
        }
        Ok(rank)
    }

    /// Null vector (original row order) of the factored block for the dropped permuted row `q`:
    /// `y = [-L11⁻ᵀ l; e_q]` with `l` the kept part of row `q` of `L`.
    fn null_vector(&self, n: usize, rank: usize, q: usize) -> [Real; MAX_DIM] {
        let mut y = [0.0; MAX_DIM];
        y[q] = 1.0;
        for a in 0..rank {
            let mut acc = 0.0;
            for i in a..rank {
                acc += self.x[i * n + a] * self.w[q * n + i];
            }
            y[a] = -acc;
        }
        let mut v = [0.0; MAX_DIM];
        for (i, &yi) in y[..n].iter().enumerate() {
            v[self.perm[i]] = yi;
        }
        v
    }
}
