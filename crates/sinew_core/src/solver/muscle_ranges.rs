//! Muscles of similar sizes shared out over a pool's threads in ranges:
//! each thread runs its own range of the list from the front, then takes
//! the muscles left in the others' ranges from their backs, one at a time,
//! and waits for the last muscle spinning, not asleep.
//!
//! A pass over the muscles split by rayon's parallel iterator ends in a
//! join: a thread out of muscles waits for the other's last one, and after
//! a few dozen rounds of finding no work it goes to sleep, to be woken when
//! that muscle ends. On this 2-core machine that wake cost 0.1 ms at the
//! end of each of T7's two blocks a frame (0.00–0.22 ms in 40 blocks of
//! its run, with a muscle of 50 µs the most a thread had to wait for).
//! Here a thread out of muscles spins until every member has finished (0.004
//! ms on average after the last muscle), running any rayon work it finds
//! meanwhile (a large muscle's chunks). The ranges keep each thread on
//! the same muscles block after block, as the halving of the list did:
//! one shared queue, each thread taking the next muscle, spread the
//! muscles over both cores' caches and was slower than the halving
//! (×1.02–1.05 on T7's run).
//!
//! The members are a parallel iterator over the threads' count (no
//! allocation); a member that has not started when the others finish is
//! run by a waiting one, whose spin runs pending rayon work, and finds
//! nothing left. Only a thread's outermost member waits: a thread waiting
//! inside a muscle for a chunk another thread took runs pending work too,
//! and a member it starts there would wait for that muscle, beneath it on
//! the same thread, for ever (a 16-thread probe with smaller closest-data
//! chunks hung T7 so). And no member spins longer than `SPIN_AT_MOST`
//! (0.5 ms, several times the longest muscle's block): a worker that took
//! a muscle's chunk and started a member while it waited inside it is
//! outermost, yet holds that muscle beneath it; after the bound the member
//! waits in rayon's join, which runs the chunk's muscle on. Muscles read
//! each other only through snapshots, so which thread runs which gives the
//! same bits.
//!
//! What a thread takes from a range is a [`Share`]'s to say: a range of
//! items hands them out one at a time; a pass by groups of muscles in
//! lanes (`super::lane_groups`) hands out whole groups from a share's
//! front and its lone muscles from its back.

use super::parallel::MusclePair;
use super::workspace::MuscleWorkspace;
use crate::muscle::Muscle;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

/// Most ranges, and members: on a pool of more threads, at most this many
/// of them share the items out.
const MAX_RANGES: usize = 64;

/// Runs `f` on every muscle of `muscles` on the current rayon pool's
/// `threads` threads (module docs).
pub(super) fn for_each_in_ranges(
    muscles: &mut [MusclePair],
    threads: usize,
    f: &(impl Fn(&mut Muscle, &mut MuscleWorkspace) + Sync),
) {
    for_each_item_in_ranges(muscles, threads, &|_, (m, ws)| f(m, ws));
}

/// Runs `f(index, item)` on every item of `items` on the current rayon
/// pool's `threads` threads, shared out in ranges as the muscles are
/// (module docs): a pass over muscles or their snapshots.
pub(super) fn for_each_item_in_ranges<'a, T: Send>(
    items: &'a mut [T],
    threads: usize,
    f: &(impl Fn(usize, &mut T) + Sync),
) {
    let range = |start, chunk: &'a mut [T]| (start, chunk.iter_mut().enumerate());
    for_each_in_ranges_as(items, threads, range, &|(i, item)| f(i, item));
}

/// Runs `f` on every item of the shares that `share(start, range)` makes
/// of `items` cut into one range of the same size per thread (`start`:
/// the index of the range's first item) on the current rayon pool's
/// `threads` threads (module docs).
pub(super) fn for_each_in_ranges_as<'a, T, S: Share + Default>(
    items: &'a mut [T],
    threads: usize,
    share: impl Fn(usize, &'a mut [T]) -> S,
    f: &(impl Fn(S::Item) + Sync),
) {
    let members = threads.clamp(1, MAX_RANGES);
    let size = items.len().div_ceil(members).max(1);
    let mut shares: [Mutex<S>; MAX_RANGES] = std::array::from_fn(|_| Mutex::default());
    for (k, (slot, chunk)) in shares.iter_mut().zip(items.chunks_mut(size)).enumerate() {
        *slot.get_mut().unwrap_or_else(PoisonError::into_inner) = share(k * size, chunk);
    }
    for_each_in_shares(&shares[..members], f);
}

/// A thread's share of a pass's work: its own thread takes it from the
/// front, a thread out of work of its own from the back.
pub(super) trait Share: Send {
    /// One piece of work.
    type Item;
    /// The share's next item, from its front.
    fn front(&mut self) -> Option<Self::Item>;
    /// The share's last item left.
    fn back(&mut self) -> Option<Self::Item>;
}

/// A range of items: the index of its first, and its items left numbered
/// from 0; an item comes with its index.
impl<'a, T: Send> Share for Range<'a, T> {
    type Item = (usize, &'a mut T);

    fn front(&mut self) -> Option<Self::Item> {
        let start = self.0;
        self.1.next().map(|(i, item)| (start + i, item))
    }

    fn back(&mut self) -> Option<Self::Item> {
        let start = self.0;
        self.1.next_back().map(|(i, item)| (start + i, item))
    }
}

/// Runs `f` on every item of `shares`, one member per share on the
/// current rayon pool (module docs): each member its own share from the
/// front, then the others' from their backs, and the outermost member of
/// a thread waits for the rest spinning.
fn for_each_in_shares<S: Share>(shares: &[Mutex<S>], f: &(impl Fn(S::Item) + Sync)) {
    use rayon::prelude::*;
    let members = shares.len();
    let finished = AtomicUsize::new(0);
    (0..members)
        .into_par_iter()
        .with_max_len(1)
        .for_each(|member| {
            let outermost = Member::enter();
            {
                // Counted as finished even if `f` panics, so that no member
                // waits for it (the panic reaches the caller).
                let _finish = Finish(&finished);
                // Its own share from the front, then the others' from the back.
                while let Some(item) = take(&shares[member], false) {
                    f(item);
                }
                for k in 1..members {
                    let other = &shares[(member + k) % members];
                    while let Some(item) = take(other, true) {
                        f(item);
                    }
                }
            }
            // Only the outermost member of a thread waits: one started
            // inside another's item would wait for that item, beneath it
            // on this thread (the rayon join it returns to finishes the
            // pass all the same).
            if outermost.0 {
                wait_spinning(&finished, members);
            }
        });
}

/// Longest a member waits spinning for the others ([`wait_spinning`]):
/// far above a muscle's block (T7's largest, five iterations, ≈ 0.1 ms on
/// one thread), so a pass ends on it as before.
const SPIN_AT_MOST: Duration = Duration::from_micros(500);

/// Waits until `members` members are `finished`, spinning and running
/// pending rayon work meanwhile (module docs) — for at most
/// [`SPIN_AT_MOST`], then returns to the pass's rayon join, which waits
/// as rayon does. The bound keeps any wait that cannot end from hanging:
/// a worker that took a chunk of a muscle and, waiting inside it, started
/// a member, holds that muscle's member beneath the waiting one.
fn wait_spinning(finished: &AtomicUsize, members: usize) {
    let start = Instant::now();
    while finished.load(Ordering::Acquire) < members && start.elapsed() < SPIN_AT_MOST {
        if rayon::yield_now() != Some(rayon::Yield::Executed) {
            std::hint::spin_loop();
        }
    }
}

thread_local! {
    /// Whether this thread is running a member of a pass in ranges.
    static IN_MEMBER: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// A member running on this thread; `.0`: the thread's outermost (it
/// was running no other member when this one started). Dropped when the
/// member ends, unwinding too.
struct Member(bool);

impl Member {
    fn enter() -> Self {
        Self(!IN_MEMBER.replace(true))
    }
}

impl Drop for Member {
    fn drop(&mut self) {
        if self.0 {
            IN_MEMBER.set(false);
        }
    }
}

/// A range: the index of its first item, and its items left, numbered from 0.
type Range<'a, T> = (usize, std::iter::Enumerate<std::slice::IterMut<'a, T>>);

/// The next item of a share, from its front or its back.
fn take<S: Share>(share: &Mutex<S>, back: bool) -> Option<S::Item> {
    let mut share = share.lock().unwrap_or_else(PoisonError::into_inner);
    match back {
        true => share.back(),
        false => share.front(),
    }
}

/// Counts a member finished when dropped.
struct Finish<'a>(&'a AtomicUsize);

impl Drop for Finish<'_> {
    fn drop(&mut self) {
        self.0.fetch_add(1, Ordering::AcqRel);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every item runs once, with its index, on 1 to 5 threads, with
    /// fewer items than threads and with none. (That a thread out of its
    /// own range takes the others' leftovers is
    /// `parallel::tests::a_slow_muscle_holds_no_other_behind_it`.)
    #[test]
    fn every_item_runs_once_with_its_index() {
        for (count, threads) in [(10, 1), (10, 2), (7, 3), (3, 5), (64, 4), (0, 2)] {
            let mut items: Vec<usize> = (0..count).collect();
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let runs = Mutex::new(vec![0; count]);
            pool.install(|| {
                for_each_item_in_ranges(&mut items, threads, &|i, item: &mut usize| {
                    assert_eq!(i, *item);
                    runs.lock().unwrap()[i] += 1;
                });
            });
            let runs = runs.into_inner().unwrap();
            assert_eq!(runs, vec![1; count], "{count} on {threads}");
        }
    }

    /// Items that fork work of their own (a large muscle's chunks, split
    /// by `rayon::join`) on many threads. A thread waiting inside an item
    /// for the half another took runs other work meanwhile, and may start
    /// a member no thread has started yet; that member must not wait for
    /// the members to finish, one of them the item beneath it on its own
    /// thread. 144 items of 8 forked pieces each, 100 passes on 16
    /// threads: with every member waiting, this hung within seconds.
    #[test]
    fn items_that_fork_their_own_work_finish_on_many_threads() {
        fn pieces(n: u32) -> u64 {
            if n == 1 {
                return (0..20_000u64).map(std::hint::black_box).sum();
            }
            let (a, b) = rayon::join(|| pieces(n / 2), || pieces(n - n / 2));
            a + b
        }
        let threads = 16;
        let (sender, receiver) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut items = vec![0u64; 144];
            pool.install(|| {
                for _ in 0..100 {
                    for_each_item_in_ranges(&mut items, threads, &|_, item: &mut u64| {
                        *item += pieces(8);
                    });
                }
            });
            sender.send(items).ok();
        });
        let items = receiver
            .recv_timeout(std::time::Duration::from_secs(120))
            .expect("the passes hung");
        let each = 100 * 8 * (0..20_000u64).sum::<u64>();
        assert!(items.iter().all(|&i| i == each));
    }

    /// A wait for members that never finish ends after its bound (with
    /// no bound it never returned).
    #[test]
    fn a_wait_for_members_that_never_finish_ends() {
        let (sender, receiver) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let start = Instant::now();
            wait_spinning(&AtomicUsize::new(1), 2);
            sender.send(start.elapsed()).ok();
        });
        let waited = receiver
            .recv_timeout(Duration::from_secs(30))
            .expect("the wait never ended");
        assert!(waited >= SPIN_AT_MOST, "{waited:?}");
    }
}
