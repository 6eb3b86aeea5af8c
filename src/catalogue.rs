//! The MPC184 joint catalogue: KEYOPT(1) = 6..19 with their KEYOPT(4) variants, and the
//! pin-ended rigid link (KEYOPT(1) = 0).
//!
//! Node I is `1`, node J is `2` everywhere. Relative DOFs are those of J with respect to I,
//! measured in the local coordinate system at node I (see [`crate::dof`]).
//!
//! | kind | KEYOPT(1)/(4) | subtype | constrained | free | Rapier X axis | rows Rapier cannot express |
//! |---|---|---|---|---|---|---|
//! | revolute x | 6/0 | REVO | UX UY UZ ROTY ROTZ | ROTX | e1 | none |
//! | revolute z | 6/1 | REVO | UX UY UZ ROTX ROTY | ROTZ | e3 | none |
//! | universal | 7 | UNIV | UX UY UZ ROTY | ROTX ROTZ | e1 | ROTY as `e1I.e3J` (Rapier uses a quaternion component) |
//! | slot | 8 | SLOT | UY UZ | UX, rotations | e1 | none |
//! | point-in-plane | 9 | PINP | UX | UY UZ, rotations | e1 | none |
//! | translational | 10 | PRIS | UY UZ ROTX ROTY ROTZ | UX | e1 | none |
//! | cylindrical x | 11/0 | CYLI | UY UZ ROTY ROTZ | UX ROTX | e1 | none |
//! | cylindrical z | 11/1 | CYLI | UX UY ROTX ROTY | UZ ROTZ | e3 | none |
//! | planar x | 12/0 | PLAN | UX ROTY ROTZ | UY UZ ROTX | e1 | none |
//! | planar z | 12/1 | PLAN | UZ ROTX ROTY | UX UY ROTZ | e3 | none |
//! | weld | 13 | WELD | all six | none | e1 | none |
//! | orient | 14 | ORIE | ROTX ROTY ROTZ | UX UY UZ | e1 | none |
//! | spherical | 15 | SPHE | UX UY UZ | rotations | e1 | none |
//! | general | 16/0, 16/1 | GENE | all but SECJOINT,RDOF (16/1: rotations released too) | the rest | e1 | none |
//! | screw | 17 | SCRE | UX UY ROTX ROTY + UZ = p ROTZ | ROTZ | e3 | the pitch coupling |
//! | spotweld | 18 | SPOT | none (6x6 spring/damper) | all | e1 | the spring/damper |
//! | genb | 19/0, 19/1 | GENB | as general, rotations as 3-1-3 Euler angles | the rest | e1 | none |
//! | rigid link | 0 | (none) | one row: the distance `\|x_J - x_I\| = L` (no single DOF) | none as coordinates | e1 | the distance row (no Rapier mask holds a distance) |
//!
//! The rigid link is a pin-ended rigid bar between node I on body 1 and node J on body 2: one
//! equation, `|x_J - x_I|` held at its initial value, no rotational coupling. Its relative DOFs
//! are neither constrained one by one nor free coordinates (the six are tied by the one
//! equation), so it takes no drives, loads, stops, locks, springs or friction. Its reaction is
//! an axial force along the link ([`crate::world::JointOutput::axial_force`]).

use serde::{Deserialize, Serialize};

use crate::dof::{Dof, DofMask};
use crate::error::Error;
use crate::math::Real;

/// Which axis of frame I a hinge-like joint turns about or slides along (KEYOPT(4)).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Axis {
    /// e1, KEYOPT(4) = 0 (the default).
    X,
    /// e3, KEYOPT(4) = 1.
    Z,
}

/// One MPC184 joint type (KEYOPT(1) = 6..19 with its KEYOPT(4) variant), or the rigid link
/// (KEYOPT(1) = 0).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum JointKind {
    /// Revolute joint (KEYOPT(1) = 6): free rotation about e1 (`Axis::X`) or e3 (`Axis::Z`).
    #[doc(alias = "REVO")]
    Revolute {
        /// Hinge axis (KEYOPT(4)).
        axis: Axis,
    },
    /// Universal joint (KEYOPT(1) = 7): ROTX and ROTZ free, the angle between e1 of I and e3 of J held.
    #[doc(alias = "UNIV")]
    Universal,
    /// Slot joint (KEYOPT(1) = 8): node J stays on the e1 line of I; all rotations free.
    #[doc(alias = "SLOT")]
    Slot,
    /// Point-in-plane joint (KEYOPT(1) = 9): node J stays in the e2-e3 plane of I.
    #[doc(alias = "PINP")]
    PointInPlane,
    /// Translational (prismatic) joint (KEYOPT(1) = 10): sliding along e1 only.
    #[doc(alias = "PRIS")]
    #[doc(alias = "prismatic")]
    Translational,
    /// Cylindrical joint (KEYOPT(1) = 11): sliding along and turning about e1 or e3.
    #[doc(alias = "CYLI")]
    Cylindrical {
        /// Axis (KEYOPT(4)).
        axis: Axis,
    },
    /// Planar joint (KEYOPT(1) = 12): motion in the plane normal to e1 or e3.
    #[doc(alias = "PLAN")]
    Planar {
        /// Plane normal (KEYOPT(4)).
        axis: Axis,
    },
    /// Weld joint (KEYOPT(1) = 13): all six relative DOFs fixed.
    #[doc(alias = "WELD")]
    #[doc(alias = "fixed")]
    Weld,
    /// Orient joint (KEYOPT(1) = 14): rotations fixed, translations free.
    #[doc(alias = "ORIE")]
    Orient,
    /// Spherical joint (KEYOPT(1) = 15): translations fixed, rotations free.
    #[doc(alias = "SPHE")]
    #[doc(alias = "ball")]
    Spherical,
    /// General joint (KEYOPT(1) = 16): every DOF fixed except those released by SECJOINT,RDOF.
    #[doc(alias = "GENE")]
    General {
        /// DOFs released by `SECJOINT,RDOF`.
        #[doc(alias = "RDOF")]
        released: DofMask,
        /// KEYOPT(4) = 1: the nodes carry displacements only, so every rotation is free.
        translations_only: bool,
    },
    /// Screw joint (KEYOPT(1) = 17): cylindrical about e3 with `UZ = pitch * (ROTZ - ROTZ0)`.
    #[doc(alias = "SCRE")]
    #[doc(alias = "helical")]
    Screw {
        /// Axial travel per radian of relative rotation (m/rad, `SECJOINT,PITC`; positive: a
        /// positive ROTZ moves J along +e3).
        #[doc(alias = "PITC")]
        pitch: Real,
    },
    /// Spot weld (KEYOPT(1) = 18): no rigid constraint, a 6x6 spring/damper at a centre point.
    #[doc(alias = "SPOT")]
    #[doc(alias = "SPWE")]
    Spotweld,
    /// General joint with 3-1-3 Euler rotation measures (KEYOPT(1) = 19).
    #[doc(alias = "GENB")]
    Genb {
        /// DOFs released by `SECJOINT,RDOF`.
        #[doc(alias = "RDOF")]
        released: DofMask,
        /// KEYOPT(4) = 1: translations only, every rotation free.
        translations_only: bool,
    },
    /// Rigid link (KEYOPT(1) = 0): a pin-ended rigid bar, `|x_J - x_I|` held at its length at
    /// time 0 (one constraint equation, no rotational coupling; the nodes must be distinct).
    #[doc(alias = "LINK")]
    #[doc(alias = "distance")]
    RigidLink,
}

use Dof::{RotX, RotY, RotZ, Ux, Uy, Uz};

impl JointKind {
    /// One representative of every variant (both axes where KEYOPT(4) matters), for exhaustive
    /// walks in tests and tables. General and genb appear with nothing released, screw with a
    /// pitch of 0.01 m/rad. The rigid link comes last (it needs distinct nodes).
    pub fn representatives() -> Vec<JointKind> {
        let mut v = Vec::new();
        for kind in [
            JointKind::Revolute { axis: Axis::X },
            JointKind::Universal,
            JointKind::Slot,
            JointKind::PointInPlane,
            JointKind::Translational,
            JointKind::Cylindrical { axis: Axis::X },
            JointKind::Planar { axis: Axis::X },
            JointKind::Weld,
            JointKind::Orient,
            JointKind::Spherical,
            JointKind::General {
                released: DofMask::NONE,
                translations_only: false,
            },
            JointKind::Screw { pitch: 0.01 },
            JointKind::Spotweld,
            JointKind::Genb {
                released: DofMask::NONE,
                translations_only: false,
            },
            JointKind::RigidLink,
        ] {
            // Exhaustive match: a new variant must be listed here.
            match kind {
                JointKind::Revolute { .. } => {
                    v.push(JointKind::Revolute { axis: Axis::X });
                    v.push(JointKind::Revolute { axis: Axis::Z });
                }
                JointKind::Cylindrical { .. } => {
                    v.push(JointKind::Cylindrical { axis: Axis::X });
                    v.push(JointKind::Cylindrical { axis: Axis::Z });
                }
                JointKind::Planar { .. } => {
                    v.push(JointKind::Planar { axis: Axis::X });
                    v.push(JointKind::Planar { axis: Axis::Z });
                }
                JointKind::General { .. } => {
                    v.push(kind);
                    v.push(JointKind::General {
                        released: DofMask::NONE,
                        translations_only: true,
                    });
                }
                JointKind::Genb { .. } => {
                    v.push(kind);
                    v.push(JointKind::Genb {
                        released: DofMask::NONE,
                        translations_only: true,
                    });
                }
                JointKind::Universal
                | JointKind::Slot
                | JointKind::PointInPlane
                | JointKind::Translational
                | JointKind::Weld
                | JointKind::Orient
                | JointKind::Spherical
                | JointKind::Screw { .. }
                | JointKind::Spotweld
                | JointKind::RigidLink => v.push(kind),
            }
        }
        v
    }

    /// Builds a kind from the element's KEYOPT(1) and KEYOPT(4), the released DOFs of
    /// `SECJOINT,RDOF` (general and genb only) and the pitch of `SECJOINT,PITC` (screw only).
    /// KEYOPT(1) = 0 is the rigid link (its KEYOPT(4) is not read).
    pub fn from_keyopts(
        keyopt1: i64,
        keyopt4: i64,
        released: DofMask,
        pitch: Real,
    ) -> Result<JointKind, Error> {
        let axis = |k4: i64| match k4 {
            0 => Ok(Axis::X),
            1 => Ok(Axis::Z),
            other => Err(Error::InvalidKeyopt {
                keyopt: 4,
                value: other,
                reason: "KEYOPT(4) must be 0 (e1 axis) or 1 (e3 axis)".into(),
            }),
        };
        let gen_k4 = |k4: i64| match k4 {
            0 => Ok(false),
            1 => Ok(true),
            other => Err(Error::InvalidKeyopt {
                keyopt: 4,
                value: other,
                reason:
                    "KEYOPT(4) must be 0 (displacements and rotations) or 1 (displacements only)"
                        .into(),
            }),
        };
        Ok(match keyopt1 {
            6 => JointKind::Revolute {
                axis: axis(keyopt4)?,
            },
            7 => JointKind::Universal,
            8 => JointKind::Slot,
            9 => JointKind::PointInPlane,
            10 => JointKind::Translational,
            11 => JointKind::Cylindrical {
                axis: axis(keyopt4)?,
            },
            12 => JointKind::Planar {
                axis: axis(keyopt4)?,
            },
            13 => JointKind::Weld,
            14 => JointKind::Orient,
            15 => JointKind::Spherical,
            16 => JointKind::General {
                released,
                translations_only: gen_k4(keyopt4)?,
            },
            17 => JointKind::Screw { pitch },
            18 => JointKind::Spotweld,
            19 => JointKind::Genb {
                released,
                translations_only: gen_k4(keyopt4)?,
            },
            0 => JointKind::RigidLink,
            1..=5 => {
                return Err(Error::Unsupported {
                    what: format!("MPC184 KEYOPT(1) = {keyopt1} (rigid beam, slider, ...)"),
                    hint: "only the rigid link (KEYOPT(1) = 0) and the joint types KEYOPT(1) = \
                           6..19 are joints; rigid beams are handled by the deck reader as rigid \
                           bodies"
                        .into(),
                });
            }
            other => {
                return Err(Error::InvalidKeyopt {
                    keyopt: 1,
                    value: other,
                    reason: "MPC184 joints have KEYOPT(1) = 0 (rigid link) or 6..19".into(),
                });
            }
        })
    }

    /// KEYOPT(1).
    pub const fn keyopt1(&self) -> i64 {
        match self {
            JointKind::Revolute { .. } => 6,
            JointKind::Universal => 7,
            JointKind::Slot => 8,
            JointKind::PointInPlane => 9,
            JointKind::Translational => 10,
            JointKind::Cylindrical { .. } => 11,
            JointKind::Planar { .. } => 12,
            JointKind::Weld => 13,
            JointKind::Orient => 14,
            JointKind::Spherical => 15,
            JointKind::General { .. } => 16,
            JointKind::Screw { .. } => 17,
            JointKind::Spotweld => 18,
            JointKind::Genb { .. } => 19,
            JointKind::RigidLink => 0,
        }
    }

    /// KEYOPT(4) (0 when the kind has no variant).
    pub const fn keyopt4(&self) -> i64 {
        match self {
            JointKind::Revolute { axis }
            | JointKind::Cylindrical { axis }
            | JointKind::Planar { axis } => match axis {
                Axis::X => 0,
                Axis::Z => 1,
            },
            JointKind::General {
                translations_only, ..
            }
            | JointKind::Genb {
                translations_only, ..
            } => *translations_only as i64,
            JointKind::Universal
            | JointKind::Slot
            | JointKind::PointInPlane
            | JointKind::Translational
            | JointKind::Weld
            | JointKind::Orient
            | JointKind::Spherical
            | JointKind::Screw { .. }
            | JointKind::Spotweld
            | JointKind::RigidLink => 0,
        }
    }

    /// The ANSYS section subtype (`SECTYPE,id,JOINT,subtype`); empty for the rigid link, which
    /// has no joint section.
    pub const fn subtype(&self) -> &'static str {
        match self {
            JointKind::Revolute { .. } => "REVO",
            JointKind::Universal => "UNIV",
            JointKind::Slot => "SLOT",
            JointKind::PointInPlane => "PINP",
            JointKind::Translational => "PRIS",
            JointKind::Cylindrical { .. } => "CYLI",
            JointKind::Planar { .. } => "PLAN",
            JointKind::Weld => "WELD",
            JointKind::Orient => "ORIE",
            JointKind::Spherical => "SPHE",
            JointKind::General { .. } => "GENE",
            JointKind::Screw { .. } => "SCRE",
            JointKind::Spotweld => "SPOT",
            JointKind::Genb { .. } => "GENB",
            JointKind::RigidLink => "",
        }
    }

    /// A short human name (`"revolute z"`).
    pub const fn name(&self) -> &'static str {
        match self {
            JointKind::Revolute { axis: Axis::X } => "revolute x",
            JointKind::Revolute { axis: Axis::Z } => "revolute z",
            JointKind::Universal => "universal",
            JointKind::Slot => "slot",
            JointKind::PointInPlane => "point-in-plane",
            JointKind::Translational => "translational",
            JointKind::Cylindrical { axis: Axis::X } => "cylindrical x",
            JointKind::Cylindrical { axis: Axis::Z } => "cylindrical z",
            JointKind::Planar { axis: Axis::X } => "planar x",
            JointKind::Planar { axis: Axis::Z } => "planar z",
            JointKind::Weld => "weld",
            JointKind::Orient => "orient",
            JointKind::Spherical => "spherical",
            JointKind::General { .. } => "general",
            JointKind::Screw { .. } => "screw",
            JointKind::Spotweld => "spotweld",
            JointKind::Genb { .. } => "genb",
            JointKind::RigidLink => "rigid link",
        }
    }

    /// The relative DOFs held fixed by plain (uncoupled) constraint rows. The screw's UZ, tied
    /// to ROTZ by the pitch, is not in this set: see [`JointKind::coupled`]. The rigid link
    /// holds no single DOF (its one row is the distance).
    pub const fn constrained(&self) -> DofMask {
        match self {
            JointKind::Revolute { axis: Axis::X } => DofMask::of(&[Ux, Uy, Uz, RotY, RotZ]),
            JointKind::Revolute { axis: Axis::Z } => DofMask::of(&[Ux, Uy, Uz, RotX, RotY]),
            JointKind::Universal => DofMask::of(&[Ux, Uy, Uz, RotY]),
            JointKind::Slot => DofMask::of(&[Uy, Uz]),
            JointKind::PointInPlane => DofMask::of(&[Ux]),
            JointKind::Translational => DofMask::of(&[Uy, Uz, RotX, RotY, RotZ]),
            JointKind::Cylindrical { axis: Axis::X } => DofMask::of(&[Uy, Uz, RotY, RotZ]),
            JointKind::Cylindrical { axis: Axis::Z } => DofMask::of(&[Ux, Uy, RotX, RotY]),
            JointKind::Planar { axis: Axis::X } => DofMask::of(&[Ux, RotY, RotZ]),
            JointKind::Planar { axis: Axis::Z } => DofMask::of(&[Uz, RotX, RotY]),
            JointKind::Weld => DofMask::ALL,
            JointKind::Orient => DofMask::ROTATIONS,
            JointKind::Spherical => DofMask::TRANSLATIONS,
            JointKind::General {
                released,
                translations_only,
            }
            | JointKind::Genb {
                released,
                translations_only,
            } => {
                let free = if *translations_only {
                    released.union(DofMask::ROTATIONS)
                } else {
                    *released
                };
                free.complement()
            }
            JointKind::Screw { .. } => DofMask::of(&[Ux, Uy, RotX, RotY]),
            JointKind::Spotweld | JointKind::RigidLink => DofMask::NONE,
        }
    }

    /// A coupled pair `(slave, master)`: the screw's `UZ = pitch * ROTZ`.
    pub const fn coupled(&self) -> Option<(Dof, Dof)> {
        match self {
            JointKind::Screw { .. } => Some((Uz, RotZ)),
            _ => None,
        }
    }

    /// The relative DOFs left free (independent coordinates of the joint). None for the rigid
    /// link: its six relative DOFs are tied together by the distance, none is a coordinate.
    pub const fn free(&self) -> DofMask {
        if let JointKind::RigidLink = self {
            return DofMask::NONE;
        }
        let c = self.constrained();
        match self.coupled() {
            Some((slave, _)) => DofMask(c.complement().0 & !(1 << slave.index())),
            None => c.complement(),
        }
    }

    /// Number of scalar constraint equations (the screw coupling and the rigid link's distance
    /// count as one each).
    pub const fn constraint_count(&self) -> usize {
        let extra = match self {
            JointKind::RigidLink => 1,
            _ if self.coupled().is_some() => 1,
            _ => 0,
        };
        self.constrained().count() + extra
    }

    /// The axis of frame I (0 = e1, 2 = e3) that is mapped onto Rapier's principal X axis.
    pub const fn principal_axis(&self) -> usize {
        match self {
            JointKind::Revolute { axis: Axis::Z }
            | JointKind::Cylindrical { axis: Axis::Z }
            | JointKind::Planar { axis: Axis::Z }
            | JointKind::Screw { .. } => 2,
            _ => 0,
        }
    }
}
