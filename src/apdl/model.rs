//! The parsed deck: plain data, no Rapier types.
//!
//! Units are those of the deck. The decks shipped in `assets/decks` use SI (m, kg, s, N, rad),
//! and the fields below are documented with SI units on that understanding: this reader does
//! not convert units (ANSYS has no unit system either), except LOCAL angles, which ANSYS gives in
//! degrees and which are stored both as given and as a rotation matrix.
//!
//! Frames: "global" is the global Cartesian system (CSYS 0). Node coordinates are stored in
//! global coordinates whatever coordinate system was active when the node was defined. Joint
//! loads and stops are in the joint's local frame at node I, as in ANSYS.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::expr::AngleUnit;

/// A whole APDL deck as read by [`crate::deck::parse_str`].
///
/// Maps are keyed by the ANSYS number (node, element, type, section, coordinate system, real
/// constant set), so iteration is in ascending number order.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Deck {
    /// The file name the deck was read from (as given to the parser).
    pub file: String,
    /// `/TITLE` text (default: none).
    #[doc(alias = "/TITLE")]
    pub title: Option<String>,
    /// Scalar parameters at the end of the deck, names upper case (`NAME=expr`, `*SET`).
    #[doc(alias = "*SET")]
    pub parameters: BTreeMap<String, f64>,
    /// Angle unit of the trigonometric functions at the end of the deck (`*AFUN`; default radians).
    #[doc(alias = "*AFUN")]
    pub angle_unit: AngleUnit,
    /// Local coordinate systems defined with `LOCAL` (numbers >= 11). The global system 0 is not
    /// stored; use [`Deck::coordinate_system`], which returns it for 0.
    #[doc(alias = "LOCAL")]
    pub coordinate_systems: BTreeMap<u32, CoordinateSystem>,
    /// Nodes (`N`), positions global.
    #[doc(alias = "N")]
    pub nodes: BTreeMap<u32, Node>,
    /// Element types (`ET`, `KEYOPT`).
    #[doc(alias = "ET")]
    pub element_types: BTreeMap<u32, ElementType>,
    /// Real constant sets (`R`, `RMORE`).
    #[doc(alias = "R")]
    pub real_constants: BTreeMap<u32, RealConstants>,
    /// Joint sections (`SECTYPE,id,JOINT,...` and the SECJOINT/SECSTOP/SECLOCK/SECDATA that follow).
    #[doc(alias = "SECTYPE")]
    pub sections: BTreeMap<u32, JointSection>,
    /// `TB,JOIN` tables in deck order (several may share a material number).
    #[doc(alias = "TB")]
    pub join_tables: Vec<JoinTable>,
    /// Elements (`E`, `EN`).
    #[doc(alias = "E")]
    pub elements: BTreeMap<u32, Element>,
    /// Rigid-region constraints (`CERIG`), in deck order.
    #[doc(alias = "CERIG")]
    pub rigid_regions: Vec<RigidRegion>,
    /// Initial conditions (`IC`), one per node and DOF (a later IC replaces an earlier one).
    #[doc(alias = "IC")]
    pub initial_conditions: Vec<InitialCondition>,
    /// One entry per `SOLVE`, in order.
    #[doc(alias = "SOLVE")]
    pub load_steps: Vec<LoadStep>,
    /// Informational notes: commands accepted but without effect here, and similar remarks.
    pub notes: Vec<Note>,
}

impl Deck {
    /// The coordinate system `id`: the global Cartesian system for 0, a `LOCAL` system otherwise.
    pub fn coordinate_system(&self, id: u32) -> Option<CoordinateSystem> {
        if id == 0 {
            Some(CoordinateSystem::GLOBAL)
        } else {
            self.coordinate_systems.get(&id).copied()
        }
    }

    /// The element type of `element` (always present in a deck returned by the parser).
    pub fn element_type_of(&self, element: &Element) -> Option<&ElementType> {
        self.element_types.get(&element.element_type)
    }

    /// What `element` is: a mass, a rigid link or beam, or a joint with its section.
    pub fn role_of(&self, element: &Element) -> Option<ElementRole> {
        let et = self.element_type_of(element)?;
        match et.element {
            ElementName::Mass21 => Some(ElementRole::Mass),
            ElementName::Combin14 => Some(ElementRole::Spring),
            ElementName::Mpc184 => match et.keyopt(1) {
                0 => Some(ElementRole::RigidLink),
                1 => Some(ElementRole::RigidBeam),
                k => JointSubtype::from_keyopt1(k).map(|_| ElementRole::Joint),
            },
        }
    }

    /// The joint section of a joint element (`SECNUM` pointer at creation).
    pub fn section_of(&self, element: &Element) -> Option<&JointSection> {
        self.sections.get(&element.section)
    }

    /// The `TB,JOIN` tables of material `mat`, in deck order.
    pub fn join_tables_of(&self, mat: u32) -> impl Iterator<Item = &JoinTable> {
        self.join_tables.iter().filter(move |t| t.material == mat)
    }

    /// CERIG constraints grouped by master node: master -> slaves in deck order.
    pub fn rigid_groups(&self) -> BTreeMap<u32, Vec<u32>> {
        let mut groups: BTreeMap<u32, Vec<u32>> = BTreeMap::new();
        for r in &self.rigid_regions {
            groups.entry(r.master).or_default().push(r.slave);
        }
        groups
    }
}

/// An informational remark about the deck (not an error).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Note {
    /// 1-based line number.
    pub line: usize,
    /// The remark, starting with the command (`NLGEOM: ...`).
    pub text: String,
}

/// A node (`N,node,x,y,z`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "N")]
pub struct Node {
    /// Node number (>= 1).
    pub id: u32,
    /// Position in global coordinates (m), converted from the coordinate system active when the
    /// node was defined. Blank coordinates are 0.
    pub position: [f64; 3],
    /// 1-based line of the `N` command.
    pub line: usize,
}

/// A Cartesian coordinate system: the global one or a `LOCAL` one.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "LOCAL")]
pub struct CoordinateSystem {
    /// Number (0 for global, >= 11 for LOCAL systems).
    pub id: u32,
    /// Origin in global coordinates (m).
    pub origin: [f64; 3],
    /// Rotation matrix, row-major (`rotation[row][col]`), whose COLUMNS are the local x, y, z axes
    /// expressed in global coordinates: `global = origin + rotation * local`.
    pub rotation: [[f64; 3]; 3],
    /// The LOCAL angles as given (degrees): THXY about Z, then THYZ about the new X, then THZX
    /// about the new Y (default: 0).
    pub angles_deg: [f64; 3],
    /// 1-based line of the `LOCAL` command (0 for the global system).
    pub line: usize,
}

impl CoordinateSystem {
    /// The global Cartesian system (CSYS 0).
    pub const GLOBAL: CoordinateSystem = CoordinateSystem {
        id: 0,
        origin: [0.0; 3],
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        angles_deg: [0.0; 3],
        line: 0,
    };

    /// Builds the system ANSYS `LOCAL,id,0,origin,thxy,thyz,thzx` defines (angles in degrees).
    pub fn from_local(id: u32, origin: [f64; 3], angles_deg: [f64; 3], line: usize) -> Self {
        let [a, b, c] = angles_deg.map(f64::to_radians);
        let rz = [
            [a.cos(), -a.sin(), 0.0],
            [a.sin(), a.cos(), 0.0],
            [0.0, 0.0, 1.0],
        ];
        let rx = [
            [1.0, 0.0, 0.0],
            [0.0, b.cos(), -b.sin()],
            [0.0, b.sin(), b.cos()],
        ];
        let ry = [
            [c.cos(), 0.0, c.sin()],
            [0.0, 1.0, 0.0],
            [-c.sin(), 0.0, c.cos()],
        ];
        CoordinateSystem {
            id,
            origin,
            rotation: mat_mul(&mat_mul(&rz, &rx), &ry),
            angles_deg,
            line,
        }
    }

    /// Why this system is not a proper Cartesian frame (a non-finite origin or rotation, or a
    /// rotation matrix that is not orthonormal with determinant +1 to 1e-9), or `None` when it
    /// is one. The parser builds only proper systems; a [`Deck`] made or deserialised by hand may
    /// hold others, which the builder refuses.
    pub fn defect(&self) -> Option<String> {
        if !self.origin.iter().all(|x| x.is_finite()) {
            return Some(format!("origin {:?} is not finite", self.origin));
        }
        let r = &self.rotation;
        if !r.iter().flatten().all(|x| x.is_finite()) {
            return Some(format!("rotation {r:?} is not finite"));
        }
        for a in 0..3 {
            for b in 0..3 {
                let dot: f64 = (0..3).map(|k| r[k][a] * r[k][b]).sum();
                let want = if a == b { 1.0 } else { 0.0 };
                if (dot - want).abs() > 1e-9 {
                    return Some(format!("rotation {r:?} is not orthonormal"));
                }
            }
        }
        let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
            - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        if (det - 1.0).abs() > 1e-9 {
            return Some(format!("rotation {r:?} has determinant {det}, not +1"));
        }
        None
    }

    /// Local axis `k` (0 = x, 1 = y, 2 = z; others give z) as a global unit vector.
    pub fn axis(&self, k: usize) -> [f64; 3] {
        let k = k.min(2);
        self.rotation.map(|row| row[k])
    }

    /// Converts a point from this system's coordinates to global coordinates.
    pub fn to_global(&self, local: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        let mut g = self.origin;
        for (gi, row) in g.iter_mut().zip(r) {
            *gi += row[0] * local[0] + row[1] * local[1] + row[2] * local[2];
        }
        g
    }
}

fn mat_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

/// The element names this reader accepts in `ET`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ElementName {
    /// MPC184 (`ET,n,MPC184` or `ET,n,184`): rigid link/beam (KEYOPT(1) = 0/1) or joint (6..19).
    #[doc(alias = "MPC184")]
    Mpc184,
    /// MASS21 (`ET,n,MASS21` or `ET,n,21`): point mass with optional rotary inertia.
    #[doc(alias = "MASS21")]
    Mass21,
    /// COMBIN14 (`ET,n,COMBIN14` or `ET,n,14`): longitudinal spring-damper between nodes I and
    /// J (KEYOPT(2) = 0, KEYOPT(3) = 0 only: 3-D, along the line of the nodes).
    #[doc(alias = "COMBIN14")]
    Combin14,
}

/// What an element is for a builder.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ElementRole {
    /// MASS21 point mass at node I.
    Mass,
    /// MPC184 KEYOPT(1) = 0: rigid link (a pin-ended bar: the distance of nodes I and J held).
    RigidLink,
    /// MPC184 KEYOPT(1) = 1: rigid beam (nodes I and J on one rigid body).
    RigidBeam,
    /// MPC184 KEYOPT(1) = 6..19: a joint (see its section).
    Joint,
    /// COMBIN14: a spring-damper between nodes I and J (real constants K, CV1, CV2, ILEN,
    /// IFORCE).
    Spring,
}

/// An element type (`ET,itype,name,k1..k6` and `KEYOPT,itype,k,value`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "ET")]
pub struct ElementType {
    /// Type number (>= 1).
    pub id: u32,
    /// The element.
    pub element: ElementName,
    /// KEYOPT(1..=18): `keyopts[k - 1]` is KEYOPT(k) (default: 0). For MPC184, KEYOPT(1) is the
    /// kind (0 rigid link, 1 rigid beam, 6..19 joints), KEYOPT(2) the constraint method
    /// (0 Lagrange, 1 penalty) and KEYOPT(4) the axis (0 e1, 1 e3). For MASS21, KEYOPT(3) = 0
    /// means 3-D mass with rotary inertia (real constants MASSX MASSY MASSZ IXX IYY IZZ), 2 means
    /// 3-D mass without rotary inertia (real constant MASS).
    #[doc(alias = "KEYOPT")]
    pub keyopts: [i64; 18],
    /// 1-based line of the `ET` command.
    pub line: usize,
}

impl ElementType {
    /// KEYOPT(k) for k in 1..=18 (0 outside that range).
    pub fn keyopt(&self, k: usize) -> i64 {
        k.checked_sub(1)
            .and_then(|i| self.keyopts.get(i))
            .copied()
            .unwrap_or(0)
    }

    /// The joint subtype KEYOPT(1) asks for (MPC184 joints only).
    pub fn joint_subtype(&self) -> Option<JointSubtype> {
        match self.element {
            ElementName::Mpc184 => JointSubtype::from_keyopt1(self.keyopt(1)),
            ElementName::Mass21 | ElementName::Combin14 => None,
        }
    }
}

/// A real constant set (`R,set,r1..r6` and `RMORE,r7..r12`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "R")]
#[doc(alias = "RMORE")]
pub struct RealConstants {
    /// Set number (>= 1).
    pub id: u32,
    /// The constants in order (`values[0]` = R1). Blank fields are 0.0, as ANSYS reads them;
    /// the list is padded to a multiple of 6. For MASS21 KEYOPT(3) = 0: MASSX MASSY MASSZ (kg)
    /// IXX IYY IZZ (kg m^2, about the node, global axes); KEYOPT(3) = 2: MASS (kg). For
    /// COMBIN14: K (N/m), CV1 (N s/m), CV2 (N s^2/m^2), two blanks, ILEN (m), IFORCE (N).
    pub values: Vec<f64>,
    /// 1-based line of the `R` command.
    pub line: usize,
}

/// An element (`E,i,j` or `EN,num,i,j`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "E")]
#[doc(alias = "EN")]
pub struct Element {
    /// Element number (>= 1). `E` takes the highest number so far plus one.
    pub id: u32,
    /// Node I (None: left blank; for a joint the I side is then grounded at J's position).
    pub i: Option<u32>,
    /// Node J (None: left blank; grounded joint side, or a one-node element such as MASS21).
    pub j: Option<u32>,
    /// Element type number (`TYPE` pointer at creation; default 1).
    #[doc(alias = "TYPE")]
    pub element_type: u32,
    /// Real constant set (`REAL` pointer at creation; default 1).
    #[doc(alias = "REAL")]
    pub real: u32,
    /// Material number (`MAT` pointer at creation; default 1): the `TB,JOIN` tables of a joint.
    #[doc(alias = "MAT")]
    pub material: u32,
    /// Section number (`SECNUM` pointer at creation; default 1): the joint section.
    #[doc(alias = "SECNUM")]
    pub section: u32,
    /// 1-based line of the `E`/`EN` command.
    pub line: usize,
}

/// One `CERIG,master,slave,dofs` constraint: the slave node moves rigidly with the master.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[doc(alias = "CERIG")]
pub struct RigidRegion {
    /// Master node.
    pub master: u32,
    /// Slave node.
    pub slave: u32,
    /// The coupled DOF labels as given, upper case (default: `["ALL"]`; also `UXYZ`, `RXYZ`,
    /// `UX` ... `ROTZ`).
    pub dofs: Vec<String>,
    /// 1-based line of the `CERIG` command.
    pub line: usize,
}

/// A joint section subtype (`SECTYPE,id,JOINT,subtype`) and the MPC184 KEYOPT(1) it goes with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum JointSubtype {
    /// `REVO`, KEYOPT(1) = 6.
    #[doc(alias = "REVO")]
    Revolute,
    /// `UNIV`, KEYOPT(1) = 7.
    #[doc(alias = "UNIV")]
    Universal,
    /// `SLOT`, KEYOPT(1) = 8.
    Slot,
    /// `PINP`, KEYOPT(1) = 9.
    #[doc(alias = "PINP")]
    PointInPlane,
    /// `PRIS`, KEYOPT(1) = 10.
    #[doc(alias = "PRIS")]
    Translational,
    /// `CYLI`, KEYOPT(1) = 11.
    #[doc(alias = "CYLI")]
    Cylindrical,
    /// `PLAN`, KEYOPT(1) = 12.
    #[doc(alias = "PLAN")]
    Planar,
    /// `WELD`, KEYOPT(1) = 13.
    Weld,
    /// `ORIE`, KEYOPT(1) = 14.
    #[doc(alias = "ORIE")]
    Orient,
    /// `SPHE`, KEYOPT(1) = 15.
    #[doc(alias = "SPHE")]
    Spherical,
    /// `GENE`, KEYOPT(1) = 16.
    #[doc(alias = "GENE")]
    General,
    /// `SCRE`, KEYOPT(1) = 17.
    #[doc(alias = "SCRE")]
    Screw,
    /// `SPOT`, KEYOPT(1) = 18.
    #[doc(alias = "SPOT")]
    Spotweld,
    /// `GENB`, KEYOPT(1) = 19.
    Genb,
}

impl JointSubtype {
    /// All subtypes in KEYOPT(1) order.
    pub const ALL: [JointSubtype; 14] = [
        JointSubtype::Revolute,
        JointSubtype::Universal,
        JointSubtype::Slot,
        JointSubtype::PointInPlane,
        JointSubtype::Translational,
        JointSubtype::Cylindrical,
        JointSubtype::Planar,
        JointSubtype::Weld,
        JointSubtype::Orient,
        JointSubtype::Spherical,
        JointSubtype::General,
        JointSubtype::Screw,
        JointSubtype::Spotweld,
        JointSubtype::Genb,
    ];

    /// The ANSYS label (`REVO`, ...).
    pub const fn label(self) -> &'static str {
        match self {
            JointSubtype::Revolute => "REVO",
            JointSubtype::Universal => "UNIV",
            JointSubtype::Slot => "SLOT",
            JointSubtype::PointInPlane => "PINP",
            JointSubtype::Translational => "PRIS",
            JointSubtype::Cylindrical => "CYLI",
            JointSubtype::Planar => "PLAN",
            JointSubtype::Weld => "WELD",
            JointSubtype::Orient => "ORIE",
            JointSubtype::Spherical => "SPHE",
            JointSubtype::General => "GENE",
            JointSubtype::Screw => "SCRE",
            JointSubtype::Spotweld => "SPOT",
            JointSubtype::Genb => "GENB",
        }
    }

    /// The MPC184 KEYOPT(1) of this subtype (6..=19).
    pub const fn keyopt1(self) -> i64 {
        self as i64 + 6
    }

    /// The subtype for a MPC184 KEYOPT(1) (None outside 6..=19).
    pub fn from_keyopt1(k: i64) -> Option<JointSubtype> {
        usize::try_from(k - 6)
            .ok()
            .and_then(|i| Self::ALL.get(i).copied())
    }

    /// Parses an ANSYS label, case-insensitive (`revo`, `REVO`).
    pub fn from_label(label: &str) -> Option<JointSubtype> {
        let up = label.trim().to_ascii_uppercase();
        Self::ALL.into_iter().find(|s| s.label() == up)
    }
}

/// A nodal or relative degree of freedom label, ANSYS order (1..6 = UX..ROTZ).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum DofLabel {
    /// `UX` (1): displacement along x (m).
    Ux,
    /// `UY` (2).
    Uy,
    /// `UZ` (3).
    Uz,
    /// `ROTX` (4): rotation about x (rad).
    RotX,
    /// `ROTY` (5).
    RotY,
    /// `ROTZ` (6).
    RotZ,
}

impl DofLabel {
    /// All six in ANSYS order.
    pub const ALL: [DofLabel; 6] = [
        DofLabel::Ux,
        DofLabel::Uy,
        DofLabel::Uz,
        DofLabel::RotX,
        DofLabel::RotY,
        DofLabel::RotZ,
    ];

    /// The ANSYS number (UX = 1 .. ROTZ = 6), as SECSTOP, SECLOCK and SECJOINT,RDOF use it.
    pub const fn number(self) -> u8 {
        self as u8 + 1
    }

    /// The DOF with ANSYS number `n` (1..=6).
    pub fn from_number(n: i64) -> Option<DofLabel> {
        usize::try_from(n - 1)
            .ok()
            .and_then(|i| Self::ALL.get(i).copied())
    }

    /// The ANSYS label (`UX` ... `ROTZ`).
    pub const fn label(self) -> &'static str {
        match self {
            DofLabel::Ux => "UX",
            DofLabel::Uy => "UY",
            DofLabel::Uz => "UZ",
            DofLabel::RotX => "ROTX",
            DofLabel::RotY => "ROTY",
            DofLabel::RotZ => "ROTZ",
        }
    }

    /// Parses `UX` ... `ROTZ` (upper case).
    pub fn from_label(s: &str) -> Option<DofLabel> {
        Self::ALL.into_iter().find(|d| d.label() == s)
    }
}

/// A force or moment label (`FX` ... `MZ`), same order as [`DofLabel`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum ForceLabel {
    /// `FX`: force along x (N).
    Fx,
    /// `FY`.
    Fy,
    /// `FZ`.
    Fz,
    /// `MX`: moment about x (N m).
    Mx,
    /// `MY`.
    My,
    /// `MZ`.
    Mz,
}

impl ForceLabel {
    /// All six in ANSYS order.
    pub const ALL: [ForceLabel; 6] = [
        ForceLabel::Fx,
        ForceLabel::Fy,
        ForceLabel::Fz,
        ForceLabel::Mx,
        ForceLabel::My,
        ForceLabel::Mz,
    ];

    /// The ANSYS label.
    pub const fn label(self) -> &'static str {
        match self {
            ForceLabel::Fx => "FX",
            ForceLabel::Fy => "FY",
            ForceLabel::Fz => "FZ",
            ForceLabel::Mx => "MX",
            ForceLabel::My => "MY",
            ForceLabel::Mz => "MZ",
        }
    }

    /// Parses `FX` ... `MZ` (upper case).
    pub fn from_label(s: &str) -> Option<ForceLabel> {
        Self::ALL.into_iter().find(|d| d.label() == s)
    }

    /// The DOF this force or moment acts on.
    pub const fn dof(self) -> DofLabel {
        DofLabel::ALL[self as usize]
    }
}

/// How `SECJOINT,LSYS` picks the spotweld frame from the I-to-J vector (`IJX`, `IJY`, `IJZ`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum NodeAxis {
    /// `IJX`: local x along I to J.
    X,
    /// `IJY`: local y along I to J.
    Y,
    /// `IJZ`: local z along I to J.
    Z,
}

/// Where a spotweld's centre lies (`SECJOINT,SPWE`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum SpotweldCenter {
    /// `SPWE,RATIO,r`: at I + r (J - I), 0 <= r <= 1.
    Ratio(f64),
    /// `SPWE,COORD,x,y,z`: at this point (m, global).
    Coord([f64; 3]),
}

/// A min/max range on one relative DOF (`SECSTOP` or `SECLOCK`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DofRange {
    /// The relative DOF, in the local frame at node I.
    pub dof: DofLabel,
    /// Lower limit (m or rad, absolute value of the relative DOF; blank reads as 0).
    pub min: f64,
    /// Upper limit (m or rad; blank reads as 0).
    pub max: f64,
    /// 1-based line of the command.
    pub line: usize,
}

/// A joint section: `SECTYPE,id,JOINT,subtype` and what follows it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "SECTYPE")]
pub struct JointSection {
    /// Section number.
    pub id: u32,
    /// The subtype.
    pub subtype: JointSubtype,
    /// Optional section name (5th SECTYPE field; default: none).
    pub name: Option<String>,
    /// `SECJOINT,LSYS,cs1,cs2` first field: coordinate system at node I (default: none given;
    /// ANSYS requires one, 0 is the global system).
    #[doc(alias = "LSYS")]
    pub lsys_i: Option<u32>,
    /// `SECJOINT,LSYS,cs1,cs2` second field: coordinate system at node J (default: none, meaning
    /// the system at I).
    pub lsys_j: Option<u32>,
    /// `SECJOINT,LSYS,IJX|IJY|IJZ` (spotweld only; default: none).
    pub lsys_from_nodes: Option<NodeAxis>,
    /// `SECJOINT,RDOF,d1..d6`: the relative DOFs FIXED (constrained) by a general or genb joint,
    /// as the ANSYS SECJOINT documentation states (default: none).
    #[doc(alias = "RDOF")]
    pub fixed_dofs: Vec<DofLabel>,
    /// `SECJOINT,PITC,p`: screw pitch, relative axial displacement per radian of relative
    /// rotation (m/rad; default: none).
    #[doc(alias = "PITC")]
    pub pitch: Option<f64>,
    /// `SECJOINT,FRIC,v1,v2,v3`: friction geometry (m). Revolute: outer radius, inner radius,
    /// effective length; translational: effective length, effective radius; spherical: effective
    /// radius (default: none given).
    #[doc(alias = "FRIC")]
    pub friction_geometry: [Option<f64>; 3],
    /// `SECJOINT,PNLT,DISP,v`: penalty for displacement constraints; v > 0 scales the internal
    /// penalty, v < 0 gives |v| as the absolute penalty (N/m) (default: none).
    #[doc(alias = "PNLT")]
    pub penalty_displacement: Option<f64>,
    /// `SECJOINT,PNLT,ROT,v`: the same for rotation constraints (N m/rad) (default: none).
    pub penalty_rotation: Option<f64>,
    /// `SECJOINT,SPWE,...`: spotweld centre (default: none, midway between I and J).
    #[doc(alias = "SPWE")]
    pub spotweld_center: Option<SpotweldCenter>,
    /// `SECDATA,length1,length2,length3,angle1,angle2,angle3`: reference values of the free
    /// relative DOFs as given (lengths in m; angles as given, ANSYS joint reference angles are in
    /// radians like every joint rotation); None where not given, meaning the initial
    /// configuration is the reference.
    #[doc(alias = "SECDATA")]
    pub reference: [Option<f64>; 6],
    /// `SECSTOP` ranges, at most one per DOF (a later one replaces an earlier one).
    #[doc(alias = "SECSTOP")]
    pub stops: Vec<DofRange>,
    /// `SECLOCK` ranges, at most one per DOF (a later one replaces an earlier one).
    #[doc(alias = "SECLOCK")]
    pub locks: Vec<DofRange>,
    /// 1-based line of the `SECTYPE` command.
    pub line: usize,
}

impl JointSection {
    /// A section with nothing but its id, subtype and line.
    pub fn new(id: u32, subtype: JointSubtype, line: usize) -> Self {
        JointSection {
            id,
            subtype,
            name: None,
            lsys_i: None,
            lsys_j: None,
            lsys_from_nodes: None,
            fixed_dofs: Vec::new(),
            pitch: None,
            friction_geometry: [None; 3],
            penalty_displacement: None,
            penalty_rotation: None,
            spotweld_center: None,
            reference: [None; 6],
            stops: Vec::new(),
            locks: Vec::new(),
            line,
        }
    }
}

/// One `TB,JOIN,mat,ntemp,npts,TBOPT` table with its `TBDATA` constants and `TBPT` points.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "TB")]
#[doc(alias = "JOIN")]
pub struct JoinTable {
    /// Material number (default: 1).
    pub material: u32,
    /// TBOPT as given, upper case: `STIF`, `DAMP`, `JNSA`, `JNS1`..`JNS6`, `JNDA`, `JND1`..`JND6`,
    /// `MUS1`/`MUS4`/`MUS6`, `EXP1`.., `SL1`.., `SK1`.., `TMX1`.., `FI1`.. (n = 1 UX, 4 ROTX, 6 ROTZ).
    pub tbopt: String,
    /// Number of temperatures (always 1 here; more are rejected).
    pub ntemp: u32,
    /// NPTS as given (default: 0): number of TBPT points announced.
    pub npts: u32,
    /// `TBTEMP` temperature of the data (default: none).
    #[doc(alias = "TBTEMP")]
    pub temperature: Option<f64>,
    /// Constants from `TBDATA`: `constants[k - 1]` is Ck (None where never given). For STIF and
    /// DAMP, C1..C21 are the lower triangle of the 6x6 matrix by columns (N/m, N m/rad, N s/m ...);
    /// for `MUSn`, C1 is the static friction coefficient; for `EXPn`, C1..C3 = static and dynamic
    /// coefficients and the decay coefficient (s/m).
    #[doc(alias = "TBDATA")]
    pub constants: Vec<Option<f64>>,
    /// `TBPT` points (x, y) in order: relative displacement/rotation/velocity against force or
    /// moment, or (for `MUSn` with NPTS > 0) the table the option defines.
    #[doc(alias = "TBPT")]
    pub points: Vec<[f64; 2]>,
    /// 1-based line of the `TB` command.
    pub line: usize,
}

/// A nodal displacement constraint (`D,node,label,value`): global axes (nodes are not rotated).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "D")]
pub struct NodalConstraint {
    /// Node number.
    pub node: u32,
    /// Constrained DOF.
    pub dof: DofLabel,
    /// Imposed value (m or rad; blank reads as 0).
    pub value: f64,
    /// 1-based line of the command.
    pub line: usize,
}

/// A nodal force or moment (`F,node,label,value`): global axes.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "F")]
pub struct NodalForce {
    /// Node number.
    pub node: u32,
    /// Component.
    pub label: ForceLabel,
    /// Value (N or N m; blank reads as 0).
    pub value: f64,
    /// 1-based line of the command.
    pub line: usize,
}

/// What a `DJ` imposes on a relative DOF.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum MotionKind {
    /// `UX`..`ROTZ`: relative displacement (m) or rotation (rad).
    Displacement,
    /// `VELX`..`VELZ`, `OMGX`..`OMGZ`: relative velocity (m/s, rad/s).
    Velocity,
    /// `ACCX`..`ACCZ`, `DMGX`..`DMGZ`: relative acceleration (m/s^2, rad/s^2).
    Acceleration,
}

/// A joint relative-motion boundary condition (`DJ,elem,label,value`) on a free relative DOF, in
/// the local frame at node I. One per element and DOF: the last DJ on a DOF wins.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "DJ")]
pub struct JointMotion {
    /// Joint element number.
    pub element: u32,
    /// Relative DOF.
    pub dof: DofLabel,
    /// Displacement, velocity or acceleration.
    pub kind: MotionKind,
    /// Value (see [`MotionKind`] for units; blank reads as 0).
    pub value: f64,
    /// 1-based line of the command.
    pub line: usize,
}

impl JointMotion {
    /// The ANSYS label (`ROTZ`, `OMGZ`, `DMGZ`, ...).
    pub fn label(&self) -> &'static str {
        const LABELS: [[&str; 6]; 3] = [
            ["UX", "UY", "UZ", "ROTX", "ROTY", "ROTZ"],
            ["VELX", "VELY", "VELZ", "OMGX", "OMGY", "OMGZ"],
            ["ACCX", "ACCY", "ACCZ", "DMGX", "DMGY", "DMGZ"],
        ];
        let k = match self.kind {
            MotionKind::Displacement => 0,
            MotionKind::Velocity => 1,
            MotionKind::Acceleration => 2,
        };
        LABELS[k][self.dof as usize]
    }

    /// Parses a DJ label into (DOF, kind).
    pub fn parse_label(s: &str) -> Option<(DofLabel, MotionKind)> {
        if let Some(d) = DofLabel::from_label(s) {
            return Some((d, MotionKind::Displacement));
        }
        let (kind, axis) = match s.get(..3)? {
            "VEL" => (MotionKind::Velocity, 0),
            "OMG" => (MotionKind::Velocity, 3),
            "ACC" => (MotionKind::Acceleration, 0),
            "DMG" => (MotionKind::Acceleration, 3),
            _ => return None,
        };
        let offset = match s.get(3..)? {
            "X" => 0,
            "Y" => 1,
            "Z" => 2,
            _ => return None,
        };
        DofLabel::ALL.get(axis + offset).map(|d| (*d, kind))
    }
}

/// A joint relative force or moment (`FJ,elem,label,value`) on a free relative DOF, in the local
/// frame at node I.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "FJ")]
pub struct JointLoad {
    /// Joint element number.
    pub element: u32,
    /// Component.
    pub label: ForceLabel,
    /// Value (N or N m; blank reads as 0).
    pub value: f64,
    /// 1-based line of the command.
    pub line: usize,
}

/// An initial condition (`IC,node,label,value,velocity`), global axes, at time 0.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "IC")]
pub struct InitialCondition {
    /// Node number.
    pub node: u32,
    /// DOF.
    pub dof: DofLabel,
    /// Initial displacement (m or rad; default 0).
    pub displacement: f64,
    /// Initial velocity (m/s or rad/s; default 0).
    pub velocity: f64,
    /// 1-based line of the command.
    pub line: usize,
}

/// The analysis type (`ANTYPE`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[doc(alias = "ANTYPE")]
pub enum AnalysisType {
    /// `STATIC` or 0 (the ANSYS default).
    #[default]
    Static,
    /// `TRANS` or 4 (full transient).
    Transient,
}

/// How loads change over a load step (`KBC`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[doc(alias = "KBC")]
pub enum LoadRamp {
    /// `KBC,0` (default): loads ramp linearly from the previous load step's values.
    #[default]
    Ramped,
    /// `KBC,1`: loads jump to their new values at the start of the step.
    Stepped,
}

/// `DELTIM,dt,dtmin,dtmax`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "DELTIM")]
pub struct TimeIncrement {
    /// Time step (s).
    pub dt: f64,
    /// Minimum time step (s; default: none).
    pub min: Option<f64>,
    /// Maximum time step (s; default: none).
    pub max: Option<f64>,
}

/// `NSUBST,n,nmax,nmin`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[doc(alias = "NSUBST")]
pub struct Substeps {
    /// Number of substeps in the load step.
    pub n: u32,
    /// Maximum number (default: none).
    pub max: Option<u32>,
    /// Minimum number (default: none).
    pub min: Option<u32>,
}

/// `OUTRES,Item,Freq`: at which steps of a load step the results are written (a step of the
/// deck's `DELTIM` or `NSUBST` is ANSYS's substep; `AUTOTS`'s own substeps inside it are not
/// rows, their count and sizes are in the run summary).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[doc(alias = "OUTRES")]
pub enum OutputFrequency {
    /// `ALL` (or a blank `Freq`): every step.
    All,
    /// `n`: every `n`-th step and the last of the load step.
    Every(u32),
    /// `-n`: up to `n` equally spaced: the load step's time divided into `n` equal intervals,
    /// the last step in each written.
    Spaced(u32),
    /// `LAST`: the last step of the load step.
    Last,
    /// `NONE`: no step of the load step (a run that stops in it still writes its last good
    /// state).
    None,
}

impl OutputFrequency {
    /// Whether step `i` (0-based) of a load step of `steps` steps is written.
    pub fn writes(self, i: usize, steps: usize) -> bool {
        let last = i + 1 == steps;
        match self {
            OutputFrequency::All => true,
            OutputFrequency::Every(n) => last || (i + 1).is_multiple_of(n.max(1) as usize),
            OutputFrequency::Spaced(n) => {
                // Step `s` (1-based) ends in interval `ceil(s n / steps)`; it is the last one
                // there when step `s + 1` ends in the next.
                let n = n.max(1) as usize;
                let interval = |s: usize| (s * n).div_ceil(steps);
                last || interval(i + 2) > interval(i + 1)
            }
            OutputFrequency::Last => last,
            OutputFrequency::None => false,
        }
    }
}

/// The state of the loads and solution options at one `SOLVE`.
///
/// Loads persist from one load step to the next until deleted (`DDELE`, `FDELE`, `DJDELE`,
/// `FJDELE`) or overwritten, as in ANSYS. Lists are sorted by node or element, then DOF.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[doc(alias = "SOLVE")]
pub struct LoadStep {
    /// 1-based load step number.
    pub number: usize,
    /// Time at the end of the step (s; `TIME`, default: previous end time + 1).
    #[doc(alias = "TIME")]
    pub end_time: f64,
    /// `DELTIM` in effect (default: none). DELTIM and NSUBST replace each other.
    pub deltim: Option<TimeIncrement>,
    /// `NSUBST` in effect (default: none).
    pub nsubst: Option<Substeps>,
    /// `AUTOTS` in effect (default: off): the substeps of each step are chosen to a tolerance.
    #[doc(alias = "AUTOTS")]
    #[serde(default)]
    pub autots: bool,
    /// `MIDTOL,ON,TOLERB` in effect (`Some(None)`: on with the default tolerance).
    #[doc(alias = "MIDTOL")]
    #[serde(default)]
    pub midtol: Option<Option<f64>>,
    /// `OUTRES` in effect (`None`: not given, or reset by `OUTRES,ERASE`; the program writes
    /// every step then unless told otherwise, see `mpc184 run --every`).
    #[doc(alias = "OUTRES")]
    #[serde(default)]
    pub outres: Option<OutputFrequency>,
    /// `KBC` in effect (default: ramped).
    pub kbc: LoadRamp,
    /// `ANTYPE` in effect (default: static).
    pub antype: AnalysisType,
    /// Nodal constraints (`D`).
    pub d: Vec<NodalConstraint>,
    /// Nodal forces (`F`).
    pub f: Vec<NodalForce>,
    /// Joint relative motions (`DJ`).
    pub dj: Vec<JointMotion>,
    /// Joint relative forces (`FJ`).
    pub fj: Vec<JointLoad>,
    /// `ACEL,ax,ay,az` (m/s^2, global), stored as given in the ANSYS convention: this is the
    /// acceleration of the reference frame, so bodies feel the opposite: `ACEL,0,9.81,0` means
    /// gravity pulls toward -Y. A builder sets gravity = -acel. (default: 0)
    #[doc(alias = "ACEL")]
    pub acel: [f64; 3],
    /// 1-based line of the `SOLVE` command.
    pub line: usize,
}
