//! Initial velocities (`IC`): each body's rigid velocity, least-squares fitted to the
//! velocities given at its nodes (unspecified DOFs 0, as in ANSYS).

use std::collections::BTreeSet;

use crate::apdl::{Deck, DofLabel};
use crate::error::Error;
use crate::world::Mpc184World;

use super::bodies::NodeBodies;
use super::{DeckBody, invalid, unsupported, vec3};

/// Sets the initial velocity of every body with an `IC` on one of its nodes.
pub(super) fn set_initial(
    deck: &Deck,
    world: &mut Mpc184World,
    bodies: &[DeckBody],
    node_body: &NodeBodies,
    static_run: bool,
    notes: &mut Vec<String>,
) -> Result<(), Error> {
    let mut ic_bodies: BTreeSet<usize> = BTreeSet::new();
    for ic in &deck.initial_conditions {
        if ic.displacement != 0.0 {
            return Err(unsupported(
                deck,
                ic.line,
                "IC",
                "an initial displacement",
                "move the node in N instead (the deck's geometry is the initial configuration)",
            ));
        }
        let Some((Some(b), _)) = node_body.get(&ic.node).copied() else {
            return Err(invalid(
                deck,
                ic.line,
                "IC",
                format!("node {} is not defined", ic.node),
            ));
        };
        if bodies[b].fixed {
            if ic.velocity != 0.0 {
                notes.push(format!(
                    "{}:{}: IC: node {} is on a fixed body: its velocity is ignored",
                    deck.file, ic.line, ic.node
                ));
            }
            continue;
        }
        if static_run {
            notes.push(format!(
                "{}:{}: IC: a static run has no velocities: ignored",
                deck.file, ic.line
            ));
            continue;
        }
        ic_bodies.insert(b);
    }
    for b in ic_bodies {
        let x = rigid_velocity(deck, &bodies[b], notes);
        let rb = &mut world.physics.bodies[bodies[b].handle];
        rb.set_linvel(vec3([x[0], x[1], x[2]]), true);
        rb.set_angvel(vec3([x[3], x[4], x[5]]), true);
    }
    Ok(())
}

/// The rigid velocity `[v; w]` (centre of mass) that fits the body's nodal velocities best in
/// the least-squares sense; a misfit above 1e-9 is noted.
fn rigid_velocity(deck: &Deck, body: &DeckBody, notes: &mut Vec<String>) -> [f64; 6] {
    let mut ata = [[0.0f64; 6]; 6];
    let mut atb = [0.0f64; 6];
    let mut rows: Vec<([f64; 6], f64)> = Vec::new();
    for n in &body.nodes {
        let given = |dof: DofLabel| {
            deck.initial_conditions
                .iter()
                .rev()
                .find(|ic| ic.node == *n && ic.dof == dof)
                .map_or(0.0, |ic| ic.velocity)
        };
        let p = deck.nodes[n].position;
        let c = body.com;
        let r = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
        // v + w x r = u: w x r = (wy rz - wz ry, wz rx - wx rz, wx ry - wy rx).
        rows.push(([1.0, 0.0, 0.0, 0.0, r[2], -r[1]], given(DofLabel::Ux)));
        rows.push(([0.0, 1.0, 0.0, -r[2], 0.0, r[0]], given(DofLabel::Uy)));
        rows.push(([0.0, 0.0, 1.0, r[1], -r[0], 0.0], given(DofLabel::Uz)));
        rows.push(([0.0, 0.0, 0.0, 1.0, 0.0, 0.0], given(DofLabel::RotX)));
        rows.push(([0.0, 0.0, 0.0, 0.0, 1.0, 0.0], given(DofLabel::RotY)));
        rows.push(([0.0, 0.0, 0.0, 0.0, 0.0, 1.0], given(DofLabel::RotZ)));
    }
    for (a, y) in &rows {
        for i in 0..6 {
            atb[i] += a[i] * y;
            for j in 0..6 {
                ata[i][j] += a[i] * a[j];
            }
        }
    }
    let x = solve6(ata, atb);
    let residual = rows
        .iter()
        .map(|(a, y)| (a.iter().zip(&x).map(|(p, q)| p * q).sum::<f64>() - y).abs())
        .fold(0.0, f64::max);
    if residual > 1e-9 {
        notes.push(format!(
            "{}: IC: the initial velocities of nodes {} are not those of one rigid body (largest \
             misfit {residual:.3e}): least-squares rigid velocity used",
            deck.file,
            body.nodes
                .iter()
                .map(u32::to_string)
                .collect::<Vec<_>>()
                .join(",")
        ));
    }
    x
}

/// Least-squares solve of the normal equations `A x = b` (6x6, symmetric positive
/// semi-definite) with a tiny Tikhonov term, by Gaussian elimination.
fn solve6(mut a: [[f64; 6]; 6], mut b: [f64; 6]) -> [f64; 6] {
    let scale = (0..6).map(|i| a[i][i]).fold(0.0, f64::max).max(1.0);
    for (i, row) in a.iter_mut().enumerate() {
        row[i] += 1e-12 * scale;
    }
    for c in 0..6 {
        let p = (c..6)
            .max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))
            .unwrap_or(c);
        a.swap(c, p);
        b.swap(c, p);
        let d = a[c][c];
        if d.abs() < 1e-300 {
            continue;
        }
        for r in c + 1..6 {
            let f = a[r][c] / d;
            let pivot_row = a[c];
            for (x, p) in a[r].iter_mut().zip(pivot_row).skip(c) {
                *x -= f * p;
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = [0.0; 6];
    for c in (0..6).rev() {
        let s: f64 = (c + 1..6).map(|k| a[c][k] * x[k]).sum();
        x[c] = if a[c][c].abs() < 1e-300 {
            0.0
        } else {
            (b[c] - s) / a[c][c]
        };
    }
    x
}
