//! The Bevy driver's step allocates nothing once the scene is set: the arm
//! (T5) steps 100 frames after its first ones with every method, on 1 and
//! on 2 threads, under a global allocator that counts while the plug-in's
//! step runs (its animation of the bones in `SinewPrepareSchedule` and its
//! step in `SinewStepSchedule`; transform propagation and the render
//! write-back apart).
//!
//! With worker threads the plug-in hands work to its pool twice a step
//! (the activations, then the substeps), and rayon's queue for jobs from
//! outside the pool takes a new block every 63 jobs: that, and nothing of
//! sinew's, is allowed.
#![expect(
    unsafe_code,
    reason = "a global allocator is an unsafe trait; this one forwards to the system's"
)]

use bevy::prelude::*;
use sinew_bevy::prelude::*;
use sinew_core::SolverMethod;
use sinew_core::scene::Scene;
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// The system allocator, counting allocations and reallocations while
/// `COUNTING` is on.
struct Counting;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

fn count() {
    if COUNTING.load(Ordering::Relaxed) {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    }
}

// SAFETY: forwards every call to the system allocator unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: the caller's contract is the system allocator's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn counting(on: bool) -> impl Fn() {
    move || COUNTING.store(on, Ordering::Relaxed)
}

#[test]
fn stepping_the_arm_in_bevy_allocates_nothing_after_the_first_frames() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes/t5.ron");
    let scene = Scene::load(&path).unwrap();
    let base = scene.instantiate(path.parent().unwrap()).unwrap();
    const FRAMES: usize = 100;
    let mut found = Vec::new();
    // Every app lives to the end: a dropped worker pool's threads exit on
    // their own time, and what they free and allocate as they go would be
    // counted in the next case.
    let mut kept = Vec::new();
    for method in SolverMethod::EVERY {
        for threads in [1, 2] {
            let mut parts = base.clone().into_parts();
            parts.settings.method = method;
            parts.settings.threads = threads;
            parts.settings.parallel_threshold = 0;
            let mut app = App::new();
            app.add_plugins((
                MinimalPlugins,
                bevy::transform::TransformPlugin,
                SinewPlugin::default().every_update(),
            ));
            app.add_systems(
                SinewPrepareSchedule,
                (
                    counting(true).before(SinewSystems::AnimateBones),
                    counting(false).after(SinewSystems::AnimateBones),
                ),
            )
            .add_systems(
                SinewStepSchedule,
                (
                    counting(true).before(SinewSystems::ReadInputs),
                    counting(false)
                        .after(SinewSystems::Substeps)
                        .before(SinewSystems::WriteBack),
                ),
            );
            app.world_mut()
                .spawn(SinewSceneRoot::Built(Arc::new(SinewScene {
                    scene: scene.clone(),
                    parts,
                })));
            for _ in 0..3 {
                app.update();
            }
            let before = ALLOCATIONS.load(Ordering::Relaxed);
            for _ in 0..FRAMES {
                app.update();
            }
            let allocations = ALLOCATIONS.load(Ordering::Relaxed) - before;
            let rayon_queue = if threads == 1 {
                0
            } else {
                2 * FRAMES.div_ceil(63)
            };
            assert!(app.world().resource::<SinewClock>().frame >= FRAMES as u64);
            kept.push(app);
            if allocations > rayon_queue {
                found.push(format!(
                    "{method:?}, {threads} threads: {allocations} allocations"
                ));
            }
        }
    }
    assert!(found.is_empty(), "{found:#?}");
}
