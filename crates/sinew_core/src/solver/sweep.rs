//! Parallel colour sweeps that write positions in place.
//!
//! A [`SweepPlan`] is what a sweep runs: colours of chunks, each chunk runs
//! of one constraint type, each constraint with the particles it moves.
//! Threads run the chunks of one colour at the same time, each reading and
//! writing only its own constraints' particles and multipliers: no scratch
//! buffer, no serial commit, the same result for any thread count. A colour
//! starts once every chunk of the colour before it has finished: after a
//! join, or — a sweep run by the threads as one team — after a wait on the
//! team's count of finished chunks (`Team`).
//!
//! Rust cannot see that disjointness through `&mut [Vec3]`, so this module —
//! with the prefetch hint of `crate::prefetch` the only one in the crate
//! allowed `unsafe` — hands each thread a
//! [`SharedSlice`], a raw view of the muscle's positions and multipliers.
//! Soundness rests on this module alone:
//!
//! - [`SweepPlan::new`] checks, on the plan's own copy of every constraint's
//!   particles, that no particle and no multiplier is touched by two chunks
//!   of one colour, and that every index is in range for the counts it
//!   records; the plan's fields are private to this module, so nothing can
//!   change them afterwards.
//! - A sweep checks that the muscle still has those counts (positions and
//!   multipliers are the views' lengths), and every access is bounds-checked.
//! - Positions are written only at the plan's particles, and a kernel is
//!   given its particles' positions by value ([`Gathered`]): it cannot read
//!   a particle another thread writes.
//!
//! A plan that no longer fits its muscle (a host retied a constraint) solves
//! the old topology until it is rebuilt — stale, never racy.
#![expect(
    unsafe_code,
    reason = "threads write disjoint entries of one slice; the disjointness is checked here"
)]

use super::coloring::{CHUNK_CONSTRAINTS, TASK_CONSTRAINTS};
use crate::constraints::{BatchFn, ConstraintBatch, Gathered, Particles};
use crate::muscle::{BATCHED_KINDS, ConstraintCounts, ConstraintKind, MuscleLambdas};
use crate::muscle::{Muscle, MuscleConstraints};
use glam::Vec3;
use std::marker::PhantomData;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// One planned constraint: its index in its batch and the particles it
/// moves (what [`ConstraintBatch::particles`] gave when the plan was built).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct PlannedConstraint {
    /// Index in its type's batch.
    pub index: u32,
    /// The particles it moves, padded by repeating the last (`[p, p, p]`
    /// for one).
    pub particles: Particles,
}

/// A run of a chunk's constraints of one type: `ops[start..end]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Segment {
    /// Constraint type of the run.
    pub kind: ConstraintKind,
    /// First op.
    pub start: u32,
    /// One past the last op.
    pub end: u32,
}

/// What a colour sweep runs, checked for disjointness when made (module
/// docs). Chunk `g` (a global chunk index) owns
/// `segments[chunk_segments[g]..chunk_segments[g + 1]]`; colour `c` owns
/// chunks `chunk_colors[c]..chunk_colors[c + 1]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SweepPlan {
    ops: Vec<PlannedConstraint>,
    segments: Vec<Segment>,
    chunk_segments: Vec<u32>,
    chunk_colors: Vec<u32>,
    particles: usize,
    counts: ConstraintCounts,
}

impl SweepPlan {
    /// Checks and keeps a packed plan for a muscle of `particles` particles
    /// and `counts` constraints. Panics when two chunks of a colour share a
    /// particle or a multiplier, or an index is out of range: that is a bug
    /// in the plan's builder, and a sweep must never run it.
    pub(super) fn new(
        ops: Vec<PlannedConstraint>,
        segments: Vec<Segment>,
        chunk_segments: Vec<u32>,
        chunk_colors: Vec<u32>,
        particles: usize,
        counts: ConstraintCounts,
    ) -> Self {
        let plan = Self {
            ops,
            segments,
            chunk_segments,
            chunk_colors,
            particles,
            counts,
        };
        plan.check();
        plan
    }

    fn check(&self) {
        let chunks = self.chunk_segments.len().saturating_sub(1);
        assert!(
            self.chunk_colors.first() == Some(&0)
                && self.chunk_colors.windows(2).all(|w| w[0] <= w[1])
                && self
                    .chunk_colors
                    .last()
                    .is_some_and(|&c| c as usize <= chunks),
            "chunk boundaries of the colours out of order"
        );
        assert!(
            self.chunk_segments.first() == Some(&0)
                && self.chunk_segments.windows(2).all(|w| w[0] <= w[1])
                && self
                    .chunk_segments
                    .last()
                    .is_some_and(|&s| s as usize == self.segments.len()),
            "segment boundaries of the chunks out of order"
        );
        for s in &self.segments {
            assert!(
                s.start <= s.end && s.end as usize <= self.ops.len(),
                "segment out of range"
            );
        }
        // owner[p] / owner of a multiplier: (colour + 1, chunk) of the last
        // chunk that touched it.
        let mut owner = vec![(0u32, 0u32); self.particles];
        let mut lambda_owner: Vec<Vec<(u32, u32)>> = ConstraintKind::CANONICAL_ORDER
            .iter()
            .map(|&k| vec![(0, 0); self.counts.get(k)])
            .collect();
        for c in 0..self.color_count() {
            for k in 0..self.chunk_count(c) {
                let mark = (c as u32 + 1, k as u32);
                for s in self.chunk_segments(c, k) {
                    assert!(s.kind != ConstraintKind::Volume, "Volume is solved apart");
                    for op in self.segment_ops(s) {
                        let l = &mut lambda_owner[s.kind as usize][op.index as usize];
                        assert!(
                            l.0 != mark.0 || l.1 == mark.1,
                            "colour {c}: a multiplier of two chunks"
                        );
                        *l = mark;
                        for p in op.particles {
                            let o = &mut owner[p.index()];
                            assert!(
                                o.0 != mark.0 || o.1 == mark.1,
                                "colour {c}: particle {p} in two chunks"
                            );
                            *o = mark;
                        }
                    }
                }
            }
        }
    }

    /// Number of colours.
    pub fn color_count(&self) -> usize {
        self.chunk_colors.len() - 1
    }

    /// Chunks of colour `c`.
    pub fn chunk_count(&self, c: usize) -> usize {
        (self.chunk_colors[c + 1] - self.chunk_colors[c]) as usize
    }

    /// Constraints colour `c` runs.
    pub fn color_op_count(&self, c: usize) -> usize {
        let first = self.chunk_segments[self.chunk_colors[c] as usize] as usize;
        let last = self.chunk_segments[self.chunk_colors[c + 1] as usize] as usize;
        self.segments[first..last]
            .iter()
            .map(|s| (s.end - s.start) as usize)
            .sum()
    }

    /// Whether colour `c` is worth splitting over threads: more than one
    /// chunk, and at least [`TASK_CONSTRAINTS`] constraints (a smaller
    /// colour costs less on one thread than a fork and a join).
    pub(super) fn splits(&self, c: usize) -> bool {
        self.chunk_count(c) > 1 && self.color_op_count(c) >= TASK_CONSTRAINTS
    }

    /// Constraints the sweeps run (switched-off ones are left out).
    pub fn op_count(&self) -> usize {
        self.ops.len()
    }

    /// Every run of one constraint type, in solve order.
    #[cfg(test)]
    pub(super) fn segments(&self) -> &[Segment] {
        &self.segments
    }

    /// The runs of chunk `k` of colour `c`, in solve order.
    pub(super) fn chunk_segments(&self, c: usize, k: usize) -> &[Segment] {
        let g = self.chunk_colors[c] as usize + k;
        &self.segments[self.chunk_segments[g] as usize..self.chunk_segments[g + 1] as usize]
    }

    /// The constraints of run `s`.
    #[inline]
    pub(super) fn segment_ops(&self, s: &Segment) -> &[PlannedConstraint] {
        &self.ops[s.start as usize..s.end as usize]
    }

    /// Whether `m` has the particle and constraint counts the plan was
    /// checked for (the lengths the sweep's views come from).
    pub(super) fn sized_for(&self, m: &Muscle) -> bool {
        self.particles == m.x.len() && self.counts == m.counts()
    }
}

/// A slice several threads of one sweep write at disjoint indices.
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
    /// # Safety
    /// No other thread writes `i` during the sweep.
    #[inline(always)]
    unsafe fn read(&self, i: usize) -> T {
        assert!(i < self.len);
        // SAFETY: in bounds (checked); no concurrent writer (the caller's contract).
        unsafe { self.ptr.add(i).read() }
    }

    /// Writes index `i`.
    ///
    /// # Safety
    /// No other thread reads or writes `i` during the sweep.
    #[inline(always)]
    unsafe fn write(&self, i: usize, value: T) {
        assert!(i < self.len);
        // SAFETY: in bounds (checked); exclusive to this thread (the caller's contract).
        unsafe { self.ptr.add(i).write(value) }
    }
}

/// The shared state of a sweep run as a team ([`MuscleSweep::run_as_team`]).
#[derive(Default)]
struct Team {
    /// The next chunk to claim, in solve order.
    next: AtomicUsize,
    /// Chunks finished. A chunk waits for this to reach the index of its
    /// colour's first chunk; no chunk of that colour or a later one
    /// finishes before, so it gets there only once every chunk of the
    /// colours before has finished.
    done: AtomicUsize,
    /// A member's chunk panicked: the others stop waiting (the panic
    /// reaches the caller through the fork).
    failed: AtomicBool,
}

impl Team {
    /// The next unclaimed chunk below `chunks`, if any.
    fn claim(&self, chunks: usize) -> Option<usize> {
        let g = self.next.fetch_add(1, Ordering::Relaxed);
        (g < chunks).then_some(g)
    }

    /// Waits until `count` chunks are finished (spinning, then yielding
    /// the core); false when a member failed instead.
    fn wait_for(&self, count: usize) -> bool {
        let mut spins = 0u32;
        // Acquire: pairs with `finished`'s release, so the positions and
        // multipliers those chunks wrote are seen here.
        while self.done.load(Ordering::Acquire) < count {
            if self.failed.load(Ordering::Relaxed) {
                return false;
            }
            if spins < SPINS_BEFORE_YIELD {
                std::hint::spin_loop();
                spins += 1;
            } else {
                std::thread::yield_now();
            }
        }
        true
    }

    /// Counts a chunk as finished, publishing its writes.
    fn finished(&self) {
        self.done.fetch_add(1, Ordering::Release);
    }
}

/// Spins of a team member's wait before it yields its core each turn: a
/// colour's last chunk is a few microseconds of work away.
const SPINS_BEFORE_YIELD: u32 = 64;

/// Marks the team failed if the chunk being run unwinds (dropped only
/// then: it is forgotten after a chunk that returns).
struct ChunkRunning<'a>(&'a AtomicBool);

impl Drop for ChunkRunning<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

/// One muscle during a sweep: shared views of what units write, plain
/// borrows of what they only read.
struct MuscleSweep<'a> {
    p: SharedSlice<'a, Vec3>,
    lambdas: [SharedSlice<'a, f32>; BATCHED_KINDS],
    w: &'a [f32],
    k: &'a MuscleConstraints,
    plan: &'a SweepPlan,
    inv_h2: f32,
}

/// One run of a chunk, handed to the constraint table to get its batch's
/// concrete type ([`MuscleConstraints::with_batch`]).
struct RunSegment<'s, 'a> {
    sweep: &'s MuscleSweep<'a>,
    kind: ConstraintKind,
    ops: &'s [PlannedConstraint],
}

impl BatchFn for RunSegment<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn call<B: ConstraintBatch>(self, batch: &B) {
        self.sweep.run(batch, self.kind, self.ops);
    }
}

impl<'a> MuscleSweep<'a> {
    /// Views of `p` and `lambdas` (taken out of `k`) for `plan`.
    fn new(
        p: &'a mut [Vec3],
        w: &'a [f32],
        k: &'a MuscleConstraints,
        lambdas: &'a mut MuscleLambdas,
        plan: &'a SweepPlan,
        inv_h2: f32,
    ) -> Self {
        assert!(
            p.len() == plan.particles && w.len() == plan.particles,
            "colour plan built for another particle count"
        );
        for (kind, l) in ConstraintKind::CANONICAL_ORDER.iter().zip(lambdas.iter()) {
            assert_eq!(
                l.len(),
                plan.counts.get(*kind),
                "colour plan built for other counts"
            );
        }
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
        for s in self.plan.chunk_segments(color, chunk) {
            let ops = self.plan.segment_ops(s);
            let run = RunSegment {
                sweep: self,
                kind: s.kind,
                ops,
            };
            self.k.with_batch(s.kind, run);
        }
    }

    /// Projects a run of `batch`'s constraints (of type `kind`) one after the
    /// other, writing each correction at once, at the particles the plan
    /// gives.
    #[inline(always)]
    fn run<B: ConstraintBatch>(&self, batch: &B, kind: ConstraintKind, ops: &[PlannedConstraint]) {
        let lambda = &self.lambdas[kind as usize];
        // A constant of `B` once inlined: only the slots it uses are read.
        let count = batch.particles_per_constraint();
        for op in ops {
            let i = op.index as usize;
            // SAFETY: the chunk being run is the only one of its colour that
            // touches these particles and this multiplier (`SweepPlan::check`),
            // and the colours run one after the other (a join between
            // colours, or a team's wait for every chunk before them).
            let (l, at) = unsafe {
                let at = Gathered::from_fn(op.particles, count, |k| (self.p.read(k), self.w[k]));
                (lambda.read(i), at)
            };
            if let Some(c) = batch.correction_of(i, l, at, self.inv_h2) {
                // SAFETY: as above.
                unsafe {
                    lambda.write(i, l + c.dlambda);
                    for (&to, &k) in c.to[..c.count as usize].iter().zip(&op.particles) {
                        self.p.write(k.index(), to);
                    }
                }
            }
        }
    }

    /// Runs every colour of the plan on the pool's threads as one team (see
    /// [`sweep_muscle`]): each member claims the next chunk in solve order
    /// from a shared cursor and waits, spinning, until every chunk of the
    /// colours before that chunk's colour is done, then runs it. A chunk
    /// is claimed by one member only, claims go in order, and a claimed
    /// chunk is always being run, so the wait always ends. Members that
    /// start late (a thread finishing another muscle first) find the
    /// cursor further on, or past the end.
    fn run_as_team(&self) {
        use rayon::prelude::*;
        let bounds = self.plan.chunk_colors.as_slice();
        let chunks = bounds.last().map_or(0, |&c| c as usize);
        let team = Team::default();
        (0..rayon::current_num_threads())
            .into_par_iter()
            .with_max_len(1)
            .for_each(|_| {
                let mut color = 0;
                while let Some(g) = team.claim(chunks) {
                    while bounds[color + 1] as usize <= g {
                        color += 1;
                    }
                    let first = bounds[color] as usize;
                    if !team.wait_for(first) {
                        return;
                    }
                    let running = ChunkRunning(&team.failed);
                    self.run_chunk(color, g - first);
                    std::mem::forget(running);
                    team.finished();
                }
            });
    }

    /// Runs colour `color`, its chunks in parallel when `parallel` and the
    /// colour is worth splitting ([`SweepPlan::splits`]): a task takes
    /// one chunk when the colour has no more chunks than threads, else up
    /// to [`TASK_CONSTRAINTS`] worth of them.
    fn run_color(&self, color: usize, parallel: bool) {
        use rayon::prelude::*;
        let chunks = self.plan.chunk_count(color);
        if parallel && self.plan.splits(color) {
            let most = TASK_CONSTRAINTS / CHUNK_CONSTRAINTS;
            let per_task = (chunks / rayon::current_num_threads()).clamp(1, most);
            (0..chunks)
                .into_par_iter()
                .with_min_len(per_task)
                .for_each(|k| self.run_chunk(color, k));
        } else {
            (0..chunks).for_each(|k| self.run_chunk(color, k));
        }
    }
}

/// Runs every colour of `plan` on `m` (the Jacobi tail apart): colour by
/// colour, each split over the threads when `parallel` and big enough
/// ([`MuscleSweep::run_color`]), or — when the colours would give each of
/// the pool's threads less than [`TASK_CONSTRAINTS`] apiece
/// ([`runs_as_team`]) — by the threads as one team
/// ([`MuscleSweep::run_as_team`]): one fork for the whole sweep, each
/// colour's start a wait on a counter instead of a fork and a join of its
/// own. Either way each chunk runs the same constraints in the same order,
/// after the same colours: the same bits.
pub(super) fn sweep_muscle(m: &mut Muscle, plan: &SweepPlan, inv_h2: f32, parallel: bool) {
    assert!(plan.sized_for(m), "colour plan built for another topology");
    let mut lambdas = m.constraints.take_lambdas();
    {
        let sweep = MuscleSweep::new(&mut m.p, &m.w, &m.constraints, &mut lambdas, plan, inv_h2);
        if parallel && runs_as_team(plan, rayon::current_num_threads()) {
            sweep.run_as_team();
        } else {
            for color in 0..plan.color_count() {
                sweep.run_color(color, parallel);
            }
        }
    }
    m.constraints.restore_lambdas(lambdas);
}

/// Whether a sweep of `plan` on `threads` threads runs as one team: it
/// has a colour worth splitting ([`SweepPlan::splits`]), and its colours hold on average less than
/// [`TASK_CONSTRAINTS`] per thread, so a fork and a join for each colour
/// would cost about as much as the colour's work on each thread. The
/// fitted MakeHuman's skin (about 90 000 constraints in 23 colours) runs
/// as a team from 4 threads up: on a 16-core Xeon its frame took ×0.92–0.95
/// with the team (three interleaved pairs), while on 2 threads the team
/// was slower (×1.07, the median of six pairs here), the threads waiting
/// at every colour for each other instead of taking other work.
pub(super) fn runs_as_team(plan: &SweepPlan, threads: usize) -> bool {
    let colors = plan.color_count();
    threads > 1
        && (0..colors).any(|c| plan.splits(c))
        && plan.op_count() < TASK_CONSTRAINTS * colors * threads
}

/// Runs colour `color` of `plan` on `m`, its chunks in parallel on the
/// current rayon pool: one muscle's share of a sweep across muscles (SPEC
/// §9.3, global scope). Nothing for a colour `plan` does not have.
pub(super) fn sweep_color(m: &mut Muscle, plan: &SweepPlan, color: usize, inv_h2: f32) {
    if color >= plan.color_count() {
        return;
    }
    assert!(plan.sized_for(m), "colour plan built for another topology");
    let mut lambdas = m.constraints.take_lambdas();
    MuscleSweep::new(&mut m.p, &m.w, &m.constraints, &mut lambdas, plan, inv_h2)
        .run_color(color, true);
    m.constraints.restore_lambdas(lambdas);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constraints::ParticleId;

    fn counts(fiber: usize) -> ConstraintCounts {
        let mut c = ConstraintCounts::default();
        c.0[ConstraintKind::Fiber as usize] = fiber;
        c
    }

    fn fiber(index: u32, [a, b]: [u32; 2]) -> PlannedConstraint {
        PlannedConstraint {
            index,
            particles: [a, b, b].map(ParticleId::new),
        }
    }

    /// Two chunks of one colour, one op each.
    fn plan(a: [u32; 2], b: [u32; 2]) -> SweepPlan {
        let segment = |start| Segment {
            kind: ConstraintKind::Fiber,
            start,
            end: start + 1,
        };
        SweepPlan::new(
            vec![fiber(0, a), fiber(1, b)],
            vec![segment(0), segment(1)],
            vec![0, 1, 2],
            vec![0, 2],
            4,
            counts(2),
        )
    }

    #[test]
    fn chunks_of_a_colour_on_disjoint_particles_are_accepted() {
        let p = plan([0, 1], [2, 3]);
        assert_eq!((p.color_count(), p.chunk_count(0), p.op_count()), (1, 2, 2));
    }

    #[test]
    #[should_panic(expected = "particle 1 in two chunks")]
    fn chunks_of_a_colour_sharing_a_particle_are_refused() {
        plan([0, 1], [1, 2]);
    }

    #[test]
    #[should_panic]
    fn a_particle_out_of_range_is_refused() {
        plan([0, 1], [2, 9]);
    }
}
