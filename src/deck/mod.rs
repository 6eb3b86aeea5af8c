//! The APDL deck reader: a subset of Mechanical APDL input for rigid multibody models with
//! MPC184 joints, read into plain data ([`Deck`]) by the parser (the crate's `apdl` module: it depends on
//! nothing else of the crate and has no Rapier types, as rapier's `mjcf-rs` beside
//! `rapier3d-mjcf`), and the builder (`DeckModel::build`, `build.rs`) that turns a [`Deck`] into
//! a runnable `Mpc184World`.
//!
//! # Syntax
//! - Commands are case-insensitive, fields are separated by commas and blank fields are "not
//!   given". Trailing fields may be omitted. A command may be abbreviated to four or more leading
//!   characters (`SECJ` = `SECJOINT`), as ANSYS reads only the first four.
//! - `!` starts a comment; `$` separates several commands on one line (not in `/TITLE`, `/COM`).
//! - Parameters: `NAME=expr` and `*SET,NAME,expr` (`*SET,NAME` deletes it). Names are
//!   case-insensitive. Any numeric field may be an expression ([`evaluate`]): `+ - * / **`,
//!   parentheses, `SIN COS TAN ASIN ACOS ATAN ATAN2 SQRT ABS EXP LOG ...`; `*AFUN,DEG|RAD` sets the
//!   angle unit of the trigonometric functions (radians by default). There is no predefined `PI`.
//!   Label fields (`UX`, `REVO`, `JOIN`, ...) are not evaluated.
//!
//! # Commands
//! | group | commands |
//! |---|---|
//! | session | `/PREP7 /SOLU FINISH /TITLE /COM /CLEAR /EOF`; noted and ignored: `/OUTPUT NLGEOM TINTP TRNOPT,FULL /NOPR /GOPR /BATCH ALLSEL` |
//! | elements | `ET,n,MPC184\|MASS21,k1..k6`, `KEYOPT`, `TYPE REAL MAT SECNUM`, `R RMORE`, `N`, `E`, `EN`, `CERIG` |
//! | joints | `SECTYPE,id,JOINT,subtype`, `SECJOINT,LSYS\|RDOF\|PITC\|FRIC\|PNLT\|SPWE`, `SECSTOP`, `SECLOCK`, `SECDATA` |
//! | frames | `LOCAL,n,0,x,y,z,thxy,thyz,thzx` (Cartesian, degrees), `CSYS` |
//! | materials | `TB,JOIN,mat,1,npts,TBOPT`, `TBTEMP`, `TBDATA`, `TBPT` |
//! | loads | `D F DJ FJ DDELE FDELE DJDELE FJDELE ACEL IC` |
//! | analysis | `ANTYPE,STATIC\|TRANS`, `TIME`, `DELTIM`, `NSUBST`, `KBC`, `AUTOTS`, `MIDTOL`, `SOLVE` (one [`LoadStep`] each; `AUTOTS,ON` chooses the substeps by step doubling, see [`StepPlan::autots`]) |
//! | output | `OUTRES,Item,Freq` (`n`, `-n`, `ALL`, `LAST`, `NONE`; `ERASE`; see [`OutputFrequency`]) |
//!
//! Anything else is an error ([`DeckErrorKind::Unsupported`], with a hint). Errors display as
//! `FILE:LINE: COMMAND: what is wrong`.
//!
//! # Semantics kept from ANSYS
//! - `N` coordinates are in the active coordinate system (`LOCAL` activates the system it
//!   defines, `CSYS` switches) and stored global.
//! - `E` takes the highest element number so far plus one; each element records the `TYPE`,
//!   `REAL`, `MAT` and `SECNUM` pointers in effect. A blank node I or J of a joint means that side
//!   is grounded.
//! - Loads persist between load steps until deleted or overwritten. `ACEL` is stored as given:
//!   `ACEL,0,9.81,0` is gravity toward -Y.
//! - `SECJOINT,RDOF` lists the relative DOFs that a general joint FIXES.
//! - At the end, every joint element's section must exist with the subtype its KEYOPT(1) asks
//!   for.
//!
//! ```
//! use rapier3d_mpc184::deck::{parse_str, ElementRole};
//! let deck = parse_str(
//!     "ET,1,MPC184,6,,,1\nSECTYPE,1,JOINT,REVO\nSECJOINT,LSYS,0\nN,1\nE,,1 ! grounded\n",
//!     "hinge.inp",
//! )
//! .unwrap();
//! let e = &deck.elements[&1];
//! assert_eq!((e.i, e.j), (None, Some(1)));
//! assert_eq!(deck.role_of(e), Some(ElementRole::Joint));
//! ```

mod build;

pub use crate::apdl::{
    AnalysisType, CoordinateSystem, Deck, DofLabel, DofRange, Element, ElementName, ElementRole,
    ElementType, ForceLabel, InitialCondition, JoinTable, JointLoad, JointMotion, JointSection,
    JointSubtype, LoadRamp, LoadStep, MotionKind, NodalConstraint, NodalForce, Node, NodeAxis,
    Note, OutputFrequency, RealConstants, RigidRegion, SpotweldCenter, Substeps, TimeIncrement,
};
pub use crate::apdl::{AngleUnit, DeckError, DeckErrorKind, ExprError, MAX_DEPTH, evaluate};
pub use crate::apdl::{parse_file, parse_str};
pub use build::{
    AUTOTS_TOLERANCE, BuildOptions, DeckBody, DeckJoint, DeckModel, FrictionData,
    POINT_MASS_INERTIA, StepPlan,
};
