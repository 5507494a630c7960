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
//! nothing left. Muscles read each other only through snapshots, so which
//! thread runs which gives the same bits.

use super::parallel::MusclePair;
use super::workspace::MuscleWorkspace;
use crate::muscle::Muscle;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};

/// Most ranges: a pool of more threads runs its members on the first
/// ranges only, the others taking from them.
pub(super) const MAX_RANGES: usize = 64;

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
pub(super) fn for_each_item_in_ranges<T: Send>(
    items: &mut [T],
    threads: usize,
    f: &(impl Fn(usize, &mut T) + Sync),
) {
    use rayon::prelude::*;
    let members = threads.clamp(1, MAX_RANGES);
    let size = items.len().div_ceil(members).max(1);
    let mut ranges: [Mutex<Range<T>>; MAX_RANGES] =
        std::array::from_fn(|_| Mutex::new((0, Default::default())));
    for (k, (range, chunk)) in ranges.iter_mut().zip(items.chunks_mut(size)).enumerate() {
        *range.get_mut().unwrap_or_else(PoisonError::into_inner) =
            (k * size, chunk.iter_mut().enumerate());
    }
    let ranges = &ranges[..members];
    let finished = AtomicUsize::new(0);
    (0..members)
        .into_par_iter()
        .with_max_len(1)
        .for_each(|member| {
            {
                // Counted as finished even if `f` panics, so that no member
                // waits for it (the panic reaches the caller).
                let _finish = Finish(&finished);
                // Its own range from the front, then the others' from the back.
                while let Some((i, item)) = take(&ranges[member], false) {
                    f(i, item);
                }
                for k in 1..members {
                    let other = &ranges[(member + k) % members];
                    while let Some((i, item)) = take(other, true) {
                        f(i, item);
                    }
                }
            }
            while finished.load(Ordering::Acquire) < members {
                if rayon::yield_now() != Some(rayon::Yield::Executed) {
                    std::hint::spin_loop();
                }
            }
        });
}

/// A range: the index of its first item, and its items left, numbered from 0.
type Range<'a, T> = (usize, std::iter::Enumerate<std::slice::IterMut<'a, T>>);

/// The next item of a range and its index, from its front or its back.
fn take<'a, T>(range: &Mutex<Range<'a, T>>, back: bool) -> Option<(usize, &'a mut T)> {
    let mut range = range.lock().unwrap_or_else(PoisonError::into_inner);
    let start = range.0;
    let next = if back {
        range.1.next_back()
    } else {
        range.1.next()
    };
    next.map(|(i, item)| (start + i, item))
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

    /// Every muscle runs once, on 1 to 5 threads and with fewer muscles
    /// than threads; and on two threads, while the first muscle takes 300
    /// ms, the other thread runs every other one (its own range, then the
    /// first range's from the back).
    #[test]
    fn every_muscle_runs_once_its_own_range_first() {
        let oval = crate::scene::builtin("P1")
            .unwrap()
            .instantiate(std::path::Path::new("."))
            .unwrap()
            .muscles()[0]
            .clone();
        for (count, threads) in [(10, 1), (10, 2), (7, 3), (3, 5), (64, 4)] {
            let mut muscles = vec![oval.clone(); count];
            let mut workspaces = vec![MuscleWorkspace::default(); count];
            let mut pairs: Vec<MusclePair> = muscles.iter_mut().zip(&mut workspaces).collect();
            for (i, (m, _)) in pairs.iter_mut().enumerate() {
                m.name = i.to_string();
            }
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let runs = Mutex::new(vec![0; count]);
            pool.install(|| {
                for_each_in_ranges(&mut pairs, threads, &|m, _| {
                    runs.lock().unwrap()[m.name.parse::<usize>().unwrap()] += 1;
                });
            });
            assert_eq!(
                runs.into_inner().unwrap(),
                vec![1; count],
                "{count} on {threads}"
            );
        }
        let mut muscles = vec![oval; 40];
        let mut workspaces = vec![MuscleWorkspace::default(); 40];
        let mut pairs: Vec<MusclePair> = muscles.iter_mut().zip(&mut workspaces).collect();
        for (i, (m, _)) in pairs.iter_mut().enumerate() {
            m.name = i.to_string();
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let thread_of = Mutex::new(vec![usize::MAX; 40]);
        pool.install(|| {
            for_each_in_ranges(&mut pairs, 2, &|m, _| {
                let i: usize = m.name.parse().unwrap();
                let slow = if i == 0 { 300 } else { 1 };
                std::thread::sleep(std::time::Duration::from_millis(slow));
                thread_of.lock().unwrap()[i] = rayon::current_thread_index().unwrap();
            });
        });
        let thread_of = thread_of.into_inner().unwrap();
        let with_slow = thread_of.iter().filter(|&&t| t == thread_of[0]).count();
        assert_eq!(
            with_slow, 1,
            "muscles waited for the slow one: {thread_of:?}"
        );
    }
}
