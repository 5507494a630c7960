//! The Volume constraint's sums, polygon by polygon: each polygon's part
//! of `6V` and its vertices' parts of `6∇V` (the formulas are in
//! [`super::volume`]'s module docs).
//!
//! A small mesh's whole sum ([`scatter_rotated`]) keeps every vector with
//! its lanes rotated to `(y, z, x)`. A cross product on SSE2 is three
//! shuffles: the two operands' `zxy` swizzles and one more that puts the
//! difference's lanes, `(y, z, x)` of the result, back in order. A
//! polygon's cross products share their operands (a quad's centroid is in
//! two of them), so with the rotated order kept from polygon to polygon
//! a quad takes four shuffles and its dot product where it took eleven
//! (the shuffle unit was what the sum waited on). Every lane's arithmetic
//! is the same operations in the same order, and the dot product adds its
//! lanes in glam's order: the same bits as [`polygon_part`] and
//! [`gradient_part`].

use glam::{Vec3A, Vec3Swizzles};

/// A polygon's part of `6V` and the terms its vertices' gradients share:
/// `(A·m, m, A/K)` with `A = Σ p_k × p_k+1` and `m` the centroid (a
/// triangle needs neither term: see [`gradient_part`]).
#[inline(always)]
pub(super) fn polygon_part(poly: &[u32], r: &[Vec3A]) -> (f32, Vec3A, Vec3A) {
    match *poly {
        [a, b, c] => {
            let (a, b, c) = (a as usize, b as usize, c as usize);
            (r[a].dot(r[b].cross(r[c])), Vec3A::ZERO, Vec3A::ZERO)
        }
        [a, b, c, d] => {
            let (pa, pb, pc, pd) = (r[a as usize], r[b as usize], r[c as usize], r[d as usize]);
            let m = (pa + pb + pc + pd) * 0.25;
            // Σ p_k × p_k+1 of a quad is (c − a) × (d − b).
            let area = (pc - pa).cross(pd - pb);
            (area.dot(m), m, area * 0.25)
        }
        _ => {
            let k = poly.len();
            let at = |j: usize| r[poly[j % k] as usize];
            let m = poly.iter().map(|&i| r[i as usize]).sum::<Vec3A>() / k as f32;
            let area = (0..k).map(|j| at(j).cross(at(j + 1))).sum::<Vec3A>();
            (area.dot(m), m, area / k as f32)
        }
    }
}

/// `6 ∂V/∂p` of the vertex in slot `j` of `poly` (before the sum over
/// polygons): `p_j+1 × p_j+2` for a triangle, `m × (p_j−1 − p_j+1) + A/K`
/// otherwise, with `(m, share)` from [`polygon_part`].
#[inline(always)]
pub(super) fn gradient_part(poly: &[u32], j: usize, r: &[Vec3A], m: Vec3A, share: Vec3A) -> Vec3A {
    let k = poly.len();
    // Slots j − 1 and j + 1, without a division for the usual sizes.
    let (prev, next) = match k {
        3 => ([2, 0, 1][j], [1, 2, 0][j]),
        4 => ((j + 3) & 3, (j + 1) & 3),
        _ => ((j + k - 1) % k, (j + 1) % k),
    };
    let at = |slot: usize| r[poly[slot] as usize];
    if k == 3 {
        // p_j+1 × p_j+2, and j + 2 is j − 1.
        at(next).cross(at(prev))
    } else {
        m.cross(at(prev) - at(next)) + share
    }
}

/// A vector and its `zxy` swizzle, taken once for every cross product it
/// is an operand of.
#[derive(Clone, Copy)]
struct Operand {
    v: Vec3A,
    zxy: Vec3A,
}

impl Operand {
    #[inline(always)]
    fn new(v: Vec3A) -> Self {
        Self { v, zxy: v.zxy() }
    }

    /// `−self`, exactly (a negation rounds nothing).
    #[inline(always)]
    fn negated(self) -> Self {
        Self {
            v: -self.v,
            zxy: -self.zxy,
        }
    }

    /// `self × rhs` with its lanes rotated to `(y, z, x)`: glam's cross
    /// product without its last shuffle, the same products and difference.
    #[inline(always)]
    fn cross(self, rhs: Operand) -> Vec3A {
        self.zxy * rhs.v - rhs.zxy * self.v
    }
}

/// `a · b` of two vectors with their lanes rotated to `(y, z, x)`, the
/// lanes added in glam's order (`(x + y) + z`): the bits of the dot product
/// of the vectors in order.
#[inline(always)]
fn dot_rotated(a: Vec3A, b: Vec3A) -> f32 {
    let p = a * b;
    (p.z + p.x) + p.y
}

/// Adds every polygon's vertices' parts of `6∇V` to `g_rotated` (lanes
/// `(y, z, x)`, see the module docs) and returns the sum of the polygons'
/// parts of `6V` (in f64): the polygon-by-polygon sum of [`polygon_part`]
/// and [`gradient_part`], with the same bits.
pub(super) fn scatter_rotated(
    offsets: &[u32],
    indices: &[u32],
    r: &[Vec3A],
    g_rotated: &mut [Vec3A],
) -> f64 {
    let mut six_v = 0.0f64;
    for o in offsets.windows(2) {
        let poly = &indices[o[0] as usize..o[1] as usize];
        match *poly {
            [a, b, c] => {
                let (a, b, c) = (a as usize, b as usize, c as usize);
                let (pa, pb, pc) = (Operand::new(r[a]), Operand::new(r[b]), Operand::new(r[c]));
                let bc = pb.cross(pc);
                six_v += dot_rotated(r[a].yzx(), bc) as f64;
                g_rotated[a] += bc;
                g_rotated[b] += pc.cross(pa);
                g_rotated[c] += pa.cross(pb);
            }
            [a, b, c, d] => {
                let (a, b, c, d) = (a as usize, b as usize, c as usize, d as usize);
                let m = Operand::new((r[a] + r[b] + r[c] + r[d]) * 0.25);
                // Σ p_k × p_k+1 of a quad is (c − a) × (d − b). Opposite
                // corners take opposite cross products: m × (p_d − p_b) is
                // −(m × (p_b − p_d)) to the bit (IEEE rounding is
                // symmetric, and a zero's sign is lost in the sum from +0),
                // so two cross products serve its four corners.
                let ca = Operand::new(r[c] - r[a]);
                let db = Operand::new(r[d] - r[b]);
                let area = ca.cross(db);
                six_v += dot_rotated(area, m.v.yzx()) as f64;
                let share = area * 0.25;
                // r[b] − r[d] is −(r[d] − r[b]) to the bit.
                let across_bd = m.cross(db.negated());
                let across_ca = m.cross(ca);
                g_rotated[a] += -across_bd + share;
                g_rotated[b] += -across_ca + share;
                g_rotated[c] += across_bd + share;
                g_rotated[d] += across_ca + share;
            }
            _ => {
                let (six, m, share) = polygon_part(poly, r);
                six_v += six as f64;
                for (j, &v) in poly.iter().enumerate() {
                    g_rotated[v as usize] += gradient_part(poly, j, r, m, share).yzx();
                }
            }
        }
    }
    six_v
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eight vertices at scattered places (relative to the first) and
    /// polygons of three, four and five corners that share them.
    fn mixed_polygons() -> (Vec<u32>, Vec<u32>, Vec<Vec3A>) {
        let r: Vec<Vec3A> = (0..8)
            .map(|i| {
                let k = i as f32;
                Vec3A::new((k * 1.7).sin(), (k * 0.9).cos() - 1.0, (k * 2.3).sin()) * 0.1
            })
            .collect();
        let polygons: [&[u32]; 5] = [
            &[0, 1, 2, 3],
            &[3, 2, 4],
            &[4, 5, 6, 7, 3],
            &[7, 6, 1, 0],
            &[1, 6, 2],
        ];
        let mut offsets = vec![0];
        let mut indices = Vec::new();
        for poly in polygons {
            indices.extend_from_slice(poly);
            offsets.push(indices.len() as u32);
        }
        (offsets, indices, r)
    }

    /// The rotated sum gives the bits of the polygon-by-polygon sum of
    /// [`polygon_part`] and [`gradient_part`] (what the blocked evaluation
    /// of a large mesh adds), for triangles, quads and a pentagon.
    #[test]
    fn the_rotated_sum_has_the_bits_of_the_polygon_by_polygon_sum() {
        let (offsets, indices, r) = mixed_polygons();
        let mut six_v = 0.0f64;
        let mut g = vec![Vec3A::ZERO; r.len()];
        for o in offsets.windows(2) {
            let poly = &indices[o[0] as usize..o[1] as usize];
            let (six, m, share) = polygon_part(poly, &r);
            six_v += six as f64;
            for (j, &v) in poly.iter().enumerate() {
                g[v as usize] += gradient_part(poly, j, &r, m, share);
            }
        }
        let mut g_rotated = vec![Vec3A::ZERO; r.len()];
        let rotated_six_v = scatter_rotated(&offsets, &indices, &r, &mut g_rotated);
        assert_eq!(rotated_six_v.to_bits(), six_v.to_bits());
        for (v, (&plain, &rotated)) in g.iter().zip(&g_rotated).enumerate() {
            let back = rotated.zxy();
            let bits = |x: Vec3A| x.to_array().map(f32::to_bits);
            assert_eq!(bits(back), bits(plain), "vertex {v}");
            assert_ne!(plain, Vec3A::ZERO, "vertex {v} has a gradient");
        }
    }

    /// A rotated cross product is the cross product with its lanes in
    /// `(y, z, x)` order, and the rotated dot product the dot product.
    #[test]
    fn rotated_products_are_the_products_in_another_lane_order() {
        let a = Vec3A::new(0.3, -1.7, 2.9);
        let b = Vec3A::new(-4.1, 0.6, 1.3);
        let rotated = Operand::new(a).cross(Operand::new(b));
        assert_eq!(rotated, a.cross(b).yzx());
        assert_eq!(
            Operand::new(a).negated().cross(Operand::new(b)),
            (-a).cross(b).yzx()
        );
        assert_eq!(dot_rotated(a.yzx(), b.yzx()).to_bits(), a.dot(b).to_bits());
    }
}
