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
//! Body pivots are symmetric positive definite and are factored by the unpivoted `LDLᵀ` (backward
//! stable there; a scaled pivot at or below `64 eps` is
//! [`KktError::NotPositiveDefinite`]). Joint pivots are negative semidefinite and are
//! factored by a dense `LDLᵀ` with symmetric diagonal pivoting, largest scaled `|d|` first (each row
//! is scaled by the accumulated magnitude of its diagonal, see below). A joint pivot is tried
//! without pivoting first, which stands when the product of its scaled pivots is above twice
//! the tolerance below: the pivoted factorisation would then drop no row (the proof is at
//! `PivotWork::factor`), and only round-off differs. A pivot with
//! `|d| <= tol * s`, where `s` is the sum of the absolute values of everything that was added to
//! that diagonal entry (its compliance and every Schur update), marks the row as *redundant*: the
//! row is dropped from the system and its multiplier is zero. Since the pivot is the largest
//! remaining one, all remaining rows of the block are then dropped too. The default `tol` is
//! `2 Real::EPSILON^(2/3)` (about `7e-11` in `f64`, `5e-5` in `f32`), see
//! [`KktSolver::default_redundancy_tolerance`].
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
//!
//! # Four systems at once
//!
//! The numeric kernels (assembly, the unpivoted block steps, the Schur updates, the inversion
//! of each pivot) are generic over [`Lane`](crate::solver::lane::Lane): one system in
//! [`Real`], or four systems of the same structure in the four lanes of a SIMD register
//! (`lanes`, `KktSolver::factor_lanes`), each lane running the scalar operations in the
//! same order. A solver's structure ([`KktSolver::new`]'s pivots, blocks, Schur updates and
//! assembly) is kept apart from its values for that.

use std::collections::{BTreeSet, HashMap};

use crate::math::Real;
use crate::solver::lane::Lane;

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

/// Number of pivots assembled ahead of their elimination (see [`KktSolver::factor`]).
const ASSEMBLY_CHUNK: usize = 64;

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

/// Runs `$body` with the constant `$M` equal to the runtime block height `$m` when it is at most
/// [`BODY_DOFS`] (the common sizes, so that the block kernels are unrolled), else `$dyn`.
macro_rules! by_rows {
    ($m:expr, $M:ident => $body:expr, $dyn:expr) => {
        match $m {
            1 => {
                const $M: usize = 1;
                $body
            }
            2 => {
                const $M: usize = 2;
                $body
            }
            3 => {
                const $M: usize = 3;
                $body
            }
            4 => {
                const $M: usize = 4;
                $body
            }
            5 => {
                const $M: usize = 5;
                $body
            }
            6 => {
                const $M: usize = 6;
                $body
            }
            _ => $dyn,
        }
    };
}

/// One arm of [`by_pair`]: `$body` with the constants of entry `$k` of [`PAIRS`], then `true`.
macro_rules! pair_arm {
    ($k:literal, $N:ident, $M:ident, $B:ident => $body:expr) => {{
        const $N: usize = PAIRS[$k].0;
        const $M: usize = PAIRS[$k].1;
        const $B: bool = PAIRS[$k].2;
        $body;
        true
    }};
}

/// Runs `$body` with the constants `$N` (the pivot's dimension), `$M` (the rows of its one
/// off-diagonal block) and, in the second form, `$B` (the pivot is a body and its block's
/// node a joint; else the reverse) for the pairs of a tree's body and joint pivots (a body of
/// 6 with its parent joint of 3 to 6 rows, such a joint with its parent body:
/// [`Pivot::pair`]), and evaluates to `true`; to `false` (nothing run) for a pivot with no
/// block, several, or another pair. One jump on a code stored with the pivot: a match on the
/// two sizes read at each pivot compiled to a chain of comparisons (1.6 % of the 100-link
/// chain's step), and with `$B` the solve picks its two segments without a branch on where
/// each lives (1.4 % more).
macro_rules! by_pair {
    ($pv:expr, $N:ident, $M:ident => $body:expr) => {
        by_pair!($pv, $N, $M, _B => $body)
    };
    ($pv:expr, $N:ident, $M:ident, $B:ident => $body:expr) => {{
        match $pv.pair {
            1 => pair_arm!(0, $N, $M, $B => $body),
            2 => pair_arm!(1, $N, $M, $B => $body),
            3 => pair_arm!(2, $N, $M, $B => $body),
            4 => pair_arm!(3, $N, $M, $B => $body),
            5 => pair_arm!(4, $N, $M, $B => $body),
            6 => pair_arm!(5, $N, $M, $B => $body),
            7 => pair_arm!(6, $N, $M, $B => $body),
            8 => pair_arm!(7, $N, $M, $B => $body),
            _ => false,
        }
    }};
}

/// The (pivot dimension, block rows, the pivot is a body) triples [`by_pair`] runs with their
/// own kernels: a body with its parent joint of 5, 3, 4 or 6 rows, and such a joint with its
/// parent body. Code `k + 1` is entry `k`.
const PAIRS: [(usize, usize, bool); 8] = [
    (6, 5, true),
    (5, 6, false),
    (6, 3, true),
    (3, 6, false),
    (6, 4, true),
    (4, 6, false),
    (6, 6, true),
    (6, 6, false),
];

/// The code [`by_pair`] reads for a pivot of dimension `n` (a body: `body`) whose one
/// off-diagonal block has `m` rows and couples it to a node of the other kind (0: another
/// pair, run by the general steps).
fn pair_code(n: usize, m: usize, body: bool) -> u8 {
    PAIRS
        .iter()
        .position(|&p| p == (n, m, body))
        .map_or(0, |k| k as u8 + 1)
}

// After the macros above, which it uses.
mod lanes;
pub(crate) use lanes::KktLanes;

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
    /// Offset of the diagonal block, packed lower triangle (`tri(dim)` reals, see [`tri`]);
    /// after factorisation it holds `X = L⁻¹` and `D⁺` (see [`Packed`]).
    diag_off: usize,
    /// Offset of the `dim` diagonal reference scales (`D⁺` after factorisation).
    scale_off: usize,
    rhs: RhsLoc,
    /// Range of this pivot's off-diagonal blocks in `blocks`.
    blk_start: usize,
    blk_end: usize,
    /// The sizes of a pivot with one off-diagonal block, see [`pair_code`].
    pair: u8,
    /// Range of this pivot's pair updates in `ops`.
    op_start: usize,
    op_end: usize,
}

/// Off-diagonal block between a pivot `p` and a later node `j`: `dim(p) × dim(j)`, row-major
/// (the transpose `Wᵀ` of the coupling `W` of `j`'s rows with `p`'s).
#[derive(Clone, Copy, Debug)]
struct Block {
    off: usize,
    /// `dim(j)` (the number of columns; `W` has that many rows).
    rows: usize,
    /// Pivot index of `j`.
    tgt: usize,
    /// Whether `j` is a body.
    tgt_body: bool,
    /// Right-hand side of `j`.
    rhs: RhsLoc,
}

/// Schur update of pivot `p` on the block between two of its later neighbours `j` (earlier) and
/// `k` (later): `A_jk -= W_j P⁺ W_kᵀ`.
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
    /// Index of the block.
    blk: usize,
    /// Stored as `6 × m` (body eliminated before the joint) rather than `m × 6`.
    transposed: bool,
    /// Adds to the block (another slot of the same joint wrote it first) instead of
    /// overwriting it.
    add: bool,
}

/// One piece of the numeric assembly.
#[derive(Clone, Copy, Debug)]
enum Assembly {
    /// The diagonal block and scales of a pivot (by index).
    Diag(usize),
    /// A Jacobian slot of a joint into its block.
    Jac { joint: usize, slot: usize },
    /// A fill block to clear: `(offset, length)` in `offd`.
    Zero(usize, usize),
}

/// Why a pivot block could not be factored.
enum PivotFail {
    NonFinite,
    NotPositive,
}

/// The values of a factorisation, over one system ([`Real`]) or four ([`crate::solver::lane::Lanes`],
/// see [`KktLanes`]), at the offsets of the structure's [`Pivot`]s and [`Block`]s.
#[derive(Clone, Debug)]
struct Numeric<T> {
    /// Per pivot its diagonal block (packed lower triangle), `X = L⁻¹` and `D⁺` once factored
    /// (see [`Packed`]).
    diag: Vec<T>,
    /// Per pivot its reference scales, `D⁺` once factored.
    scale: Vec<T>,
    /// Off-diagonal blocks `Wᵀ`, replaced by `Y = L⁻¹ Π Wᵀ` when their pivot is factored.
    offd: Vec<T>,
}

/// The structure of a [`KktSolver`] (what [`KktSolver::new`] computes from the bodies and the
/// joint blocks), apart from its values, so that the same kernels fill the solver's own
/// [`Numeric`] or a group's lanes.
#[derive(Clone, Debug)]
struct Shape {
    specs: Vec<JointBlockSpec>,
    row_off: Vec<usize>,
    pivots: Vec<Pivot>,
    blocks: Vec<Block>,
    ops: Vec<PairOp>,
    jac_targets: Vec<[Option<JacTarget>; 2]>,
    /// Assembly work, bucketed by the first pivot that needs it (its own diagonal block, or the
    /// first Schur update into a block): the items of pivot `t` are
    /// `asm[asm_start[t]..asm_start[t + 1]]`. [`KktSolver::factor`] assembles by chunks of
    /// pivots just ahead of their elimination, so that the data is still in cache.
    asm: Vec<Assembly>,
    asm_start: Vec<usize>,
}

/// Where the assembly reads its inputs: one system's ([`FactorInputs`], [`Real`]) or four
/// systems' (one per lane).
trait Inputs<T: Lane> {
    /// Body `b`'s mass block: entry `k` (row-major).
    fn mass(&self, b: usize) -> impl Fn(usize) -> T + '_;
    /// `M` rows of one body slot of the Jacobian arena from entry `base` on (stride
    /// [`JAC_ROW_STRIDE`]).
    fn jac_rows<const M: usize>(&self, base: usize) -> [[T; BODY_DOFS]; M];
    /// The Jacobian arena from entry `base` on: entry `base + i`.
    fn jac(&self, base: usize) -> impl Fn(usize) -> T + '_;
    /// The compliances of the `N` global rows from `r0` on.
    fn compliance<const N: usize>(&self, r0: usize) -> [T; N];
}

/// One system's inputs to [`KktSolver::factor`] (see there).
#[derive(Clone, Copy)]
pub(crate) struct FactorInputs<'a> {
    /// Per body its 6×6 mass block, row-major.
    pub(crate) mass: &'a [[Real; 36]],
    /// The Jacobian arena.
    pub(crate) jac: &'a [Real],
    /// One compliance per global row.
    pub(crate) compliance: &'a [Real],
}

impl Inputs<Real> for FactorInputs<'_> {
    #[inline(always)]
    fn mass(&self, b: usize) -> impl Fn(usize) -> Real + '_ {
        let m = &self.mass[b];
        move |k| m[k]
    }
    #[inline(always)]
    fn jac_rows<const M: usize>(&self, base: usize) -> [[Real; BODY_DOFS]; M] {
        let src = &self.jac[base..];
        let mut rows = [[0.0; BODY_DOFS]; M];
        for (i, row) in rows.iter_mut().enumerate() {
            row.copy_from_slice(&src[JAC_ROW_STRIDE * i..JAC_ROW_STRIDE * i + BODY_DOFS]);
        }
        rows
    }
    #[inline(always)]
    fn jac(&self, base: usize) -> impl Fn(usize) -> Real + '_ {
        let j = &self.jac[base..];
        move |i| j[i]
    }
    #[inline(always)]
    fn compliance<const N: usize>(&self, r0: usize) -> [Real; N] {
        let mut c = [0.0; N];
        c.copy_from_slice(&self.compliance[r0..r0 + N]);
        c
    }
}

/// Block-sparse `LDLᵀ` solver for the KKT system of jointed rigid bodies.
///
/// Create it with [`KktSolver::new`] when the topology changes, then call
/// [`KktSolver::factor`] once per new set of values and [`KktSolver::solve`] once per
/// right-hand side.
#[derive(Clone, Debug)]
pub struct KktSolver {
    nb: usize,
    shape: Shape,
    num: Numeric<Real>,
    /// Permutation of each pivot's `LDLᵀ` (at the pivot's `scale_off`).
    perms: Vec<u8>,
    dropped: Vec<DroppedRow>,
    tol: Real,
    /// Whether the last factorisation pivoted a joint block (every permutation is the
    /// identity otherwise, and [`Self::solve`] skips reading them).
    pivoted: bool,
    factored: bool,
    /// This solver's and its factorisation's stamp: a number no other solver of the process
    /// was built with (never 0), and the count of its successful factorisations. [`KktLanes`]
    /// recognises the factors it holds by it. (A process-wide count of factorisations would
    /// be one atomic cache line written by every island on every thread.)
    stamp: Stamp,
}

/// See [`KktSolver`]'s `stamp`.
type Stamp = (u64, u64);

/// A number for the next [`KktSolver`] built (never 0).
fn next_solver_id() -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static IDS: AtomicU64 = AtomicU64::new(1);
    IDS.fetch_add(1, Ordering::Relaxed)
}

/// The elimination game of [`KktSolver::new`] on the graph whose nodes are the bodies and the
/// joints with rows and whose edges are the joint–body incidences: the order (nodes, bodies
/// `0..nb` then joints `nb + k`) and each eliminated node's neighbours at its elimination.
struct Game {
    order: Vec<usize>,
    nbr_lists: Vec<Vec<usize>>,
}

impl Game {
    /// Plays the game: the eligible node of least degree first (a joint is eligible once it
    /// has no body left or a body that was a leaf hung from it, see the module docs).
    fn play(nb: usize, joints: &[JointBlockSpec]) -> Game {
        let nj = joints.len();
        let n_nodes = nb + nj;
        let active = |v: usize| v < nb || joints[v - nb].rows > 0;
        let mut adj: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); n_nodes];
        for (k, s) in joints.iter().enumerate() {
            if s.rows == 0 {
                continue;
            }
            for &b in s.bodies.iter().flatten() {
                if adj[nb + k].insert(b) {
                    adj[b].insert(nb + k);
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
        Game { order, nbr_lists }
    }
}

/// The numbering and storage that follow from the elimination order.
struct Layout {
    pivots: Vec<Pivot>,
    blocks: Vec<Block>,
    /// (eliminated node, neighbour) -> its off-diagonal block.
    edge: HashMap<(usize, usize), usize>,
    /// Each node's position in the order (`usize::MAX` for joints without rows).
    pos: Vec<usize>,
    /// Each pivot's neighbours at its elimination, by elimination position.
    nbrs: Vec<Vec<usize>>,
    diag_len: usize,
    scale_len: usize,
    offd_len: usize,
}

impl Layout {
    /// Pivots and off-diagonal blocks, each neighbour list sorted by elimination position.
    fn new(nb: usize, joints: &[JointBlockSpec], row_off: &[usize], game: &Game) -> Layout {
        let dim = |v: usize| {
            if v < nb {
                BODY_DOFS
            } else {
                joints[v - nb].rows
            }
        };
        let mut pos = vec![usize::MAX; nb + joints.len()];
        for (t, &v) in game.order.iter().enumerate() {
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
        let mut l = Layout {
            pivots: Vec::with_capacity(game.order.len()),
            blocks: Vec::new(),
            edge: HashMap::new(),
            pos: Vec::new(),
            nbrs: Vec::with_capacity(game.order.len()),
            diag_len: 0,
            scale_len: 0,
            offd_len: 0,
        };
        for (t, &v) in game.order.iter().enumerate() {
            let n = dim(v);
            let mut nbrs = game.nbr_lists[t].clone();
            nbrs.sort_unstable_by_key(|&j| pos[j]);
            let blk_start = l.blocks.len();
            for &j in &nbrs {
                l.edge.insert((v, j), l.blocks.len());
                l.blocks.push(Block {
                    off: l.offd_len,
                    rows: dim(j),
                    tgt: pos[j],
                    tgt_body: j < nb,
                    rhs: rhs_of(j),
                });
                l.offd_len += dim(j) * n;
            }
            l.pivots.push(Pivot {
                node: if v < nb {
                    KktNode::Body(v)
                } else {
                    KktNode::Joint(v - nb)
                },
                dim: n,
                diag_off: l.diag_len,
                scale_off: l.scale_len,
                rhs: rhs_of(v),
                blk_start,
                blk_end: l.blocks.len(),
                pair: match nbrs.as_slice() {
                    // A body with a joint, or a joint with a body (not a loop's joint-joint
                    // fill): the solve then knows which side each vector is on.
                    [j] if (v < nb) != (*j < nb) => pair_code(n, dim(*j), v < nb),
                    _ => 0,
                },
                op_start: 0,
                op_end: 0,
            });
            l.diag_len += tri(n);
            l.scale_len += n;
            l.nbrs.push(nbrs);
        }
        l.pos = pos;
        l
    }

    /// The Schur updates of each pivot: for every pair of its neighbours `j` before `k`, the
    /// block `(j, k)` gets `-Y_k^T Y_j`. Sets each pivot's range of them.
    fn pair_ops(&mut self, game: &Game) -> Vec<PairOp> {
        let mut ops = Vec::new();
        for (t, &v) in game.order.iter().enumerate() {
            let nbrs = &self.nbrs[t];
            let start = ops.len();
            for (a, &j) in nbrs.iter().enumerate() {
                for &k in &nbrs[a + 1..] {
                    ops.push(PairOp {
                        k_blk: self.edge[&(v, k)],
                        j_blk: self.edge[&(v, j)],
                        // `j` and `k` are adjacent from `v`'s elimination on and `j` goes first.
                        dst_blk: self.edge[&(j, k)],
                    });
                }
            }
            self.pivots[t].op_start = start;
            self.pivots[t].op_end = ops.len();
        }
        ops
    }

    /// Where each joint's Jacobian slots go (the block between the joint and its body, in the
    /// direction of elimination), and which blocks a Jacobian writes.
    fn jacobian_targets(
        &self,
        nb: usize,
        joints: &[JointBlockSpec],
    ) -> (Vec<[Option<JacTarget>; 2]>, Vec<bool>) {
        let mut jac_targets = vec![[None; 2]; joints.len()];
        let mut written = vec![false; self.blocks.len()];
        for (k, s) in joints.iter().enumerate() {
            if s.rows == 0 {
                continue;
            }
            let vj = nb + k;
            for (slot, body) in s.bodies.iter().enumerate() {
                if let Some(b) = *body {
                    let (first, second, transposed) = if self.pos[b] < self.pos[vj] {
                        (b, vj, true)
                    } else {
                        (vj, b, false)
                    };
                    let e = self.edge[&(first, second)];
                    let add = std::mem::replace(&mut written[e], true);
                    jac_targets[k][slot] = Some(JacTarget {
                        off: self.blocks[e].off,
                        blk: e,
                        transposed,
                        add,
                    });
                }
            }
        }
        (jac_targets, written)
    }

    /// Just-in-time assembly: a diagonal block before the first pivot that updates it (or its
    /// own), an off-diagonal block before its pivot or the first fill update into it. Returns
    /// the items bucketed by pivot and the buckets' starts.
    fn assembly(
        &self,
        ops: &[PairOp],
        jac_targets: &[[Option<JacTarget>; 2]],
        written: &[bool],
    ) -> (Vec<Assembly>, Vec<usize>) {
        let (pivots, blocks) = (&self.pivots, &self.blocks);
        let np = pivots.len();
        let mut first_blk = vec![usize::MAX; blocks.len()];
        let mut first_diag: Vec<usize> = (0..np).collect();
        for (t, pv) in pivots.iter().enumerate() {
            for (b, blk) in blocks
                .iter()
                .enumerate()
                .take(pv.blk_end)
                .skip(pv.blk_start)
            {
                first_blk[b] = first_blk[b].min(t);
                first_diag[blk.tgt] = first_diag[blk.tgt].min(t);
            }
            for op in &ops[pv.op_start..pv.op_end] {
                first_blk[op.dst_blk] = first_blk[op.dst_blk].min(t);
            }
        }
        let mut buckets: Vec<Vec<Assembly>> = vec![Vec::new(); np];
        for (t, &f) in first_diag.iter().enumerate() {
            buckets[f].push(Assembly::Diag(t));
        }
        for (k, targets) in jac_targets.iter().enumerate() {
            for (slot, t) in targets.iter().enumerate() {
                if let Some(t) = t {
                    buckets[first_blk[t.blk]].push(Assembly::Jac { joint: k, slot });
                }
            }
        }
        for pv in pivots {
            for (b, blk) in blocks
                .iter()
                .enumerate()
                .take(pv.blk_end)
                .skip(pv.blk_start)
            {
                if !written[b] {
                    buckets[first_blk[b]].push(Assembly::Zero(blk.off, blk.rows * pv.dim));
                }
            }
        }
        let mut asm_start = Vec::with_capacity(np + 1);
        let mut asm = Vec::new();
        for bucket in buckets {
            asm_start.push(asm.len());
            asm.extend(bucket);
        }
        asm_start.push(asm.len());
        (asm, asm_start)
    }
}

/// Inspection of the structure and of the last factorisation, for the tests.
#[cfg(test)]
impl KktSolver {
    /// Number of stored off-diagonal blocks (joint–body incidences plus fill).
    pub fn stored_offdiag_blocks(&self) -> usize {
        self.shape.blocks.len()
    }

    /// Number of fill blocks (stored off-diagonal blocks that are not joint–body incidences).
    pub fn fill_blocks(&self) -> usize {
        let incidences: usize = (self.shape.specs.iter())
            .filter(|s| s.rows > 0)
            .map(|s| match s.bodies {
                [Some(a), Some(b)] if a == b => 1,
                bodies => bodies.iter().flatten().count(),
            })
            .sum();
        self.shape.blocks.len() - incidences
    }

    /// The elimination order.
    pub fn elimination_order(&self) -> impl Iterator<Item = KktNode> + '_ {
        self.shape.pivots.iter().map(|p| p.node)
    }

    /// The rows dropped as redundant by the last factorisation.
    pub fn dropped_rows(&self) -> &[DroppedRow] {
        &self.dropped
    }
}

impl KktSolver {
    /// Symbolic phase: elimination order and fill pattern for `nb` bodies and the given joints.
    /// Call it only when the topology changes.
    ///
    /// # Errors
    /// [`KktError::InvalidJoint`] if a joint has more than [`MAX_JOINT_ROWS`] rows or a body index
    /// `>= nb`.
    pub fn new(nb: usize, joints: &[JointBlockSpec]) -> Result<Self, KktError> {
        for (k, s) in joints.iter().enumerate() {
            if s.rows > MAX_JOINT_ROWS || s.bodies.iter().flatten().any(|&b| b >= nb) {
                return Err(KktError::InvalidJoint { joint: k });
            }
        }
        let mut row_off = Vec::with_capacity(joints.len() + 1);
        let mut acc = 0;
        for s in joints {
            row_off.push(acc);
            acc += s.rows;
        }
        row_off.push(acc);
        let game = Game::play(nb, joints);
        let mut layout = Layout::new(nb, joints, &row_off, &game);
        let ops = layout.pair_ops(&game);
        let (jac_targets, written) = layout.jacobian_targets(nb, joints);
        let (asm, asm_start) = layout.assembly(&ops, &jac_targets, &written);
        Ok(Self {
            nb,
            shape: Shape {
                specs: joints.to_vec(),
                row_off,
                pivots: layout.pivots,
                blocks: layout.blocks,
                ops,
                jac_targets,
                asm,
                asm_start,
            },
            num: Numeric {
                diag: vec![0.0; layout.diag_len],
                scale: vec![0.0; layout.scale_len],
                offd: vec![0.0; layout.offd_len],
            },
            perms: vec![0; layout.scale_len],
            dropped: Vec::new(),
            tol: Self::default_redundancy_tolerance(),
            pivoted: false,
            factored: false,
            stamp: (next_solver_id(), 0),
        })
    }

    /// The default relative tolerance of the redundancy test, `2 Real::EPSILON^(2/3)`.
    pub fn default_redundancy_tolerance() -> Real {
        2.0 * Real::EPSILON.powf(2.0 / 3.0)
    }

    /// Number of bodies.
    pub fn num_bodies(&self) -> usize {
        self.nb
    }

    /// Total number of constraint rows.
    pub fn num_rows(&self) -> usize {
        self.shape.row_off[self.shape.specs.len()]
    }

    /// First global row of `joint` (its rows are `row_offset(joint) .. row_offset(joint + 1)`;
    /// `joint == joint_specs().len()` gives [`Self::num_rows`]).
    pub fn row_offset(&self, joint: usize) -> usize {
        self.shape.row_off[joint.min(self.shape.specs.len())]
    }

    /// The joint structure given to [`Self::new`].
    pub fn joint_specs(&self) -> &[JointBlockSpec] {
        &self.shape.specs
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
        self.pivoted = false;
        self.dropped.clear();
        let rows = self.num_rows();
        check_len("mass", self.nb, mass.len())?;
        check_len("jac", JAC_ROW_STRIDE * rows, jac.len())?;
        check_len("compliance", rows, compliance.len())?;
        // Assembly (see `asm`) with a fast test that everything read is finite (and the
        // compliances non-negative), and right-looking block elimination, by chunks of pivots:
        // the assembly of a chunk streams its inputs (many independent loads in flight), then
        // its elimination finds the data in cache. The input checks (in the documented order)
        // run only when the fast test fails, or before reporting an error of the factorisation:
        // input errors come first, as if they were checked before anything else.
        let inputs = FactorInputs {
            mass,
            jac,
            compliance,
        };
        let mut ok = true;
        let mut work = PivotWork::default();
        let np = self.shape.pivots.len();
        for c0 in (0..np).step_by(ASSEMBLY_CHUNK) {
            let c1 = (c0 + ASSEMBLY_CHUNK).min(np);
            let (shape, num, _) = self.split();
            for &item in &shape.asm[shape.asm_start[c0]..shape.asm_start[c1]] {
                ok &= assemble_item(shape, num, item, &inputs);
            }
            for pi in c0..c1 {
                let pv = self.shape.pivots[pi];
                let mut result = Ok(());
                // A tree's pivot with its one block (see `by_pair`), else any.
                if !by_pair!(pv, N, M => result = self.eliminate::<N, M>(pi, &mut work)) {
                    result = by_dim!(pv.dim, N => self.eliminate::<N, 0>(pi, &mut work));
                }
                if let Err(e) = result {
                    self.check_inputs(mass, jac, compliance)?;
                    return Err(e);
                }
            }
        }
        if !ok {
            self.check_inputs(mass, jac, compliance)?;
        }
        self.factored = true;
        self.stamp.1 += 1;
        Ok(FactorReport {
            redundant_rows: self.dropped.len(),
        })
    }

    /// The structure, the values and the permutations, borrowed apart.
    fn split(&mut self) -> (&Shape, &mut Numeric<Real>, &[u8]) {
        (&self.shape, &mut self.num, &self.perms)
    }

    /// The input checks of [`Self::factor`], in order: masses, then each joint's compliance and
    /// Jacobian. On an error the list of dropped rows is cleared (nothing was factored, as far
    /// as the caller can tell).
    fn check_inputs(
        &mut self,
        mass: &[[Real; 36]],
        jac: &[Real],
        compliance: &[Real],
    ) -> Result<(), KktError> {
        let r = self.first_input_error(mass, jac, compliance);
        if r.is_err() {
            self.dropped.clear();
        }
        r
    }

    /// The first input error, see [`Self::check_inputs`].
    fn first_input_error(
        &self,
        mass: &[[Real; 36]],
        jac: &[Real],
        compliance: &[Real],
    ) -> Result<(), KktError> {
        for (b, m) in mass.iter().enumerate() {
            if m.iter().any(|v| !v.is_finite()) {
                return Err(KktError::NonFinite {
                    at: KktNode::Body(b),
                });
            }
        }
        for (k, s) in self.shape.specs.iter().enumerate() {
            let (r0, r1) = (self.shape.row_off[k], self.shape.row_off[k + 1]);
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
        Ok(())
    }

    /// Factors pivot `pi` (dimension `N`), records its dropped rows and applies its Schur
    /// updates: with `M > 0` to its one off-diagonal block of `M` rows ([`schur_one`]), with
    /// `M = 0` to any blocks.
    fn eliminate<const N: usize, const M: usize>(
        &mut self,
        pi: usize,
        work: &mut PivotWork,
    ) -> Result<(), KktError> {
        let pv = self.shape.pivots[pi];
        let body = matches!(pv.node, KktNode::Body(_));
        let thresh = if body { 64.0 * Real::EPSILON } else { self.tol };
        let rank = match work.factor::<N>(
            &mut self.num.diag[pv.diag_off..pv.diag_off + tri(N)],
            &mut self.num.scale[pv.scale_off..pv.scale_off + N],
            &mut self.perms[pv.scale_off..pv.scale_off + N],
            thresh,
            body,
        ) {
            Ok(r) => r,
            Err(PivotFail::NonFinite) => return Err(KktError::Breakdown { at: pv.node }),
            Err(PivotFail::NotPositive) => {
                return Err(match pv.node {
                    KktNode::Body(b) => KktError::NotPositiveDefinite { body: b },
                    KktNode::Joint(_) => KktError::Breakdown { at: pv.node },
                });
            }
        };
        if let (KktNode::Joint(k), true) = (pv.node, rank < N) {
            self.check_dropped(work, &pv, rank, k)?;
            for q in rank..N {
                self.dropped.push(DroppedRow {
                    joint: k,
                    row: work.perm[q],
                });
            }
        }
        self.pivoted |= work.pivoted;
        let (shape, num, perms) = self.split();
        match (work.pivoted, M) {
            (false, 1..) => schur_one::<Real, N, M, false>(shape, num, perms, &pv),
            (true, 1..) => schur_one::<Real, N, M, true>(shape, num, perms, &pv),
            (false, 0) => schur_update::<Real, N, false>(shape, num, perms, &pv),
            (true, 0) => schur_update::<Real, N, true>(shape, num, perms, &pv),
        }
        // The solve uses `L⁻¹` (no dependency chain); nothing downstream in the factorisation
        // waits for it.
        invert_and_pack::<Real, N>(
            &mut num.diag[pv.diag_off..pv.diag_off + tri(N)],
            &num.scale[pv.scale_off..pv.scale_off + N],
        );
        Ok(())
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
            for blk in &self.shape.blocks[pv.blk_start..pv.blk_end] {
                if !blk.tgt_body {
                    continue;
                }
                // The stored block is `Wᵀ` (`n × m`): the rows of `W` are its columns.
                let m = blk.rows;
                let wt = &self.num.offd[blk.off..blk.off + m * n];
                let wmax = wt.iter().fold(0.0, |a: Real, &x| a.max(x.abs()));
                for c in 0..m {
                    let wv: Real = wt
                        .chunks_exact(m)
                        .zip(&v[..n])
                        .map(|(row, &vi)| row[c] * vi)
                        .sum();
                    if wv.abs() > loose * wmax * vnorm {
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
        // Forward: z_p final; u_p = D⁺ L⁻¹ Π z_p replaces it, and rhs_j -= Y_j u_p
        // (= W_j P⁺ z_p).
        if self.pivoted {
            substitute::<Real, true>(&self.shape, &self.num, &self.perms, bodies, rhs_joints);
        } else {
            substitute::<Real, false>(&self.shape, &self.num, &self.perms, bodies, rhs_joints);
        }
        Ok(())
    }
}

/// The forward and backward substitutions of [`KktSolver::solve`] on the factors `num` (one
/// system or four in lanes); `P`: some pivot block's permutation is not the identity.
///
/// A tree's pivots (a body with its parent joint, a joint with its parent body) have one
/// off-diagonal block each: those run [`forward_one`] and [`backward_one`], one dispatch on
/// both sizes and no loop over blocks, the same arithmetic as [`forward_step`] and
/// [`backward_step`]. Measured (callgrind, 1/60 s x 4, the same results to the bit): -1.8 %
/// instructions per step on the 100-link chain, -2.1 % on the 1000-link chain, -0.3 % on
/// the mixed scene of 100 arms (in lanes).
fn substitute<T: Lane, const P: bool>(
    shape: &Shape,
    num: &Numeric<T>,
    perms: &[u8],
    bodies: &mut [T],
    joints: &mut [T],
) {
    for pv in &shape.pivots {
        if !by_pair!(pv, N, M, B => forward_one::<T, N, M, P, B>(shape, num, perms, pv, bodies, joints))
        {
            by_dim!(pv.dim, N => forward_step::<T, N, P>(shape, num, perms, pv, bodies, joints));
        }
    }
    // Backward: x_p = P⁺ (z_p - Σ W_jᵀ x_j) = Πᵀ L⁻ᵀ (u_p - D⁺ Σ Y_jᵀ x_j).
    for pv in shape.pivots.iter().rev() {
        if !by_pair!(pv, N, M, B => backward_one::<T, N, M, P, B>(shape, num, perms, pv, bodies, joints))
        {
            by_dim!(pv.dim, N => backward_step::<T, N, P>(shape, num, perms, pv, bodies, joints));
        }
    }
}

/// [`forward_step`] of a pivot of dimension `N` with one off-diagonal block of `M` rows, to a
/// node of the other kind (`B`: the pivot is a body, its block's node a joint).
#[inline(always)]
fn forward_one<T: Lane, const N: usize, const M: usize, const P: bool, const B: bool>(
    shape: &Shape,
    num: &Numeric<T>,
    perms: &[u8],
    pv: &Pivot,
    bodies: &mut [T],
    joints: &mut [T],
) {
    let fac = Packed::<T, N, P>::new(&num.diag[pv.diag_off..], &perms[pv.scale_off..]);
    let blk = &shape.blocks[pv.blk_start];
    let (slot, r) = sides::<T, N, M, B>(pv.rhs.off, blk.rhs.off, bodies, joints);
    let u = fac.scaled_into(fac.lower_solve(slot), slot);
    let y = &num.offd[blk.off..blk.off + M * N];
    sub_mat_t_vec::<T, N, M>(y, &u, r);
}

/// The right-hand-side segments of a pivot (`N` long at `own`) and of its block's node (`M`
/// long at `other`), the body's in `bodies` and the joint's in `joints` (`B`: the pivot is the
/// body).
#[inline(always)]
fn sides<'a, T, const N: usize, const M: usize, const B: bool>(
    own: usize,
    other: usize,
    bodies: &'a mut [T],
    joints: &'a mut [T],
) -> (&'a mut [T], &'a mut [T]) {
    if B {
        (&mut bodies[own..own + N], &mut joints[other..other + M])
    } else {
        (&mut joints[own..own + N], &mut bodies[other..other + M])
    }
}

/// [`backward_step`] of a pivot of dimension `N` with one off-diagonal block of `M` rows, as
/// [`forward_one`].
#[inline(always)]
fn backward_one<T: Lane, const N: usize, const M: usize, const P: bool, const B: bool>(
    shape: &Shape,
    num: &Numeric<T>,
    perms: &[u8],
    pv: &Pivot,
    bodies: &mut [T],
    joints: &mut [T],
) {
    let fac = Packed::<T, N, P>::new(&num.diag[pv.diag_off..], &perms[pv.scale_off..]);
    let mut acc = [T::ZERO; N];
    let blk = &shape.blocks[pv.blk_start];
    let y = &num.offd[blk.off..blk.off + M * N];
    let (slot, x) = sides::<T, N, M, B>(pv.rhs.off, blk.rhs.off, bodies, joints);
    add_mat_vec::<T, N, M>(y, x, &mut acc);
    let mut t = [T::ZERO; N];
    for (((ti, &ui), &ai), &di) in t.iter_mut().zip(slot.iter()).zip(&acc).zip(fac.dinv) {
        *ti = ui - di * ai;
    }
    fac.upper_solve_into(t, slot);
}

/// Forward substitution of pivot `pv` (dimension `N`).
#[inline(always)]
fn forward_step<T: Lane, const N: usize, const P: bool>(
    shape: &Shape,
    num: &Numeric<T>,
    perms: &[u8],
    pv: &Pivot,
    bodies: &mut [T],
    joints: &mut [T],
) {
    let fac = Packed::<T, N, P>::new(&num.diag[pv.diag_off..], &perms[pv.scale_off..]);
    let slot = seg(pv.rhs, N, bodies, joints);
    let u = fac.scaled_into(fac.lower_solve(slot), slot);
    for blk in &shape.blocks[pv.blk_start..pv.blk_end] {
        let y = &num.offd[blk.off..blk.off + blk.rows * N];
        let r = seg(blk.rhs, blk.rows, bodies, joints);
        by_rows!(blk.rows, M => sub_mat_t_vec::<T, N, M>(y, &u, r), sub_mat_t_vec_dyn::<T, N>(y, &u, r));
    }
}

/// Backward substitution of pivot `pv` (dimension `N`).
#[inline(always)]
fn backward_step<T: Lane, const N: usize, const P: bool>(
    shape: &Shape,
    num: &Numeric<T>,
    perms: &[u8],
    pv: &Pivot,
    bodies: &mut [T],
    joints: &mut [T],
) {
    let fac = Packed::<T, N, P>::new(&num.diag[pv.diag_off..], &perms[pv.scale_off..]);
    let mut acc = [T::ZERO; N];
    for blk in &shape.blocks[pv.blk_start..pv.blk_end] {
        let y = &num.offd[blk.off..blk.off + blk.rows * N];
        let x = seg(blk.rhs, blk.rows, bodies, joints);
        by_rows!(blk.rows, M => add_mat_vec::<T, N, M>(y, x, &mut acc), add_mat_vec_dyn::<T, N>(y, x, &mut acc));
    }
    let slot = seg(pv.rhs, N, bodies, joints);
    let mut t = [T::ZERO; N];
    for (((ti, &ui), &ai), &di) in t.iter_mut().zip(slot.iter()).zip(&acc).zip(fac.dinv) {
        *ti = ui - di * ai;
    }
    fac.upper_solve_into(t, slot);
}

/// The factors of one pivot block (`Π P Πᵀ = L D Lᵀ`, `P` of dimension `N`) as the
/// factorisation left them, viewed for the fixed-size kernels of the Schur updates.
struct Factor<'a, T, const N: usize, const P: bool> {
    /// `L` strictly below the diagonal, in the packed lower layout of the diagonal blocks
    /// (`(i, k)` at `tri(i) + k`; the diagonal is not read).
    l: &'a [T],
    /// `D⁺`: `1 / d_k` for the kept pivots, `0` for the dropped ones.
    dinv: &'a [T],
    /// `perm[i]` is the original row of position `i` (see [`Self::row`]).
    perm: &'a [u8],
}

impl<'a, T: Lane, const N: usize, const P: bool> Factor<'a, T, N, P> {
    /// The factors stored at the start of `l`, `dinv` and `perm` by [`PivotWork::factor`].
    #[inline(always)]
    fn new(l: &'a [T], dinv: &'a [T], perm: &'a [u8]) -> Self {
        Self {
            l: &l[..tri(N)],
            dinv: &dinv[..N],
            perm: &perm[..N],
        }
    }

    /// The original row of position `i` (see [`permuted_row`]).
    #[inline(always)]
    fn row(&self, i: usize) -> usize {
        permuted_row::<N, P>(self.perm, i)
    }

    /// For one off-diagonal block `Wᵀ` (`N × M`, in `wy`) towards a later node with diagonal
    /// block `d` (`M × M`, packed lower triangle) and scales `s`: replaces it with
    /// `Y = L⁻¹ Π Wᵀ` and applies `d -= Yᵀ D⁺ Y`, `s += |diag(Yᵀ D⁺ Y)|`.
    #[inline(always)]
    #[allow(
        clippy::needless_range_loop,
        reason = "index loops with compile-time bounds, fully unrolled"
    )]
    fn block_update<const M: usize>(&self, wy: &mut [T], d: &mut [T], s: &mut [T]) {
        // Fixed-size views, so that every loop below has compile-time bounds.
        let (y, _) = wy[..N * M].as_chunks_mut::<M>();
        let d = &mut d[..tri(M)];
        let s = &mut s[..M];
        if T::IN_PLACE && !P {
            // Lanes: no copies of the block (see `Lane::IN_PLACE`), the same arithmetic.
            let y = &mut y[..N];
            self.substitute_block(y);
            for a in 0..M {
                let ych: [T; N] = std::array::from_fn(|k| y[k][a] * self.dinv[k]);
                for b in 0..=a {
                    let yc: [T; N] = std::array::from_fn(|k| y[k][b]);
                    self.update_entry(d, s, a, b, &ych, &yc);
                }
            }
            return;
        }
        let mut yt: [[T; M]; N] = std::array::from_fn(|i| y[self.row(i)]);
        self.substitute_block(&mut yt);
        y[..N].copy_from_slice(&yt);
        let yc: [[T; N]; M] = std::array::from_fn(|b| std::array::from_fn(|k| yt[k][b]));
        let ych: [[T; N]; M] =
            std::array::from_fn(|b| std::array::from_fn(|k| yt[k][b] * self.dinv[k]));
        for a in 0..M {
            for b in 0..=a {
                self.update_entry(d, s, a, b, &ych[a], &yc[b]);
            }
        }
    }

    /// `Y = L⁻¹ y` in place, for the `N` rows of `y` in pivot order.
    #[inline(always)]
    #[allow(
        clippy::needless_range_loop,
        reason = "index loops with compile-time bounds, fully unrolled"
    )]
    fn substitute_block<const M: usize>(&self, y: &mut [[T; M]]) {
        for k in 0..N {
            for i in 0..N {
                if i > k {
                    let c = self.l[tri(i) + k];
                    for b in 0..M {
                        let t = y[k][b];
                        y[i][b] -= c * t;
                    }
                }
            }
        }
    }

    /// Entry `(a, b)` (`b <= a`) of `D -= Yᵀ D⁺ Y` (lower triangle only: the diagonal blocks
    /// are only read there, see [`PivotWork::factor`]), from column `a` of `Y` scaled by `D⁺`
    /// and column `b`; on the diagonal also `s += |diag(Yᵀ D⁺ Y)|`.
    #[inline(always)]
    fn update_entry(
        &self,
        d: &mut [T],
        s: &mut [T],
        a: usize,
        b: usize,
        ych: &[T; N],
        yc: &[T; N],
    ) {
        let v = dot_n::<T, N>(ych, yc);
        d[tri(a) + b] -= v;
        if a == b {
            s[a] += v.abs();
        }
    }

    /// [`Self::block_update`] for a block of `m <= MAX_DIM` columns (any size).
    fn block_update_dyn(&self, m: usize, wy: &mut [T], d: &mut [T], s: &mut [T]) {
        let mut yt = [[T::ZERO; MAX_DIM]; N];
        for (i, row) in yt.iter_mut().enumerate() {
            let p = self.row(i);
            row[..m].copy_from_slice(&wy[p * m..p * m + m]);
        }
        for k in 0..N {
            let yk = yt[k];
            for (i, yi) in yt.iter_mut().enumerate().skip(k + 1) {
                let c = self.l[tri(i) + k];
                for (x, &v) in yi[..m].iter_mut().zip(&yk[..m]) {
                    *x -= c * v;
                }
            }
        }
        for (dst, row) in wy[..N * m].chunks_exact_mut(m).zip(&yt) {
            dst.copy_from_slice(&row[..m]);
        }
        // Lower triangle (packed), like `block_update`.
        for a in 0..m {
            for b in 0..=a {
                let mut v = T::ZERO;
                for (row, &dk) in yt.iter().zip(self.dinv) {
                    v += row[a] * dk * row[b];
                }
                d[tri(a) + b] -= v;
                if b == a {
                    s[a] += v.abs();
                }
            }
        }
    }
}

/// One assembly item into `num`; returns whether everything it read is finite (and the
/// compliances non-negative).
#[inline]
fn assemble_item<T: Lane, I: Inputs<T>>(
    shape: &Shape,
    num: &mut Numeric<T>,
    item: Assembly,
    inputs: &I,
) -> bool {
    match item {
        Assembly::Diag(t) => {
            let pv = &shape.pivots[t];
            let d = &mut num.diag[pv.diag_off..];
            let s = &mut num.scale[pv.scale_off..];
            match pv.node {
                KktNode::Body(b) => assemble_body(inputs.mass(b), d, s),
                KktNode::Joint(k) => {
                    let r0 = shape.row_off[k];
                    by_dim!(pv.dim, N => assemble_joint::<T, N>(inputs.compliance::<N>(r0), d, s))
                }
            }
        }
        Assembly::Jac { joint, slot } => {
            let (r0, m) = (shape.row_off[joint], shape.specs[joint].rows);
            let Some(t) = shape.jac_targets[joint][slot] else {
                return true;
            };
            let base = JAC_ROW_STRIDE * r0 + BODY_DOFS * slot;
            let dst = &mut num.offd[t.off..];
            by_rows!(
                m,
                M => scatter_jac::<T, M>(inputs.jac_rows::<M>(base), t, dst),
                scatter_jac_dyn(m, inputs.jac(base), t, dst)
            )
        }
        Assembly::Zero(off, len) => {
            num.offd[off..off + len].fill(T::ZERO);
            true
        }
    }
}

/// Schur-complement updates of pivot `pv` (dimension `N`, already factored as
/// `Π P Πᵀ = L D Lᵀ`) on its later neighbours: with `Y_j = L⁻¹ Π W_jᵀ` (stored for the
/// solve), `D_j -= Y_jᵀ D⁺ Y_j` and `A_jk -= Y_jᵀ D⁺ Y_k` (an overflow shows up as a
/// non-finite pivot later).
fn schur_update<T: Lane, const N: usize, const P: bool>(
    shape: &Shape,
    num: &mut Numeric<T>,
    perms: &[u8],
    pv: &Pivot,
) {
    if pv.blk_start == pv.blk_end {
        return;
    }
    // Later pivots' diagonal blocks and scales lie after this one's.
    let split = pv.diag_off + tri(N);
    let (head, tail) = num.diag.split_at_mut(split);
    let ssplit = pv.scale_off + N;
    let (shead, stail) = num.scale.split_at_mut(ssplit);
    let fac = Factor::<T, N, P>::new(
        &head[pv.diag_off..],
        &shead[pv.scale_off..],
        &perms[pv.scale_off..],
    );
    for blk in &shape.blocks[pv.blk_start..pv.blk_end] {
        let (m, len) = (blk.rows, blk.rows * N);
        let wy = &mut num.offd[blk.off..blk.off + len];
        let tgt = &shape.pivots[blk.tgt];
        let d = &mut tail[tgt.diag_off - split..tgt.diag_off - split + tri(m)];
        let s = &mut stail[tgt.scale_off - ssplit..tgt.scale_off - ssplit + m];
        by_rows!(m, M => fac.block_update::<M>(wy, d, s), fac.block_update_dyn(m, wy, d, s));
    }
    // Off-diagonal (fill) updates A_jk -= Y_jᵀ D⁺ Y_k.
    for op in &shape.ops[pv.op_start..pv.op_end] {
        let (bk, bj, bd) = (
            shape.blocks[op.k_blk],
            shape.blocks[op.j_blk],
            shape.blocks[op.dst_blk],
        );
        let (mj, mk) = (bj.rows, bk.rows);
        // The destination belongs to a later pivot, so it lies after `p`'s blocks.
        let (lo, hi) = num.offd.split_at_mut(bd.off);
        let yk = &lo[bk.off..bk.off + N * mk];
        let yj = &lo[bj.off..bj.off + N * mj];
        let dst = &mut hi[..mj * mk];
        for (a, drow) in dst.chunks_exact_mut(mk).enumerate() {
            for (((yjc, ykc), &dc), _) in yj
                .chunks_exact(mj)
                .zip(yk.chunks_exact(mk))
                .zip(fac.dinv)
                .zip(0..N)
            {
                let c = yjc[a] * dc;
                for (x, &v) in drow.iter_mut().zip(ykc) {
                    *x -= c * v;
                }
            }
        }
    }
}

/// [`schur_update`] of a pivot with one off-diagonal block, of `M` rows (a tree's pivots, see
/// [`by_pair`]): its block update alone (a pair update needs two blocks), with no loop and no
/// dispatch on the block's size.
#[inline(always)]
fn schur_one<T: Lane, const N: usize, const M: usize, const P: bool>(
    shape: &Shape,
    num: &mut Numeric<T>,
    perms: &[u8],
    pv: &Pivot,
) {
    let split = pv.diag_off + tri(N);
    let (head, tail) = num.diag.split_at_mut(split);
    let ssplit = pv.scale_off + N;
    let (shead, stail) = num.scale.split_at_mut(ssplit);
    let fac = Factor::<T, N, P>::new(
        &head[pv.diag_off..],
        &shead[pv.scale_off..],
        &perms[pv.scale_off..],
    );
    let blk = &shape.blocks[pv.blk_start];
    let wy = &mut num.offd[blk.off..blk.off + M * N];
    let tgt = &shape.pivots[blk.tgt];
    let d = &mut tail[tgt.diag_off - split..tgt.diag_off - split + tri(M)];
    let s = &mut stail[tgt.scale_off - ssplit..tgt.scale_off - ssplit + M];
    fac.block_update::<M>(wy, d, s);
}

/// `r -= Yᵀ u` for `Y` of `N × M` (row-major).
#[inline(always)]
fn sub_mat_t_vec<T: Lane, const N: usize, const M: usize>(y: &[T], u: &[T; N], r: &mut [T]) {
    let (y, r) = (&y[..N * M], &mut r[..M]);
    let mut acc = [T::ZERO; M];
    for (yrow, &uk) in y.chunks_exact(M).zip(u) {
        for (a, &v) in acc.iter_mut().zip(yrow) {
            *a += uk * v;
        }
    }
    for (ri, &a) in r.iter_mut().zip(&acc) {
        *ri -= a;
    }
}

/// [`sub_mat_t_vec`] for any number of columns (`r.len()`).
fn sub_mat_t_vec_dyn<T: Lane, const N: usize>(y: &[T], u: &[T; N], r: &mut [T]) {
    let m = r.len();
    let mut acc = [T::ZERO; MAX_DIM];
    for (yrow, &uk) in y[..N * m].chunks_exact(m).zip(u) {
        for (a, &v) in acc.iter_mut().zip(yrow) {
            *a += uk * v;
        }
    }
    for (ri, &a) in r.iter_mut().zip(&acc) {
        *ri -= a;
    }
}

/// `acc += Y x` for `Y` of `N × M` (row-major).
#[inline(always)]
fn add_mat_vec<T: Lane, const N: usize, const M: usize>(y: &[T], x: &[T], acc: &mut [T; N]) {
    let (y, x) = (&y[..N * M], &x[..M]);
    for (a, yrow) in acc.iter_mut().zip(y.chunks_exact(M)) {
        *a += dot_n::<T, M>(yrow, x);
    }
}

/// [`add_mat_vec`] for any number of columns (`x.len()`).
fn add_mat_vec_dyn<T: Lane, const N: usize>(y: &[T], x: &[T], acc: &mut [T; N]) {
    let m = x.len();
    for (a, yrow) in acc.iter_mut().zip(y[..N * m].chunks_exact(m)) {
        *a += dot(yrow, x);
    }
}

/// Assembles the diagonal block `d` (packed lower triangle of the symmetric part of `m`, see
/// [`tri`]) and the scales `s` of a body. Returns whether every entry is finite.
#[inline]
#[allow(
    clippy::needless_range_loop,
    reason = "index loops with compile-time bounds, fully unrolled"
)]
fn assemble_body<T: Lane>(m: impl Fn(usize) -> T, d: &mut [T], s: &mut [T]) -> bool {
    let (d, s) = (&mut d[..tri(6)], &mut s[..6]);
    let half = T::splat(0.5);
    for i in 0..6 {
        for j in 0..6 {
            if j <= i {
                d[tri(i) + j] = half * (m(i * 6 + j) + m(j * 6 + i));
            }
        }
        s[i] = d[tri(i) + i].abs();
    }
    // A sum is finite where every term is (`finite` tells, see there).
    let mut chk = [T::ZERO; 6];
    for i in 0..6 {
        for (j, c) in chk.iter_mut().enumerate() {
            *c += m(i * 6 + j);
        }
    }
    finite(&chk)
}

/// Assembles the diagonal block `d` (`-diag(c)`, `N × N`, packed lower triangle) and the scales
/// `s` of a joint. Returns whether every compliance is finite and non-negative.
#[inline]
#[allow(
    clippy::needless_range_loop,
    reason = "index loops with compile-time bounds, fully unrolled"
)]
fn assemble_joint<T: Lane, const N: usize>(c: [T; N], d: &mut [T], s: &mut [T]) -> bool {
    let (d, s) = (&mut d[..tri(N)], &mut s[..N]);
    let mut ok = true;
    d.fill(T::ZERO);
    for i in 0..N {
        let ci = c[i];
        d[tri(i) + i] = -ci;
        s[i] = ci;
        ok &= T::all(T::and(ci.ge(T::ZERO), ci.le(T::splat(Real::MAX))));
    }
    ok
}

/// Writes (or adds, see [`JacTarget`]) the `M` Jacobian rows starting at `src` (stride
/// [`JAC_ROW_STRIDE`], 6 entries each) into the block at the start of `dst`. Returns whether
/// every value read is finite.
#[inline]
#[allow(
    clippy::needless_range_loop,
    reason = "index loops with compile-time bounds, fully unrolled"
)]
fn scatter_jac<T: Lane, const M: usize>(
    rows: [[T; BODY_DOFS]; M],
    t: JacTarget,
    dst: &mut [T],
) -> bool {
    let mut chk = [T::ZERO; BODY_DOFS];
    for row in &rows {
        for (c, &v) in chk.iter_mut().zip(row.iter()) {
            *c += v;
        }
    }
    let dst = &mut dst[..BODY_DOFS * M];
    match (t.transposed, t.add) {
        (false, false) => {
            for (d, row) in dst.chunks_exact_mut(BODY_DOFS).zip(&rows) {
                d.copy_from_slice(row);
            }
        }
        (false, true) => {
            for (d, row) in dst.chunks_exact_mut(BODY_DOFS).zip(&rows) {
                for (x, &v) in d.iter_mut().zip(row) {
                    *x += v;
                }
            }
        }
        (true, false) => {
            for c in 0..BODY_DOFS {
                for i in 0..M {
                    dst[c * M + i] = rows[i][c];
                }
            }
        }
        (true, true) => {
            for c in 0..BODY_DOFS {
                for i in 0..M {
                    dst[c * M + i] += rows[i][c];
                }
            }
        }
    }
    finite(&chk)
}

/// [`scatter_jac`] for `m` rows (any number).
#[allow(
    clippy::needless_range_loop,
    reason = "the column indexes the source, the check and the destination"
)]
fn scatter_jac_dyn<T: Lane>(
    m: usize,
    src: impl Fn(usize) -> T,
    t: JacTarget,
    dst: &mut [T],
) -> bool {
    let mut chk = [T::ZERO; BODY_DOFS];
    let dst = &mut dst[..BODY_DOFS * m];
    for i in 0..m {
        for c in 0..BODY_DOFS {
            let v = src(JAC_ROW_STRIDE * i + c);
            chk[c] += v;
            let idx = if t.transposed {
                c * m + i
            } else {
                i * BODY_DOFS + c
            };
            if t.add {
                dst[idx] += v;
            } else {
                dst[idx] = v;
            }
        }
    }
    finite(&chk)
}

/// Whether the sums `chk` are finite: each the sum of some inputs, which is NaN or infinite
/// where an input is (or, for inputs beyond `Real::MAX / 12`, where the sum overflows: then the
/// caller's exact checks find nothing and the factorisation goes on). A finite `x` has `x - x
/// = 0`; NaN and the infinities give NaN. Summed instead of `v * 0` per input, one
/// multiplication less per entry of the assembly.
#[inline(always)]
#[allow(clippy::eq_op, reason = "`x - x` is the finiteness test")]
fn finite<T: Lane>(chk: &[T]) -> bool {
    chk.iter().all(|&c| T::all((c - c).eq(T::ZERO)))
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
#[inline(always)]
fn seg<'a, T>(loc: RhsLoc, len: usize, bodies: &'a mut [T], joints: &'a mut [T]) -> &'a mut [T] {
    if loc.joint {
        &mut joints[loc.off..loc.off + len]
    } else {
        &mut bodies[loc.off..loc.off + len]
    }
}

/// Dot product of the first `N` entries (a compile-time length, so the loop is unrolled),
/// summed in two interleaved halves so that it vectorises.
#[inline(always)]
fn dot_n<T: Lane, const N: usize>(a: &[T], b: &[T]) -> T {
    let (a, b) = (&a[..N], &b[..N]);
    if N == 1 {
        return a[0] * b[0];
    }
    // The first products start the two accumulators (no `0 + x`, which cannot be folded).
    let mut acc = [a[0] * b[0], a[1] * b[1]];
    for (x, y) in a[2..].chunks_exact(2).zip(b[2..].chunks_exact(2)) {
        acc[0] += x[0] * y[0];
        acc[1] += x[1] * y[1];
    }
    let mut s = acc[0] + acc[1];
    if N % 2 == 1 {
        s += a[N - 1] * b[N - 1];
    }
    s
}

#[inline]
fn dot<T: Lane>(a: &[T], b: &[T]) -> T {
    // From `-0.0`, as `Iterator::sum` of the floats adds (it keeps an all-negative-zero sum's
    // sign): the same bits as the scalar `sum` this replaced.
    a.iter()
        .zip(b)
        .fold(T::splat(-0.0), |acc, (&x, &y)| acc + x * y)
}

/// Replaces the unit lower triangular `L` stored strictly below the diagonal of the packed
/// lower `a` (see [`tri`]) by `X = L⁻¹` and `D⁺` (`dinv`) in the packed layout of [`Packed`]
/// (same `tri(N)` entries). From `L X = I`, row by row: `X_ij = -L_ij - Σ_{j<k<i} L_ik X_kj`.
#[inline]
#[allow(
    clippy::needless_range_loop,
    reason = "index loops with compile-time bounds, fully unrolled"
)]
fn invert_and_pack<T: Lane, const N: usize>(a: &mut [T], dinv: &[T]) {
    let a = &mut a[..tri(N)];
    let mut w = [[T::ZERO; N]; N];
    for i in 0..N {
        for j in 0..N {
            if j < i {
                w[i][j] = a[tri(i) + j];
            }
        }
    }
    for i in 1..N {
        let li = w[i];
        for j in 0..N {
            if j < i {
                let mut acc = -li[j];
                for k in 0..N {
                    if k > j && k < i {
                        acc -= li[k] * w[k][j];
                    }
                }
                w[i][j] = acc;
            }
        }
    }
    // Packed: `X_ik` at `i (i - 1) / 2 + k`, then `D⁺` (see [`Packed`]); `tri(N)` entries.
    for i in 1..N {
        for k in 0..N {
            if k < i {
                a[i * (i - 1) / 2 + k] = w[i][k];
            }
        }
    }
    let o = N * (N - 1) / 2;
    a[o..o + N].copy_from_slice(&dinv[..N]);
}

/// The factors of one pivot block as the solve reads them: `X = L⁻¹` packed by rows (strictly
/// lower part, `X_ik` at `i (i - 1) / 2 + k`), followed by `D⁺`, and the permutation.
struct Packed<'a, T, const N: usize, const P: bool> {
    x: &'a [T],
    dinv: &'a [T],
    /// `perm[i]` is the original row of position `i` (see [`Self::row`]).
    perm: &'a [u8],
}

impl<'a, T: Lane, const N: usize, const P: bool> Packed<'a, T, N, P> {
    /// The factors stored at the start of `a` by [`invert_and_pack`] and of `perm`.
    #[inline(always)]
    fn new(a: &'a [T], perm: &'a [u8]) -> Self {
        let o = N * (N - 1) / 2;
        Self {
            x: &a[..o],
            dinv: &a[o..o + N],
            perm: &perm[..N],
        }
    }

    /// The original row of position `i` (see [`permuted_row`]).
    #[inline(always)]
    fn row(&self, i: usize) -> usize {
        permuted_row::<N, P>(self.perm, i)
    }

    /// `X Π v = L⁻¹ Π v` (`v` in original order, at least `N` long). Unrolled; the rows are
    /// independent.
    #[inline(always)]
    #[allow(
        clippy::needless_range_loop,
        reason = "index loops with compile-time bounds, fully unrolled"
    )]
    fn lower_solve(&self, v: &[T]) -> [T; N] {
        let vp: [T; N] = std::array::from_fn(|i| v[self.row(i)]);
        let mut y = vp;
        for i in 0..N {
            for k in 0..N {
                if k < i {
                    y[i] += self.x[i * (i - 1) / 2 + k] * vp[k];
                }
            }
        }
        y
    }

    /// `out = Πᵀ Xᵀ t = Πᵀ L⁻ᵀ t` (`out` in original order, at least `N` long). Unrolled.
    #[inline(always)]
    #[allow(
        clippy::needless_range_loop,
        reason = "index loops with compile-time bounds, fully unrolled"
    )]
    fn upper_solve_into(&self, t: [T; N], out: &mut [T]) {
        let mut x = t;
        for k in 0..N {
            for j in 0..N {
                if j < k {
                    x[j] += self.x[k * (k - 1) / 2 + j] * t[k];
                }
            }
        }
        for (i, &xi) in x.iter().enumerate() {
            out[self.row(i)] = xi;
        }
    }

    /// `u = D⁺ y` (`y` in permuted order), written into `out` (at least `N` long) and
    /// returned. Each entry is stored from the product itself: the `[Real; N]` copied into
    /// `out` afterwards was read back with wider loads than its stores (with `-C
    /// target-cpu=native`), which stall until the stores reach the cache.
    #[inline(always)]
    #[allow(
        clippy::needless_range_loop,
        reason = "index loops with compile-time bounds, fully unrolled"
    )]
    fn scaled_into(&self, y: [T; N], out: &mut [T]) -> [T; N] {
        let out = &mut out[..N];
        let mut u = [T::ZERO; N];
        for i in 0..N {
            u[i] = y[i] * self.dinv[i];
            out[i] = u[i];
        }
        u
    }
}

/// Entry `i` of a pivot block's stored permutation `perm` (`N` entries, each the original
/// position of position `i`, `< N`), clamped to `N - 1` so that indexing with it is trivially in
/// range. Read from the stored bytes at each use: copying them into a `[usize; N]` first was
/// compiled, with `-C target-cpu=native` on this machine's AVX-512 core, into a masked vector
/// store that the scalar reads right after could not take their values from (the store had to
/// reach the cache first): 17 % of `KktSolver::solve`'s samples stalled on those reads.
/// Without `P` (no block of the factorisation was pivoted) the permutation is the identity
/// and is not read: `i` itself.
#[inline(always)]
fn permuted_row<const N: usize, const P: bool>(perm: &[u8], i: usize) -> usize {
    if P {
        usize::from(perm[i]).min(N - 1)
    } else {
        i
    }
}

/// `n (n + 1) / 2`: the size of a packed lower triangle; its row `i` starts at `tri(i)`. The
/// diagonal blocks are stored that way (only their lower triangle is ever used).
#[inline(always)]
const fn tri(n: usize) -> usize {
    n * (n + 1) / 2
}

/// `Some(NonFinite)` if some entry of `v` is NaN or infinite.
#[inline(always)]
fn not_finite<T: Lane, const N: usize>(v: &[T; N]) -> Option<PivotFail> {
    let mut good = true;
    for &x in v {
        good &= T::all(x.finite());
    }
    (!good).then_some(PivotFail::NonFinite)
}

/// State of the pivoted `LDLᵀ` of one `N × N` block, see [`PivotWork::factor`].
struct Ldl<'a, T, const N: usize> {
    /// The block, worked on in place (packed lower triangle, see [`tri`]): `L` in the eliminated
    /// columns, the Schur complement in the others.
    w: &'a mut [T],
    /// `1 / s` by position.
    inv_s: [T; N],
    /// `perm[i]` is the original index of position `i`.
    perm: [usize; N],
    /// `1 / d` of the eliminated steps.
    dinv: [T; N],
}

impl<'a, T: Lane, const N: usize> Ldl<'a, T, N> {
    /// The block `a` (packed lower triangle, worked on in place) with its scales `s`
    /// (`1 / s`, or 0 for a zero scale, by position), in its original order.
    #[inline(always)]
    fn new(a: &'a mut [T], s: &[T]) -> Self {
        let mut inv_s = [T::ZERO; N];
        for (is, &sc) in inv_s.iter_mut().zip(s) {
            *is = T::select(sc.gt(T::ZERO), T::splat(1.0) / sc, T::ZERO);
        }
        Self {
            w: &mut a[..tri(N)],
            inv_s,
            perm: std::array::from_fn(|i| i),
            dinv: [T::ZERO; N],
        }
    }

    /// The body block's unpivoted steps ([`Self::step_spd`]): the rank reached (`N`, or the
    /// first step whose scaled pivot is not above `thresh`).
    #[inline(always)]
    fn spd(&mut self, thresh: Real) -> Result<usize, PivotFail> {
        let mut rank = N;
        macro_rules! steps {
            ($($k:literal)*) => {
                $(
                    if $k < N && rank == N && !self.step_spd::<$k>(thresh)? {
                        rank = $k;
                    }
                )*
            };
        }
        steps!(0 1 2 3 4 5 6 7 8 9 10 11);
        Ok(rank)
    }

    /// A joint block's unpivoted attempt (see [`PivotWork::factor`]): whether every step's
    /// scaled pivot kept the product of them above `2 thresh`.
    #[inline(always)]
    fn definite(&mut self, thresh: Real) -> bool {
        let (mut unpivoted, mut prod) = (true, T::splat(1.0));
        let floor = T::splat(2.0 * thresh);
        macro_rules! definite {
            ($($k:literal)*) => {
                $(
                    unpivoted = unpivoted && ($k >= N || self.step_definite::<$k>(&mut prod, floor));
                )*
            };
        }
        definite!(0 1 2 3 4 5 6 7 8 9 10 11);
        unpivoted
    }

    /// Step `K` (`< N`) of a body block, symmetric positive definite: no pivot search (the
    /// unpivoted `LDLᵀ` of a positive definite matrix is backward stable), position `K`
    /// eliminated as it stands. Returns `false` when its scaled pivot `d_K / s_K` is not above
    /// `thresh` (not positive definite to working precision).
    ///
    /// The body blocks' factorisation by the pivoted [`Self::step`] was 8.8 % of the Lagrange
    /// backend's step on the mixed scene (`perf`, 200 arms); without the search, the swap and
    /// the candidates' reciprocals the step is 4-6 % faster.
    #[inline(always)]
    fn step_spd<const K: usize>(&mut self, thresh: Real) -> Result<bool, PivotFail> {
        let w = &mut self.w[..tri(N)];
        if K >= N {
            return Ok(false);
        }
        let d = w[tri(K) + K];
        // `d * 0` is `±0` for finite `d` and NaN otherwise.
        if !T::all((d * T::ZERO).eq(T::ZERO)) {
            return Err(PivotFail::NonFinite);
        }
        // Not above `thresh`, or NaN.
        let ratio = d * self.inv_s[K];
        if !T::all(ratio.gt(T::splat(thresh))) {
            return Ok(false);
        }
        let id = T::splat(1.0) / d;
        self.dinv[K] = id;
        self.eliminate_column::<K>(id);
        Ok(true)
    }

    /// Step `K` (`< N`) of a joint block's unpivoted attempt (see [`PivotWork::factor`]):
    /// eliminates position `K` as it stands and multiplies `prod` by its scaled pivot
    /// `|d_K| / s_K` when the product stays above `floor`, and returns whether it did (`false`
    /// also for a non-finite pivot, which the pivoted factorisation then reports).
    #[inline(always)]
    fn step_definite<const K: usize>(&mut self, prod: &mut T, floor: T) -> bool {
        if K >= N {
            return false;
        }
        let d = self.w[tri(K) + K];
        let p = *prod * (d.abs() * self.inv_s[K]);
        // NaN and infinities fail one of the tests.
        if !T::all(T::and(p.gt(floor), d.finite())) {
            return false;
        }
        *prod = p;
        let id = T::splat(1.0) / d;
        self.dinv[K] = id;
        self.eliminate_column::<K>(id);
        true
    }

    /// Eliminates position `K`, whose pivot is `1 / id`: `L` into its column, the Schur
    /// complement into the trailing block.
    #[inline(always)]
    #[allow(
        clippy::needless_range_loop,
        reason = "index loops with compile-time bounds, fully unrolled"
    )]
    fn eliminate_column<const K: usize>(&mut self, id: T) {
        let w = &mut self.w[..tri(N)];
        // Rows in increasing order: for `j < i` the column entry `(j, K)` is already `l_j`,
        // and `A_ij - l_i d l_j = A_ij - A_iK l_j`.
        for i in K + 1..N {
            let aik = w[tri(i) + K];
            let li = aik * id;
            for j in K + 1..N {
                if j < i {
                    w[tri(i) + j] -= aik * w[tri(j) + K];
                }
            }
            w[tri(i) + i] -= aik * li;
            w[tri(i) + K] = li;
        }
    }
}

impl<const N: usize> Ldl<'_, Real, N> {
    /// Step `K` (`< N`) of a joint block: chooses the pivot among positions `K..N` (largest
    /// `|d_i| / s_i`, first position on ties, NaN never chosen), moves it to position `K` and
    /// eliminates it. Returns `false` (nothing changed) when the largest scaled pivot is
    /// `<= thresh`: the remaining rows are dropped.
    #[inline(always)]
    #[allow(
        clippy::needless_range_loop,
        reason = "index loops with compile-time bounds, fully unrolled"
    )]
    fn step<const K: usize>(&mut self, thresh: Real) -> Result<bool, PivotFail> {
        let w = &mut self.w[..tri(N)];
        if K >= N {
            return Ok(false);
        }
        // The reciprocals of the candidates, computed while the pivot is searched (the
        // division is on the critical path otherwise).
        let mut dg = [0.0; N];
        for i in K..N {
            dg[i] = w[tri(i) + i];
        }
        // A non-finite candidate (overflow).
        let mut bad = false;
        let mut recip = [0.0; N];
        let mut ratio = [0.0; N];
        for i in K..N {
            // `d * 0` is `±0` for finite `d` and NaN otherwise.
            bad |= dg[i] * 0.0 != 0.0;
            recip[i] = 1.0 / dg[i];
            ratio[i] = dg[i].abs() * self.inv_s[i];
        }
        if bad {
            return Err(PivotFail::NonFinite);
        }
        let mut best = K;
        let mut best_ratio = -1.0;
        for i in K..N {
            if ratio[i] > best_ratio {
                best = i;
                best_ratio = ratio[i];
            }
        }
        if best_ratio.is_nan() || best_ratio <= thresh {
            return Ok(false);
        }
        if best != K {
            // Symmetric swap of rows/columns `K <= best` in lower-triangle storage, without
            // branches on `best` (it is data-dependent; a no-op when `best == K`).
            for j in 0..K {
                let t = w[tri(K) + j];
                w[tri(K) + j] = w[tri(best) + j];
                w[tri(best) + j] = t;
            }
            for i in K + 1..N {
                // Partner of `(i, K)`: `(best, i)` above `best`, `(i, best)` below it, itself on
                // row `best` (whose entry `(best, K)` is swapped with the diagonal below).
                let (r, c) = if i < best {
                    (best, i)
                } else if i > best {
                    (i, best)
                } else {
                    (i, K)
                };
                let t = w[tri(i) + K];
                w[tri(i) + K] = w[tri(r) + c];
                w[tri(r) + c] = t;
            }
            let t = w[tri(K) + K];
            w[tri(K) + K] = w[tri(best) + best];
            w[tri(best) + best] = t;
            self.perm.swap(K, best);
            self.inv_s.swap(K, best);
        }
        let id = recip[best];
        self.dinv[K] = id;
        self.eliminate_column::<K>(id);
        Ok(true)
    }
}

/// Scratch of the factorisation of one pivot block.
struct PivotWork {
    /// `L` of the last rank-deficient pivot (row stride [`MAX_DIM`], permuted order).
    l: [Real; MAX_DIM * MAX_DIM],
    /// `perm[i]` is the original index of position `i` (kept rows first, then the dropped
    /// ones).
    perm: [usize; MAX_DIM],
    /// The last block was factored with pivoting (its permutation may not be the identity).
    pivoted: bool,
}

impl Default for PivotWork {
    fn default() -> Self {
        Self {
            l: [0.0; MAX_DIM * MAX_DIM],
            perm: [0; MAX_DIM],
            pivoted: false,
        }
    }
}

impl PivotWork {
    /// `LDLᵀ` factorisation of the symmetric `N×N` block `a` (its lower triangle is read) with
    /// symmetric diagonal pivoting (largest `|d_i| / s_i` first, `s` read from `sd`, first index
    /// on ties); stops at the first pivot whose scaled value is `<= thresh`, the remaining rows
    /// are dropped. Returns the rank.
    ///
    /// A joint block is first factored without pivoting, and that factorisation stands when the
    /// product of its scaled pivots `|d_k| / s_k` is above `2 thresh`; otherwise the block is
    /// restored and factored with pivoting. Why the pivoting then drops no row: a joint block
    /// is semidefinite (its bodies are eliminated before it, see the module docs: it is a
    /// Schur complement of `-(J M⁻¹ Jᵀ + C)`), so every step shrinks the remaining diagonal
    /// and each scaled pivot is at most 1 (`s` sums the magnitudes of what the diagonal entry
    /// holds). Had the pivoted factorisation dropped rows at step `k`, the product of all `N`
    /// scaled pivots, which is `|det| / prod(s)` in any order, would be at most
    /// `thresh^(N-k) <= thresh`. So both factor the whole block, and only round-off tells them
    /// apart. The product, not each pivot, is tested: a bead's revolute (a light bead whose
    /// rotary inertia is tiny against its lever arm) has a scaled pivot near 1e-4 once its
    /// translations are eliminated, in any order. Counted over 20 steps at 1/60 s x 4
    /// (2026-11-28): every joint block of the mixed scene, the 1:1 chain of 100 links and the
    /// pendulum stands unpivoted; on the 1:1000 chain of 100, 75 of 8200. Then
    /// [`KktSolver::solve`] and the Schur updates read no permutation: callgrind, -4.0 to -4.9 %
    /// instructions per step on those scenes. A body block is positive definite and never
    /// pivoted.
    ///
    /// Outputs (permuted order): `a` receives `L` strictly below its diagonal (zero in the
    /// columns of the dropped rows; the rest of `a` is left unspecified), `sd` receives `D⁺`
    /// (`1 / d` for the kept pivots, `0` for the dropped ones) and `perm_out` the permutation.
    #[allow(
        clippy::needless_range_loop,
        reason = "index loops with compile-time bounds, fully unrolled"
    )]
    fn factor<const N: usize>(
        &mut self,
        a: &mut [Real],
        sd: &mut [Real],
        perm_out: &mut [u8],
        thresh: Real,
        body: bool,
    ) -> Result<usize, PivotFail> {
        // Worked on in place.
        let mut st = Ldl::<Real, N>::new(a, sd);
        let mut rank = N;
        if body {
            self.pivoted = false;
            rank = st.spd(thresh)?;
        } else {
            // The block for the pivoted factorisation: `N × N` holds its `tri(N)` reals (a
            // length of `tri(N)` is not a type on stable Rust), filled entry by entry (zeroing
            // it first was a `memset` call per block, 0.3 % of the 100-link chain's step).
            let saved: [[Real; N]; N] = std::array::from_fn(|i| {
                std::array::from_fn(|j| st.w.get(i * N + j).copied().unwrap_or(0.0))
            });
            let unpivoted = st.definite(thresh);
            self.pivoted = !unpivoted;
            if !unpivoted {
                st.w.copy_from_slice(&saved.as_flattened()[..tri(N)]);
                st.dinv = [0.0; N];
                // The steps, unrolled (each one has compile-time loop bounds).
                macro_rules! steps {
                    ($($k:literal)*) => {
                        $(
                            if $k < N && rank == N && !st.step::<$k>(thresh)? {
                                rank = $k;
                            }
                        )*
                    };
                }
                steps!(0 1 2 3 4 5 6 7 8 9 10 11);
            }
        }
        let Ldl { w, perm, dinv, .. } = st;
        if body && rank < N {
            return Err(PivotFail::NotPositive);
        }
        // Overflow in `1 / d` (a non-finite multiplier would have made a later diagonal entry
        // non-finite).
        if let Some(e) = not_finite(&dinv) {
            return Err(e);
        }
        if rank < N {
            for i in rank..N {
                for j in rank..i {
                    w[tri(i) + j] = 0.0;
                }
            }
            // `L` for the null vectors.
            for i in 0..N {
                for j in 0..i {
                    self.l[i * MAX_DIM + j] = w[tri(i) + j];
                }
            }
        }
        sd[..N].copy_from_slice(&dinv);
        for (o, &p) in perm_out.iter_mut().zip(&perm) {
            // `p < N <= MAX_DIM`, which fits a byte.
            *o = p as u8;
        }
        self.perm[..N].copy_from_slice(&perm);
        Ok(rank)
    }

    /// Null vector (original row order) of the last factored block for the dropped position
    /// `q`: `y = [-L11⁻ᵀ l; e_q]` with `l` the kept part of row `q` of `L`.
    fn null_vector(&self, n: usize, rank: usize, q: usize) -> [Real; MAX_DIM] {
        let l = |i: usize, j: usize| self.l[i * MAX_DIM + j];
        let mut y = [0.0; MAX_DIM];
        y[q] = 1.0;
        for a in (0..rank).rev() {
            let mut acc = -l(q, a);
            for (i, &yi) in y.iter().enumerate().take(rank).skip(a + 1) {
                acc -= l(i, a) * yi;
            }
            y[a] = acc;
        }
        let mut v = [0.0; MAX_DIM];
        for (&p, &yi) in self.perm.iter().zip(&y).take(n) {
            v[p] = yi;
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
    fn lanes_factor_as_the_scalar_solver_does() {
        // Four systems of one structure factored in lanes (`factor_lanes`) against each
        // factored on its own (`factor`): every lane runs the scalar operations in the same
        // order, so the stored factors, and the solves from them, must be equal to the bit
        // (no tolerance). Structures: a chain with joints of 1 to 6 rows, a branching tree,
        // and a loop (fill blocks); compliance 0 and 1e-10.
        let mut rng = Lcg(7);
        let chain = chain_joints(6, |k| 1 + (k * 7 + 3) % 6);
        let bits = |v: &[Real]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let mut in_lanes = 0;
        for (nb, joints) in [(6, chain), (8, tree_joints()), (3, loop_joints())] {
            for comp in [0.0, 1e-10] {
                let ps: Vec<Problem> = (0..4)
                    .map(|_| random_problem(&mut rng, nb, &joints, comp))
                    .collect();
                let scalar: Vec<_> = ps.iter().map(Problem::sparse_solve).collect();
                let fresh = KktSolver::new(nb, &ps[0].specs).unwrap();
                let mut lanes: Vec<KktSolver> = (0..4).map(|_| fresh.clone()).collect();
                let inputs: [FactorInputs; 4] = std::array::from_fn(|l| FactorInputs {
                    mass: &ps[l].mass,
                    jac: &ps[l].jac,
                    compliance: &ps[l].comp,
                });
                let [a, b, c, d] = &mut lanes[..] else {
                    unreachable!()
                };
                // The lanes take the systems whose every block stands unpivoted (in `f32`, whose
                // redundancy tolerance is 5e-5, some random blocks are pivoted).
                let unpivoted = scalar.iter().all(|(s, ..)| !s.pivoted);
                let done = KktSolver::factor_lanes([a, b, c, d], &mut KktLanes::default(), inputs);
                assert_eq!(done, unpivoted);
                if !done {
                    continue;
                }
                in_lanes += 1;
                for ((p, l), (s, rep, x, lambda)) in ps.iter().zip(&lanes).zip(&scalar) {
                    assert_eq!(rep.redundant_rows, 0);
                    assert!(l.factored && !l.pivoted && l.dropped.is_empty());
                    assert_eq!(bits(&l.num.diag), bits(&s.num.diag));
                    assert_eq!(bits(&l.num.offd), bits(&s.num.offd));
                    assert_eq!(l.perms, s.perms);
                    let (mut xl, mut ll) = (p.f.clone(), p.g.clone());
                    l.solve(&mut xl, &mut ll).unwrap();
                    assert_eq!(bits(xl.as_flattened()), bits(x.as_flattened()));
                    assert_eq!(bits(&ll), bits(lambda));
                }
            }
        }
        assert!(in_lanes >= 3, "{in_lanes} of 6 groups factored in lanes");
    }

    #[test]
    fn lanes_leave_a_block_that_needs_pivoting_to_the_scalar_path() {
        // One lane's joint has two equal rows: its block fails the unpivoted test (it is
        // pivoted, and a row dropped, by `factor`). The lanes must then refuse, leaving every
        // solver as it was (not factored), and the scalar path reports the dropped row.
        let mut rng = Lcg(11);
        let joints = tree_joints();
        let mut ps: Vec<Problem> = (0..4)
            .map(|_| random_problem(&mut rng, 8, &joints, 0.0))
            .collect();
        // Joint 1 (5 rows from global row 6): its second row a copy of its first.
        let r0 = 6;
        let row: Vec<Real> = ps[2].jac[JAC_ROW_STRIDE * r0..JAC_ROW_STRIDE * (r0 + 1)].to_vec();
        ps[2].jac[JAC_ROW_STRIDE * (r0 + 1)..JAC_ROW_STRIDE * (r0 + 2)].copy_from_slice(&row);
        let fresh = KktSolver::new(8, &ps[0].specs).unwrap();
        let mut lanes: Vec<KktSolver> = (0..4).map(|_| fresh.clone()).collect();
        let inputs: [FactorInputs; 4] = std::array::from_fn(|l| FactorInputs {
            mass: &ps[l].mass,
            jac: &ps[l].jac,
            compliance: &ps[l].comp,
        });
        let [a, b, c, d] = &mut lanes[..] else {
            unreachable!()
        };
        assert!(!KktSolver::factor_lanes(
            [a, b, c, d],
            &mut KktLanes::default(),
            inputs
        ));
        assert!(lanes.iter().all(|l| !l.factored));
        let (s, rep, _, _) = ps[2].sparse_solve();
        assert!(s.pivoted);
        assert_eq!(rep.redundant_rows, 1);
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
    fn well_conditioned_joint_blocks_stand_unpivoted() {
        // The random chains and trees (each row a dominant entry plus noise, far from the
        // redundancy test): every joint block's unpivoted factorisation stands, so no
        // permutation is stored or read, and the solution is the dense one to rounding.
        let mut rng = Lcg(5);
        for _ in 0..20 {
            let chain = chain_joints(6, |k| 1 + (k * 7 + 3) % 6);
            for p in [
                random_problem(&mut rng, 6, &chain, 0.0),
                random_problem(&mut rng, 8, &tree_joints(), 1e-3),
            ] {
                check_against_dense(&p);
                let (s, ..) = p.sparse_solve();
                assert!(!s.pivoted);
            }
        }
    }

    #[test]
    fn a_nearly_dependent_block_is_pivoted_and_kept_or_dropped_as_before() {
        // One body (unit mass matrix) held by two rows: `e_0` and `e_0 + delta e_1`. The
        // joint block is `-[[1, 1], [1, 1 + delta^2]]` with scales `1` and `1 + delta^2`, so
        // its scaled pivots are 1 and `delta^2 / (1 + delta^2)` in either order. At
        // `delta^2 = 1e-10` their product is below twice the redundancy tolerance (7.3e-11 in
        // `f64`): the unpivoted factorisation does not stand, and the pivoted one keeps both
        // rows (1e-10 is above the tolerance). At `1e-11` it drops the second row. Kept: the
        // residuals, relative to the largest term, are a backward error (measured 0 and 6e-17;
        // bound 1e-12), and `x_1` is 9.1e-8 from 0.9, within the system's conditioning (1e10)
        // times the rounding (bound 1e-5).
        if Real::EPSILON > 1e-10 {
            // `f32`: a tolerance of 4.8e-5 puts both cases on the dropping side.
            return;
        }
        for (delta2, dropped) in [(1e-10, 0), (1e-11, 1)] {
            let delta = Real::sqrt(delta2);
            let mut jac = vec![0.0; 2 * JAC_ROW_STRIDE];
            jac[0] = 1.0;
            jac[JAC_ROW_STRIDE] = 1.0;
            jac[JAC_ROW_STRIDE + 1] = delta;
            for r in 0..2 {
                jac[JAC_ROW_STRIDE * r + 6..JAC_ROW_STRIDE * (r + 1)].fill(Real::NAN);
            }
            let mut mass = [0.0; 36];
            for i in 0..6 {
                mass[7 * i] = 1.0;
            }
            let p = Problem {
                nb: 1,
                specs: vec![JointBlockSpec {
                    rows: 2,
                    bodies: [Some(0), None],
                }],
                mass: vec![mass],
                jac,
                comp: vec![0.0; 2],
                f: vec![[0.3, -0.2, 0.1, 0.0, 0.5, -0.4]],
                // Consistent with both rows: `J x = g` for `x = (0.7, 0.9, ..)`.
                g: vec![0.7, 0.7 + delta * 0.9],
            };
            let (s, rep, x, l) = p.sparse_solve();
            assert!(s.pivoted);
            assert_eq!(rep.redundant_rows, dropped, "delta^2 = {delta2}");
            if dropped == 0 {
                let (eb, ej) = p.residual(&x, &l);
                assert!(eb < 1e-12 && ej < 1e-12, "delta^2 = {delta2}: {eb} {ej}");
                assert!((x[0][1] - 0.9).abs() < 1e-5, "{x:?}");
            } else {
                // The second row's multiplier is zero: `x_1` moves freely under its force.
                assert_eq!(l[1], 0.0);
                assert!((x[0][1] + 0.2).abs() < 1e-12, "{x:?}");
            }
            assert!((x[0][0] - 0.7).abs() < 1e-6, "{x:?}");
        }
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
