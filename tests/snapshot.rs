//! Snapshot and resume: a world serialised mid-run (`Mpc184World::snapshot`, bytes) and
//! restored (`Mpc184World::from_snapshot`) continues bit for bit as the original does.
//!
//! Scene (Lagrange backend, gravity -Y): a crank (1 kg) on a grounded revolute z joint turned at
//! 3 rad/s by a drive (DJ); a pendulum (0.5 kg) hinged to the crank's end on a revolute with a
//! stop at +-0.4 rad and Coulomb friction; a slider (0.2 kg) on a translational joint along the
//! pendulum with a spring, a damper and a lock at +-0.05 m; the slider carries a ball collider
//! and the ground a floor collider below everything (Rapier's collider sets, broad and narrow
//! phase go through the snapshot too). After 90 steps (1.5 s) the snapshot is taken; the
//! original runs 120 more steps, the world restored from the bytes runs the same 120 steps.
//! Every step's time, body poses, velocities and centres of mass, every joint output (relative
//! motion, reactions, stop, lock and friction state) and the energy ledger must be equal to the
//! bit: the drive's reference, the stop and friction states, the engaged lock row, the solver's
//! warm starts and factorisation all matter for the next steps. The restored world's own
//! snapshot must be the same bytes (nothing lost in the round trip), the window must see the
//! stop, friction and the lock act (else the test would not test them), and damaged bytes must
//! give `Error::Snapshot`, not a panic.
//!
//! No tolerance: exact comparison (`Debug` prints every float to the bit).
#![cfg(feature = "serde-snapshot")]

use rapier3d_mpc184::math::rapier::prelude::{
    ColliderBuilder, MassProperties, RigidBodyBuilder, RigidBodyHandle,
};
use rapier3d_mpc184::prelude::*;

fn body(world: &mut Mpc184World, at: Vector, mass: Real, inertia: Real) -> RigidBodyHandle {
    world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(at)
            .additional_mass_properties(MassProperties::new(
                Vector::ZERO,
                mass,
                Vector::splat(inertia),
            ))
            .can_sleep(false),
    )
}

struct Scene {
    world: Mpc184World,
    bodies: Vec<RigidBodyHandle>,
    joints: Vec<JointId>,
}

fn scene() -> Scene {
    let mut world = Mpc184World::new(WorldSettings {
        dt: 1.0 / 60.0,
        substeps: 4,
        backend: Backend::Lagrange,
        ..Default::default()
    });
    let crank = body(&mut world, Vector::new(0.25, 0.0, 0.0), 1.0, 1e-2);
    let pendulum = body(&mut world, Vector::new(0.5, -0.3, 0.0), 0.5, 5e-3);
    let slider = body(&mut world, Vector::new(0.5, -0.5, 0.0), 0.2, 1e-3);
    let ground = world.ground();
    world.physics.colliders.insert_with_parent(
        ColliderBuilder::cuboid(5.0, 0.1, 5.0).translation(Vector::new(0.0, -3.0, 0.0)),
        ground,
        &mut world.physics.bodies,
    );
    world.physics.colliders.insert_with_parent(
        ColliderBuilder::ball(0.05).density(0.0),
        slider,
        &mut world.physics.bodies,
    );
    let drive = world
        .insert_joint(
            None,
            Some(crank),
            Mpc184Joint::revolute(Axis::Z, Vector::ZERO),
        )
        .unwrap();
    world
        .set_drive(drive, Dof::RotZ, DriveProfile::constant_rate(3.0))
        .unwrap();
    let hinge = world
        .insert_joint(
            Some(crank),
            Some(pendulum),
            Mpc184Joint::revolute(Axis::Z, Vector::new(0.5, 0.0, 0.0))
                .with_stop(Dof::RotZ, -0.4, 0.4)
                .with_friction(Friction::coulomb(0.3, [Some(0.5), Some(0.4), None])),
        )
        .unwrap();
    // Sliding along the pendulum (global -Y at the start): frame I's e1 turned onto -Y.
    let along = Rotation::from_rotation_z(-core::f64::consts::FRAC_PI_2 as Real);
    let slide = world
        .insert_joint(
            Some(pendulum),
            Some(slider),
            Mpc184Joint::new(JointKind::Translational, Vector::new(0.5, -0.5, 0.0))
                .with_axes(along)
                .with_stiffness(Sym6::diagonal([20.0, 0.0, 0.0, 0.0, 0.0, 0.0]))
                .with_damping(Sym6::diagonal([0.5, 0.0, 0.0, 0.0, 0.0, 0.0]))
                .with_lock(Dof::Ux, -0.05, 0.05),
        )
        .unwrap();
    Scene {
        world,
        bodies: vec![crank, pendulum, slider],
        joints: vec![drive, hinge, slide],
    }
}

/// Everything observable, printed exactly.
fn state(s: &Scene, world: &Mpc184World) -> String {
    let mut out = format!("t {:?}\n", world.time());
    for b in &s.bodies {
        let rb = &world.physics.bodies[*b];
        out += &format!(
            "{:?} {:?} {:?} {:?}\n",
            rb.position(),
            rb.linvel(),
            rb.angvel(),
            rb.center_of_mass()
        );
    }
    for j in &s.joints {
        out += &format!("{:?}\n", world.output(*j).unwrap());
    }
    out += &format!("{:?}\n", world.energy());
    out
}

#[test]
fn a_restored_world_continues_bit_for_bit() {
    let mut s = scene();
    let mut world = std::mem::replace(&mut s.world, Mpc184World::new(WorldSettings::default()));
    for _ in 0..90 {
        world.step().unwrap();
    }
    let bytes = world.snapshot().unwrap().into_bytes();
    println!("snapshot: {} bytes", bytes.len());
    let (mut stops, mut slips, mut sticks) = (0, 0, 0);
    let mut reference = Vec::new();
    for _ in 0..120 {
        world.step().unwrap();
        reference.push(state(&s, &world));
        let o = world.output(s.joints[1]).unwrap();
        stops += usize::from(o.stops > 0);
        match o.friction {
            Some(f) if f.slipping => slips += 1,
            Some(_) => sticks += 1,
            None => {}
        }
    }
    let lock = world.output(s.joints[2]).unwrap().locks;
    println!(
        "window: stop active in {stops} steps, slipping {slips}, sticking {sticks}; locks {lock}"
    );
    assert!(stops > 0 && slips > 0 && sticks > 0 && lock == 1);
    let mut restored = Mpc184World::from_snapshot(&Snapshot::from_bytes(bytes.clone())).unwrap();
    assert!(
        restored.snapshot().unwrap().as_bytes() == bytes.as_slice(),
        "the restored world's snapshot differs from the one it was made from"
    );
    for (k, want) in reference.iter().enumerate() {
        restored.step().unwrap();
        let got = state(&s, &restored);
        assert!(
            got == *want,
            "step {k} after the snapshot:\n{got}\n!=\n{want}"
        );
    }
}

#[test]
fn damaged_bytes_give_a_snapshot_error() {
    let mut s = scene();
    for _ in 0..5 {
        s.world.step().unwrap();
    }
    let bytes = s.world.snapshot().unwrap().into_bytes();
    let mut cases: Vec<Vec<u8>> = vec![
        Vec::new(),
        b"not a snapshot at all".to_vec(),
        bytes[..bytes.len() / 2].to_vec(),
        bytes[..bytes.len() - 1].to_vec(),
    ];
    let mut newer = bytes.clone();
    newer[8] = newer[8].wrapping_add(1); // the format number
    cases.push(newer);
    let mut extra = bytes.clone();
    extra.push(0);
    cases.push(extra);
    for (k, c) in cases.into_iter().enumerate() {
        match Mpc184World::from_snapshot(&Snapshot::from_bytes(c)) {
            Err(Error::Snapshot { reason }) => println!("case {k}: {reason}"),
            Err(e) => panic!("case {k}: wrong error {e}"),
            Ok(_) => panic!("case {k}: damaged bytes accepted"),
        }
    }
}
