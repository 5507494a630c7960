//! What each triangle of a scanned bone is: a wall of the bone, or a loose
//! sheet outside or inside it, with its winding made consistent first.
//!
//! Scanned bones are not clean surfaces: the full body's torso, head and
//! neck have hundreds of open edges, a few triangles wound the wrong way and
//! overlapping shells (the skull, its jaw, its teeth). Two passes make their
//! sides readable (see the `side` module):
//!
//! 1. [`orient`]: the triangles of each piece that hangs together across
//!    edges shared by exactly two triangles are wound consistently with
//!    each other, the way most of them already were. A wrongly wound
//!    triangle corrupts the winding number right next to it by a whole
//!    turn, so this comes first.
//! 2. [`classify`]: the winding number at a triangle's centre, the
//!    triangle itself left out (the mean of just in front and just
//!    behind, where its own solid angle is a half turn either way), is ½
//!    for a wall (the rest of the surface wraps half-way around it), 0
//!    for a sheet outside the bone and 1 (or more) for one inside another
//!    shell.

use super::winding::WindingTree;
use glam::Vec3;
use rayon::prelude::*;
use std::collections::HashMap;

/// What one triangle of a rigid target is ([`classify`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum FaceKind {
    /// A wall of the bone: outside in front of it, inside behind it.
    Wall,
    /// A loose sheet outside the bone: outside on both sides.
    Outside,
    /// A sheet inside the bone: inside on both sides.
    Inside,
}

/// Per undirected edge `(low, high)`, the triangles on it and whether each
/// runs along it from low to high ([`edge_table`]).
pub(super) type EdgeTable = HashMap<(u32, u32), Vec<(u32, bool)>>;

/// The [`EdgeTable`] of `triangles`.
pub(super) fn edge_table(triangles: &[[u32; 3]]) -> EdgeTable {
    let mut edges = EdgeTable::with_capacity(3 * triangles.len() / 2);
    for (i, t) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            edges
                .entry((a.min(b), a.max(b)))
                .or_default()
                .push((i as u32, a < b));
        }
    }
    edges
}

/// Whether every edge (of the surface `edges` is the table of) has exactly
/// two triangles, which run along it in opposite directions: a closed,
/// consistently wound surface.
pub(super) fn closed_and_consistent(edges: &EdgeTable) -> bool {
    edges
        .values()
        .all(|on| matches!(on[..], [(_, a), (_, b)] if a != b))
}

/// `triangles` wound consistently within each piece connected across
/// edges of exactly two triangles (module docs): a triangle is turned where
/// it runs along such an edge the same way as its neighbour, and a piece
/// is turned whole where that turned most of its triangles, so the
/// majority's winding is kept. `edges`: their [`EdgeTable`].
pub(super) fn orient(triangles: &[[u32; 3]], edges: &EdgeTable) -> Vec<[u32; 3]> {
    let n = triangles.len();
    // Per triangle: whether it is turned, and whether it was reached yet.
    let mut turned = vec![false; n];
    let mut reached = vec![false; n];
    let mut queue = Vec::new();
    for seed in 0..n {
        if reached[seed] {
            continue;
        }
        reached[seed] = true;
        queue.clear();
        queue.push(seed as u32);
        let mut piece = Vec::new();
        while let Some(t) = queue.pop() {
            piece.push(t);
            let tri = triangles[t as usize];
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let [(u, u_up), (v, v_up)] = edges[&(a.min(b), a.max(b))][..] else {
                    continue;
                };
                let (other, other_up) = if u == t { (v, v_up) } else { (u, u_up) };
                if reached[other as usize] {
                    continue;
                }
                reached[other as usize] = true;
                // Same direction along the edge: the windings disagree.
                turned[other as usize] = turned[t as usize] ^ ((a < b) == other_up);
                queue.push(other);
            }
        }
        let flips = piece.iter().filter(|&&t| turned[t as usize]).count();
        if 2 * flips > piece.len() {
            for &t in &piece {
                turned[t as usize] = !turned[t as usize];
            }
        }
    }
    triangles
        .iter()
        .zip(turned)
        .map(|(&[a, b, c], turn)| if turn { [a, c, b] } else { [a, b, c] })
        .collect()
}

/// Each triangle's kind, from the winding number of the `oriented`
/// surface at its centre (module docs): below ¼ a sheet outside, above ¾ a
/// sheet inside, a wall between.
pub(super) fn classify(
    positions: &[Vec3],
    oriented: &[[u32; 3]],
    tree: &WindingTree,
) -> Vec<FaceKind> {
    oriented
        .par_iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            // Just in front and just behind: the triangle's own half turn
            // cancels out of the mean (on it, its solid angle is undefined).
            let (centre, normal) = ((a + b + c) / 3.0, (b - a).cross(c - a).normalize_or_zero());
            let step = 1e-4 * (a.distance(b) + b.distance(c) + c.distance(a));
            let at = |p: Vec3| tree.winding_number(p);
            let w = 0.5 * (at(centre + normal * step) + at(centre - normal * step));
            if w < 0.25 {
                FaceKind::Outside
            } else if w > 0.75 {
                FaceKind::Inside
            } else {
                FaceKind::Wall
            }
        })
        .collect()
}
