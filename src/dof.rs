//! The six relative degrees of freedom of an MPC184 joint and sets of them.
//!
//! ANSYS numbers the relative DOFs 1..6 = UX, UY, UZ, ROTX, ROTY, ROTZ, measured in the local
//! coordinate system of node I (`1`). [`DofMask`] is a set of them (bit `i` = DOF number `i + 1`),
//! the same bit layout as Rapier's `JointAxesMask` before any axis permutation.

use serde::{Deserialize, Serialize};

/// One relative degree of freedom of a joint, in ANSYS order (1..6 = UX..ROTZ).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Dof {
    /// Relative displacement along e1 of frame I (m).
    Ux,
    /// Relative displacement along e2 of frame I (m).
    Uy,
    /// Relative displacement along e3 of frame I (m).
    Uz,
    /// Relative rotation about e1 (rad, Bryant angle psi).
    RotX,
    /// Relative rotation about e2 (rad, Bryant angle phi).
    RotY,
    /// Relative rotation about e3 (rad, Bryant angle theta).
    RotZ,
}

impl Dof {
    /// All six DOFs in ANSYS order.
    pub const ALL: [Dof; 6] = [Dof::Ux, Dof::Uy, Dof::Uz, Dof::RotX, Dof::RotY, Dof::RotZ];

    /// Zero-based index (UX = 0 .. ROTZ = 5).
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The ANSYS DOF number (UX = 1 .. ROTZ = 6), as used by SECSTOP, SECLOCK and SECJOINT,RDOF.
    pub const fn number(self) -> u8 {
        self as u8 + 1
    }

    /// The DOF with ANSYS number `n` (1..=6).
    pub const fn from_number(n: u8) -> Option<Dof> {
        match n {
            1..=6 => Some(Dof::ALL[(n - 1) as usize]),
            _ => None,
        }
    }

    /// The ANSYS label (`UX` .. `ROTZ`).
    pub const fn label(self) -> &'static str {
        match self {
            Dof::Ux => "UX",
            Dof::Uy => "UY",
            Dof::Uz => "UZ",
            Dof::RotX => "ROTX",
            Dof::RotY => "ROTY",
            Dof::RotZ => "ROTZ",
        }
    }

    /// True for ROTX, ROTY, ROTZ.
    pub const fn is_rotation(self) -> bool {
        self.index() >= 3
    }

    /// The axis (0 = e1, 1 = e2, 2 = e3) of frame I this DOF acts along or about.
    pub const fn axis(self) -> usize {
        self.index() % 3
    }
}

impl core::fmt::Display for Dof {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.label())
    }
}

/// A set of relative DOFs (bit `i` = [`Dof::ALL`]`[i]`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct DofMask(pub u8);

impl DofMask {
    /// No DOF.
    pub const NONE: DofMask = DofMask(0);
    /// UX, UY, UZ.
    pub const TRANSLATIONS: DofMask = DofMask(0b000_111);
    /// ROTX, ROTY, ROTZ.
    pub const ROTATIONS: DofMask = DofMask(0b111_000);
    /// All six.
    pub const ALL: DofMask = DofMask(0b111_111);

    /// The set holding exactly `dofs`.
    pub const fn of(dofs: &[Dof]) -> DofMask {
        let mut bits = 0u8;
        let mut i = 0;
        while i < dofs.len() {
            bits |= 1 << dofs[i].index();
            i += 1;
        }
        DofMask(bits)
    }

    /// True if `dof` is in the set.
    pub const fn contains(self, dof: Dof) -> bool {
        self.0 & (1 << dof.index()) != 0
    }

    /// The DOFs not in this set.
    pub const fn complement(self) -> DofMask {
        DofMask(!self.0 & Self::ALL.0)
    }

    /// Union.
    pub const fn union(self, other: DofMask) -> DofMask {
        DofMask(self.0 | other.0)
    }

    /// Number of DOFs in the set.
    pub const fn count(self) -> usize {
        self.0.count_ones() as usize
    }

    /// The members, in ANSYS order.
    pub fn iter(self) -> impl Iterator<Item = Dof> {
        Dof::ALL.into_iter().filter(move |d| self.contains(*d))
    }
}

impl core::fmt::Display for DofMask {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        if self.0 == 0 {
            return f.write_str("none");
        }
        let mut first = true;
        for d in self.iter() {
            if !first {
                f.write_str(" ")?;
            }
            first = false;
            f.write_str(d.label())?;
        }
        Ok(())
    }
}
