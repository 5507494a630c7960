//! The substeps and iterations (core: the body of `Solver::step`): bones
//! posed at the substep, attachment goals, then the core's passes over
//! every muscle on the plug-in's worker pool.

use super::{SolverWorkers, StepContext, pair, surface_of};
use crate::components::*;
use crate::events::MuscleFaulted;
use crate::settings::{SimulationState, SinewClock, SinewTimings};
use crate::{SinewIterationSchedule, SinewSubstepSchedule};
use bevy::prelude::*;
use sinew_core::animation::interpolate_rigid;
use sinew_core::closest::TargetSurface;
use sinew_core::constraints::TargetId;
use sinew_core::glam::Affine3A;
use sinew_core::solver::{Stopwatch, guard, passes, pipeline};
use std::cell::Cell;
use std::sync::Arc;

/// Runs the substep schedule once per substep, then closes the step. With
/// worker threads the substeps run on one of them (as the plain solver's
/// frame does), so the passes inside reach the others without a
/// cross-thread hand-off each: systems added to [`SinewSubstepSchedule`]
/// and [`SinewIterationSchedule`] then run on that worker thread.
pub(crate) fn run_substeps(world: &mut World) {
    let threads = world.resource::<SolverWorkers>().pool.threads();
    match threads {
        Some(threads) => threads.install(|| substeps(world)),
        None => substeps(world),
    }
    let dt = world.resource::<StepContext>().frame.dt;
    let mut clock = world.resource_mut::<SinewClock>();
    clock.time += dt;
    clock.frame += 1;
    let mut state = world.resource_mut::<SimulationState>();
    if *state == SimulationState::StepOnce {
        *state = SimulationState::Paused;
    }
}

/// The substep schedule, once per substep.
fn substeps(world: &mut World) {
    let frame = world.resource::<StepContext>().frame;
    for s in 0..frame.substeps {
        world.resource_mut::<StepContext>().substep = frame.substep(s);
        world.run_schedule(SinewSubstepSchedule);
    }
}

/// Every bone's pose at the substep's end time — a skeleton's bones from
/// the skeleton itself, others interpolated rigidly between the frame's
/// start and end poses — and its target moved there.
pub(crate) fn pose_bones(
    ctx: Res<StepContext>,
    clock: Res<SinewClock>,
    mut timings: ResMut<SinewTimings>,
    mut bones: Query<(&mut BonePose, Option<&mut BoneTarget>)>,
    skeletons: Query<&SkeletonDriver>,
    mut scratch: Local<(Vec<f32>, Vec<Affine3A>)>,
) {
    let mut watch = Stopwatch::new(ctx.settings.timers);
    let alpha = ctx.substep.alpha;
    for (mut pose, _) in &mut bones {
        pose.substep = interpolate_rigid(pose.previous, pose.current, alpha);
    }
    if alpha < 1.0 {
        let (values, world) = &mut *scratch;
        for driver in &skeletons {
            driver
                .rig
                .pose_at(clock.time + alpha * ctx.frame.dt, values, world);
            for &(entity, body) in &driver.bones {
                if let (Ok((mut pose, _)), Some(frame)) = (bones.get_mut(entity), world.get(body)) {
                    pose.substep = *frame;
                }
            }
        }
    }
    for (pose, target) in &mut bones {
        if let Some(mut target) = target {
            target.0.set_transform(pose.substep);
        }
    }
    watch.lap(&mut timings.step.update_targets);
}

/// Attachment goals at the substep's bone poses, then the prediction, pins
/// and λ = 0 of every muscle ([`passes::begin_substep_all`]).
pub(crate) fn begin_substep(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut workers: ResMut<SolverWorkers>,
    mut muscles: Query<(&mut MuscleState, &mut SolverWorkspace)>,
    poses: Query<&BonePose>,
) {
    let mut watch = Stopwatch::new(ctx.settings.timers);
    for (mut state, _) in &mut muscles {
        let MuscleState {
            muscle,
            attached,
            bone_poses,
            bound_bones,
            bind_poses,
            ..
        } = &mut *state;
        cache_substep_poses(bone_poses, attached.iter().map(|&(_, bone)| bone), &poses);
        // A skin binding numbers its bones apart from the attachments.
        cache_substep_poses(bind_poses, bound_bones.iter().copied().map(Some), &poses);
        let pose = |b: Option<usize>| {
            b.and_then(|b| bone_poses.get(b).copied())
                .unwrap_or(Affine3A::IDENTITY)
        };
        let bind_pose = |b: usize| bind_poses.get(b).copied().unwrap_or(Affine3A::IDENTITY);
        pipeline::update_attachment_goals(muscle, &pose, &bind_pose);
    }
    watch.lap(&mut timings.step.update_targets);
    let workers = &mut *workers;
    let pairs = muscles.iter_mut().map(pair);
    workers.pairs.with(pairs, |muscles| {
        // The goals were moved above, from each muscle's cached bone poses.
        passes::begin_substep_all(&workers.pool, muscles, &ctx.substep, |_| {});
    });
    watch.lap(&mut timings.step.integrate);
}

/// Refreshes `cache` with the substep pose of each of `bones` (`None`: the
/// world); a bone that goes within the step keeps its last pose (its
/// attachments are dropped on the next step).
fn cache_substep_poses(
    cache: &mut Vec<Affine3A>,
    bones: impl ExactSizeIterator<Item = Option<Entity>>,
    poses: &Query<&BonePose>,
) {
    cache.resize(bones.len(), Affine3A::IDENTITY);
    for (cached, bone) in cache.iter_mut().zip(bones) {
        if let Some(p) = bone.and_then(|b| poses.get(b).ok()) {
            *cached = p.substep;
        }
    }
}

/// Runs the iteration schedule once per block of iterations
/// ([`sinew_core::SolverSettings::snapshot_interval`]; once per iteration
/// by default): the context's iteration is the block's first.
pub(crate) fn run_iterations(world: &mut World) {
    let ctx = world.resource::<StepContext>();
    let (substep, iterations) = (ctx.substep, ctx.iterations);
    for block in substep.blocks(iterations) {
        world.resource_mut::<StepContext>().iteration = block;
        world.run_schedule(SinewIterationSchedule);
    }
}

/// `v = (p − x)/h`, `x = p` for every muscle ([`passes::end_substep_all`]).
pub(crate) fn end_substep(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut workers: ResMut<SolverWorkers>,
    mut muscles: Query<(&mut MuscleState, &mut SolverWorkspace)>,
) {
    let mut watch = Stopwatch::new(ctx.settings.timers);
    let workers = &mut *workers;
    workers.pairs.with(muscles.iter_mut().map(pair), |muscles| {
        passes::end_substep_all(&workers.pool, muscles, &ctx.substep);
    });
    watch.lap(&mut timings.step.apply);
}

/// The run-time guard over every muscle after the step
/// ([`sinew_core::solver::guard()`], as the plain solver runs it): a muscle
/// that blew up is put back to its last good frame and reported as a
/// [`MuscleFaulted`] message and entity event (logged on its first fault).
pub(crate) fn guard_muscles(
    mut commands: Commands,
    ctx: Res<StepContext>,
    clock: Res<SinewClock>,
    mut muscles: Query<(Entity, &mut MuscleState, &mut SolverWorkspace)>,
) {
    let unit = ctx.settings.length_unit;
    let max_speed = ctx.settings.max_speed * unit;
    let order = ctx.frame.order;
    for (i, (entity, mut state, mut ws)) in muscles.iter_mut().enumerate() {
        let m = &mut state.muscle;
        let found = guard(
            m,
            &mut ws.0,
            clock.frame,
            i,
            max_speed,
            unit,
            order.as_slice(),
        );
        if let Some(fault) = found {
            if fault.count == 1 {
                warn!("sinew: {fault}");
            }
            let faulted = MuscleFaulted {
                entity,
                fault: Arc::new(fault),
            };
            commands.write_message(faulted.clone());
            commands.trigger(faulted);
        }
    }
}

/// Publishes every targeted muscle's predictions as its snapshot
/// ([`passes::publish_all`]).
pub(crate) fn publish_snapshots(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut workers: ResMut<SolverWorkers>,
    mut muscles: Query<(&MuscleState, &mut MuscleSnapshot)>,
) {
    let mut watch = Stopwatch::new(ctx.settings.timers);
    let workers = &mut *workers;
    let snapshots = muscles
        .iter_mut()
        .filter(|(_, snapshot)| snapshot.targeted)
        .map(|(state, snapshot)| (&mut snapshot.into_inner().surface, &state.muscle));
    workers.snapshots.with(snapshots, |snapshots| {
        passes::publish_all(&workers.pool, snapshots, &ctx.iteration);
    });
    watch.lap(&mut timings.step.update_targets);
}

/// Closest data and projection of every muscle ([`passes::iterate_all`]:
/// one task per muscle, or colour sweeps across muscles), against the
/// step's target table.
pub(crate) fn iterate(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut workers: ResMut<SolverWorkers>,
    mut muscles: Query<(&mut MuscleState, &mut SolverWorkspace)>,
    bones: Query<&BoneTarget>,
    snapshots: Query<&MuscleSnapshot>,
) {
    let mut watch = Stopwatch::new(ctx.settings.timers);
    let SolverWorkers {
        pool,
        pairs,
        surfaces,
        table,
        gone,
        ..
    } = &mut *workers;
    let missing = Cell::new(false);
    let table_surfaces = table.iter().map(|&e| {
        surface_of(e, &bones, &snapshots).unwrap_or_else(|| {
            missing.set(true);
            gone
        })
    });
    surfaces.with(table_surfaces, |surfaces| {
        let timings = &mut timings.step;
        // A target was despawned during the step: the muscles that read it
        // run without contacts until it is dropped from their targets.
        let saved: Vec<_> = if missing.get() {
            let gone: &TargetSurface = gone;
            let lost: Vec<TargetId> = (0..surfaces.len())
                .filter(|&t| std::ptr::eq(surfaces[t], gone))
                .map(TargetId::new)
                .collect();
            muscles
                .iter_mut()
                .map(|(_, mut ws)| {
                    let reads_lost = ws.0.target_ids.iter().any(|t| lost.contains(t));
                    reads_lost.then(|| std::mem::take(&mut ws.0.target_ids))
                })
                .collect()
        } else {
            Vec::new()
        };
        pairs.with(muscles.iter_mut().map(pair), |muscles| {
            passes::iterate_all(
                pool,
                muscles,
                &*surfaces,
                &ctx.iteration,
                &mut watch,
                timings,
            );
        });
        for ((_, mut ws), ids) in muscles.iter_mut().zip(saved) {
            if let Some(ids) = ids {
                ws.0.target_ids = ids;
            }
        }
    });
}

/// Closes the step's timings.
pub(crate) fn finish_timings(mut timings: ResMut<SinewTimings>) {
    timings.finish_step();
}
