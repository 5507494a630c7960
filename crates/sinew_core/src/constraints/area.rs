//! Triangle area constraints: a surface layer (skin, fat, fascia) keeps the
//! area of each of its triangles, so it resists being sheared flat or
//! gathered into folds that its edges alone would allow.
//!
//! ```text
//! N = (p_b − p_a) × (p_c − p_a),  n = N/|N|,  A = |N|/2
//! C = A − A0
//! ∇_b C = ½ (p_c − p_a) × n,  ∇_c C = ½ n × (p_b − p_a),  ∇_a C = −∇_b C − ∇_c C
//! ```
//! A degenerate triangle (`|N|` ≈ 0) has no gradient and is left alone
//! that iteration. In [`AreaMode::NoShrink`] the constraint is one-sided,
//! like a contact: the total multiplier stays ≥ 0, so it only pushes a
//! shrunk triangle open and lets a stretched one be (its edges hold it) —
//! what a skin over a bulging muscle needs. Compliance units: m³/N (`C`
//! is an area: `α` is compared with `w |∇C|²`, in kg⁻¹·m²), scaled by the
//! square of the scene's length unit like every SI parameter.

use super::{
    ConstraintBatch, Correction, Gathered, MAX_PARTICLES, ParticleId, Particles, delta_lambda,
};
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Whether Area keeps a triangle's area both ways or only stops it
/// shrinking.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum AreaMode {
    /// Equality: the area stays at its rest value, stretched or shrunk.
    #[default]
    Keep,
    /// Inequality: a triangle may stretch freely (its edges hold it) but
    /// not shrink below its rest area — no collapse, no fold — so a skin
    /// stretches over a bulging muscle (with `Keep` at 1e-7 m³/N the
    /// skin over MakeHuman's biceps stood out 3.3 mm instead of 5.0).
    NoShrink,
}

/// A batch of triangle area constraints.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AreaBatch {
    /// First corner.
    pub a: Vec<ParticleId>,
    /// Second corner.
    pub b: Vec<ParticleId>,
    /// Third corner.
    pub c: Vec<ParticleId>,
    /// Rest area `A0`. Units: m² (scene units²).
    pub rest: Vec<f32>,
    /// Accumulated multipliers (reset every substep).
    pub lambda: Vec<f32>,
    /// Compliance in scene units. Units: m³/N × (scene units per metre)².
    /// `0` is rigid.
    pub compliance: f32,
    /// Both ways or only against shrinking.
    pub mode: AreaMode,
}

impl AreaBatch {
    /// Number of constraints.
    pub fn len(&self) -> usize {
        self.a.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.a.is_empty()
    }

    /// Area of triangle `(a, b, c)`.
    pub fn triangle_area(a: Vec3, b: Vec3, c: Vec3) -> f32 {
        0.5 * (b - a).cross(c - a).length()
    }

    /// Adds a constraint keeping triangle `(a, b, c)` at area `rest`.
    pub fn push(&mut self, [a, b, c]: [ParticleId; 3], rest: f32) {
        self.a.push(a);
        self.b.push(b);
        self.c.push(c);
        self.rest.push(rest);
        self.lambda.push(0.0);
    }

    /// Constraint value `C` of constraint `i` at positions `p`.
    pub fn value(&self, i: usize, p: &[Vec3]) -> f32 {
        let [a, b, c] = [self.a[i], self.b[i], self.c[i]].map(|k| p[k.index()]);
        Self::triangle_area(a, b, c) - self.rest[i]
    }
}

impl ConstraintBatch for AreaBatch {
    fn count(&self) -> usize {
        self.a.len()
    }

    #[inline(always)]
    fn lambdas_mut(&mut self) -> &mut [f32] {
        &mut self.lambda
    }

    #[inline(always)]
    fn lambdas(&self) -> &[f32] {
        &self.lambda
    }

    #[inline(always)]
    fn particles_per_constraint(&self) -> usize {
        3
    }

    fn index_arrays(&self) -> [&[ParticleId]; MAX_PARTICLES] {
        [&self.a, &self.b, &self.c]
    }

    fn lambda_storage(&mut self) -> &mut Vec<f32> {
        &mut self.lambda
    }

    #[inline(always)]
    fn particles(&self, i: usize) -> Particles {
        [self.a[i], self.b[i], self.c[i]]
    }

    #[inline(always)]
    fn correction_of(
        &self,
        i: usize,
        lambda: f32,
        Gathered {
            at: [pa, pb, pc],
            w: [wa, wb, wc],
        }: Gathered,
        inv_dt2: f32,
    ) -> Option<Correction> {
        let alpha = self.compliance * inv_dt2;
        let (e1, e2) = (pb - pa, pc - pa);
        let normal = e1.cross(e2);
        let twice_area = normal.length();
        // Below ~1e-6 of a square millimetre the normal is noise.
        if twice_area < 1e-12 {
            return None;
        }
        let n = normal / twice_area;
        let gb = 0.5 * e2.cross(n);
        let gc = 0.5 * n.cross(e1);
        let ga = -gb - gc;
        let weighted =
            wa * ga.length_squared() + wb * gb.length_squared() + wc * gc.length_squared();
        let dl = delta_lambda(0.5 * twice_area - self.rest[i], lambda, weighted, alpha);
        let dl = match self.mode {
            AreaMode::Keep => dl,
            // One-sided: the total multiplier stays ≥ 0, so the constraint
            // only ever pushes a shrunk triangle open.
            AreaMode::NoShrink => (lambda + dl).max(0.0) - lambda,
        };
        if dl == 0.0 {
            return None;
        }
        Some(Correction::three(
            dl,
            pa + ga * (wa * dl),
            pb + gb * (wb * dl),
            pc + gc * (wc * dl),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ids(k: [u32; 3]) -> [ParticleId; 3] {
        k.map(|i| ParticleId::from_index(i as usize))
    }

    /// The kernel moves each corner along the derivative of the area: its
    /// correction, divided by the corner's inverse mass and the multiplier
    /// step, matches central finite differences of `C`.
    #[test]
    fn the_kernel_moves_along_the_area_gradient() {
        let p = [
            Vec3::new(0.01, 0.0, 0.002),
            Vec3::new(0.031, 0.004, -0.001),
            Vec3::new(0.012, 0.027, 0.005),
        ];
        let mut batch = AreaBatch::default();
        batch.push(ids([0, 1, 2]), 1e-4);
        let w = [1.0, 2.0, 0.5];
        let at = Gathered::from_slices(batch.particles(0), 3, &p, &w);
        let c = batch
            .correction_of(0, 0.0, at, 3600.0)
            .expect("not degenerate");
        assert_eq!(c.count, 3);
        let h = 1e-4f32;
        for corner in 0..3 {
            let g = (c.to[corner] - p[corner]) / (w[corner] * c.dlambda);
            for axis in 0..3 {
                let (mut q, mut r) = (p, p);
                q[corner][axis] += h;
                r[corner][axis] -= h;
                let fd = (batch.value(0, &q) - batch.value(0, &r)) / (2.0 * h);
                assert!(
                    (fd - g[axis]).abs() < 1e-4 * g.length().max(1e-3),
                    "corner {corner} axis {axis}: {fd} vs {}",
                    g[axis]
                );
            }
        }
    }

    /// Rigid (compliance 0), one projection of a stretched triangle brings
    /// its area back to rest to first order, and repeated projections
    /// converge; the centre of mass does not move.
    #[test]
    fn a_rigid_area_is_restored() {
        let rest = [
            Vec3::ZERO,
            Vec3::new(0.02, 0.0, 0.0),
            Vec3::new(0.0, 0.02, 0.0),
        ];
        let mut batch = AreaBatch::default();
        batch.push(
            ids([0, 1, 2]),
            AreaBatch::triangle_area(rest[0], rest[1], rest[2]),
        );
        let mut p = rest.map(|x| x * 1.3 + Vec3::new(0.0, 0.0, 0.001));
        let w = [1.0, 1.0, 1.0];
        let centre = (p[0] + p[1] + p[2]) / 3.0;
        for _ in 0..20 {
            batch.solve(&mut p, &w, 3600.0);
        }
        let err = batch.value(0, &p).abs() / batch.rest[0];
        assert!(err < 1e-5, "relative area error {err}");
        let moved = ((p[0] + p[1] + p[2]) / 3.0 - centre).length();
        assert!(moved < 1e-7, "centre moved {moved}");
    }

    /// `NoShrink` opens a shrunk triangle and leaves a stretched one alone.
    #[test]
    fn no_shrink_only_pushes_a_shrunk_triangle_open() {
        let rest = [
            Vec3::ZERO,
            Vec3::new(0.02, 0.0, 0.0),
            Vec3::new(0.0, 0.02, 0.0),
        ];
        let mut batch = AreaBatch {
            mode: AreaMode::NoShrink,
            ..Default::default()
        };
        batch.push(
            ids([0, 1, 2]),
            AreaBatch::triangle_area(rest[0], rest[1], rest[2]),
        );
        let w = [1.0; 3];
        let mut stretched = rest.map(|x| x * 1.3);
        let before = stretched;
        batch.solve(&mut stretched, &w, 3600.0);
        assert_eq!(stretched, before, "a stretched triangle is left alone");
        let mut shrunk = rest.map(|x| x * 0.7);
        for _ in 0..20 {
            batch.solve(&mut shrunk, &w, 3600.0);
        }
        let err = batch.value(0, &shrunk).abs() / batch.rest[0];
        assert!(err < 1e-5, "a shrunk one is opened to its rest area: {err}");
    }

    /// A degenerate (collinear) triangle has no gradient: no correction, no NaN.
    #[test]
    fn a_degenerate_triangle_is_left_alone() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        let mut batch = AreaBatch::default();
        batch.push(ids([0, 1, 2]), 0.1);
        let at = Gathered::from_slices(batch.particles(0), 3, &p, &[1.0; 3]);
        assert!(batch.correction_of(0, 0.0, at, 3600.0).is_none());
    }
}
