//! A step allocates nothing once the scene is set: the arm (T5: a
//! skeleton, sensors, 17 muscles sliding on bones and on each other) steps
//! 100 frames after its first with every method, on 1 and on 2 threads,
//! and a skin over P1's oval on 4 threads (its colour sweep run by the
//! threads as one team) 20 frames after its first, under a global
//! allocator that counts.
//!
//! With worker threads a step is handed to the pool once
//! ([`rayon::ThreadPool::install`]), and rayon's queue for jobs from outside
//! the pool takes a new block every 63 jobs: that, and nothing of sinew's,
//! is allowed — one allocation per 63 steps.
#![expect(
    unsafe_code,
    reason = "a global allocator is an unsafe trait; this one forwards to the system's"
)]

mod common;

use sinew_core::scene::Scene;
use sinew_core::{SolverMethod, SweepSchedule};
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The system allocator, counting allocations and reallocations.
struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards every call to the system allocator unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: the caller's contract is the system allocator's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn stepping_the_arm_and_a_skin_allocates_nothing_after_the_first_frame() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes/t5.ron");
    let scene = Scene::load(&path).unwrap();
    let base = scene.instantiate(path.parent().unwrap()).unwrap();
    const FRAMES: usize = 100;
    let mut found = Vec::new();
    // Every solver lives to the end: a dropped worker pool's threads exit on
    // their own time, and what they free and allocate as they go would be
    // counted in the next case.
    let mut kept = Vec::new();
    for method in SolverMethod::EVERY {
        for (threads, schedule) in [
            (1, SweepSchedule::Auto),
            (2, SweepSchedule::ByMuscle),
            (2, SweepSchedule::ByColor),
        ] {
            let mut solver = base.clone();
            solver.settings.method = method;
            solver.settings.threads = threads;
            solver.settings.schedule = schedule;
            solver.settings.parallel_threshold = 0;
            solver.step();
            let before = ALLOCATIONS.load(Ordering::Relaxed);
            for _ in 0..FRAMES {
                solver.step();
            }
            let allocations = ALLOCATIONS.load(Ordering::Relaxed) - before;
            let rayon_queue = if threads == 1 { 0 } else { FRAMES.div_ceil(63) };
            kept.push(solver);
            if allocations > rayon_queue {
                found.push(format!(
                    "{method:?}, {threads} threads, {schedule:?}: {allocations} allocations"
                ));
            }
        }
    }
    // A skin big enough that four threads sweep its colours as one team.
    let mut scene = common::oval_with_skin(110, 90);
    scene.settings.threads = 4;
    scene.settings.parallel_threshold = 0;
    let mut solver = scene.instantiate(Path::new(".")).unwrap();
    solver.step();
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    const SKIN_FRAMES: usize = 20;
    for _ in 0..SKIN_FRAMES {
        solver.step();
    }
    let allocations = ALLOCATIONS.load(Ordering::Relaxed) - before;
    if allocations > SKIN_FRAMES.div_ceil(63) {
        found.push(format!("a skin on 4 threads: {allocations} allocations"));
    }
    kept.push(solver);
    assert!(found.is_empty(), "{found:#?}");
}
