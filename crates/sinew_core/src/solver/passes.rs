//! The frame loop's passes over every muscle of a driver, built from the
//! per-muscle phases of [`super::pipeline`]: where the plain
//! [`super::Solver`] and the Bevy systems hand over their muscles (as
//! [`MusclePair`]s) and their targets, and get the same bits back for any
//! thread count.
//!
//! ```text
//! update_activations   activation → rest lengths, volume ratio
//! begin_substep_all    predict, pins, λ = 0 (after the driver's attachment goals)
//! begin_frame_all      the two above in one pass, for a frame's first substep
//! publish_all          the snapshots other muscles read
//! iterate_all          closest data and projection, by muscle or by colour
//! end_substep_all      v = (p − x)/h, x = p
//! end_frame_all        a frame's last end_substep and the guard (a muscle
//!                      that blew up is put back) in one pass
//! ```
//!
//! The plain solver runs the fused passes; the Bevy driver runs each part
//! as a system of its own. Either way each muscle goes through the same
//! phases in the same order, so the bits are the same.

use super::coloring::PlanKind;
use super::guard::{Fault, guard};
use super::lane_groups;
use super::muscle_ranges::for_each_item_in_ranges;
use super::parallel::{MusclePair, WorkerPool, for_each_muscle, sweeps_by_color_pay};
use super::params::{IterationParams, SubstepParams};
use super::pipeline;
use super::sweep;
use super::timings::{StepTimings, Stopwatch, TaskSplit};
use crate::closest::{TargetSet, TargetSurface};
use crate::muscle::Muscle;
use std::sync::Mutex;

/// Muscles above which activations are updated in parallel (their rest
/// lengths: a few µs per muscle).
const PARALLEL_MUSCLES: usize = 16;

/// Rest lengths and volume ratio of every muscle from its activation, on
/// the pool when there are many muscles (`always`: whatever their number);
/// each warning (an activation out of range) goes to `warn`.
pub fn update_activations(
    pool: &WorkerPool,
    muscles: &mut [MusclePair],
    always: bool,
    warn: impl Fn(String) + Sync + Send,
) {
    let pool = pool.when(activations_split(always, muscles));
    for_each_muscle(pool, muscles, |m, _| {
        if let Some(w) = m.update_activation() {
            warn(w);
        }
    });
}

/// Whether the activations of `muscles` are updated on the pool: many
/// muscles, or `always`.
fn activations_split(always: bool, muscles: &[MusclePair]) -> bool {
    always || muscles.len() > PARALLEL_MUSCLES
}

/// [`pipeline::begin_substep`] for every muscle (on the pool when the
/// step's particle passes are parallel), each after `goals(muscle)` in the
/// same task: a driver that can pose the bones from any thread moves the
/// attachment goals there ([`pipeline::update_attachment_goals`]); one
/// that cannot has moved them before and passes a closure that does
/// nothing.
pub fn begin_substep_all(
    pool: &WorkerPool,
    muscles: &mut [MusclePair],
    sub: &SubstepParams,
    goals: impl Fn(&mut Muscle) + Sync + Send,
) {
    let pool = pool.when(sub.frame.parallelism.particles);
    for_each_muscle(pool, muscles, |m, ws| {
        goals(m);
        pipeline::begin_substep(m, ws, sub);
    });
}

/// A frame's start for every muscle in one pass (the plain solver's; the
/// Bevy driver runs the two as systems of their own): each muscle's
/// activation ([`update_activations`]) and then its first substep's start
/// ([`begin_substep_all`], after `goals(muscle)`) in one task, so the
/// threads fork and join once instead of twice (about 30 µs a pass on 16
/// threads). The same bits as the two passes one after the other: a
/// muscle's activation touches only its own rest lengths and volume. On
/// the pool when either pass would be. `split` takes each part's time
/// (part 0 the activation, part 1 the substep's start), for the read-inputs
/// and integrate blocks.
pub fn begin_frame_all(
    pool: &WorkerPool,
    muscles: &mut [MusclePair],
    sub: &SubstepParams,
    always: bool,
    warn: impl Fn(String) + Sync + Send,
    goals: impl Fn(&mut Muscle) + Sync + Send,
    split: &TaskSplit,
) {
    let pool = pool.when(sub.frame.parallelism.particles || activations_split(always, muscles));
    for_each_muscle(pool, muscles, |m, ws| {
        let start = split.start();
        if let Some(w) = m.update_activation() {
            warn(w);
        }
        let middle = split.lap(start, 0);
        goals(m);
        pipeline::begin_substep(m, ws, sub);
        split.lap(middle, 1);
    });
}

/// [`pipeline::end_substep`] for every muscle.
pub fn end_substep_all(pool: &WorkerPool, muscles: &mut [MusclePair], sub: &SubstepParams) {
    let pool = pool.when(sub.frame.parallelism.particles);
    for_each_muscle(pool, muscles, |m, ws| pipeline::end_substep(m, ws, sub));
}

/// A frame's end for every muscle in one pass: each muscle's last substep
/// ended ([`pipeline::end_substep`]) and then its run-time [`guard`] (a
/// muscle that blew up put back to its last good frame) in one task —
/// the muscle still in that thread's cache, and one fork and join instead
/// of two (about 30 µs a pass on 16 threads). The Bevy
/// driver runs the two as systems of their own, the same bits and faults:
/// each muscle's check reads only its own state. On the pool when the
/// step's particle passes are parallel (the guard reads and copies every
/// particle's position and velocity). `max_speed` is in scene units per
/// second, `length_unit` the scene's. The faults found are appended to
/// `faults` in muscle order (a fault's `muscle` is its index in
/// `muscles`), whatever thread found them. `split` takes each part's time
/// (part 0 the substep's end, part 1 the guard), for the apply and
/// write-back blocks.
pub fn end_frame_all(
    pool: &WorkerPool,
    muscles: &mut [MusclePair],
    sub: &SubstepParams,
    max_speed: f32,
    length_unit: f32,
    faults: &mut Vec<Fault>,
    split: &TaskSplit,
) {
    let first_new = faults.len();
    let frame = &sub.frame;
    let order = frame.order.as_slice();
    let found = Mutex::new(&mut *faults);
    let check = |i: usize, (m, ws): &mut MusclePair| {
        let start = split.start();
        pipeline::end_substep(m, ws, sub);
        let ended = split.lap(start, 0);
        let frame_number = frame.frame + 1;
        if let Some(f) = guard(m, ws, frame_number, i, max_speed, length_unit, order) {
            found.lock().expect("not poisoned").push(f);
        }
        split.lap(ended, 1);
    };
    match pool.when(frame.parallelism.particles) {
        Some(pool) if muscles.len() > 1 => pool.install(|| {
            for_each_item_in_ranges(muscles, pool.current_num_threads(), &check);
        }),
        _ => muscles
            .iter_mut()
            .enumerate()
            .for_each(|(i, pair)| check(i, pair)),
    }
    faults[first_new..].sort_by_key(|f| f.muscle);
}

/// [`pipeline::publish`] for every (snapshot, muscle) pair: the muscles
/// that other muscles target, in parallel when there are several (in
/// ranges, as [`for_each_muscle`] shares out muscles of similar sizes).
pub fn publish_all(
    pool: &WorkerPool,
    snapshots: &mut [(&mut TargetSurface, &Muscle)],
    it: &IterationParams,
) {
    match pool.when(it.substep.frame.parallelism.particles) {
        Some(pool) if snapshots.len() > 1 => pool.install(|| {
            let publish = |_, (t, m): &mut (&mut TargetSurface, &Muscle)| {
                pipeline::publish(t, m, it);
            };
            for_each_item_in_ranges(snapshots, pool.current_num_threads(), &publish);
        }),
        _ => snapshots
            .iter_mut()
            .for_each(|(t, m)| pipeline::publish(t, m, it)),
    }
}

/// Closest data and projection of every muscle for the block of
/// iterations `it` starts ([`IterationParams::block`]; one iteration
/// unless [`crate::SolverSettings::snapshot_interval`] says more), its
/// time lapped on `clock` into `timings`' closest-data and project blocks.
///
/// One task per muscle running the block's iterations back to back
/// ([`pipeline::iterate`]; a muscle reads the others only through the
/// published snapshots, so the split gives the same bits, and one task
/// keeps the muscle in cache), or — for a clustered or
/// Hybrid plan whose largest muscle would leave threads idle, or when
/// [`super::SweepSchedule::ByColor`] asks — the same phases interleaved:
/// closest data of every muscle, colour `c` of every muscle's plan for each
/// `c`, then every muscle's [`pipeline::finish`], for each iteration of
/// the block.
pub fn iterate_all<T: TargetSet + Sync + ?Sized>(
    pool: &WorkerPool,
    muscles: &mut [MusclePair],
    targets: &T,
    it: &IterationParams,
    clock: &mut Stopwatch,
    timings: &mut StepTimings,
) {
    let frame = &it.substep.frame;
    let pool = pool.when(frame.parallelism.muscles);
    let by_color = pool.is_some()
        && pipeline::plan_kind(frame.method)
            .is_some_and(|(kind, _)| kind != PlanKind::PerConstraint)
        && sweeps_by_color_pay(frame, muscles);
    let Some(pool) = pool.filter(|_| by_color) else {
        let split = TaskSplit::new(clock.is_running());
        lane_groups::iterate_by_muscle(pool, muscles, targets, it, &split);
        let [closest, project] = split.shares();
        let slots = [&mut timings.closest_data, &mut timings.project];
        clock.lap_split(slots, [closest, project], split.reads());
        timings.layers += split.layers();
        return;
    };
    let end = it.block_end();
    for it in it.block() {
        let it = &it;
        timings.sweeps_by_color += 1;
        for_each_muscle(Some(pool), muscles, |m, ws| {
            pipeline::closest(m, ws, targets, it);
        });
        clock.lap(&mut timings.closest_data);
        let mut colors = 0;
        for (m, ws) in muscles.iter_mut() {
            if it.runs(m) {
                colors = colors.max(pipeline::plan_for(m, ws, it).color_count());
            }
        }
        pool.install(|| {
            use rayon::prelude::*;
            for color in 0..colors {
                muscles.par_iter_mut().for_each(|(m, ws)| {
                    if let Some(plan) = pipeline::sweep_plan(ws).filter(|_| it.runs(m)) {
                        sweep::sweep_color(m, plan, color, it.substep.inv_h2);
                    }
                });
            }
        });
        for_each_muscle(Some(pool), muscles, |m, ws| {
            if it.runs(m) {
                pipeline::finish(m, ws, targets, it);
                if it.stages_for(m, end) {
                    pipeline::stage_snapshot(m, ws, targets, it);
                }
            }
        });
        clock.lap(&mut timings.project);
    }
}
