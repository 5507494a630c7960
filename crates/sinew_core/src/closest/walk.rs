//! The local search over a target's surface ([`TargetSurface::walk`], see
//! the module docs of [`crate::closest`]): from a triangle to its
//! neighbours around the closest feature while that brings the point closer.

use super::{ClosestHit, TargetSurface, csr_row};
use glam::Vec3;

impl TargetSurface {
    /// Most steps [`TargetSurface::walk`] takes before giving up.
    pub const MAX_WALK_STEPS: usize = 16;

    /// Local search from triangle `start` (see the module docs): the closest
    /// point of the local minimum reached, or `None` when `start` is out of
    /// range or the walk needed more than [`TargetSurface::MAX_WALK_STEPS`]
    /// steps (the caller then runs the full search).
    pub fn walk(&self, query: Vec3, start: u32) -> Option<ClosestHit> {
        if start as usize >= self.geometry.triangles.len() {
            return None;
        }
        let q = self.to_local(query);
        let mut t = start;
        let (mut c, mut bary) = self.closest_on_triangle(t, q);
        let mut d2 = c.distance_squared(q);
        for _ in 0..Self::MAX_WALK_STEPS {
            let tri = self.geometry.triangles[t as usize];
            let next = match (bary.x > 0.0, bary.y > 0.0, bary.z > 0.0) {
                // Inside the triangle: no neighbour of a smooth surface is closer.
                (true, true, true) => None,
                // On an edge: only the triangle across it can be closer.
                (true, true, false) => self.across(t, 0, q, d2),
                (false, true, true) => self.across(t, 1, q, d2),
                (true, false, true) => self.across(t, 2, q, d2),
                // On a vertex: it is the closest point of every triangle around
                // it unless the query leans along one of its edges (Ericson's
                // vertex-region test), so most calls end here without a
                // triangle test.
                (true, false, false) => self.around(t, tri[0], q, d2),
                (false, true, false) => self.around(t, tri[1], q, d2),
                _ => self.around(t, tri[2], q, d2),
            };
            match next {
                Some((dn, n, cn, bn)) => (d2, t, c, bary) = (dn, n, cn, bn),
                None => return Some(self.hit(query, d2, t, c, bary)),
            }
        }
        None
    }

    /// The triangle across edge `k` of `t`, if its closest point is strictly
    /// closer than `d2`.
    fn across(&self, t: u32, k: usize, q: Vec3, d2: f32) -> Option<(f32, u32, Vec3, Vec3)> {
        let n = self.geometry.across_edge[t as usize][k];
        if n == u32::MAX {
            return None;
        }
        let (c, bary) = self.closest_on_triangle(n, q);
        let dn = c.distance_squared(q);
        (dn < d2 * (1.0 - 1e-6)).then_some((dn, n, c, bary))
    }

    /// The closest of the triangles around vertex `v` (other than `t`), if it
    /// is strictly closer than `d2`. The vertex is the closest point of every
    /// triangle around it unless the query leans along one of its edges
    /// (Ericson's vertex-region test), so most calls test no triangle; else
    /// the two triangles of the edge it leans along most are tested.
    fn around(&self, t: u32, v: u32, q: Vec3, d2: f32) -> Option<(f32, u32, Vec3, Vec3)> {
        let pv = self.geometry.positions[v as usize];
        let r = q - pv;
        let neighbors = csr_row(&self.geometry.neighbor_offsets, &self.geometry.neighbors, v);
        // Follow the edge the query leans along most (largest cosine): the
        // closest point moves onto it or into one of its two triangles.
        let mut lean: Option<(f32, u32)> = None;
        for &u in neighbors {
            let e = self.geometry.positions[u as usize] - pv;
            let along = r.dot(e);
            if along <= 0.0 {
                continue;
            }
            let cosine = along * along / e.length_squared();
            if lean.is_none_or(|(c, _)| cosine > c) {
                lean = Some((cosine, u));
            }
        }
        let (_, u) = lean?;
        let mut next: Option<(f32, u32, Vec3, Vec3)> = None;
        for &n in self.triangles_around(v) {
            if n == t || !self.geometry.triangles[n as usize].contains(&u) {
                continue;
            }
            let (c, bary) = self.closest_on_triangle(n, q);
            let dn = c.distance_squared(q);
            if dn < d2 * (1.0 - 1e-6) && next.is_none_or(|b| dn < b.0) {
                next = Some((dn, n, c, bary));
            }
        }
        next
    }

    /// Builds the world-space hit for a local closest point. The normal is
    /// interpolated from the corners' normals and normalised once, after
    /// the transform (the same direction as normalising before it as well,
    /// for a rotation with or without a uniform scale; a second
    /// normalisation was a square root and a division on the path of every
    /// bone hit: T7's closest data ×0.94 without it).
    #[inline]
    pub(super) fn hit(
        &self,
        query: Vec3,
        d2: f32,
        triangle: u32,
        c: Vec3,
        bary: Vec3,
    ) -> ClosestHit {
        let [a, b, cc] = self.geometry.triangles[triangle as usize];
        let sum = self.geometry.normals[a as usize] * bary.x
            + self.geometry.normals[b as usize] * bary.y
            + self.geometry.normals[cc as usize] * bary.z;
        let (normal, point) = if self.identity {
            (sum.try_normalize().unwrap_or(Vec3::Y), c)
        } else {
            let length_squared = sum.length_squared();
            let local = if length_squared > 0.0 && length_squared.is_finite() {
                sum
            } else {
                Vec3::Y
            };
            (
                self.transform
                    .transform_vector3(local)
                    .normalize_or(Vec3::Y),
                self.transform.transform_point3(c),
            )
        };
        ClosestHit {
            point: point.into(),
            normal: normal.into(),
            barycentric: bary.into(),
            triangle,
            distance: d2.sqrt(),
            signed_distance: normal.dot(query - point),
        }
    }

    /// The closest point to `query` (world) on the feature of triangle `t`
    /// that barycentric `bary` lies on: its plane (unit normal `plane`) for
    /// an interior point, the segment of an edge, or a corner. It is the
    /// closest point of the triangle while the query stays in that feature's
    /// region, for a few loads instead of a triangle test: what later
    /// iterations of a frame ask for, the vertex having moved a little.
    pub fn on_feature(&self, query: Vec3, t: u32, bary: Vec3, plane: Vec3) -> Vec3 {
        let [a, b, c] = self.geometry.triangles[t as usize];
        match (bary.x > 0.0, bary.y > 0.0, bary.z > 0.0) {
            (true, true, true) => {
                let on = self.point_at(t, bary);
                query - plane * plane.dot(query - on)
            }
            (true, true, false) => self.on_segment(query, a, b),
            (false, true, true) => self.on_segment(query, b, c),
            (true, false, true) => self.on_segment(query, c, a),
            (true, false, false) => self.world_vertex(a),
            (false, true, false) => self.world_vertex(b),
            _ => self.world_vertex(c),
        }
    }

    /// The closest point to `query` (world) on the edge from vertex `a` to `b`.
    fn on_segment(&self, query: Vec3, a: u32, b: u32) -> Vec3 {
        let (pa, pb) = (self.world_vertex(a), self.world_vertex(b));
        let edge = pb - pa;
        let along = (query - pa).dot(edge) / edge.length_squared().max(f32::MIN_POSITIVE);
        pa + edge * along.clamp(0.0, 1.0)
    }
}
