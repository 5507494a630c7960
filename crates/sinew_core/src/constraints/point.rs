//! Particle ↔ external point constraints: Attach, BranchAttach (SPEC §5.5–5.6),
//! Soft and Hard (§5.8–5.9), and Bind (a skin vertex ↔ its linear-blend
//! skinned position). The external point `q` is read-only (`w = 0`).
//!
//! ```text
//! C = |p − q| − d0        ∇_p C = (p − q)/|p − q|
//! Attach/BranchAttach: q = M(t) ℓ, d0 = 0
//! Soft:  q = Σ β_k q_{T,k}(t), d0 = rest distance
//! Hard:  q = c0(t) + F(t) ℓ,   d0 = 0
//! Bind:  q = Σ w_k M_k(t) ℓ_k,  d0 = 0
//! ```

use super::{
    ConstraintBatch, Correction, Gathered, MAX_PARTICLES, ParticleId, Particles, delta_lambda,
};
use glam::Vec3;

/// A batch of single-particle constraints towards goal points.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointBatch {
    /// Constrained particle.
    pub particle: Vec<ParticleId>,
    /// Current goal point (world), refreshed before projection.
    pub goal: Vec<Vec3>,
    /// Rest distance to the goal. Units: m.
    pub rest: Vec<f32>,
    /// Per-constraint compliance (type compliance / painted weight). Units: m/N.
    /// `f32::INFINITY` disables the constraint (weight 0).
    pub compliance: Vec<f32>,
    /// Accumulated multipliers.
    pub lambda: Vec<f32>,
    /// Generalised inverse mass of the goal's other body (Soft and Hard on a
    /// muscle target; 0 for bones and attachments). Units: 1/kg.
    pub target_w: Vec<f32>,
}

impl PointBatch {
    /// Number of constraints.
    pub fn len(&self) -> usize {
        self.particle.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.particle.is_empty()
    }

    /// Adds a constraint.
    pub fn push(&mut self, particle: ParticleId, goal: Vec3, rest: f32, compliance: f32) {
        self.particle.push(particle);
        self.goal.push(goal);
        self.rest.push(rest);
        self.compliance.push(compliance);
        self.lambda.push(0.0);
        self.target_w.push(0.0);
    }

    /// Constraint value `C` for constraint `i`.
    pub fn value(&self, i: usize, p: &[Vec3]) -> f32 {
        (p[self.particle[i].index()] - self.goal[i]).length() - self.rest[i]
    }
}

impl ConstraintBatch for PointBatch {
    fn count(&self) -> usize {
        self.particle.len()
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
        1
    }

    fn index_arrays(&self) -> [&[ParticleId]; MAX_PARTICLES] {
        [&self.particle, &[], &[]]
    }

    fn is_off(&self, i: usize) -> bool {
        !self.compliance[i].is_finite()
    }

    fn list_on(&self, list: &mut Vec<u32>) {
        super::list_finite(&self.compliance, list);
    }

    fn off_flags_are(&self, flags: &[bool]) -> bool {
        flags.len() == self.compliance.len()
            && (self.compliance.iter())
                .zip(flags)
                // Off exactly where the compliance is not finite.
                .all(|(c, &off)| off != c.is_finite())
    }

    fn lambda_storage(&mut self) -> &mut Vec<f32> {
        &mut self.lambda
    }

    #[inline(always)]
    fn particles(&self, i: usize) -> Particles {
        [self.particle[i]; MAX_PARTICLES]
    }

    #[inline(always)]
    fn correction_of(
        &self,
        i: usize,
        lambda: f32,
        Gathered {
            at: [x, ..],
            w: [w, ..],
        }: Gathered,
        inv_dt2: f32,
    ) -> Option<Correction> {
        let alpha = self.compliance[i] * inv_dt2;
        if !alpha.is_finite() {
            return None;
        }
        let d = x - self.goal[i];
        let len = d.length();
        if len < 1e-9 {
            return None;
        }
        let dl = delta_lambda(len - self.rest[i], lambda, w + self.target_w[i], alpha);
        let mut to = x;
        to += d * (w * dl / len);
        Some(Correction::one(dl, to))
    }
}
