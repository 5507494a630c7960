//! The frame loop as systems. Every kernel is `sinew_core`'s
//! ([`sinew_core::solver::stage`]); this module only schedules them over
//! entities, in the order the plain [`sinew_core::Solver::step`] uses, so both
//! drivers give the same bits.

use crate::components::*;
use crate::settings::{SimulationState, SinewClock, SinewSettings, SinewTimings};
use crate::{SinewIterationSchedule, SinewSubstepSchedule};
use bevy::prelude::*;
use sinew_core::SolverSettings;
use sinew_core::animation::interpolate_rigid;
use sinew_core::closest::TargetSurface;
use sinew_core::glam::Affine3A;
use sinew_core::solver::stage;
use std::time::{Duration, Instant};

/// What the step in progress is doing: the settings it runs with, the time
/// step, and which substep and iteration is running. Systems added to the
/// substep and iteration schedules can read it.
#[derive(Resource, Clone, Debug, Default)]
pub struct StepContext {
    /// The validated settings of this step.
    pub settings: SolverSettings,
    /// Simulated time at the end of the step, seconds.
    pub end_time: f32,
    /// Simulated time the step covers (`dt × time_scale`), seconds.
    pub dt: f32,
    /// Substep length, seconds.
    pub h: f32,
    /// Current substep.
    pub substep: u32,
    /// Fraction of the frame reached at the end of the current substep.
    pub alpha: f32,
    /// Current iteration within the substep.
    pub iteration: u32,
    /// Iterations this step runs (`max(global, every muscle's own)`).
    pub iterations: u32,
}

impl StepContext {
    /// Whether the current iteration is the frame's first (full closest-point
    /// searches, snapshot normals and refits).
    pub fn first_iteration_of_frame(&self) -> bool {
        self.iteration == 0 && self.substep == 0
    }
}

/// The last settings that passed validation, and the last rejected ones.
#[derive(Resource, Default)]
pub(crate) struct ValidSettings {
    settings: Option<SolverSettings>,
    rejected: Option<SinewSettings>,
}

/// Run condition: the simulation advances this frame.
pub fn simulation_running(state: Res<SimulationState>) -> bool {
    *state != SimulationState::Paused
}

/// Adds the time since `start` to `slot` when timers are on.
fn lap(on: bool, start: Instant, slot: &mut Duration) {
    if on {
        *slot += start.elapsed();
    }
}

/// Runs `body` on every item of a query: on Bevy's compute pool when the
/// settings allow threads, else in order on this thread (no task spawned).
macro_rules! each_muscle {
    ($query:expr, $threads:expr, $body:expr) => {
        if $threads == 1 {
            $query.iter_mut().for_each($body)
        } else {
            $query.par_iter_mut().for_each($body)
        }
    };
}

/// The targets of a muscle, in its own order (`target_ids = 0..k`); `None`
/// when one has gone (the muscle is relinked next frame).
fn gather_targets<'a>(
    targets: &MuscleTargets,
    bones: &'a Query<&BoneTarget>,
    snapshots: &'a Query<&MuscleSnapshot>,
) -> Option<Vec<&'a TargetSurface>> {
    targets
        .0
        .iter()
        .map(|&e| {
            bones
                .get(e)
                .map(|b| &b.0)
                .or_else(|_| snapshots.get(e).map(|s| &s.surface))
                .ok()
        })
        .collect()
}

// ---------------------------------------------------------------- bones ----

/// Writes keyframed bones' transforms for the end time of the coming step.
pub(crate) fn animate_bone_tracks(
    clock: Res<SinewClock>,
    settings: Res<SinewSettings>,
    mut bones: Query<(&BoneTrack, &mut Transform)>,
) {
    let end_time = clock.time + settings.dt * settings.time_scale;
    for (track, mut transform) in &mut bones {
        if track.0.keys.is_empty() {
            continue;
        }
        let (rotation, translation) = track.0.sample_parts(end_time);
        transform.rotation = rotation;
        transform.translation = translation;
    }
}

/// Poses skeleton-driven bones for the end time of the coming step.
pub(crate) fn animate_skeletons(
    clock: Res<SinewClock>,
    settings: Res<SinewSettings>,
    skeletons: Query<&SkeletonDriver>,
    mut transforms: Query<&mut Transform>,
    mut scratch: Local<(Vec<f32>, Vec<Affine3A>)>,
) {
    let end_time = clock.time + settings.dt * settings.time_scale;
    let (values, world) = &mut *scratch;
    for driver in &skeletons {
        driver.rig.pose_at(end_time, values, world);
        for &(entity, body) in &driver.bones {
            if let (Ok(mut t), Some(pose)) = (transforms.get_mut(entity), world.get(body)) {
                *t = Transform::from_matrix(Mat4::from(*pose));
            }
        }
    }
}

// ---------------------------------------------------------- read inputs ----

/// Validates the settings and opens the step.
pub(crate) fn begin_step(
    settings: Res<SinewSettings>,
    clock: Res<SinewClock>,
    mut valid: ResMut<ValidSettings>,
    mut ctx: ResMut<StepContext>,
    mut timings: ResMut<SinewTimings>,
) {
    let start = Instant::now();
    timings.start_step();
    let core = settings.to_core();
    match core.validate() {
        Ok(()) => {
            valid.settings = Some(core);
            valid.rejected = None;
        }
        Err(e) => {
            if valid.rejected.as_ref() != Some(&*settings) {
                warn!("sinew: settings rejected, keeping the last valid ones: {e}");
                valid.rejected = Some(settings.clone());
            }
        }
    }
    let s = valid.settings.clone().unwrap_or_default();
    let dt = s.dt * s.time_scale;
    *ctx = StepContext {
        end_time: clock.time + dt,
        dt,
        h: dt / s.substeps.max(1) as f32,
        settings: s,
        ..default()
    };
    lap(ctx.settings.timers, start, &mut timings.step.read_inputs);
}

/// A bone target added since the last step starts where its bone was.
pub(crate) fn place_new_targets(
    mut new_targets: Query<(&BonePose, &mut BoneTarget), Added<BoneTarget>>,
) {
    for (pose, mut target) in &mut new_targets {
        let at = if pose.initialized {
            pose.current
        } else {
            Affine3A::IDENTITY
        };
        target.0.set_transform(at);
    }
}

/// Reads every bone's pose after transform propagation.
pub(crate) fn read_bones(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut bones: Query<(&GlobalTransform, &mut BonePose)>,
) {
    let start = Instant::now();
    for (global, mut pose) in &mut bones {
        let now = global.affine();
        if pose.initialized {
            pose.previous = pose.current;
        } else {
            pose.previous = now;
            pose.initialized = true;
        }
        pose.current = now;
    }
    lap(ctx.settings.timers, start, &mut timings.step.read_inputs);
}

/// Activation curves and sensor rigs set the activation of driven muscles.
pub(crate) fn read_activation(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut muscles: Query<(&mut Muscle, Option<&ActivationCurve>)>,
    mut rigs: Query<&mut SensorRig>,
    bones: Query<&BonePose>,
    mut poses: Local<Vec<Affine3A>>,
) {
    let start = Instant::now();
    for (mut muscle, curve) in &mut muscles {
        if let Some(curve) = curve
            && muscle.driven
        {
            muscle.activation = curve.0.sample(ctx.end_time);
        }
    }
    for mut rig in &mut rigs {
        let rig = &mut *rig;
        poses.clear();
        poses.extend(
            rig.bones
                .iter()
                .map(|&b| bones.get(b).map_or(Affine3A::IDENTITY, |pose| pose.current)),
        );
        let targets = &rig.muscles;
        rig.rig.update(&poses, ctx.end_time, ctx.dt, |m, a| {
            if let Some(&entity) = targets.get(m)
                && let Ok((mut muscle, _)) = muscles.get_mut(entity)
                && muscle.driven
            {
                muscle.activation = a;
            }
        });
    }
    lap(ctx.settings.timers, start, &mut timings.step.read_inputs);
}

/// Pushes each muscle's live parameters into its built state and updates
/// the activation-dependent rest data.
pub(crate) fn sync_muscles(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut muscles: Query<(&Muscle, &mut MuscleState)>,
) {
    let start = Instant::now();
    for (muscle, mut state) in &mut muscles {
        let state = &mut *state;
        if let Some((parameter, value, reason)) = muscle.invalid() {
            if state.rejected.as_ref() != Some(muscle) {
                warn!(
                    "sinew: muscle '{}': {parameter} = {value} {reason}; keeping the last valid parameters",
                    state.muscle.name
                );
                state.rejected = Some(muscle.clone());
            }
        } else {
            state.rejected = None;
            if muscle.write_to(&mut state.muscle.params) {
                state.muscle.apply_compliances();
            }
        }
        if let Some(w) = state.muscle.update_activation() {
            warn!("sinew: {w}");
        }
    }
    lap(ctx.settings.timers, start, &mut timings.step.read_inputs);
}

/// Drops targets that are gone, marks which muscles are targeted, and links
/// Sliding / Soft / Hard for muscles that are new or whose targets changed.
pub(crate) fn link_muscles(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut muscles: Query<(Entity, &mut MuscleState, &mut MuscleTargets)>,
    bones: Query<&BoneTarget>,
    mut snapshots: Query<&mut MuscleSnapshot>,
) {
    let start = Instant::now();
    for (entity, mut state, mut targets) in &mut muscles {
        let before = targets.0.len();
        let keep = |&e: &Entity| e != entity && (bones.contains(e) || snapshots.contains(e));
        if !targets.0.iter().all(keep) {
            targets.0.retain(keep);
        }
        if targets.0.len() != before || state.muscle.target_ids.len() != targets.0.len() {
            state.linked = false;
        }
    }
    if muscles.iter().all(|(_, state, _)| state.linked) {
        lap(ctx.settings.timers, start, &mut timings.step.read_inputs);
        return;
    }
    // Link against every targeted muscle's current geometry.
    for (entity, state, _) in &muscles {
        let Ok(mut snapshot) = snapshots.get_mut(entity) else {
            continue;
        };
        snapshot.targeted = muscles.iter().any(|(_, _, t)| t.0.contains(&entity));
        if snapshot.targeted {
            stage::publish(&mut snapshot.surface, &state.muscle, true);
        }
    }
    let published = snapshots.as_readonly();
    for (_, mut state, targets) in &mut muscles {
        if state.linked {
            continue;
        }
        let Some(surfaces) = gather_targets(&targets, &bones, &published) else {
            continue;
        };
        let state = &mut *state;
        state.muscle.target_ids = (0..surfaces.len()).collect();
        stage::link_muscle(&mut state.muscle, surfaces.as_slice());
        state.linked = true;
    }
    lap(ctx.settings.timers, start, &mut timings.step.read_inputs);
}

// -------------------------------------------------------------- substeps ----

/// Runs the substep schedule `substeps` times, then closes the step.
pub(crate) fn run_substeps(world: &mut World) {
    let substeps = world.resource::<StepContext>().settings.substeps.max(1);
    for s in 0..substeps {
        {
            let mut ctx = world.resource_mut::<StepContext>();
            ctx.substep = s;
            ctx.alpha = (s + 1) as f32 / substeps as f32;
        }
        world.run_schedule(SinewSubstepSchedule);
    }
    let end_time = world.resource::<StepContext>().end_time;
    let mut clock = world.resource_mut::<SinewClock>();
    clock.time = end_time;
    clock.frame += 1;
    let mut state = world.resource_mut::<SimulationState>();
    if *state == SimulationState::StepOnce {
        *state = SimulationState::Paused;
    }
}

/// Every bone's pose at the substep's end time, and its target moved there.
pub(crate) fn pose_bones(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut bones: Query<(&mut BonePose, Option<&mut BoneTarget>)>,
) {
    let start = Instant::now();
    for (mut pose, target) in &mut bones {
        pose.substep = interpolate_rigid(pose.previous, pose.current, ctx.alpha);
        if let Some(mut target) = target {
            target.0.set_transform(pose.substep);
        }
    }
    lap(ctx.settings.timers, start, &mut timings.step.update_targets);
}

/// Attachment goals at the substep's end time.
pub(crate) fn update_attachment_goals(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut muscles: Query<(&mut MuscleState, &AttachmentBones)>,
    poses: Query<&BonePose>,
) {
    let start = Instant::now();
    for (mut state, attached) in &mut muscles {
        let state = &mut *state;
        // A bone that has gone keeps its last pose: its attachments stay put.
        state
            .bone_poses
            .resize(attached.0.len(), Affine3A::IDENTITY);
        for (cached, &bone) in state.bone_poses.iter_mut().zip(&attached.0) {
            if let Ok(p) = poses.get(bone) {
                *cached = p.substep;
            }
        }
        let cached = &state.bone_poses;
        let pose = |b: Option<usize>| {
            b.and_then(|b| cached.get(b).copied())
                .unwrap_or(Affine3A::IDENTITY)
        };
        stage::update_attachment_goals(&mut state.muscle, &pose);
    }
    lap(ctx.settings.timers, start, &mut timings.step.update_targets);
}

/// Prediction, pins, λ = 0 (and the momentum a free muscle keeps).
pub(crate) fn integrate(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut muscles: Query<&mut MuscleState>,
) {
    let start = Instant::now();
    let s = &ctx.settings;
    let gravity = s.gravity / s.space_scale;
    let damping_exp = 1.0 / s.substeps.max(1) as f32;
    let h = ctx.h;
    each_muscle!(muscles, s.threads, |mut state: Mut<MuscleState>| {
        let state = &mut *state;
        state.momentum = stage::begin_substep(&mut state.muscle, gravity, h, damping_exp);
    });
    lap(s.timers, start, &mut timings.step.integrate);
}

/// Runs the iteration schedule `iterations` times.
pub(crate) fn run_iterations(world: &mut World) {
    let global = world.resource::<StepContext>().settings.iterations;
    let mut muscles = world.query::<&MuscleState>();
    let iterations = muscles
        .iter(world)
        .map(|s| s.muscle.params.iterations.unwrap_or(global))
        .max()
        .unwrap_or(global)
        .max(global);
    world.resource_mut::<StepContext>().iterations = iterations;
    for it in 0..iterations {
        world.resource_mut::<StepContext>().iteration = it;
        world.run_schedule(SinewIterationSchedule);
    }
}

/// `v = (p − x)/h`, `x = p` (and a free muscle's momentum restored).
pub(crate) fn apply_predictions(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut muscles: Query<&mut MuscleState>,
) {
    let start = Instant::now();
    let h = ctx.h;
    each_muscle!(muscles, ctx.settings.threads, |mut state: Mut<
        MuscleState,
    >| {
        let state = &mut *state;
        stage::end_substep(&mut state.muscle, h, state.momentum);
    });
    lap(ctx.settings.timers, start, &mut timings.step.apply);
}

// ------------------------------------------------------------ iterations ----

/// Publishes every targeted muscle's predictions as its snapshot.
pub(crate) fn publish_snapshots(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut muscles: Query<(&MuscleState, &mut MuscleSnapshot)>,
) {
    let start = Instant::now();
    let first = ctx.first_iteration_of_frame();
    for (state, mut snapshot) in &mut muscles {
        if snapshot.targeted {
            stage::publish(&mut snapshot.surface, &state.muscle, first);
        }
    }
    lap(ctx.settings.timers, start, &mut timings.step.update_targets);
}

/// Closest points on the targets (BE5).
pub(crate) fn closest_data(
    ctx: Res<StepContext>,
    clock: Res<SinewClock>,
    mut timings: ResMut<SinewTimings>,
    mut muscles: Query<(&mut MuscleState, &MuscleTargets)>,
    bones: Query<&BoneTarget>,
    snapshots: Query<&MuscleSnapshot>,
) {
    let start = Instant::now();
    let s = &ctx.settings;
    let full = ctx.first_iteration_of_frame();
    let search = stage::ClosestSchedule {
        frame: clock.frame,
        interval: s.full_search_interval.max(1),
        choose_interval: s.choose_interval.max(1),
        feature_contacts: s.feature_contacts,
        active: full,
        walk: full || s.walk_every_iteration,
        substep_start: ctx.iteration == 0,
        parallel: s.threads != 1,
    };
    let (it, global) = (ctx.iteration, s.iterations);
    each_muscle!(muscles, s.threads, |(mut state, targets): (
        Mut<MuscleState>,
        &MuscleTargets
    )| {
        let m = &mut state.muscle;
        if it >= m.params.iterations.unwrap_or(global) || m.target_ids.is_empty() {
            return;
        }
        if let Some(surfaces) = gather_targets(targets, &bones, &snapshots) {
            stage::closest_data(m, surfaces.as_slice(), search);
        }
    });
    lap(s.timers, start, &mut timings.step.closest_data);
}

/// Projects every constraint once (BE6), with the configured method.
pub(crate) fn project(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut muscles: Query<(&mut MuscleState, &MuscleTargets)>,
    bones: Query<&BoneTarget>,
    snapshots: Query<&MuscleSnapshot>,
) {
    let start = Instant::now();
    let s = &ctx.settings;
    let inv_h2 = 1.0 / (ctx.h * ctx.h);
    let (it, global, method, parallel) = (ctx.iteration, s.iterations, s.method, s.threads != 1);
    let order = s.projection_order.as_slice();
    each_muscle!(muscles, s.threads, |(mut state, targets): (
        Mut<MuscleState>,
        &MuscleTargets
    )| {
        let m = &mut state.muscle;
        if it >= m.params.iterations.unwrap_or(global) {
            return;
        }
        let surfaces = gather_targets(targets, &bones, &snapshots).unwrap_or_default();
        if surfaces.len() != m.target_ids.len() {
            // A target went missing mid-step: project without contacts.
            let saved = std::mem::take(&mut m.target_ids);
            let none: &[&TargetSurface] = &[];
            stage::project_iteration(m, method, order, none, inv_h2, parallel, it == 0);
            m.target_ids = saved;
            return;
        }
        stage::project_iteration(
            m,
            method,
            order,
            surfaces.as_slice(),
            inv_h2,
            parallel,
            it == 0,
        );
    });
    lap(s.timers, start, &mut timings.step.project);
}

// ------------------------------------------------------------ write back ----

/// Closes the step's timings.
pub(crate) fn finish_timings(mut timings: ResMut<SinewTimings>) {
    timings.finish_step();
}
