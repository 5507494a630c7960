//! Jacobi projection with a deterministic gather (SPEC §9.2).
//!
//! The single-particle constraints — Attach and BranchAttach (the SPEC's
//! Gauss–Seidel constraints), and the target connections Hard, Soft and
//! Sliding — are solved Gauss–Seidel first: each moves one particle toward
//! a goal off the muscle, so they never compete with one another and need
//! no averaging. (Averaged with a vertex's eight or so other constraints, a
//! connection kept an eighth of its pull: P3 under gravity stretched its
//! edges to ×2.3 and folded 17 triangles in its first frames, and never
//! settled.) Every other constraint but Volume then computes its
//! [`Correction`] from the same positions, with each particle's mass split
//! among the `nᵢ` Jacobi constraints that move it (inverse mass `nᵢ wᵢ`);
//! each particle takes the corrections that move it, in a fixed order from
//! a particle → (constraint, slot) incidence list built once, and moves by
//! `ω / nᵢ` times their sum — `ω Σ wᵢ ∇C Δλ` — and each multiplier grows
//! by `ω Δλ`, the impulse its particles took. (With unsplit masses and the
//! whole `Δλ` kept, a compliant constraint's multiplier ran ahead of the
//! position it gave and balanced a force `nᵢ/ω` times too large: T5 held
//! still sagged to edges at ×0.57.) Nothing is accumulated with atomics, so
//! the result is the same for any thread count.

use super::coloring::{
    ConstraintRef, TASK_CONSTRAINTS, commit, constraints_in_order, correction, particles_of,
};
use super::constraint_ref::correction_with_weights;
use crate::constraints::Correction;
use crate::muscle::ConstraintKind;
use crate::muscle::Muscle;
use glam::Vec3;

/// A muscle's Jacobi split, incidence and scratch.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct JacobiState {
    /// Solved Gauss–Seidel, first (the single-particle constraints).
    pub gauss_seidel: Vec<ConstraintRef>,
    /// Solved Jacobi.
    pub jacobi: Vec<ConstraintRef>,
    /// CSR offsets of each particle's incidence entries.
    offsets: Vec<u32>,
    /// `(index into jacobi, slot in its Correction)`, per particle.
    entries: Vec<(u32, u8)>,
    /// One slot per Jacobi constraint.
    corrections: Vec<Option<Correction>>,
    /// Each particle's split inverse mass `nᵢ wᵢ` (scratch, filled per pass).
    split_w: Vec<f32>,
}

impl JacobiState {
    /// Splits `m`'s constraints (but Volume) in `order` and builds the incidence.
    pub fn new(m: &Muscle, order: &[ConstraintKind]) -> Self {
        let (gauss_seidel, jacobi): (Vec<_>, Vec<_>) = constraints_in_order(m, order)
            .into_iter()
            .partition(|c| single_particle(m, c.kind));
        Self::from_parts(m, gauss_seidel, jacobi)
    }

    /// `gauss_seidel` solved first in order, then `jacobi` averaged.
    pub fn from_parts(
        m: &Muscle,
        gauss_seidel: Vec<ConstraintRef>,
        jacobi: Vec<ConstraintRef>,
    ) -> Self {
        let n = m.x.len();
        let mut count = vec![0u32; n + 1];
        for c in &jacobi {
            for p in particles_of(m, *c).iter().flatten() {
                count[p.index() + 1] += 1;
            }
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let offsets = count.clone();
        let mut fill = count;
        let mut entries = vec![(0u32, 0u8); offsets[n] as usize];
        for (j, c) in jacobi.iter().enumerate() {
            for (slot, p) in particles_of(m, *c).iter().enumerate() {
                if let Some(p) = p {
                    let at = &mut fill[p.index()];
                    entries[*at as usize] = (j as u32, slot as u8);
                    *at += 1;
                }
            }
        }
        Self {
            corrections: vec![None; jacobi.len()],
            split_w: Vec::with_capacity(n),
            gauss_seidel,
            jacobi,
            offsets,
            entries,
        }
    }

    /// Jacobi constraints that move particle `p` (its `nᵢ`).
    pub fn degree(&self, p: usize) -> usize {
        (self.offsets[p + 1] - self.offsets[p]) as usize
    }
}

/// Whether `m`'s constraints of `kind` move a single particle toward a goal
/// off the muscle (solved Gauss–Seidel by [`JacobiState::new`]): what
/// their batch says ([`crate::constraints::ConstraintBatch::particles_per_constraint`]).
pub fn single_particle(m: &Muscle, kind: ConstraintKind) -> bool {
    m.constraints
        .batch(kind)
        .is_some_and(|b| b.particles_per_constraint() == 1)
}

/// The position a correction gives particle `p`, from `slot` of it.
fn moved_to(c: &Correction, slot: u8) -> Vec3 {
    c.to[slot as usize]
}

/// One Jacobi iteration of `m` (see the module docs). `parallel` computes the
/// corrections and the gather on the current rayon pool.
pub fn project_jacobi(
    m: &mut Muscle,
    state: &mut JacobiState,
    inv_h2: f32,
    omega: f32,
    parallel: bool,
) {
    use rayon::prelude::*;
    for &c in &state.gauss_seidel {
        if let Some(corr) = correction(m, c, inv_h2) {
            commit(m, c, &corr);
        }
    }
    let offsets = &state.offsets;
    state.split_w.clear();
    state.split_w.extend(m.w.iter().enumerate().map(|(i, &w)| {
        let n = offsets[i + 1] - offsets[i];
        w * n.max(1) as f32
    }));
    {
        let (muscle, split_w): (&Muscle, &[f32]) = (m, &state.split_w);
        let compute = |(slot, c): (&mut Option<Correction>, &ConstraintRef)| {
            *slot = correction_with_weights(muscle, *c, split_w, inv_h2);
        };
        if parallel {
            state
                .corrections
                .par_iter_mut()
                .zip(state.jacobi.par_iter())
                .with_min_len(TASK_CONSTRAINTS)
                .for_each(compute);
        } else {
            state
                .corrections
                .iter_mut()
                .zip(state.jacobi.iter())
                .for_each(compute);
        }
    }
    // Multipliers: each constraint keeps the increment its particles take.
    for (c, corr) in state.jacobi.iter().zip(&state.corrections) {
        if let Some(corr) = corr {
            let lambda_only = Correction {
                count: 0,
                dlambda: omega * corr.dlambda,
                ..*corr
            };
            commit(m, *c, &lambda_only);
        }
    }
    // Gather: particle i moves by ω/nᵢ Σ (its corrections − its position).
    let (offsets, entries, corrections) = (&state.offsets, &state.entries, &state.corrections);
    let gather = |(i, p): (usize, &mut Vec3)| {
        let (a, b) = (offsets[i] as usize, offsets[i + 1] as usize);
        if a == b {
            return;
        }
        let mut sum = Vec3::ZERO;
        for &(j, slot) in &entries[a..b] {
            if let Some(c) = &corrections[j as usize] {
                sum += moved_to(c, slot) - *p;
            }
        }
        *p += sum * (omega / (b - a) as f32);
    };
    if parallel {
        m.p.par_iter_mut()
            .enumerate()
            .with_min_len(TASK_CONSTRAINTS)
            .for_each(gather);
    } else {
        m.p.iter_mut().enumerate().for_each(gather);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin;

    #[test]
    fn incidence_lists_every_particle_of_every_jacobi_constraint_once() {
        let solver = builtin("P3")
            .unwrap()
            .instantiate(std::path::Path::new("."))
            .unwrap();
        for m in solver.muscles() {
            let state = JacobiState::new(m, &ConstraintKind::CANONICAL_ORDER);
            let touches: usize = state
                .jacobi
                .iter()
                .map(|c| particles_of(m, *c).iter().flatten().count())
                .sum();
            assert_eq!(state.entries.len(), touches);
            let degrees: usize = (0..m.x.len()).map(|p| state.degree(p)).sum();
            assert_eq!(degrees, touches);
            assert!(
                state
                    .gauss_seidel
                    .iter()
                    .all(|c| single_particle(m, c.kind))
            );
            assert!(state.jacobi.iter().all(|c| !single_particle(m, c.kind)));
            let counts = m.counts();
            assert_eq!(
                state.gauss_seidel.len() + state.jacobi.len(),
                counts.total() - counts.get(ConstraintKind::Volume)
            );
        }
    }
}
