//! Where a step's passes run: [`Parallelism::decide`].

use super::params::Parallelism;
use crate::muscle::Muscle;
use crate::scene::Scene;
use crate::solver::SolverSettings;
use std::path::Path;

/// T5's 3,009 particles all follow held lines: weighed as
/// [`Parallelism::HELD_LINE_WEIGHT`] each, its per-particle passes split
/// on worker threads; the same muscles with the bones' blend instead
/// (no line) keep them on the calling thread, and without worker
/// threads nothing splits.
#[test]
fn held_lines_weigh_in_the_particle_split() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes/t5.ron");
    let scene = Scene::load(&path).unwrap();
    let solver = scene.instantiate(path.parent().unwrap()).unwrap();
    let settings = SolverSettings::default();
    let muscles = solver.muscles();
    let particles: usize = muscles.iter().map(|m| m.x.len()).sum();
    assert!(particles < settings.parallel_threshold, "{particles}");
    assert!(muscles.iter().all(|m| m.hold_line.is_some()));
    let held = Parallelism::decide(&settings, true, muscles);
    assert_eq!(
        held,
        Parallelism {
            muscles: true,
            particles: true
        }
    );
    let blended: Vec<Muscle> = (muscles.iter().cloned())
        .map(|mut m| {
            m.hold_line = None;
            m
        })
        .collect();
    let bare = Parallelism::decide(&settings, true, &blended);
    assert_eq!(
        bare,
        Parallelism {
            muscles: true,
            particles: false
        }
    );
    let alone = Parallelism::decide(&settings, false, muscles);
    assert_eq!(alone, Parallelism::default());
}

/// A frame's first and last passes each run two phases in one task
/// (`passes::begin_frame_all`, `passes::end_frame_all`): on 1 and 2
/// threads every block they hold still gets its share of the time (T5,
/// its 17 muscles in parallel on 2), and the per-block timers add up to no
/// more than the step took.
#[test]
fn fused_passes_keep_every_block_timed() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes/t5.ron");
    let scene = Scene::load(&path).unwrap();
    for threads in [1, 2] {
        let mut solver = scene.instantiate(path.parent().unwrap()).unwrap();
        solver.settings.threads = threads;
        solver.settings.iterations = 2;
        for _ in 0..3 {
            let start = std::time::Instant::now();
            solver.step();
            let took = start.elapsed();
            let t = *solver.timings();
            for (name, block) in super::StepTimings::NAMES.iter().zip(t.as_array()) {
                assert!(!block.is_zero(), "{threads} threads: {name} untimed");
            }
            assert!(
                t.total() <= took,
                "{threads} threads: {:?} > {took:?}",
                t.total()
            );
        }
    }
}
