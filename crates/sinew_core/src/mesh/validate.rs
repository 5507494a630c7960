//! Closed / manifold / orientation checks.

use super::SurfaceMesh;
use crate::error::MeshError;
use std::collections::HashMap;
use std::path::Path;

/// What [`SurfaceMesh::report`] found. Edges are `(a, b)` vertex pairs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshReport {
    /// Vertices.
    pub vertices: usize,
    /// Polygons.
    pub polygons: usize,
    /// Unique edges.
    pub edges: usize,
    /// Edges bordering exactly one polygon.
    pub open_edges: Vec<(u32, u32)>,
    /// Edges bordering more than two polygons, with their polygon count.
    pub non_manifold_edges: Vec<(u32, u32, usize)>,
    /// Edges traversed twice in the same direction.
    pub inconsistent_edges: Vec<(u32, u32)>,
    /// Signed volume (negative when the faces point inwards).
    pub volume: f64,
}

impl MeshReport {
    /// True when closed, manifold and consistently oriented.
    pub fn is_closed_manifold(&self) -> bool {
        self.open_edges.is_empty()
            && self.non_manifold_edges.is_empty()
            && self.inconsistent_edges.is_empty()
    }

    /// The first problem as a typed error.
    pub fn into_result(&self, file: &Path) -> Result<(), MeshError> {
        let file = file.to_path_buf();
        if let Some(&(a, b, faces)) = self.non_manifold_edges.first() {
            return Err(MeshError::NonManifoldEdge { file, a, b, faces });
        }
        if let Some(&(a, b)) = self.open_edges.first() {
            return Err(MeshError::Open {
                file,
                a,
                b,
                open_edges: self.open_edges.len(),
            });
        }
        if let Some(&(a, b)) = self.inconsistent_edges.first() {
            return Err(MeshError::InconsistentOrientation { file, a, b });
        }
        Ok(())
    }
}

pub(super) fn report(mesh: &SurfaceMesh) -> MeshReport {
    // (min, max) -> (uses as min->max, uses as max->min)
    let mut uses: HashMap<(u32, u32), (usize, usize)> = HashMap::new();
    for poly in mesh.polygons() {
        for k in 0..poly.len() {
            let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
            let e = uses.entry((a.min(b), a.max(b))).or_default();
            if a < b {
                e.0 += 1;
            } else {
                e.1 += 1;
            }
        }
    }
    let mut report = MeshReport {
        vertices: mesh.vertex_count(),
        polygons: mesh.polygon_count(),
        edges: mesh.edges.len(),
        volume: mesh.volume(),
        ..Default::default()
    };
    for &[a, b] in &mesh.edges {
        let (f, r) = uses[&(a, b)];
        match f + r {
            1 => report.open_edges.push((a, b)),
            2 if f != 1 => report.inconsistent_edges.push((a, b)),
            2 => {}
            n => report.non_manifold_edges.push((a, b, n)),
        }
    }
    report
}
