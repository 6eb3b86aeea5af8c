//! Model validation before the first step: every inconsistent model is refused when the joint is
//! inserted (library) or the deck is read or built, with a typed error that names the joint or
//! body (library: `joint N`, body 1 or 2) or the deck file, line and command. One case per
//! rule, each through the library API and, where a deck can express it, through a deck:
//!
//! - revolute and universal nodes that do not coincide (beyond `COINCIDENCE_TOLERANCE`, relative
//!   to the coordinates' size with a 1 m floor: 1e-6 m here; a 1e-7 m gap is accepted);
//! - a screw of zero pitch; stops with min > max; a stop or lock on a constrained DOF;
//! - a linear and a nonlinear law on the same component; a joint between a body and itself;
//! - a dynamic body without mass or with a singular inertia (a fixed one is fine);
//! - a section subtype that disagrees with KEYOPT(1); a LOCAL frame from invalid numbers.
//!
//! No numerical tolerance is involved beyond the coincidence rule stated above.

use rapier3d_mpc184::deck::{
    BuildOptions, DeckError, DeckErrorKind, DeckModel, JointSubtype, parse_str,
};
use rapier3d_mpc184::joint::COINCIDENCE_TOLERANCE;
use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder, RigidBodyHandle};
use rapier3d_mpc184::prelude::*;

const FILE: &str = "model.inp";

fn world() -> Mpc184World {
    let mut w = Mpc184World::new(WorldSettings::default());
    w.physics.gravity = Vector::ZERO;
    w
}

fn body(w: &mut Mpc184World, at: Vector, mass: Real, inertia: Vector) -> RigidBodyHandle {
    w.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(at)
            .additional_mass_properties(MassProperties::new(Vector::ZERO, mass, inertia)),
    )
}

/// Two unit bodies and a third joint slot: inserts `joint` between them after one good joint,
/// so the failing joint is `joint 1`.
fn insert_second(joint: Mpc184Joint) -> Result<JointId, Error> {
    let mut w = world();
    let a = body(&mut w, Vector::new(-0.5, 0.0, 0.0), 1.0, Vector::splat(0.1));
    let b = body(&mut w, Vector::new(0.5, 0.0, 0.0), 1.0, Vector::splat(0.1));
    w.insert_joint(
        None,
        Some(a),
        Mpc184Joint::revolute(Axis::Z, Vector::new(-1.0, 0.0, 0.0)),
    )
    .unwrap();
    w.insert_joint(Some(a), Some(b), joint)
}

fn names_joint_1(e: &Error) {
    assert!(e.to_string().starts_with("joint 1"), "{e}");
}

// ---- the library ----

#[test]
fn revolute_and_universal_nodes_must_coincide() {
    for kind in [JointKind::Revolute { axis: Axis::Z }, JointKind::Universal] {
        let apart = Mpc184Joint::new(kind, Vector::ZERO).with_node2(Vector::new(0.0, 1e-3, 0.0));
        let e = insert_second(apart).unwrap_err();
        names_joint_1(&e);
        match e {
            Error::NodesApart {
                joint,
                distance,
                tolerance,
                ..
            } => {
                assert_eq!(joint, JointId(1));
                assert!((distance - 1e-3).abs() < 1e-12, "{distance}");
                assert_eq!(tolerance, COINCIDENCE_TOLERANCE);
            }
            other => panic!("{other}"),
        }
        // Within the tolerance: accepted.
        let close = Mpc184Joint::new(kind, Vector::ZERO).with_node2(Vector::new(0.0, 1e-7, 0.0));
        assert_eq!(insert_second(close).unwrap(), JointId(1));
    }
    // A spherical joint keeps an offset (MPC184 allows it).
    let sphere = Mpc184Joint::new(JointKind::Spherical, Vector::ZERO).with_node2(Vector::Y);
    assert!(insert_second(sphere).is_ok());
}

#[test]
fn screw_of_zero_pitch_is_refused() {
    let e = insert_second(Mpc184Joint::new(
        JointKind::Screw { pitch: 0.0 },
        Vector::ZERO,
    ))
    .unwrap_err();
    names_joint_1(&e);
    assert!(
        matches!(e, Error::InvalidPitch { joint: JointId(1), pitch } if pitch == 0.0),
        "{e}"
    );
}

#[test]
fn stop_with_min_above_max_is_refused() {
    let j = Mpc184Joint::revolute(Axis::Z, Vector::ZERO).with_stop(Dof::RotZ, 0.5, -0.5);
    let e = insert_second(j).unwrap_err();
    names_joint_1(&e);
    assert!(
        matches!(
            e,
            Error::InvalidBehaviour {
                joint: JointId(1),
                field: "SECSTOP",
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn stop_or_lock_on_a_constrained_dof_is_refused() {
    for (j, field) in [
        (
            Mpc184Joint::revolute(Axis::Z, Vector::ZERO).with_stop(Dof::Ux, -1.0, 1.0),
            "SECSTOP",
        ),
        (
            Mpc184Joint::revolute(Axis::Z, Vector::ZERO).with_lock(Dof::RotX, -1.0, 1.0),
            "SECLOCK",
        ),
    ] {
        let e = insert_second(j).unwrap_err();
        names_joint_1(&e);
        assert!(
            matches!(e, Error::InvalidBehaviour { joint: JointId(1), field: f, .. } if f == field),
            "{e}"
        );
        assert!(e.to_string().contains("not a free DOF"), "{e}");
    }
}

#[test]
fn linear_and_nonlinear_law_on_one_component_is_refused() {
    let table = Table {
        points: vec![(-1.0, -10.0), (1.0, 10.0)],
    };
    let j = Mpc184Joint::revolute(Axis::Z, Vector::ZERO)
        .with_stiffness(Sym6::diagonal([0.0, 0.0, 0.0, 0.0, 0.0, 5.0]))
        .with_stiffness_table(Dof::RotZ, table);
    let e = insert_second(j).unwrap_err();
    names_joint_1(&e);
    assert!(
        matches!(
            e,
            Error::InvalidBehaviour {
                joint: JointId(1),
                field: "JNS",
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn joint_between_a_body_and_itself_is_refused() {
    let mut w = world();
    let a = body(&mut w, Vector::ZERO, 1.0, Vector::splat(0.1));
    let e = w
        .insert_joint(
            Some(a),
            Some(a),
            Mpc184Joint::new(JointKind::Spherical, Vector::ZERO),
        )
        .unwrap_err();
    assert!(e.to_string().starts_with("joint 0: body 2"), "{e}");
    assert!(
        matches!(
            e,
            Error::InvalidBody {
                joint: JointId(0),
                which: 2,
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn dynamic_body_without_mass_or_with_singular_inertia_is_refused() {
    for (mass, inertia, what) in [
        (0.0, Vector::splat(0.1), "mass 0"),
        (1.0, Vector::new(0.1, 0.1, 0.0), "singular inertia"),
    ] {
        let mut w = world();
        let good = body(&mut w, Vector::ZERO, 1.0, Vector::splat(0.1));
        let bad = body(&mut w, Vector::X, mass, inertia);
        let e = w
            .insert_joint(
                Some(good),
                Some(bad),
                Mpc184Joint::new(JointKind::Spherical, Vector::X * 0.5),
            )
            .unwrap_err();
        assert!(e.to_string().starts_with("joint 0: body 2"), "{e}");
        assert!(e.to_string().contains(what), "{e}");
        assert!(
            matches!(
                e,
                Error::MassProperties {
                    joint: JointId(0),
                    which: 2,
                    ..
                }
            ),
            "{e}"
        );
        // The world is unchanged: no joint was added.
        assert_eq!(w.joint_ids().count(), 0);
    }
    // A massless body that is fixed (grounded) is fine.
    let mut w = world();
    let fixed = w.physics.bodies.insert(RigidBodyBuilder::fixed());
    let moving = body(&mut w, Vector::X, 1.0, Vector::splat(0.1));
    assert!(
        w.insert_joint(
            Some(fixed),
            Some(moving),
            Mpc184Joint::new(JointKind::Spherical, Vector::ZERO)
        )
        .is_ok()
    );
}

#[test]
fn frame_from_invalid_numbers_is_refused() {
    let nan = Rotation::from_xyzw(Real::NAN, 0.0, 0.0, 1.0);
    let e = insert_second(Mpc184Joint::revolute(Axis::Z, Vector::ZERO).with_axes(nan)).unwrap_err();
    names_joint_1(&e);
    assert!(
        matches!(
            e,
            Error::DegenerateFrame {
                joint: JointId(1),
                node: 1,
                ..
            }
        ),
        "{e}"
    );
}

// ---- decks ----

/// Two 1 kg bodies (nodes 1-2 and 3-4, rigid beams, point masses at 2 and 4, node 1 on a
/// grounded revolute), `joint` lines inserted after line 14 (the joint's ET is type 4, its
/// section 2), a transient load step at the end.
fn deck(et4: &str, section: &str, nodes: &str, joint: &str) -> String {
    format!(
        "/PREP7\n\
         ET,1,MPC184,6,,,1\n\
         ET,2,MPC184,1\n\
         ET,3,MASS21,,,2\n\
         {et4}\n\
         R,1,1.0\n\
         SECTYPE,1,JOINT,REVO\n\
         {section}\n\
         N,1,0,0,0\n\
         N,2,1,0,0\n\
         {nodes}\n\
         N,4,2,0,0\n\
         TYPE,1 $ SECNUM,1 $ E,,1\n\
         TYPE,2 $ E,1,2 $ E,3,4\n\
         TYPE,3 $ REAL,1 $ E,2 $ E,4\n\
         TYPE,4 $ SECNUM,2\n\
         {joint}\n\
         FINISH\n/SOLU\nANTYPE,TRANS\nTIME,0.1\nDELTIM,0.01\nSOLVE\n"
    )
}

fn deck_error(text: &str) -> DeckError {
    let deck = match parse_str(text, FILE) {
        Err(e) => return e,
        Ok(d) => d,
    };
    match DeckModel::build(&deck, BuildOptions::default()) {
        Err(Error::Deck(e)) => e,
        Err(other) => panic!("not a deck error: {other}"),
        Ok(_) => panic!("built:\n{text}"),
    }
}

fn at(e: &DeckError, line: usize, command: &str) {
    assert_eq!(
        (e.file.as_str(), e.line, e.command.as_str()),
        (FILE, line, command),
        "{e}"
    );
    assert!(
        e.to_string()
            .starts_with(&format!("{FILE}:{line}: {command}: ")),
        "{e}"
    );
}

const REVO2: &str = "SECTYPE,2,JOINT,REVO";

/// The template itself is a valid model (a double pendulum of point masses), so each case
/// below fails for its one change. It steps in the f64 build; the f32 Lagrange solve of point
/// masses stops at t = 0 (as for `assets/decks/double_pendulum.inp`, a solver matter).
#[test]
fn the_template_deck_builds_and_runs() {
    let text = deck("ET,4,MPC184,6,,,1", REVO2, "N,3,1,0,0", "E,2,3");
    let mut m = DeckModel::build(&parse_str(&text, FILE).unwrap(), BuildOptions::default())
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(m.joints.len(), 2);
    m.begin_load_step(0).unwrap();
    if cfg!(feature = "f64") {
        m.step().unwrap();
    }
}

#[test]
fn deck_revolute_nodes_apart() {
    let text = deck("ET,4,MPC184,6,,,1", REVO2, "N,3,1,0.01,0", "E,2,3");
    let e = deck_error(&text);
    at(&e, 17, "E");
    assert!(matches!(e.kind, DeckErrorKind::InvalidValue { .. }), "{e}");
    assert!(e.to_string().contains("nodes 2 (I) and 3 (J)"), "{e}");
    let text = deck(
        "ET,4,MPC184,7",
        "SECTYPE,2,JOINT,UNIV",
        "N,3,1,0.01,0",
        "E,2,3",
    );
    at(&deck_error(&text), 17, "E");
}

#[test]
fn deck_screw_of_zero_pitch() {
    let text = deck(
        "ET,4,MPC184,17",
        "SECTYPE,2,JOINT,SCRE\nSECJOINT,PITC,0",
        "N,3,1,0,0",
        "E,2,3",
    );
    let e = deck_error(&text);
    at(&e, 8, "SECTYPE");
    assert!(e.to_string().contains("PITC,0"), "{e}");
}

#[test]
fn deck_stop_min_above_max() {
    let text = deck(
        "ET,4,MPC184,6,,,1",
        "SECTYPE,2,JOINT,REVO\nSECSTOP,6,1,-1",
        "N,3,1,0,0",
        "E,2,3",
    );
    let e = deck_error(&text);
    at(&e, 9, "SECSTOP");
    assert!(
        matches!(e.kind, DeckErrorKind::InvalidValue { field: 2, .. }),
        "{e}"
    );
}

#[test]
fn deck_lock_on_constrained_dof() {
    let text = deck(
        "ET,4,MPC184,6,,,1",
        "SECTYPE,2,JOINT,REVO\nSECSTOP,6,-1,1\nSECLOCK,1,-1,1",
        "N,3,1,0,0",
        "E,2,3",
    );
    let e = deck_error(&text);
    at(&e, 10, "SECLOCK");
    assert!(e.to_string().contains("not a free DOF"), "{e}");
}

#[test]
fn deck_linear_and_nonlinear_on_one_component() {
    let text = deck(
        "ET,4,MPC184,6,,,1",
        REVO2,
        "N,3,1,0,0",
        "MAT,2 $ E,2,3\nTB,JOIN,2,,,STIF\nTBDATA,21,5\nTB,JOIN,2,1,2,JNS6\nTBPT,,-1,-5\nTBPT,,1,5",
    );
    let e = deck_error(&text);
    at(&e, 20, "TB");
    assert!(e.to_string().contains("linear or nonlinear"), "{e}");
}

#[test]
fn deck_joint_between_a_body_and_itself() {
    // Nodes 2 and 3 tied by CERIG: the joint's two sides are one body.
    let text = deck("ET,4,MPC184,6,,,1", REVO2, "N,3,1,0,0", "E,2,3\nCERIG,2,3");
    let e = deck_error(&text);
    at(&e, 17, "E");
    assert!(e.to_string().contains("one rigid body"), "{e}");
}

#[test]
fn deck_joint_on_a_massless_body() {
    // Node 3 carries no mass (no beam to node 4, no MASS21).
    let text = deck("ET,4,MPC184,6,,,1", REVO2, "N,3,1,0,0", "E,2,3")
        .replace("TYPE,2 $ E,1,2 $ E,3,4", "TYPE,2 $ E,1,2")
        .replace("TYPE,3 $ REAL,1 $ E,2 $ E,4", "TYPE,3 $ REAL,1 $ E,2");
    let e = deck_error(&text);
    at(&e, 17, "E");
    assert!(e.to_string().contains("node 3 carries no mass"), "{e}");
}

#[test]
fn deck_section_subtype_disagrees_with_keyopt1() {
    let text = deck("ET,4,MPC184,7", REVO2, "N,3,1,0,0", "E,2,3");
    let e = deck_error(&text);
    at(&e, 17, "E");
    assert!(
        matches!(
            e.kind,
            DeckErrorKind::SubtypeMismatch {
                section: 2,
                subtype: JointSubtype::Revolute,
                keyopt1: 7,
                expected: JointSubtype::Universal,
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn deck_local_frame_from_invalid_numbers() {
    for (bad, kind) in [
        ("0/0", "NonFinite"),
        ("1e999", "NonFinite"),
        ("NAN", "Unknown"),
    ] {
        let text = deck(
            "ET,4,MPC184,6,,,1",
            &format!("LOCAL,11,0,0,0,0,{bad}\nCSYS,0\n{REVO2}\nSECJOINT,LSYS,11"),
            "N,3,1,0,0",
            "E,2,3",
        );
        let e = deck_error(&text);
        at(&e, 8, "LOCAL");
        let ok = match kind {
            "NonFinite" => matches!(e.kind, DeckErrorKind::NonFinite { field: 6, .. }),
            _ => matches!(e.kind, DeckErrorKind::UnknownParameter { field: 6, .. }),
        };
        assert!(ok, "{e}");
    }
    // A deck made (or deserialised) by hand whose LOCAL rotation is NaN: the builder refuses it
    // at the LOCAL line.
    let text = deck(
        "ET,4,MPC184,6,,,1",
        &format!("LOCAL,11,0,0,0,0,30\nCSYS,0\n{REVO2}\nSECJOINT,LSYS,11"),
        "N,3,1,0,0",
        "E,2,3",
    );
    let mut d = parse_str(&text, FILE).unwrap();
    d.coordinate_systems.get_mut(&11).unwrap().rotation[1][1] = f64::NAN;
    let Err(Error::Deck(e)) = DeckModel::build(&d, BuildOptions::default()) else {
        panic!("built a NaN frame");
    };
    at(&e, 8, "LOCAL");
    assert!(e.to_string().contains("not finite"), "{e}");
}
