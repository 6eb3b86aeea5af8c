//! Scalar constraint rows of a joint, in MPC184's terms.
//!
//! Every row is measured between frame 1, attached to body 1 at node J's initial position with
//! frame I's axes, and frame 2, the local system at node J attached to body 2 (its axes default
//! to frame I's). Each row holds its initial value: zero for the translations (the origins
//! coincide) and for rotations whose frames start aligned; when the system at J is turned against
//! the one at I, the dot products below keep their initial values, which is MPC184's rule (the
//! universal joint: "the angle between e1 of I and e3 of J is held at its initial value").
//! With `e_k` the axes of frame 1, `f_k` those of frame 2, `p1`, `p2` their origins:
//!
//! | DOF | constraint `C = 0` | why this form |
//! |---|---|---|
//! | UX, UY, UZ | `e_k . (p2 - p1)` | relative displacement in frame I |
//! | ROTX | `e2 . f3` | `= -sin(psi) cos(phi)`: zero iff the Bryant angle psi is |
//! | ROTY | `e1 . f3` | `= sin(phi)`: exactly MPC184's universal-joint rule (`e1I.e3J` held) |
//! | ROTZ | `e1 . f2` | `= -cos(phi) sin(theta)`: zero iff theta is |
//!
//! The screw joint adds the coupled row `u_z - p theta = 0` (`u_z = e3 . (p2 - p1)`, `theta`
//! the relative rotation about e3, unwrapped past +-pi from the last known value), with
//! `J1 = (-e3, -(p2 - c1) x e3 + p e3)`, `J2 = (e3, (p2 - c2) x e3 - p e3)`.
//!
//! The rigid link (KEYOPT(1) = 0) has one row, measured between node I itself (frame 1 then sits
//! at node I, not at node J's initial position) and node J: the distance
//! `|p2 - p1| - L = 0` with `L` its value at time 0 and `n = (p2 - p1) / |p2 - p1|`,
//! `J1 = (-n, -(p1 - c1) x n)`, `J2 = (n, (p2 - c2) x n)`. Its multiplier is the axial force
//! (positive pushes the nodes apart).
//!
//! An idle spin ([`crate::idle`]) is removed by a velocity-level row on one side only,
//! `w . a = 0` with `a` fixed in that side's frame: `J = (0, a)` on that side, zero on the
//! other, value always zero (nothing for the position projection to do).
//!
//! A row's Jacobian acts on body velocities `(v, w)` (world frame, at the centre of mass):
//! linear rows `J1 = (-e, -(p2 - c1) x e)`, `J2 = (e, (p2 - c2) x e)`; angular rows with
//! `n = a x b`: `J1 = (0, n)`, `J2 = (0, -n)`. A multiplier `lambda` applies `J^T lambda`
//! (force and torque about the centre of mass) to each body.

use crate::dof::{Dof, DofMask};
use crate::math::{Matrix, Real, Vector};

/// The geometry of one row.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum RowKind {
    /// `e_axis . (p2 - p1)`.
    Linear {
        /// Axis of frame 1 (0 = e1).
        axis: usize,
    },
    /// `e_a . f_b - target` (axis `a` of frame 1 dotted with axis `b` of frame 2, held at its
    /// initial value).
    Angular {
        /// Axis of frame 1.
        a: usize,
        /// Axis of frame 2.
        b: usize,
        /// The value held: `e_a . f_b` at time 0 (0 when the two frames start aligned).
        target: Real,
    },
    /// A prescribed relative displacement or rotation (DJ): the DOF's value relative to time 0
    /// minus `target`. Rotations about e1 and e3 are unwrapped like the screw's angle.
    Drive {
        /// The driven DOF (a free one).
        dof: Dof,
        /// The prescribed value now (m or rad, relative to time 0).
        target: Real,
        /// The DOF's absolute measure at time 0.
        initial: Real,
        /// The last unwrapped absolute measure (rotations about e1 and e3).
        reference: Real,
    },
    /// The rigid link's distance `|p2 - p1| - length` (frame 1 at node I).
    Distance {
        /// The length held: `|p2 - p1|` at time 0 (m).
        length: Real,
    },
    /// The screw coupling `e3 . (p2 - p1) - pitch * (theta - theta0)`.
    Screw {
        /// Axial travel per radian (m/rad).
        pitch: Real,
        /// The last unwrapped rotation about e3 (rad): the branch `theta` is taken on.
        reference: Real,
        /// The rotation at time 0 (rad).
        theta0: Real,
    },
    /// The spin of one side's body about an axis fixed in it held at zero rate (`w . a = 0`,
    /// velocity level; the removal of an idle mode, see [`crate::idle`]).
    Spin {
        /// The side whose body spins: 1 or 2.
        side: u8,
        /// The axis in that side's frame (unit).
        axis: Vector,
    },
}

/// The absolute measure of a DOF between the two frames: `e_k . (p2 - p1)` for a translation,
/// the Bryant angle for a rotation (psi and theta unwrapped to lie within pi of `reference`).
pub fn dof_measure(f: &FramePair, dof: Dof, reference: Real) -> Real {
    let unwrap = |wrapped: Real| {
        let two_pi = 2.0 * crate::math::PI;
        let mut d = wrapped - reference;
        d -= two_pi * (d / two_pi).round();
        reference + d
    };
    let e = |i: usize| f.axis1(i);
    let g = |i: usize| f.axis2(i);
    match dof {
        Dof::Ux | Dof::Uy | Dof::Uz => e(dof.axis()).dot(f.p2 - f.p1),
        Dof::RotX => unwrap(-crate::math::atan2(g(2).dot(e(1)), g(2).dot(e(2)))),
        Dof::RotY => crate::math::asin(g(2).dot(e(0))),
        Dof::RotZ => screw_angle(f, reference),
    }
}

/// The relative rotation about e3 of frame 2 from frame 1 (`-atan2(e1 . f2, e1 . f1)`, the
/// Bryant angle theta), unwrapped to lie within pi of `reference` (rad).
pub fn screw_angle(f: &FramePair, reference: Real) -> Real {
    let e1 = f.axis1(0);
    let wrapped = -crate::math::atan2(e1.dot(f.axis2(1)), e1.dot(f.axis2(0)));
    let two_pi = 2.0 * crate::math::PI;
    let mut d = wrapped - reference;
    d -= two_pi * (d / two_pi).round();
    reference + d
}

/// How a row acts on body 2 at frame 2's origin `p2` (see [`RowKind::node_wrench`]); on body
/// 1 it acts with the opposite wrench at the same point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NodeWrench {
    /// A force along the direction, no moment about `p2`.
    Force(Vector),
    /// A moment about the direction, no force.
    Moment(Vector),
}

impl RowKind {
    /// The row that holds `dof` at its initial value.
    pub const fn lock(dof: Dof) -> RowKind {
        match dof {
            Dof::Ux => RowKind::Linear { axis: 0 },
            Dof::Uy => RowKind::Linear { axis: 1 },
            Dof::Uz => RowKind::Linear { axis: 2 },
            Dof::RotX => RowKind::Angular {
                a: 1,
                b: 2,
                target: 0.0,
            },
            Dof::RotY => RowKind::Angular {
                a: 0,
                b: 2,
                target: 0.0,
            },
            Dof::RotZ => RowKind::Angular {
                a: 0,
                b: 1,
                target: 0.0,
            },
        }
    }
}

/// The lock rows of a set of constrained DOFs, in ANSYS order.
pub fn lock_rows(constrained: DofMask) -> impl Iterator<Item = (Dof, RowKind)> {
    constrained.iter().map(|d| (d, RowKind::lock(d)))
}

/// Every row of a joint kind: its lock rows and, for the screw, the coupling row; for the rigid
/// link the distance row (its length set from the initial positions when the joint is
/// inserted).
pub fn joint_rows(kind: &crate::catalogue::JointKind) -> Vec<RowKind> {
    let mut rows: Vec<RowKind> = lock_rows(kind.constrained()).map(|(_, r)| r).collect();
    match kind {
        crate::catalogue::JointKind::Screw { pitch } => rows.push(RowKind::Screw {
            pitch: *pitch,
            reference: 0.0,
            theta0: 0.0,
        }),
        crate::catalogue::JointKind::RigidLink => rows.push(RowKind::Distance { length: 0.0 }),
        _ => {}
    }
    rows
}

/// World-frame state of the two frames a row is measured between.
#[derive(Clone, Copy, Debug)]
pub struct FramePair {
    /// Origin of frame 1 (m).
    pub p1: Vector,
    /// Axes of frame 1 (columns, global components).
    pub r1: Matrix,
    /// Centre of mass of body 1 (m).
    pub c1: Vector,
    /// Origin of frame 2 (m).
    pub p2: Vector,
    /// Axes of frame 2.
    pub r2: Matrix,
    /// Centre of mass of body 2 (m).
    pub c2: Vector,
}

impl FramePair {
    /// The frame pair of a joint whose frames are `frames` (in each body's local coordinates)
    /// on bodies at `body1` and `body2` (pose, centre of mass): `body * frame` for each side.
    ///
    /// The two sides run in the two lanes of one register ([`crate::math::pair`]; in `f64`
    /// the same results to the bit as glam's `DPose3 * DPose3` and `DMat3::from_quat`), in 201
    /// instructions a call where the compiler's own vectorisation of the scalar code took 302
    /// (callgrind, 1/60 s x 4: -2.5 % instructions per step on the 100-link chain, -2.7 % on
    /// the mixed scene of 100 arms).
    pub(crate) fn at(
        frames: &[crate::math::Pose; 2],
        body1: (crate::math::Pose, Vector),
        body2: (crate::math::Pose, Vector),
    ) -> FramePair {
        use crate::math::pair::{Q, V};
        let (b1, b2) = (body1.0, body2.0);
        let body = Q::new(b1.rotation, b2.rotation);
        let local = V::new(frames[0].translation, frames[1].translation);
        let rotation = body.mul(Q::new(frames[0].rotation, frames[1].rotation));
        // `DPose3 * DPose3`: the translation is the body's plus its rotation of the frame's.
        let [p1, p2] = V::new(b1.translation, b2.translation)
            .add(body.rotate(local))
            .split();
        let [r1, r2] = rotation.axes();
        FramePair {
            p1,
            r1,
            c1: body1.1,
            p2,
            r2,
            c2: body2.1,
        }
    }

    /// The vectors the rows of this frame pair share.
    #[inline(always)]
    pub(crate) fn arms(&self) -> Arms {
        Arms {
            d: self.p2 - self.p1,
            arm1: self.p2 - self.c1,
            arm2: self.p2 - self.c2,
        }
    }

    /// Axis `i` of frame 1 (`i < 3`, else a panic, as `Matrix::col`).
    #[inline(always)]
    pub fn axis1(&self, i: usize) -> Vector {
        column(&self.r1, i)
    }

    /// Axis `i` of frame 2 (`i < 3`, else a panic).
    #[inline(always)]
    pub fn axis2(&self, i: usize) -> Vector {
        column(&self.r2, i)
    }
}

/// Column `i` of `m`, read from the matrix's stored array: `Matrix::col` matches on `i`, a
/// branch per call in the rows' evaluation (0.8 % of the 100-link chain's instructions).
#[inline(always)]
fn column(m: &Matrix, i: usize) -> Vector {
    let a: &[Real; 9] = m.as_ref();
    Vector::from_slice(&a[3 * i..3 * i + 3])
}

/// What the rows of one joint share at one configuration ([`FramePair::arms`]): computed
/// once per joint instead of once per row.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Arms {
    /// The frames' separation `p2 - p1` (m).
    pub(crate) d: Vector,
    /// Frame 2's origin from body 1's centre of mass, `p2 - c1` (m).
    pub(crate) arm1: Vector,
    /// Frame 2's origin from body 2's centre of mass, `p2 - c2` (m).
    pub(crate) arm2: Vector,
}

/// A row evaluated at one configuration: value and Jacobian blocks (linear, angular) per body.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RowEval {
    /// Constraint value `C` (m or dimensionless).
    pub value: Real,
    /// Body 1 block `[v part; w part]`.
    pub j1: [Vector; 2],
    /// Body 2 block.
    pub j2: [Vector; 2],
}

impl RowEval {
    /// The row's rate `J1 (v1, w1) + J2 (v2, w2)` for the two sides' velocities (linear at the
    /// centre of mass, angular).
    pub fn rate(&self, v1: [Vector; 2], v2: [Vector; 2]) -> Real {
        self.j1[0].dot(v1[0])
            + self.j1[1].dot(v1[1])
            + self.j2[0].dot(v2[0])
            + self.j2[1].dot(v2[1])
    }
}

impl RowKind {
    /// The value alone at the configuration `f` (the same as [`RowKind::eval`]'s, without the
    /// Jacobian's cross products).
    pub fn value(self, f: &FramePair) -> Real {
        match self {
            RowKind::Linear { axis } => linear_value(f, f.p2 - f.p1, axis),
            RowKind::Angular { a, b, target } => angular_value(f, a, b, target),
            RowKind::Distance { .. } | RowKind::Drive { .. } | RowKind::Screw { .. } => {
                self.eval(f).value
            }
            RowKind::Spin { .. } => 0.0,
        }
    }

    /// Value and Jacobian at the configuration `f`.
    pub fn eval(self, f: &FramePair) -> RowEval {
        let arms = f.arms();
        match self {
            RowKind::Spin { side, axis } => {
                let zero = [Vector::ZERO, Vector::ZERO];
                if side == 1 {
                    RowEval {
                        value: 0.0,
                        j1: [Vector::ZERO, f.r1 * axis],
                        j2: zero,
                    }
                } else {
                    RowEval {
                        value: 0.0,
                        j1: zero,
                        j2: [Vector::ZERO, f.r2 * axis],
                    }
                }
            }
            RowKind::Linear { axis } => linear_row(f, &arms, axis),
            RowKind::Distance { length } => {
                let d = f.p2 - f.p1;
                let len = d.length();
                // At zero length the direction is undefined: take e1 of frame 1 (a link is
                // built with distinct nodes, so this only guards against a collapse).
                let n = if len > 0.0 { d / len } else { f.axis1(0) };
                RowEval {
                    value: len - length,
                    j1: [-n, -(f.p1 - f.c1).cross(n)],
                    j2: [n, (f.p2 - f.c2).cross(n)],
                }
            }
            RowKind::Screw {
                pitch,
                reference,
                theta0,
            } => {
                let e = f.axis1(2);
                RowEval {
                    value: e.dot(arms.d) - pitch * (screw_angle(f, reference) - theta0),
                    j1: [-e, -arms.arm1.cross(e) + e * pitch],
                    j2: [e, arms.arm2.cross(e) - e * pitch],
                }
            }
            RowKind::Drive {
                dof,
                target,
                initial,
                reference,
            } => {
                let e = f.axis1(dof.axis());
                let value = dof_measure(f, dof, reference) - initial - target;
                if dof.is_rotation() {
                    RowEval {
                        value,
                        j1: [Vector::ZERO, -e],
                        j2: [Vector::ZERO, e],
                    }
                } else {
                    RowEval {
                        value,
                        j1: [-e, -arms.arm1.cross(e)],
                        j2: [e, arms.arm2.cross(e)],
                    }
                }
            }
            RowKind::Angular { a, b, target } => angular_row(f, a, b, target),
        }
    }

    /// The row's wrench per unit multiplier on body 2 about frame 2's origin `p2` when it is a
    /// pure force or a pure moment there (with the opposite one on body 1 about the same
    /// point), from [`RowKind::eval`]'s Jacobian: a translation row `J2 = (e, (p2 - c2) x e)`
    /// is the force `e` at `p2`, `J1 = (-e, -(p2 - c1) x e)` its opposite; the rigid link's
    /// row acts along the line of the nodes, so about `p2` as about `p1`; a rotation row is a
    /// moment. `None` for a screw's coupled row (force and moment along e3) and an idle spin's
    /// one-sided row.
    pub fn node_wrench(self, f: &FramePair) -> Option<NodeWrench> {
        match self {
            RowKind::Linear { axis } => Some(NodeWrench::Force(f.axis1(axis))),
            RowKind::Angular { a, b, .. } => {
                Some(NodeWrench::Moment(-f.axis1(a).cross(f.axis2(b))))
            }
            RowKind::Drive { dof, .. } => {
                let e = f.axis1(dof.axis());
                Some(if dof.is_rotation() {
                    NodeWrench::Moment(e)
                } else {
                    NodeWrench::Force(e)
                })
            }
            RowKind::Distance { .. } => {
                let d = f.p2 - f.p1;
                let len = d.length();
                Some(NodeWrench::Force(if len > 0.0 {
                    d / len
                } else {
                    f.axis1(0)
                }))
            }
            RowKind::Screw { .. } | RowKind::Spin { .. } => None,
        }
    }
}

/// The value and Jacobian of [`RowKind::Linear`] along axis `axis` of frame 1, `e . (p2 -
/// p1)`: body 1 `(-e, -(p2 - c1) x e)`, body 2 `(e, (p2 - c2) x e)`. Inlined into the
/// backends' passes over the rows, where the result goes straight to the Jacobian arena
/// (called once per row through [`RowKind::eval`], with the lever arms computed per row and
/// the result returned through memory, the rows' evaluation took 2.4 % more of the
/// 100-link chain's instructions, 3.0 % more of the mixed scene's).
#[inline(always)]
pub(crate) fn linear_row(f: &FramePair, arms: &Arms, axis: usize) -> RowEval {
    let e = f.axis1(axis);
    RowEval {
        value: linear_value(f, arms.d, axis),
        j1: [-e, -arms.arm1.cross(e)],
        j2: [e, arms.arm2.cross(e)],
    }
}

/// The value of [`RowKind::Linear`] along axis `axis` of frame 1 with the frames' separation
/// `d = p2 - p1` given (shared by a joint's rows). Inlined as [`linear_row`].
#[inline(always)]
pub(crate) fn linear_value(f: &FramePair, d: Vector, axis: usize) -> Real {
    f.axis1(axis).dot(d)
}

/// The value of [`RowKind::Angular`], `e_a . f_b - target`. Inlined as [`linear_row`].
#[inline(always)]
pub(crate) fn angular_value(f: &FramePair, a: usize, b: usize, target: Real) -> Real {
    f.axis1(a).dot(f.axis2(b)) - target
}

/// The value and Jacobian of [`RowKind::Angular`], `e_a . f_b - target`: body 1 `(0, n)`,
/// body 2 `(0, -n)` with `n = e_a x f_b`. Inlined as [`linear_row`].
#[inline(always)]
pub(crate) fn angular_row(f: &FramePair, a: usize, b: usize, target: Real) -> RowEval {
    let u = f.axis1(a);
    let w = f.axis2(b);
    let n = u.cross(w);
    RowEval {
        value: angular_value(f, a, b, target),
        j1: [Vector::ZERO, n],
        j2: [Vector::ZERO, -n],
    }
}
