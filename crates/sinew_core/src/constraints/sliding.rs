//! Sliding constraint (SPEC §5.7): a vertex keeps its rest gap to the closest
//! point `c` on the closest target, recomputed every iteration, so it can slide.
//!
//! ```text
//! s = n_c·(p − c)                           signed distance (n_c outward normal at c)
//! outside (or inside at rest):  C = |p − c| − d0,  ∇C = (p − c)/|p − c|
//! inside but outside at rest:   C = s − d0,        ∇C = n_c   (push back out)
//! Contact mode: C ≥ 0 only (collision), λ clamped to ≥ 0
//! ```
//!
//! A surface layer in Contact mode (a skin held by its binding) walks to
//! its closest points in the first iteration of a substep only
//! ([`SlidingBatch::walk_first_only`]); later iterations re-project onto
//! the triangles found.
//!
//! Beyond the thesis: a vertex found inside a *rigid* target (a bone) that it
//! was outside of at rest is first put back on the surface with a plain,
//! non-compliant position projection (bones do not give way), then the
//! compliant gap equality acts as usual.

use super::{
    ConstraintBatch, Correction, Gathered, MAX_PARTICLES, ParticleId, Particles, TargetSlot,
    delta_lambda,
};
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Whether Sliding keeps the rest gap (equality) or only prevents penetration.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum SlidingMode {
    /// Equality: the gap to the closest target stays at its rest value (SPEC default).
    #[default]
    KeepGap,
    /// Inequality: the vertex may move away freely but not closer than its rest gap.
    Contact,
}

/// One Sliding constraint per surface vertex.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SlidingBatch {
    /// Constrained vertex.
    pub particle: Vec<ParticleId>,
    /// Compliance per constraint (type compliance / painted weight); infinite = off.
    pub compliance: Vec<f32>,
    /// Rest gap per (constraint, target): `rest_gap[i * targets + t]`;
    /// `f32::INFINITY` where the vertex never slides on that target (out of
    /// its contact band at rest, see [`crate::solver::pipeline::link`]).
    /// Units: m.
    pub rest_gap: Vec<f32>,
    /// Whether the vertex was outside the target at rest, per (constraint, target).
    pub rest_outside: Vec<bool>,
    /// Closest point on the chosen target (written by the closest-data block).
    pub point: Vec<Vec3>,
    /// Outward normal at `point`.
    pub normal: Vec<Vec3>,
    /// Triangle of the chosen target that `point` was found on.
    pub triangle: Vec<u32>,
    /// Barycentric coordinates of `point` in `triangle` when it was found.
    pub barycentric: Vec<Vec3>,
    /// Unit normal of `triangle`'s plane when `point` was found.
    pub plane: Vec<Vec3>,
    /// Chosen target slot this iteration ([`TargetSlot::NONE`]: none within reach).
    pub target: Vec<TargetSlot>,
    /// Accumulated multipliers.
    pub lambda: Vec<f32>,
    /// Equality or contact.
    pub mode: SlidingMode,
    /// Number of targets of the muscle.
    pub targets: usize,
    /// Per target slot: a rigid bone (contact with it is not compliant).
    pub rigid: Vec<bool>,
    /// Generalised inverse mass of `point` on its target (0 on a bone),
    /// written with `point`. Units: 1/kg.
    pub target_w: Vec<f32>,
    /// Walk to the closest points in the first iteration of a substep
    /// only; later iterations re-project onto the triangles found (a
    /// surface layer in [`SlidingMode::Contact`]: a skin over a body, held
    /// by its binding, needs no sliding from triangle to triangle within a
    /// substep). Otherwise as
    /// [`crate::solver::SolverSettings::walk_every_iteration`] says.
    pub walk_first_only: bool,
    /// The target slots each constraint may slide on (those with a finite
    /// rest gap), ascending: constraint `i`'s are
    /// `candidates[candidate_start[i]..candidate_start[i + 1]]`. Closest
    /// data visits only these (a skin over a body has hundreds of targets
    /// and a handful within reach of each vertex).
    pub candidates: Vec<u32>,
    /// Where each constraint's run of `candidates` starts; one more entry
    /// than constraints.
    pub candidate_start: Vec<u32>,
    /// The rest gap of each entry of `candidates` (`rest_gap` of that
    /// constraint and slot), beside it: closest data reads a vertex's
    /// gaps from one place instead of from a row of `targets` cells (a
    /// skin's rows are hundreds of targets wide). Units: m.
    pub candidate_gap: Vec<f32>,
    /// Whether the vertex connects at all: some target lies within reach
    /// ([`crate::muscle::MuscleParams::contact_reach`] for muscles, any gap
    /// for bones). A vertex out of reach keeps its constraints, switched off.
    pub connected: Vec<bool>,
}

impl SlidingBatch {
    /// Rebuilds [`Self::candidates`] and [`Self::candidate_gap`] from the
    /// rest gaps.
    pub fn index_candidates(&mut self) {
        self.candidates.clear();
        self.candidate_gap.clear();
        self.candidate_start.clear();
        self.candidate_start.push(0);
        for row in self.rest_gap.chunks(self.targets.max(1)) {
            for (slot, &gap) in row.iter().enumerate().filter(|(_, g)| g.is_finite()) {
                self.candidates.push(slot as u32);
                self.candidate_gap.push(gap);
            }
            self.candidate_start.push(self.candidates.len() as u32);
        }
    }

    /// Number of constraints.
    pub fn len(&self) -> usize {
        self.particle.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.particle.is_empty()
    }

    /// Value and gradient of constraint `i` at `p` (None when inactive).
    pub fn value_and_gradient(&self, i: usize, p: Vec3) -> Option<(f32, Vec3)> {
        let t = self.target[i].get()?;
        let slot = i * self.targets + t;
        let (c, n) = (self.point[i], self.normal[i]);
        let gap = self.rest_gap[slot];
        if !gap.is_finite() {
            // Out of the vertex's contact band: no rest gap to keep.
            return None;
        }
        let s = n.dot(p - c);
        if s < 0.0 && self.rest_outside[slot] {
            return Some((s - gap, n));
        }
        let d = p - c;
        let len = d.length();
        if len < 1e-9 {
            return Some((s - gap, n));
        }
        Some((len - gap, d / len))
    }
}

impl ConstraintBatch for SlidingBatch {
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
            at: [start, ..],
            w: [w, ..],
        }: Gathered,
        inv_dt2: f32,
    ) -> Option<Correction> {
        let alpha = self.compliance[i] * inv_dt2;
        if !alpha.is_finite() {
            return None;
        }
        let mut x = start;
        if let Some(t) = self.target[i].get()
            && w > 0.0
            && self.rigid.get(t) == Some(&true)
        {
            let slot = i * self.targets + t;
            let s = self.normal[i].dot(x - self.point[i]);
            if s < 0.0 && self.rest_outside[slot] {
                x -= self.normal[i] * s;
            }
        }
        let Some((c, g)) = self.value_and_gradient(i, x) else {
            return (x != start).then(|| Correction::one(0.0, x));
        };
        let wk = w + self.target_w[i];
        let mut dl = delta_lambda(c, lambda, wk * g.length_squared(), alpha);
        if self.mode == SlidingMode::Contact {
            // Unilateral: total λ stays ≥ 0 (it may only push outwards).
            let total = (lambda + dl).max(0.0);
            dl = total - lambda;
        }
        x += g * (w * dl);
        Some(Correction::one(dl, x))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each candidate's gap is its constraint's rest gap on that slot, and
    /// slots out of reach (infinite gaps) are not candidates.
    #[test]
    fn candidate_gaps_sit_beside_their_slots() {
        let inf = f32::INFINITY;
        let mut s = SlidingBatch {
            targets: 3,
            rest_gap: vec![0.1, inf, 0.3, inf, inf, inf, inf, 0.2, 0.0],
            ..Default::default()
        };
        s.index_candidates();
        assert_eq!(s.candidate_start, [0, 2, 2, 4]);
        assert_eq!(s.candidates, [0, 2, 1, 2]);
        assert_eq!(s.candidate_gap, [0.1, 0.3, 0.2, 0.0]);
    }
}
