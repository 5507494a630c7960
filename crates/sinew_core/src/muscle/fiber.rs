//! Fibre directions per vertex (SPEC §7.3, PROPOSED there).
//!
//! ```text
//! f_v = t_{b(v)}                       tangent of the internal point v links to
//! f_v ← normalize(f_v − (f_v·n_v) n_v) projected onto the surface, unless
//!                                     f_v is within ~15° of the normal (tips), unless
//!                                     f_v is within ~15° of the normal (tips)
//! k × sign-aligned one-ring Laplacian smoothing, reprojected
//! ```

use super::internal::InternalStructure;
use crate::mesh::SurfaceMesh;
use glam::Vec3;

/// Computes unit fibre directions for the surface vertices.
///
/// With an internal structure the fibre follows the branch tangent of the
/// vertex's internal point; without one (`structure = None`) it follows the
/// mesh's longest principal direction.
pub fn fiber_field(
    mesh: &SurfaceMesh,
    structure: Option<&InternalStructure>,
    smoothing_iterations: u32,
) -> Vec<Vec3> {
    let n = mesh.vertex_count();
    let mut normals = Vec::new();
    mesh.vertex_normals(&mesh.positions, &mut normals);
    let axis = longest_axis(&mesh.positions);
    // Where the fibre is nearly normal to the surface (poles, tendon tips) the
    // projection leaves a tiny residual in an arbitrary tangential direction;
    // normalising it would invent a fibre, so such vertices keep theirs.
    let project = |f: Vec3, nrm: Vec3| -> Vec3 {
        let t = f - f.dot(nrm) * nrm;
        if t.length_squared() < 0.0625 * f.length_squared() {
            f.normalize_or(Vec3::X)
        } else {
            t.normalize()
        }
    };
    let mut fibers: Vec<Vec3> = (0..n)
        .map(|v| {
            let f = match structure {
                Some(s) if !s.points.is_empty() => s.tangents[s.vertex_point[v] as usize],
                _ => axis,
            };
            project(f, normals[v])
        })
        .collect();
    let mut next = fibers.clone();
    for _ in 0..smoothing_iterations {
        for v in 0..n {
            let f = fibers[v];
            let mut sum = f;
            for &u in mesh.neighbors_of(v) {
                let g = fibers[u as usize];
                sum += if g.dot(f) < 0.0 { -g } else { g };
            }
            next[v] = project(sum.try_normalize().unwrap_or(f), normals[v]);
        }
        std::mem::swap(&mut fibers, &mut next);
    }
    fibers
}

/// Principal axis of largest variance (power iteration on the covariance).
pub fn longest_axis(points: &[Vec3]) -> Vec3 {
    if points.is_empty() {
        return Vec3::X;
    }
    let mean = points.iter().sum::<Vec3>() / points.len() as f32;
    let mut cov = glam::Mat3::ZERO;
    for &p in points {
        let d = p - mean;
        cov += glam::Mat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    let mut v = Vec3::new(1.0, 0.7, 0.3).normalize();
    for _ in 0..64 {
        v = (cov * v).try_normalize().unwrap_or(Vec3::X);
    }
    v
}
