//! A driver's threads: its worker pool, the buffer its passes borrow the
//! muscles through, the pass that runs muscle by muscle, and the choice
//! between sweeping by muscle and by colour.

use super::coloring::ColorPlan;
use super::params::FrameParams;
use super::settings::SweepSchedule;
use super::workspace::MuscleWorkspace;
use crate::muscle::Muscle;
use std::alloc::Layout;
use std::sync::Arc;

/// One muscle as a driver hands it to a pass: its model and the solver's
/// workspace for it.
pub type MusclePair<'a> = (&'a mut Muscle, &'a mut MuscleWorkspace);

/// The worker threads of a driver: none for `threads == 1`, else a rayon
/// pool of `threads` workers (`0`: one per core) that runs every parallel
/// part of a step — muscles, and the chunks inside a large muscle.
#[derive(Debug, Default)]
pub struct WorkerPool {
    pool: Option<(u32, Arc<rayon::ThreadPool>)>,
}

/// A clone has no threads until its first [`WorkerPool::sync`].
impl Clone for WorkerPool {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl WorkerPool {
    /// Makes the pool match `threads`, reusing it when it already has that
    /// count. A pool that cannot be built leaves the driver on its own
    /// thread (the same result, only slower).
    pub fn sync(&mut self, threads: u32) {
        if threads == 1 {
            self.pool = None;
            return;
        }
        if self.pool.as_ref().is_some_and(|(n, _)| *n == threads) {
            return;
        }
        self.pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads as usize)
            .thread_name(|i| format!("sinew-{i}"))
            .build()
            .ok()
            .map(|p| {
                // Every worker takes one job now, so that each registers
                // with the work-stealing queues' memory reclamation here
                // and not, allocating, in the first step it steals in.
                p.broadcast(|_| ());
                (threads, Arc::new(p))
            });
    }

    /// The threads, as a handle a driver can hold while it lends itself
    /// out: it runs a whole step on them ([`rayon::ThreadPool::install`]),
    /// so that every pass inside reaches the workers with no cross-thread
    /// hand-off (a wake-up and one job-queue slot each).
    pub fn threads(&self) -> Option<Arc<rayon::ThreadPool>> {
        self.pool.as_ref().map(|(_, p)| Arc::clone(p))
    }

    /// Whether there are worker threads.
    pub fn is_some(&self) -> bool {
        self.pool.is_some()
    }

    /// The pool, when `wanted` (a [`super::Parallelism`] flag) and there is one.
    pub fn when(&self, wanted: bool) -> Option<&rayon::ThreadPool> {
        self.pool.as_ref().filter(|_| wanted).map(|(_, p)| &**p)
    }
}

/// Storage kept between steps for a list of borrows that lives for one
/// pass (a [`MusclePair`] per muscle, a reference per target): `T` is the
/// list's item type with `'static` lifetimes, [`BorrowBuffer::with`] fills it
/// with the pass's own. After the first step no pass allocates.
#[derive(Debug)]
pub struct BorrowBuffer<T>(Vec<T>);

impl<T> Default for BorrowBuffer<T> {
    fn default() -> Self {
        Self(Vec::new())
    }
}

/// A clone starts with no storage (the buffer is empty between passes).
impl<T> Clone for BorrowBuffer<T> {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl<T> BorrowBuffer<T> {
    /// Runs `f` on `items` collected into this buffer's storage. `U` must
    /// be `T` with other lifetimes (the same layout: checked in debug
    /// builds); the storage is reused through the standard library's
    /// in-place collection, which keeps an allocation whose layout fits.
    pub fn with<U, R>(
        &mut self,
        items: impl IntoIterator<Item = U>,
        f: impl FnOnce(&mut [U]) -> R,
    ) -> R {
        debug_assert_eq!(Layout::new::<T>(), Layout::new::<U>());
        let mut list: Vec<U> = recycle(std::mem::take(&mut self.0));
        list.extend(items);
        let result = f(&mut list);
        self.0 = recycle(list);
        result
    }

    /// Items the storage holds without growing.
    pub fn capacity(&self) -> usize {
        self.0.capacity()
    }
}

/// An empty vector of `U` in `v`'s allocation (when the layouts match).
fn recycle<T, U>(mut v: Vec<T>) -> Vec<U> {
    v.clear();
    v.into_iter()
        .map(|_| unreachable!("the vector was cleared"))
        .collect()
}

/// Runs `f` on every muscle, on the pool's threads when `pool` is given (a
/// single muscle runs inside the pool too: its own parallel chunks use it).
pub fn for_each_muscle(
    pool: Option<&rayon::ThreadPool>,
    muscles: &mut [MusclePair],
    f: impl Fn(&mut Muscle, &mut MuscleWorkspace) + Sync + Send,
) {
    use rayon::prelude::*;
    match pool {
        Some(pool) if muscles.len() > 1 => pool.install(|| {
            muscles.par_iter_mut().for_each(|(m, ws)| f(m, ws));
        }),
        Some(pool) => pool.install(|| muscles.iter_mut().for_each(|(m, ws)| f(m, ws))),
        None => muscles.iter_mut().for_each(|(m, ws)| f(m, ws)),
    }
}

/// Constraints one sweep's synchronisation costs as much as (about 10 µs of
/// fork and join on the 2-core development machine against about 50 ns per
/// constraint; `sinew suite` measures both).
const SWEEP_SYNC_CONSTRAINTS: usize = 200;

/// Whether colour-by-colour sweeps across muscles beat splitting by muscle:
/// the split by muscle cannot finish before its largest muscle, the sweeps
/// pay a synchronisation per colour. The two give the same bits, so this
/// only picks the faster schedule (or follows [`FrameParams::schedule`]).
pub(super) fn sweeps_by_color_pay(frame: &FrameParams, muscles: &[MusclePair]) -> bool {
    match frame.schedule {
        SweepSchedule::ByMuscle => return false,
        SweepSchedule::ByColor => return true,
        SweepSchedule::Auto => {}
    }
    let threads = match frame.threads {
        0 => rayon::current_num_threads(),
        n => n as usize,
    };
    let sizes = muscles.iter().map(|(m, _)| m.counts().total());
    let (total, largest) = sizes.fold((0, 0), |(t, l), n| (t + n, l.max(n)));
    let sweeps = muscles
        .iter()
        .filter_map(|(_, ws)| ws.plan().map(ColorPlan::color_count))
        .max()
        .unwrap_or(16);
    largest > total / threads.max(1) + SWEEP_SYNC_CONSTRAINTS * sweeps
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_borrow_buffer_keeps_its_storage_between_passes() {
        let mut muscles = vec![1u64, 2, 3];
        let mut buffer = BorrowBuffer::<&'static mut u64>::default();
        buffer.with(muscles.iter_mut(), |list| *list[1] += 10);
        let storage = buffer.0.as_ptr();
        assert!(buffer.capacity() >= 3);
        for _ in 0..3 {
            buffer.with(muscles.iter_mut(), |list| *list[0] += 1);
        }
        assert_eq!(buffer.0.as_ptr(), storage, "the storage was reallocated");
        assert_eq!(muscles, [4, 12, 3]);
    }
}
