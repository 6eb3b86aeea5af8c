//! Four systems of the same structure factored at once, one per SIMD lane
//! ([`KktSolver::factor_lanes`]).
//!
//! The islands of a scene are often copies of one another (the mixed scene's arms: five
//! bodies, joints of 5, 3, 4, 5 and 5 rows). Their factorisations then run the same
//! operations on different values, which is what SIMD lanes are for: the assembly, the
//! unpivoted block steps, the Schur updates and the inversion of each pivot run on
//! [`Lanes`] over the same kernels as the scalar [`KktSolver::factor`], and each lane's
//! factors are unpacked into its own solver. Every lane runs the scalar operations in the same
//! order, so each solver ends up with the factors its own [`KktSolver::factor`] gives, to the
//! bit.
//!
//! What the lanes do not do, they leave to the scalar path: a joint block that the unpivoted
//! test rejects (it would be pivoted, and may drop rows), a body block that is not positive
//! definite, a non-finite input or pivot. Then [`KktSolver::factor_lanes`] returns `false`
//! with the four solvers untouched, and the caller factors each on its own (with its errors
//! and redundancy report).

use super::*;
use crate::solver::lane::{LANES, Lanes};

/// The lane values of a group of [`LANES`] solvers of the same structure (scratch of
/// [`KktSolver::factor_lanes`], kept from call to call so that it does not allocate).
/// Aligned to two cache lines: the pool's groups step on different threads with `parallel`,
/// and a solve writes its scratch vectors' lengths here.
#[derive(Clone, Debug)]
#[repr(align(128))]
pub(crate) struct KktLanes {
    num: Numeric<Lanes>,
    /// Identity permutations of every pivot, as the scalar unpivoted steps write them.
    perms: Vec<u8>,
    /// The stamps of the four factorisations `num` holds (see [`KktSolver::solve_lanes`]).
    stamps: [Stamp; LANES],
    /// A solve's right-hand sides in lanes (bodies flattened, joints).
    rhs_b: Vec<Lanes>,
    rhs_j: Vec<Lanes>,
}

impl Default for KktLanes {
    fn default() -> Self {
        Self {
            num: Numeric {
                diag: Vec::new(),
                scale: Vec::new(),
                offd: Vec::new(),
            },
            perms: Vec::new(),
            stamps: [(0, 0); LANES],
            rhs_b: Vec::new(),
            rhs_j: Vec::new(),
        }
    }
}

/// One system's right-hand side, solved in place: the bodies' and the joints' parts (see
/// [`KktSolver::solve`]).
pub(crate) type Rhs<'a> = (&'a mut [[Real; 6]], &'a mut [Real]);

impl Inputs<Lanes> for [FactorInputs<'_>; LANES] {
    #[inline(always)]
    fn mass(&self, b: usize) -> impl Fn(usize) -> Lanes + '_ {
        let [m0, m1, m2, m3] = [0, 1, 2, 3].map(|l| &self[l].mass[b]);
        move |k| Lanes::new([m0[k], m1[k], m2[k], m3[k]])
    }
    #[inline(always)]
    fn jac_rows<const M: usize>(&self, base: usize) -> [[Lanes; BODY_DOFS]; M] {
        let len = JAC_ROW_STRIDE * (M - 1) + BODY_DOFS;
        let [j0, j1, j2, j3] = [0, 1, 2, 3].map(|l| &self[l].jac[base..base + len]);
        let mut rows = [[Lanes::ZERO; BODY_DOFS]; M];
        for (i, row) in rows.iter_mut().enumerate() {
            for (c, x) in row.iter_mut().enumerate() {
                let k = JAC_ROW_STRIDE * i + c;
                *x = Lanes::new([j0[k], j1[k], j2[k], j3[k]]);
            }
        }
        rows
    }
    #[inline(always)]
    fn jac(&self, base: usize) -> impl Fn(usize) -> Lanes + '_ {
        let j: [&[Real]; LANES] = std::array::from_fn(|l| &self[l].jac[base..]);
        move |i| Lanes::gather(|l| j[l][i])
    }
    #[inline(always)]
    fn compliance<const N: usize>(&self, r0: usize) -> [Lanes; N] {
        let [c0, c1, c2, c3] = [0, 1, 2, 3].map(|l| &self[l].compliance[r0..r0 + N]);
        let mut out = [Lanes::ZERO; N];
        for (i, x) in out.iter_mut().enumerate() {
            *x = Lanes::new([c0[i], c1[i], c2[i], c3[i]]);
        }
        out
    }
}

impl KktSolver {
    /// Whether `other` was built for the same bodies and joint blocks with the same redundancy
    /// tolerance: [`Self::new`] is a function of those, so both have the same pivots, blocks,
    /// Schur updates and assembly, and can be factored in lanes together.
    pub(crate) fn same_structure(&self, other: &KktSolver) -> bool {
        self.nb == other.nb && self.shape.specs == other.shape.specs && self.tol == other.tol
    }

    /// Factors the [`LANES`] systems `inputs` (each as [`Self::factor`] reads its `mass`, `jac`
    /// and `compliance`) of `solvers`, which have one structure ([`Self::same_structure`]), in
    /// lanes (see the module docs): afterwards each solver holds the factors its own
    /// [`Self::factor`] gives, bit for bit, and no row is dropped. Returns `false` where a
    /// lane needs the scalar path (see the module docs): the solvers are then unchanged and
    /// each is to be factored by [`Self::factor`] (the lanes hold no factors then).
    pub(crate) fn factor_lanes(
        solvers: [&mut KktSolver; LANES],
        lanes: &mut KktLanes,
        inputs: [FactorInputs<'_>; LANES],
    ) -> bool {
        // Whatever happens below, the lanes no longer hold any solver's factors.
        lanes.stamps = [(0, 0); LANES];
        let t = &*solvers[0];
        let rows = t.num_rows();
        if inputs.iter().any(|x| {
            x.mass.len() != t.nb
                || x.jac.len() != JAC_ROW_STRIDE * rows
                || x.compliance.len() != rows
        }) {
            return false;
        }
        let num = &mut lanes.num;
        for (v, n) in [
            (&mut num.diag, t.num.diag.len()),
            (&mut num.scale, t.num.scale.len()),
            (&mut num.offd, t.num.offd.len()),
        ] {
            v.resize(n, Lanes::ZERO);
        }
        let shape = &t.shape;
        let np = shape.pivots.len();
        for c0 in (0..np).step_by(ASSEMBLY_CHUNK) {
            let c1 = (c0 + ASSEMBLY_CHUNK).min(np);
            let mut ok = true;
            for &item in &shape.asm[shape.asm_start[c0]..shape.asm_start[c1]] {
                ok &= assemble_item(shape, num, item, &inputs);
            }
            if !ok {
                return false;
            }
            for pi in c0..c1 {
                let pv = &shape.pivots[pi];
                let mut whole = true;
                // A tree's pivot with its one block (see `by_pair`), else any.
                if !by_pair!(pv, N, M => whole = eliminate_lanes::<N, M>(shape, num, &t.perms, pi, t.tol))
                {
                    whole = by_dim!(pv.dim, N => eliminate_lanes::<N, 0>(shape, num, &t.perms, pi, t.tol));
                }
                if !whole {
                    return false;
                }
            }
        }
        let perms = &mut lanes.perms;
        perms.resize(t.perms.len(), 0);
        for pv in &shape.pivots {
            for (i, p) in perms[pv.scale_off..pv.scale_off + pv.dim]
                .iter_mut()
                .enumerate()
            {
                // `i < dim <= MAX_DIM`, which fits a byte.
                *p = i as u8;
            }
        }
        let [s0, s1, s2, s3] = solvers;
        // The scales are not unpacked: nothing reads them after the factorisation (its next
        // assembly writes them first).
        unpack(
            &num.diag,
            [
                &mut s0.num.diag,
                &mut s1.num.diag,
                &mut s2.num.diag,
                &mut s3.num.diag,
            ],
        );
        unpack(
            &num.offd,
            [
                &mut s0.num.offd,
                &mut s1.num.offd,
                &mut s2.num.offd,
                &mut s3.num.offd,
            ],
        );
        for (s, stamp) in [s0, s1, s2, s3].into_iter().zip(&mut lanes.stamps) {
            s.perms.copy_from_slice(perms);
            s.dropped.clear();
            s.pivoted = false;
            s.factored = true;
            s.stamp.1 += 1;
            *stamp = s.stamp;
        }
        true
    }

    /// Solves the systems of `solvers` in lanes, as [`Self::solve`] solves each (the same
    /// operations in each lane: the same result to the bit), where `lanes` holds their
    /// current factors (the last [`Self::factor_lanes`] of these four solvers, none of them
    /// factored since). A `None` lane is solved for a zero right-hand side and dropped.
    /// Returns `false`, touching nothing, where `lanes` does not hold their factors or a
    /// right-hand side has the wrong length: each is then to be solved by [`Self::solve`].
    pub(crate) fn solve_lanes(
        solvers: [&KktSolver; LANES],
        lanes: &mut KktLanes,
        mut rhs: [Option<Rhs<'_>>; LANES],
    ) -> bool {
        let t = solvers[0];
        let (nb, rows) = (t.nb, t.num_rows());
        let held = solvers
            .iter()
            .zip(&lanes.stamps)
            .all(|(s, &stamp)| s.factored && s.stamp == stamp);
        let fits = rhs
            .iter()
            .flatten()
            .all(|(b, j)| b.len() == nb && j.len() == rows);
        if !held || !fits {
            return false;
        }
        let b: [Option<&[Real]>; LANES] =
            std::array::from_fn(|l| rhs[l].as_ref().map(|(b, _)| b.as_flattened()));
        let j: [Option<&[Real]>; LANES] =
            std::array::from_fn(|l| rhs[l].as_ref().map(|(_, j)| &j[..]));
        gather(&mut lanes.rhs_b, b, 6 * nb);
        gather(&mut lanes.rhs_j, j, rows);
        substitute::<Lanes, false>(
            &t.shape,
            &lanes.num,
            &t.perms,
            &mut lanes.rhs_b,
            &mut lanes.rhs_j,
        );
        for (l, slot) in rhs.iter_mut().enumerate() {
            let Some((b, j)) = slot else { continue };
            for (x, v) in b.as_flattened_mut().iter_mut().zip(&lanes.rhs_b) {
                *x = v.as_array()[l];
            }
            for (x, v) in j.iter_mut().zip(&lanes.rhs_j) {
                *x = v.as_array()[l];
            }
        }
        true
    }
}

/// The first `n` entries of `src[l]` into lane `l` of `dst` (0 for a `None`).
fn gather(dst: &mut Vec<Lanes>, src: [Option<&[Real]>; LANES], n: usize) {
    const NONE: &[Real] = &[];
    let [s0, s1, s2, s3] = src.map(|x| x.map_or(NONE, |x| &x[..n]));
    dst.clear();
    dst.extend((0..n).map(|i| {
        let at = |s: &[Real]| s.get(i).copied().unwrap_or(0.0);
        Lanes::new([at(s0), at(s1), at(s2), at(s3)])
    }));
}

/// Lane `l` of `src` into `dst[l]` (each at least as long).
fn unpack(src: &[Lanes], dst: [&mut Vec<Real>; LANES]) {
    let n = src.len();
    let [d0, d1, d2, d3] = dst.map(|d| &mut d[..n]);
    for (i, v) in src.iter().enumerate() {
        // Read in place (a copy of the value first went through the stack).
        let x = v.as_array();
        d0[i] = x[0];
        d1[i] = x[1];
        d2[i] = x[2];
        d3[i] = x[3];
    }
}

/// Factors pivot `pi` (dimension `N`) in lanes, as [`KktSolver::eliminate`] does where its
/// block stands unpivoted with full rank, and applies its Schur updates. Returns `false`
/// (leaving the lanes half done) where some lane's block would not: not positive definite
/// (a body), rejected by the unpivoted test (a joint), or non-finite. `M`: as for
/// [`KktSolver::eliminate`].
fn eliminate_lanes<const N: usize, const M: usize>(
    shape: &Shape,
    num: &mut Numeric<Lanes>,
    perms: &[u8],
    pi: usize,
    tol: Real,
) -> bool {
    let pv = shape.pivots[pi];
    let body = matches!(pv.node, KktNode::Body(_));
    let thresh = if body { 64.0 * Real::EPSILON } else { tol };
    let diag = &mut num.diag[pv.diag_off..pv.diag_off + tri(N)];
    let scale = &mut num.scale[pv.scale_off..pv.scale_off + N];
    let mut st = Ldl::<Lanes, N>::new(diag, scale);
    let whole = if body {
        matches!(st.spd(thresh), Ok(rank) if rank == N)
    } else {
        st.definite(thresh)
    };
    if !whole || not_finite(&st.dinv).is_some() {
        return false;
    }
    scale.copy_from_slice(&st.dinv);
    if M > 0 {
        schur_one_lanes::<N, M>(shape, num, perms, &pv);
    } else {
        schur_update::<Lanes, N, false>(shape, num, perms, &pv);
    }
    invert_and_pack::<Lanes, N>(
        &mut num.diag[pv.diag_off..pv.diag_off + tri(N)],
        &num.scale[pv.scale_off..pv.scale_off + N],
    );
    true
}

/// [`schur_one`] in lanes, as a function of its own: inlined into [`eliminate_lanes`] (one
/// instance per pivot and block size), it left the iterators of the block update as calls
/// (+24 % instructions on the mixed scene).
#[inline(never)]
fn schur_one_lanes<const N: usize, const M: usize>(
    shape: &Shape,
    num: &mut Numeric<Lanes>,
    perms: &[u8],
    pv: &Pivot,
) {
    schur_one::<Lanes, N, M, false>(shape, num, perms, pv);
}
