//! Target surfaces (bones, planes, other muscles) and closest data (SPEC §6).
//!
//! A [`TargetSurface`] stores its triangles in a *local* frame with a parry3d
//! [`Bvh`] over them. Rigid targets (bones, planes) never refit: a query point
//! is moved into the bone's frame instead. Muscle targets are deforming: their
//! published snapshot rewrites the local positions and refits the tree once per
//! global iteration.
//!
//! Queries are warm-started: the distance to the triangle found last iteration
//! bounds a best-first BVH search ([`Bvh::find_best`]), so a vertex that barely
//! moved visits only a handful of nodes.

use glam::{Affine3A, Mat3A, Vec3, Vec3A};
use parry3d::bounding_volume::Aabb;
use parry3d::partitioning::{Bvh, BvhBuildStrategy};

/// What a target is attached to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetSource {
    /// A kinematic bone (index into the solver's bones); rigid.
    Bone(usize),
    /// A simulated muscle (index into the solver's muscles); deforming.
    Muscle(usize),
}

/// The closest point of a target to a query point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestHit {
    /// Closest point, world.
    pub point: Vec3,
    /// Interpolated outward unit normal at the point, world.
    pub normal: Vec3,
    /// Barycentric coordinates in the triangle.
    pub barycentric: Vec3,
    /// Triangle index.
    pub triangle: u32,
    /// Euclidean distance to the query point.
    pub distance: f32,
    /// `normal · (query − point)`: negative inside the target.
    pub signed_distance: f32,
}

impl ClosestHit {
    /// Whether the query point lies inside (behind) the surface.
    pub fn is_inside(&self) -> bool {
        self.signed_distance < 0.0
    }
}

/// Tangent frame `[t̂ b̂ n̂]` at a point of a triangle (SPEC §5.9).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceFrame {
    /// Point on the surface.
    pub origin: Vec3,
    /// Columns: tangent, binormal, normal.
    pub basis: Mat3A,
}

/// Triangle geometry of one target, with a BVH.
#[derive(Clone)]
pub struct TargetSurface {
    /// Name (bone or muscle).
    pub name: String,
    /// Where the target comes from.
    pub source: TargetSource,
    /// Vertex positions in the target's local frame (world for muscles).
    pub positions: Vec<Vec3>,
    /// Area-weighted vertex normals, local frame.
    pub normals: Vec<Vec3>,
    /// Triangles.
    pub triangles: Vec<[u32; 3]>,
    /// World from local (identity for muscles).
    pub transform: Affine3A,
    inverse: Affine3A,
    bvh: Bvh,
}

impl std::fmt::Debug for TargetSurface {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TargetSurface")
            .field("name", &self.name)
            .field("source", &self.source)
            .field("vertices", &self.positions.len())
            .field("triangles", &self.triangles.len())
            .finish()
    }
}

fn triangle_aabb(p: &[Vec3], t: [u32; 3]) -> Aabb {
    let (a, b, c) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
    Aabb::new(a.min(b).min(c), a.max(b).max(c))
}

impl TargetSurface {
    /// Creates a target from local-frame geometry.
    pub fn new(
        name: impl Into<String>,
        source: TargetSource,
        positions: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
    ) -> Self {
        let leaves: Vec<Aabb> = triangles
            .iter()
            .map(|&t| triangle_aabb(&positions, t))
            .collect();
        let bvh = Bvh::from_leaves(BvhBuildStrategy::Binned, &leaves);
        let mut normals = Vec::new();
        crate::mesh::vertex_normals(&triangles, &positions, &mut normals);
        Self {
            name: name.into(),
            source,
            positions,
            normals,
            triangles,
            transform: Affine3A::IDENTITY,
            inverse: Affine3A::IDENTITY,
            bvh,
        }
    }

    /// Sets the world transform of a rigid target.
    pub fn set_transform(&mut self, transform: Affine3A) {
        self.transform = transform;
        self.inverse = transform.inverse();
    }

    /// Replaces the positions of a deforming target (same topology): recomputes
    /// normals and refits the BVH. This is the per-iteration snapshot publish.
    pub fn publish(&mut self, positions: &[Vec3]) {
        self.positions.clear();
        self.positions.extend_from_slice(positions);
        crate::mesh::vertex_normals(&self.triangles, &self.positions, &mut self.normals);
        for (i, &t) in self.triangles.iter().enumerate() {
            self.bvh
                .update_partially_if_present(triangle_aabb(&self.positions, t), i as u32, 0.0);
        }
        self.bvh.refit_without_opt();
    }

    /// World position of local vertex `i`.
    #[inline]
    pub fn world_vertex(&self, i: u32) -> Vec3 {
        self.transform.transform_point3(self.positions[i as usize])
    }

    /// Closest point on triangle `t` to a local-frame point: `(point, barycentric)`.
    #[inline]
    fn closest_on_triangle(&self, t: u32, q: Vec3) -> (Vec3, Vec3) {
        let [a, b, c] = self.triangles[t as usize];
        closest_point_triangle(
            q,
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        )
    }

    /// Closest point to `query` (world). `warm` is last iteration's triangle.
    pub fn closest(&self, query: Vec3, warm: Option<u32>) -> Option<ClosestHit> {
        self.closest_within(query, warm, f32::MAX)
    }

    /// Closest point to `query` no farther than `max_distance` (world units;
    /// rigid transforms keep distances), or `None`. A tight bound prunes most
    /// of the tree: a muscle choosing its closest target passes the best
    /// distance found so far on the other targets.
    pub fn closest_within(
        &self,
        query: Vec3,
        warm: Option<u32>,
        max_distance: f32,
    ) -> Option<ClosestHit> {
        let q = self.inverse.transform_point3(query);
        let mut best: Option<(f32, u32, Vec3, Vec3)> = None;
        let mut bound = if max_distance < f32::MAX {
            max_distance * max_distance
        } else {
            f32::MAX
        };
        if let Some(t) = warm.filter(|&t| (t as usize) < self.triangles.len()) {
            let (c, bary) = self.closest_on_triangle(t, q);
            let d2 = c.distance_squared(q);
            if d2 <= bound {
                best = Some((d2, t, c, bary));
                // A slightly larger bound keeps the warm triangle on ties.
                bound = d2 * (1.0 + 1e-5) + 1e-20;
            }
        }
        let qa = Vec3A::from(q);
        let found = self.bvh.find_best(
            bound,
            |node, _| {
                let mins = Vec3A::from(node.mins());
                let maxs = Vec3A::from(node.maxs());
                let d = (mins - qa).max(qa - maxs).max(Vec3A::ZERO);
                d.length_squared()
            },
            |leaf, _| {
                let (c, bary) = self.closest_on_triangle(leaf, q);
                Some((c.distance_squared(q), (c, bary)))
            },
        );
        if let Some((leaf, (d2, (c, bary)))) = found
            && best.is_none_or(|b| d2 < b.0)
        {
            best = Some((d2, leaf, c, bary));
        }
        let (d2, triangle, c, bary) = best?;
        let [a, b, cc] = self.triangles[triangle as usize];
        let local_n = (self.normals[a as usize] * bary.x
            + self.normals[b as usize] * bary.y
            + self.normals[cc as usize] * bary.z)
            .try_normalize()
            .unwrap_or(Vec3::Y);
        let normal = self
            .transform
            .transform_vector3(local_n)
            .normalize_or(Vec3::Y);
        let point = self.transform.transform_point3(c);
        Some(ClosestHit {
            point,
            normal,
            barycentric: bary,
            triangle,
            distance: d2.sqrt(),
            signed_distance: normal.dot(query - point),
        })
    }

    /// World point at barycentric `bary` of triangle `t`.
    #[inline]
    pub fn point_at(&self, t: u32, bary: Vec3) -> Vec3 {
        let [a, b, c] = self.triangles[t as usize];
        let local = self.positions[a as usize] * bary.x
            + self.positions[b as usize] * bary.y
            + self.positions[c as usize] * bary.z;
        self.transform.transform_point3(local)
    }

    /// Tangent frame at barycentric `bary` of triangle `t` (SPEC §5.9): normal
    /// interpolated from vertex normals, tangent along the first edge.
    pub fn frame_at(&self, t: u32, bary: Vec3) -> SurfaceFrame {
        let [a, b, c] = self.triangles[t as usize];
        let (pa, pb) = (self.positions[a as usize], self.positions[b as usize]);
        let n = (self.normals[a as usize] * bary.x
            + self.normals[b as usize] * bary.y
            + self.normals[c as usize] * bary.z)
            .try_normalize()
            .unwrap_or(Vec3::Y);
        let e = pb - pa;
        let t_hat = (e - e.dot(n) * n)
            .try_normalize()
            .unwrap_or_else(|| n.any_orthonormal_vector());
        let b_hat = n.cross(t_hat);
        let local = Mat3A::from_cols(t_hat.into(), b_hat.into(), n.into());
        let origin = self.point_at(t, bary);
        SurfaceFrame {
            origin,
            basis: self.transform.matrix3 * local,
        }
    }
}

/// Closest point on triangle `abc` to `p` and its barycentric coordinates
/// (Ericson, *Real-Time Collision Detection*, §5.1.5).
pub fn closest_point_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> (Vec3, Vec3) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Vec3::X);
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Vec3::Y);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + v * ab, Vec3::new(1.0 - v, v, 0.0));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Vec3::Z);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + w * ac, Vec3::new(1.0 - w, 0.0, w));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + w * (c - b), Vec3::new(0.0, 1.0 - w, w));
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    (a + ab * v + ac * w, Vec3::new(1.0 - v - w, v, w))
}
