//! Distance constraints ordered in runs that share no particle.
//!
//! A Gauss–Seidel pass projects one constraint after another, each reading
//! what the one before wrote. When consecutive constraints share a
//! particle, the processor waits for each projection (a square root and two
//! divisions deep) before it can start the next; when they share none, it
//! overlaps several. [`DistanceBatch::arrange_in_runs`] finds an order in
//! runs of up to [`RUN`] constraints that share no particle, taking the
//! constraints in their order into the first of [`OPEN_RUNS`] open runs
//! that has none of their particles, so that a run holds constraints lying
//! close in the batch (and in memory), and puts the batch itself in that
//! order: every per-constraint array is permuted, so that a pass reads
//! them front to back. The batch remembers the order its constraints were
//! created in ([`DistanceBatch::creation_order`]), which the colour plans,
//! Jacobi and Hybrid read (their colourings, and so their results, are
//! those of the batch in creation order).
//!
//! A lane kernel (the eight constraints of a run projected side by side,
//! packed square roots and divisions, the same bits) was measured too, and
//! is not used: gathering each lane's positions from the particles' `Vec3`
//! array and scattering them back cost more than the packed arithmetic
//! saved (T7's step 5–8 % slower than the same order one at a time).

use super::distance::project_pair;
use super::{ConstraintBatch, DistanceBatch};
use glam::Vec3;
use std::collections::VecDeque;

/// Most constraints in one run.
pub const RUN: usize = 8;

/// Runs open at once while [`DistanceBatch::arrange_in_runs`] fills them:
/// how far apart in the batch two constraints of one run can lie.
pub const OPEN_RUNS: usize = 16;

impl DistanceBatch {
    /// Puts the constraints in an order for Gauss–Seidel in runs of up to
    /// [`RUN`] that share no particle: each constraint, in the batch's
    /// order, goes into the first of [`OPEN_RUNS`] open runs that has none
    /// of its particles; with none, a new run opens (the oldest one
    /// closing, short, when there are [`OPEN_RUNS`]). A run closes when
    /// full. Every per-constraint array is permuted, and
    /// [`DistanceBatch::creation_order`] keeps where each constraint went.
    /// Returns where each run starts in the new order, and the batch's
    /// length.
    pub fn arrange_in_runs(&mut self) -> Vec<u32> {
        let mut open: VecDeque<Vec<u32>> = VecDeque::with_capacity(OPEN_RUNS);
        let mut closed: Vec<Vec<u32>> = Vec::with_capacity(self.len().div_ceil(RUN));
        for i in 0..self.len() {
            let (a, b) = (self.a[i], self.b[i]);
            let free = |run: &Vec<u32>| {
                run.iter().all(|&k| {
                    let (ka, kb) = (self.a[k as usize], self.b[k as usize]);
                    ka != a && ka != b && kb != a && kb != b
                })
            };
            match open.iter().position(free) {
                Some(r) => {
                    open[r].push(i as u32);
                    if open[r].len() == RUN {
                        closed.extend(open.remove(r));
                    }
                }
                None => {
                    if open.len() == OPEN_RUNS {
                        closed.extend(open.pop_front());
                    }
                    open.push_back(vec![i as u32]);
                }
            }
        }
        closed.extend(open);
        let order: Vec<u32> = closed.iter().flatten().copied().collect();
        // Where each constraint goes, and so where each created one is.
        let mut position = vec![0u32; order.len()];
        for (k, &i) in order.iter().enumerate() {
            position[i as usize] = k as u32;
        }
        self.creation_order = match ConstraintBatch::creation_order(self) {
            [] => position,
            created => created.iter().map(|&i| position[i as usize]).collect(),
        };
        self.permute(&order);
        std::iter::once(0)
            .chain(closed.iter().scan(0u32, |end, run| {
                *end += run.len() as u32;
                Some(*end)
            }))
            .collect()
    }

    /// Puts the constraints back in the order they were created (undoing
    /// [`DistanceBatch::arrange_in_runs`]): Gauss–Seidel then projects them
    /// in that order.
    pub fn in_creation_order(&mut self) {
        let created = std::mem::take(&mut self.creation_order);
        if created.len() == self.len() {
            self.permute(&created);
        }
    }

    /// One Gauss–Seidel pass in the batch's order (runs, once
    /// [`DistanceBatch::arrange_in_runs`] has put it in them):
    /// [`project_pair`] on each constraint, written at once. The same bits
    /// as projecting each with [`super::ConstraintBatch::correction`] and
    /// committing it; written out here so that each constraint's particle
    /// indices are read once and the arrays' bounds checked once per index
    /// (the generic path re-read both indices after writing the
    /// multiplier: ×0.9 of T7's instructions in this loop, see
    /// ARCHITECTURE.md).
    pub(super) fn solve_in_order(&mut self, p: &mut [Vec3], w: &[f32], inv_dt2: f32) {
        let alpha = self.compliance * inv_dt2;
        let n = self.len();
        let (a, b, rest) = (&self.a[..n], &self.b[..n], &self.rest[..n]);
        let lambda = &mut self.lambda[..n];
        let particles = p.len().min(w.len());
        let (p, w) = (&mut p[..particles], &w[..particles]);
        for i in 0..n {
            let (ia, ib) = (a[i].index(), b[i].index());
            let (at, inverse_mass) = ([p[ia], p[ib]], [w[ia], w[ib]]);
            if let Some((dl, to_a, to_b)) =
                project_pair(at, inverse_mass, rest[i], lambda[i], alpha)
            {
                lambda[i] += dl;
                p[ia] = to_a;
                p[ib] = to_b;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constraints::{ConstraintBatch, ParticleId};
    use std::collections::HashSet;

    /// A ring of `n` particles with every chord to the next three, in an
    /// order where each constraint shares a particle with the one before,
    /// and positions off their rest lengths.
    fn tangled(n: usize) -> (DistanceBatch, Vec<Vec3>, Vec<f32>) {
        let mut batch = DistanceBatch {
            compliance: 1e-6,
            ..Default::default()
        };
        for step in 1..=3 {
            for i in 0..n {
                let (a, b) = (i, (i + step) % n);
                let id = ParticleId::from_index;
                batch.push(id(a), id(b), 0.1 * step as f32);
            }
        }
        let p = (0..n)
            .map(|i| {
                let t = i as f32 * 0.7;
                Vec3::new(t.cos(), t.sin(), 0.01 * i as f32)
            })
            .collect();
        let w = (0..n).map(|i| if i % 7 == 0 { 0.0 } else { 1.0 }).collect();
        (batch, p, w)
    }

    /// The pairs and rest lengths of a batch's constraints, in creation
    /// order.
    fn created(batch: &DistanceBatch) -> Vec<(ParticleId, ParticleId, u32)> {
        let at = |i: usize| (batch.a[i], batch.b[i], batch.rest[i].to_bits());
        match ConstraintBatch::creation_order(batch) {
            [] => (0..batch.len()).map(at).collect(),
            order => order.iter().map(|&i| at(i as usize)).collect(),
        }
    }

    #[test]
    fn runs_are_full_share_no_particle_and_hold_every_constraint_once() {
        let (mut batch, _, _) = tangled(40);
        let before = batch.clone();
        let runs = batch.arrange_in_runs();
        assert_eq!(*runs.last().unwrap() as usize, batch.len());
        let full = runs
            .windows(2)
            .filter(|r| r[1] - r[0] == RUN as u32)
            .count();
        assert!(full * RUN * 10 >= batch.len() * 9, "{full} full runs");
        for run in runs.windows(2) {
            let mut seen = HashSet::new();
            for i in run[0] as usize..run[1] as usize {
                assert!(seen.insert(batch.a[i]) && seen.insert(batch.b[i]));
            }
        }
        // Every constraint once, found where the creation order says.
        assert_ne!(batch.a, before.a);
        assert_eq!(created(&batch), created(&before));
        let mut sorted = batch.creation_order.clone();
        sorted.sort_unstable();
        assert!(sorted.iter().enumerate().all(|(k, &i)| k == i as usize));
        // Arranged again, the creation order follows.
        batch.arrange_in_runs();
        assert_eq!(created(&batch), created(&before));
        // And put back, the batch is the one created.
        batch.in_creation_order();
        assert_eq!(batch, before);
    }

    #[test]
    fn a_pass_follows_the_batch_order() {
        let (mut batch, p0, w) = tangled(40);
        let mut in_creation_order = batch.clone();
        batch.arrange_in_runs();
        // By hand: the constraints one at a time in the batch's order.
        let by_hand = |batch: &DistanceBatch| {
            let (mut batch, mut p) = (batch.clone(), p0.clone());
            for i in 0..batch.len() {
                if let Some(c) = batch.correction(i, &p, &w, 3600.0) {
                    batch.commit(i, &c, &mut p);
                }
            }
            (p, batch.lambda)
        };
        let (p_hand, lambda_hand) = by_hand(&batch);
        let mut p = p0.clone();
        batch.solve(&mut p, &w, 3600.0);
        assert_eq!(p, p_hand);
        assert_eq!(batch.lambda, lambda_hand);
        // And not what the creation order gives, which is its own by hand.
        let (p_hand, lambda_hand) = by_hand(&in_creation_order);
        let mut p_created = p0.clone();
        in_creation_order.solve(&mut p_created, &w, 3600.0);
        assert_ne!(p, p_created);
        assert_eq!(p_created, p_hand);
        assert_eq!(in_creation_order.lambda, lambda_hand);
    }

    /// The rest lengths activation gives follow the constraints they
    /// belong to into the runs, to the bit.
    #[test]
    fn activation_rest_lengths_follow_their_constraints() {
        use crate::constraints::{ActivationRest, ActivationScale, FiberMode};
        let (mut batch, p, _) = tangled(24);
        let mut act = ActivationRest::default();
        for i in 0..batch.len() {
            let edge = p[batch.a[i].index()] - p[batch.b[i].index()];
            let fiber = Vec3::new(1.0, 0.2 * i as f32, 0.1).normalize();
            act.push(edge, fiber);
        }
        act.contractile = (0..batch.len()).map(|i| (i % 5) as f32 / 4.0).collect();
        batch.activation = Some(act);
        let mut arranged = batch.clone();
        arranged.arrange_in_runs();
        let scale = ActivationScale::new(0.8, 0.1, 0.5, Some(1.3));
        for mode in [FiberMode::RotationInvariant, FiberMode::PaperExact] {
            batch.update_rest(mode, &scale);
            arranged.update_rest(mode, &scale);
            assert_eq!(created(&arranged), created(&batch), "{mode:?}");
        }
    }

    #[test]
    fn a_pushed_constraint_comes_last_in_both_orders() {
        let (mut batch, _, _) = tangled(16);
        batch.arrange_in_runs();
        let (a, b) = (ParticleId::from_index(0), ParticleId::from_index(1));
        batch.push(a, b, 0.05);
        let n = batch.len();
        assert_eq!(batch.creation_order.len(), n);
        assert_eq!(batch.creation_order[n - 1] as usize, n - 1);
        assert_eq!((batch.a[n - 1], batch.b[n - 1]), (a, b));
        assert_eq!(created(&batch).last(), Some(&(a, b, 0.05f32.to_bits())));
    }
}
