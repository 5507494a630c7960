//! Target surfaces (bones, planes, other muscles) and closest data (SPEC §6).
//!
//! A [`TargetSurface`] stores its triangles in a *local* frame with a
//! [`TriangleBvh`] over them. Rigid targets (bones, planes) never refit: a
//! query point is moved into the bone's frame instead. Muscle targets are
//! deforming: their published snapshot rewrites the local positions.
//!
//! Two queries answer "closest point":
//!
//! - [`TargetSurface::closest_within`], the full search: a nearest-first BVH
//!   descent ([`TriangleBvh::closest`]) bounded by the distance to last
//!   iteration's triangle. Exact, ≈ 0.5–1 µs when the query is centimetres
//!   away; on a bone ≈ 0.3–0.5 µs with its data in cache, its leaves'
//!   triangles tested four at a time in SIMD lanes (`corner_pack`), the
//!   same triangle and distance to the bit.
//! - [`TargetSurface::walk`], the local search: from last iteration's
//!   triangle, step to a neighbouring triangle around the closest feature
//!   (edge or vertex) while that brings the point strictly closer. It stops
//!   where the closest point is inside a triangle or on a feature no neighbour
//!   improves — a local minimum of the distance over the surface, which is
//!   what sliding means: the contact point travels continuously over the
//!   target instead of jumping across it. Typically one or two triangle tests.
//!
//! The solver walks in the first iteration of every substep and every
//! [`crate::solver::SolverSettings::walk_interval`]-th after it (every
//! iteration by default), re-projects onto the triangle found in the
//! others ([`TargetSurface::on_triangle`], or onto its feature), and runs
//! the full search for each vertex once every
//! [`crate::solver::SolverSettings::full_search_interval`] frames
//! (staggered over vertices), so a closer region found elsewhere on a
//! target is picked up within a few frames. A vertex re-chooses which of its
//! muscle's targets it slides on once every
//! [`crate::solver::SolverSettings::choose_interval`] frames (staggered too,
//! and at every full search), walking on each target whose bounding box is
//! nearer than the best distance so far.
//!
//! A deforming target's BVH is refitted lazily. [`TargetSurface::publish`]
//! records how far any vertex has moved since the boxes were fitted (the
//! slack); the full search grows every box by it, so it stays exact, and
//! [`TargetSurface::refit`] refits only once the slack exceeds a quarter of
//! the mean edge length.

use crate::constraints::TargetId;
use crate::prefetch::prefetch;
use glam::{Affine3A, Mat3A, Vec3, Vec3A};
use std::sync::Arc;

mod bvh;
mod corner_pack;
mod faces;
mod side;
mod snapshot;
mod walk;
mod winding;

pub use bvh::TriangleBvh;
pub use side::SideMemo;

/// What a target is attached to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetSource {
    /// A kinematic bone (index into the solver's bones); rigid.
    Bone(usize),
    /// A simulated muscle (index into the solver's muscles); deforming.
    Muscle(usize),
}

/// A triangle index that names no triangle (no search has run yet).
pub const NO_TRIANGLE: u32 = u32::MAX;

/// The closest point of a target to a query point.
///
/// Its vectors are [`Vec3A`]s, each written and read whole in one 16-byte
/// move: a hit is returned through memory and copied a few times in closest
/// data's loop, and with `Vec3`s (written as 8 + 4 bytes) each 16-byte read
/// that spanned two writes waited for them to reach the cache (T7's closest
/// data ×0.93 with `Vec3A`, the same bits).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestHit {
    /// Closest point, world.
    pub point: Vec3A,
    /// Outward unit normal at the point, world, interpolated from the vertex
    /// normals ([`TargetSurface::settle_side`] turns it to the direction
    /// from the point to the query where that reads the wrong side of a
    /// bone).
    pub normal: Vec3A,
    /// Barycentric coordinates in the triangle.
    pub barycentric: Vec3A,
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

/// Where a muscle's `target_ids` are looked up: the solver's table of every
/// target, or a driver's slice of references in the muscle's own order.
pub trait TargetSet {
    /// The target `id`.
    fn target(&self, id: TargetId) -> &TargetSurface;
}

impl TargetSet for [TargetSurface] {
    fn target(&self, id: TargetId) -> &TargetSurface {
        &self[id.index()]
    }
}

impl TargetSet for [&TargetSurface] {
    fn target(&self, id: TargetId) -> &TargetSurface {
        self[id.index()]
    }
}

/// Triangle geometry of one target, with a BVH.
///
/// Cloning a target is cheap: its geometry (positions, normals, triangles,
/// BVH, adjacency and side data) is shared behind an [`Arc`] and copied
/// only when a clone of a deforming target publishes new positions (copy
/// on write). The solver gives every bone whose mesh is the same, in its
/// local frame, the one geometry (a crowd's copies of a body,
/// [`crate::scene::Scene::crowd`]).
#[derive(Clone)]
pub struct TargetSurface {
    /// Name (bone or muscle).
    pub name: String,
    /// Where the target comes from.
    pub source: TargetSource,
    /// World from local (identity for muscles).
    pub transform: Affine3A,
    inverse: Affine3A,
    /// `transform` is the identity (muscle targets): skip the transforms.
    identity: bool,
    /// The positions, normals, triangles, BVH and adjacency, shared with
    /// every target of the same geometry.
    geometry: Arc<SurfaceGeometry>,
    /// How far any vertex has moved since the BVH was fitted: every box,
    /// grown by this, still bounds its triangle.
    slack: f32,
    /// Per vertex of a deforming target, its particle's inverse mass (see
    /// [`TargetSurface::point_inverse_mass`]); empty for rigid targets.
    inverse_mass: Vec<f32>,
}

/// What targets of one mesh share: everything a closest-point query reads
/// but the frame, the slack and a muscle's inverse masses. A rigid target's never changes after it is
/// built; a deforming target's positions, normals and BVH fit change as its
/// muscle publishes them.
#[derive(Clone)]
struct SurfaceGeometry {
    /// Vertex positions in the target's local frame (world for muscles).
    positions: Vec<Vec3>,
    /// Area-weighted vertex normals, local frame.
    normals: Vec<Vec3>,
    /// Triangles.
    triangles: Vec<[u32; 3]>,
    bvh: TriangleBvh,
    /// A bone's BVH leaves with their triangles' corners in SIMD lanes, for
    /// its full search; empty for a deforming target.
    leaf_packs: corner_pack::LeafPacks,
    /// Positions the BVH's boxes were fitted to.
    fitted: Vec<Vec3>,
    /// [`TargetSurface::refit`] refits once the slack exceeds this (a
    /// quarter of the mean edge length).
    max_slack: f32,
    /// CSR offsets of the triangles around each vertex.
    vertex_triangle_offsets: Vec<u32>,
    /// CSR entries of the triangles around each vertex.
    vertex_triangles: Vec<u32>,
    /// Per triangle, the triangle across edge `(t[k], t[k+1])`, or `u32::MAX`.
    across_edge: Vec<[u32; 3]>,
    /// CSR offsets of each vertex's neighbours.
    neighbor_offsets: Vec<u32>,
    /// CSR entries of each vertex's neighbours.
    neighbors: Vec<u32>,
    /// A bone's face kinds and pseudo-normals, which say which side of it
    /// a hit is on; empty for a deforming target.
    /// (Boxed: the closest-point queries read the fields above, and keep
    /// them together.)
    pseudo_normals: Box<side::PseudoNormals>,
}

impl std::fmt::Debug for TargetSurface {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TargetSurface")
            .field("name", &self.name)
            .field("source", &self.source)
            .field("vertices", &self.geometry.positions.len())
            .field("triangles", &self.geometry.triangles.len())
            .finish()
    }
}

impl TargetSurface {
    /// Creates a target from local-frame geometry.
    pub fn new(
        name: impl Into<String>,
        source: TargetSource,
        positions: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
    ) -> Self {
        let bvh = TriangleBvh::new(&positions, &triangles);
        let mut normals = Vec::new();
        crate::mesh::vertex_normals(&triangles, &positions, &mut normals);
        let edge_sum: f32 = triangles
            .iter()
            .map(|t| {
                (0..3)
                    .map(|k| positions[t[k] as usize].distance(positions[t[(k + 1) % 3] as usize]))
                    .sum::<f32>()
            })
            .sum();
        let max_slack = 0.25 * edge_sum / (3 * triangles.len()).max(1) as f32;
        let mut vertex_triangle_offsets = vec![0u32; positions.len() + 1];
        for t in &triangles {
            for &v in t {
                vertex_triangle_offsets[v as usize + 1] += 1;
            }
        }
        for i in 0..positions.len() {
            vertex_triangle_offsets[i + 1] += vertex_triangle_offsets[i];
        }
        let mut fill = vertex_triangle_offsets.clone();
        let mut vertex_triangles = vec![0u32; 3 * triangles.len()];
        for (ti, t) in triangles.iter().enumerate() {
            for &v in t {
                vertex_triangles[fill[v as usize] as usize] = ti as u32;
                fill[v as usize] += 1;
            }
        }
        let around = |v: u32| csr_row(&vertex_triangle_offsets, &vertex_triangles, v);
        let across_edge = triangles
            .iter()
            .enumerate()
            .map(|(ti, t)| {
                std::array::from_fn(|k| {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    around(a)
                        .iter()
                        .copied()
                        .find(|&n| n as usize != ti && triangles[n as usize].contains(&b))
                        .unwrap_or(u32::MAX)
                })
            })
            .collect();
        let mut neighbor_offsets = Vec::with_capacity(positions.len() + 1);
        let mut neighbors = Vec::new();
        neighbor_offsets.push(0);
        for v in 0..positions.len() as u32 {
            let start = neighbors.len();
            for &n in around(v) {
                for &u in &triangles[n as usize] {
                    if u != v && !neighbors[start..].contains(&u) {
                        neighbors.push(u);
                    }
                }
            }
            neighbor_offsets.push(neighbors.len() as u32);
        }
        let fitted = positions.clone();
        let pseudo_normals = Box::new(match source {
            TargetSource::Bone(_) => side::PseudoNormals::new(&positions, &triangles, &bvh),
            TargetSource::Muscle(_) => side::PseudoNormals::default(),
        });
        let leaf_packs = match source {
            TargetSource::Bone(_) => corner_pack::LeafPacks::new(&bvh, &positions, &triangles),
            TargetSource::Muscle(_) => corner_pack::LeafPacks::default(),
        };
        Self {
            name: name.into(),
            source,
            transform: Affine3A::IDENTITY,
            inverse: Affine3A::IDENTITY,
            identity: true,
            geometry: Arc::new(SurfaceGeometry {
                positions,
                normals,
                triangles,
                bvh,
                leaf_packs,
                fitted,
                max_slack,
                vertex_triangle_offsets,
                vertex_triangles,
                across_edge,
                neighbor_offsets,
                neighbors,
                pseudo_normals,
            }),
            slack: 0.0,
            inverse_mass: Vec::new(),
        }
    }

    /// The generalised inverse mass `Σ βₖ² wₖ` of the surface point with
    /// barycentric coordinates `barycentric` in `triangle`: how easily the
    /// target gives way there. 0 for a rigid target (a bone) or before
    /// [`TargetSurface::set_inverse_masses`].
    #[inline]
    pub fn point_inverse_mass(&self, triangle: u32, barycentric: Vec3) -> f32 {
        if self.inverse_mass.is_empty() {
            return 0.0;
        }
        let [a, b, c] = self.geometry.triangles[triangle as usize];
        let w = &self.inverse_mass;
        barycentric.x * barycentric.x * w[a as usize]
            + barycentric.y * barycentric.y * w[b as usize]
            + barycentric.z * barycentric.z * w[c as usize]
    }

    /// Triangles around vertex `v`.
    #[inline]
    fn triangles_around(&self, v: u32) -> &[u32] {
        csr_row(
            &self.geometry.vertex_triangle_offsets,
            &self.geometry.vertex_triangles,
            v,
        )
    }

    /// A world point in the target's local frame.
    #[inline]
    pub fn to_local(&self, query: Vec3) -> Vec3 {
        if self.identity {
            query
        } else {
            self.inverse.transform_point3(query)
        }
    }

    /// Sets the world transform of a rigid target.
    pub fn set_transform(&mut self, transform: Affine3A) {
        self.transform = transform;
        self.inverse = transform.inverse();
        self.identity = transform == Affine3A::IDENTITY;
    }

    /// Vertex positions in the target's local frame (world for a muscle: its
    /// last published snapshot).
    pub fn positions(&self) -> &[Vec3] {
        &self.geometry.positions
    }

    /// Area-weighted unit vertex normals, local frame (a muscle's as of its
    /// last [`TargetSurface::update_normals`]).
    pub fn normals(&self) -> &[Vec3] {
        &self.geometry.normals
    }

    /// The triangles, as vertex indices.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.geometry.triangles
    }

    /// A target of `name` and `source` on this target's geometry, shared
    /// rather than copied (its frame starts as this target's): a bone of the
    /// same mesh. Building one from the mesh would give the same queries, bit
    /// for bit: the geometry is a function of the positions and triangles
    /// alone. (A muscle target made this way gets a copy of its own when it
    /// first publishes.)
    pub fn sharing_geometry(&self, name: impl Into<String>, source: TargetSource) -> Self {
        Self {
            name: name.into(),
            source,
            inverse_mass: Vec::new(),
            slack: 0.0,
            ..self.clone()
        }
    }

    /// Whether this is a rigid target built from exactly these local
    /// positions (to the bit) and triangles, whose geometry a bone of that
    /// mesh can share ([`TargetSurface::sharing_geometry`]).
    pub fn is_rigid_of(&self, positions: &[Vec3], triangles: &[[u32; 3]]) -> bool {
        let bits = |p: &Vec3| p.to_array().map(f32::to_bits);
        !self.is_deforming()
            && self.geometry.triangles == triangles
            && self.geometry.positions.len() == positions.len()
            && (self.geometry.positions.iter().map(bits)).eq(positions.iter().map(bits))
    }

    /// Whether two targets share one geometry (not merely equal ones).
    pub fn shares_geometry_with(&self, other: &TargetSurface) -> bool {
        Arc::ptr_eq(&self.geometry, &other.geometry)
    }

    /// Whether the target deforms (a muscle) rather than moving rigidly with
    /// a bone.
    #[inline]
    pub fn is_deforming(&self) -> bool {
        matches!(self.source, TargetSource::Muscle(_))
    }

    /// World position of local vertex `i`.
    #[inline]
    pub fn world_vertex(&self, i: u32) -> Vec3 {
        self.transform
            .transform_point3(self.geometry.positions[i as usize])
    }

    /// Asks for the cache line of triangle `t`'s corner indices (a hint:
    /// see [`crate::prefetch`]); nothing for a triangle out of range.
    #[inline]
    pub(crate) fn prefetch_triangle(&self, t: u32) {
        if let Some(corners) = self.geometry.triangles.get(t as usize) {
            prefetch(corners);
        }
    }

    /// Asks for the positions, normals and (a muscle's) inverse masses of
    /// triangle `t`'s corners, which a walk from `t` reads first (a hint,
    /// best after [`TargetSurface::prefetch_triangle`] had time to bring
    /// the indices).
    #[inline]
    pub(crate) fn prefetch_corners(&self, t: u32) {
        let g = &*self.geometry;
        let Some(corners) = g.triangles.get(t as usize) else {
            return;
        };
        for &v in corners {
            let v = v as usize;
            for line in [g.positions.get(v), g.normals.get(v)].into_iter().flatten() {
                prefetch(line);
            }
            if let Some(w) = self.inverse_mass.get(v) {
                prefetch(w);
            }
        }
    }

    /// Closest point on triangle `t` to a local-frame point: `(point, barycentric)`.
    #[inline]
    fn closest_on_triangle(&self, t: u32, q: Vec3) -> (Vec3, Vec3) {
        let [a, b, c] = self.geometry.triangles[t as usize];
        closest_point_triangle(
            q,
            self.geometry.positions[a as usize],
            self.geometry.positions[b as usize],
            self.geometry.positions[c as usize],
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
        let q = self.to_local(query);
        let mut best: Option<(f32, u32, Vec3, Vec3)> = None;
        let mut bound = if max_distance < f32::MAX {
            max_distance * max_distance
        } else {
            f32::MAX
        };
        if let Some(t) = warm.filter(|&t| (t as usize) < self.geometry.triangles.len()) {
            let (c, bary) = self.closest_on_triangle(t, q);
            let d2 = c.distance_squared(q);
            if d2 <= bound {
                best = Some((d2, t, c, bary));
                // A slightly larger bound keeps the warm triangle on ties.
                bound = d2 * (1.0 + 1e-5) + 1e-20;
            }
        }
        let found = self.nearest_triangle(q, bound).map(|t| {
            let (c, bary) = self.closest_on_triangle(t, q);
            (t, c.distance_squared(q), (c, bary))
        });
        if let Some((leaf, d2, (c, bary))) = found
            && best.is_none_or(|b| d2 < b.0)
        {
            best = Some((d2, leaf, c, bary));
        }
        let (d2, triangle, c, bary) = best?;
        Some(self.hit(query, d2, triangle, c, bary))
    }

    /// The triangle nearest local point `q` among those nearer than
    /// `bound` (squared), the first found of equals. A bone's leaves are
    /// tested four triangles at a time ([`corner_pack`]), each lane the
    /// scalar test's distance to the bit, so both find the same triangle.
    fn nearest_triangle(&self, q: Vec3, bound: f32) -> Option<u32> {
        let g = &self.geometry;
        let mut nearest = None;
        if g.leaf_packs.is_empty() {
            // Boxes grown by the slack still bound their triangles.
            g.bvh.search_leaves(q, bound, self.slack, |_, list, bound| {
                for &t in list {
                    let (c, _) = self.closest_on_triangle(t, q);
                    let d2 = c.distance_squared(q);
                    if d2 < *bound {
                        *bound = d2;
                        nearest = Some(t);
                    }
                }
            });
        } else {
            g.bvh
                .search_leaves(q, bound, self.slack, |node, list, bound| {
                    let lanes = g.leaf_packs.squared_distances(node, q);
                    for (&t, &d2) in list.iter().zip(&lanes) {
                        if d2 < *bound {
                            *bound = d2;
                            nearest = Some(t);
                        }
                    }
                });
        }
        nearest
    }

    /// Generalised winding number of the surface around a world point: ≈ 1
    /// inside, ≈ 0 outside, and robust to the holes and slivers of scanned
    /// bones (Jacobson et al. 2013). O(triangles); for build-time checks and
    /// for confirming what the closest-point test reports.
    pub fn winding_number(&self, query: Vec3) -> f32 {
        let q = self.to_local(query);
        let sum: f64 = self
            .geometry
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| (self.geometry.positions[i as usize] - q).as_dvec3());
                winding::solid_angle(a, b, c)
            })
            .sum();
        (sum / (4.0 * std::f64::consts::PI)) as f32
    }

    /// Whether a world point is inside the surface (winding number > ½).
    /// Outside the bounding box the answer is no without summing: seen from
    /// outside its convex hull a surface spans at most half the sphere.
    pub fn contains(&self, query: Vec3) -> bool {
        self.lower_bound(query) == 0.0 && self.winding_number(query) > 0.5
    }

    /// A lower bound on the distance from `query` (world) to this target: the
    /// distance to its bounding box. Cheap; a muscle choosing its closest
    /// target skips targets whose bound exceeds the best distance found.
    pub fn lower_bound(&self, query: Vec3) -> f32 {
        let q = self.to_local(query);
        self.geometry.bvh.lower_bound(q, self.slack)
    }

    /// A world-space box around the target as it is now (its local box,
    /// grown by the refit slack, moved by its transform), or `None` when
    /// it has no triangles: a point outside it by `d` is at least `d` from
    /// every triangle.
    pub fn world_box(&self) -> Option<(Vec3A, Vec3A)> {
        let (lo, hi) = self.geometry.bvh.root_box()?;
        let (lo, hi) = (lo - Vec3A::splat(self.slack), hi + Vec3A::splat(self.slack));
        if self.identity {
            return Some((lo, hi));
        }
        // The box of the moved box: centre moved, half-size through |R|.
        let (centre, half) = ((lo + hi) * 0.5, (hi - lo) * 0.5);
        let m = self.transform.matrix3;
        let abs = Mat3A::from_cols(m.x_axis.abs(), m.y_axis.abs(), m.z_axis.abs());
        let (centre, half) = (self.transform.transform_point3a(centre), abs * half);
        Some((centre - half, centre + half))
    }

    /// [`TargetSurface::lower_bound`] for a point already in the local frame.
    pub fn lower_bound_local(&self, local: Vec3) -> f32 {
        self.geometry.bvh.lower_bound(local, self.slack)
    }

    /// Closest point to `query` on triangle `t` only, or `None` when `t` is
    /// out of range.
    pub fn on_triangle(&self, query: Vec3, t: u32) -> Option<ClosestHit> {
        if t as usize >= self.geometry.triangles.len() {
            return None;
        }
        let q = self.to_local(query);
        let (c, bary) = self.closest_on_triangle(t, q);
        Some(self.hit(query, c.distance_squared(q), t, c, bary))
    }

    /// World unit normal of triangle `t`'s plane (from its winding; `Y`
    /// for a degenerate triangle).
    pub fn face_normal(&self, t: u32) -> Vec3 {
        let [a, b, c] =
            self.geometry.triangles[t as usize].map(|i| self.geometry.positions[i as usize]);
        let local = (b - a).cross(c - a);
        if self.identity {
            local.normalize_or(Vec3::Y)
        } else {
            self.transform
                .transform_vector3(local)
                .normalize_or(Vec3::Y)
        }
    }

    /// World point at barycentric `bary` of triangle `t`.
    #[inline]
    pub fn point_at(&self, t: u32, bary: Vec3) -> Vec3 {
        let [a, b, c] = self.geometry.triangles[t as usize];
        let local = self.geometry.positions[a as usize] * bary.x
            + self.geometry.positions[b as usize] * bary.y
            + self.geometry.positions[c as usize] * bary.z;
        self.transform.transform_point3(local)
    }

    /// Tangent frame at barycentric `bary` of triangle `t` (SPEC §5.9): normal
    /// interpolated from vertex normals, tangent along the first edge.
    pub fn frame_at(&self, t: u32, bary: Vec3) -> SurfaceFrame {
        let (origin, local) = self.local_frame(t, bary);
        SurfaceFrame {
            origin: self.transform.transform_point3(origin),
            basis: self.transform.matrix3 * local,
        }
    }

    /// The world point with coordinates `offset` in the tangent frame at
    /// barycentric `bary` of triangle `t`: the Hard constraint's goal. Same
    /// as `frame_at(t, bary)` applied to `offset`, with one transform.
    pub fn point_in_frame(&self, t: u32, bary: Vec3, offset: Vec3) -> Vec3 {
        let (origin, local) = self.local_frame(t, bary);
        let p = origin + Vec3::from(local * Vec3A::from(offset));
        if self.identity {
            p
        } else {
            self.transform.transform_point3(p)
        }
    }

    /// Origin and basis `[t̂ b̂ n̂]` of the tangent frame, in the local frame.
    #[inline]
    fn local_frame(&self, t: u32, bary: Vec3) -> (Vec3, Mat3A) {
        let [a, b, c] = self.geometry.triangles[t as usize].map(|i| i as usize);
        let at = |v: &[Vec3], i: usize| Vec3A::from(v[i]);
        let (wa, wb, wc) = (bary.x, bary.y, bary.z);
        let n = (at(&self.geometry.normals, a) * wa
            + at(&self.geometry.normals, b) * wb
            + at(&self.geometry.normals, c) * wc)
            .try_normalize()
            .unwrap_or(Vec3A::Y);
        let (pa, pb) = (
            at(&self.geometry.positions, a),
            at(&self.geometry.positions, b),
        );
        let e = pb - pa;
        let t_hat = (e - e.dot(n) * n)
            .try_normalize()
            .unwrap_or_else(|| n.any_orthonormal_vector());
        let b_hat = n.cross(t_hat);
        let origin = pa * wa + pb * wb + at(&self.geometry.positions, c) * wc;
        (origin.into(), Mat3A::from_cols(t_hat, b_hat, n))
    }
}

/// Row `i` of a compressed sparse row table.
#[inline]
fn csr_row<'a>(offsets: &[u32], entries: &'a [u32], i: u32) -> &'a [u32] {
    let i = i as usize;
    &entries[offsets[i] as usize..offsets[i + 1] as usize]
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

/// The bone-sized ellipsoid (10 × 4 × 5 cm, 24 segments by 16 stacks)
/// that the closest-point and winding-number tests build their bones from.
#[cfg(test)]
fn test_ellipsoid() -> crate::mesh::SurfaceMesh {
    crate::mesh::primitives::MeshGenerator::Ellipsoid {
        center: Vec3::ZERO,
        radii: Vec3::new(0.05, 0.02, 0.025),
        segments: 24,
        stacks: 16,
    }
    .build("bone")
    .expect("a valid ellipsoid")
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod side_tests;
