//! The generalised winding number (Jacobson et al. 2013), exact and fast.
//!
//! The winding number of a surface around a point is the solid angle its
//! triangles span seen from the point, over 4π: ≈ 1 inside, ≈ 0 outside,
//! and it degrades gracefully where a scanned bone has holes, slivers or a
//! few flipped triangles, where the sign of a closest point's normal does
//! not (the torso, head and neck of the full body have hundreds of open and
//! inconsistent edges).
//!
//! Summing every triangle is O(triangles). The fast form (Barill et al.
//! 2018) walks the target's BVH: a node whose triangles are all far from
//! the point, relative to their extent, contributes as one dipole (their
//! area-weighted normals summed at their area-weighted centre); only near
//! nodes are summed triangle by triangle. Built once for a rigid target.
//!
//! A query on one of T7's bones visits about a hundred nodes and sums
//! about ninety triangles, wherever they lie in memory. So each node is one
//! 32-byte record holding its dipole and what it contains (where it read a
//! dipole and then the BVH's node), and each leaf's triangles are copied
//! out as corner positions side by side in leaf order (where it read the
//! BVH's order, the triangles and their nine corners): the same sums in
//! the same order, ×0.8–0.85 of the time per query in T7's walk.

use super::bvh::{NodeContents, TriangleBvh};
use glam::{DVec3, Vec3, Vec3A};

/// Solid angle of triangle `abc` seen from the origin (the corners relative
/// to the point), signed: positive where the triangle's winding faces away
/// from the point (Van Oosterom and Strackee 1983).
pub(super) fn solid_angle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let numerator = a.dot(b.cross(c));
    let denominator = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    2.0 * numerator.atan2(denominator)
}

/// [`solid_angle`] in single precision, for the fast winding number's near
/// triangles: it only has to tell ½ from 0 or 1.
fn solid_angle_f32(a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let numerator = a.dot(b.cross(c));
    let denominator = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    2.0 * numerator.atan2(denominator)
}

/// A node seen from far away: every triangle under it at once, and what it
/// holds.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(32))]
struct Node {
    /// Area-weighted centre of the node's triangles.
    centre: Vec3,
    /// Distance from `centre` to the farthest corner of the node's box.
    radius: f32,
    /// Sum of the triangles' area vectors (½ of the edges' cross product).
    area: Vec3,
    /// A leaf: where its triangles start in [`WindingTree::corners`], and
    /// in the top [`COUNT_BITS`] bits how many there are; an inner node:
    /// its left child (the right one follows it), the top bits 0.
    contents: u32,
}

/// Bits of [`Node::contents`] that count a leaf's triangles.
const COUNT_BITS: u32 = 3;

/// Bits of [`Node::contents`] below the count.
const START_MASK: u32 = u32::MAX >> COUNT_BITS;

/// The dipoles of a rigid target's BVH nodes and its triangles' corners
/// in leaf order (module docs).
#[derive(Clone, Debug, Default)]
pub(super) struct WindingTree {
    nodes: Vec<Node>,
    corners: Vec<[Vec3; 3]>,
}

/// A node is summed as one dipole when the point is farther from its
/// centre than this many times its radius: relative error of order
/// `1 / FAR²` on the node's share.
const FAR: f32 = 2.0;

impl WindingTree {
    /// The dipoles of `bvh`'s nodes over `triangles` at `positions`, and
    /// the corners of its leaves' triangles.
    pub(super) fn new(bvh: &TriangleBvh, positions: &[Vec3], triangles: &[[u32; 3]]) -> Self {
        let mut nodes = vec![Node::default(); bvh.node_count()];
        let mut corners = Vec::with_capacity(triangles.len());
        // Children come after their parents: a reverse sweep sees them first.
        let mut weight = vec![0.0f32; nodes.len()];
        for i in (0..nodes.len()).rev() {
            let (min, max, contents) = bvh.node(i);
            let (mut centre, mut area, mut total) = (Vec3::ZERO, Vec3::ZERO, 0.0);
            let contents = match contents {
                NodeContents::Leaf(list) => {
                    let start = corners.len() as u32;
                    for &t in list {
                        let [a, b, c] = triangles[t as usize].map(|v| positions[v as usize]);
                        corners.push([a, b, c]);
                        let vector = 0.5 * (b - a).cross(c - a);
                        let size = vector.length();
                        area += vector;
                        centre += size * (a + b + c) / 3.0;
                        total += size;
                        if size == 0.0 {
                            centre += a;
                            total += f32::MIN_POSITIVE;
                        }
                    }
                    debug_assert!(list.len() < 1 << COUNT_BITS && start <= START_MASK);
                    start | (list.len() as u32) << (32 - COUNT_BITS)
                }
                NodeContents::Inner(left) => {
                    for child in [left, left + 1] {
                        area += nodes[child].area;
                        centre += weight[child] * nodes[child].centre;
                        total += weight[child];
                    }
                    left as u32
                }
            };
            let centre = if total > 0.0 {
                centre / total
            } else {
                Vec3::from((min + max) * 0.5)
            };
            let corner = Vec3A::from(centre);
            let radius = (corner - min).abs().max((max - corner).abs()).length();
            nodes[i] = Node {
                centre,
                radius,
                area,
                contents,
            };
            weight[i] = total;
        }
        Self { nodes, corners }
    }

    /// Winding number around local point `q` of the surface the tree was
    /// built over (module docs).
    pub(super) fn winding_number(&self, q: Vec3) -> f32 {
        if self.nodes.is_empty() {
            return 0.0;
        }
        let mut sum = 0.0f64;
        let mut stack = [0usize; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top]];
            let r = node.centre - q;
            let far = r.length_squared();
            if far > (FAR * node.radius).powi(2) {
                sum += f64::from(node.area.dot(r) / (far * far.sqrt()));
                continue;
            }
            let (count, start) = (
                node.contents >> (32 - COUNT_BITS),
                node.contents & START_MASK,
            );
            if count > 0 {
                let start = start as usize;
                for corners in &self.corners[start..start + count as usize] {
                    let [a, b, c] = corners.map(|v| v - q);
                    sum += f64::from(solid_angle_f32(a, b, c));
                }
            } else if top + 2 <= stack.len() {
                stack[top] = start as usize;
                stack[top + 1] = start as usize + 1;
                top += 2;
            } else {
                // Deeper than any median-split tree gets: sum the node's
                // subtree by its dipole rather than overflow.
                sum += f64::from(node.area.dot(r) / (far * far.sqrt()).max(f32::MIN_POSITIVE));
            }
        }
        (sum / (4.0 * std::f64::consts::PI)) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::primitives::MeshGenerator;

    /// The fast winding number agrees with the sum over every triangle
    /// ([`solid_angle`] in double precision) to 0.05 (it is at most 0.025
    /// off here; a side is told by 0.5) around an ellipsoid
    /// with a cap of triangles cut away (a hole), inside and out, near and
    /// far: each leaf's corners are its own triangles', each node's dipole
    /// its subtree's.
    #[test]
    fn the_tree_agrees_with_the_sum_over_every_triangle() {
        let mesh = MeshGenerator::Ellipsoid {
            center: Vec3::ZERO,
            radii: Vec3::new(0.05, 0.02, 0.025),
            segments: 24,
            stacks: 16,
        }
        .build("bone")
        .unwrap();
        let positions = mesh.positions;
        // A hole: every triangle with a corner beyond x = 0.04 is gone.
        let triangles: Vec<[u32; 3]> = (mesh.triangles.into_iter())
            .filter(|t| t.iter().all(|&v| positions[v as usize].x < 0.04))
            .collect();
        let bvh = TriangleBvh::new(&positions, &triangles);
        let tree = WindingTree::new(&bvh, &positions, &triangles);
        assert_eq!(tree.corners.len(), triangles.len());
        let exact = |q: Vec3| {
            let sum: f64 = (triangles.iter())
                .map(|t| solid_angle_f64_at(t.map(|v| positions[v as usize]), q))
                .sum();
            (sum / (4.0 * std::f64::consts::PI)) as f32
        };
        let (mut inside, mut outside) = (0, 0);
        for i in 0..400 {
            let k = i as f32;
            let direction = Vec3::new((k * 12.99).sin(), (k * 78.23).sin(), (k * 37.72).sin());
            // From the centre out to three times the size.
            let q = direction * Vec3::new(0.05, 0.02, 0.025) * (0.2 + 0.0075 * (i % 400) as f32);
            let (fast, exact) = (tree.winding_number(q), exact(q));
            assert!((fast - exact).abs() < 0.05, "{q}: {fast} against {exact}");
            inside += usize::from(exact > 0.9);
            outside += usize::from(exact < 0.1);
        }
        assert!(
            inside > 50 && outside > 50,
            "{inside} inside, {outside} outside"
        );
    }

    fn solid_angle_f64_at(corners: [Vec3; 3], q: Vec3) -> f64 {
        let [a, b, c] = corners.map(|v| (v - q).as_dvec3());
        solid_angle(a, b, c)
    }
}
