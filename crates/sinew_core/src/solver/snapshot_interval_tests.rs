//! Iterations in blocks ([`SolverSettings::snapshot_interval`]): a block
//! reads the snapshots published at its start, and gives the same bits on
//! any thread count and schedule.

use super::*;
use crate::scene::builtin;
use glam::Vec3;

/// P3 (the biceps slides on the brachialis, the brachialis on the biceps)
/// under gravity, with `edit` applied to its settings.
fn p3(edit: impl FnOnce(&mut SolverSettings)) -> Solver {
    let mut scene = builtin("P3").unwrap();
    scene.settings.gravity = Vec3::new(0.0, -9.81, 0.0);
    scene.settings.parallel_threshold = 0;
    edit(&mut scene.settings);
    scene.instantiate(std::path::Path::new(".")).unwrap()
}

/// Every muscle's positions, as bits.
fn bits(solver: &Solver) -> Vec<u32> {
    (solver.muscles().iter())
        .flat_map(|m| m.x.iter().flat_map(|p| p.to_array().map(f32::to_bits)))
        .collect()
}

/// The biceps' positions (as bits) after 30 frames and one more, with
/// `interval`, the brachialis fully activated before the last frame when
/// `activate`.
fn biceps_after(interval: u32, activate: bool) -> Vec<u32> {
    let mut solver = p3(|s| s.snapshot_interval = interval);
    for _ in 0..30 {
        solver.step();
    }
    if activate {
        let brachialis = solver.muscle_index("brachialis").unwrap();
        solver.muscle_mut(brachialis).params.activation = 1.0;
    }
    solver.step();
    let biceps = solver.muscle_index("biceps").unwrap();
    (solver.muscles()[biceps].x.iter())
        .flat_map(|p| p.to_array().map(f32::to_bits))
        .collect()
}

/// With one block per substep the biceps reads the brachialis' snapshot
/// published at the substep's start, its prediction: what the
/// brachialis' activation changes in its projections within the step
/// cannot reach the biceps, to the bit. With a block per iteration (or two
/// blocks) it does: the biceps slides on the brachialis as it moves.
#[test]
fn a_block_of_iterations_reads_the_snapshots_published_at_its_start() {
    let n = builtin("P3").unwrap().settings.iterations;
    assert!(n >= 4, "{n}");
    assert_eq!(biceps_after(n, false), biceps_after(n, true));
    assert_ne!(biceps_after(1, false), biceps_after(1, true));
    assert_ne!(biceps_after(n / 2, false), biceps_after(n / 2, true));
}

/// Blocks of iterations, with a muscle that sits out the last iterations
/// (its block ends early and its snapshot is staged at its own last), give
/// the same bits on 1, 2 and 8 threads, Gauss–Seidel split by muscle and
/// global colour sweeps across muscles alike.
#[test]
fn blocks_of_iterations_are_bit_identical_for_1_2_and_8_threads() {
    let methods = [
        (SolverMethod::Sequential, SweepSchedule::Auto),
        (
            SolverMethod::Colored {
                scope: ColorScope::Global,
            },
            SweepSchedule::ByColor,
        ),
    ];
    for (method, schedule) in methods {
        let run = |threads: u32| {
            let mut solver = p3(|s| {
                s.snapshot_interval = 3;
                s.threads = threads;
                s.method = method;
                s.schedule = schedule;
            });
            solver.muscle_mut(1).params.iterations = Some(4);
            for _ in 0..40 {
                solver.step();
            }
            bits(&solver)
        };
        let one = run(1);
        assert_eq!(one, run(2), "{method:?}: 2 threads");
        assert_eq!(one, run(8), "{method:?}: 8 threads");
    }
}

/// An interval of zero is refused by name; one past the iteration count
/// runs every iteration in one block.
#[test]
fn a_zero_interval_is_refused_and_a_long_one_is_one_block() {
    let settings = SolverSettings {
        snapshot_interval: 0,
        ..SolverSettings::default()
    };
    let err = settings.validate().unwrap_err().to_string();
    assert!(err.contains("snapshot_interval"), "{err}");
    let n = builtin("P3").unwrap().settings.iterations;
    let run = |interval: u32| {
        let mut solver = p3(|s| s.snapshot_interval = interval);
        for _ in 0..20 {
            solver.step();
        }
        bits(&solver)
    };
    assert_eq!(run(n), run(n + 7));
}

/// A substep's blocks start every `snapshot_interval` iterations, the last
/// one short; one block per iteration by default; none without iterations.
#[test]
fn blocks_start_every_interval_iterations() {
    let starts = |interval: u32, count: u32| -> Vec<(u32, u32)> {
        let settings = SolverSettings {
            snapshot_interval: interval,
            ..SolverSettings::default()
        };
        let frame = FrameParams::new(&settings, 0, Parallelism::default());
        (frame.substep(0).blocks(count))
            .map(|b| (b.index, b.block_end()))
            .collect()
    };
    assert_eq!(starts(3, 10), [(0, 3), (3, 6), (6, 9), (9, 10)]);
    assert_eq!(starts(1, 3), [(0, 1), (1, 2), (2, 3)]);
    assert_eq!(starts(5, 5), [(0, 5)]);
    assert_eq!(starts(12, 5), [(0, 5)]);
    assert!(starts(2, 0).is_empty());
}
