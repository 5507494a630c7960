//! Polygon surface meshes: welding, edges, adjacency, normals, validation, volume.
//!
//! A [`SurfaceMesh`] keeps the *polygons* as authored (quads stay quads) because
//! MSXPBD puts one Fiber constraint on every polygon edge (SPEC §5.1: the 10×10
//! UV sphere has 92 vertices and 190 edges, the thesis' P1 count). Triangles are
//! derived by fan triangulation for volume, normals and closest-point queries.
//! [`SurfaceMesh::triangulated`] turns every polygon into triangles when a user
//! wants diagonal edges to carry fibres as well.

mod crossing;
pub(crate) mod load;
pub mod primitives;
mod validate;

pub use load::{LoadOptions, ObjGroups, load_mesh};
pub use validate::MeshReport;

use crate::error::MeshError;
use glam::{DVec3, Vec3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A polygon surface mesh with derived edges, triangles and vertex adjacency.
///
/// Polygons are stored flat: polygon `i` is
/// `polygon_indices[polygon_offsets[i]..polygon_offsets[i + 1]]`.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceMesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Start of every polygon in `polygon_indices`, plus one final entry.
    pub polygon_offsets: Vec<u32>,
    /// Vertex indices of all polygons, counter-clockwise seen from outside.
    pub polygon_indices: Vec<u32>,
    /// Fan triangulation of the polygons (derived; rebuilt by [`SurfaceMesh::new`]).
    pub triangles: Vec<[u32; 3]>,
    /// Unique undirected polygon edges `[a, b]`, `a < b`, in first-seen order (derived).
    pub edges: Vec<[u32; 2]>,
    /// CSR offsets of the vertex one-ring (derived).
    pub neighbor_offsets: Vec<u32>,
    /// CSR entries of the vertex one-ring, sorted per vertex (derived).
    pub neighbors: Vec<u32>,
    /// Where the mesh came from, used in error messages.
    pub source: PathBuf,
}

impl SurfaceMesh {
    /// Builds a mesh from positions and polygons, checking indices, finiteness and
    /// degenerate polygons. `source` names the file or generator in errors.
    pub fn new(
        source: impl Into<PathBuf>,
        positions: Vec<Vec3>,
        polygons: &[Vec<u32>],
    ) -> Result<Self, MeshError> {
        let source = source.into();
        if polygons.is_empty() {
            return Err(MeshError::NoFaces { file: source });
        }
        for (vertex, p) in positions.iter().enumerate() {
            if !p.is_finite() {
                return Err(MeshError::NonFinite {
                    file: source,
                    vertex,
                    value: p.to_array(),
                });
            }
        }
        let mut polygon_offsets = Vec::with_capacity(polygons.len() + 1);
        let mut polygon_indices = Vec::new();
        polygon_offsets.push(0);
        for (face, poly) in polygons.iter().enumerate() {
            if let Some(&index) = poly.iter().find(|&&i| i as usize >= positions.len()) {
                return Err(MeshError::IndexOutOfRange {
                    file: source,
                    face,
                    index: index as usize,
                    count: positions.len(),
                });
            }
            let distinct = {
                let mut v = poly.clone();
                v.sort_unstable();
                v.dedup();
                v.len()
            };
            if poly.len() < 3 || distinct != poly.len() {
                return Err(MeshError::DegenerateFace {
                    file: source,
                    face,
                    reason: format!("{} vertices, {} distinct", poly.len(), distinct),
                });
            }
            polygon_indices.extend_from_slice(poly);
            polygon_offsets.push(polygon_indices.len() as u32);
        }
        let mut mesh = Self {
            positions,
            polygon_offsets,
            polygon_indices,
            triangles: Vec::new(),
            edges: Vec::new(),
            neighbor_offsets: Vec::new(),
            neighbors: Vec::new(),
            source,
        };
        mesh.rebuild_topology();
        mesh.check_degenerate_area()?;
        Ok(mesh)
    }

    fn rebuild_topology(&mut self) {
        self.triangles.clear();
        self.edges.clear();
        let mut seen: HashMap<(u32, u32), ()> = HashMap::new();
        for w in self.polygon_offsets.windows(2) {
            let poly = &self.polygon_indices[w[0] as usize..w[1] as usize];
            for k in 1..poly.len() - 1 {
                self.triangles.push([poly[0], poly[k], poly[k + 1]]);
            }
            for k in 0..poly.len() {
                let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
                let key = (a.min(b), a.max(b));
                if seen.insert(key, ()).is_none() {
                    self.edges.push([key.0, key.1]);
                }
            }
        }
        let n = self.positions.len();
        let mut lists = vec![Vec::new(); n];
        for &[a, b] in &self.edges {
            lists[a as usize].push(b);
            lists[b as usize].push(a);
        }
        self.neighbor_offsets = Vec::with_capacity(n + 1);
        self.neighbors.clear();
        self.neighbor_offsets.push(0);
        for mut list in lists {
            list.sort_unstable();
            self.neighbors.extend(list);
            self.neighbor_offsets.push(self.neighbors.len() as u32);
        }
    }

    fn check_degenerate_area(&self) -> Result<(), MeshError> {
        let min_area = min_polygon_area(&self.positions);
        for (face, poly) in self.polygons().enumerate() {
            let area = polygon_area(&self.positions, poly);
            if area.is_nan() || area <= min_area {
                return Err(MeshError::DegenerateFace {
                    file: self.source.clone(),
                    face,
                    reason: format!("zero area ({area:e})"),
                });
            }
        }
        Ok(())
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of polygons.
    pub fn polygon_count(&self) -> usize {
        self.polygon_offsets.len() - 1
    }

    /// Iterates over the polygons as index slices.
    pub fn polygons(&self) -> impl Iterator<Item = &[u32]> + '_ {
        self.polygon_offsets
            .windows(2)
            .map(|w| &self.polygon_indices[w[0] as usize..w[1] as usize])
    }

    /// One-ring neighbours of vertex `v`.
    pub fn neighbors_of(&self, v: usize) -> &[u32] {
        &self.neighbors[self.neighbor_offsets[v] as usize..self.neighbor_offsets[v + 1] as usize]
    }

    /// The vertices reachable over mesh edges from `from`, breadth first,
    /// each with its number of edges from the nearest of `from` (those at
    /// 0, in their order, a repeated one once): hops never decrease along
    /// the list. Vertices on a shell `from` does not touch are not in it.
    pub fn breadth_first(&self, from: &[u32]) -> Vec<(u32, u32)> {
        let mut seen = vec![false; self.vertex_count()];
        let mut order: Vec<(u32, u32)> = Vec::with_capacity(self.vertex_count());
        for &v in from {
            if !std::mem::replace(&mut seen[v as usize], true) {
                order.push((v, 0));
            }
        }
        let mut next = 0;
        while let Some(&(v, hops)) = order.get(next) {
            next += 1;
            for &n in self.neighbors_of(v as usize) {
                if !std::mem::replace(&mut seen[n as usize], true) {
                    order.push((n, hops + 1));
                }
            }
        }
        order
    }

    /// Returns a copy whose polygons are all triangles (diagonals become edges).
    pub fn triangulated(&self) -> Self {
        let polys: Vec<Vec<u32>> = self.triangles.iter().map(|t| t.to_vec()).collect();
        // Cannot fail: the triangles come from a valid mesh.
        let mut mesh = self.clone();
        mesh.polygon_offsets = (0..=polys.len() as u32).map(|i| 3 * i).collect();
        mesh.polygon_indices = polys.into_iter().flatten().collect();
        mesh.rebuild_topology();
        mesh
    }

    /// Merges vertices closer than `tolerance` (exporters split vertices at UV seams
    /// and hard normals; a muscle must not tear there). Returns the welded mesh and,
    /// for every input vertex, its index in the welded mesh.
    pub fn welded(&self, tolerance: f32) -> Result<(Self, Vec<u32>), MeshError> {
        let (positions, remap) = weld_positions(&self.positions, tolerance);
        let polygons: Vec<Vec<u32>> = self
            .polygons()
            .map(|p| p.iter().map(|&i| remap[i as usize]).collect())
            .collect();
        let mesh = Self::new(self.source.clone(), positions, &polygons)?;
        Ok((mesh, remap))
    }

    /// Axis-aligned bounds `(min, max)` of the vertices.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        bounds_of(&self.positions)
    }

    /// Length of the bounding-box diagonal.
    pub fn bounding_box_diagonal(&self) -> f32 {
        let (lo, hi) = self.bounds();
        (hi - lo).length()
    }

    /// Area-weighted vertex normals for the given positions (same topology),
    /// from the polygons' area vectors (Newell). Unlike normals of the fan
    /// triangulation they do not depend on which diagonal splits a quad, so a
    /// rotationally symmetric mesh gets rotationally symmetric normals (a
    /// twisted normal field would make fibres helical and muscles spin).
    pub fn vertex_normals(&self, positions: &[Vec3], out: &mut Vec<Vec3>) {
        out.clear();
        out.resize(positions.len(), Vec3::ZERO);
        for poly in self.polygons() {
            let mut n = Vec3::ZERO;
            for k in 0..poly.len() {
                let a = positions[poly[k] as usize];
                let b = positions[poly[(k + 1) % poly.len()] as usize];
                n += a.cross(b);
            }
            for &v in poly {
                out[v as usize] += n;
            }
        }
        for n in out.iter_mut() {
            *n = n.normalize_or_zero();
        }
    }

    /// Enclosed volume of the (closed, outward-oriented) mesh, accumulated in f64.
    ///
    /// Polygons with more than three vertices are fanned about their vertex
    /// centroid (see [`polygon_volume`]), the same formula the Volume
    /// constraint uses.
    pub fn volume(&self) -> f64 {
        polygon_volume(
            &self.polygon_offsets,
            &self.polygon_indices,
            &self.positions,
        )
    }

    /// Checks that the mesh is closed, edge-manifold and consistently oriented.
    pub fn check_closed_manifold(&self) -> Result<(), MeshError> {
        self.report().into_result(&self.source)
    }

    /// Topology report (open edges, non-manifold edges, orientation, volume).
    pub fn report(&self) -> MeshReport {
        validate::report(self)
    }

    /// Loads an OBJ or STL file (see [`load_mesh`]).
    pub fn load(path: &Path, options: &LoadOptions) -> Result<Self, MeshError> {
        load_mesh(path, options)
    }
}

/// Appends `positions` and `polygons` to Wavefront OBJ text. Faces refer to
/// the first position as OBJ index `first_index` (1 for a file's first
/// object). `decimals` fixes the digits of the coordinates; `None` writes the
/// shortest text that reads back to the same `f32`.
pub fn append_obj<'a>(
    text: &mut String,
    positions: &[Vec3],
    polygons: impl IntoIterator<Item = &'a [u32]>,
    first_index: usize,
    decimals: Option<usize>,
) {
    use std::fmt::Write as _;
    for p in positions {
        let _ = match decimals {
            Some(d) => writeln!(text, "v {:.d$} {:.d$} {:.d$}", p.x, p.y, p.z),
            None => writeln!(text, "v {} {} {}", p.x, p.y, p.z),
        };
    }
    for poly in polygons {
        text.push('f');
        for &i in poly {
            let _ = write!(text, " {}", first_index + i as usize);
        }
        text.push('\n');
    }
}

/// Wavefront OBJ text of named objects (`o NAME`), each one's faces
/// indexing its own vertices (the file's indices run on from object to
/// object).
#[derive(Clone, Debug, Default)]
pub struct ObjObjects {
    text: String,
    vertices: usize,
}

impl ObjObjects {
    /// Appends object `name`: `positions` and `polygons` (indices into
    /// `positions`), coordinates written as [`append_obj`] writes them.
    pub fn push<'a>(
        &mut self,
        name: &str,
        positions: &[Vec3],
        polygons: impl IntoIterator<Item = &'a [u32]>,
        decimals: Option<usize>,
    ) {
        self.text.push_str("o ");
        self.text.push_str(name);
        self.text.push('\n');
        append_obj(
            &mut self.text,
            positions,
            polygons,
            self.vertices + 1,
            decimals,
        );
        self.vertices += positions.len();
    }

    /// The OBJ text.
    pub fn into_text(self) -> String {
        self.text
    }
}

/// Polygons of `positions` at or below this area count as degenerate: a
/// tiny fraction of the squared bounding-box diagonal.
pub(crate) fn min_polygon_area(positions: &[Vec3]) -> f32 {
    let (lo, hi) = bounds_of(positions);
    let diag = (hi - lo).length().max(f32::MIN_POSITIVE);
    1e-12 * diag * diag
}

/// Whether a polygon has repeated corners or (near) zero area, the faces
/// [`SurfaceMesh::new`] rejects.
pub(crate) fn is_degenerate(positions: &[Vec3], poly: &[u32], min_area: f32) -> bool {
    let mut distinct = poly.to_vec();
    distinct.sort_unstable();
    distinct.dedup();
    let area = polygon_area(positions, poly);
    poly.len() < 3 || distinct.len() != poly.len() || area.is_nan() || area <= min_area
}

/// Area of a planar polygon (fan triangulation).
pub fn polygon_area(positions: &[Vec3], poly: &[u32]) -> f32 {
    let p0 = positions[poly[0] as usize];
    let mut n = Vec3::ZERO;
    for k in 1..poly.len() - 1 {
        let a = positions[poly[k] as usize] - p0;
        let b = positions[poly[k + 1] as usize] - p0;
        n += a.cross(b);
    }
    0.5 * n.length()
}

/// Axis-aligned bounds of a point set; `(0, 0)` for an empty set.
pub fn bounds_of(points: &[Vec3]) -> (Vec3, Vec3) {
    if points.is_empty() {
        return (Vec3::ZERO, Vec3::ZERO);
    }
    points.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &p| {
        (lo.min(p), hi.max(p))
    })
}

/// Area-weighted vertex normals of a triangle soup over `positions`.
pub fn vertex_normals(triangles: &[[u32; 3]], positions: &[Vec3], out: &mut Vec<Vec3>) {
    out.clear();
    out.resize(positions.len(), Vec3::ZERO);
    for &[a, b, c] in triangles {
        let (pa, pb, pc) = (
            positions[a as usize],
            positions[b as usize],
            positions[c as usize],
        );
        let n = (pb - pa).cross(pc - pa);
        out[a as usize] += n;
        out[b as usize] += n;
        out[c as usize] += n;
    }
    for n in out.iter_mut() {
        *n = n.normalize_or_zero();
    }
}

/// Signed volume of a closed triangle mesh, relative to its bounding-box centre
/// (SPEC §5.2: the reference point keeps precision far from the origin).
pub fn signed_volume(triangles: &[[u32; 3]], positions: &[Vec3]) -> f64 {
    let (lo, hi) = bounds_of(positions);
    let o = ((lo + hi) * 0.5).as_dvec3();
    let mut six_v = 0.0f64;
    for &[a, b, c] in triangles {
        let pa: DVec3 = positions[a as usize].as_dvec3() - o;
        let pb: DVec3 = positions[b as usize].as_dvec3() - o;
        let pc: DVec3 = positions[c as usize].as_dvec3() - o;
        six_v += pa.cross(pb).dot(pc);
    }
    six_v / 6.0
}

/// Signed volume of a closed polygon mesh (flat polygons as in [`SurfaceMesh`]),
/// relative to its bounding-box centre, accumulated in f64.
///
/// Triangles count as they are; a polygon with more vertices is fanned about
/// its vertex centroid. Unlike a fan from its first vertex, this is symmetric
/// in the polygon's vertices: a consistent diagonal choice over a quad mesh is
/// chiral, and its volume gradient pushes every vertex slightly sideways in
/// the same rotational sense, which twists a muscle about its axis.
pub fn polygon_volume(offsets: &[u32], indices: &[u32], positions: &[Vec3]) -> f64 {
    let (lo, hi) = bounds_of(positions);
    let o = ((lo + hi) * 0.5).as_dvec3();
    let rel = |i: u32| positions[i as usize].as_dvec3() - o;
    let mut six_v = 0.0f64;
    for w in offsets.windows(2) {
        let poly = &indices[w[0] as usize..w[1] as usize];
        if let [a, b, c] = *poly {
            six_v += rel(a).cross(rel(b)).dot(rel(c));
            continue;
        }
        let centroid = poly.iter().map(|&i| rel(i)).sum::<DVec3>() / poly.len() as f64;
        for (k, &a) in poly.iter().enumerate() {
            let b = poly[(k + 1) % poly.len()];
            six_v += rel(a).cross(rel(b)).dot(centroid);
        }
    }
    six_v / 6.0
}

/// Welds positions on a hash grid of cell `tolerance`; returns unique positions and
/// the old → new index map. Vertices keep first-seen order.
pub fn weld_positions(positions: &[Vec3], tolerance: f32) -> (Vec<Vec3>, Vec<u32>) {
    let tol = tolerance.max(f32::MIN_POSITIVE);
    let cell = |p: Vec3| -> [i64; 3] {
        let q = (p / tol).floor();
        [q.x as i64, q.y as i64, q.z as i64]
    };
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    let mut unique: Vec<Vec3> = Vec::new();
    let mut remap = Vec::with_capacity(positions.len());
    for &p in positions {
        let c = cell(p);
        let mut found = None;
        'search: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    // Saturating: a zero tolerance (a single point's box) or
                    // far-out coordinates put cells at the ends of i64.
                    let key = [
                        c[0].saturating_add(dx),
                        c[1].saturating_add(dy),
                        c[2].saturating_add(dz),
                    ];
                    if let Some(list) = grid.get(&key) {
                        for &u in list {
                            if unique[u as usize].distance(p) <= tol {
                                found = Some(u);
                                break 'search;
                            }
                        }
                    }
                }
            }
        }
        let index = found.unwrap_or_else(|| {
            unique.push(p);
            let i = (unique.len() - 1) as u32;
            grid.entry(c).or_default().push(i);
            i
        });
        remap.push(index);
    }
    (unique, remap)
}
