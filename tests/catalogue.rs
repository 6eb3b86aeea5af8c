//! The MPC184 joint catalogue (KEYOPT(1) = 6..19 with KEYOPT(4)) and its lowering to Rapier.
//!
//! What is checked, against the catalogue table of the issue (reference A.2), written out here
//! independently of `src/catalogue.rs`:
//!
//! - For every `JointKind` variant (walked through `JointKind::representatives()` and an
//!   exhaustive `match`, so a new variant fails to build until it gets a table row): KEYOPT(1),
//!   KEYOPT(4), the section subtype, the constrained and free relative DOFs (frame I), and the
//!   number of constraint equations `6 - (number of free DOFs)` (the screw's UZ is neither free
//!   nor plainly locked: it is tied to ROTZ by the pitch, which is its fifth equation).
//! - General (16) and genb (19) for all 64 `SECJOINT,RDOF` release sets, with KEYOPT(4) = 0 and 1
//!   (KEYOPT(4) = 1: the nodes carry displacements only, so every rotation is free as well).
//! - The rigid link (KEYOPT(1) = 0): no section subtype, one equation (the distance), no DOF
//!   constrained alone and none free, not expressible by a Rapier mask.
//! - `from_keyopts` round-trips; KEYOPT(1) = 1..=5 (beams, sliders) is `Error::Unsupported`, any
//!   other value outside 6..=19 and KEYOPT(4) outside {0, 1} on a kind with a KEYOPT(4)
//!   variant is `Error::InvalidKeyopt` naming the KEYOPT and the value.
//! - Lowering to Rapier (both backends, Lagrange): Rapier's joint X is the principal axis, e1 for
//!   most kinds and e3 for the z variants and the screw, with Rapier (X, Y, Z) = (e3, e1, e2),
//!   i.e. ANSYS axis `a` -> Rapier axis `(a + 1) % 3`. The locked-axes mask must be exactly the
//!   constrained DOFs so permuted. Kinds Rapier cannot express are `Error::Unsupported`:
//!   universal and general/genb with one locked rotation (a lone Bryant-angle lock is not a
//!   quaternion-component lock), the screw (a translation tied to a rotation), the spotweld (a
//!   6x6 spring, no rigid rows), and genb with exactly two locked rotations: its rotations are
//!   3-1-3 Euler angles `R = Rz(alpha) Rx(beta) Rz(gamma)`, which start at the singular
//!   `beta = 0`; locking alpha and gamma leaves `R = Rx(beta)` free about e1 while a Rapier mask
//!   locking ROTX and ROTZ would leave e2 free, so no mask is right. The penalty method is
//!   `Unsupported` on both Rapier backends.
//! - `principal_rotation(2)` maps Rapier X, Y, Z to e3, e1, e2 and is a proper rotation, and the
//!   Rapier axes a mask locks, carried through `principal_rotation`, are the frame-I axes of the
//!   constrained DOFs.
//!
//! Everything here is integer or set logic, compared exactly. The only tolerance is on the
//! principal rotation (a unit quaternion built from a permutation matrix): `16 eps` (a few
//! rounding errors of a quaternion-vector product, `eps` the machine epsilon of `Real`).

use rapier3d_mpc184::Error;
use rapier3d_mpc184::catalogue::{Axis, JointKind};
use rapier3d_mpc184::dof::{Dof, DofMask};
use rapier3d_mpc184::joint::ConstraintMethod;
use rapier3d_mpc184::lower::{self, Backend};
use rapier3d_mpc184::math::rapier::dynamics::JointAxesMask;
use rapier3d_mpc184::math::{Matrix, Real, Vector};

use Dof::{RotX, RotY, RotZ, Ux, Uy, Uz};

const ALL_DOFS: [Dof; 6] = [Ux, Uy, Uz, RotX, RotY, RotZ];
const ROTATIONS: [Dof; 3] = [RotX, RotY, RotZ];
const BACKENDS: [Backend; 2] = [Backend::RapierImpulse, Backend::RapierMultibody];

/// Frame-I axis of a DOF and whether it is a rotation, written out from the ANSYS numbering.
fn axis_of(d: Dof) -> (usize, bool) {
    match d {
        Ux => (0, false),
        Uy => (1, false),
        Uz => (2, false),
        RotX => (0, true),
        RotY => (1, true),
        RotZ => (2, true),
    }
}

/// One row of the table.
#[derive(Debug)]
struct Expected {
    keyopt1: i64,
    keyopt4: i64,
    subtype: &'static str,
    constrained: Vec<Dof>,
    free: Vec<Dof>,
    /// Number of constraint equations (screw: its coupling counts as one).
    equations: usize,
    /// 0 = e1, 2 = e3 goes to Rapier X.
    principal: usize,
    /// Whether a Rapier locked-axes mask expresses the joint exactly.
    rapier_exact: bool,
}

/// The table row of a kind. The `match` is exhaustive on purpose: a new variant must be added.
fn expected(kind: &JointKind) -> Expected {
    let row =
        |keyopt1, keyopt4, subtype, constrained: &[Dof], free: &[Dof], principal, rapier_exact| {
            Expected {
                keyopt1,
                keyopt4,
                subtype,
                constrained: constrained.to_vec(),
                free: free.to_vec(),
                equations: 6 - free.len(),
                principal,
                rapier_exact,
            }
        };
    // General / genb: everything is locked except the RDOF releases, and with KEYOPT(4) = 1
    // every rotation is free too.
    let general = |released: &DofMask, translations_only: bool, subtype, keyopt1, genb: bool| {
        let is_free = |d: Dof| released.contains(d) || (translations_only && axis_of(d).1);
        let constrained: Vec<Dof> = ALL_DOFS.into_iter().filter(|d| !is_free(*d)).collect();
        let free: Vec<Dof> = ALL_DOFS.into_iter().filter(|d| is_free(*d)).collect();
        let locked_rotations = constrained.iter().filter(|d| axis_of(**d).1).count();
        let rapier_exact = match locked_rotations {
            0 | 3 => true,
            1 => false,
            // Bryant angles (general): any two locked leave one axis free, as a mask does.
            // 3-1-3 Euler angles (genb): see the header, no mask is right.
            _ => !genb,
        };
        Expected {
            keyopt1,
            keyopt4: translations_only as i64,
            subtype,
            equations: constrained.len(),
            constrained,
            free,
            principal: 0,
            rapier_exact,
        }
    };
    match kind {
        JointKind::Revolute { axis: Axis::X } => {
            row(6, 0, "REVO", &[Ux, Uy, Uz, RotY, RotZ], &[RotX], 0, true)
        }
        JointKind::Revolute { axis: Axis::Z } => {
            row(6, 1, "REVO", &[Ux, Uy, Uz, RotX, RotY], &[RotZ], 2, true)
        }
        JointKind::Universal => row(7, 0, "UNIV", &[Ux, Uy, Uz, RotY], &[RotX, RotZ], 0, false),
        JointKind::Slot => row(8, 0, "SLOT", &[Uy, Uz], &[Ux, RotX, RotY, RotZ], 0, true),
        JointKind::PointInPlane => row(9, 0, "PINP", &[Ux], &[Uy, Uz, RotX, RotY, RotZ], 0, true),
        JointKind::Translational => row(10, 0, "PRIS", &[Uy, Uz, RotX, RotY, RotZ], &[Ux], 0, true),
        JointKind::Cylindrical { axis: Axis::X } => {
            row(11, 0, "CYLI", &[Uy, Uz, RotY, RotZ], &[Ux, RotX], 0, true)
        }
        JointKind::Cylindrical { axis: Axis::Z } => {
            row(11, 1, "CYLI", &[Ux, Uy, RotX, RotY], &[Uz, RotZ], 2, true)
        }
        JointKind::Planar { axis: Axis::X } => {
            row(12, 0, "PLAN", &[Ux, RotY, RotZ], &[Uy, Uz, RotX], 0, true)
        }
        JointKind::Planar { axis: Axis::Z } => {
            row(12, 1, "PLAN", &[Uz, RotX, RotY], &[Ux, Uy, RotZ], 2, true)
        }
        JointKind::Weld => row(13, 0, "WELD", &ALL_DOFS, &[], 0, true),
        JointKind::Orient => row(14, 0, "ORIE", &[RotX, RotY, RotZ], &[Ux, Uy, Uz], 0, true),
        JointKind::Spherical => row(15, 0, "SPHE", &[Ux, Uy, Uz], &[RotX, RotY, RotZ], 0, true),
        JointKind::General {
            released,
            translations_only,
        } => general(released, *translations_only, "GENE", 16, false),
        // Plain locks: UX UY ROTX ROTY; UZ is the pitch-coupled one, ROTZ the only free DOF.
        // Rapier: a cylindrical joint about e3 (its constrained DOFs locked); the coupling UZ =
        // pitch ROTZ is projected around each Rapier call (src/backend/rapier/screw.rs).
        JointKind::Screw { .. } => row(17, 0, "SCRE", &[Ux, Uy, RotX, RotY], &[RotZ], 2, true),
        JointKind::Spotweld => row(18, 0, "SPOT", &[], &ALL_DOFS, 0, false),
        // One distance equation; no DOF is locked alone or a free coordinate, no section.
        JointKind::RigidLink => Expected {
            equations: 1,
            ..row(0, 0, "", &[], &[], 0, false)
        },
        JointKind::Genb {
            released,
            translations_only,
        } => general(released, *translations_only, "GENB", 19, true),
    }
}

fn labels(dofs: impl IntoIterator<Item = Dof>) -> String {
    let v: Vec<&str> = dofs.into_iter().map(Dof::label).collect();
    if v.is_empty() {
        "none".into()
    } else {
        v.join(" ")
    }
}

fn members(mask: DofMask) -> Vec<Dof> {
    ALL_DOFS.into_iter().filter(|d| mask.contains(*d)).collect()
}

fn released_of(kind: &JointKind) -> DofMask {
    match kind {
        JointKind::General { released, .. } | JointKind::Genb { released, .. } => *released,
        _ => DofMask::NONE,
    }
}

fn pitch_of(kind: &JointKind) -> Real {
    match kind {
        JointKind::Screw { pitch } => *pitch,
        _ => 0.0,
    }
}

/// Every general and genb kind: 64 release sets x KEYOPT(4) in {0, 1}.
fn all_general_kinds() -> Vec<JointKind> {
    let mut v = Vec::new();
    for bits in 0u8..64 {
        let released = DofMask::of(
            &ALL_DOFS
                .into_iter()
                .enumerate()
                .filter(|(i, _)| bits & (1 << i) != 0)
                .map(|(_, d)| d)
                .collect::<Vec<_>>(),
        );
        for translations_only in [false, true] {
            v.push(JointKind::General {
                released,
                translations_only,
            });
            v.push(JointKind::Genb {
                released,
                translations_only,
            });
        }
    }
    v
}

/// The kinds to walk: the representatives plus every general/genb release set.
fn all_kinds() -> Vec<JointKind> {
    let mut v = JointKind::representatives();
    v.extend(all_general_kinds());
    v
}

#[test]
fn dof_numbering_is_ansys() {
    // UX..ROTZ = 1..6 (SECJOINT,RDOF / SECSTOP numbering), labels as ANSYS prints them.
    let table = [
        (Ux, 1, "UX"),
        (Uy, 2, "UY"),
        (Uz, 3, "UZ"),
        (RotX, 4, "ROTX"),
        (RotY, 5, "ROTY"),
        (RotZ, 6, "ROTZ"),
    ];
    for (d, n, label) in table {
        assert_eq!(
            d.number(),
            n,
            "{label}: number {} vs expected {n}",
            d.number()
        );
        assert_eq!(d.label(), label, "DOF {n}: label {} vs {label}", d.label());
        assert_eq!(
            Dof::from_number(n),
            Some(d),
            "from_number({n}) = {:?} vs expected {d:?}",
            Dof::from_number(n)
        );
        let (axis, rot) = axis_of(d);
        assert_eq!(
            d.axis(),
            axis,
            "{label}: axis {} vs expected {axis}",
            d.axis()
        );
        assert_eq!(d.is_rotation(), rot, "{label}: is_rotation");
    }
    for n in [0u8, 7, 255] {
        assert_eq!(Dof::from_number(n), None, "from_number({n}) must be None");
    }
}

#[test]
fn representatives_cover_every_table_row() {
    let mut got: Vec<(i64, i64)> = JointKind::representatives()
        .iter()
        .map(|k| {
            let e = expected(k);
            (e.keyopt1, e.keyopt4)
        })
        .collect();
    got.sort_unstable();
    // The rigid link (0), every KEYOPT(1) 6..19 once, plus the KEYOPT(4) = 1 variants of 6,
    // 11, 12, 16 and 19.
    let mut want: Vec<(i64, i64)> = std::iter::once(0).chain(6..=19).map(|k1| (k1, 0)).collect();
    want.extend([(6, 1), (11, 1), (12, 1), (16, 1), (19, 1)]);
    want.sort_unstable();
    assert_eq!(
        got, want,
        "representatives' (KEYOPT(1), KEYOPT(4)) {got:?} vs expected {want:?}"
    );
}

#[test]
fn every_kind_matches_the_table() {
    let kinds = all_kinds();
    for kind in &kinds {
        let e = expected(kind);
        let name = format!("{} ({}/{})", kind.name(), e.keyopt1, e.keyopt4);
        assert_eq!(
            kind.keyopt1(),
            e.keyopt1,
            "{name}: KEYOPT(1) {} vs expected {}",
            kind.keyopt1(),
            e.keyopt1
        );
        assert_eq!(
            kind.keyopt4(),
            e.keyopt4,
            "{name}: KEYOPT(4) {} vs expected {}",
            kind.keyopt4(),
            e.keyopt4
        );
        assert_eq!(
            kind.subtype(),
            e.subtype,
            "{name}: subtype {} vs expected {}",
            kind.subtype(),
            e.subtype
        );
        let constrained = members(kind.constrained());
        assert_eq!(
            constrained,
            e.constrained,
            "{name} released {}: constrained {} vs expected {}",
            released_of(kind),
            labels(constrained.clone()),
            labels(e.constrained.clone())
        );
        let free = members(kind.free());
        assert_eq!(
            free,
            e.free,
            "{name} released {}: free {} vs expected {}",
            released_of(kind),
            labels(free.clone()),
            labels(e.free.clone())
        );
        assert_eq!(
            kind.constraint_count(),
            e.equations,
            "{name} released {}: constraint_count {} vs expected {}",
            released_of(kind),
            kind.constraint_count(),
            e.equations
        );
        assert_eq!(
            kind.principal_axis(),
            e.principal,
            "{name}: principal axis {} vs expected e{}",
            kind.principal_axis(),
            e.principal + 1
        );
        // Constrained and free never overlap; only the screw leaves a DOF (UZ) in neither set.
        assert_eq!(
            kind.constrained().0 & kind.free().0,
            0,
            "{name}: constrained and free overlap"
        );
        let neither = members(DofMask(!(kind.constrained().0 | kind.free().0) & 0b11_1111));
        let want_neither = match kind {
            JointKind::Screw { .. } => vec![Uz],
            JointKind::RigidLink => ALL_DOFS.to_vec(),
            _ => vec![],
        };
        assert_eq!(
            neither,
            want_neither,
            "{name}: DOFs neither constrained nor free {} vs expected {}",
            labels(neither.clone()),
            labels(want_neither.clone())
        );
        let want_coupled = match kind {
            JointKind::Screw { .. } => Some((Uz, RotZ)),
            _ => None,
        };
        assert_eq!(
            kind.coupled(),
            want_coupled,
            "{name}: coupled {:?} vs expected {want_coupled:?}",
            kind.coupled()
        );
    }
}

#[test]
fn general_with_released_rotz_and_ux() {
    // SECJOINT,RDOF,1,6 (UX and ROTZ released), KEYOPT(4) = 0: UY UZ ROTX ROTY held.
    for kind in [
        JointKind::General {
            released: DofMask::of(&[RotZ, Ux]),
            translations_only: false,
        },
        JointKind::Genb {
            released: DofMask::of(&[RotZ, Ux]),
            translations_only: false,
        },
    ] {
        let c = members(kind.constrained());
        let f = members(kind.free());
        assert_eq!(
            c,
            vec![Uy, Uz, RotX, RotY],
            "{}: constrained {} vs expected UY UZ ROTX ROTY",
            kind.name(),
            labels(c.clone())
        );
        assert_eq!(
            f,
            vec![Ux, RotZ],
            "{}: free {} vs expected UX ROTZ",
            kind.name(),
            labels(f.clone())
        );
        assert_eq!(
            kind.constraint_count(),
            4,
            "{}: constraint_count {} vs 4",
            kind.name(),
            kind.constraint_count()
        );
    }
    // KEYOPT(4) = 1 with UY released: only UX and UZ held, rotations free.
    let k = JointKind::General {
        released: DofMask::of(&[Uy]),
        translations_only: true,
    };
    let c = members(k.constrained());
    assert_eq!(
        c,
        vec![Ux, Uz],
        "general 16/1 RDOF UY: constrained {} vs expected UX UZ",
        labels(c.clone())
    );
    assert_eq!(
        k.constraint_count(),
        2,
        "general 16/1 RDOF UY: constraint_count {} vs 2",
        k.constraint_count()
    );
}

#[test]
fn from_keyopts_round_trips() {
    for kind in all_kinds()
        .iter()
        .chain([JointKind::Screw { pitch: -0.25 }].iter())
    {
        let e = expected(kind);
        let back = JointKind::from_keyopts(e.keyopt1, e.keyopt4, released_of(kind), pitch_of(kind))
            .unwrap_or_else(|err| panic!("{}: from_keyopts failed: {err}", kind.name()));
        assert_eq!(
            back, *kind,
            "from_keyopts({}, {}) = {back:?} vs expected {kind:?}",
            e.keyopt1, e.keyopt4
        );
        let again = JointKind::from_keyopts(
            kind.keyopt1(),
            kind.keyopt4(),
            released_of(kind),
            pitch_of(kind),
        )
        .unwrap_or_else(|err| panic!("{}: from_keyopts failed: {err}", kind.name()));
        assert_eq!(again, *kind, "round trip {again:?} vs {kind:?}");
    }
}

#[test]
fn invalid_keyopts_give_typed_errors() {
    for k1 in 1..=5 {
        let r = JointKind::from_keyopts(k1, 0, DofMask::NONE, 0.0);
        assert!(
            matches!(r, Err(Error::Unsupported { .. })),
            "KEYOPT(1) = {k1}: got {r:?}, expected Error::Unsupported"
        );
    }
    for k1 in [-1, 20, 21, 100, i64::MAX, i64::MIN] {
        let r = JointKind::from_keyopts(k1, 0, DofMask::NONE, 0.0);
        assert!(
            matches!(r, Err(Error::InvalidKeyopt { keyopt: 1, value, .. }) if value == k1),
            "KEYOPT(1) = {k1}: got {r:?}, expected InvalidKeyopt {{ keyopt: 1, value: {k1} }}"
        );
    }
    // Kinds with a KEYOPT(4) variant accept only 0 and 1.
    for k1 in [6, 11, 12, 16, 19] {
        for k4 in [2, -1, 7] {
            let r = JointKind::from_keyopts(k1, k4, DofMask::NONE, 0.0);
            assert!(
                matches!(r, Err(Error::InvalidKeyopt { keyopt: 4, value, .. }) if value == k4),
                "KEYOPT(1) = {k1}, KEYOPT(4) = {k4}: got {r:?}, expected InvalidKeyopt {{ keyopt: 4, value: {k4} }}"
            );
        }
    }
}

/// The mask expected from the table: each constrained DOF on its Rapier axis.
fn expected_mask(e: &Expected) -> JointAxesMask {
    let lin = [
        JointAxesMask::LIN_X,
        JointAxesMask::LIN_Y,
        JointAxesMask::LIN_Z,
    ];
    let ang = [
        JointAxesMask::ANG_X,
        JointAxesMask::ANG_Y,
        JointAxesMask::ANG_Z,
    ];
    let mut m = JointAxesMask::empty();
    for d in &e.constrained {
        let (a, rot) = axis_of(*d);
        let r = if e.principal == 2 { (a + 1) % 3 } else { a };
        m |= if rot { ang[r] } else { lin[r] };
    }
    m
}

#[test]
fn lowering_to_rapier() {
    for backend in BACKENDS {
        for kind in all_kinds() {
            let e = expected(&kind);
            let name = format!(
                "{} ({}/{}, released {}) on {}",
                kind.name(),
                e.keyopt1,
                e.keyopt4,
                released_of(&kind),
                backend.name()
            );
            let got = lower::lower(&kind, ConstraintMethod::Lagrange, backend);
            if e.rapier_exact {
                let want = expected_mask(&e);
                match got {
                    Ok(mask) => assert_eq!(
                        mask,
                        want,
                        "{name}: mask {mask:?} vs expected {want:?} (constrained {})",
                        labels(e.constrained.clone())
                    ),
                    Err(err) => panic!("{name}: expected mask {want:?}, got error {err}"),
                }
            } else {
                assert!(
                    matches!(got, Err(Error::Unsupported { .. })),
                    "{name}: got {got:?}, expected Error::Unsupported"
                );
            }
            let penalty = ConstraintMethod::Penalty {
                disp: 1.0,
                rot: 1.0,
            };
            let p = lower::lower(&kind, penalty, backend);
            assert!(
                matches!(p, Err(Error::Unsupported { .. })),
                "{name} with the penalty method: got {p:?}, expected Error::Unsupported"
            );
        }
    }
}

#[test]
fn unsupported_set_is_exactly_the_expected_one() {
    // Among the representatives: universal, spotweld, the rigid link (a distance is no
    // locked-axes mask; general/genb representatives lock
    // 0 or 3 rotations and are supported).
    let mut unsupported: Vec<&str> = JointKind::representatives()
        .iter()
        .filter(|k| lower::lower(k, ConstraintMethod::Lagrange, Backend::RapierImpulse).is_err())
        .map(|k| k.name())
        .collect();
    unsupported.sort_unstable();
    let want = vec!["rigid link", "spotweld", "universal"];
    assert_eq!(
        unsupported, want,
        "unsupported {unsupported:?} vs expected {want:?}"
    );
    // General with one locked rotation (released UX, ROTX, ROTZ: ROTY alone locked).
    let lone = JointKind::General {
        released: DofMask::of(&[Ux, RotX, RotZ]),
        translations_only: false,
    };
    let r = lower::lower(&lone, ConstraintMethod::Lagrange, Backend::RapierMultibody);
    assert!(
        matches!(r, Err(Error::Unsupported { .. })),
        "general with ROTY alone locked: got {r:?}, expected Unsupported"
    );
}

fn close(a: Vector, b: Vector) -> bool {
    (a - b).abs().max_element() <= 16.0 * Real::EPSILON
}

#[test]
fn principal_rotation_is_the_cyclic_permutation() {
    let (x, y, z) = (Vector::X, Vector::Y, Vector::Z);
    let r = lower::principal_rotation(2);
    for (rapier, frame_i, what) in [(x, z, "X -> e3"), (y, x, "Y -> e1"), (z, y, "Z -> e2")] {
        let got = r * rapier;
        assert!(
            close(got, frame_i),
            "principal_rotation(2): {what}: got {got:?} vs {frame_i:?}"
        );
    }
    let m = Matrix::from_quat(r);
    let det = m.determinant();
    assert!(
        (det - 1.0).abs() <= 16.0 * Real::EPSILON,
        "principal_rotation(2): det {det} vs expected +1"
    );
    let orth = (m.transpose() * m - Matrix::IDENTITY).abs().to_cols_array();
    let worst = orth.iter().copied().fold(0.0, Real::max);
    assert!(
        worst <= 16.0 * Real::EPSILON,
        "R^T R - I: largest entry {worst:e} vs 0"
    );
    let r0 = lower::principal_rotation(0);
    for a in [x, y, z] {
        let got = r0 * a;
        assert!(
            close(got, a),
            "principal_rotation(0) moves {a:?} to {got:?}"
        );
    }
}

#[test]
fn mask_axes_carried_to_frame_i_are_the_constrained_axes() {
    // Ties the mask permutation to the frame rotation: the Rapier axis a mask locks, turned by
    // principal_rotation into frame I, must be the axis of a constrained DOF of the same type.
    let lin = [
        JointAxesMask::LIN_X,
        JointAxesMask::LIN_Y,
        JointAxesMask::LIN_Z,
    ];
    let ang = [
        JointAxesMask::ANG_X,
        JointAxesMask::ANG_Y,
        JointAxesMask::ANG_Z,
    ];
    for kind in all_kinds() {
        let Ok(mask) = lower::lower(&kind, ConstraintMethod::Lagrange, Backend::RapierImpulse)
        else {
            continue;
        };
        let e = expected(&kind);
        let r = lower::principal_rotation(e.principal);
        let mut locked_in_frame_i = Vec::new();
        for k in 0..3 {
            let in_i = r * Vector::AXES[k];
            let a = (0..3)
                .find(|&a| close(in_i, Vector::AXES[a]))
                .unwrap_or_else(|| panic!("Rapier axis {k} maps to {in_i:?}, not a frame axis"));
            if mask.contains(lin[k]) {
                locked_in_frame_i.push([Ux, Uy, Uz][a]);
            }
            if mask.contains(ang[k]) {
                locked_in_frame_i.push(ROTATIONS[a]);
            }
        }
        locked_in_frame_i.sort_unstable();
        assert_eq!(
            locked_in_frame_i,
            e.constrained,
            "{} (released {}): mask locks {} in frame I vs constrained {}",
            kind.name(),
            released_of(&kind),
            labels(locked_in_frame_i.clone()),
            labels(e.constrained.clone())
        );
    }
}
