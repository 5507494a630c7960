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
//! close in the batch (and in memory), and keeps it as the batch's
//! Gauss–Seidel order ([`DistanceBatch::solve_order`]); the batch itself
//! stays in mesh order, which the colour plans, Jacobi and Hybrid read as
//! before (their colourings, and so their results, are unchanged).
//!
//! A lane kernel (the eight constraints of a run projected side by side,
//! packed square roots and divisions, the same bits) was measured too, and
//! is not used: gathering each lane's positions from the particles' `Vec3`
//! array and scattering them back cost more than the packed arithmetic
//! saved (T7's step 5–8 % slower than the same order one at a time).

use super::DistanceBatch;
use super::distance::project_pair;
use glam::Vec3;
use std::collections::VecDeque;

/// Most constraints in one run.
pub const RUN: usize = 8;

/// Runs open at once while [`DistanceBatch::arrange_in_runs`] fills them:
/// how far apart in the batch two constraints of one run can lie.
pub const OPEN_RUNS: usize = 16;

impl DistanceBatch {
    /// Orders the constraints for Gauss–Seidel in runs of up to [`RUN`]
    /// that share no particle, into [`DistanceBatch::solve_order`]: each
    /// constraint, in the batch's order, goes into the first of
    /// [`OPEN_RUNS`] open runs that has none of its particles; with none, a
    /// new run opens (the oldest one closing, short, when there are
    /// [`OPEN_RUNS`]). A run closes when full. Returns where each run
    /// starts in that order, and the batch's length. Pushing a constraint
    /// drops the order (the batch's own order is used); call it again.
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
        self.solve_order = closed.iter().flatten().copied().collect();
        std::iter::once(0)
            .chain(closed.iter().scan(0u32, |end, run| {
                *end += run.len() as u32;
                Some(*end)
            }))
            .collect()
    }

    /// One Gauss–Seidel pass in [`DistanceBatch::solve_order`] (the
    /// batch's order when it is not set): [`project_pair`] on each
    /// constraint, written at once. The same bits as projecting each with
    /// [`super::ConstraintBatch::correction`] and committing it; written out here
    /// so that each constraint's particle indices are read once and the
    /// arrays' bounds checked once per index (the generic path re-read
    /// both indices after writing the multiplier: ×0.9 of T7's
    /// instructions in this loop, see ARCHITECTURE.md).
    pub(super) fn solve_in_order(&mut self, p: &mut [Vec3], w: &[f32], inv_dt2: f32) {
        let alpha = self.compliance * inv_dt2;
        match self.solve_order.len() == self.len() {
            true => {
                let order = std::mem::take(&mut self.solve_order);
                self.pass(order.iter().map(|&i| i as usize), p, w, alpha);
                self.solve_order = order;
            }
            false => self.pass(0..self.len(), p, w, alpha),
        }
    }

    /// [`project_pair`] on the constraints `indices` gives, in that order,
    /// each written at once; `alpha` is the compliance ÷ h².
    #[inline(always)]
    fn pass(
        &mut self,
        indices: impl Iterator<Item = usize>,
        p: &mut [Vec3],
        w: &[f32],
        alpha: f32,
    ) {
        let n = self.len();
        let (a, b, rest) = (&self.a[..n], &self.b[..n], &self.rest[..n]);
        let lambda = &mut self.lambda[..n];
        let particles = p.len().min(w.len());
        let (p, w) = (&mut p[..particles], &w[..particles]);
        for i in indices {
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

    #[test]
    fn runs_are_full_share_no_particle_and_hold_every_constraint_once() {
        let (mut batch, _, _) = tangled(40);
        let runs = batch.arrange_in_runs();
        let order = &batch.solve_order;
        assert_eq!(*runs.last().unwrap() as usize, batch.len());
        let full = runs
            .windows(2)
            .filter(|r| r[1] - r[0] == RUN as u32)
            .count();
        assert!(full * RUN * 10 >= batch.len() * 9, "{full} full runs");
        for run in runs.windows(2) {
            let mut seen = HashSet::new();
            for &i in &order[run[0] as usize..run[1] as usize] {
                let i = i as usize;
                assert!(seen.insert(batch.a[i]) && seen.insert(batch.b[i]));
            }
        }
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert!(sorted.iter().enumerate().all(|(k, &i)| k == i as usize));
    }

    #[test]
    fn a_pass_follows_the_solve_order() {
        let (mut batch, p0, w) = tangled(40);
        batch.arrange_in_runs();
        assert_ne!(
            batch.solve_order,
            (0..batch.len() as u32).collect::<Vec<_>>()
        );
        // By hand: the constraints one at a time in the solve order.
        let mut by_hand = batch.clone();
        let mut p_hand = p0.clone();
        for k in 0..by_hand.len() {
            let i = by_hand.solve_order[k] as usize;
            if let Some(c) = by_hand.correction(i, &p_hand, &w, 3600.0) {
                by_hand.commit(i, &c, &mut p_hand);
            }
        }
        let mut p = p0.clone();
        batch.solve(&mut p, &w, 3600.0);
        assert_eq!(p, p_hand);
        assert_eq!(batch.lambda, by_hand.lambda);
        // And not what the batch's own order gives.
        let mut in_batch_order = DistanceBatch {
            solve_order: Vec::new(),
            ..batch.clone()
        };
        in_batch_order.lambda.fill(0.0);
        let mut p_batch = p0.clone();
        in_batch_order.solve(&mut p_batch, &w, 3600.0);
        assert_ne!(p, p_batch);
        // Which is, by hand, the constraints one at a time in the batch's order.
        let mut by_hand = DistanceBatch {
            solve_order: Vec::new(),
            ..batch.clone()
        };
        by_hand.lambda.fill(0.0);
        let mut p_hand = p0.clone();
        for i in 0..by_hand.len() {
            if let Some(c) = by_hand.correction(i, &p_hand, &w, 3600.0) {
                by_hand.commit(i, &c, &mut p_hand);
            }
        }
        assert_eq!(p_batch, p_hand);
        assert_eq!(in_batch_order.lambda, by_hand.lambda);
    }

    #[test]
    fn pushing_a_constraint_drops_the_order() {
        let (mut batch, _, _) = tangled(16);
        batch.arrange_in_runs();
        batch.push(ParticleId::from_index(0), ParticleId::from_index(1), 0.05);
        assert!(batch.solve_order.is_empty());
    }
}
