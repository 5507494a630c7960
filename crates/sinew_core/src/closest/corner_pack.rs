//! A BVH leaf's triangles side by side in SIMD lanes ([`CornerPack`]): the
//! winding number takes their four solid angles at once (the `winding`
//! module), and a rigid target's full closest-point search their four
//! distances ([`LeafPacks`]).
//!
//! A bone never changes in its own frame, so its leaves are packed once,
//! when the target is built. The full search then reads one leaf's corners
//! from one place (144 bytes, in leaf order) instead of four triangles'
//! indices and twelve scattered positions, and tests its triangles in one
//! pass of four lanes. Each lane computes the distance with the operations
//! of [`super::closest_point_triangle`], in its order, so the search finds
//! the triangle the scalar one found, at the same squared distance to the
//! bit.

use super::bvh::{LEAF_SIZE, NodeContents, TriangleBvh};
use glam::{Vec3, Vec4};

// A leaf's triangles fit one pack's four lanes.
const _: () = assert!(LEAF_SIZE <= 4);

/// The corners of up to four triangles (a leaf's), coordinate by
/// coordinate: lane `k` of `a[0]` is the `x` of triangle `k`'s first
/// corner. A leaf of fewer fills its other lanes with a point triangle
/// (its first triangle's first corner): its solid angle is 0 from
/// anywhere, and its distance is never read.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct CornerPack {
    pub(super) a: [Vec4; 3],
    pub(super) b: [Vec4; 3],
    pub(super) c: [Vec4; 3],
}

impl CornerPack {
    /// The pack of `triangles` (at most four), given by their corners.
    pub(super) fn new(triangles: &[[Vec3; 3]]) -> Self {
        debug_assert!(!triangles.is_empty() && triangles.len() <= LEAF_SIZE);
        let point = [triangles[0][0]; 3];
        let lane = |k: usize| triangles.get(k).copied().unwrap_or(point);
        let axis = |corner: usize, axis: usize| {
            Vec4::from_array(std::array::from_fn(|k| lane(k)[corner][axis]))
        };
        Self {
            a: std::array::from_fn(|i| axis(0, i)),
            b: std::array::from_fn(|i| axis(1, i)),
            c: std::array::from_fn(|i| axis(2, i)),
        }
    }

    /// The squared distance from `p` to each lane's triangle: lane by lane
    /// the squared distance from `p` to the point
    /// [`super::closest_point_triangle`] returns, to the bit. Every region's
    /// point is computed in every lane (a lane's other regions may hold
    /// infinities or NaN from a degenerate triangle's divisions) and each
    /// lane keeps the one the scalar test's first true condition returns,
    /// the conditions the same comparisons (false on NaN).
    pub(super) fn squared_distances(&self, p: Vec3) -> Vec4 {
        type V3 = [Vec4; 3];
        let sub = |u: V3, v: V3| [u[0] - v[0], u[1] - v[1], u[2] - v[2]];
        let add = |u: V3, v: V3| [u[0] + v[0], u[1] + v[1], u[2] + v[2]];
        let scale = |u: V3, s: Vec4| [u[0] * s, u[1] * s, u[2] * s];
        // `Vec3::dot`'s order: (x·x + y·y) + z·z.
        let dot = |u: V3, v: V3| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
        let select =
            |m: glam::BVec4A, u: V3, v: V3| std::array::from_fn(|i| Vec4::select(m, u[i], v[i]));
        let zero = Vec4::ZERO;
        let p: V3 = [Vec4::splat(p.x), Vec4::splat(p.y), Vec4::splat(p.z)];
        let (a, b, c) = (self.a, self.b, self.c);
        let ab = sub(b, a);
        let ac = sub(c, a);
        let ap = sub(p, a);
        let (d1, d2) = (dot(ab, ap), dot(ac, ap));
        let bp = sub(p, b);
        let (d3, d4) = (dot(ab, bp), dot(ac, bp));
        let vc = d1 * d4 - d3 * d2;
        let cp = sub(p, c);
        let (d5, d6) = (dot(ab, cp), dot(ac, cp));
        let vb = d5 * d2 - d1 * d6;
        let va = d3 * d6 - d5 * d4;
        // The scalar test's regions, in the order it tries them.
        let at_a = d1.cmple(zero) & d2.cmple(zero);
        let at_b = d3.cmpge(zero) & d4.cmple(d3);
        let on_ab = vc.cmple(zero) & d1.cmpge(zero) & d3.cmple(zero);
        let at_c = d6.cmpge(zero) & d5.cmple(d6);
        let on_ac = vb.cmple(zero) & d2.cmpge(zero) & d6.cmple(zero);
        let (b4, c5) = (d4 - d3, d5 - d6);
        let on_bc = va.cmple(zero) & b4.cmpge(zero) & c5.cmpge(zero);
        // The interior, then each region over it from the last tried to
        // the first (the first true one stays).
        let denom = Vec4::ONE / (va + vb + vc);
        let (v, w) = (vb * denom, vc * denom);
        let mut point = add(add(a, scale(ab, v)), scale(ac, w));
        let bc_w = b4 / (b4 + c5);
        point = select(on_bc, add(b, scale(sub(c, b), bc_w)), point);
        let ac_w = d2 / (d2 - d6);
        point = select(on_ac, add(a, scale(ac, ac_w)), point);
        point = select(at_c, c, point);
        let ab_v = d1 / (d1 - d3);
        point = select(on_ab, add(a, scale(ab, ab_v)), point);
        point = select(at_b, b, point);
        point = select(at_a, a, point);
        let offset = sub(point, p);
        dot(offset, offset)
    }
}

/// A rigid target's BVH leaves as [`CornerPack`]s, for its full
/// closest-point search (module docs); empty for a deforming target, whose
/// corners move with every publish.
#[derive(Clone, Debug, Default)]
pub(super) struct LeafPacks {
    /// Per BVH node, its leaf's index in `packs` (`u32::MAX`: an inner
    /// node).
    pack_of: Vec<u32>,
    packs: Vec<CornerPack>,
}

impl LeafPacks {
    /// The packs of `bvh`'s leaves over `triangles` at `positions`.
    pub(super) fn new(bvh: &TriangleBvh, positions: &[Vec3], triangles: &[[u32; 3]]) -> Self {
        let mut packs = Vec::with_capacity(triangles.len().div_ceil(LEAF_SIZE));
        let pack_of = (0..bvh.node_count())
            .map(|i| match bvh.node(i).2 {
                NodeContents::Leaf(list) => {
                    let corners: Vec<[Vec3; 3]> = (list.iter())
                        .map(|&t| triangles[t as usize].map(|v| positions[v as usize]))
                        .collect();
                    packs.push(CornerPack::new(&corners));
                    packs.len() as u32 - 1
                }
                NodeContents::Inner(_) => u32::MAX,
            })
            .collect();
        Self { pack_of, packs }
    }

    /// Whether there are no packs (a deforming target, or no triangles).
    pub(super) fn is_empty(&self) -> bool {
        self.packs.is_empty()
    }

    /// The squared distances from local `q` to the triangles of leaf node
    /// `node`, lane `k` its `k`-th ([`CornerPack::squared_distances`]).
    #[inline]
    pub(super) fn squared_distances(&self, node: usize, q: Vec3) -> [f32; 4] {
        self.packs[self.pack_of[node] as usize]
            .squared_distances(q)
            .to_array()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::closest::closest_point_triangle;

    /// A small deterministic generator of coordinates in `[-1, 1)`.
    fn coordinates(seed: u64) -> impl FnMut() -> f32 {
        let mut state = seed;
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 23) as f32 - 1.0
        }
    }

    /// Each lane's squared distance is the scalar test's to the bit, over
    /// points in every region of ordinary triangles and of degenerate ones
    /// (a point, a segment, two corners equal, a needle), whose divisions
    /// give infinities and NaN in the regions a lane does not keep. Seen to
    /// fail with the dot products summed as `x + (y + z)`, and with the
    /// interior's point summed as `a + (ab·v + ac·w)`.
    #[test]
    fn each_lane_is_the_scalar_distance_to_the_bit() {
        let mut r = coordinates(7);
        let mut v = || Vec3::new(r(), r(), r());
        let mut triangles: Vec<[Vec3; 3]> = (0..400).map(|_| [v(), v(), v()]).collect();
        let (a, b) = (Vec3::new(0.1, 0.2, 0.3), Vec3::new(-0.4, 0.5, 0.05));
        triangles.extend([
            [a, a, a],
            [a, b, a],
            [a, a, b],
            [b, a, a],
            [a, b, a + (b - a) * 0.5],
            [a, b, a + Vec3::splat(1e-7)],
        ]);
        let mut checked = 0;
        for chunk in triangles.chunks(4) {
            let pack = CornerPack::new(chunk);
            for _ in 0..64 {
                let p = v() * 1.5;
                let lanes = pack.squared_distances(p).to_array();
                for (k, &[a, b, c]) in chunk.iter().enumerate() {
                    let (point, _) = closest_point_triangle(p, a, b, c);
                    let want = point.distance_squared(p);
                    let same =
                        lanes[k].to_bits() == want.to_bits() || lanes[k].is_nan() && want.is_nan();
                    assert!(same, "lane {k} of {chunk:?} at {p}: {} {want}", lanes[k]);
                    checked += 1;
                }
            }
        }
        assert!(checked > 6000);
    }
}
