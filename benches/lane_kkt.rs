//! A probe for issue 15 (`cargo bench --bench lane_kkt`): what stepping identical islands in
//! lockstep, four to a SIMD register, gives a KKT factorisation and its solves with the data
//! already in lanes and in cache (the ceiling: the crate's own lanes, `src/solver/kkt/lanes.rs`,
//! gather their inputs from four islands and unpack the factors, and its solves are still
//! scalar). Not the crate's solver: a plain block `LDLᵀ` of one arm of the mixed scene
//! (`studies::benchmarks::mixed`: five bodies in a chain from the ground, joints of 5, 3, 4, 5
//! and 5 rows), written once over a lane type and run
//!
//! - `scalar`: on `f64`, one arm after another (four calls per iteration);
//! - `lanes`: on `wide::f64x4`, the four arms in the four lanes (one call per iteration).
//!
//! Each iteration factors four arms, or solves each of them three times (the mixed scene's
//! islands take 1.65 solves a substep, the chains up to 2.75).
//! Before timing, the bench checks that every lane's factors equal the scalar ones to the bit
//! (each lane runs the same operations in the same order) and that a scalar solve satisfies
//! the assembled KKT system (`[M Jᵀ; J -C] x = b`) to 1e-12.
//!
//! The arms' inputs are random (seeded): bead masses 0.1 kg and inertias 1e-3 kg m², Jacobian
//! rows of unit-size linear and 0.1-size angular parts, compliance 1e-10 (the crate's tree
//! regularisation scale). The elimination order is the crate's on a chain (leaf body, its
//! joint to the parent, the parent body, ...), so the work per arm is the same as its
//! factorisation's, without its rank tests, scales and pivoting (those would run per lane the
//! same way, with a per-lane fallback where a block needs pivoting).
#![allow(
    missing_docs,
    reason = "criterion_group! generates an undocumented function"
)]
#![allow(
    clippy::needless_range_loop,
    reason = "index loops over small fixed blocks, as in the solver's kernels"
)]

use std::hint::black_box;
use std::ops::{Add, Div, Mul, Neg, Sub};
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use wide::f64x4;

/// The arithmetic the kernels need: `f64` (one arm) or `f64x4` (four arms, one per lane).
trait Lane:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    fn splat(x: f64) -> Self;
}

impl Lane for f64 {
    fn splat(x: f64) -> Self {
        x
    }
}

impl Lane for f64x4 {
    fn splat(x: f64) -> Self {
        f64x4::splat(x)
    }
}

/// Rows of joints 0 to 4 (joint `b` joins body `b` to body `b - 1`, joint 0 to the ground).
const ROWS: [usize; 5] = [5, 3, 4, 5, 5];

/// One arm's KKT inputs: per body its 6x6 mass block (row-major, lower triangle read), per
/// joint its rows' blocks on its child body `b` (`jc`) and on its parent `b - 1` (`jp`), each
/// `rows x 6` row-major, and its rows' compliances.
#[derive(Clone, Copy)]
struct Arm<T> {
    mass: [[T; 36]; 5],
    jc: [[T; 30]; 5],
    jp: [[T; 30]; 5],
    compliance: [[T; 5]; 5],
}

impl<T: Lane> Arm<T> {
    fn zero() -> Self {
        let z = T::splat(0.0);
        Arm {
            mass: [[z; 36]; 5],
            jc: [[z; 30]; 5],
            jp: [[z; 30]; 5],
            compliance: [[z; 5]; 5],
        }
    }
}

/// The factors: per body `L` (unit lower, stride 6) and `D⁻¹`, `Y = L⁻¹ J_cᵀ` (6 x rows);
/// per joint `L_s`, `D_s⁻¹` of its Schur complement and `Z = L_s⁻¹ J_p` (rows x 6).
#[derive(Clone, Copy)]
struct Factors<T> {
    l: [[T; 36]; 5],
    dinv: [[T; 6]; 5],
    y: [[T; 30]; 5],
    ls: [[T; 25]; 5],
    dsinv: [[T; 5]; 5],
    z: [[T; 30]; 5],
}

impl<T: Lane> Factors<T> {
    fn zero() -> Self {
        let z = T::splat(0.0);
        Factors {
            l: [[z; 36]; 5],
            dinv: [[z; 6]; 5],
            y: [[z; 30]; 5],
            ls: [[z; 25]; 5],
            dsinv: [[z; 5]; 5],
            z: [[z; 30]; 5],
        }
    }
}

/// `LDLᵀ` of the leading `n x n` block of `a` (stride 6) in place: `L` below the diagonal,
/// `D` on it, `D⁻¹` into `dinv`.
fn ldl<T: Lane>(a: &mut [T; 36], n: usize, dinv: &mut [T]) {
    for k in 0..n {
        let mut d = a[k * 6 + k];
        for j in 0..k {
            d = d - a[k * 6 + j] * a[k * 6 + j] * a[j * 6 + j];
        }
        a[k * 6 + k] = d;
        let di = T::splat(1.0) / d;
        dinv[k] = di;
        for i in k + 1..n {
            let mut s = a[i * 6 + k];
            for j in 0..k {
                s = s - a[i * 6 + j] * a[k * 6 + j] * a[j * 6 + j];
            }
            a[i * 6 + k] = s * di;
        }
    }
}

/// Factors the arm from the leaf up: body `b`, then joint `b` (its Schur complement
/// `S = -C - J_c M_b⁻¹ J_cᵀ`), whose elimination updates the parent's block by
/// `-J_pᵀ S⁻¹ J_p`.
fn factor<T: Lane>(arm: &Arm<T>, f: &mut Factors<T>) {
    let mut mass = arm.mass;
    for b in (0..5).rev() {
        let m = ROWS[b];
        let mut l = mass[b];
        ldl(&mut l, 6, &mut f.dinv[b]);
        let mut y = [T::splat(0.0); 30];
        for r in 0..m {
            for i in 0..6 {
                let mut s = arm.jc[b][r * 6 + i];
                for j in 0..i {
                    s = s - l[i * 6 + j] * y[j * m + r];
                }
                y[i * m + r] = s;
            }
        }
        let mut s = [T::splat(0.0); 36];
        for r in 0..m {
            for q in 0..=r {
                let mut acc = if q == r {
                    -arm.compliance[b][r]
                } else {
                    T::splat(0.0)
                };
                for i in 0..6 {
                    acc = acc - y[i * m + r] * f.dinv[b][i] * y[i * m + q];
                }
                s[r * 6 + q] = acc;
            }
        }
        ldl(&mut s, m, &mut f.dsinv[b]);
        for r in 0..m {
            for q in 0..m {
                f.ls[b][r * 5 + q] = s[r * 6 + q];
            }
        }
        f.l[b] = l;
        f.y[b] = y;
        if b == 0 {
            continue;
        }
        let mut z = [T::splat(0.0); 30];
        for c in 0..6 {
            for r in 0..m {
                let mut acc = arm.jp[b][r * 6 + c];
                for q in 0..r {
                    acc = acc - s[r * 6 + q] * z[q * 6 + c];
                }
                z[r * 6 + c] = acc;
            }
        }
        for i in 0..6 {
            for j in 0..=i {
                let mut acc = T::splat(0.0);
                for r in 0..m {
                    acc = acc + z[r * 6 + i] * f.dsinv[b][r] * z[r * 6 + j];
                }
                mass[b - 1][i * 6 + j] = mass[b - 1][i * 6 + j] - acc;
            }
        }
        f.z[b] = z;
    }
}

/// Solves the arm's KKT system in place (`xb`: per body, `xj`: per joint's rows): forward
/// from the leaf, backward from the root.
fn solve<T: Lane>(f: &Factors<T>, xb: &mut [[T; 6]; 5], xj: &mut [[T; 5]; 5]) {
    for b in (0..5).rev() {
        let m = ROWS[b];
        let mut u = xb[b];
        for i in 0..6 {
            for j in 0..i {
                u[i] = u[i] - f.l[b][i * 6 + j] * u[j];
            }
        }
        xb[b] = u;
        let mut v = xj[b];
        for r in 0..m {
            for i in 0..6 {
                v[r] = v[r] - f.y[b][i * m + r] * (f.dinv[b][i] * u[i]);
            }
        }
        for r in 0..m {
            for q in 0..r {
                v[r] = v[r] - f.ls[b][r * 5 + q] * v[q];
            }
        }
        xj[b] = v;
        if b > 0 {
            for c in 0..6 {
                for r in 0..m {
                    xb[b - 1][c] = xb[b - 1][c] - f.z[b][r * 6 + c] * (f.dsinv[b][r] * v[r]);
                }
            }
        }
    }
    for b in 0..5 {
        let m = ROWS[b];
        let mut t = [T::splat(0.0); 5];
        for r in 0..m {
            let mut acc = xj[b][r];
            if b > 0 {
                for c in 0..6 {
                    acc = acc - f.z[b][r * 6 + c] * xb[b - 1][c];
                }
            }
            t[r] = f.dsinv[b][r] * acc;
        }
        for r in (0..m).rev() {
            for q in r + 1..m {
                t[r] = t[r] - f.ls[b][q * 5 + r] * t[q];
            }
        }
        xj[b] = t;
        let mut w = [T::splat(0.0); 6];
        for i in 0..6 {
            let mut acc = xb[b][i];
            for r in 0..m {
                acc = acc - f.y[b][i * m + r] * t[r];
            }
            w[i] = f.dinv[b][i] * acc;
        }
        for i in (0..6).rev() {
            for j in i + 1..6 {
                w[i] = w[i] - f.l[b][j * 6 + i] * w[j];
            }
        }
        xb[b] = w;
    }
}

/// A seeded arm (xorshift).
fn arm(seed: u64) -> Arm<f64> {
    let mut s = seed | 1;
    let mut rnd = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut a = Arm::zero();
    for b in 0..5 {
        for i in 0..3 {
            a.mass[b][i * 6 + i] = 0.1;
            a.mass[b][(3 + i) * 6 + 3 + i] = 1e-3;
        }
        for r in 0..ROWS[b] {
            for i in 0..6 {
                let size = if i < 3 { 1.0 } else { 0.1 };
                a.jc[b][r * 6 + i] = size * rnd();
                a.jp[b][r * 6 + i] = size * rnd();
            }
            a.compliance[b][r] = 1e-10;
        }
    }
    a
}

/// Four arms in the four lanes.
fn pack(arms: &[Arm<f64>; 4]) -> Arm<f64x4> {
    let lanes = |f: &dyn Fn(&Arm<f64>) -> f64| f64x4::from(arms.each_ref().map(f));
    let mut p = Arm::zero();
    for b in 0..5 {
        for i in 0..36 {
            p.mass[b][i] = lanes(&|a| a.mass[b][i]);
        }
        for i in 0..30 {
            p.jc[b][i] = lanes(&|a| a.jc[b][i]);
            p.jp[b][i] = lanes(&|a| a.jp[b][i]);
        }
        for i in 0..5 {
            p.compliance[b][i] = lanes(&|a| a.compliance[b][i]);
        }
    }
    p
}

/// The largest entry of `[M Jᵀ; J -C] x - b` for the arm (`M`, `J`, `C` as given).
fn kkt_residual(
    a: &Arm<f64>,
    xb: &[[f64; 6]; 5],
    xj: &[[f64; 5]; 5],
    b: (&[[f64; 6]; 5], &[[f64; 5]; 5]),
) -> f64 {
    let mut worst: f64 = 0.0;
    for k in 0..5 {
        for i in 0..6 {
            let mut v = -b.0[k][i];
            for j in 0..6 {
                v += a.mass[k][i.max(j) * 6 + i.min(j)] * xb[k][j];
            }
            for r in 0..ROWS[k] {
                v += a.jc[k][r * 6 + i] * xj[k][r];
            }
            if k < 4 {
                for r in 0..ROWS[k + 1] {
                    v += a.jp[k + 1][r * 6 + i] * xj[k + 1][r];
                }
            }
            worst = worst.max(v.abs());
        }
        for r in 0..ROWS[k] {
            let mut v = -b.1[k][r] - a.compliance[k][r] * xj[k][r];
            for i in 0..6 {
                v += a.jc[k][r * 6 + i] * xb[k][i];
                if k > 0 {
                    v += a.jp[k][r * 6 + i] * xb[k - 1][i];
                }
            }
            worst = worst.max(v.abs());
        }
    }
    worst
}

/// Lane `lane` of `lanes` equals `scalar` to the bit.
fn same(lane: usize, what: &str, lanes: &[f64x4], scalar: &[f64]) {
    for (i, (w, s)) in lanes.iter().zip(scalar).enumerate() {
        let w: [f64; 4] = (*w).into();
        assert_eq!(w[lane].to_bits(), s.to_bits(), "lane {lane}: {what}[{i}]");
    }
}

/// The lanes reproduce the scalar factors to the bit, and a scalar solve satisfies the
/// assembled system (the sum of a few dozen products of size 1 with round-off 1e-16 each,
/// amplified by the blocks' condition: 1e-12 leaves two to three orders of margin).
fn check(arms: &[Arm<f64>; 4]) {
    let packed = pack(arms);
    let mut fw = Factors::zero();
    factor(&packed, &mut fw);
    for (lane, a) in arms.iter().enumerate() {
        let mut f = Factors::zero();
        factor(a, &mut f);
        for b in 0..5 {
            same(lane, "L", &fw.l[b], &f.l[b]);
            same(lane, "D^-1", &fw.dinv[b], &f.dinv[b]);
            same(lane, "Y", &fw.y[b], &f.y[b]);
            same(lane, "Ls", &fw.ls[b], &f.ls[b]);
            same(lane, "Ds^-1", &fw.dsinv[b], &f.dsinv[b]);
            same(lane, "Z", &fw.z[b], &f.z[b]);
        }
        let rb = [[0.3, -0.2, 0.1, 0.05, 0.4, -0.6]; 5];
        let rj = [[0.7, -0.1, 0.2, 0.3, -0.5]; 5];
        let (mut xb, mut xj) = (rb, rj);
        solve(&f, &mut xb, &mut xj);
        let res = kkt_residual(a, &xb, &xj, (&rb, &rj));
        assert!(res < 1e-12, "lane {lane}: KKT residual {res:e}");
    }
}

fn bench(c: &mut Criterion) {
    let arms: [Arm<f64>; 4] =
        core::array::from_fn(|k| arm(0x9e37_79b9_7f4a_7c15 ^ (k as u64 * 7919)));
    check(&arms);
    let packed = pack(&arms);
    let mut group = c.benchmark_group("lane_kkt");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(2));
    let mut fs = [Factors::zero(); 4];
    group.bench_function("factor four arms/scalar", |b| {
        b.iter(|| {
            for (a, f) in arms.iter().zip(fs.iter_mut()) {
                factor(black_box(a), f);
            }
        });
    });
    let mut fw = Factors::zero();
    group.bench_function("factor four arms/lanes", |b| {
        b.iter(|| factor(black_box(&packed), &mut fw));
    });
    group.bench_function("three solves of four arms/scalar", |b| {
        b.iter(|| {
            for f in &fs {
                let (mut xb, mut xj) = ([[0.5; 6]; 5], [[0.25; 5]; 5]);
                for _ in 0..3 {
                    solve(black_box(f), &mut xb, &mut xj);
                }
                black_box((xb, xj));
            }
        });
    });
    group.bench_function("three solves of four arms/lanes", |b| {
        b.iter(|| {
            let (mut xb, mut xj) = ([[f64x4::splat(0.5); 6]; 5], [[f64x4::splat(0.25); 5]; 5]);
            for _ in 0..3 {
                solve(black_box(&fw), &mut xb, &mut xj);
            }
            black_box((xb, xj));
        });
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
