//! The frame loop as systems. Every phase is `sinew_core`'s
//! ([`sinew_core::solver::passes`] over every muscle, the per-muscle
//! [`sinew_core::solver::pipeline`]); these systems only hand it the
//! entities' data, in the order [`sinew_core::Solver::step`] uses, with the
//! same parameters ([`FrameParams`] → [`SubstepParams`] →
//! [`IterationParams`]) and the same worker pool semantics, so both drivers
//! give the same bits.

mod attach;
mod inputs;
mod solve;

pub(crate) use attach::*;

pub(crate) use inputs::*;
pub(crate) use solve::*;

use crate::components::{BoneTarget, MuscleSnapshot, MuscleState, SolverWorkspace};
use crate::settings::{SimulationState, SinewSettings};
use bevy::ecs::entity::EntityHashMap;
use bevy::prelude::*;
use sinew_core::SolverSettings;
use sinew_core::closest::{TargetSource, TargetSurface};
use sinew_core::constraints::TargetId;
use sinew_core::muscle::Muscle as CoreMuscle;
use sinew_core::solver::{
    BorrowBuffer, FrameParams, IterationParams, MusclePair, Parallelism, SubstepParams, WorkerPool,
};

/// What the step in progress is doing: the settings it runs with and the
/// parameters of the frame, substep and iteration that are running.
/// Systems added to [`crate::SinewSubstepSchedule`] and
/// [`crate::SinewIterationSchedule`] can read it.
#[derive(Resource, Clone, Debug)]
pub struct StepContext {
    /// The validated settings of this step.
    pub settings: SolverSettings,
    /// Simulated time at the end of the step, seconds.
    pub end_time: f32,
    /// The step's parameters (set once the inputs are read).
    pub frame: FrameParams,
    /// The current substep's parameters.
    pub substep: SubstepParams,
    /// The current iteration's parameters.
    pub iteration: IterationParams,
    /// Iterations this step runs (`max(global, every muscle's own)`).
    pub iterations: u32,
    /// Steps this app update runs ([`crate::SimulationPacing`]).
    pub steps_this_update: u32,
    /// Which of them is running (0-based).
    pub step_of_update: u32,
}

impl Default for StepContext {
    fn default() -> Self {
        let settings = SolverSettings::default();
        let frame = FrameParams::new(&settings, 0, Parallelism::default());
        let substep = frame.substep(0);
        Self {
            end_time: 0.0,
            iteration: substep.iteration(0, frame.iterations),
            iterations: frame.iterations,
            frame,
            substep,
            settings,
            steps_this_update: 0,
            step_of_update: 0,
        }
    }
}

impl StepContext {
    /// Whether the current iteration is the frame's first (full closest-point
    /// searches, snapshot normals and refits).
    pub fn first_iteration_of_frame(&self) -> bool {
        self.iteration.first_of_frame()
    }
}

/// The last settings that passed validation, and the last rejected ones.
#[derive(Resource, Default)]
pub(crate) struct ValidSettings {
    settings: Option<SolverSettings>,
    rejected: Option<SinewSettings>,
}

/// The solver's worker threads, the step's target table, and the buffers
/// the passes borrow the entities' data through (kept between steps, so a
/// step allocates nothing once the scene is set).
#[derive(Resource)]
pub(crate) struct SolverWorkers {
    /// Worker threads for [`SolverSettings::threads`] `!= 1`.
    pool: WorkerPool,
    /// Every muscle's model and workspace, for one pass.
    pairs: BorrowBuffer<MusclePair<'static>>,
    /// The target table's surfaces, for one iteration.
    surfaces: BorrowBuffer<&'static TargetSurface>,
    /// The targeted muscles' snapshots with their muscles, for publishing.
    snapshots: BorrowBuffer<(&'static mut TargetSurface, &'static CoreMuscle)>,
    /// The step's target table: every entity some muscle targets (a bone
    /// with a [`BoneTarget`] or a muscle's [`MuscleSnapshot`]).
    /// [`sinew_core::solver::MuscleWorkspace::target_ids`] index it.
    table: Vec<Entity>,
    /// Each table entity's index.
    slots: EntityHashMap<TargetId>,
    /// One muscle's targets, as its connections name them (scratch).
    targets: Vec<Entity>,
    /// Stands in the table for a target despawned during the step (its
    /// muscles run the rest of the step without contacts; it is dropped
    /// from their targets on the next one).
    gone: TargetSurface,
}

impl Default for SolverWorkers {
    fn default() -> Self {
        Self {
            pool: WorkerPool::default(),
            pairs: BorrowBuffer::default(),
            surfaces: BorrowBuffer::default(),
            snapshots: BorrowBuffer::default(),
            table: Vec::new(),
            slots: EntityHashMap::default(),
            targets: Vec::new(),
            gone: TargetSurface::new("despawned", TargetSource::Bone(0), Vec::new(), Vec::new()),
        }
    }
}

/// Run condition: the simulation advances this frame.
pub fn simulation_running(state: Res<SimulationState>) -> bool {
    *state != SimulationState::Paused
}

/// A muscle entity's model and workspace, as a pass takes them.
fn pair<'a>(
    (state, workspace): (Mut<'a, MuscleState>, Mut<'a, SolverWorkspace>),
) -> MusclePair<'a> {
    (
        &mut state.into_inner().muscle,
        &mut workspace.into_inner().0,
    )
}

/// The surface of target entity `e`: its bone's or its muscle's snapshot.
fn surface_of<'a>(
    e: Entity,
    bones: &'a Query<&BoneTarget>,
    snapshots: &'a Query<&MuscleSnapshot>,
) -> Option<&'a TargetSurface> {
    bones
        .get(e)
        .map(|b| &b.0)
        .or_else(|_| snapshots.get(e).map(|s| &s.surface))
        .ok()
}
