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

/// Whether a vertex was outside target `slot` at rest, from its run of a
/// [`SlidingBatch::inside`] list: `start` holds the run's two bounds (its
/// entries of `inside_start`).
#[inline]
pub(crate) fn outside_at_rest(inside: &[u32], start: &[u32], slot: usize) -> bool {
    let run = &inside[start[0] as usize..start[1] as usize];
    !run.contains(&(slot as u32))
}

/// Whether Sliding keeps the rest gap (equality) or only prevents penetration.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum SlidingMode {
    /// Equality: the gap to the closest target stays at its rest value (SPEC default).
    #[default]
    KeepGap,
    /// Inequality: the vertex may move away freely but not closer than its rest gap.
    Contact,
}

/// What closest data found for one Sliding constraint: its chosen target
/// and the closest point on it, everything the projection reads of it in
/// one cache line. Closest data visits the vertices in a contact band, a
/// sparse few of a muscle's (T7: about one in ten), where a field per
/// array cost a cache line per field and vertex; together the record
/// costs one, for closest data and for the projection after it.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct SlidingContact {
    /// Closest point on the chosen target (written by the closest-data block).
    pub point: Vec3,
    /// Outward normal at `point`.
    pub normal: Vec3,
    /// Barycentric coordinates of `point` in `triangle` when it was found.
    pub barycentric: Vec3,
    /// Generalised inverse mass of `point` on its target (0 on a bone),
    /// written with `point`. Units: 1/kg.
    pub target_w: f32,
    /// The rest gap to the chosen target, written with `target` (infinite
    /// when none is chosen or it is out of the contact band). Units: m.
    pub gap: f32,
    /// Triangle of the chosen target that `point` was found on.
    pub triangle: u32,
    /// Chosen target slot this iteration ([`TargetSlot::NONE`]: none within reach).
    pub target: TargetSlot,
    /// Whether the vertex was outside the chosen target at rest, written
    /// with `target`.
    pub outside: bool,
}

/// One Sliding constraint per surface vertex.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SlidingBatch {
    /// Constrained vertex.
    pub particle: Vec<ParticleId>,
    /// Compliance per constraint (type compliance / painted weight); infinite = off.
    pub compliance: Vec<f32>,
    /// Per constraint, its chosen target and closest point on it.
    pub contact: Vec<SlidingContact>,
    /// Unit normal of the contact's triangle's plane when its point was
    /// found (read by [`crate::solver::SolverSettings::feature_contacts`]).
    pub plane: Vec<Vec3>,
    /// Accumulated multipliers.
    pub lambda: Vec<f32>,
    /// Equality or contact.
    pub mode: SlidingMode,
    /// Number of targets of the muscle.
    pub targets: usize,
    /// Per target slot: a rigid bone (contact with it is not compliant).
    pub rigid: Vec<bool>,
    /// Walk to the closest points in the first iteration of a substep
    /// only; later iterations re-project onto the triangles found (a
    /// surface layer in [`SlidingMode::Contact`]: a skin over a body, held
    /// by its binding, needs no sliding from triangle to triangle within a
    /// substep). Otherwise as
    /// [`crate::solver::SolverSettings::walk_interval`] says.
    pub walk_first_only: bool,
    /// The target slots each constraint may slide on (those within its
    /// contact band at rest, with a finite rest gap), ascending: constraint
    /// `i`'s are `candidates[candidate_start[i]..candidate_start[i + 1]]`.
    /// Closest data visits only these (a skin over a body has hundreds of
    /// targets and a handful within reach of each vertex). Set by
    /// [`Self::set_rest`].
    pub candidates: Vec<u32>,
    /// Where each constraint's run of `candidates` starts; one more entry
    /// than constraints.
    pub candidate_start: Vec<u32>,
    /// The rest gap of each entry of `candidates`, beside it: the vertex's
    /// distance to that target at rest, capped by its thickness. Every other
    /// target's is infinite: the vertex never slides on it. Units: m.
    pub candidate_gap: Vec<f32>,
    /// Whether the vertex was outside the target of each entry of
    /// `candidates` at rest, beside it.
    pub candidate_outside: Vec<bool>,
    /// The target slots each constraint's vertex was inside of at rest,
    /// ascending: constraint `i`'s are `inside[inside_start[i]..
    /// inside_start[i + 1]]` (most vertices have none). A vertex inside a
    /// target at rest is not pushed out of it.
    pub inside: Vec<u32>,
    /// Where each constraint's run of `inside` starts; one more entry than
    /// constraints.
    pub inside_start: Vec<u32>,
    /// Whether the vertex connects at all: some target lies within reach
    /// ([`crate::muscle::MuscleParams::contact_reach`] for muscles, any gap
    /// for bones). A vertex out of reach keeps its constraints, switched off.
    pub connected: Vec<bool>,
}

impl SlidingBatch {
    /// Sets the rest data from dense rows of `targets` cells per
    /// constraint: `rest_gap[i * targets + t]` (infinite where the vertex
    /// never slides on target `t`) and `rest_outside[i * targets + t]`
    /// (whether the vertex was outside `t` at rest). Keeps only the sparse
    /// form: the candidates with their gaps and sides, and the targets
    /// each vertex was inside of.
    pub fn set_rest(&mut self, rest_gap: &[f32], rest_outside: &[bool]) {
        let nt = self.targets.max(1);
        debug_assert_eq!(rest_gap.len(), rest_outside.len());
        self.candidates.clear();
        self.candidate_gap.clear();
        self.candidate_outside.clear();
        self.candidate_start.clear();
        self.candidate_start.push(0);
        self.inside.clear();
        self.inside_start.clear();
        self.inside_start.push(0);
        for (gaps, outside) in rest_gap.chunks(nt).zip(rest_outside.chunks(nt)) {
            for (slot, (&gap, &out)) in gaps.iter().zip(outside).enumerate() {
                if gap.is_finite() {
                    self.candidates.push(slot as u32);
                    self.candidate_gap.push(gap);
                    self.candidate_outside.push(out);
                }
                if !out {
                    self.inside.push(slot as u32);
                }
            }
            self.candidate_start.push(self.candidates.len() as u32);
            self.inside_start.push(self.inside.len() as u32);
        }
    }

    /// Whether constraint `i`'s vertex was outside target `slot` at rest.
    pub fn outside_at_rest(&self, i: usize, slot: usize) -> bool {
        outside_at_rest(&self.inside, &self.inside_start[i..=i + 1], slot)
    }

    /// Constraint `i`'s rest gap to target `slot`: infinite where it
    /// never slides on it. Units: m.
    pub fn rest_gap(&self, i: usize, slot: usize) -> f32 {
        let run = self.candidate_start[i] as usize..self.candidate_start[i + 1] as usize;
        let k = self.candidates[run.clone()].binary_search(&(slot as u32));
        k.map_or(f32::INFINITY, |k| self.candidate_gap[run.start + k])
    }

    /// Chooses target `slot` for constraint `i` (`None`: no target), with
    /// its rest gap and side; the closest point is written apart.
    pub fn choose(&mut self, i: usize, slot: Option<usize>) {
        let gap = slot.map_or(f32::INFINITY, |s| self.rest_gap(i, s));
        let outside = slot.is_none_or(|s| self.outside_at_rest(i, s));
        let c = &mut self.contact[i];
        c.target = slot.map_or(TargetSlot::NONE, TargetSlot::new);
        (c.gap, c.outside) = (gap, outside);
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
        let contact = &self.contact[i];
        contact.target.get()?;
        let (c, n) = (contact.point, contact.normal);
        let gap = contact.gap;
        if !gap.is_finite() {
            // Out of the vertex's contact band: no rest gap to keep.
            return None;
        }
        let s = n.dot(p - c);
        if s < 0.0 && contact.outside {
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
        let contact = &self.contact[i];
        if let Some(t) = contact.target.get()
            && w > 0.0
            && self.rigid.get(t) == Some(&true)
        {
            let s = contact.normal.dot(x - contact.point);
            if s < 0.0 && contact.outside {
                x -= contact.normal * s;
            }
        }
        let Some((c, g)) = self.value_and_gradient(i, x) else {
            return (x != start).then(|| Correction::one(0.0, x));
        };
        let wk = w + contact.target_w;
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

    /// A contact is one cache line, starting on one: closest data and the
    /// projection touch one line per constraint.
    #[test]
    fn a_contact_fills_one_cache_line() {
        assert_eq!(std::mem::size_of::<SlidingContact>(), 64);
        assert_eq!(std::mem::align_of::<SlidingContact>(), 64);
    }

    /// Each candidate's gap and side sit beside its slot, slots out of
    /// reach (infinite gaps) are not candidates, and the targets a vertex
    /// was inside of at rest are listed whatever their gap.
    #[test]
    fn rest_data_is_kept_sparse_beside_its_slots() {
        let inf = f32::INFINITY;
        let mut s = SlidingBatch {
            targets: 3,
            ..Default::default()
        };
        let gaps = [0.1, inf, 0.3, inf, inf, inf, inf, 0.2, 0.0];
        let outside = [true, false, true, true, true, true, true, true, false];
        s.set_rest(&gaps, &outside);
        assert_eq!(s.candidate_start, [0, 2, 2, 4]);
        assert_eq!(s.candidates, [0, 2, 1, 2]);
        assert_eq!(s.candidate_gap, [0.1, 0.3, 0.2, 0.0]);
        assert_eq!(s.candidate_outside, [true, true, true, false]);
        assert_eq!(s.inside_start, [0, 1, 1, 2]);
        assert_eq!(s.inside, [1, 2]);
        for i in 0..3 {
            for t in 0..3 {
                assert_eq!(s.rest_gap(i, t), gaps[i * 3 + t], "({i}, {t})");
                assert_eq!(s.outside_at_rest(i, t), outside[i * 3 + t], "({i}, {t})");
            }
        }
        let unset = SlidingContact {
            point: Vec3::ZERO,
            normal: Vec3::ZERO,
            barycentric: Vec3::ZERO,
            target_w: 0.0,
            gap: 0.0,
            triangle: 0,
            target: TargetSlot::NONE,
            outside: true,
        };
        s.contact = vec![unset; 3];
        let chosen = |s: &SlidingBatch, i: usize| {
            let c = s.contact[i];
            (c.target.get(), c.gap, c.outside)
        };
        s.choose(2, Some(2));
        assert_eq!(chosen(&s, 2), (Some(2), 0.0, false));
        s.choose(0, Some(1));
        assert_eq!(chosen(&s, 0), (Some(1), inf, false));
        s.choose(0, None);
        assert_eq!(chosen(&s, 0), (None, inf, true));
    }
}
