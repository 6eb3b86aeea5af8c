//! Nodal constraints (`D`): which nodes fix their body (all six labels at 0 in every load step)
//! and which get a grounded general joint (partial or nonzero `D`).

use std::collections::{BTreeMap, BTreeSet};

use crate::apdl::Deck;
use crate::catalogue::JointKind;
use crate::dof::DofMask;
use crate::error::Error;
use crate::joint::Mpc184Joint;
use crate::world::Mpc184World;

use super::{DeckBody, NodalDrive, at_line, dof_of, invalid, unsupported, vec3};

/// The `D` commands of a deck, read across its load steps.
pub(super) struct NodalConstraints {
    /// Per node: the constrained labels and the first `D` line.
    pub(super) labels: BTreeMap<u32, (DofMask, usize)>,
    /// Per node: the labels given a nonzero value in some load step (released and driven).
    driven: BTreeMap<u32, DofMask>,
    /// Nodes with all six labels at 0 in every load step: their bodies are fixed.
    pub(super) fixed: BTreeSet<u32>,
}

impl NodalConstraints {
    /// Reads the `D` of every load step. The set of constrained labels of every node must stay
    /// the same in every load step (values may change).
    pub(super) fn read(deck: &Deck) -> Result<NodalConstraints, Error> {
        let mut labels: BTreeMap<u32, (DofMask, usize)> = BTreeMap::new();
        let mut driven: BTreeMap<u32, DofMask> = BTreeMap::new();
        for (k, ls) in deck.load_steps.iter().enumerate() {
            let mut now: BTreeMap<u32, (DofMask, usize)> = BTreeMap::new();
            for d in &ls.d {
                let e = now.entry(d.node).or_insert((DofMask::NONE, d.line));
                e.0 = e.0.union(DofMask::of(&[dof_of(d.dof)]));
                e.1 = e.1.min(d.line);
                if d.value != 0.0 {
                    let m = driven.entry(d.node).or_insert(DofMask::NONE);
                    *m = m.union(DofMask::of(&[dof_of(d.dof)]));
                }
            }
            if k == 0 {
                labels = now;
            } else if now
                .iter()
                .map(|(n, x)| (n, x.0))
                .ne(labels.iter().map(|(n, x)| (n, x.0)))
            {
                return Err(changed_labels(deck, ls.line, &labels, &now));
            }
        }
        let fixed = labels
            .iter()
            .filter(|(n, (m, _))| *m == DofMask::ALL && !driven.contains_key(n))
            .map(|(n, _)| *n)
            .collect();
        Ok(NodalConstraints {
            labels,
            driven,
            fixed,
        })
    }

    /// Partial or nonzero nodal constraints: a grounded general joint at the node, global
    /// axes, body 1 the ground and body 2 the node's body. Labels held at 0 in every load step
    /// are its constraints; labels with a nonzero value in some load step are released and
    /// driven (the drive, relative to time 0, is the node's displacement).
    pub(super) fn insert_joints(
        &self,
        deck: &Deck,
        world: &mut Mpc184World,
        bodies: &[DeckBody],
        node_body: &BTreeMap<u32, (Option<usize>, crate::math::Vector)>,
        notes: &mut Vec<String>,
    ) -> Result<Vec<NodalDrive>, Error> {
        let mut d_joints = Vec::new();
        for (node, (labels, line)) in &self.labels {
            if self.fixed.contains(node) {
                continue;
            }
            let Some((Some(b), _)) = node_body.get(node).copied() else {
                return Err(invalid(
                    deck,
                    *line,
                    "D",
                    format!("node {node} is not defined"),
                ));
            };
            let driven = self.driven.get(node).copied().unwrap_or(DofMask::NONE);
            if bodies[b].fixed {
                notes.push(format!(
                    "{}:{line}: D: node {node} is on a fixed body: its constraints ({labels}) \
                     have no effect",
                    deck.file
                ));
                continue;
            }
            let released = labels.complement().union(driven);
            let kind = JointKind::General {
                released,
                translations_only: false,
            };
            let joint = Mpc184Joint::new(kind, vec3(deck.nodes[node].position));
            let id = world
                .insert_joint(None, Some(bodies[b].handle), joint)
                .map_err(|x| at_line(deck, *line, "D", x))?;
            notes.push(format!(
                "{}:{line}: D: node {node} ({labels}): a grounded general joint, global axes{}",
                deck.file,
                if driven == DofMask::NONE {
                    String::new()
                } else {
                    format!("; {driven} released and driven by the D values")
                }
            ));
            d_joints.push(NodalDrive {
                node: *node,
                id,
                kind,
                driven,
            });
        }
        Ok(d_joints)
    }
}

/// The error for a load step whose `D` labels differ from the first load step's.
fn changed_labels(
    deck: &Deck,
    line: usize,
    first: &BTreeMap<u32, (DofMask, usize)>,
    now: &BTreeMap<u32, (DofMask, usize)>,
) -> Error {
    let node = now
        .iter()
        .map(|(n, x)| (*n, x.0))
        .chain(first.iter().map(|(n, x)| (*n, x.0)))
        .find(|(n, m)| now.get(n).map(|x| x.0) != Some(*m) || first.get(n).map(|x| x.0) != Some(*m))
        .map_or(0, |x| x.0);
    let show = |m: Option<DofMask>| m.unwrap_or(DofMask::NONE).to_string();
    unsupported(
        deck,
        line,
        "SOLVE",
        format!(
            "nodal constraints (D) on other labels than in the first load step (node {node}: {} \
             then {})",
            show(first.get(&node).map(|x| x.0)),
            show(now.get(&node).map(|x| x.0))
        ),
        "keep the set of constrained labels of every node the same in every load step (the \
         values may change: set a value back to 0 rather than deleting it with DDELE)",
    )
}
