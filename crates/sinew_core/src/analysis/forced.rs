//! The edge strain a muscle's attachments force, whatever the solver does.
//!
//! ```text
//! forced = max over attached a, b on different bones of  |x_a − x_b| / d(a, b)
//! ```
//! `d(a, b)` is the shortest path from `a` to `b` over the mesh's edges (the
//! edges the strain figures measure) at their rest lengths. Any such path
//! is now at least `|x_a − x_b|` long and is made of edges whose lengths
//! grew by at most the largest strain `s`, so `s·d(a, b) ≥ |x_a − x_b|`:
//! `forced` is a lower bound on the largest edge strain of the frame. Where
//! it is above the strain range, no solver can keep the muscle in range
//! with its attachments held. (The span of the attachment groups'
//! centroids assumes a straight muscle: a muscle curved at rest has room
//! to straighten, one whose rings are close together has less than its
//! span says.)

use crate::muscle::Muscle;
use glam::Vec3;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// Pairs of a muscle's attached vertices on different bones, with their
/// shortest rest path over the mesh's edges (see the module).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ForcedStrain {
    /// `(a, b, d(a, b))`: particle indices and the rest path length (scene
    /// units), for every pair that a path joins.
    pairs: Vec<(u32, u32, f32)>,
}

impl ForcedStrain {
    /// The pairs of `m`'s attachments (see [`ForcedStrain::from_edges`]).
    pub fn new(m: &Muscle) -> Self {
        let attached: Vec<(u32, Option<usize>)> = m
            .attachments
            .iter()
            .map(|a| (a.vertex.index() as u32, a.bone))
            .collect();
        Self::from_edges(&m.rest, &m.mesh.edges, &attached)
    }

    /// The pairs of `attached` vertices (particle, bone) on different bones
    /// (the world, `None`, counts as one), with the shortest path between
    /// them over `edges` at their lengths in `rest`. Empty where every
    /// attachment is on one bone.
    pub fn from_edges(
        rest: &[Vec3],
        edges: &[[u32; 2]],
        attached: &[(u32, Option<usize>)],
    ) -> Self {
        let mut around = vec![Vec::new(); rest.len()];
        for &[a, b] in edges {
            let length = rest[a as usize].distance(rest[b as usize]);
            around[a as usize].push((b, length));
            around[b as usize].push((a, length));
        }
        let mut pairs = Vec::new();
        let mut distance = vec![f32::INFINITY; rest.len()];
        for (k, &(a, bone_a)) in attached.iter().enumerate() {
            if !attached[k + 1..].iter().any(|&(_, bone)| bone != bone_a) {
                continue;
            }
            shortest_paths(&around, a, &mut distance);
            for &(b, bone_b) in &attached[k + 1..] {
                let d = distance[b as usize];
                if bone_b != bone_a && d.is_finite() && d > 0.0 {
                    pairs.push((a, b, d));
                }
            }
        }
        Self { pairs }
    }

    /// The forced strain of positions `x` (see the module); `None` without
    /// pairs (a muscle attached to one bone).
    pub fn at(&self, x: &[Vec3]) -> Option<f32> {
        self.pairs
            .iter()
            .map(|&(a, b, d)| x[a as usize].distance(x[b as usize]) / d)
            .reduce(f32::max)
    }
}

/// Dijkstra from `source` over `around` (neighbour, edge length) into
/// `distance` (refilled).
fn shortest_paths(around: &[Vec<(u32, f32)>], source: u32, distance: &mut [f32]) {
    distance.fill(f32::INFINITY);
    distance[source as usize] = 0.0;
    let mut queue = BinaryHeap::from([(Reverse(OrderedLength(0.0)), source)]);
    while let Some((Reverse(OrderedLength(d)), v)) = queue.pop() {
        if d > distance[v as usize] {
            continue;
        }
        for &(w, length) in &around[v as usize] {
            let through = d + length;
            if through < distance[w as usize] {
                distance[w as usize] = through;
                queue.push((Reverse(OrderedLength(through)), w));
            }
        }
    }
}

/// A finite, non-negative length ordered for the queue.
#[derive(Clone, Copy, Debug, PartialEq)]
struct OrderedLength(f32);

impl Eq for OrderedLength {}

impl PartialOrd for OrderedLength {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for OrderedLength {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ladder of `n` rungs along X (two rails 1 apart in Y), rungs 1
    /// apart: rail edges, rungs and one diagonal per square.
    fn ladder(n: usize) -> (Vec<Vec3>, Vec<[u32; 2]>) {
        let rest: Vec<Vec3> = (0..n)
            .flat_map(|i| [Vec3::new(i as f32, 0.0, 0.0), Vec3::new(i as f32, 1.0, 0.0)])
            .collect();
        let mut edges = Vec::new();
        for i in 0..n as u32 {
            edges.push([2 * i, 2 * i + 1]);
            if i + 1 < n as u32 {
                edges.extend([
                    [2 * i, 2 * i + 2],
                    [2 * i + 1, 2 * i + 3],
                    [2 * i, 2 * i + 3],
                ]);
            }
        }
        (rest, edges)
    }

    #[test]
    fn a_uniform_stretch_is_forced_whole() {
        let (rest, edges) = ladder(5);
        // First rung on bone 0, last on bone 1.
        let attached = [(0, Some(0)), (1, Some(0)), (8, Some(1)), (9, Some(1))];
        let forced = ForcedStrain::from_edges(&rest, &edges, &attached);
        assert_eq!(forced.pairs.len(), 4);
        assert_eq!(forced.at(&rest), Some(1.0));
        let stretched: Vec<Vec3> = rest
            .iter()
            .map(|p| Vec3::new(p.x * 1.5, p.y, p.z))
            .collect();
        let s = forced.at(&stretched).unwrap();
        assert!((s - 1.5).abs() < 1e-6, "{s}");
        // The bound holds: no edge of the stretched ladder is longer than
        // it allows, and the rails reach it.
        let largest = edges
            .iter()
            .map(|&[a, b]| {
                stretched[a as usize].distance(stretched[b as usize])
                    / rest[a as usize].distance(rest[b as usize])
            })
            .fold(0.0, f32::max);
        assert!(largest >= s - 1e-6, "{largest} < {s}");
    }

    #[test]
    fn a_bent_strip_straightened_is_not_forced_by_its_chord() {
        // A strip folded into a U (every edge keeps its length): its end
        // rungs 1 apart, its rails 7 long.
        let (straight, edges) = ladder(8);
        let bend = |p: Vec3| {
            if p.x <= 3.0 {
                Vec3::new(p.x, p.y, 0.0)
            } else {
                Vec3::new(7.0 - p.x, p.y, 1.0)
            }
        };
        let rest: Vec<Vec3> = straight.iter().map(|&p| bend(p)).collect();
        let attached = [(0, Some(0)), (1, Some(0)), (14, Some(1)), (15, Some(1))];
        let forced = ForcedStrain::from_edges(&rest, &edges, &attached);
        // Straightened, its end rungs are 7 apart: the chord grew ×7, the
        // paths not at all.
        assert!((rest[0].distance(rest[14]) - 1.0).abs() < 1e-6);
        let s = forced.at(&straight).unwrap();
        assert!((s - 1.0).abs() < 1e-6, "{s}");
    }

    #[test]
    fn one_bone_forces_nothing() {
        let (rest, edges) = ladder(3);
        let forced = ForcedStrain::from_edges(&rest, &edges, &[(0, Some(2)), (5, Some(2))]);
        assert_eq!(forced.at(&rest), None);
        let world = ForcedStrain::from_edges(&rest, &edges, &[(0, None), (5, Some(2))]);
        assert_eq!(world.pairs.len(), 1);
    }
}
