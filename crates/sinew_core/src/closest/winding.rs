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
//! the same order, ×0.8–0.85 of the time per query in T7's walk. A side
//! ([`WindingTree::side`]) is first read from a coarser sum, about half
//! the work, and from the accurate one only where the coarse reads near ½.
//!
//! A leaf holds up to four triangles ([`super::bvh::LEAF_SIZE`]), and its
//! corners are kept coordinate by coordinate across them ([`CornerPack`]),
//! so that its four solid angles are taken at once, in four SIMD lanes,
//! with an arc tangent of the lanes' own ([`atan2_lanes`], a polynomial
//! within 6e-7 rad of the exact one): the arc tangents were half of a
//! winding number's time, each a call to libm in a chain of ninety.

use super::bvh::{LEAF_SIZE, NodeContents, TriangleBvh};
use super::corner_pack::CornerPack;
use glam::{DVec3, Vec3, Vec3A, Vec4};

/// Solid angle of triangle `abc` seen from the origin (the corners relative
/// to the point), signed: positive where the triangle's winding faces away
/// from the point (Van Oosterom and Strackee 1983).
pub(super) fn solid_angle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let numerator = a.dot(b.cross(c));
    let denominator = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    2.0 * numerator.atan2(denominator)
}

impl CornerPack {
    /// The sum of the pack's solid angles seen from `q` ([`solid_angle`],
    /// in single precision: the fast winding number only has to tell ½
    /// from 0 or 1).
    fn solid_angle_sum(&self, q: Vec3) -> f32 {
        let at = |corner: &[Vec4; 3]| {
            [
                corner[0] - Vec4::splat(q.x),
                corner[1] - Vec4::splat(q.y),
                corner[2] - Vec4::splat(q.z),
            ]
        };
        let (a, b, c) = (at(&self.a), at(&self.b), at(&self.c));
        let dot = |u: [Vec4; 3], v: [Vec4; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
        let cross = |u: [Vec4; 3], v: [Vec4; 3]| {
            [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ]
        };
        let (la, lb, lc) = (dot(a, a).sqrt(), dot(b, b).sqrt(), dot(c, c).sqrt());
        let numerator = dot(a, cross(b, c));
        let denominator = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
        2.0 * atan2_lanes(numerator, denominator).element_sum()
    }
}

/// `atan2(y, x)` in each lane, within 6e-7 rad (the polynomial's 3.3e-7
/// and the rounding of the turn to the octant): the arc tangent of the
/// smaller of `|x|, |y|` over the larger (in `[0, 1]`) by an odd
/// polynomial of degree 13 (fitted here to the least largest error), then
/// turned to the lane's octant. `atan2(0, 0)` is 0.
fn atan2_lanes(y: Vec4, x: Vec4) -> Vec4 {
    use std::f32::consts::{FRAC_PI_2, PI};
    /// `atan(t) ≈ t · Σ C[k] t^(2k)` on `[0, 1]`.
    const C: [f32; 7] = [
        0.999_996_1,
        -0.333_173_7,
        0.198_078_14,
        -0.132_333_37,
        0.079_623_58,
        -0.033_604_137,
        0.006_811_765,
    ];
    let (ax, ay) = (x.abs(), y.abs());
    let (small, large) = (ax.min(ay), ax.max(ay));
    let t = Vec4::select(large.cmpgt(Vec4::ZERO), small / large, Vec4::ZERO);
    let u = t * t;
    let poly = C[..6]
        .iter()
        .rev()
        .fold(Vec4::splat(C[6]), |p, &c| p * u + Vec4::splat(c));
    let r = t * poly;
    let r = Vec4::select(ay.cmpgt(ax), Vec4::splat(FRAC_PI_2) - r, r);
    let r = Vec4::select(x.cmplt(Vec4::ZERO), Vec4::splat(PI) - r, r);
    r.copysign(y)
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
    /// A leaf: its [`CornerPack`]'s index in [`WindingTree::packs`], and
    /// in the top [`COUNT_BITS`] bits how many triangles it has; an inner node:
    /// its left child (the right one follows it), the top bits 0.
    contents: u32,
}

/// Bits of [`Node::contents`] that count a leaf's triangles.
const COUNT_BITS: u32 = 3;

/// Bits of [`Node::contents`] below the count.
const START_MASK: u32 = u32::MAX >> COUNT_BITS;

/// The dipoles of a rigid target's BVH nodes and its triangles' corners
/// in leaf order, a pack per leaf (module docs).
#[derive(Clone, Debug, Default)]
pub(super) struct WindingTree {
    nodes: Vec<Node>,
    packs: Vec<CornerPack>,
}

/// A node is summed as one dipole when the point is farther from its
/// centre than this many times its radius: relative error of order
/// `1 / FAR²` on the node's share.
const FAR: f32 = 2.0;

/// [`FAR`] of [`WindingTree::side`]'s first, coarse sum: on T7's bones it
/// visits 68 nodes and 12 leaves a query where [`FAR`] visits 124 and 27,
/// and read within 0.10 of the accurate sum in 12 000 of the run's side
/// decisions (0.03 at the median).
const FAR_COARSE: f32 = 1.25;

/// How far from ½ the coarse sum must read for its side to stand (three
/// times the most it was seen off); nearer, the accurate sum decides. Of
/// T7's decisions 0.6 % came that near.
const COARSE_DECIDES: f32 = 0.3;

impl WindingTree {
    /// The dipoles of `bvh`'s nodes over `triangles` at `positions`, and
    /// the corners of its leaves' triangles.
    pub(super) fn new(bvh: &TriangleBvh, positions: &[Vec3], triangles: &[[u32; 3]]) -> Self {
        let mut nodes = vec![Node::default(); bvh.node_count()];
        let mut packs = Vec::with_capacity(triangles.len().div_ceil(LEAF_SIZE));
        // Children come after their parents: a reverse sweep sees them first.
        let mut weight = vec![0.0f32; nodes.len()];
        for i in (0..nodes.len()).rev() {
            let (min, max, contents) = bvh.node(i);
            let (mut centre, mut area, mut total) = (Vec3::ZERO, Vec3::ZERO, 0.0);
            let contents = match contents {
                NodeContents::Leaf(list) => {
                    let start = packs.len() as u32;
                    let corners: Vec<[Vec3; 3]> = (list.iter())
                        .map(|&t| triangles[t as usize].map(|v| positions[v as usize]))
                        .collect();
                    packs.push(CornerPack::new(&corners));
                    for &[a, b, c] in &corners {
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
                    debug_assert!(list.len() <= LEAF_SIZE && start <= START_MASK);
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
        Self { nodes, packs }
    }

    /// Winding number around local point `q` of the surface the tree was
    /// built over (module docs).
    pub(super) fn winding_number(&self, q: Vec3) -> f32 {
        self.winding_number_opened_at(q, FAR)
    }

    /// Which side of the surface local point `q` is on: `½ − w` in sign
    /// (positive outside), `w` its winding number. A side only needs to
    /// tell ½ from 0 or 1, and nearly every query is near 0 or 1 (on T7's
    /// scanned bones 97 % within 0.05), so a coarse sum ([`FAR_COARSE`],
    /// half the work) decides where it reads at least [`COARSE_DECIDES`]
    /// from ½, and the accurate one ([`Self::winding_number`]) elsewhere.
    /// Only the sign is meant: the magnitude is whichever sum decided.
    pub(super) fn side(&self, q: Vec3) -> f32 {
        let coarse = 0.5 - self.winding_number_opened_at(q, FAR_COARSE);
        if coarse.abs() >= COARSE_DECIDES {
            coarse
        } else {
            0.5 - self.winding_number(q)
        }
    }

    /// The winding number around `q`, a node summed as one dipole where
    /// `q` is farther than `opening` times its radius from its centre.
    fn winding_number_opened_at(&self, q: Vec3, opening: f32) -> f32 {
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
            if far > (opening * node.radius).powi(2) {
                sum += f64::from(node.area.dot(r) / (far * far.sqrt()));
                continue;
            }
            let (count, start) = (
                node.contents >> (32 - COUNT_BITS),
                node.contents & START_MASK,
            );
            if count > 0 {
                sum += f64::from(self.packs[start as usize].solid_angle_sum(q));
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

    /// The fast winding number agrees with the sum over every triangle
    /// ([`solid_angle`] in double precision) to 0.05 (it is at most 0.025
    /// off here; a side is told by 0.5) around an ellipsoid
    /// with a cap of triangles cut away (a hole), inside and out, near and
    /// far: each leaf's corners are its own triangles', each node's dipole
    /// its subtree's.
    #[test]
    fn the_tree_agrees_with_the_sum_over_every_triangle() {
        let (positions, triangles, tree) = holed_ellipsoid();
        let leaves = tree.nodes.iter().map(|n| n.contents >> (32 - COUNT_BITS));
        assert_eq!(leaves.sum::<u32>() as usize, triangles.len());
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

    /// The test ellipsoid with a cap of triangles cut away (every triangle
    /// with a corner beyond x = 0.04: a hole), and its tree.
    fn holed_ellipsoid() -> (Vec<Vec3>, Vec<[u32; 3]>, WindingTree) {
        let mesh = crate::closest::test_ellipsoid();
        let positions = mesh.positions;
        let triangles: Vec<[u32; 3]> = (mesh.triangles.into_iter())
            .filter(|t| t.iter().all(|&v| positions[v as usize].x < 0.04))
            .collect();
        let bvh = TriangleBvh::new(&positions, &triangles);
        let tree = WindingTree::new(&bvh, &positions, &triangles);
        (positions, triangles, tree)
    }

    /// The side from the coarse sum first has the accurate sum's sign
    /// everywhere around a holed ellipsoid, along lines through its hole
    /// (where the winding number passes ½) and around it, inside and out;
    /// both passes decide somewhere, and the coarse sum alone would read
    /// some point near ½ on the wrong side (so the threshold is what
    /// keeps the two agreeing).
    #[test]
    fn the_coarse_side_is_the_accurate_one() {
        let (_, _, tree) = holed_ellipsoid();
        let (mut coarse_decided, mut deferred, mut coarse_alone_wrong) = (0, 0, 0);
        for i in 0..4000 {
            let k = i as f32;
            let q = if i % 2 == 0 {
                // Lines through the hole, from the centre out past the cap.
                let across = Vec3::new(0.0, (k * 0.37).sin() * 0.012, (k * 0.61).cos() * 0.015);
                Vec3::new(0.1 * (i % 200) as f32 / 200.0, 0.0, 0.0) + across
            } else {
                let direction = Vec3::new((k * 12.99).sin(), (k * 78.23).sin(), (k * 37.72).sin());
                direction * Vec3::new(0.05, 0.02, 0.025) * (0.2 + 0.0009 * (i % 2000) as f32)
            };
            let accurate = 0.5 - tree.winding_number(q);
            let side = tree.side(q);
            assert_eq!(
                side.signum(),
                accurate.signum(),
                "{q}: side {side}, accurate {accurate}"
            );
            let coarse = 0.5 - tree.winding_number_opened_at(q, FAR_COARSE);
            match coarse.abs() >= COARSE_DECIDES {
                true => coarse_decided += 1,
                false => deferred += 1,
            }
            coarse_alone_wrong += usize::from(coarse.signum() != accurate.signum());
        }
        assert!(
            coarse_decided > 1000 && deferred > 10 && coarse_alone_wrong > 0,
            "{coarse_decided} decided coarsely, {deferred} deferred, {coarse_alone_wrong} read wrong alone"
        );
    }

    /// The lanes' arc tangent is within 6e-7 rad of the exact one in every
    /// octant, on the axes, at 0 and for a zero of either sign; one wrong
    /// coefficient, octant or sign breaks it.
    #[test]
    fn the_lanes_arc_tangent_is_the_exact_one() {
        let mut worst = 0.0f64;
        let mut check = |y: f32, x: f32| {
            let lanes = atan2_lanes(Vec4::splat(y), Vec4::splat(x)).x;
            let exact = f64::from(y).atan2(f64::from(x));
            let exact = if x == 0.0 && y == 0.0 { 0.0 } else { exact };
            let error = (f64::from(lanes) - exact).abs();
            assert!(error < 6e-7, "atan2({y}, {x}): {lanes} against {exact}");
            worst = worst.max(error);
        };
        for i in 0..20_000 {
            let angle = i as f32 * (std::f32::consts::TAU / 20_000.0) - std::f32::consts::PI;
            let radius = 1e-3 + (i % 17) as f32;
            check(radius * angle.sin(), radius * angle.cos());
        }
        for (y, x) in [
            (0.0, 1.0),
            (1.0, 0.0),
            (0.0, -1.0),
            (-1.0, 0.0),
            (0.0, 0.0),
            (-0.0, 1.0),
            (1.0, 1.0),
            (-2.0, -2.0),
        ] {
            check(y, x);
        }
        assert!(worst > 1e-8, "the polynomial is not exact: {worst}");
    }

    /// A pack's solid angles are the double-precision ones, summed, for
    /// one to four triangles, seen from points around them, near and far:
    /// its padding lanes add nothing.
    #[test]
    fn a_pack_sums_its_triangles_solid_angles() {
        let corner = |k: f32| Vec3::new((k * 1.7).sin(), (k * 2.3).cos(), (k * 0.9).sin()) * 0.03;
        for n in 1..=LEAF_SIZE {
            let triangles: Vec<[Vec3; 3]> = (0..n)
                .map(|t| std::array::from_fn(|c| corner((3 * t + c) as f32)))
                .collect();
            let pack = CornerPack::new(&triangles);
            for i in 0..200 {
                let q = corner(100.0 + i as f32) * (0.1 + 0.05 * i as f32);
                let exact: f64 = triangles.iter().map(|&t| solid_angle_f64_at(t, q)).sum();
                let lanes = f64::from(pack.solid_angle_sum(q));
                assert!(
                    (lanes - exact).abs() < 1e-5,
                    "{n} triangles at {q}: {lanes} against {exact}"
                );
            }
        }
    }

    fn solid_angle_f64_at(corners: [Vec3; 3], q: Vec3) -> f64 {
        let [a, b, c] = corners.map(|v| (v - q).as_dvec3());
        solid_angle(a, b, c)
    }
}
