//! Volume constraint with activation-driven gain (SPEC §5.2).
//!
//! ```text
//! V(p)   = 1/6 Σ_(a,b,c) ((p_a − o) × (p_b − o))·(p_c − o)      o = bounding-box centre
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
use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};

/// Volume parameters of a muscle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct VolumeParams {
    /// Create the constraint. Default: `true`.
    pub enabled: bool,
    /// Activation-independent gain `G` ([A] "Volume Ratio"). Default: `1.0`.
    pub gain: f32,
    /// Gain at full activation `R` ([A] "Volume Activation Ratio"). Default: `1.2`.
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
    pub gradient: Vec<Vec3>,
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
        let surface = &p[..self.surface_count];
        let (lo, hi) = crate::mesh::bounds_of(surface);
        let o = (lo + hi) * 0.5;
        let od = o.as_dvec3();
        self.gradient.clear();
        self.gradient.resize(self.surface_count, Vec3::ZERO);
        let rel = |i: u32| surface[i as usize] - o;
        let reld = |i: u32| surface[i as usize].as_dvec3() - od;
        let mut six_v = 0.0f64;
        for w in self.polygon_offsets.windows(2) {
            let poly = &self.polygon_indices[w[0] as usize..w[1] as usize];
            if let [a, b, c] = *poly {
                let (pa, pb, pc) = (rel(a), rel(b), rel(c));
                six_v += reld(a).cross(reld(b)).dot(reld(c));
                self.gradient[a as usize] += pb.cross(pc);
                self.gradient[b as usize] += pc.cross(pa);
                self.gradient[c as usize] += pa.cross(pb);
                continue;
            }
            let k = poly.len();
            let m = poly.iter().map(|&i| rel(i)).sum::<Vec3>() / k as f32;
            let md = poly.iter().map(|&i| reld(i)).sum::<DVec3>() / k as f64;
            let mut grad_m = Vec3::ZERO;
            for (j, &a) in poly.iter().enumerate() {
                let b = poly[(j + 1) % k];
                let (pa, pb) = (rel(a), rel(b));
                six_v += reld(a).cross(reld(b)).dot(md);
                self.gradient[a as usize] += pb.cross(m);
                self.gradient[b as usize] += m.cross(pa);
                grad_m += pa.cross(pb);
            }
            let share = grad_m / k as f32;
            for &i in poly {
                self.gradient[i as usize] += share;
            }
        }
        let mut wg = 0.0f64;
        for (g, &wi) in self.gradient.iter_mut().zip(w) {
            *g /= 6.0;
            wg += (wi * g.length_squared()) as f64;
        }
        (six_v / 6.0 - self.ratio as f64 * self.rest_volume, wg)
    }

    /// One projection. Volume is cubic in the positions, so a large violation
    /// is not removed by one linearised step; the projection takes up to
    /// [`VolumeConstraint::MAX_NEWTON_STEPS`] Newton steps, stopping as soon as
    /// the step was small enough (relative |C| < 1e-3 before it) that the
    /// quadratic residual is negligible. Usually that is one step.
    pub fn solve(&mut self, p: &mut [Vec3], w: &[f32], inv_dt2: f32) {
        let alpha = self.compliance * inv_dt2;
        let scale = self.rest_volume.abs().max(f64::MIN_POSITIVE);
        for _ in 0..Self::MAX_NEWTON_STEPS {
            let (c, wg) = self.evaluate(p, w);
            let dl = delta_lambda(c as f32, self.lambda, wg as f32, alpha);
            if dl == 0.0 {
                break;
            }
            self.lambda += dl;
            for (i, g) in self.gradient.iter().enumerate() {
                p[i] += *g * (w[i] * dl);
            }
            if (c / scale).abs() < 1e-3 {
                break;
            }
        }
    }

    /// Upper bound on Newton steps per projection.
    pub const MAX_NEWTON_STEPS: usize = 4;
}
