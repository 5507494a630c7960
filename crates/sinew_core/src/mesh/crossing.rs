//! Where a surface passes through itself: pairs of triangles that share no
//! vertex and intersect.
//!
//! A closed surface that crosses itself at rest has no consistent inside
//! there: its rings cut through each other, and the edge lengths the
//! strain figures measure against are those of a crumpled surface (a short
//! edge between two crossing rings must stretch many times over when the
//! muscle straightens). `sinew check` reports the count per muscle and
//! `sinew import-mjcf` notes every muscle it builds that crosses itself.

use super::SurfaceMesh;
use glam::Vec3;

impl SurfaceMesh {
    /// Pairs of this mesh's triangles that share no vertex and intersect,
    /// at positions `positions` (one per vertex; the mesh's own for its
    /// rest shape). Touching counts. Triangles are sorted by their bounds
    /// along X and swept, so a surface that does not cross itself costs
    /// about `n log n`.
    pub fn self_crossings(&self, positions: &[Vec3]) -> usize {
        let corners = |t: &[u32; 3]| t.map(|v| positions[v as usize]);
        let mut boxes: Vec<(Vec3, Vec3, usize)> = self
            .triangles
            .iter()
            .enumerate()
            .map(|(k, t)| {
                let [a, b, c] = corners(t);
                (a.min(b).min(c), a.max(b).max(c), k)
            })
            .collect();
        boxes.sort_by(|p, q| p.0.x.total_cmp(&q.0.x));
        let mut count = 0;
        for (i, &(lo, hi, k)) in boxes.iter().enumerate() {
            for &(lo2, hi2, k2) in &boxes[i + 1..] {
                if lo2.x > hi.x {
                    break;
                }
                if lo2.cmpgt(hi).any() || lo.cmpgt(hi2).any() {
                    continue;
                }
                let (s, t) = (&self.triangles[k], &self.triangles[k2]);
                if s.iter().any(|v| t.contains(v)) {
                    continue;
                }
                if triangles_cross(corners(s), corners(t)) {
                    count += 1;
                }
            }
        }
        count
    }
}

/// Whether two triangles intersect: an edge of one passes through the other.
fn triangles_cross(p: [Vec3; 3], q: [Vec3; 3]) -> bool {
    let edges_through =
        |a: [Vec3; 3], b: [Vec3; 3]| (0..3).any(|k| segment_hits_triangle(a[k], a[(k + 1) % 3], b));
    edges_through(p, q) || edges_through(q, p)
}

/// Whether the segment `s`–`e` meets triangle `t` (Möller–Trumbore, ends
/// and edges included).
fn segment_hits_triangle(s: Vec3, e: Vec3, t: [Vec3; 3]) -> bool {
    let d = e - s;
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let h = d.cross(e2);
    let det = e1.dot(h);
    if det.abs() <= f32::EPSILON * e1.length() * e2.length() * d.length() {
        return false;
    }
    let f = det.recip();
    let o = s - t[0];
    let u = f * o.dot(h);
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let q = o.cross(e1);
    let v = f * d.dot(q);
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    (0.0..=1.0).contains(&(f * e2.dot(q)))
}

#[cfg(test)]
mod tests {
    use crate::mesh::primitives::MeshGenerator;

    fn sphere() -> crate::mesh::SurfaceMesh {
        MeshGenerator::Ellipsoid {
            center: glam::Vec3::ZERO,
            radii: glam::Vec3::splat(1.0),
            segments: 12,
            stacks: 8,
        }
        .build("sphere")
        .unwrap()
    }

    #[test]
    fn a_sphere_does_not_cross_itself() {
        let s = sphere();
        assert_eq!(s.self_crossings(&s.positions), 0);
    }

    #[test]
    fn a_sphere_with_its_top_pushed_through_its_bottom_does() {
        let s = sphere();
        // The top half pressed down below the bottom pole: its cap passes
        // through the lower half.
        let pressed: Vec<glam::Vec3> = s
            .positions
            .iter()
            .map(|&p| {
                if p.y > 0.1 {
                    glam::Vec3::new(p.x * 0.5, p.y - 1.6, p.z * 0.5)
                } else {
                    p
                }
            })
            .collect();
        assert!(s.self_crossings(&pressed) > 0);
    }
}
