//! A driver's threads: its worker pool, the buffer its passes borrow the
//! muscles through, the pass that runs muscle by muscle, and the choice
//! between sweeping by muscle and by colour.

use super::coloring::ColorPlan;
use super::muscle_ranges::for_each_in_ranges;
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
///
/// A muscle that holds more than a quarter of a thread's share of the
/// particles starts first, on the calling thread, while the other threads
/// share out the rest (the first step of a longest-task-first schedule): a
/// skin over a body, 13 380 particles beside 144 muscles of at most 155,
/// then runs beside the muscles, its own chunks taken by whichever thread
/// is free, instead of starting wherever the halving of the list put it
/// (last, listed after its muscles). Muscles read each other only through
/// snapshots, so the order gives the same bits. Among muscles of similar
/// sizes the list is halved as it is (T7's walk took ×1.05 with its
/// largest muscle started first).
///
/// The rest of the list is split down to single muscles
/// (`with_max_len(1)`), so that a thread out of work takes muscles one by
/// one from the other's rest: rayon otherwise stops splitting after a few
/// halvings, and one frame of T7's run had each thread run exactly 72
/// muscles, one idle for 0.64 ms of a 4.3 ms block. With no dominant muscle
/// the list is shared out in ranges, one a thread, the muscles left in a
/// range taken from its back by threads out of their own, and the last
/// waited for spinning (`solver/muscle_ranges.rs`): rayon's join put the
/// waiting thread to sleep, and its wake cost 0.1 ms a block.
pub fn for_each_muscle(
    pool: Option<&rayon::ThreadPool>,
    muscles: &mut [MusclePair],
    f: impl Fn(&mut Muscle, &mut MuscleWorkspace) + Sync + Send,
) {
    use rayon::prelude::*;
    let Some(pool) = pool else {
        return muscles.iter_mut().for_each(|(m, ws)| f(m, ws));
    };
    pool.install(|| match dominant(muscles, pool.current_num_threads()) {
        Some(largest) => {
            let (before, from) = muscles.split_at_mut(largest);
            let ((m, ws), after) = from.split_first_mut().expect("the largest is in the list");
            let rest = before
                .par_iter_mut()
                .chain(after.par_iter_mut())
                .with_max_len(1);
            rayon::join(|| f(m, ws), || rest.for_each(|(m, ws)| f(m, ws)));
        }
        None if muscles.len() > 1 => {
            for_each_in_ranges(muscles, pool.current_num_threads(), &f);
        }
        None => muscles.iter_mut().for_each(|(m, ws)| f(m, ws)),
    });
}

/// The index of the muscle with the most particles, when it holds more than
/// a quarter of a thread's share of them all on `threads` threads (and
/// there are others to run beside it).
pub(super) fn dominant(muscles: &[MusclePair], threads: usize) -> Option<usize> {
    let sizes = muscles.iter().map(|(m, _)| m.x.len());
    let (total, (largest, size)) = sizes
        .enumerate()
        .fold((0, (0, 0)), |(total, best), (i, n)| {
            (total + n, if n > best.1 { (i, n) } else { best })
        });
    (muscles.len() > 1 && size * 4 * threads > total).then_some(largest)
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

    /// P1's, P2's and P3's muscles (101, 101, 87, 533 and 183 particles),
    /// smallest first.
    fn builtin_muscles() -> Vec<Muscle> {
        let mut muscles: Vec<Muscle> = ["P1", "P2", "P3"]
            .into_iter()
            .flat_map(|name| {
                let scene = crate::scene::builtin(name).unwrap();
                let solver = scene.instantiate(std::path::Path::new(".")).unwrap();
                solver.muscles().to_vec()
            })
            .collect();
        muscles.sort_by_key(|m| m.x.len());
        muscles
    }

    /// The muscle with the most particles dominates when it holds more than
    /// a quarter of a thread's share: P3's biceps among the built-in
    /// muscles (533 of 1 005) on any number of threads; one of ten copies
    /// of P1's oval on one or two threads not, on three it does.
    #[test]
    fn a_muscle_dominates_with_a_quarter_of_a_threads_share() {
        let mut muscles = builtin_muscles();
        let mut workspaces = vec![MuscleWorkspace::default(); muscles.len()];
        let pairs: Vec<MusclePair> = muscles.iter_mut().zip(&mut workspaces).collect();
        for threads in [1, 2, 8] {
            assert_eq!(dominant(&pairs, threads), Some(4));
        }
        let mut ovals = vec![builtin_muscles()[2].clone(); 10];
        let mut workspaces = vec![MuscleWorkspace::default(); 10];
        let pairs: Vec<MusclePair> = ovals.iter_mut().zip(&mut workspaces).collect();
        assert_eq!(dominant(&pairs, 1), None);
        assert_eq!(dominant(&pairs, 2), None);
        assert_eq!(dominant(&pairs, 3), Some(0));
        assert_eq!(dominant(&pairs[..1], 1), None, "nothing to run beside it");
    }

    /// A slow muscle holds no other behind it: on two threads, while the
    /// first of 144 equal muscles takes 200 ms, the other thread runs
    /// every other one, its own range and then the slow one's from the
    /// back (split in halves and quarters only, the slow one's thread kept
    /// 35 of them; with no taking from another range, 71).
    #[test]
    fn a_slow_muscle_holds_no_other_behind_it() {
        let oval = builtin_muscles()[2].clone();
        let mut muscles = vec![oval; 144];
        let mut workspaces = vec![MuscleWorkspace::default(); muscles.len()];
        let mut pairs: Vec<MusclePair> = muscles.iter_mut().zip(&mut workspaces).collect();
        assert_eq!(dominant(&pairs, 2), None);
        for (i, (m, _)) in pairs.iter_mut().enumerate() {
            m.name = i.to_string();
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let thread_of = std::sync::Mutex::new(vec![usize::MAX; 144]);
        for_each_muscle(Some(&pool), &mut pairs, |m, _| {
            let i: usize = m.name.parse().unwrap();
            if i == 0 {
                std::thread::sleep(std::time::Duration::from_millis(200));
            }
            thread_of.lock().unwrap()[i] = rayon::current_thread_index().unwrap();
        });
        let thread_of = thread_of.into_inner().unwrap();
        let behind = thread_of[1..]
            .iter()
            .filter(|&&t| t == thread_of[0])
            .count();
        assert!(behind <= 2, "{behind} muscles waited for the slow one");
    }

    /// On a pool, a dominant muscle is the first one run, wherever it is in
    /// the list; every muscle runs once. (One thread, so that the order of
    /// the calls is the order of the starts.)
    #[test]
    fn a_dominant_muscle_starts_first() {
        let mut muscles = builtin_muscles();
        let sizes: Vec<usize> = muscles.iter().map(|m| m.x.len()).collect();
        let mut workspaces = vec![MuscleWorkspace::default(); muscles.len()];
        let mut pairs: Vec<MusclePair> = muscles.iter_mut().zip(&mut workspaces).collect();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let order = std::sync::Mutex::new(Vec::new());
        for_each_muscle(Some(&pool), &mut pairs, |m, _| {
            order.lock().unwrap().push(m.x.len());
        });
        let mut order = order.into_inner().unwrap();
        assert_eq!(order[0], *sizes.last().unwrap(), "{order:?}");
        order.sort();
        assert_eq!(order, sizes);
    }
}
