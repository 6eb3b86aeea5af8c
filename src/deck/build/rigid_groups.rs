//! Rigid groups: nodes tied into one body by rigid beams (MPC184 KEYOPT(1) = 1) and `CERIG`
//! (union-find), the point masses (`MASS21`) on them, and the nodes that matter (on joints,
//! loads and initial conditions).

use std::collections::BTreeMap;

use crate::apdl::{Deck, Element, ElementRole, ElementType};
use crate::error::Error;

use super::constraints::NodalConstraints;
use super::{err, invalid, unsupported};
use crate::apdl::DeckErrorKind;

/// A `MASS21` element: its node, mass (kg), rotary inertia about the node in global axes
/// (kg m^2) and deck line.
#[derive(Clone, Copy, Debug)]
pub(super) struct PointMass {
    pub(super) node: u32,
    pub(super) mass: f64,
    pub(super) inertia: [f64; 3],
    pub(super) line: usize,
}

/// The deck's nodes grouped into rigid bodies, and its point masses.
pub(super) struct RigidGroups {
    /// The node groups, each ascending, by their lowest node.
    pub(super) groups: Vec<Vec<u32>>,
    pub(super) masses: Vec<PointMass>,
}

struct UnionFind(BTreeMap<u32, u32>);

impl UnionFind {
    /// The root of `x`, compressing the path (iterative: a deck can chain any number of nodes).
    fn find(&mut self, x: u32) -> u32 {
        let mut root = x;
        loop {
            let p = *self.0.entry(root).or_insert(root);
            if p == root {
                break;
            }
            root = p;
        }
        let mut y = x;
        while y != root {
            let next = self.0.insert(y, root).unwrap_or(root);
            y = next;
        }
        root
    }
    fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            let (lo, hi) = (ra.min(rb), ra.max(rb));
            self.0.insert(hi, lo);
        }
    }
}

impl RigidGroups {
    /// Reads the rigid beams, `CERIG` and `MASS21` elements of a deck.
    pub(super) fn read(deck: &Deck) -> Result<RigidGroups, Error> {
        let mut uf = UnionFind(BTreeMap::new());
        for n in deck.nodes.keys() {
            uf.find(*n);
        }
        let mut masses = Vec::new();
        for e in deck.elements.values() {
            let et = deck
                .element_type_of(e)
                .ok_or_else(|| invalid(deck, e.line, "E", "element type missing"))?;
            match deck.role_of(e) {
                Some(ElementRole::RigidBeam) => {
                    let (Some(i), Some(j)) = (e.i, e.j) else {
                        return Err(invalid(
                            deck,
                            e.line,
                            "E",
                            format!("rigid beam element {} needs two nodes", e.id),
                        ));
                    };
                    uf.union(i, j);
                }
                // A pin-ended distance constraint between two bodies: a joint.
                Some(ElementRole::RigidLink | ElementRole::Joint | ElementRole::Spring) | None => {}
                Some(ElementRole::Mass) => masses.push(point_mass(deck, e, et)?),
            }
        }
        for r in &deck.rigid_regions {
            let all = r.dofs.iter().any(|d| d == "ALL")
                || (r.dofs.iter().any(|d| d == "UXYZ") && r.dofs.iter().any(|d| d == "RXYZ"));
            if !all {
                return Err(unsupported(
                    deck,
                    r.line,
                    "CERIG",
                    format!("CERIG on some DOFs only ({})", r.dofs.join(" ")),
                    "CERIG,master,slave,ALL ties the nodes into one rigid body; partial \
                     couplings are joints (use an MPC184 joint)",
                ));
            }
            uf.union(r.master, r.slave);
        }
        let mut groups: BTreeMap<u32, Vec<u32>> = BTreeMap::new();
        for n in deck.nodes.keys() {
            let r = uf.find(*n);
            groups.entry(r).or_default().push(*n);
        }
        Ok(RigidGroups {
            groups: groups.into_values().collect(),
            masses,
        })
    }
}

/// A `MASS21` element's mass and inertia (KEYOPT(3) = 0: mass and rotary inertia; 2: mass
/// only).
fn point_mass(deck: &Deck, e: &Element, et: &ElementType) -> Result<PointMass, Error> {
    let Some(node) = e.i.or(e.j).filter(|n| deck.nodes.contains_key(n)) else {
        return Err(invalid(
            deck,
            e.line,
            "E",
            format!("MASS21 element {} needs a defined node", e.id),
        ));
    };
    let r = deck.real_constants.get(&e.real).ok_or_else(|| {
        err(
            deck,
            e.line,
            "E",
            DeckErrorKind::MissingReference {
                what: format!(
                    "MASS21 element {}: real constant set {} is not defined",
                    e.id, e.real
                ),
            },
        )
    })?;
    let v = |k: usize| r.values.get(k).copied().unwrap_or(0.0);
    let (m, inertia) = match et.keyopt(3) {
        0 => {
            if v(0) != v(1) || v(0) != v(2) {
                return Err(unsupported(
                    deck,
                    r.line,
                    "R",
                    format!(
                        "MASS21 with direction-dependent mass ({}, {}, {})",
                        v(0),
                        v(1),
                        v(2)
                    ),
                    "rigid bodies have one mass: give MASSX = MASSY = MASSZ",
                ));
            }
            (v(0), [v(3), v(4), v(5)])
        }
        2 => (v(0), [0.0; 3]),
        k => {
            return Err(unsupported(
                deck,
                et.line,
                "ET",
                format!("MASS21 KEYOPT(3) = {k} (2-D mass)"),
                "use KEYOPT(3) = 0 (mass and rotary inertia) or 2 (mass only)",
            ));
        }
    };
    if m < 0.0 || inertia.iter().any(|x| *x < 0.0) {
        return Err(invalid(deck, r.line, "R", "negative mass or inertia"));
    }
    Ok(PointMass {
        node,
        mass: m,
        inertia,
        line: e.line,
    })
}

/// The nodes that matter (on joints, springs, loads, initial conditions and partial or nonzero
/// `D`),
/// each with the line and command that first uses it: a body of such nodes needs mass.
pub(super) fn used_nodes(
    deck: &Deck,
    constraints: &NodalConstraints,
) -> BTreeMap<u32, (usize, &'static str)> {
    let mut used: BTreeMap<u32, (usize, &'static str)> = BTreeMap::new();
    for e in deck.elements.values() {
        if matches!(
            deck.role_of(e),
            Some(ElementRole::Joint | ElementRole::RigidLink | ElementRole::Spring)
        ) {
            for n in [e.i, e.j].into_iter().flatten() {
                used.entry(n).or_insert((e.line, "E"));
            }
        }
    }
    for ls in &deck.load_steps {
        for f in &ls.f {
            used.entry(f.node).or_insert((f.line, "F"));
        }
    }
    for ic in &deck.initial_conditions {
        used.entry(ic.node).or_insert((ic.line, "IC"));
    }
    for (n, (_, line)) in &constraints.labels {
        if !constraints.fixed.contains(n) {
            used.entry(*n).or_insert((*line, "D"));
        }
    }
    used
}
