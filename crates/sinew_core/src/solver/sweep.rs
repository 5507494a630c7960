//! Parallel colour sweeps that write positions in place.
//!
//! A [`ColorPlan`] colour is a set of units that share no particle, and
//! every constraint is in one unit (its constructor checks both). Threads
//! can therefore run the units of one colour at the same time, each reading
//! and writing only its own particles and its own constraints' multipliers:
//! there is no race, no scratch buffer and no serial commit, and the result
//! is the same for any thread count.
//!
//! Rust cannot see that disjointness through `&mut [Vec3]`, so this module —
//! the only one in the crate allowed `unsafe` — hands each thread a
//! [`SharedSlice`]: a raw view of the muscle's positions and multipliers.
//! The views never leave this module and every access is bounds-checked.
//! Positions are written only at the particles the plan holds for each
//! constraint (its own copy, the one its constructor checked), and each
//! multiplier belongs to one planned constraint, so no muscle edit can make
//! two threads write one place: a plan that no longer fits its muscle
//! ([`ColorPlan::fits`], checked in the first iteration of every substep)
//! solves the old topology until it is rebuilt, and the sweeps re-check the
//! counts the views' lengths come from.
#![allow(unsafe_code)]

use super::coloring::{ColorPlan, PlannedConstraint};
use crate::constraints::{ConstraintBatch, ConstraintKind, MuscleLambdas, Particles};
use crate::muscle::{Muscle, MuscleConstraints};
use glam::Vec3;
use std::marker::PhantomData;

/// A slice several threads write at disjoint indices.
struct SharedSlice<'a, T> {
    ptr: *mut T,
    len: usize,
    _borrow: PhantomData<&'a mut [T]>,
}

// SAFETY: a `SharedSlice` is an exclusive borrow shared between the threads
// of one sweep; they touch disjoint indices (see the module docs).
unsafe impl<T: Send> Send for SharedSlice<'_, T> {}
// SAFETY: as above.
unsafe impl<T: Send> Sync for SharedSlice<'_, T> {}

impl<'a, T: Copy> SharedSlice<'a, T> {
    fn new(slice: &'a mut [T]) -> Self {
        Self {
            ptr: slice.as_mut_ptr(),
            len: slice.len(),
            _borrow: PhantomData,
        }
    }

    /// Reads index `i`.
    ///
    /// Callers guarantee no other thread writes `i` during the sweep.
    #[inline(always)]
    fn read(&self, i: usize) -> T {
        assert!(i < self.len);
        // SAFETY: in bounds (checked); no concurrent writer (module invariant).
        unsafe { self.ptr.add(i).read() }
    }

    /// Writes index `i`.
    ///
    /// Callers guarantee no other thread reads or writes `i` during the sweep.
    #[inline(always)]
    fn write(&self, i: usize, value: T) {
        assert!(i < self.len);
        // SAFETY: in bounds (checked); exclusive to this thread (module invariant).
        unsafe { self.ptr.add(i).write(value) }
    }
}

impl Particles for SharedSlice<'_, Vec3> {
    #[inline(always)]
    fn at(&self, i: usize) -> Vec3 {
        self.read(i)
    }
}

/// One muscle during a sweep: shared views of what units write, plain
/// borrows of what they only read.
struct MuscleSweep<'a> {
    p: SharedSlice<'a, Vec3>,
    lambdas: [SharedSlice<'a, f32>; 8],
    w: &'a [f32],
    k: &'a MuscleConstraints,
    plan: &'a ColorPlan,
    inv_h2: f32,
}

impl<'a> MuscleSweep<'a> {
    /// Views of `p` and `lambdas` (taken out of `k`) for `plan`, which must fit.
    fn new(
        p: &'a mut [Vec3],
        w: &'a [f32],
        k: &'a MuscleConstraints,
        lambdas: &'a mut MuscleLambdas,
        plan: &'a ColorPlan,
        inv_h2: f32,
    ) -> Self {
        Self {
            p: SharedSlice::new(p),
            lambdas: lambdas
                .each_mut()
                .map(|l| SharedSlice::new(l.as_mut_slice())),
            w,
            k,
            plan,
            inv_h2,
        }
    }

    /// Runs chunk `chunk` of colour `color`: its runs of one constraint
    /// type one after the other.
    fn run_chunk(&self, color: usize, chunk: usize) {
        let k = self.k;
        for s in self.plan.chunk_segments(color, chunk) {
            let ops = self.plan.segment_ops(s);
            match s.kind {
                ConstraintKind::Attach => self.run(&k.attach, s.kind, ops),
                ConstraintKind::BranchAttach => self.run(&k.branch_attach, s.kind, ops),
                ConstraintKind::Hard => self.run(&k.hard, s.kind, ops),
                ConstraintKind::Soft => self.run(&k.soft, s.kind, ops),
                ConstraintKind::Sliding => self.run(&k.sliding, s.kind, ops),
                ConstraintKind::Branch => self.run(&k.branch, s.kind, ops),
                ConstraintKind::Internal => self.run(&k.internal, s.kind, ops),
                ConstraintKind::Fiber => self.run(&k.fiber, s.kind, ops),
                ConstraintKind::Volume => {}
            }
        }
    }

    /// Projects a run of `batch`'s constraints (of type `kind`) one after the
    /// other, writing each correction at once. Positions are written only at
    /// the particles the plan gives (the kernel moves exactly those, in
    /// order), so the plan's disjointness is what the writes rely on.
    #[inline(always)]
    fn run<B: ConstraintBatch>(&self, batch: &B, kind: ConstraintKind, ops: &[PlannedConstraint]) {
        let (p, w, h) = (&self.p, self.w, self.inv_h2);
        let lambda = &self.lambdas[kind as usize];
        for op in ops {
            let i = op.index as usize;
            let l = lambda.read(i);
            if let Some(c) = batch.correction_with(i, op.particles, l, p, w, h) {
                lambda.write(i, l + c.dlambda);
                for (&(moved, to), &particle) in
                    c.moves[..c.count as usize].iter().zip(&op.particles)
                {
                    debug_assert_eq!(moved, particle);
                    p.write(particle as usize, to);
                }
            }
        }
    }

    /// Runs colour `color`, its chunks in parallel when `parallel`.
    fn run_color(&self, color: usize, parallel: bool) {
        use rayon::prelude::*;
        let chunks = self.plan.chunk_count(color);
        if parallel && chunks > 1 {
            (0..chunks)
                .into_par_iter()
                .for_each(|k| self.run_chunk(color, k));
        } else {
            (0..chunks).for_each(|k| self.run_chunk(color, k));
        }
    }
}

/// Runs every colour of `plan` on `m` (the Jacobi tail apart).
pub(super) fn sweep_muscle(m: &mut Muscle, plan: &ColorPlan, inv_h2: f32, parallel: bool) {
    assert!(plan.sized_for(m), "colour plan built for another topology");
    let mut lambdas = m.constraints.take_lambdas();
    {
        let sweep = MuscleSweep::new(&mut m.p, &m.w, &m.constraints, &mut lambdas, plan, inv_h2);
        for color in 0..plan.color_count() {
            sweep.run_color(color, parallel);
        }
    }
    m.constraints.restore_lambdas(lambdas);
}

/// Runs colour `c` of every muscle in one parallel sweep, for `c` up to the
/// largest colour count (SPEC §9.3, global scope): `plans[i]` is muscle
/// `i`'s plan, `None` for a muscle that sits this iteration out. Each sweep
/// splits into (muscle, chunk) tasks on the current rayon pool, so a large
/// muscle spreads over threads and small ones share them.
pub(super) fn sweep_global(muscles: &mut [Muscle], plans: &[Option<ColorPlan>], inv_h2: f32) {
    use rayon::prelude::*;
    let mut lambdas: Vec<Option<MuscleLambdas>> = muscles
        .iter_mut()
        .zip(plans)
        .map(|(m, plan)| {
            plan.as_ref().map(|plan| {
                assert!(plan.sized_for(m), "colour plan built for another topology");
                m.constraints.take_lambdas()
            })
        })
        .collect();
    {
        let sweeps: Vec<Option<MuscleSweep>> = muscles
            .iter_mut()
            .zip(plans)
            .zip(lambdas.iter_mut())
            .map(|((m, plan), l)| match (plan, l) {
                (Some(plan), Some(l)) => Some(MuscleSweep::new(
                    &mut m.p,
                    &m.w,
                    &m.constraints,
                    l,
                    plan,
                    inv_h2,
                )),
                _ => None,
            })
            .collect();
        let colors = plans
            .iter()
            .flatten()
            .map(ColorPlan::color_count)
            .max()
            .unwrap_or(0);
        let mut tasks: Vec<(usize, usize)> = Vec::new();
        for color in 0..colors {
            tasks.clear();
            for (i, s) in sweeps.iter().enumerate() {
                if let Some(s) = s.as_ref().filter(|s| color < s.plan.color_count()) {
                    tasks.extend((0..s.plan.chunk_count(color)).map(|k| (i, k)));
                }
            }
            tasks.par_iter().for_each(|&(i, k)| {
                if let Some(s) = &sweeps[i] {
                    s.run_chunk(color, k);
                }
            });
        }
    }
    for (m, l) in muscles.iter_mut().zip(lambdas) {
        if let Some(l) = l {
            m.constraints.restore_lambdas(l);
        }
    }
}
