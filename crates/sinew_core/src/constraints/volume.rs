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
use glam::{Vec3, Vec3A};
use serde::{Deserialize, Serialize};

/// Volume parameters of a muscle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
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
        // Any point on the mesh keeps the relative coordinates as small as
        // the bounding-box centre would (within 2×) and needs no extra pass.
        let o = Vec3A::from(surface.first().copied().unwrap_or_default());
        self.relative.clear();
        self.relative
            .extend(surface.iter().map(|&x| Vec3A::from(x) - o));
        self.gradient.clear();
        self.gradient.resize(self.surface_count, Vec3A::ZERO);
        let (r, g) = (&self.relative, &mut self.gradient);
        // Per polygon with vertices p_k (relative to o), centroid m and
        // A = Σ p_k × p_k+1:  6V = A·m  and  6 ∂V/∂p_k = m × (p_k−1 − p_k+1) + A/K.
        // Triple products are formed in f32 (small, centred coordinates) and
        // summed in f64.
        let mut six_v = 0.0f64;
        for w in self.polygon_offsets.windows(2) {
            let poly = &self.polygon_indices[w[0] as usize..w[1] as usize];
            match *poly {
                [a, b, c] => {
                    let (a, b, c) = (a as usize, b as usize, c as usize);
                    let bc = r[b].cross(r[c]);
                    six_v += r[a].dot(bc) as f64;
                    g[a] += bc;
                    g[b] += r[c].cross(r[a]);
                    g[c] += r[a].cross(r[b]);
                }
                [a, b, c, d] => {
                    let (a, b, c, d) = (a as usize, b as usize, c as usize, d as usize);
                    let (pa, pb, pc, pd) = (r[a], r[b], r[c], r[d]);
                    let m = (pa + pb + pc + pd) * 0.25;
                    // Σ p_k × p_k+1 of a quad is (c − a) × (d − b).
                    let area = (pc - pa).cross(pd - pb);
                    six_v += area.dot(m) as f64;
                    let share = area * 0.25;
                    g[a] += m.cross(pd - pb) + share;
                    g[b] += m.cross(pa - pc) + share;
                    g[c] += m.cross(pb - pd) + share;
                    g[d] += m.cross(pc - pa) + share;
                }
                _ => {
                    let k = poly.len();
                    let at = |j: usize| r[poly[j % k] as usize];
                    let m = poly.iter().map(|&i| r[i as usize]).sum::<Vec3A>() / k as f32;
                    let area = (0..k).map(|j| at(j).cross(at(j + 1))).sum::<Vec3A>();
                    six_v += area.dot(m) as f64;
                    let share = area / k as f32;
                    for j in 0..k {
                        g[poly[j] as usize] += m.cross(at(j + k - 1) - at(j + 1)) + share;
                    }
                }
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
    /// the step was small enough (relative |C| < 1e-2 before it) that the
    /// residual, quadratic in that violation (≈ 1e-4), is negligible. Usually
    /// that is one step.
    pub fn solve(&mut self, p: &mut [Vec3], w: &[f32], inv_dt2: f32) {
        let alpha = self.compliance * inv_dt2;
        let scale = self.rest_volume.abs().max(f64::MIN_POSITIVE);
        let mut limit = Self::MAX_NEWTON_STEPS;
        let mut step = 0;
        while step < limit {
            step += 1;
            let (c, wg) = self.evaluate(p, w);
            if (c / scale).abs() > Self::FAR {
                // Far from the target (e.g. after contacts moved many
                // vertices): keep stepping until close.
                limit = Self::MAX_NEWTON_STEPS_FAR;
            }
            let dl = delta_lambda(c as f32, self.lambda, wg as f32, alpha);
            if dl == 0.0 {
                break;
            }
            self.lambda += dl;
            for (i, g) in self.gradient.iter().enumerate() {
                p[i] += Vec3::from(*g * (w[i] * dl));
            }
            if (c / scale).abs() < 1e-2 {
                break;
            }
        }
    }

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
