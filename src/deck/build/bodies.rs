//! One Rapier body per rigid group: mass and centre of mass from its `MASS21` elements,
//! inertia about the centre of mass (parallel-axis sums), the point-mass regularisation, and a
//! fixed body for a group held by `D,node,ALL,0` or without mass.

use std::collections::BTreeMap;

use crate::apdl::Deck;
use crate::error::Error;
use crate::math::rapier::dynamics::{RigidBodyBuilder, RigidBodyHandle};
use crate::math::rapier::prelude::MassProperties;
use crate::math::{Matrix, Real, Vector};
use crate::world::Mpc184World;

use super::constraints::NodalConstraints;
use super::rigid_groups::{PointMass, RigidGroups};
use super::{DeckBody, POINT_MASS_INERTIA, invalid, vec3};

/// Node -> (body index, offset from the body's origin in its local frame).
pub(super) type NodeBodies = BTreeMap<u32, (Option<usize>, Vector)>;

/// The mass properties of one group of nodes (global axes, about the centre of mass).
struct GroupMass {
    mass: f64,
    com: [f64; 3],
    inertia: [[f64; 3]; 3],
    /// Largest distance of the group's nodes from the centre of mass (m).
    r_max: f64,
    /// The deck line of the group's first `MASS21` element (errors about its mass name it).
    line: usize,
}

/// Inserts a body for every rigid group (see the module docs).
pub(super) fn insert_bodies(
    deck: &Deck,
    groups: &RigidGroups,
    constraints: &NodalConstraints,
    used: &BTreeMap<u32, (usize, &'static str)>,
    world: &mut Mpc184World,
    notes: &mut Vec<String>,
) -> Result<(Vec<DeckBody>, NodeBodies), Error> {
    let mut bodies: Vec<DeckBody> = Vec::new();
    let mut node_body: NodeBodies = BTreeMap::new();
    for nodes in &groups.groups {
        let g = group_mass(deck, nodes, &groups.masses);
        let fixed = nodes.iter().any(|n| constraints.fixed.contains(n));
        let label = nodes
            .iter()
            .map(u32::to_string)
            .collect::<Vec<_>>()
            .join(",");
        if g.mass <= 0.0 && !fixed {
            if let Some((n, (line, cmd))) = nodes.iter().find_map(|n| used.get(n).map(|u| (*n, *u)))
            {
                return Err(invalid(
                    deck,
                    line,
                    cmd,
                    format!(
                        "node {n} carries no mass: no MASS21 on it and no rigid beam or CERIG \
                         ties it to a node that has one (add a MASS21, tie it to a massive \
                         body, or fix it with D,{n},ALL,0)"
                    ),
                ));
            }
            notes.push(format!(
                "{}: nodes {label}: no mass and no joint or load: left fixed where they are",
                deck.file
            ));
        }
        // In `Real` too: the f32 build overflows sooner.
        let finite = g.mass.is_finite()
            && (g.mass as Real).is_finite()
            && vec3(g.com).is_finite()
            && g.inertia.iter().flatten().all(|x| x.is_finite());
        if !finite {
            return Err(invalid(
                deck,
                g.line,
                "E",
                format!(
                    "body of nodes {label}: its mass, centre of mass or inertia overflows (mass \
                     {:e} kg): masses and coordinates are too large",
                    g.mass
                ),
            ));
        }
        let index = bodies.len();
        let (handle, principal) = if fixed || g.mass <= 0.0 {
            let h = world
                .physics
                .bodies
                .insert(RigidBodyBuilder::fixed().translation(vec3(g.com)));
            (h, [0.0; 3])
        } else {
            insert_dynamic(deck, world, &g, &label, notes)?
        };
        for n in nodes {
            let p = deck.nodes[n].position;
            let off = [p[0] - g.com[0], p[1] - g.com[1], p[2] - g.com[2]];
            node_body.insert(*n, (Some(index), vec3(off)));
        }
        bodies.push(DeckBody {
            handle,
            nodes: nodes.clone(),
            mass: g.mass,
            inertia: principal,
            com: g.com,
            fixed: fixed || g.mass <= 0.0,
        });
    }
    Ok((bodies, node_body))
}

/// Mass, centre of mass and inertia of a group's point masses.
fn group_mass(deck: &Deck, nodes: &[u32], masses: &[PointMass]) -> GroupMass {
    let mut m = 0.0;
    let mut mx = [0.0; 3];
    for pm in masses.iter().filter(|pm| nodes.contains(&pm.node)) {
        let p = deck.nodes[&pm.node].position;
        m += pm.mass;
        for k in 0..3 {
            mx[k] += pm.mass * p[k];
        }
    }
    let com = if m > 0.0 {
        mx.map(|x| x / m)
    } else {
        deck.nodes[&nodes[0]].position
    };
    // Inertia about the centre of mass, global axes (parallel-axis sums).
    let mut inertia = [[0.0f64; 3]; 3];
    let mut r_max: f64 = 0.0;
    for n in nodes {
        let p = deck.nodes[n].position;
        let d = [p[0] - com[0], p[1] - com[1], p[2] - com[2]];
        r_max = r_max.max((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt());
    }
    for pm in masses.iter().filter(|pm| nodes.contains(&pm.node)) {
        let p = deck.nodes[&pm.node].position;
        let d = [p[0] - com[0], p[1] - com[1], p[2] - com[2]];
        let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        for a in 0..3 {
            inertia[a][a] += pm.inertia[a];
            for b in 0..3 {
                let delta = if a == b { d2 } else { 0.0 };
                inertia[a][b] += pm.mass * (delta - d[a] * d[b]);
            }
        }
    }
    let line = masses
        .iter()
        .find(|pm| nodes.contains(&pm.node))
        .map_or(0, |pm| pm.line);
    GroupMass {
        mass: m,
        com,
        inertia,
        r_max,
        line,
    }
}

/// A dynamic body for a group with mass: its inertia regularised where point masses leave an
/// axis without rotary inertia (see the module docs of the builder), refused if too light to
/// invert. Returns the handle and the principal moments.
fn insert_dynamic(
    deck: &Deck,
    world: &mut Mpc184World,
    g: &GroupMass,
    label: &str,
    notes: &mut Vec<String>,
) -> Result<(RigidBodyHandle, [f64; 3]), Error> {
    let m = g.mass;
    let i = g.inertia;
    let mat = Matrix::from_cols(vec3(i[0]), vec3(i[1]), vec3(i[2]));
    let mut mp = MassProperties::with_inertia_matrix(Vector::ZERO, m as Real, mat);
    let pi = mp.principal_inertia();
    let floor = POINT_MASS_INERTIA * m as Real * (g.r_max.max(0.01) as Real).powi(2);
    let largest = pi.max_element();
    if pi.min_element() < floor.max(1e-9 * largest) {
        let reg = Vector::new(pi.x.max(floor), pi.y.max(floor), pi.z.max(floor));
        mp = MassProperties::with_principal_inertia_frame(
            Vector::ZERO,
            m as Real,
            reg,
            mp.principal_inertia_local_frame,
        );
        notes.push(format!(
            "{}: body of nodes {label}: no rotary inertia about some axis (point masses); \
             {floor:.3e} kg m^2 added there so that it turns with its joints",
            deck.file
        ));
    }
    let pi = mp.principal_inertia();
    let inv = mp.inv_principal_inertia;
    if !(mp.inv_mass.is_finite() && mp.inv_mass > 0.0 && inv.is_finite() && inv.min_element() > 0.0)
    {
        // Too light (or too small) to invert: Rapier would take it as infinitely heavy on some
        // axis.
        return Err(invalid(
            deck,
            g.line,
            "E",
            format!(
                "body of nodes {label}: mass {m:e} kg, principal inertia {pi} kg m^2: too small \
                 to invert (give it a real mass, or fix it)"
            ),
        ));
    }
    let h = world.physics.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(vec3(g.com))
            .additional_mass_properties(mp)
            .can_sleep(false),
    );
    Ok((h, [pi.x as f64, pi.y as f64, pi.z as f64]))
}
