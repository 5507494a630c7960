//! Volume constraint with activation-driven gain (SPEC §5.2).
//!
//! ```text
//! V(p)   = 1/6 Σ_(a,b,c) ((p_a − o) × (p_b − o))·(p_c − o)      o = first surface vertex
//! C      = V(p) − k_p(a) V0                                       (true volume, m³)
//! ∇_a C  = 1/6 Σ (p_b − o) × (p_c − o)      over triangles with a first in cyclic order
//! ```
//! The triangles are the mesh's triangles, and for a polygon with more than
//! three vertices the fan `(p_i, p_i+1, m)` about its vertex centroid
//! `m = mean(p_i)`; the centroid's gradient is shared equally by the
//! polygon's vertices. A first-vertex fan would be chiral on a quad mesh (every
//! quad split along "the same" diagonal) and its gradient twists the muscle
//! about its axis at every projection — the free T1 oval ended a cycle
//! twisted by ≈ 1 % of its diagonal (see [`crate::mesh::polygon_volume`]).
//!
//! ```text
//! k_p(a) = G (1 + (R − 1) s(a)) / (1 + (R − 1) s(a0)),  s = clamp(a, 0, 1)
//! ```
//! `G` is the activation-independent volume gain, `R` the gain at full
//! activation (1.2 = +20 %). Sums run in f64. Compliance units: m³/N.

use super::delta_lambda;
use super::volume_terms::{gradient_part, polygon_part, scatter_rotated};
use glam::{Vec3, Vec3A, Vec3Swizzles};
use serde::{Deserialize, Serialize};

/// Volume parameters of a muscle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VolumeParams {
    /// Create the constraint. Default: `true`.
    pub enabled: bool,
    /// Activation-independent gain `G` (AdonisFX "Volume Ratio"). Default: `1.0`.
    pub gain: f32,
    /// Gain at full activation `R` (AdonisFX "Volume Activation Ratio"). Default: `1.2`.
    pub activation_gain: f32,
    /// For an open mesh: drop the Volume constraint with a warning instead of
    /// failing. Default: `false`.
    pub allow_open_mesh: bool,
}

impl Default for VolumeParams {
    fn default() -> Self {
        Self {
            enabled: true,
            gain: 1.0,
            activation_gain: 1.2,
            allow_open_mesh: false,
        }
    }
}

impl VolumeParams {
    /// Target ratio `k_p(a)` of the rest volume.
    pub fn ratio(&self, a: f32, a0: f32) -> f32 {
        self.gain * self.activation_ratio(a, a0)
    }

    /// The activation-driven part `k_p(a)/k_p(a0)` (without `G`).
    pub fn activation_ratio(&self, a: f32, a0: f32) -> f32 {
        let s = |x: f32| x.clamp(0.0, 1.0);
        let r = self.activation_gain - 1.0;
        (1.0 + r * s(a)) / (1.0 + r * s(a0))
    }
}

/// The single volume constraint of a muscle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VolumeConstraint {
    /// Start of every surface polygon in `polygon_indices`, plus one final entry.
    pub polygon_offsets: Vec<u32>,
    /// Surface-particle indices of the polygons, counter-clockwise from outside.
    pub polygon_indices: Vec<u32>,
    /// Number of surface particles (the first particles of the muscle).
    pub surface_count: usize,
    /// Rest volume `V0`. Units: m³.
    pub rest_volume: f64,
    /// Current target ratio `k_p(a)` (updated once per frame).
    pub ratio: f32,
    /// Compliance. Units: m³/N. `0` is rigid.
    pub compliance: f32,
    /// Accumulated multiplier.
    pub lambda: f32,
    /// Gradient workspace (no allocation in the step).
    pub gradient: Vec<Vec3A>,
    /// Workspace: surface positions relative to the first one.
    pub relative: Vec<Vec3A>,
    /// Large meshes ([`VolumeConstraint::BLOCKED_POLYGONS`]): CSR offsets of
    /// the polygons around each surface vertex (built on first use).
    pub vertex_polygon_offsets: Vec<u32>,
    /// Large meshes: `(polygon, slot of the vertex in it)` around each
    /// surface vertex, in polygon order.
    pub vertex_polygons: Vec<(u32, u32)>,
    /// Large meshes, workspace: each polygon's centroid and area share.
    pub polygon_terms: Vec<(Vec3A, Vec3A)>,
}

/// `f(block index, block)` of each block of [`VolumeConstraint::BLOCK`]
/// items of `items`, in block order, the blocks on the current rayon pool
/// when `parallel`.
fn map_blocks<T: Send, R: Send>(
    items: &mut [T],
    parallel: bool,
    f: impl Fn((usize, &mut [T])) -> R + Sync + Send,
) -> Vec<R> {
    use rayon::prelude::*;
    let size = VolumeConstraint::BLOCK;
    if parallel {
        items.par_chunks_mut(size).enumerate().map(f).collect()
    } else {
        items.chunks_mut(size).enumerate().map(f).collect()
    }
}

/// How far one projection of the Volume constraint goes. Volume is cubic
/// in the positions, so one linearised step leaves a residual quadratic in
/// the violation: about 1e-4 of the volume after a 1 % violation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VolumeProjection {
    /// One linearised step, XPBD's: for an iteration that others follow.
    /// The constraints projected before the Volume move the volume by
    /// 1–10 % in each of T7's iterations, so a second step's precision
    /// would be lost in the next iteration; a second evaluation was two
    /// fifths of the Volume's cost.
    Step,
    /// Newton steps until the last one was small: up to
    /// [`VolumeConstraint::MAX_NEWTON_STEPS`], stopping once the
    /// violation before a step is under 1 % (its residual, about 1e-4, is
    /// negligible), and up to [`VolumeConstraint::MAX_NEWTON_STEPS_FAR`]
    /// while it is above [`VolumeConstraint::FAR`] (e.g. after contacts
    /// moved many vertices). For a substep's last iteration, whose volume
    /// is the one the frame ends with.
    Converge,
}

impl VolumeProjection {
    /// The Newton steps a projection takes at most while it is not
    /// [`VolumeConstraint::FAR`] from the target: one for
    /// [`VolumeProjection::Step`], [`VolumeConstraint::MAX_NEWTON_STEPS`]
    /// for [`VolumeProjection::Converge`].
    pub fn steps_at_most(self) -> usize {
        match self {
            VolumeProjection::Step => 1,
            VolumeProjection::Converge => VolumeConstraint::MAX_NEWTON_STEPS,
        }
    }
}

impl VolumeConstraint {
    /// Current volume of `p` (f64 accumulation about the bounding-box centre).
    pub fn volume(&self, p: &[Vec3]) -> f64 {
        crate::mesh::polygon_volume(
            &self.polygon_offsets,
            &self.polygon_indices,
            &p[..self.surface_count],
        )
    }

    /// Constraint value `C = V − k_p V0`.
    pub fn value(&self, p: &[Vec3]) -> f64 {
        self.volume(p) - self.ratio as f64 * self.rest_volume
    }

    /// Fills `self.gradient` with `∇C` and returns `(C, Σ w |∇C|²)`.
    pub fn evaluate(&mut self, p: &[Vec3], w: &[f32]) -> (f64, f64) {
        self.evaluate_with(p, w, false)
    }

    /// Meshes with at least this many polygons are evaluated in blocks:
    /// per polygon block its part of the volume and the terms its vertices
    /// share, then per vertex block the gradient gathered from the polygons
    /// around each vertex, and the sums added block by block. The blocks
    /// run in parallel when asked, with the same bits on any thread count;
    /// smaller meshes are a few µs of serial work.
    pub const BLOCKED_POLYGONS: usize = 4096;

    /// Polygons or vertices per block of the blocked evaluation.
    pub const BLOCK: usize = 1024;

    /// [`VolumeConstraint::evaluate`], the blocks of a large mesh on the
    /// current rayon pool when `parallel` (same result).
    pub fn evaluate_with(&mut self, p: &[Vec3], w: &[f32], parallel: bool) -> (f64, f64) {
        let surface = &p[..self.surface_count];
        // Any point on the mesh keeps the relative coordinates as small as
        // the bounding-box centre would (within 2×) and needs no extra pass.
        let o = Vec3A::from(surface.first().copied().unwrap_or_default());
        self.relative.clear();
        self.relative
            .extend(surface.iter().map(|&x| Vec3A::from(x) - o));
        self.gradient.clear();
        self.gradient.resize(self.surface_count, Vec3A::ZERO);
        // Per polygon with vertices p_k (relative to o), centroid m and
        // A = Σ p_k × p_k+1:  6V = A·m  and  6 ∂V/∂p_k = m × (p_k−1 − p_k+1) + A/K.
        // Triple products are formed in f32 (small, centred coordinates) and
        // summed in f64.
        if self.polygon_offsets.len() > Self::BLOCKED_POLYGONS {
            return self.evaluate_blocked(w, parallel);
        }
        // Slices of one length, held apart from `self`: a vertex index
        // checked against one is checked against both, and the gradient's
        // stores do not make the compiler reload the vectors' headers.
        let n = self.surface_count;
        let (r, g) = (&self.relative[..n], &mut self.gradient[..n]);
        let (offsets, indices) = (&self.polygon_offsets[..], &self.polygon_indices[..]);
        // The sum keeps the gradient's lanes rotated to (y, z, x), which
        // saves most of its shuffles; each is put back in order here.
        let six_v = scatter_rotated(offsets, indices, r, g);
        let mut wg = 0.0f64;
        for (g, &wi) in self.gradient.iter_mut().zip(w) {
            *g = g.zxy() / 6.0;
            wg += (wi * g.length_squared()) as f64;
        }
        (six_v / 6.0 - self.ratio as f64 * self.rest_volume, wg)
    }

    /// The blocked evaluation (see [`VolumeConstraint::BLOCKED_POLYGONS`]);
    /// `self.relative` is filled.
    fn evaluate_blocked(&mut self, w: &[f32], parallel: bool) -> (f64, f64) {
        if self.vertex_polygon_offsets.len() != self.surface_count + 1 {
            self.build_vertex_polygons();
        }
        let (offsets, indices, r) = (&self.polygon_offsets, &self.polygon_indices, &self.relative);
        let polygons = offsets.len() - 1;
        self.polygon_terms
            .resize(polygons, (Vec3A::ZERO, Vec3A::ZERO));
        // Polygon blocks: their part of 6V, and the shared terms.
        let polygon_block = |(b, terms): (usize, &mut [(Vec3A, Vec3A)])| {
            let mut six_v = 0.0f64;
            for (k, term) in terms.iter_mut().enumerate() {
                let i = b * Self::BLOCK + k;
                let poly = &indices[offsets[i] as usize..offsets[i + 1] as usize];
                let (six, m, share) = polygon_part(poly, r);
                six_v += six as f64;
                *term = (m, share);
            }
            six_v
        };
        // Block sums added in block order: the same bits on any thread count.
        let six_v: f64 = map_blocks(&mut self.polygon_terms, parallel, polygon_block)
            .iter()
            .sum();
        // Vertex blocks: each vertex gathers its gradient from its polygons,
        // in polygon order (the bits of the polygon-by-polygon sum).
        let (around_offsets, around, terms) = (
            &self.vertex_polygon_offsets,
            &self.vertex_polygons,
            &self.polygon_terms,
        );
        let vertex_block = |(b, g): (usize, &mut [Vec3A])| {
            let mut wg = 0.0f64;
            for (k, g) in g.iter_mut().enumerate() {
                let v = b * Self::BLOCK + k;
                let mut sum = Vec3A::ZERO;
                for &(i, j) in &around[around_offsets[v] as usize..around_offsets[v + 1] as usize] {
                    let i = i as usize;
                    let poly = &indices[offsets[i] as usize..offsets[i + 1] as usize];
                    let (m, share) = terms[i];
                    sum += gradient_part(poly, j as usize, r, m, share);
                }
                *g = sum / 6.0;
                wg += (w[v] * g.length_squared()) as f64;
            }
            wg
        };
        let wg: f64 = map_blocks(&mut self.gradient, parallel, vertex_block)
            .iter()
            .sum();
        (six_v / 6.0 - self.ratio as f64 * self.rest_volume, wg)
    }

    /// Fills the polygons-around-each-vertex table.
    fn build_vertex_polygons(&mut self) {
        let n = self.surface_count;
        let mut offsets = vec![0u32; n + 1];
        for &v in &self.polygon_indices {
            offsets[v as usize + 1] += 1;
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut around = vec![(0u32, 0u32); self.polygon_indices.len()];
        for (i, o) in self.polygon_offsets.windows(2).enumerate() {
            for (j, &v) in self.polygon_indices[o[0] as usize..o[1] as usize]
                .iter()
                .enumerate()
            {
                around[fill[v as usize] as usize] = (i as u32, j as u32);
                fill[v as usize] += 1;
            }
        }
        self.vertex_polygon_offsets = offsets;
        self.vertex_polygons = around;
    }

    /// One projection, to convergence ([`VolumeProjection::Converge`]).
    pub fn solve(&mut self, p: &mut [Vec3], w: &[f32], inv_dt2: f32) {
        self.solve_with(p, w, inv_dt2, false, VolumeProjection::Converge);
    }

    /// One projection ([`VolumeProjection`] says how far it goes), a large
    /// mesh's evaluation and update in blocks on the current rayon pool when
    /// `parallel` (same result).
    pub fn solve_with(
        &mut self,
        p: &mut [Vec3],
        w: &[f32],
        inv_dt2: f32,
        parallel: bool,
        how: VolumeProjection,
    ) {
        use rayon::prelude::*;
        let parallel = parallel && self.polygon_offsets.len() > Self::BLOCKED_POLYGONS;
        let alpha = self.compliance * inv_dt2;
        let scale = self.rest_volume.abs().max(f64::MIN_POSITIVE);
        let mut limit = how.steps_at_most();
        let mut step = 0;
        while step < limit {
            step += 1;
            let (c, wg) = self.evaluate_with(p, w, parallel);
            if how == VolumeProjection::Converge && (c / scale).abs() > Self::FAR {
                // Far from the target (e.g. after contacts moved many
                // vertices): keep stepping until close.
                limit = Self::MAX_NEWTON_STEPS_FAR;
            }
            let dl = delta_lambda(c as f32, self.lambda, wg as f32, alpha);
            if dl == 0.0 {
                break;
            }
            self.lambda += dl;
            let update = |(p, (g, w)): (&mut Vec3, (&Vec3A, &f32))| {
                *p += Vec3::from(*g * (*w * dl));
            };
            let (p, g) = (&mut p[..self.surface_count], &self.gradient);
            if parallel {
                let n = self.surface_count;
                let blocks = p.par_chunks_mut(Self::BLOCK).zip(g.par_chunks(Self::BLOCK));
                let blocks = blocks.zip(w[..n].par_chunks(Self::BLOCK));
                blocks.for_each(|((p, g), w)| p.iter_mut().zip(g.iter().zip(w)).for_each(update));
            } else {
                p.iter_mut().zip(g.iter().zip(w)).for_each(update);
            }
            if (c / scale).abs() < Self::CLOSE {
                break;
            }
        }
    }

    /// Relative violation under which a projection takes no further step
    /// (its residual after this one, about 1e-4, is negligible).
    pub const CLOSE: f64 = 1e-2;

    /// Upper bound on Newton steps per projection. With four, P3 evaluated
    /// the volume 29 times per frame, with two 20, and the T1 figures did not
    /// change.
    pub const MAX_NEWTON_STEPS: usize = 2;

    /// Relative violation above which up to
    /// [`VolumeConstraint::MAX_NEWTON_STEPS_FAR`] steps are taken.
    pub const FAR: f64 = 0.02;

    /// Upper bound on Newton steps when the violation is above
    /// [`VolumeConstraint::FAR`].
    pub const MAX_NEWTON_STEPS_FAR: usize = 8;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::primitives::MeshGenerator;

    /// A closed quad mesh (with triangle fans at the poles) large enough for
    /// the blocked evaluation, its vertices displaced so no two polygons are
    /// alike, and its Volume constraint.
    fn large_volume() -> (VolumeConstraint, Vec<Vec3>, Vec<f32>) {
        let mesh = MeshGenerator::Ellipsoid {
            center: Vec3::new(0.3, -0.2, 0.1),
            radii: Vec3::new(0.05, 0.02, 0.025),
            segments: 96,
            stacks: 48,
        }
        .build("large")
        .unwrap();
        let n = mesh.positions.len();
        let p: Vec<Vec3> = mesh
            .positions
            .iter()
            .enumerate()
            .map(|(i, &x)| {
                let k = i as f32;
                x + 1e-3 * Vec3::new((k * 1.3).sin(), (k * 2.1).cos(), (k * 0.7).sin())
            })
            .collect();
        let w: Vec<f32> = (0..n).map(|i| 1.0 + (i % 7) as f32 * 0.1).collect();
        let volume = VolumeConstraint {
            rest_volume: mesh.volume(),
            ratio: 1.1,
            surface_count: n,
            polygon_offsets: mesh.polygon_offsets,
            polygon_indices: mesh.polygon_indices,
            ..Default::default()
        };
        assert!(volume.polygon_offsets.len() > VolumeConstraint::BLOCKED_POLYGONS);
        (volume, p, w)
    }

    fn in_pool<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(f)
    }

    #[test]
    fn blocked_evaluation_is_the_polygon_by_polygon_sum() {
        let (mut v, p, w) = large_volume();
        let (c, wg) = v.evaluate(&p, &w);
        // The reference: every polygon's part added to its vertices in
        // polygon order (what smaller meshes do).
        let r = &v.relative;
        let mut g = vec![Vec3A::ZERO; v.surface_count];
        let six_v = scatter_rotated(&v.polygon_offsets, &v.polygon_indices, r, &mut g);
        for (i, (a, b)) in v.gradient.iter().zip(&g).enumerate() {
            assert_eq!(*a, b.zxy() / 6.0, "vertex {i}");
        }
        let c_ref = six_v / 6.0 - v.ratio as f64 * v.rest_volume;
        assert!((c - c_ref).abs() <= 1e-12 * v.rest_volume, "{c} {c_ref}");
        assert!(wg > 0.0);
        // And the gradient is the volume's: central differences.
        for &i in &[0usize, 17, 2000, v.surface_count - 1] {
            for axis in 0..3 {
                let (mut plus, mut minus) = (p.clone(), p.clone());
                let h = 1e-4f32;
                plus[i][axis] += h;
                minus[i][axis] -= h;
                let fd = (v.volume(&plus) - v.volume(&minus)) / (2.0 * h as f64);
                let analytic = v.gradient[i][axis] as f64;
                assert!(
                    (fd - analytic).abs() <= 1e-3 * analytic.abs().max(1e-6),
                    "vertex {i} axis {axis}: {fd} vs {analytic}"
                );
            }
        }
    }

    /// `Step` is one linearised step: from a 10 % violation it leaves the
    /// residual of one Newton step, where `Converge` goes on to the target;
    /// from under 1 % both take that one step, to the bit.
    #[test]
    fn a_step_is_one_newton_step_and_converge_goes_on_to_the_target() {
        let error = |v: &VolumeConstraint, p: &[Vec3]| {
            (v.volume(p) / (v.ratio as f64 * v.rest_volume) - 1.0).abs()
        };
        let project = |ratio: Option<f32>, how| {
            let (mut v, mut p, w) = large_volume();
            v.ratio = ratio.unwrap_or(v.ratio);
            v.solve_with(&mut p, &w, 3600.0, false, how);
            let e = error(&v, &p);
            (p, e)
        };
        let (v, p, _) = large_volume();
        let start = error(&v, &p);
        assert!(start > 0.05, "{start}");
        let (stepped, one) = project(None, VolumeProjection::Step);
        let (converged, full) = project(None, VolumeProjection::Converge);
        assert!(one < 0.1 * start && one > 1e-4, "{start} → {one}");
        assert!(full < 1e-5 && full < 0.1 * one, "{one} → {full}");
        assert_ne!(stepped, converged);
        // Half a percent off: Converge stops after its first step too.
        let near = Some((v.volume(&p) / v.rest_volume * 1.005) as f32);
        let (stepped, one) = project(near, VolumeProjection::Step);
        let (converged, full) = project(near, VolumeProjection::Converge);
        assert!(one < 1e-4, "{one}");
        assert_eq!((stepped, one), (converged, full));
    }

    #[test]
    fn parallel_volume_gives_the_same_bits_on_any_thread_count() {
        let run = |threads: usize| {
            in_pool(threads, || {
                let (mut v, mut p, w) = large_volume();
                let first = v.evaluate_with(&p, &w, true);
                v.solve_with(&mut p, &w, 3600.0, true, VolumeProjection::Converge);
                (first, v.gradient.clone(), v.lambda, p)
            })
        };
        let serial = {
            let (mut v, mut p, w) = large_volume();
            let first = v.evaluate_with(&p, &w, false);
            v.solve_with(&mut p, &w, 3600.0, false, VolumeProjection::Converge);
            (first, v.gradient.clone(), v.lambda, p)
        };
        for threads in [1, 2, 8] {
            assert!(run(threads) == serial, "{threads} threads");
        }
        // The projection moved the volume to its target.
        let (v, _, _) = large_volume();
        let after = v.volume(&serial.3) / (v.ratio as f64 * v.rest_volume);
        assert!((after - 1.0).abs() < 1e-3, "{after}");
    }
}
