//! The checks a joint passes before it is inserted: each names the joint and the node, body or
//! field at fault, and none changes the world (see `Mpc184World::insert_joint` for the order).

use crate::catalogue::JointKind;
use crate::error::{Error, JointId};
use crate::joint::Mpc184Joint;
use crate::math::Real;
use crate::math::rapier::dynamics::{RigidBodyHandle, RigidBodySet};
use crate::math::rapier::geometry::ColliderSet;

/// The joint's own data: frames, kind-specific model checks, behaviour.
pub(crate) fn joint(id: JointId, j: &Mpc184Joint, two_bodies: bool) -> Result<(), Error> {
    frames(id, j)?;
    model(id, j, two_bodies)?;
    j.behaviour
        .validate(&j.kind)
        .map_err(|(field, reason)| Error::InvalidBehaviour {
            joint: id,
            field,
            reason,
        })
}

/// Its nodes are finite and its axes proper rotations.
fn frames(id: JointId, j: &Mpc184Joint) -> Result<(), Error> {
    for (node, x, q) in [(1u8, j.node1, j.axes1), (2, j.node2, j.axes2())] {
        if !x.is_finite() {
            return Err(Error::DegenerateFrame {
                joint: id,
                node,
                reason: format!("position {x} is not finite"),
            });
        }
        if !q.is_finite() || (q.length() - 1.0).abs() > 1e-6 {
            return Err(Error::DegenerateFrame {
                joint: id,
                node,
                reason: format!("axes {q} are not a unit quaternion (a proper rotation)"),
            });
        }
    }
    Ok(())
}

/// Checks of the joint against its kind that need no body: a screw's pitch, and the
/// coincidence of the nodes of a revolute or universal joint with a body on each side (a
/// grounded side is placed at the other node).
fn model(id: JointId, j: &Mpc184Joint, two_bodies: bool) -> Result<(), Error> {
    if let JointKind::Screw { pitch } = j.kind
        && !(pitch.is_finite() && pitch != 0.0)
    {
        return Err(Error::InvalidPitch { joint: id, pitch });
    }
    if two_bodies && matches!(j.kind, JointKind::Revolute { .. } | JointKind::Universal) {
        let distance = (j.node2 - j.node1).length();
        let scale = j.node1.length().max(j.node2.length()).max(1.0);
        let tolerance = crate::joint::COINCIDENCE_TOLERANCE * scale;
        if distance > tolerance {
            return Err(Error::NodesApart {
                joint: id,
                kind: j.kind.name(),
                distance,
                tolerance,
            });
        }
    }
    Ok(())
}

/// The bodies exist, have usable mass properties (filled in now from their colliders), and
/// are two different bodies, at least one of them given.
pub(crate) fn bodies(
    id: JointId,
    bodies: &mut RigidBodySet,
    colliders: &ColliderSet,
    sides: [Option<RigidBodyHandle>; 2],
) -> Result<(), Error> {
    for (which, b) in [(1u8, sides[0]), (2, sides[1])] {
        if let Some(h) = b
            && bodies.get(h).is_none()
        {
            return Err(Error::InvalidBody {
                joint: id,
                which,
                reason: "no such body".into(),
            });
        }
    }
    for (which, b) in [(1u8, sides[0]), (2, sides[1])] {
        if let Some(h) = b {
            let rb = &mut bodies[h];
            rb.recompute_mass_properties_from_colliders(colliders);
            if let Some(reason) = crate::body::mass_defect(rb) {
                return Err(Error::MassProperties {
                    joint: id,
                    which,
                    reason: format!("{h:?}: {reason}"),
                });
            }
        }
    }
    match sides {
        [None, None] => Err(Error::InvalidBody {
            joint: id,
            which: 2,
            reason: "both nodes grounded: a joint needs at least one body".into(),
        }),
        [Some(a), Some(b)] if a == b => Err(Error::InvalidBody {
            joint: id,
            which: 2,
            reason: "a joint between a body and itself".into(),
        }),
        _ => Ok(()),
    }
}

/// A rigid link's nodes are distinct (its direction is defined).
pub(crate) fn link_length(id: JointId, j: &Mpc184Joint) -> Result<(), Error> {
    if !matches!(j.kind, JointKind::RigidLink) {
        return Ok(());
    }
    let length = (j.node2 - j.node1).length();
    let scale = j.node1.abs().max(j.node2.abs()).max_element().max(1.0);
    if length.is_nan() || length <= 1e3 * Real::EPSILON * scale {
        return Err(Error::DegenerateFrame {
            joint: id,
            node: 2,
            reason: format!(
                "a rigid link needs distinct nodes (length {length:e} m): its direction is \
                 undefined"
            ),
        });
    }
    Ok(())
}
