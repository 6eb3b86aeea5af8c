//! On the Rapier multibody backend every grounded joint gets its own fixed root, so that
//! independent grounded trees are independent multibodies (one shared ground body made them one
//! multibody with a dense solve over all their DOFs: 200 five-body arms took seconds per step);
//! a loop through the ground is still refused, and a joint grounded at node J (whose fixed side
//! would be the child link, which Rapier cannot step) is refused before a loop can form.
//! Structure only: no tolerance (multibody membership is exact).

use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder, RigidBodyHandle};
use rapier3d_mpc184::prelude::*;

fn world() -> Mpc184World {
    Mpc184World::new(WorldSettings {
        backend: Backend::RapierMultibody,
        ..WorldSettings::default()
    })
}

fn bead(w: &mut Mpc184World, at: Vector) -> RigidBodyHandle {
    w.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(at)
            .additional_mass_properties(MassProperties::new(Vector::ZERO, 1.0, Vector::splat(0.1))),
    )
}

#[test]
fn independent_grounded_trees_are_separate_multibodies() {
    let mut w = world();
    let (a, b) = (
        bead(&mut w, Vector::new(0.0, -1.0, 0.0)),
        bead(&mut w, Vector::new(3.0, -1.0, 0.0)),
    );
    let c = bead(&mut w, Vector::new(3.0, -2.0, 0.0));
    w.insert_joint(None, Some(a), Mpc184Joint::revolute(Axis::Z, Vector::ZERO))
        .unwrap();
    w.insert_joint(
        None,
        Some(b),
        Mpc184Joint::revolute(Axis::Z, Vector::new(3.0, 0.0, 0.0)),
    )
    .unwrap();
    w.insert_joint(
        Some(b),
        Some(c),
        Mpc184Joint::revolute(Axis::Z, Vector::new(3.0, -1.0, 0.0)),
    )
    .unwrap();
    let mb = |h| {
        w.physics
            .multibody_joints
            .rigid_body_link(h)
            .map(|l| l.multibody)
    };
    assert!(mb(a).is_some() && mb(b).is_some());
    assert_ne!(mb(a), mb(b), "two grounded arms share one multibody");
    assert_eq!(mb(b), mb(c), "an arm's links are one multibody");
}

#[test]
fn a_loop_through_the_ground_is_refused_in_either_order() {
    for j_grounded_first in [false, true] {
        let mut w = world();
        let (a, b) = (
            bead(&mut w, Vector::new(0.0, -1.0, 0.0)),
            bead(&mut w, Vector::new(1.0, -1.0, 0.0)),
        );
        let pin = |x| Mpc184Joint::revolute(Axis::Z, Vector::new(x, 0.0, 0.0));
        // Ground - a, a - b, b - ground (J grounded): a loop closed by the ground.
        let r = if j_grounded_first {
            // A joint grounded at J would make a fixed body the child link, which Rapier
            // cannot step (it asserts at the first step): refused before any loop forms.
            let r = w.insert_joint(Some(b), None, pin(1.0));
            assert!(
                matches!(r, Err(Error::InvalidBody { which: 2, .. })),
                "a fixed child: {r:?}"
            );
            continue;
        } else {
            w.insert_joint(None, Some(a), pin(0.0)).unwrap();
            w.insert_joint(Some(a), Some(b), pin(0.5)).unwrap();
            w.insert_joint(Some(b), None, pin(1.0))
        };
        assert!(
            matches!(r, Err(Error::Unsupported { .. })),
            "order {j_grounded_first}: got {r:?}"
        );
    }
}
