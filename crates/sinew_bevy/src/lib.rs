//! # `sinew_bevy`
//!
//! The [Bevy](https://bevyengine.org) plug-in for the sinew muscle solver.
//! Muscles, bones and sensors are entities; the frame loop of
//! [`sinew_core::Solver::step`] runs as ordered systems over them, calling
//! the same phases ([`sinew_core::solver::passes`]) with the same
//! parameters, so both drivers give the same bits.
//!
//! ```no_run
//! use bevy::prelude::*;
//! use sinew_bevy::prelude::*;
//!
//! App::new()
//!     .add_plugins(MinimalPlugins)
//!     .add_plugins(bevy::transform::TransformPlugin)
//!     .add_plugins(SinewPlugin::default().iterations(10).substeps(2))
//!     .run();
//! ```
//!
//! ## Frame loop
//!
//! The simulation follows Bevy's [`Time`]: every step is
//! [`SinewSettings::dt`] long and an update runs as many steps as the time
//! since the last one holds (none, one or several; at most
//! [`SimulationPacing::max_steps_per_update`], the rest dropped when the
//! app falls behind), with bones read at each step's own end time. For
//! batch runs, one step per update: [`SinewPlugin::every_update`].
//!
//! By default everything runs in [`PostUpdate`], after the same frame's
//! transform propagation, so bones moved by `bevy_animation` or by user
//! systems are seen without a frame of lag:
//!
//! ```text
//! PostUpdate
//!   SinewSystems::Prepare         runs SinewPrepareSchedule:
//!     (resets, muscle builds, scene spawns)
//!     SinewSystems::AnimateBones    validated settings; scene tracks and skeletons
//!                                   at the step's end time
//!   TransformSystems::Propagate
//!   SinewSystems::Step            runs SinewStepSchedule once per step of the update:
//!     SinewSystems::ReadInputs      bone poses, activation (curves, sensors), parameters,
//!                                   target table and links, FrameParams, rest lengths
//!     SinewSystems::Substeps        runs SinewSubstepSchedule once per substep:
//!       SinewSystems::Integrate       bones and their targets at the substep, attachment
//!                                     goals, prediction (passes::begin_substep_all)
//!       SinewSystems::Iterate         runs SinewIterationSchedule once per block of
//!                                     snapshot_interval iterations (1 by default):
//!         SinewIterationSystems::UpdateTargets   snapshots (passes::publish_all)
//!         SinewIterationSystems::Solve           closest data and projection
//!                                                (passes::iterate_all)
//!       SinewSystems::ApplyPredictions  v = (p − x)/h, x = p (passes::end_substep_all)
//!     SinewSystems::WriteBack       render meshes, timings
//! ```
//!
//! The four sinew schedules run their chains on the single-threaded
//! executor (no thread hand-off between systems); add your own systems to
//! them with the sets above, e.g.
//! `app.add_systems(SinewStepSchedule, my_system.after(SinewSystems::ReadInputs).before(SinewSystems::Substeps))`.
//!
//! ## Threads
//!
//! The plug-in owns a worker pool of [`SinewSettings::threads`] threads
//! (`1`: none, the step runs on the thread that runs the schedule; `0`: one
//! per core), as the plain solver does: muscles, and the chunks inside a
//! large muscle, run on it, and [`SinewSettings::schedule`] and
//! [`SinewSettings::parallel_threshold`] mean what they mean there. Any
//! count gives the same bits.
//!
//! ## Features
//!
//! - `render` (default): muscle and bone meshes ([`render`]), rewritten
//!   every frame, tinted by activation.
//! - `ui` (default): [`ui::SinewUiPlugin`], the egui tuning panel.
//! - `debug` (default): [`debug::SinewDebugPlugin`], gizmos.
//! - `gltf` (default): skinned glTF characters played by `bevy_animation`
//!   drive muscles ([`character`]).
//! - `hot_reload` (default): scene files are watched (Bevy's
//!   `file_watcher`); an edited `.ron` scene is spawned again ([`save`]).
//!
//! Without features the plug-in runs headless with `MinimalPlugins`.

pub mod build;
#[cfg(feature = "render")]
pub mod capture;
#[cfg(feature = "gltf")]
pub mod character;
pub mod components;
mod constraint_table;
#[cfg(feature = "debug")]
pub mod debug;
pub mod events;
#[cfg(feature = "render")]
pub mod mesh_maps;
#[cfg(feature = "ui")]
pub mod orbit;
mod pacing;
pub mod relations;
#[cfg(feature = "render")]
pub mod render;
pub mod save;
pub mod scene;
pub mod sensors;
pub mod settings;
mod systems;
#[cfg(feature = "ui")]
pub mod ui;
#[cfg(feature = "render")]
pub mod view;

use bevy::ecs::intern::Interned;
use bevy::ecs::schedule::{ScheduleLabel, SingleThreadedExecutor};
use bevy::prelude::*;
use bevy::transform::TransformSystems;
use components::*;
pub use pacing::{PacingMode, SimulationPacing};
use settings::*;
pub use systems::{StepContext, simulation_running};

/// The commonly used items.
pub mod prelude {
    pub use crate::build::{BuildFailed, MuscleAttachment, MuscleBuilder, MuscleSource};
    #[cfg(feature = "render")]
    pub use crate::capture::SinewScreenshotPlugin;
    #[cfg(feature = "gltf")]
    pub use crate::character::{
        CharacterJointError, ClipBlendIn, GltfCharacters, OnCharacter, PlacedOnCharacter,
    };
    pub use crate::components::{
        ActivationCurve, BonePose, BoneTarget, BoneTrack, Compliance, ConstraintSet,
        ConstraintSets, FiberMode, Muscle, MuscleSnapshot, MuscleState, SinewBone, SkeletonDriver,
        SkeletonFrames, SolverWorkspace, Weights,
    };
    #[cfg(feature = "debug")]
    pub use crate::debug::{SinewDebugPlugin, SinewDebugView};
    pub use crate::events::{
        AttachmentRejected, MuscleAttached, MuscleBuildError, MuscleBuildFailed, MuscleBuilt,
        MuscleDetached, MuscleFaulted, SettingsRejected, SinewLog,
    };
    pub use crate::relations::{
        AttachedTo, AttachmentOf, AttachmentRegion, Attachments, ConnectedFrom, ConnectionOf,
        Connections, ConnectsTo, HeldAttachments, HeldVertices,
    };
    #[cfg(feature = "render")]
    pub use crate::render::{BoneMesh, MuscleMesh, SkinLayerMesh, TargetFromMesh};
    pub use crate::save::{SaveScene, SceneSaveError, SceneSaveFailed, SceneSaved};
    pub use crate::scene::{SinewScene, SinewSceneRoot, SpawnedScene};
    pub use crate::sensors::{
        ActivationDrive, ReadsSensor, Sensor, SensorInputOf, SensorInputs, SensorReaders,
        SensorReading, SensorSlot,
    };
    pub use crate::settings::{Method, SimulationState, SinewClock, SinewSettings, SinewTimings};
    #[cfg(feature = "render")]
    pub use crate::view::SinewView;
    pub use crate::{
        PacingMode, ResetSimulation, SimulationPacing, SinewIterationSchedule,
        SinewIterationSystems, SinewPlugin, SinewPrepareSchedule, SinewStepSchedule,
        SinewSubstepSchedule, SinewSystems, StepContext,
    };
    #[cfg(feature = "ui")]
    pub use crate::{orbit::OrbitCamera, ui::SinewUiPlugin};
}

/// The plug-in's system sets, in the order they run.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SinewSystems {
    /// In the plug-in's schedule ([`PostUpdate`] by default), before
    /// transform propagation: runs [`SinewPrepareSchedule`] (resets, muscle
    /// builds, scene spawns, [`SinewSystems::AnimateBones`]).
    Prepare,
    /// In the plug-in's schedule, after transform propagation: runs
    /// [`SinewStepSchedule`], the step ([`SinewSystems::ReadInputs`],
    /// [`SinewSystems::Substeps`], [`SinewSystems::WriteBack`]).
    Step,
    /// In [`SinewPrepareSchedule`]: scene bone tracks and skeletons write
    /// bone `Transform`s for the end of the coming step.
    AnimateBones,
    /// In [`SinewStepSchedule`]: bone poses, activation from curves and
    /// sensors, parameter edits, target links.
    ReadInputs,
    /// In [`SinewStepSchedule`]: the substep loop (runs
    /// [`SinewSubstepSchedule`]).
    Substeps,
    /// In [`SinewSubstepSchedule`]: bones, their targets and attachment
    /// goals at the substep's end time, then the prediction.
    Integrate,
    /// In [`SinewSubstepSchedule`]: runs [`SinewIterationSchedule`] once per
    /// block of [`SinewSettings::snapshot_interval`] iterations (N times by
    /// default).
    Iterate,
    /// In [`SinewSubstepSchedule`]: velocities from the corrections.
    ApplyPredictions,
    /// In [`SinewStepSchedule`]: render meshes rewritten; timings closed.
    WriteBack,
}

/// The sets of one block of solver iterations (one iteration unless
/// [`SinewSettings::snapshot_interval`] says more), in
/// [`SinewIterationSchedule`].
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SinewIterationSystems {
    /// Muscle snapshots published for the muscles that target them.
    UpdateTargets,
    /// Closest points on the targets and constraint projection, in one task
    /// per muscle running the block's iterations back to back (or colour by
    /// colour across muscles).
    Solve,
}

/// What runs before transform propagation, once a frame: resets, muscle
/// builds, scene spawns, then [`SinewSystems::AnimateBones`].
#[derive(ScheduleLabel, Clone, Debug, PartialEq, Eq, Hash)]
pub struct SinewPrepareSchedule;

/// The step, once a frame after transform propagation:
/// [`SinewSystems::ReadInputs`], [`SinewSystems::Substeps`],
/// [`SinewSystems::WriteBack`].
#[derive(ScheduleLabel, Clone, Debug, PartialEq, Eq, Hash)]
pub struct SinewStepSchedule;

/// One substep: [`SinewSystems::Integrate`], [`SinewSystems::Iterate`],
/// [`SinewSystems::ApplyPredictions`].
#[derive(ScheduleLabel, Clone, Debug, PartialEq, Eq, Hash)]
pub struct SinewSubstepSchedule;

/// One block of iterations: [`SinewIterationSystems`] (the snapshots
/// published once, then each muscle's iterations of the block).
#[derive(ScheduleLabel, Clone, Debug, PartialEq, Eq, Hash)]
pub struct SinewIterationSchedule;

/// Sent to put every scene back to its first frame and the clock to zero.
#[derive(Message, Clone, Copy, Debug, Default)]
pub struct ResetSimulation;

/// The simulation plug-in. Settings are set with the builder methods and
/// live in the [`SinewSettings`] resource afterwards.
///
/// ```
/// use sinew_bevy::prelude::*;
/// let plugin = SinewPlugin::default()
///     .iterations(5)
///     .substeps(2)
///     .method(Method::Jacobi { omega: 1.5 })
///     .threads(1)
///     .length_unit(100.0); // a scene in centimetres
/// ```
#[derive(Clone, Debug)]
pub struct SinewPlugin {
    schedule: Interned<dyn ScheduleLabel>,
    settings: SinewSettings,
    pacing: SimulationPacing,
}

impl Default for SinewPlugin {
    fn default() -> Self {
        Self {
            schedule: PostUpdate.intern(),
            settings: SinewSettings::default(),
            pacing: SimulationPacing::default(),
        }
    }
}

impl SinewPlugin {
    /// Runs the simulation in `schedule` instead of [`PostUpdate`]. Bones are
    /// read after [`TransformSystems::Propagate`] when that schedule has it.
    pub fn in_schedule(mut self, schedule: impl ScheduleLabel) -> Self {
        self.schedule = schedule.intern();
        self
    }

    /// Starts from these settings.
    pub fn settings(mut self, settings: SinewSettings) -> Self {
        self.settings = settings;
        self
    }

    /// Iterations per substep.
    pub fn iterations(mut self, iterations: u32) -> Self {
        self.settings.iterations = iterations;
        self
    }

    /// Substeps per step.
    pub fn substeps(mut self, substeps: u32) -> Self {
        self.settings.substeps = substeps;
        self
    }

    /// Projection method.
    pub fn method(mut self, method: Method) -> Self {
        self.settings.method = method;
        self
    }

    /// Worker threads of the solver pool: `1` runs everything on the thread
    /// that runs the schedule, `0` uses one per core.
    pub fn threads(mut self, threads: u32) -> Self {
        self.settings.threads = threads;
        self
    }

    /// Scene units per metre (`100` for a scene in centimetres): gravity,
    /// densities, Volume's compliance and lengths such as the contact reach
    /// are converted to match ([`SinewSettings::length_unit`]).
    pub fn length_unit(mut self, units_per_metre: f32) -> Self {
        self.settings.length_unit = units_per_metre;
        self
    }

    /// The fixed step in seconds (one step per `dt` of app time).
    pub fn dt(mut self, dt: f32) -> Self {
        self.settings.dt = dt;
        self
    }

    /// Gravity in m/s².
    pub fn gravity(mut self, gravity: Vec3) -> Self {
        self.settings.gravity = gravity;
        self
    }

    /// How the simulation follows the app's updates (default: real time,
    /// steps of `dt` as [`Time`] advances, at most 4 an update).
    pub fn pacing(mut self, pacing: SimulationPacing) -> Self {
        self.pacing = pacing;
        self
    }

    /// One step per app update, whatever time it took (offline runs,
    /// frame-by-frame comparisons): `pacing` with [`PacingMode::EveryUpdate`].
    pub fn every_update(mut self) -> Self {
        self.pacing.mode = PacingMode::EveryUpdate;
        self
    }
}

impl Plugin for SinewPlugin {
    fn build(&self, app: &mut App) {
        #[cfg(feature = "gltf")]
        character::register_reflected_types(app);
        app.insert_resource(self.settings.clone())
            .insert_resource(self.pacing)
            .register_type::<SimulationPacing>()
            .add_systems(First, pacing::lock_time_to_steps)
            .init_resource::<SinewClock>()
            .init_resource::<SinewTimings>()
            .init_resource::<SimulationState>()
            .init_resource::<StepContext>()
            .init_resource::<systems::ValidSettings>()
            .init_resource::<systems::SolverWorkers>()
            .init_resource::<save::SavedScenes>()
            .add_message::<ResetSimulation>()
            .add_message::<events::MuscleBuilt>()
            .add_observer(settings::restart_timing_history)
            .add_message::<events::MuscleBuildFailed>()
            .add_message::<events::SettingsRejected>()
            .add_message::<events::MuscleAttached>()
            .add_message::<events::MuscleDetached>()
            .add_message::<events::AttachmentRejected>()
            .add_message::<events::MuscleFaulted>()
            .add_message::<save::SaveScene>()
            .add_message::<save::SceneSaved>()
            .add_message::<save::SceneSaveFailed>()
            .init_resource::<events::SinewLog>()
            .register_type::<SinewSettings>()
            .register_type::<SinewClock>()
            .register_type::<SinewTimings>()
            .register_type::<SimulationState>()
            .register_type::<SinewBone>()
            .register_type::<BonePose>()
            .register_type::<Muscle>()
            .register_type::<ConstraintSets>()
            .register_type::<relations::AttachmentOf>()
            .register_type::<relations::Attachments>()
            .register_type::<relations::AttachedTo>()
            .register_type::<relations::HeldAttachments>()
            .register_type::<relations::AttachmentRegion>()
            .register_type::<relations::ConnectionOf>()
            .register_type::<relations::Connections>()
            .register_type::<relations::ConnectsTo>()
            .register_type::<relations::ConnectedFrom>()
            .register_type::<sensors::SensorReading>()
            .register_type::<sensors::SensorInputOf>()
            .register_type::<sensors::SensorInputs>()
            .register_type::<sensors::ReadsSensor>()
            .register_type::<sensors::SensorReaders>()
            .register_type::<sensors::SensorSlot>();
        for label in [
            SinewPrepareSchedule.intern(),
            SinewStepSchedule.intern(),
            SinewSubstepSchedule.intern(),
            SinewIterationSchedule.intern(),
        ] {
            let mut schedule = Schedule::new(label);
            // Chains of systems, each depending on the last: the
            // single-threaded executor runs them with no hand-off between
            // threads (in a multi-threaded schedule each costs a wake-up,
            // ≈ 0.45 ms a frame for the step's systems); muscles still run
            // in parallel inside each system, on the plug-in's worker pool.
            schedule.set_executor(SingleThreadedExecutor::new());
            app.add_schedule(schedule);
        }
        let schedule = self.schedule;
        app.configure_sets(
            schedule,
            (
                SinewSystems::Prepare.before(TransformSystems::Propagate),
                SinewSystems::Step.after(TransformSystems::Propagate),
            ),
        )
        .add_systems(
            schedule,
            (
                run_prepare.in_set(SinewSystems::Prepare),
                run_step.in_set(SinewSystems::Step),
                (save::save_scenes, events::log_messages)
                    .chain()
                    .after(SinewSystems::Step),
            ),
        )
        .configure_sets(
            SinewPrepareSchedule,
            SinewSystems::AnimateBones.run_if(simulation_running),
        )
        .configure_sets(
            SinewStepSchedule,
            (
                SinewSystems::ReadInputs,
                SinewSystems::Substeps,
                SinewSystems::WriteBack,
            )
                .chain()
                .run_if(simulation_running),
        )
        .configure_sets(
            SinewSubstepSchedule,
            (
                SinewSystems::Integrate,
                SinewSystems::Iterate,
                SinewSystems::ApplyPredictions,
            )
                .chain(),
        )
        .configure_sets(
            SinewIterationSchedule,
            (
                SinewIterationSystems::UpdateTargets,
                SinewIterationSystems::Solve,
            )
                .chain(),
        )
        .add_systems(
            SinewPrepareSchedule,
            (
                systems::validate_settings,
                systems::plan_update,
                systems::animate_bone_tracks,
                systems::animate_skeletons,
            )
                .chain()
                .in_set(SinewSystems::AnimateBones),
        )
        .add_systems(
            SinewStepSchedule,
            (
                (
                    systems::place_new_targets,
                    systems::read_bones,
                    systems::read_activation,
                    sensors::drive_activation,
                    systems::sync_muscles,
                    systems::sync_attachments,
                    systems::link_muscles,
                    systems::plan_step,
                )
                    .chain()
                    .in_set(SinewSystems::ReadInputs),
                systems::run_substeps.in_set(SinewSystems::Substeps),
                (
                    systems::guard_muscles,
                    constraint_table::report_constraint_sets,
                    systems::finish_timings,
                )
                    .chain()
                    .in_set(SinewSystems::WriteBack),
            ),
        )
        .add_systems(
            SinewSubstepSchedule,
            (
                (systems::pose_bones, systems::begin_substep)
                    .chain()
                    .in_set(SinewSystems::Integrate),
                systems::run_iterations.in_set(SinewSystems::Iterate),
                systems::end_substep.in_set(SinewSystems::ApplyPredictions),
            ),
        )
        .add_systems(
            SinewIterationSchedule,
            (
                systems::publish_snapshots.in_set(SinewIterationSystems::UpdateTargets),
                systems::iterate.in_set(SinewIterationSystems::Solve),
            ),
        );
        // Reset, building and scenes run every frame, paused or not, before
        // the bones are animated and propagated: what they spawn is posed in
        // the same frame.
        app.add_systems(
            SinewPrepareSchedule,
            (
                reset_simulation,
                build::start_builds,
                build::finish_builds,
                scene::spawn_scenes,
            )
                .chain()
                .before(SinewSystems::AnimateBones),
        );
        scene::register(app);
        #[cfg(feature = "gltf")]
        app.add_systems(
            SinewPrepareSchedule,
            character::place_scenes_on_characters
                .after(scene::spawn_scenes)
                .before(SinewSystems::AnimateBones),
        )
        .add_systems(Update, character::blend_clips_in);
        #[cfg(feature = "render")]
        render::register(app);
    }
}

/// Runs [`SinewPrepareSchedule`] (the system in [`SinewSystems::Prepare`]);
/// its [`SinewSystems::AnimateBones`] decides how many steps the update
/// runs (none unless it runs).
fn run_prepare(world: &mut World) {
    world.resource_mut::<StepContext>().steps_this_update = 0;
    world.run_schedule(SinewPrepareSchedule);
}

/// Runs [`SinewStepSchedule`] once per step of this update (the system in
/// [`SinewSystems::Step`]), each with its own end time.
fn run_step(world: &mut World) {
    let steps = world.resource::<StepContext>().steps_this_update;
    for k in 0..steps {
        let time = world.resource::<SinewClock>().time;
        let mut ctx = world.resource_mut::<StepContext>();
        ctx.step_of_update = k;
        ctx.end_time = time + ctx.settings.step_time();
        world.resource_mut::<SinewTimings>().start_step();
        world.run_schedule(SinewStepSchedule);
    }
}

/// Handles [`ResetSimulation`]: clock to zero, every scene respawned,
/// every hand-built muscle back to its built state.
fn reset_simulation(
    mut messages: MessageReader<ResetSimulation>,
    mut clock: ResMut<SinewClock>,
    mut roots: Query<&mut scene::SpawnedScene>,
    mut built: Query<(
        &build::MuscleAtBuild,
        &mut MuscleState,
        &mut SolverWorkspace,
    )>,
    mut commands: Commands,
) {
    if messages.read().count() == 0 {
        return;
    }
    *clock = SinewClock::default();
    // Hand-built muscles go back to their built state (the live `Muscle`
    // parameters are kept, and applied on the next step); their targets
    // are linked again.
    for (at_build, mut state, mut workspace) in &mut built {
        *state = MuscleState::new(at_build.0.clone());
        *workspace = SolverWorkspace::default();
    }
    for mut spawned in &mut roots {
        for e in spawned.entities.drain(..) {
            commands.entity(e).despawn();
        }
        spawned.done = false;
    }
}
