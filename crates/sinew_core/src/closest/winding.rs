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

/// A node seen from far away: every triangle under it at once.
#[derive(Clone, Copy, Debug, Default)]
struct Dipole {
    /// Area-weighted centre of the node's triangles.
    centre: Vec3,
    /// Sum of the triangles' area vectors (½ of the edges' cross product).
    area: Vec3,
    /// Distance from `centre` to the farthest corner of the node's box.
    radius: f32,
}

/// The dipoles of a rigid target's BVH nodes (module docs).
#[derive(Clone, Debug, Default)]
pub(super) struct WindingTree {
    dipoles: Vec<Dipole>,
}

/// A node is summed as one dipole when the point is farther from its
/// centre than this many times its radius: relative error of order
/// `1 / FAR²` on the node's share.
const FAR: f32 = 2.0;

impl WindingTree {
    /// The dipoles of `bvh`'s nodes over `triangles` at `positions`.
    pub(super) fn new(bvh: &TriangleBvh, positions: &[Vec3], triangles: &[[u32; 3]]) -> Self {
        let mut dipoles = vec![Dipole::default(); bvh.node_count()];
        // Children come after their parents: a reverse sweep sees them first.
        let mut weight = vec![0.0f32; dipoles.len()];
        for i in (0..dipoles.len()).rev() {
            let (min, max, contents) = bvh.node(i);
            let (mut centre, mut area, mut total) = (Vec3::ZERO, Vec3::ZERO, 0.0);
            match contents {
                NodeContents::Leaf(list) => {
                    for &t in list {
                        let [a, b, c] = triangles[t as usize].map(|v| positions[v as usize]);
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
                }
                NodeContents::Inner(left) => {
                    for child in [left, left + 1] {
                        area += dipoles[child].area;
                        centre += weight[child] * dipoles[child].centre;
                        total += weight[child];
                    }
                }
            }
            let centre = if total > 0.0 {
                centre / total
            } else {
                Vec3::from((min + max) * 0.5)
            };
            let corner = Vec3A::from(centre);
            let radius = (corner - min).abs().max((max - corner).abs()).length();
            dipoles[i] = Dipole {
                centre,
                area,
                radius,
            };
            weight[i] = total;
        }
        Self { dipoles }
    }

    /// Winding number around local point `q` of the surface `bvh` is
    /// built over (module docs).
    pub(super) fn winding_number(
        &self,
        bvh: &TriangleBvh,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        q: Vec3,
    ) -> f32 {
        if self.dipoles.is_empty() {
            return 0.0;
        }
        let mut sum = 0.0f64;
        let mut stack = [0usize; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let i = stack[top];
            let d = self.dipoles[i];
            let r = d.centre - q;
            let far = r.length_squared();
            if far > (FAR * d.radius).powi(2) {
                sum += f64::from(d.area.dot(r) / (far * far.sqrt()));
                continue;
            }
            match bvh.node(i).2 {
                NodeContents::Leaf(list) => {
                    for &t in list {
                        let [a, b, c] = triangles[t as usize].map(|v| positions[v as usize] - q);
                        sum += f64::from(solid_angle_f32(a, b, c));
                    }
                }
                NodeContents::Inner(left) if top + 2 <= stack.len() => {
                    stack[top] = left;
                    stack[top + 1] = left + 1;
                    top += 2;
                }
                // Deeper than any median-split tree gets: sum the node's
                // subtree by its dipole rather than overflow.
                NodeContents::Inner(_) => {
                    sum += f64::from(d.area.dot(r) / (far * far.sqrt()).max(f32::MIN_POSITIVE));
                }
            }
        }
        (sum / (4.0 * std::f64::consts::PI)) as f32
    }
}
