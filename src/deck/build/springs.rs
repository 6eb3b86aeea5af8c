//! COMBIN14 spring-dampers: one [`SpringDamper`] per element between the bodies of its two
//! nodes (a node on a fixed body, `D,node,ALL,0`, is a ground point).
//!
//! | real constant | here |
//! |---|---|
//! | R1 K (N/m) | [`SpringDamper::stiffness`] |
//! | R2 CV1 (N s/m) | [`SpringDamper::damping`] |
//! | R3 CV2 (N s^2/m^2) | [`SpringDamper::damping_quadratic`]: damping `CV1 + CV2 |L'|` |
//! | R4, R5 | not used by the 3-D longitudinal option (a note if nonzero) |
//! | R6 ILEN (m, `RMORE`) | [`SpringDamper::rest_length`]: the free length; 0 or blank: the node distance at time 0 |
//! | R7 IFORCE (N, `RMORE`) | [`SpringDamper::preload`]: the tension at time 0 (ignored with a note when ILEN is given, as ANSYS does) |

use crate::apdl::{Deck, ElementRole};
use crate::error::{Error, SpringId};
use crate::spring::SpringDamper;
use crate::world::Mpc184World;

use super::bodies::NodeBodies;
use super::{DeckBody, invalid, vec3};

/// One COMBIN14 element and its spring in the world.
#[derive(Clone, Copy, Debug)]
pub struct DeckSpring {
    /// Element number.
    pub element: u32,
    /// The spring in the world.
    pub id: SpringId,
    /// The bodies of nodes I and J (index into [`super::DeckModel::bodies`]).
    pub bodies: [usize; 2],
}

/// Inserts a spring for every COMBIN14 element.
pub(super) fn insert_springs(
    deck: &Deck,
    world: &mut Mpc184World,
    bodies: &[DeckBody],
    node_body: &NodeBodies,
    notes: &mut Vec<String>,
) -> Result<Vec<DeckSpring>, Error> {
    let mut springs = Vec::new();
    for e in deck.elements.values() {
        if deck.role_of(e) != Some(ElementRole::Spring) {
            continue;
        }
        let bad = |reason: String| invalid(deck, e.line, "E", reason);
        let (Some(i), Some(j)) = (e.i, e.j) else {
            return Err(bad(format!(
                "COMBIN14 element {} needs nodes I and J",
                e.id
            )));
        };
        let side = |n: u32| -> Result<usize, Error> {
            node_body.get(&n).and_then(|x| x.0).ok_or_else(|| {
                bad(format!(
                    "COMBIN14 element {}: node {n} is not defined",
                    e.id
                ))
            })
        };
        let (b1, b2) = (side(i)?, side(j)?);
        if b1 == b2 {
            return Err(bad(format!(
                "COMBIN14 element {}: nodes {i} and {j} are on one rigid body: the spring would \
                 act on nothing",
                e.id
            )));
        }
        if bodies[b1].fixed && bodies[b2].fixed {
            return Err(bad(format!(
                "COMBIN14 element {}: both nodes are fixed (D,ALL,0 or no mass): nothing can move",
                e.id
            )));
        }
        let real = deck.real_constants.get(&e.real).ok_or_else(|| {
            bad(format!(
                "COMBIN14 element {}: real constant set {} is never defined",
                e.id, e.real
            ))
        })?;
        let r = |k: usize| real.values.get(k).copied().unwrap_or(0.0);
        let (ilen, iforce) = (r(5), r(6));
        if r(3) != 0.0 || r(4) != 0.0 {
            notes.push(format!(
                "{}:{}: R,{}: real constants 4 and 5 are not used by the 3-D longitudinal \
                 COMBIN14 (ignored)",
                deck.file, real.line, real.id
            ));
        }
        if ilen != 0.0 && iforce != 0.0 {
            notes.push(format!(
                "{}:{}: R,{}: ILEN and IFORCE both given: ILEN sets the free length, IFORCE is \
                 ignored",
                deck.file, real.line, real.id
            ));
        }
        let mut spring = SpringDamper {
            point1: vec3(deck.nodes[&i].position),
            point2: vec3(deck.nodes[&j].position),
            stiffness: r(0) as _,
            damping: r(1) as _,
            damping_quadratic: r(2) as _,
            rest_length: None,
            preload: 0.0,
        };
        if ilen != 0.0 {
            spring.rest_length = Some(ilen as _);
        } else {
            spring.preload = iforce as _;
        }
        let handle = |b: usize| (!bodies[b].fixed).then_some(bodies[b].handle);
        let (h1, h2) = (handle(b1), handle(b2));
        // A fixed body's node is a ground point where it is: the world's ground stands in.
        let id = world
            .insert_spring(h1, h2, spring)
            .map_err(|x| bad(format!("COMBIN14 element {} (R,{}): {x}", e.id, real.id)))?;
        springs.push(DeckSpring {
            element: e.id,
            id,
            bodies: [b1, b2],
        });
    }
    Ok(springs)
}
