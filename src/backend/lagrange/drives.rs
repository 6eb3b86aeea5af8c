//! Prescribed motions (`DJ`) on the Lagrange backend: each drive row's target and rate over
//! the coming substep, and the work the drives do.

use crate::joint_set::JointSet;
use crate::math::Real;
use crate::rows::RowKind;

use super::Island;

impl Island {
    /// Sets every drive row's target to its value at `t1` (the end of the coming substep) and
    /// its rate to the change over the substep divided by h.
    pub(super) fn update_drives(&mut self, joints: &mut JointSet, t1: Real, h: Real) {
        let Some(kkt) = self.kkt.as_ref() else { return };
        for (k, &j) in self.blocks.iter().enumerate() {
            let Some(e) = joints.get_mut(j) else {
                continue;
            };
            let r0 = kkt.row_offset(k);
            for (n, row) in e.state.rows.iter_mut().enumerate() {
                if let RowKind::Drive { dof, target, .. } = row
                    && let Some(d) = e.drives.iter().find(|d| d.dof == *dof)
                {
                    let (v0, v1) = (d.value(t1 - h), d.value(t1));
                    *target = v1;
                    self.rate[r0 + n] = (v1 - v0) / h;
                }
            }
        }
    }

    /// Books the work of the prescribed motions (DJ) over the substep just taken: each drive
    /// row's impulse times its prescribed rate (`lambda . J v` with `J v` = the rate).
    pub(super) fn book_drive_work(&mut self, joints: &JointSet) {
        let mut work = 0.0;
        for &j in &self.blocks {
            let Some(e) = joints.get(j) else { continue };
            if e.drives.is_empty() {
                continue;
            }
            let Some(range) = self.rows_of(j) else {
                continue;
            };
            for (row, r) in e.state.rows.iter().zip(range) {
                if let RowKind::Drive { dof, .. } = row
                    && e.drives.iter().any(|d| d.dof == *dof)
                {
                    work += self.impulse[r] * self.rate[r];
                }
            }
        }
        self.ledger.work += work;
    }
}
