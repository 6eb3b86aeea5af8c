//! The APDL deck reader (`rapier3d_mpc184::deck`), checked against how ANSYS reads a deck.
//!
//! - Expressions: Fortran precedence (`**` right-associative and tighter than a sign, so
//!   `-2**2 = -4`), functions, `*AFUN,DEG`, parameters (`NAME=`, `*SET`), case-insensitivity.
//! - `LOCAL` systems against hand-computed rotations (THXY about Z, then THYZ about the new X,
//!   then THZX about the new Y, degrees), node coordinates in the active system.
//! - Blank fields, comments, `$`, four-letter abbreviations; `E` with a blank node (grounded joint
//!   side) and element auto-numbering; pointers recorded per element.
//! - Load steps: loads persist between SOLVEs until deleted, DJ keeps one motion per DOF.
//! - Every error kind names the right line and command; `FILE:LINE: COMMAND: ...` display.
//! - No panic on garbage (empty text, commas, 1e999, 10000 nested parentheses, NaN, unicode).
//! - Every deck in `assets/decks` parses, with a few facts checked per deck.
//!
//! Tolerances: 1e-12 for arithmetic that is exact up to rounding of a few operations.

use std::collections::BTreeMap;
use std::path::Path;

use rapier3d_mpc184::deck::{
    AngleUnit, DeckError, DeckErrorKind, DofLabel, ForceLabel, JointSubtype, LoadRamp, MotionKind,
    NodeAxis, SpotweldCenter, evaluate, parse_file, parse_str,
};

const EPS: f64 = 1e-12;

fn eval(s: &str) -> f64 {
    evaluate(s, &BTreeMap::new(), AngleUnit::Radians).unwrap_or_else(|e| panic!("{s}: {e}"))
}

fn close(a: [f64; 3], b: [f64; 3]) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9)
}

fn err(text: &str) -> DeckError {
    match parse_str(text, "t.inp") {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => e,
    }
}

#[test]
fn expressions_follow_fortran_precedence() {
    assert_eq!(eval("-2**2"), -4.0);
    assert_eq!(eval("2**3**2"), 512.0);
    assert_eq!(eval("2*-3"), -6.0);
    assert_eq!(eval("1+2*3"), 7.0);
    assert_eq!(eval("(1+2)*3"), 9.0);
    assert_eq!(eval("10/4/5"), 0.5);
    assert_eq!(eval("2**-1"), 0.5);
    assert_eq!(eval("-(3)"), -3.0);
    assert_eq!(eval("1.5E2 + .5 + 2.e-1"), 150.7);
    assert_eq!(eval("sqrt(16)+ABS(-2)"), 6.0);
    assert!((eval("ATAN2(1,1)") - std::f64::consts::FRAC_PI_4).abs() < EPS);
    assert!((eval("LOG(EXP(2))") - 2.0).abs() < EPS);
    assert!((eval("ACOS(-1)") - std::f64::consts::PI).abs() < EPS);
    assert_eq!(
        eval("MAX(1,5,3)+MIN(2,-1)+SIGN(3,-1)+NINT(2.6)"),
        5.0 - 1.0 - 3.0 + 3.0
    );
}

#[test]
fn afun_deg_switches_trigonometric_units() {
    let p = BTreeMap::new();
    let sin30 = evaluate("SIN(30)", &p, AngleUnit::Degrees).unwrap();
    assert!((sin30 - 0.5).abs() < EPS, "{sin30}");
    let acos = evaluate("ACOS(-1)", &p, AngleUnit::Degrees).unwrap();
    assert!((acos - 180.0).abs() < EPS, "{acos}");
    let deck = parse_str(
        "PI=ACOS(-1)\n*AFUN,DEG\nA=ACOS(-1)\n*afun,rad\nB=SIN(PI/2)\n",
        "afun.inp",
    )
    .unwrap();
    assert!((deck.parameters["PI"] - std::f64::consts::PI).abs() < EPS);
    assert!((deck.parameters["A"] - 180.0).abs() < EPS);
    assert!((deck.parameters["B"] - 1.0).abs() < EPS);
    assert_eq!(deck.angle_unit, AngleUnit::Radians);
}

#[test]
fn parameters_are_case_insensitive_and_feed_numeric_fields() {
    let deck = parse_str(
        "l = 2\n*SET,Th,90\n*AFUN,DEG\nN,3,L*SIN(th),l*COS(TH)\n*SET,L\n",
        "p.inp",
    )
    .unwrap();
    assert!(close(deck.nodes[&3].position, [2.0, 0.0, 0.0]));
    assert!(
        !deck.parameters.contains_key("L"),
        "*SET,L with no value deletes L"
    );
    assert_eq!(deck.parameters["TH"], 90.0);
    let e = err("X=1\n*SET,X\nN,1,X\n");
    assert_eq!((e.line, e.command.as_str()), (3, "N"));
    assert!(
        matches!(e.kind, DeckErrorKind::UnknownParameter { ref name, field: 2 } if name == "X")
    );
}

#[test]
fn pi_is_not_predefined() {
    let e = err("N,1,PI\n");
    assert!(matches!(e.kind, DeckErrorKind::UnknownParameter { ref name, .. } if name == "PI"));
}

#[test]
fn local_systems_match_hand_computed_rotations() {
    let deck = parse_str(
        "LOCAL,11,0,1,2,3,90,0,0\nN,1,1,0,0\n\
         LOCAL,12,0,0,0,0,0,0,-90\nN,2,1,0,0\n\
         LOCAL,13,0,0,0,0,0,-90\nN,3,0,0,1\n\
         LOCAL,14,0,0,0,0,90,90\nN,4,0,0,1\nN,5,0,1,0\n\
         CSYS,0\nN,6,1,2,3\nCSYS,11\nN,7,0,1,0\n",
        "local.inp",
    )
    .unwrap();
    // Rz(90): local x = global y; origin (1,2,3).
    assert!(close(deck.nodes[&1].position, [1.0, 3.0, 3.0]));
    // Ry(-90): x -> +Z.
    assert!(close(deck.nodes[&2].position, [0.0, 0.0, 1.0]));
    // Rx(-90): z -> +Y.
    assert!(close(deck.nodes[&3].position, [0.0, 1.0, 0.0]));
    // Rz(90) Rx(90): z -> +X, y -> +Z.
    assert!(close(deck.nodes[&4].position, [1.0, 0.0, 0.0]));
    assert!(close(deck.nodes[&5].position, [0.0, 0.0, 1.0]));
    assert!(close(deck.nodes[&6].position, [1.0, 2.0, 3.0]));
    // CSYS,11 again: local y = global -x, plus the origin.
    assert!(close(deck.nodes[&7].position, [0.0, 2.0, 3.0]));
    let cs = deck.coordinate_system(14).unwrap();
    assert!(close(cs.axis(0), [0.0, 1.0, 0.0]));
    assert!(close(cs.axis(1), [0.0, 0.0, 1.0]));
    assert!(close(cs.axis(2), [1.0, 0.0, 0.0]));
    assert_eq!(cs.angles_deg, [90.0, 90.0, 0.0]);
    assert_eq!(deck.coordinate_system(0).unwrap().axis(2), [0.0, 0.0, 1.0]);
    assert!(deck.coordinate_system(15).is_none());
}

#[test]
fn blank_fields_comments_dollar_and_abbreviations() {
    let deck = parse_str(
        "! header comment\n\
         n , 5 , , 2   ! blank x\n\
         N,6,1 $ N,7,,,4 ! two commands, then a comment\n\
         \n\
         N,,9 ! blank number: next free\n\
         /title, A title, with commas ! and a comment\n\
         nsub,10 $ Delt,0.5\n",
        "syntax.inp",
    )
    .unwrap();
    assert!(close(deck.nodes[&5].position, [0.0, 2.0, 0.0]));
    assert!(close(deck.nodes[&6].position, [1.0, 0.0, 0.0]));
    assert!(close(deck.nodes[&7].position, [0.0, 0.0, 4.0]));
    assert!(close(deck.nodes[&8].position, [9.0, 0.0, 0.0]));
    assert_eq!(deck.title.as_deref(), Some("A title, with commas"));
}

#[test]
fn elements_record_pointers_and_grounded_sides() {
    let deck = parse_str(
        "ET,1,MPC184,6,,,1\nET,2,mass21,,,2\nR,4,2.5\nSECTYPE,3,JOINT,REVO\nSECJOINT,LSYS,0\n\
         N,1\nN,2,1\n\
         TYPE,1 $ SECNUM,3 $ MAT,7\nE,,1\nEN,10,1,2\nE,2\n\
         TYPE,2 $ REAL,4\nE,2\n",
        "elements.inp",
    )
    .unwrap();
    let e1 = deck.elements[&1];
    assert_eq!((e1.i, e1.j), (None, Some(1)));
    assert_eq!(
        (e1.element_type, e1.section, e1.material, e1.real),
        (1, 3, 7, 1)
    );
    assert_eq!(e1.line, 9);
    assert_eq!(
        (deck.elements[&10].i, deck.elements[&10].j),
        (Some(1), Some(2))
    );
    // E after EN,10 takes 11, a grounded J side.
    assert_eq!(
        (deck.elements[&11].i, deck.elements[&11].j),
        (Some(2), None)
    );
    let mass = deck.elements[&12];
    assert_eq!((mass.element_type, mass.real), (2, 4));
    assert_eq!(deck.element_types[&1].keyopt(4), 1);
    assert_eq!(deck.element_types[&2].keyopt(3), 2);
    assert_eq!(
        deck.element_types[&1].joint_subtype(),
        Some(JointSubtype::Revolute)
    );
    assert_eq!(
        deck.real_constants[&4].values,
        [2.5, 0.0, 0.0, 0.0, 0.0, 0.0]
    );
    assert_eq!(deck.sections[&3].lsys_i, Some(0));
}

#[test]
fn sections_tables_and_constraints_are_stored() {
    let deck = parse_str(
        "SECTYPE,1,JOINT,gene,mygen\nSECJOINT,LSYS,11,12\nSECJOINT,RDOF,1,2,3,ROTX,5,1\n\
         SECSTOP,6,-1,1,1,-0.5,0.5\nSECSTOP,6,-2,2\nSECLOCK,4,-0.1,0.1\nSECDATA,0.1,,,0.2\n\
         SECJOINT,PNLT,DISP,-1e6\nSECJOINT,PNLT,ROT,2\n\
         SECTYPE,2,JOINT,SCRE\nSECJOINT,PITC,0.001\nSECJOINT,FRIC,0.01,,0.02\n\
         SECTYPE,3,JOINT,SPOT\nSECJOINT,LSYS,IJZ\nSECJOINT,SPWE,RATIO,0.25\n\
         LOCAL,11,0\nLOCAL,12,0\n\
         TB,JOIN,2,1,3,jns6\nTBPT,,-1,-10\nTBPT,DEFI,0,0\nTBPT,,1,10\n\
         TB,JOIN,2,,,STIF\nTBDATA,1,1e3,,2\nTBDATA,,5\nTBTEMP,20\n\
         N,1\nN,2\nCERIG,1,2\nCERIG,1,2,UXYZ,ROTZ\nR,1,1,2,3\nRMORE,4\n",
        "sections.inp",
    )
    .unwrap();
    let s1 = &deck.sections[&1];
    assert_eq!(s1.subtype, JointSubtype::General);
    assert_eq!(s1.name.as_deref(), Some("mygen"));
    assert_eq!((s1.lsys_i, s1.lsys_j), (Some(11), Some(12)));
    assert_eq!(
        s1.fixed_dofs,
        [
            DofLabel::Ux,
            DofLabel::Uy,
            DofLabel::Uz,
            DofLabel::RotX,
            DofLabel::RotY
        ]
    );
    let stops: Vec<_> = s1.stops.iter().map(|r| (r.dof, r.min, r.max)).collect();
    assert_eq!(
        stops,
        [(DofLabel::Ux, -0.5, 0.5), (DofLabel::RotZ, -2.0, 2.0)]
    );
    assert_eq!(s1.locks[0].dof, DofLabel::RotX);
    assert_eq!(s1.reference, [Some(0.1), None, None, Some(0.2), None, None]);
    assert_eq!(
        (s1.penalty_displacement, s1.penalty_rotation),
        (Some(-1e6), Some(2.0))
    );
    let s2 = &deck.sections[&2];
    assert_eq!(s2.pitch, Some(0.001));
    assert_eq!(s2.friction_geometry, [Some(0.01), None, Some(0.02)]);
    let s3 = &deck.sections[&3];
    assert_eq!(s3.lsys_from_nodes, Some(NodeAxis::Z));
    assert_eq!(s3.spotweld_center, Some(SpotweldCenter::Ratio(0.25)));
    let tables: Vec<_> = deck.join_tables_of(2).collect();
    assert_eq!(tables.len(), 2);
    assert_eq!(tables[0].tbopt, "JNS6");
    assert_eq!(tables[0].npts, 3);
    assert_eq!(tables[0].points, [[-1.0, -10.0], [0.0, 0.0], [1.0, 10.0]]);
    assert_eq!(tables[1].constants, [Some(1e3), None, Some(2.0), Some(5.0)]);
    assert_eq!(tables[1].temperature, Some(20.0));
    assert_eq!(deck.rigid_regions.len(), 2);
    assert_eq!(deck.rigid_regions[1].dofs, ["UXYZ", "ROTZ"]);
    assert_eq!(deck.rigid_groups()[&1], [2, 2]);
    assert_eq!(deck.real_constants[&1].values.len(), 12);
    assert_eq!(deck.real_constants[&1].values[6], 4.0);
}

#[test]
fn load_steps_snapshot_persistent_loads() {
    let deck = parse_str(
        "ET,1,MPC184,6,,,1\nSECTYPE,1,JOINT,REVO\nN,1\nN,2\nE,,1\n\
         /SOLU\nANTYPE,TRANS\nD,1,ALL,0\nF,2,FY,-10\nDJ,1,ROTZ,0.5\nFJ,1,MZ,3\nACEL,0,9.81\n\
         KBC,1\nTIME,1\nDELTIM,0.01,0.001,0.1\nSOLVE\n\
         FDELE,2,FY\nDDELE,1,UX\nDJ,1,OMGZ,2\nNSUBST,20\nSOLVE\n\
         DJDELE,ALL,ALL\nFJDELE,1\nDDELE,ALL\nIC,2,UY,0.1,-1\nTIME,5\nSOLVE\n",
        "loads.inp",
    )
    .unwrap();
    let [s1, s2, s3] = deck.load_steps.as_slice() else {
        panic!("expected 3 load steps, got {}", deck.load_steps.len())
    };
    assert_eq!((s1.number, s1.end_time, s1.line), (1, 1.0, 16));
    assert_eq!(s1.d.len(), 6);
    assert_eq!(s1.f[0].label, ForceLabel::Fy);
    assert_eq!(s1.f[0].value, -10.0);
    assert_eq!(s1.dj[0].kind, MotionKind::Displacement);
    assert_eq!(s1.dj[0].label(), "ROTZ");
    assert_eq!(s1.fj[0].value, 3.0);
    assert_eq!(s1.acel, [0.0, 9.81, 0.0]);
    assert_eq!(s1.kbc, LoadRamp::Stepped);
    assert_eq!(s1.deltim.map(|d| d.dt), Some(0.01));
    assert!(s1.nsubst.is_none());
    // Step 2: TIME not given -> previous + 1; deletions; DJ on the same DOF replaced.
    assert_eq!(s2.end_time, 2.0);
    assert_eq!(s2.d.len(), 5);
    assert!(s2.d.iter().all(|c| c.dof != DofLabel::Ux));
    assert!(s2.f.is_empty());
    assert_eq!(s2.dj.len(), 1);
    assert_eq!((s2.dj[0].kind, s2.dj[0].value), (MotionKind::Velocity, 2.0));
    assert_eq!(s2.fj.len(), 1, "FJ persists");
    assert_eq!(s2.acel, [0.0, 9.81, 0.0], "ACEL persists");
    assert!(s2.deltim.is_none(), "NSUBST replaces DELTIM");
    assert_eq!(s2.nsubst.map(|n| n.n), Some(20));
    assert_eq!(s3.end_time, 5.0);
    assert!(s3.d.is_empty() && s3.dj.is_empty() && s3.fj.is_empty());
    let ic = deck.initial_conditions[0];
    assert_eq!(
        (ic.node, ic.dof, ic.displacement, ic.velocity),
        (2, DofLabel::Uy, 0.1, -1.0)
    );
}

#[test]
fn clear_resets_the_model() {
    let deck = parse_str("A=1\nN,1\n/CLEAR\nN,2\n", "clear.inp").unwrap();
    assert!(deck.nodes.contains_key(&2) && !deck.nodes.contains_key(&1));
    assert!(deck.parameters.is_empty());
}

#[test]
fn ineffective_commands_leave_one_note_each() {
    let deck = parse_str("NLGEOM,ON\nOUTRES,STAT\nTINTP,0.1\n/OUT,scratch\n", "n.inp").unwrap();
    let lines: Vec<_> = deck.notes.iter().map(|n| n.line).collect();
    assert_eq!(lines, [1, 2, 3, 4]);
    assert!(deck.notes[0].text.starts_with("NLGEOM"));
}

/// (deck, expected line, expected command, predicate on the kind)
type Case = (
    &'static str,
    usize,
    &'static str,
    fn(&DeckErrorKind) -> bool,
);

#[test]
#[expect(
    clippy::too_many_lines,
    reason = "a table with one case per error kind: split up, it would no longer show at a glance \
              which kinds are covered"
)]
fn every_error_kind_names_line_and_command() {
    let cases: Vec<Case> = vec![
        ("N,1\nN,2,1+*2\n", 2, "N", |k| {
            matches!(k, DeckErrorKind::MalformedExpression { field: 2, .. })
        }),
        ("N,1,(1\n", 1, "N", |k| {
            matches!(k, DeckErrorKind::MalformedExpression { .. })
        }),
        ("N,1,FOO\n", 1, "N", |k| {
            matches!(k, DeckErrorKind::UnknownParameter { .. })
        }),
        ("N,1,1e999\n", 1, "N", |k| {
            matches!(k, DeckErrorKind::NonFinite { .. })
        }),
        ("X=1/0\n", 1, "X=", |k| {
            matches!(k, DeckErrorKind::NonFinite { .. })
        }),
        ("N,1,SQRT(-1)\n", 1, "N", |k| {
            matches!(k, DeckErrorKind::NonFinite { .. })
        }),
        (
            "\n\nK,1,0,0,0\n",
            3,
            "K",
            |k| matches!(k, DeckErrorKind::Unsupported { hint, .. } if hint.contains("N and elements")),
        ),
        ("ET,1,BEAM188\n", 1, "ET", |k| {
            matches!(k, DeckErrorKind::Unsupported { hint, .. }
                if hint.starts_with("rigid multibody only: model links with MPC184 rigid beams (KEYOPT(1)=1) and MASS21"))
        }),
        ("*DO,I,1,3\n", 1, "*DO", |k| {
            matches!(k, DeckErrorKind::Unsupported { .. })
        }),
        ("TB,JOIN,1,2,,STIF\n", 1, "TB", |k| {
            matches!(k, DeckErrorKind::Unsupported { .. })
        }),
        ("TB,BISO,1\n", 1, "TB", |k| {
            matches!(k, DeckErrorKind::Unsupported { .. })
        }),
        ("LOCAL,11,1\n", 1, "LOCAL", |k| {
            matches!(k, DeckErrorKind::Unsupported { .. })
        }),
        ("LOCAL,5,0\n", 1, "LOCAL", |k| {
            matches!(k, DeckErrorKind::InvalidValue { field: 1, .. })
        }),
        ("CSYS,12\n", 1, "CSYS", |k| {
            matches!(k, DeckErrorKind::MissingReference { .. })
        }),
        (
            "ET,1,MASS21\nN,1\nE,1,7\n",
            3,
            "E",
            |k| matches!(k, DeckErrorKind::MissingReference { what } if what.contains("node 7")),
        ),
        ("N,1\nE,1\n", 2, "E", |k| {
            matches!(k, DeckErrorKind::MissingReference { .. })
        }),
        ("SECJOINT,LSYS,11\n", 1, "SECJOINT", |k| {
            matches!(k, DeckErrorKind::MissingReference { .. })
        }),
        ("SECSTOP,1,0,1\n", 1, "SECSTOP", |k| {
            matches!(k, DeckErrorKind::MissingReference { .. })
        }),
        ("TBPT,,1,2\n", 1, "TBPT", |k| {
            matches!(k, DeckErrorKind::MissingReference { .. })
        }),
        ("TBDATA,1,2\n", 1, "TBDATA", |k| {
            matches!(k, DeckErrorKind::MissingReference { .. })
        }),
        ("KEYOPT,3,1,6\n", 1, "KEYOPT", |k| {
            matches!(k, DeckErrorKind::MissingReference { .. })
        }),
        ("DJ,1,ROTZ,1\n", 1, "DJ", |k| {
            matches!(k, DeckErrorKind::MissingReference { .. })
        }),
        (
            "ET,1,MPC184,6\nN,1\nSECNUM,4\nE,,1\n",
            4,
            "E",
            |k| matches!(k, DeckErrorKind::MissingReference { what } if what.contains("section 4")),
        ),
        (
            "ET,1,MPC184,6\nSECTYPE,1,JOINT,REVO\nSECJOINT,LSYS,11\nN,1\nE,,1\n",
            3,
            "SECJOINT",
            |k| matches!(k, DeckErrorKind::MissingReference { what } if what.contains("coordinate system 11")),
        ),
        (
            "ET,1,MPC184,6\nSECTYPE,1,JOINT,SPHE\nN,1\nN,2\nE,1,2\n",
            5,
            "E",
            |k| {
                matches!(k, DeckErrorKind::SubtypeMismatch { keyopt1: 6, subtype, expected, .. }
                if *subtype == JointSubtype::Spherical && *expected == JointSubtype::Revolute)
            },
        ),
        ("SECTYPE,1,JOINT,HINGE\n", 1, "SECTYPE", |k| {
            matches!(k, DeckErrorKind::InvalidValue { field: 3, .. })
        }),
        ("SECTYPE,1,BEAM,RECT\n", 1, "SECTYPE", |k| {
            matches!(k, DeckErrorKind::Unsupported { .. })
        }),
        ("SECTYPE,1,JOINT\n", 1, "SECTYPE", |k| {
            matches!(k, DeckErrorKind::MissingField { field: 3, .. })
        }),
        ("N,1.5\n", 1, "N", |k| {
            matches!(k, DeckErrorKind::InvalidValue { field: 1, .. })
        }),
        ("N,1\nD,1,UW,0\n", 2, "D", |k| {
            matches!(k, DeckErrorKind::InvalidValue { field: 2, .. })
        }),
        ("TIME,2\nSOLVE\nTIME,1\nSOLVE\n", 4, "SOLVE", |k| {
            matches!(k, DeckErrorKind::InvalidValue { .. })
        }),
        ("ET,1,MPC184,3\n", 1, "ET", |k| {
            matches!(k, DeckErrorKind::Unsupported { .. })
        }),
        ("ET,1,MPC184,1\nN,1\nE,1\n", 3, "E", |k| {
            matches!(k, DeckErrorKind::InvalidValue { .. })
        }),
        (
            "N,1,((((((((((((((((((((((((((((((((((((((((((((((((((((((((((((((((((((((((((1",
            1,
            "N",
            |k| matches!(k, DeckErrorKind::TooDeep { .. }),
        ),
    ];
    for (text, line, command, check) in cases {
        let e = err(text);
        assert_eq!(
            (e.line, e.command.as_str()),
            (line, command),
            "{text:?} gave {e}"
        );
        assert!(check(&e.kind), "{text:?} gave the wrong kind: {e}");
        assert!(
            e.to_string()
                .starts_with(&format!("t.inp:{line}: {command}: ")),
            "{e}"
        );
    }
}

#[test]
fn error_display_is_file_line_command_message() {
    let e = err("N,1\nN,2,FOO\n");
    assert_eq!(
        e.to_string(),
        "t.inp:2: N: field 2: unknown parameter `FOO` (parameters must be defined before use)"
    );
    let crate_error = rapier3d_mpc184::Error::from(e.clone());
    assert_eq!(crate_error.to_string(), e.to_string());
    let missing = parse_file(Path::new("/nonexistent/deck.inp")).unwrap_err();
    assert!(matches!(missing.kind, DeckErrorKind::Io(_)));
}

#[test]
fn garbage_never_panics() {
    let deep_open = "(".repeat(10_000);
    let deep_sign = "-".repeat(100_000);
    let deep_pow = "2**".repeat(10_000) + "2";
    let long_line = ",".repeat(100_000);
    let nasty: Vec<String> = vec![
        String::new(),
        ",,,,".into(),
        "N,1,1e999".into(),
        deep_open.clone(),
        format!("N,1,{deep_open}"),
        format!("N,1,{deep_sign}1"),
        format!("X={deep_pow}"),
        format!("X={deep_open}1{}", ")".repeat(10_000)),
        long_line,
        "NaN".into(),
        "N,1,NaN".into(),
        "N,1,inf".into(),
        "N,1,é,ü".into(),
        "ñ=1".into(),
        "日本語,1,2".into(),
        "\u{0}\u{1}\u{7f}".into(),
        "$$$!$$$".into(),
        "E,,".into(),
        "EN,4294967296,1".into(),
        "N,-1".into(),
        "N,1e20".into(),
        "N,1,2**10000".into(),
        "N,1,(1)(2)".into(),
        "N,1,SIN()".into(),
        "N,1,MAX()".into(),
        "N,1,ATAN2(1)".into(),
        "N,1,)".into(),
        "N,1,1..2".into(),
        "=1".into(),
        "*SET".into(),
        "*SET,,1".into(),
        "/TITLE".into(),
        "/COM".into(),
        "ET,1,MPC184,1e18".into(),
        "ET,1,MPC184\nKEYOPT,1,99999999999,1".into(),
        "ET,1,MPC184\nKEYOPT,1,0,1".into(),
        "N,1\nD,1,UX,0,,4000000000,1".into(),
        "N,1\nD,1,UX,0,,1,0".into(),
        "SECTYPE,1,JOINT,REVO\nSECSTOP,7,0,1".into(),
        "SECTYPE,1,JOINT,REVO\nSECSTOP,,0,1".into(),
        "TB,JOIN,1,,,STIF\nTBDATA,99999999999,1".into(),
        "TB,JOIN,1,,,STIF\nTBDATA,0,1".into(),
        "TB,JOIN,1,,-5,STIF".into(),
        "LOCAL,11,0,1e308,1e308,1e308,1e308,1e308,1e308\nN,1,1e308".into(),
        "R,1\nRMORE".into(),
        "RMORE,1".into(),
        "SOLVE\nSOLVE\nSOLVE".into(),
        "TIME,-1".into(),
        "CSYS,99999999999".into(),
        "DJ,ALL,ROTZ,1\nFJ,ALL,MZ,1\nDJDELE,ALL\nIC,ALL,ALL,1".into(),
        "*AFUN,GRAD".into(),
        "ANTYPE,MODAL".into(),
    ];
    for text in &nasty {
        let result = std::panic::catch_unwind(|| parse_str(text, "garbage.inp"));
        assert!(
            result.is_ok(),
            "panicked on {:?}",
            text.chars().take(60).collect::<String>()
        );
    }
}

#[test]
fn every_shipped_deck_parses() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/decks");
    let mut names = Vec::new();
    for entry in std::fs::read_dir(&dir).expect("assets/decks exists") {
        let path = entry.expect("directory entry").path();
        if path.extension().is_some_and(|e| e == "inp") {
            let deck = parse_file(&path).unwrap_or_else(|e| panic!("{e}"));
            assert!(
                !deck.load_steps.is_empty(),
                "{} has no SOLVE",
                path.display()
            );
            assert!(
                std::fs::read_to_string(&path).unwrap().starts_with('!'),
                "{} must open with a ! header",
                path.display()
            );
            names.push(path.file_stem().unwrap().to_string_lossy().into_owned());
        }
    }
    names.sort();
    assert_eq!(
        names,
        [
            "andrews_squeezer",
            "bricard",
            "conical_pendulum",
            "double_pendulum",
            "friction_incline",
            "general_rdof",
            "link_swing",
            "pendulum_autots",
            "pendulum_x",
            "pendulum_z",
            "screw_jack",
            "slider_crank",
            "slider_crank_spatial",
            "slider_crank_static",
            "stops_locks",
            "stops_locks_autots"
        ]
    );
}

fn deck(name: &str) -> rapier3d_mpc184::deck::Deck {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/decks")
        .join(format!("{name}.inp"));
    parse_file(&path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn shipped_decks_hold_the_scenes_their_headers_describe() {
    let z = deck("pendulum_z");
    let step = &z.load_steps[0];
    assert_eq!(step.end_time, 2.0);
    assert!((step.deltim.unwrap().dt - 1.0 / 240.0).abs() < EPS);
    assert_eq!(step.acel, [0.0, 9.81, 0.0]);
    assert!(z.notes.iter().any(|n| n.text.starts_with("NLGEOM")));
    assert!(close(z.nodes[&2].position, [1.0, 0.0, 0.0]));

    let x = deck("pendulum_x");
    let cs = x.coordinate_system(x.sections[&1].lsys_i.unwrap()).unwrap();
    assert!(
        close(cs.axis(0), [0.0, 0.0, 1.0]),
        "e1 along +Z: {:?}",
        cs.axis(0)
    );
    assert_eq!(x.element_types[&1].keyopt(4), 0);

    let conical = deck("conical_pendulum");
    let bob = conical.nodes[&2].position;
    assert!(close(bob, [0.5, -(3f64.sqrt()) / 2.0, 0.0]), "{bob:?}");
    let uz = conical
        .initial_conditions
        .iter()
        .find(|ic| ic.node == 2 && ic.dof == DofLabel::Uz)
        .unwrap();
    assert!((uz.velocity - 1.682826).abs() < 1e-6, "{}", uz.velocity);

    let crank = deck("slider_crank");
    let stop = crank.sections[&2].stops[0];
    assert_eq!(stop.dof, DofLabel::RotZ);
    assert!((stop.max - std::f64::consts::PI / 6.0).abs() < EPS);
    assert_eq!(crank.join_tables_of(1).next().unwrap().tbopt, "MUS6");
    assert_eq!(crank.elements[&1].material, 1);
    assert_eq!(crank.elements[&2].material, 2);

    let screw = deck("screw_jack");
    let pitch = screw.sections[&1].pitch.unwrap();
    assert!((pitch - 0.005 / (2.0 * std::f64::consts::PI)).abs() < EPS);

    let gene = deck("general_rdof");
    assert_eq!(gene.sections[&1].fixed_dofs.len(), 5);

    let stops = deck("stops_locks");
    assert_eq!(stops.sections[&1].stops.len(), 1);
    assert_eq!(stops.sections[&2].locks.len(), 1);
    assert_eq!(stops.load_steps[0].acel, [0.0; 3]);

    let bricard = deck("bricard");
    let joints = bricard
        .elements
        .values()
        .filter(|e| bricard.role_of(e) == Some(rapier3d_mpc184::deck::ElementRole::Joint))
        .count();
    assert_eq!(joints, 6);
    assert_eq!(
        bricard.elements[&6].j, None,
        "P5 joint grounded on the J side"
    );
    assert!((bricard.load_steps[0].end_time - 10.0).abs() < EPS);
}

#[test]
fn the_model_round_trips_through_serde_clone() {
    let d = deck("slider_crank");
    let copy = d.clone();
    assert_eq!(d, copy);
}

#[test]
fn deck_error_stays_small_enough_to_return_by_value() {
    // clippy's result_large_err threshold is 128 bytes; crate::Error wraps DeckError unboxed.
    assert!(size_of::<DeckError>() < 128, "{}", size_of::<DeckError>());
}
