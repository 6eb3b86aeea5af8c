//! The benchmark scene builders of `rapier3d_mpc184::studies::benchmarks`: geometry, mobility, initial
//! energy and a first step.
//!
//! Checked for each scene (chain, A02 parallelogram four-bar, A04 Bricard, IFToMM slider-crank):
//! - which backends build it: trees (the chain) on both Rapier backends; loops (four-bar, Bricard,
//!   slider-crank) on the impulse backend only, the multibody backend answering
//!   `Error::Unsupported`; the slider-crank's universal joint is `Unsupported` on both Rapier
//!   backends, its spherical variant builds on the impulse backend;
//! - the joint gaps reported by the world at t = 0 (0 to 1e-12) and, since those are measured
//!   between frames that coincide at insertion by construction, an independent check that every
//!   joint node sits at the intended material points (rod ends, bead positions);
//! - the mobility, from the rank of the constraint Jacobian built from the library's own rows
//!   (`rows::RowKind::eval`) at the initial configuration: 1 for the four-bar (20 rows, rank 17)
//!   and for Bricard (30 rows, rank 29, where Gruebler's count gives 0), N for the chain, 2 for
//!   the spherical slider-crank (the rod's free spin); for Bricard a finite motion is traced along
//!   the null space (predictor step plus Gauss-Newton projection to |C| < 1e-12) to show that the
//!   mobility is not merely infinitesimal, and gravity does work along it (it moves from rest);
//! - the initial velocities are consistent: `J v0 = 0`;
//! - the initial total energy (world's kinetic + potential) against values computed by hand;
//! - one step on the impulse backend runs without NaN.
//!
//! Tolerances: the energies are sums of a few O(1..40) f64 products, so 1e-12 relative is
//! round-off with a margin of ~1000; rank decisions use a pivot threshold of 1e-9 while the
//! smallest accepted pivot is asserted to be above 1e-3 (a clear gap, stated with the test).
#![cfg(feature = "f64")]

use rapier3d_mpc184::math::rapier::dynamics::RigidBodyHandle;
use rapier3d_mpc184::math::{Matrix, Pose};
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::rows::{self, FramePair, RowKind};
use rapier3d_mpc184::studies::benchmarks::{self, Benchmark, RodSliderJoint};

const G: Real = 9.81;

fn settings(backend: Backend) -> WorldSettings {
    WorldSettings {
        backend,
        ..Default::default()
    }
}

fn assert_close(what: &str, got: Real, want: Real, rel: Real) {
    let err = (got - want).abs();
    assert!(
        err <= rel * want.abs().max(1e-300),
        "{what}: got {got:.15e}, want {want:.15e} (error {err:.2e})"
    );
}

fn assert_unsupported(r: Result<Benchmark, Error>, needle: &str) {
    match r {
        Err(Error::Unsupported { what, .. }) => {
            assert!(what.contains(needle), "`{what}` should mention `{needle}`");
        }
        Err(e) => panic!("expected Unsupported ({needle}), got {e}"),
        Ok(_) => panic!("expected Unsupported ({needle}), the scene built"),
    }
}

fn assert_initial_gaps_zero(b: &Benchmark) {
    for id in &b.joints {
        let out = b.world.output(*id).unwrap();
        assert!(out.gap <= 1e-12, "{id}: initial gap {:.2e} m", out.gap);
        assert!(
            out.angular_gap <= 1e-12,
            "{id}: initial angular gap {:.2e}",
            out.angular_gap
        );
    }
}

fn com(b: &Benchmark, h: RigidBodyHandle) -> Vector {
    b.world.physics.bodies[h].center_of_mass()
}

fn node(b: &Benchmark, k: usize) -> Vector {
    b.world.joint(b.joints[k]).unwrap().node1
}

/// Checks that joint `k`'s node is an end of the rod `h` of length `len` lying along `axis`.
fn assert_rod_end(b: &Benchmark, h: RigidBodyHandle, axis: Vector, len: Real, k: usize) {
    let d = node(b, k) - com(b, h);
    assert!(
        (d.length() - 0.5 * len).abs() <= 1e-12 && d.cross(axis).length() <= 1e-12,
        "joint {k}: node {} is not an end of the rod centred at {} along {axis}",
        node(b, k),
        com(b, h)
    );
}

/// The kinematic model of a scene at t = 0: the library's constraint rows on the bodies' poses.
struct Kinematics {
    bodies: Vec<RigidBodyHandle>,
    /// Centre of mass in each body's frame.
    local_com: Vec<Vector>,
    joints: Vec<KinJoint>,
}

struct KinJoint {
    /// Column block of the body at node I / node J (`None`: ground).
    body: [Option<usize>; 2],
    /// The joint frame in each body's frame (in world coordinates for the ground).
    frame: [Pose; 2],
    rows: Vec<RowKind>,
}

impl Kinematics {
    fn new(b: &Benchmark) -> Self {
        let bodies = b.bodies.clone();
        let poses: Vec<Pose> = bodies
            .iter()
            .map(|h| *b.world.physics.bodies[*h].position())
            .collect();
        let local_com = bodies
            .iter()
            .zip(&poses)
            .map(|(h, p)| p.inverse() * b.world.physics.bodies[*h].center_of_mass())
            .collect();
        let joints = b
            .joints
            .iter()
            .zip(&b.joint_bodies)
            .map(|(id, pair)| {
                let j = b.world.joint(*id).unwrap();
                assert_eq!(j.node1, j.node2, "the scenes use coincident nodes");
                let world_frame = Pose::from_parts(j.node1, j.axes1);
                let body = pair.map(|h| h.map(|h| bodies.iter().position(|x| *x == h).unwrap()));
                let frame = body.map(|i| match i {
                    Some(i) => poses[i].inverse() * world_frame,
                    None => world_frame,
                });
                KinJoint {
                    body,
                    frame,
                    rows: rows::lock_rows(j.kind.constrained())
                        .map(|(_, r)| r)
                        .collect(),
                }
            })
            .collect();
        Self {
            bodies,
            local_com,
            joints,
        }
    }

    fn initial_poses(&self, b: &Benchmark) -> Vec<Pose> {
        self.bodies
            .iter()
            .map(|h| *b.world.physics.bodies[*h].position())
            .collect()
    }

    fn ncols(&self) -> usize {
        6 * self.bodies.len()
    }

    /// Constraint values and Jacobian rows (on body velocities at the centres of mass).
    fn eval(&self, poses: &[Pose]) -> (Vec<Real>, Vec<Vec<Real>>) {
        let (mut c, mut jac) = (Vec::new(), Vec::new());
        for j in &self.joints {
            let world = |s: usize| match j.body[s] {
                Some(i) => (poses[i] * j.frame[s], poses[i] * self.local_com[i]),
                None => (j.frame[s], j.frame[s].translation),
            };
            let ((f1, c1), (f2, c2)) = (world(0), world(1));
            let fp = FramePair {
                p1: f1.translation,
                r1: Matrix::from_quat(f1.rotation),
                c1,
                p2: f2.translation,
                r2: Matrix::from_quat(f2.rotation),
                c2,
            };
            for r in &j.rows {
                let ev = r.eval(&fp);
                let mut row = vec![0.0; self.ncols()];
                for (s, blk) in [(0, ev.j1), (1, ev.j2)] {
                    if let Some(i) = j.body[s] {
                        for k in 0..3 {
                            row[6 * i + k] += blk[0][k];
                            row[6 * i + 3 + k] += blk[1][k];
                        }
                    }
                }
                c.push(ev.value);
                jac.push(row);
            }
        }
        (c, jac)
    }
}

/// Reduced row echelon form with partial pivoting: the rank, the smallest accepted pivot and a
/// basis of the null space.
fn null_space(jac: &[Vec<Real>], ncols: usize, tol: Real) -> (usize, Real, Vec<Vec<Real>>) {
    let mut a: Vec<Vec<Real>> = jac.to_vec();
    let (mut r, mut pivots, mut min_pivot) = (0, Vec::new(), Real::INFINITY);
    for c in 0..ncols {
        if r == a.len() {
            break;
        }
        let p = (r..a.len())
            .max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))
            .unwrap();
        if a[p][c].abs() <= tol {
            continue;
        }
        min_pivot = min_pivot.min(a[p][c].abs());
        a.swap(r, p);
        let inv = 1.0 / a[r][c];
        for v in a[r].iter_mut() {
            *v *= inv;
        }
        let pivot_row = a[r].clone();
        for (i, row) in a.iter_mut().enumerate() {
            let f = row[c];
            if i != r && f != 0.0 {
                for (x, p) in row.iter_mut().zip(&pivot_row) {
                    *x -= f * p;
                }
            }
        }
        pivots.push(c);
        r += 1;
    }
    let basis = (0..ncols)
        .filter(|c| !pivots.contains(c))
        .map(|f| {
            let mut x = vec![0.0; ncols];
            x[f] = 1.0;
            for (row, &pc) in pivots.iter().enumerate() {
                x[pc] = -a[row][f];
            }
            x
        })
        .collect();
    (r, min_pivot, basis)
}

/// Rank decision threshold: the Jacobian entries are O(1) (unit vectors, lever arms <= 1 m).
const RANK_TOL: Real = 1e-9;

/// Mobility at the initial configuration, with the rank and the smallest accepted pivot.
fn mobility(b: &Benchmark) -> (usize, usize, usize, Real) {
    let kin = Kinematics::new(b);
    let (_, jac) = kin.eval(&kin.initial_poses(b));
    let (rank, min_pivot, basis) = null_space(&jac, kin.ncols(), RANK_TOL);
    (jac.len(), rank, basis.len(), min_pivot)
}

/// The bodies' initial velocities stacked as the Jacobian's columns expect.
fn velocities(b: &Benchmark) -> Vec<Real> {
    let mut v = Vec::new();
    for h in &b.bodies {
        let (lin, ang) = b.world.body_velocity(*h).unwrap();
        v.extend([lin.x, lin.y, lin.z, ang.x, ang.y, ang.z]);
    }
    v
}

fn max_abs_jv(b: &Benchmark) -> Real {
    let kin = Kinematics::new(b);
    let (_, jac) = kin.eval(&kin.initial_poses(b));
    let v = velocities(b);
    jac.iter()
        .map(|row| row.iter().zip(&v).map(|(a, b)| a * b).sum::<Real>().abs())
        .fold(0.0, Real::max)
}

/// Bound on the joint gap after one default step (dt = 1/60 s, 4 substeps) from a consistent
/// state: a joint that did nothing would let a body fall `g dt^2 / 2` = 1.4 mm; Rapier's
/// velocity-level solver leaves O(h^2) (measured 0.4 to 1.0 mm, shrinking 16x per 4x substeps).
const FREE_FALL: Real = 0.5 * G / 3600.0;

fn step_once_finite(b: &mut Benchmark) -> Real {
    b.world.step().unwrap();
    for h in &b.bodies {
        let rb = &b.world.physics.bodies[*h];
        assert!(rb.translation().is_finite() && rb.rotation().is_finite());
        assert!(rb.linvel().is_finite() && rb.angvel().is_finite());
    }
    assert!(b.energy().is_finite() && b.probe_position().is_finite());
    b.max_gap().unwrap()
}

fn chain_default(backend: Backend, n: usize, ratio: Real) -> Benchmark {
    benchmarks::chain(
        settings(backend),
        n,
        benchmarks::CHAIN_LINK_LENGTH,
        benchmarks::CHAIN_LINK_MASS,
        ratio,
        20.0_f64.to_radians(),
    )
    .unwrap()
}

#[test]
fn chain_builds_on_both_backends_with_hand_energy() {
    let cos20 = 20.0_f64.to_radians().cos();
    // N = 10, a = 0.1 m: bead k at d_k = 0.1 (k + 1); sum m d = 0.01 * 0.1 * 55 (+ the end bead's
    // extra 999 * 0.01 kg at 1 m for the ratio 1000).
    for (ratio, sum_md) in [(1.0, 0.055), (1000.0, 0.055 + 9.99)] {
        for backend in [Backend::RapierImpulse, Backend::RapierMultibody] {
            let b = chain_default(backend, 10, ratio);
            assert_eq!((b.bodies.len(), b.joints.len()), (10, 10));
            assert_initial_gaps_zero(&b);
            // Geometry: joint k at bead k - 1 (the origin for k = 0), beads 0.1 m apart along
            // the 20 deg line, all straight.
            let dir = Vector::new(
                20.0_f64.to_radians().sin(),
                -20.0_f64.to_radians().cos(),
                0.0,
            );
            for k in 0..10 {
                let bead = com(&b, b.bodies[k]);
                let expect = dir * (0.1 * (k + 1) as Real);
                assert!((bead - expect).length() <= 1e-15, "bead {k} at {bead}");
                let pivot = if k == 0 {
                    Vector::ZERO
                } else {
                    com(&b, b.bodies[k - 1])
                };
                assert!((node(&b, k) - pivot).length() <= 1e-15, "joint {k}");
            }
            let m_end = b.world.physics.bodies[b.bodies[9]].mass();
            assert_close("end mass", m_end, 0.01 * ratio, 1e-12);
            let e0 = -G * cos20 * sum_md;
            assert_close("E0", b.energy(), e0, 1e-12);
            assert_close("b.initial_energy", b.initial_energy, e0, 1e-12);
            assert_close("E_ref", b.energy_scale, G * (1.0 - cos20) * sum_md, 1e-12);
            assert_eq!(b.world.kinetic_energy(), 0.0, "released at rest");
            // A tree: 5 rows per joint, all independent, one DOF per link.
            let (rows, rank, nullity, min_pivot) = mobility(&b);
            assert_eq!((rows, rank, nullity), (50, 50, 10));
            assert!(min_pivot > 1e-3, "smallest pivot {min_pivot:.2e}");
        }
    }
}

#[test]
fn chain_steps_on_both_backends() {
    for backend in [Backend::RapierImpulse, Backend::RapierMultibody] {
        let mut b = chain_default(backend, 10, 1.0);
        let gap = step_once_finite(&mut b);
        println!("chain {}: gap after one step {gap:.2e} m", backend.name());
        assert!(gap <= FREE_FALL, "gap after one step {gap:.2e} m");
        assert!(b.world.kinetic_energy() > 0.0);
    }
}

#[test]
fn chain_rejects_bad_input() {
    let s = settings(Backend::RapierImpulse);
    let bad = [
        benchmarks::chain(s, 0, 0.1, 0.01, 1.0, 0.3),
        benchmarks::chain(s, 3, -0.1, 0.01, 1.0, 0.3),
        benchmarks::chain(s, 3, 0.1, 0.0, 1.0, 0.3),
        benchmarks::chain(s, 3, 0.1, 0.01, Real::NAN, 0.3),
        benchmarks::chain(s, 3, 0.1, 0.01, 1.0, Real::INFINITY),
    ];
    for r in bad {
        assert!(matches!(r, Err(Error::InvalidSetting { .. })));
    }
}

#[test]
fn four_bar_is_impulse_only_and_consistent() {
    assert_unsupported(
        benchmarks::four_bar_parallelogram(settings(Backend::RapierMultibody)),
        "closes a loop",
    );
    let b = benchmarks::four_bar_parallelogram(settings(Backend::RapierImpulse)).unwrap();
    assert_eq!((b.bodies.len(), b.joints.len()), (3, 4));
    assert_initial_gaps_zero(&b);
    let [crank, coupler, rocker] = [b.bodies[0], b.bodies[1], b.bodies[2]];
    // Ground pivots (0,0), (1,0); B0 = (0,1), B1 = (1,1); each joint at an end of its links.
    let expect = [
        Vector::ZERO,
        Vector::new(0.0, 1.0, 0.0),
        Vector::new(1.0, 1.0, 0.0),
        Vector::new(1.0, 0.0, 0.0),
    ];
    for (k, x) in expect.iter().enumerate() {
        assert_eq!(node(&b, k), *x, "joint {k}");
    }
    for (h, axis, ks) in [
        (crank, Vector::Y, [0, 1]),
        (coupler, Vector::X, [1, 2]),
        (rocker, Vector::Y, [2, 3]),
    ] {
        for k in ks {
            assert_rod_end(&b, h, axis, 1.0, k);
        }
    }
    assert_eq!(b.probe_position(), Vector::new(0.0, 1.0, 0.0));
    assert!((b.probe_velocity() - Vector::X).length() <= 1e-15);
    // Kinetic: crank and rocker (1/2)(1/12 + 1/4) 1^2 each, coupler (1/2) 1 1^2; potential
    // 9.81 (0.5 + 1 + 0.5). The largest kinetic energy (crank down) adds 2 * 19.62 J.
    let e0 = 1.0 / 6.0 + 1.0 / 6.0 + 0.5 + 19.62;
    assert_close("E0", b.energy(), e0, 1e-12);
    assert_close(
        "E0 (accuracy-and-speed.md: 20.45 J)",
        e0,
        20.453333333333333,
        1e-15,
    );
    assert_close("b.initial_energy", b.initial_energy, e0, 1e-12);
    assert_close("energy scale", b.energy_scale, e0 + 19.62, 1e-12);
    // 4 revolute-z joints = 20 rows on 18 DOFs, rank 17: one redundant row, mobility 1.
    let (rows, rank, nullity, min_pivot) = mobility(&b);
    assert_eq!((rows, rank, nullity), (20, 17, 1));
    assert!(min_pivot > 1e-3, "smallest pivot {min_pivot:.2e}");
    let jv = max_abs_jv(&b);
    assert!(
        jv <= 1e-14,
        "initial velocities violate the joints: |J v| = {jv:.2e}"
    );
}

#[test]
fn four_bar_steps_on_impulse() {
    let mut b = benchmarks::four_bar_parallelogram(settings(Backend::RapierImpulse)).unwrap();
    let gap = step_once_finite(&mut b);
    let de = b.energy_error();
    println!("four-bar: gap {gap:.2e} m, dE/E_scale {de:+.2e} after one step");
    // The energy moves by the dissipation of one step: measured -8.8e-5 of the scale.
    assert!(gap <= FREE_FALL, "gap {gap:.2e} m");
    assert!(de.abs() <= 1e-2, "energy error {de:.2e}");
}

#[test]
fn bricard_is_impulse_only_and_consistent() {
    assert_unsupported(
        benchmarks::bricard(settings(Backend::RapierMultibody)),
        "closes a loop",
    );
    let b = benchmarks::bricard(settings(Backend::RapierImpulse)).unwrap();
    assert_eq!((b.bodies.len(), b.joints.len()), (5, 6));
    assert_initial_gaps_zero(&b);
    let points = [
        Vector::new(0.0, 0.0, 0.0),
        Vector::new(1.0, 0.0, 0.0),
        Vector::new(1.0, -1.0, 0.0),
        Vector::new(1.0, -1.0, 1.0),
        Vector::new(0.0, -1.0, 1.0),
        Vector::new(0.0, 0.0, 1.0),
    ];
    let axes = [
        Vector::Y,
        Vector::Z,
        Vector::X,
        Vector::Y,
        Vector::Z,
        Vector::X,
    ];
    for k in 0..6 {
        let j = b.world.joint(b.joints[k]).unwrap();
        assert_eq!(j.node1, points[k], "joint {k}");
        // MPC184 revolute z: the hinge is e3 of the local system.
        let e3 = j.axes1 * Vector::Z;
        assert!((e3 - axes[k]).length() <= 1e-15, "joint {k}: axis {e3}");
    }
    for r in 0..5 {
        let along = (points[r + 1] - points[r]).abs();
        assert_rod_end(&b, b.bodies[r], along, 1.0, r);
        assert_rod_end(&b, b.bodies[r], along, 1.0, r + 1);
        // Each rod's two hinge axes are perpendicular to each other and to the rod.
        assert_eq!(axes[r].dot(axes[r + 1]), 0.0);
        assert_eq!(axes[r].dot(along) + axes[r + 1].dot(along), 0.0);
    }
    assert_eq!(b.probe_position(), Vector::new(1.0, -1.0, 0.0));
    // At rest; rod centres at heights 0, -0.5, -1, -1, -0.5.
    assert_eq!(b.world.kinetic_energy(), 0.0);
    assert_close("E0", b.energy(), -G * 3.0, 1e-12);
    assert_close("b.initial_energy", b.initial_energy, -29.43, 1e-12);
    // Gruebler: 6 x 5 DOFs - 6 x 5 rows = 0; the rank is 29: mobility 1.
    let (rows, rank, nullity, min_pivot) = mobility(&b);
    assert_eq!((rows, rank, nullity), (30, 29, 1));
    assert!(min_pivot > 1e-3, "smallest pivot {min_pivot:.2e}");
}

/// Traces Bricard's motion along the null space of the constraint Jacobian: a predictor step of
/// `h` (P3 travel) along the null vector, then Gauss-Newton projection back onto `C = 0`. A
/// mechanism that is only infinitesimally mobile would be pulled back to its start every step;
/// here P3 travels on, and the mobility stays 1 along the way.
#[test]
fn bricard_moves_finitely_and_gravity_drives_it() {
    let b = benchmarks::bricard(settings(Backend::RapierImpulse)).unwrap();
    let kin = Kinematics::new(&b);
    let mut poses = kin.initial_poses(&b);
    let masses: Vec<Real> = b
        .bodies
        .iter()
        .map(|h| b.world.physics.bodies[*h].mass())
        .collect();
    let p3_local = b.probe.local;
    let p3_body = 1; // rod 2
    let p3 = |poses: &[Pose]| poses[p3_body] * p3_local;
    let start = p3(&poses);
    let (h, steps) = (0.02, 50);
    let mut prev: Option<Vec<Real>> = None;
    let mut path = 0.0;
    for step in 0..steps {
        let (_, jac) = kin.eval(&poses);
        let (rank, _, basis) = null_space(&jac, kin.ncols(), RANK_TOL);
        assert_eq!((rank, basis.len()), (29, 1), "step {step}: rank {rank}");
        let mut z = basis.into_iter().next().unwrap();
        // Scale to unit P3 speed; keep going the same way.
        let x3 = p3(&poses);
        let (v, w) = (
            Vector::new(z[6], z[7], z[8]),
            Vector::new(z[9], z[10], z[11]),
        );
        let c3 = poses[p3_body] * kin.local_com[p3_body];
        let speed = (v + w.cross(x3 - c3)).length();
        assert!(
            speed > 1e-6,
            "step {step}: P3 does not move along the null space"
        );
        let mut s = 1.0 / speed;
        if let Some(p) = &prev
            && p.iter().zip(&z).map(|(a, b)| a * b).sum::<Real>() < 0.0
        {
            s = -s;
        }
        z.iter_mut().for_each(|x| *x *= s);
        if step == 0 {
            // Power of gravity along the unit-P3-speed motion (N): nonzero, so the mechanism
            // accelerates from rest (sum m g . v_com).
            let power: Real = (0..5).map(|i| masses[i] * -G * z[6 * i + 1]).sum();
            println!("Bricard: gravity force along the motion {power:.4} N per m/s of P3");
            assert!(power.abs() > 1.0, "gravity does no work: {power:.2e}");
        }
        let before = p3(&poses);
        advance(&mut poses, &kin, &z, h);
        project(&kin, &mut poses);
        path += (p3(&poses) - before).length();
        prev = Some(z);
    }
    let travel = (p3(&poses) - start).length();
    println!("Bricard: P3 path {path:.3} m, net displacement {travel:.3} m in {steps} steps");
    // The projection only removes O(h^2) per step: the path is ~ steps * h = 1 m.
    assert!(path > 0.9 * steps as Real * h, "path {path:.3} m");
    assert!(travel > 0.3, "P3 came back: net {travel:.3} m");
}

/// Moves the bodies by `h` times the body velocities `z` (rotations by the exponential map).
fn advance(poses: &mut [Pose], kin: &Kinematics, z: &[Real], h: Real) {
    for (i, p) in poses.iter_mut().enumerate() {
        let v = Vector::new(z[6 * i], z[6 * i + 1], z[6 * i + 2]);
        let w = Vector::new(z[6 * i + 3], z[6 * i + 4], z[6 * i + 5]);
        let com = *p * kin.local_com[i];
        let rot = Rotation::from_scaled_axis(w * h);
        // Turn about the centre of mass, then move the centre of mass.
        let new_rot = (rot * p.rotation).normalize();
        let new_com = com + v * h;
        let t = new_com - new_rot * kin.local_com[i];
        *p = Pose::from_parts(t, new_rot);
    }
}

/// Gauss-Newton projection onto `C = 0` with the minimum-norm step
/// `dq = -J^T (J J^T + mu I)^-1 C` (the regularisation handles the redundant row).
fn project(kin: &Kinematics, poses: &mut [Pose]) {
    for _ in 0..30 {
        let (c, jac) = kin.eval(poses);
        let err = c.iter().fold(0.0 as Real, |m, x| m.max(x.abs()));
        if err <= 1e-12 {
            return;
        }
        let m = c.len();
        let mut a = vec![vec![0.0; m + 1]; m];
        for i in 0..m {
            for k in 0..m {
                a[i][k] = jac[i].iter().zip(&jac[k]).map(|(x, y)| x * y).sum();
            }
            a[i][i] += 1e-12;
            a[i][m] = -c[i];
        }
        let y = solve(a);
        let dq: Vec<Real> = (0..kin.ncols())
            .map(|col| (0..m).map(|i| jac[i][col] * y[i]).sum())
            .collect();
        advance(poses, kin, &dq, 1.0);
    }
    let (c, _) = kin.eval(poses);
    let err = c.iter().fold(0.0 as Real, |m, x| m.max(x.abs()));
    panic!("projection did not converge: |C| = {err:.2e}");
}

/// Gaussian elimination with partial pivoting on an augmented matrix `[A | b]`.
fn solve(mut a: Vec<Vec<Real>>) -> Vec<Real> {
    let n = a.len();
    for c in 0..n {
        let p = (c..n)
            .max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))
            .unwrap();
        a.swap(c, p);
        let pivot_row = a[c].clone();
        for row in a.iter_mut().skip(c + 1) {
            let f = row[c] / pivot_row[c];
            for (x, p) in row.iter_mut().zip(&pivot_row).skip(c) {
                *x -= f * p;
            }
        }
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let s: Real = (i + 1..n).map(|k| a[i][k] * x[k]).sum();
        x[i] = (a[i][n] - s) / a[i][i];
    }
    x
}

#[test]
fn bricard_steps_on_impulse() {
    let mut b = benchmarks::bricard(settings(Backend::RapierImpulse)).unwrap();
    let gap = step_once_finite(&mut b);
    let de = b.energy_error();
    println!("Bricard: gap {gap:.2e} m, dE/E_scale {de:+.2e} after one step");
    // Measured: gap 9.7e-4 m, energy -3.3e-4 of the scale.
    assert!(gap <= FREE_FALL, "gap {gap:.2e} m");
    assert!(de.abs() <= 1e-2, "energy error {de:.2e}");
    assert!(
        b.world.kinetic_energy() > 0.0,
        "Bricard did not start moving"
    );
}

#[test]
fn slider_crank_universal_is_unsupported_on_rapier() {
    for backend in [Backend::RapierImpulse, Backend::RapierMultibody] {
        assert_unsupported(benchmarks::slider_crank(settings(backend)), "universal");
    }
    // The spherical variant still closes a loop.
    assert_unsupported(
        benchmarks::slider_crank_with(
            settings(Backend::RapierMultibody),
            RodSliderJoint::Spherical,
        ),
        "closes a loop",
    );
}

#[test]
fn slider_crank_spherical_variant_is_consistent() {
    let b =
        benchmarks::slider_crank_with(settings(Backend::RapierImpulse), RodSliderJoint::Spherical)
            .unwrap();
    assert_eq!((b.bodies.len(), b.joints.len()), (3, 4));
    assert_initial_gaps_zero(&b);
    let [crank, rod, slider] = [b.bodies[0], b.bodies[1], b.bodies[2]];
    let (pa, pb, pc) = (
        Vector::new(0.0, 0.1, 0.12),
        Vector::new(0.0, 0.1, 0.2),
        Vector::new(0.2, 0.0, 0.0),
    );
    // x_C = sqrt(0.3^2 - 0.1^2 - 0.2^2) = 0.2 up to round-off.
    for (k, x) in [pa, pb, pc, pc].iter().enumerate() {
        assert!((node(&b, k) - *x).length() <= 1e-15, "joint {k}");
    }
    assert!((com(&b, crank) - Vector::new(0.0, 0.1, 0.16)).length() <= 1e-15);
    assert!((com(&b, rod) - 0.5 * (pb + pc)).length() <= 1e-15);
    assert_rod_end(&b, rod, (pc - pb) / 0.3, 0.3, 1);
    assert_rod_end(&b, rod, (pc - pb) / 0.3, 0.3, 2);
    assert!((com(&b, slider) - pc).length() <= 1e-15);
    // The Exudyn reference initial velocities (slidercrank3DiftommBenchmark).
    let (v_rod, w_rod) = b.world.body_velocity(rod).unwrap();
    assert!((v_rod - Vector::new(0.12, -0.24, 0.0)).length() <= 1e-14);
    assert!((w_rod - Vector::new(1.92, -0.96, 0.48)).length() <= 1e-14);
    assert!((b.probe_velocity() - Vector::new(0.24, 0.0, 0.0)).length() <= 1e-14);
    // The universal joint would hold the rod's spin: w_rod in the span of X and n = (0,-2,1)/sqrt5.
    let n = Vector::new(0.0, -2.0, 1.0).normalize();
    assert!(w_rod.dot(Vector::X.cross(n)).abs() <= 1e-14);
    let jv = max_abs_jv(&b);
    assert!(
        jv <= 1e-14,
        "initial velocities violate the joints: |J v| = {jv:.2e}"
    );
    // By hand. Kinetic: crank (1/2)(1e-4 + 0.12 * 0.04^2) 6^2 = 5.256e-3; rod translation
    // (1/2) 0.5 (0.12^2 + 0.24^2) = 0.018; rod rotation (1/2)(4e-4 * 1.28^2 + 4e-3 * 3.2) =
    // 6.72768e-3 (spin 1.28 rad/s about the rod axis, |w|^2 = 4.8384); slider (1/2) 2 0.24^2 =
    // 0.0576. Potential: 9.81 (0.12 * 0.16 + 0.5 * 0.1) = 0.678852.
    let e0 = 0.005256 + 0.018 + 0.00672768 + 0.0576 + 0.678852;
    assert_close("E0", b.energy(), e0, 1e-12);
    assert_close("b.initial_energy", b.initial_energy, e0, 1e-12);
    // Crank down: potential 9.81 (0.12 * 0.08 + 0.5 * 0.02) = 0.192276.
    assert_close("energy scale", b.energy_scale, e0 - 0.192276, 1e-12);
    // 5 + 3 + 3 + 5 = 16 rows on 18 DOFs, independent: the crank angle and the rod's spin.
    let (rows, rank, nullity, min_pivot) = mobility(&b);
    assert_eq!((rows, rank, nullity), (16, 16, 2));
    assert!(min_pivot > 1e-3, "smallest pivot {min_pivot:.2e}");
}

#[test]
fn slider_crank_spherical_variant_steps_on_impulse() {
    let mut b =
        benchmarks::slider_crank_with(settings(Backend::RapierImpulse), RodSliderJoint::Spherical)
            .unwrap();
    let gap = step_once_finite(&mut b);
    let de = b.energy_error();
    println!("slider-crank (spherical): gap {gap:.2e} m, dE/E_scale {de:+.2e} after one step");
    // Measured: gap 4.2e-4 m, energy -2.8e-3 of the scale.
    assert!(gap <= FREE_FALL, "gap {gap:.2e} m");
    assert!(de.abs() <= 1e-2, "energy error {de:.2e}");
}

/// A consistent initial state loses no energy in the limit h -> 0: one step of 1/60 s with 256
/// substeps leaves the energy within 5e-5 of the scale and the gaps under 1 um (measured 2.9e-7,
/// 2.4e-6, 8.7e-6 and 9e-8 to 4e-7 m, against -8.8e-5 .. -2.8e-3 and 0.4 to 1 mm at 4 substeps).
/// Inconsistent initial velocities would be projected onto the joints in the first substeps,
/// an O(1) loss that does not shrink with h (a wrong slider speed sign gave -0.14 here).
#[test]
fn loops_first_step_converges_with_substeps() {
    let s = WorldSettings {
        backend: Backend::RapierImpulse,
        substeps: 256,
        ..Default::default()
    };
    let scenes = [
        ("four-bar", benchmarks::four_bar_parallelogram(s).unwrap()),
        ("Bricard", benchmarks::bricard(s).unwrap()),
        (
            "slider-crank (spherical)",
            benchmarks::slider_crank_with(s, RodSliderJoint::Spherical).unwrap(),
        ),
    ];
    for (name, mut b) in scenes {
        let gap = step_once_finite(&mut b);
        let de = b.energy_error();
        println!("{name}, 256 substeps: gap {gap:.2e} m, dE/E_scale {de:+.2e}");
        assert!(gap <= 1e-6, "{name}: gap {gap:.2e} m");
        assert!(de.abs() <= 5e-5, "{name}: energy error {de:.2e}");
    }
}
