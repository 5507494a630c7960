//! Read inputs: the step's settings, bone poses, activation, parameters,
//! target links, and the step's parameters (core: `Solver::step`'s
//! `begin_step` and `read_inputs`).

use super::{SolverWorkers, StepContext, ValidSettings, pair, surface_of};
use crate::components::*;
use crate::events::SettingsRejected;
use crate::pacing::SimulationPacing;
use crate::relations::{Connections, ConnectsTo};
use crate::settings::{SimulationState, SinewClock, SinewSettings, SinewTimings};
use bevy::prelude::*;
use sinew_core::animation::interpolate_rigid;
use sinew_core::constraints::TargetId;
use sinew_core::glam::Affine3A;
use sinew_core::solver::{FrameParams, Parallelism, Stopwatch, passes, pipeline};
use std::sync::Arc;

/// Validates the settings when they changed, keeping the last valid ones
/// when they fail (with a warning and a [`SettingsRejected`], once).
pub(crate) fn validate_settings(
    settings: Res<SinewSettings>,
    mut valid: ResMut<ValidSettings>,
    mut ctx: ResMut<StepContext>,
    mut commands: Commands,
) {
    if settings.is_changed() || valid.settings.is_none() {
        let core = settings.to_core();
        match core.validate() {
            Ok(()) => {
                ctx.settings.clone_from(&core);
                valid.settings = Some(core);
                valid.rejected = None;
            }
            Err(e) => {
                if valid.rejected.as_ref() != Some(&*settings) {
                    warn!("sinew: settings rejected, keeping the last valid ones: {e}");
                    valid.rejected = Some(settings.clone());
                    let rejected = SettingsRejected { error: Arc::new(e) };
                    commands.write_message(rejected.clone());
                    commands.trigger(rejected);
                }
                ctx.settings = valid.settings.clone().unwrap_or_default();
            }
        }
    }
}

/// Decides how many steps this update runs ([`SimulationPacing`]): the
/// bones are animated for the end time of the last of them.
pub(crate) fn plan_update(
    time: Res<Time>,
    pacing: Res<SimulationPacing>,
    state: Res<SimulationState>,
    mut clock: ResMut<SinewClock>,
    mut ctx: ResMut<StepContext>,
) {
    let steps = pacing.steps(*state, time.delta(), ctx.settings.dt, &mut clock);
    // The steps' end times, added as the steps will add them.
    let mut end_time = clock.time;
    for _ in 0..steps {
        end_time += ctx.settings.step_time();
    }
    ctx.end_time = end_time;
    ctx.steps_this_update = steps;
    clock.steps_last_update = steps;
}

/// Writes keyframed bones' transforms for the end time of the coming step.
pub(crate) fn animate_bone_tracks(
    ctx: Res<StepContext>,
    mut bones: Query<(&BoneTrack, &mut Transform)>,
) {
    for (track, mut transform) in &mut bones {
        if let Some(posed) = track.transform_at(ctx.end_time, &transform) {
            *transform = posed;
        }
    }
}

/// Poses every skeleton for the end time of the coming step: its frames
/// ([`SkeletonFrames`], which the solver reads, [`read_bones`]) and its
/// bones' transforms (for rendering and children).
pub(crate) fn animate_skeletons(
    ctx: Res<StepContext>,
    mut skeletons: Query<(&SkeletonDriver, &mut SkeletonFrames)>,
    mut transforms: Query<&mut Transform>,
    mut values: Local<Vec<f32>>,
) {
    for (driver, mut frames) in &mut skeletons {
        let world = &mut frames.0;
        driver.rig.pose_at(ctx.end_time, &mut values, world);
        for &(entity, body) in &driver.bones {
            if let (Ok(mut t), Some(pose)) = (transforms.get_mut(entity), world.get(body)) {
                *t = Transform::from_matrix(Mat4::from(*pose));
            }
        }
    }
}

/// A bone target added since the last step starts where its bone was (a
/// bone new this frame: where propagation put it), so that muscles linked
/// in this step find it there.
pub(crate) fn place_new_targets(
    mut new_targets: Query<(&BonePose, &GlobalTransform, &mut BoneTarget), Added<BoneTarget>>,
) {
    for (pose, global, mut target) in &mut new_targets {
        let at = if pose.initialized {
            pose.current
        } else {
            global.affine()
        };
        target.0.set_transform(at);
    }
}

/// What [`read_bones`] reads of a bone: where propagation put it, its pose,
/// its sinew track (with its `Transform`, for the scale) and its parent.
type BoneInputs = (
    &'static GlobalTransform,
    &'static mut BonePose,
    Option<(&'static BoneTrack, &'static Transform)>,
    Option<&'static ChildOf>,
);

/// Reads every bone's pose at the step's end time. The update's last step
/// reads them after transform propagation (a skeleton's bones take the
/// frames [`animate_skeletons`] posed exactly: a transform round trip would
/// round them). An earlier step of an update that runs several
/// ([`SimulationPacing`]) poses sinew's own animation at its own end time —
/// tracks as propagation would, skeletons exactly — and interpolates bones
/// the app moves between their poses at the end of the last update and now.
pub(crate) fn read_bones(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut bones: Query<BoneInputs>,
    parents: Query<&GlobalTransform>,
    skeletons: Query<(&SkeletonDriver, &SkeletonFrames)>,
    mut scratch: Local<(Vec<f32>, Vec<Affine3A>)>,
) {
    let mut clock = Stopwatch::new(ctx.settings.timers);
    let (k, steps) = (ctx.step_of_update, ctx.steps_this_update);
    let last = k + 1 >= steps;
    let fraction = (k + 1) as f32 / steps.max(1) as f32;
    for (global, mut pose, track, parent) in &mut bones {
        if k == 0 {
            pose.update_start = pose.current;
        }
        let now = if last {
            global.affine()
        } else if let Some(local) =
            track.and_then(|(track, base)| track.transform_at(ctx.end_time, base))
        {
            match parent.and_then(|p| parents.get(p.parent()).ok()) {
                Some(parent) => parent.mul_transform(local).affine(),
                None => GlobalTransform::from(local).affine(),
            }
        } else if pose.initialized {
            interpolate_rigid(pose.update_start, global.affine(), fraction)
        } else {
            global.affine()
        };
        if pose.initialized {
            pose.previous = pose.current;
        } else {
            pose.previous = now;
            pose.initialized = true;
        }
        pose.current = now;
    }
    let (values, world) = &mut *scratch;
    for (driver, frames) in &skeletons {
        let frames = if last {
            &frames.0
        } else {
            driver.rig.pose_at(ctx.end_time, values, world);
            &*world
        };
        for &(entity, body) in &driver.bones {
            if let (Ok((_, mut pose, _, _)), Some(frame)) =
                (bones.get_mut(entity), frames.get(body))
            {
                pose.current = *frame;
            }
        }
    }
    clock.lap(&mut timings.step.read_inputs);
}

/// Activation curves set the activation of driven muscles (sensors then
/// override it: [`crate::sensors::drive_activation`]).
pub(crate) fn read_activation(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut muscles: Query<(&mut Muscle, &ActivationCurve)>,
) {
    let mut clock = Stopwatch::new(ctx.settings.timers);
    for (mut muscle, curve) in &mut muscles {
        if muscle.driven {
            muscle.activation = curve.0.sample(ctx.end_time);
        }
    }
    clock.lap(&mut timings.step.read_inputs);
}

/// Pushes each muscle's live parameters into its built state (an invalid
/// value is reported once and the last valid parameters are kept).
pub(crate) fn sync_muscles(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut muscles: Query<(&Muscle, &mut MuscleState), Changed<Muscle>>,
) {
    let mut clock = Stopwatch::new(ctx.settings.timers);
    for (muscle, mut state) in &mut muscles {
        let state = &mut *state;
        match muscle.validate(&state.muscle.params, &state.muscle.name) {
            Err(error) => {
                let error = error.to_string();
                if state.rejected.as_ref() != Some(&error) {
                    warn!("sinew: {error}; keeping the last valid parameters");
                    state.rejected = Some(error);
                }
            }
            Ok(()) => {
                state.rejected = None;
                if muscle.write_to(&mut state.muscle.params) {
                    state.muscle.apply_compliances();
                }
            }
        }
    }
    clock.lap(&mut timings.step.read_inputs);
}

/// Reads each muscle's targets from its connections
/// ([`crate::relations::Connections`], in order; targets that are not a
/// bone with a [`BoneTarget`] or a muscle are left out until they are),
/// lays out the step's target table (every targeted entity; each muscle's
/// workspace indexes it), marks which muscles are targeted, and links
/// Sliding / Soft / Hard for muscles that are new or whose targets changed
/// (core: `Solver::prepare`).
pub(crate) fn link_muscles(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut workers: ResMut<SolverWorkers>,
    mut muscles: Query<(
        Entity,
        &mut MuscleState,
        &mut SolverWorkspace,
        Option<&Connections>,
    )>,
    connections: Query<&ConnectsTo>,
    bones: Query<&BoneTarget>,
    mut snapshots: Query<&mut MuscleSnapshot>,
) {
    let mut clock = Stopwatch::new(ctx.settings.timers);
    let SolverWorkers {
        table,
        slots,
        surfaces,
        targets,
        ..
    } = &mut *workers;
    table.clear();
    slots.clear();
    for (entity, mut state, mut ws, links) in &mut muscles {
        let usable = |&e: &Entity| e != entity && (bones.contains(e) || snapshots.contains(e));
        targets.clear();
        targets.extend(
            links
                .into_iter()
                .flat_map(|l| l.iter())
                .filter_map(|c| connections.get(c).ok().map(|t| t.0))
                .filter(usable),
        );
        if *targets != state.connected {
            state.connected.clone_from(targets);
            state.linked = false;
        }
        if state.muscle.constraints.sliding.targets != targets.len() {
            state.linked = false;
        }
        let ids = targets.iter().map(|&e| {
            *slots.entry(e).or_insert_with(|| {
                table.push(e);
                TargetId::new(table.len() - 1)
            })
        });
        let ws = &mut ws.0;
        ws.target_ids.clear();
        ws.target_ids.extend(ids);
    }
    let mut unlinked = false;
    for (entity, state, _, _) in &muscles {
        if let Ok(mut snapshot) = snapshots.get_mut(entity) {
            let targeted = slots.contains_key(&entity);
            if snapshot.targeted != targeted {
                snapshot.targeted = targeted;
            }
        }
        unlinked |= !state.linked;
    }
    if unlinked {
        // Link against every targeted muscle's current geometry.
        for (entity, state, _, _) in &muscles {
            if let Ok(mut snapshot) = snapshots.get_mut(entity)
                && snapshot.targeted
            {
                pipeline::publish_at(&mut snapshot.surface, &state.muscle, true);
            }
        }
        let published = snapshots.as_readonly();
        let table_surfaces = table
            .iter()
            .map(|&e| surface_of(e, &bones, &published).expect("dropped above when missing"));
        surfaces.with(table_surfaces, |surfaces| {
            for (_, mut state, mut ws, _) in &mut muscles {
                if !state.linked {
                    pipeline::link(&mut state.muscle, &mut ws.0, &*surfaces);
                    state.linked = true;
                }
            }
        });
    }
    clock.lap(&mut timings.step.read_inputs);
}

/// The step's parameters ([`FrameParams`]: where the work runs, from the
/// scene's size and the worker count), then every muscle's rest lengths
/// and volume ratio from its activation (core: the end of `begin_step`
/// and `read_inputs`).
pub(crate) fn plan_step(
    mut ctx: ResMut<StepContext>,
    clock: Res<SinewClock>,
    mut timings: ResMut<SinewTimings>,
    mut workers: ResMut<SolverWorkers>,
    mut muscles: Query<(&mut MuscleState, &mut SolverWorkspace)>,
) {
    let mut watch = Stopwatch::new(ctx.settings.timers);
    let workers = &mut *workers;
    workers.pool.sync(ctx.settings.threads);
    let parallelism = Parallelism::decide(
        &ctx.settings,
        workers.pool.is_some(),
        muscles.iter().map(|(s, _)| &s.muscle),
    );
    let frame = FrameParams::new(&ctx.settings, clock.frame, parallelism);
    ctx.iterations = frame.iterations_for(muscles.iter().map(|(s, _)| &s.muscle));
    ctx.frame = frame;
    let always = ctx.settings.parallel_threshold == 0;
    workers.pairs.with(muscles.iter_mut().map(pair), |muscles| {
        passes::update_activations(&workers.pool, muscles, always, |w| warn!("sinew: {w}"));
    });
    watch.lap(&mut timings.step.read_inputs);
}
