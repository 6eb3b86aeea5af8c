//! The joints of a block-sparse system as a forest: ordered from the leaves to the roots when
//! they close no loop. The Rapier backends' reaction recovery splits the impulses along it
//! (`backend/rapier/reactions/forest.rs`); the Lagrange backend gives a tree island its own
//! regularisation.

use super::kkt::JointBlockSpec;

/// One joint of the forest, with the body on its far side from the root.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Edge {
    /// The joint (index in the specs).
    pub(crate) joint: usize,
    /// The child body (its index in the specs) and its side of the joint (0: body 1).
    pub(crate) child: usize,
    pub(crate) side: usize,
    /// The parent body, `None` for the ground.
    pub(crate) parent: Option<usize>,
}

/// The joints with rows ordered from the leaves to the roots (each after every joint below
/// it), or `None` when they close a loop (through the ground too: the ground, fixed and
/// kinematic bodies are one node) or join two bodies twice. A tree without a grounded joint is
/// rooted at its first body.
pub(crate) fn leaves_first(specs: &[JointBlockSpec], nb: usize) -> Option<Vec<Edge>> {
    let ground = nb;
    // Per node: (joint, the other node, that node's side).
    let mut adj: Vec<Vec<(usize, usize, usize)>> = vec![Vec::new(); nb + 1];
    for (k, s) in specs.iter().enumerate() {
        if s.rows == 0 {
            continue;
        }
        let [n1, n2] = s.bodies.map(|b| b.unwrap_or(ground));
        if n1 == n2 {
            if n1 == ground {
                // Rows between two non-dynamic bodies act on no body: not an edge.
                continue;
            }
            return None;
        }
        adj[n1].push((k, n2, 1));
        adj[n2].push((k, n1, 0));
    }
    let mut via: Vec<Option<usize>> = vec![None; nb + 1];
    let mut seen = vec![false; nb + 1];
    let mut edges = Vec::with_capacity(specs.len());
    let mut queue = Vec::with_capacity(nb + 1);
    for root in core::iter::once(ground).chain(0..nb) {
        if seen[root] {
            continue;
        }
        seen[root] = true;
        queue.clear();
        queue.push(root);
        let mut next = 0;
        while let Some(&u) = queue.get(next) {
            next += 1;
            for &(joint, v, side) in &adj[u] {
                if via[u] == Some(joint) {
                    continue;
                }
                if seen[v] {
                    return None;
                }
                seen[v] = true;
                via[v] = Some(joint);
                edges.push(Edge {
                    joint,
                    child: v,
                    side,
                    parent: (u != ground).then_some(u),
                });
                queue.push(v);
            }
        }
    }
    edges.reverse();
    Some(edges)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(rows: usize, a: Option<usize>, b: Option<usize>) -> JointBlockSpec {
        JointBlockSpec {
            rows,
            bodies: [a, b],
        }
    }

    /// A grounded chain and a floating pair are a forest, children before parents; a loop
    /// through the ground, a double joint and a joint on one body are not.
    #[test]
    fn forests_and_loops() {
        let chain = [
            spec(5, None, Some(0)),
            spec(5, Some(0), Some(1)),
            spec(3, Some(2), Some(1)),
        ];
        let e = leaves_first(&chain, 3).expect("a chain is a tree");
        let order: Vec<(usize, usize, usize)> =
            e.iter().map(|e| (e.joint, e.child, e.side)).collect();
        assert_eq!(order, vec![(2, 2, 0), (1, 1, 1), (0, 0, 1)]);
        assert_eq!(e[0].parent, Some(1));
        assert_eq!(e[2].parent, None);
        let floating = [spec(6, Some(0), Some(1))];
        assert_eq!(leaves_first(&floating, 2).map(|e| e.len()), Some(1));
        let through_ground = [
            spec(5, None, Some(0)),
            spec(5, Some(0), Some(1)),
            spec(5, Some(1), None),
        ];
        assert!(leaves_first(&through_ground, 2).is_none());
        let double = [spec(3, Some(0), Some(1)), spec(2, Some(1), Some(0))];
        assert!(leaves_first(&double, 2).is_none());
        let own = [spec(1, Some(0), Some(0))];
        assert!(leaves_first(&own, 1).is_none());
    }
}
