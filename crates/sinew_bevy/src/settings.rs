//! Global settings, the simulation clock and per-block timings (resources).

use bevy::prelude::*;
use sinew_core::muscle::ConstraintKind;
use sinew_core::{ColorScope, SolverMethod, SolverSettings, StepTimings, SweepSchedule};
use std::time::Duration;

/// Projection method, as [`SolverMethod`] but reflectable (the panel and
/// inspectors edit it). Converts both ways.
#[derive(Clone, Copy, Debug, Default, PartialEq, Reflect)]
pub enum Method {
    /// Gauss–Seidel, the reference ([`SolverMethod::Sequential`]).
    #[default]
    Sequential,
    /// Per-muscle graph colouring, one constraint at a time (the thesis;
    /// [`ColorScope::PerMuscle`]).
    Colored,
    /// Clustered colouring, colour by colour across muscles
    /// ([`ColorScope::Global`]).
    ColoredGlobal,
    /// Jacobi with over-relaxation `omega` ∈ [1, 2] ([`SolverMethod::Jacobi`]).
    Jacobi {
        /// Over-relaxation.
        omega: f32,
    },
    /// Colour groups of at least `min_group` constraints Gauss–Seidel, the
    /// tail Jacobi with over-relaxation `omega` ([`SolverMethod::Hybrid`]).
    Hybrid {
        /// Smallest colour group solved Gauss–Seidel.
        min_group: u32,
        /// Over-relaxation of the Jacobi tail.
        omega: f32,
    },
}

impl Method {
    /// Every method `sinew_core` offers, with default parameters (for menus).
    pub const ALL: [Method; 5] = [
        Method::Sequential,
        Method::Colored,
        Method::ColoredGlobal,
        Method::Jacobi { omega: 1.5 },
        Method::Hybrid {
            min_group: 32,
            omega: 1.5,
        },
    ];

    /// A short name.
    pub fn label(&self) -> &'static str {
        match self {
            Method::Sequential => "Sequential",
            Method::Colored => "Colored (per muscle)",
            Method::ColoredGlobal => "Colored (global)",
            Method::Jacobi { .. } => "Jacobi",
            Method::Hybrid { .. } => "Hybrid",
        }
    }
}

impl From<Method> for SolverMethod {
    fn from(m: Method) -> Self {
        match m {
            Method::Sequential => SolverMethod::Sequential,
            Method::Colored => SolverMethod::Colored {
                scope: ColorScope::PerMuscle,
            },
            Method::ColoredGlobal => SolverMethod::Colored {
                scope: ColorScope::Global,
            },
            Method::Jacobi { omega } => SolverMethod::Jacobi { omega },
            Method::Hybrid { min_group, omega } => SolverMethod::Hybrid { min_group, omega },
        }
    }
}

impl From<SolverMethod> for Method {
    fn from(m: SolverMethod) -> Self {
        match m {
            SolverMethod::Sequential => Method::Sequential,
            SolverMethod::Colored {
                scope: ColorScope::PerMuscle,
            } => Method::Colored,
            SolverMethod::Colored {
                scope: ColorScope::Global,
            } => Method::ColoredGlobal,
            SolverMethod::Jacobi { omega } => Method::Jacobi { omega },
            SolverMethod::Hybrid { min_group, omega } => Method::Hybrid { min_group, omega },
        }
    }
}

/// Global solver settings (the ECS face of [`SolverSettings`], field for
/// field, each meaning what it means there). Edits take effect on the next
/// frame; [`SinewSettings::to_core`] validates nothing, the driver does (an
/// invalid value is reported once and the last valid settings are kept).
#[derive(Resource, Clone, Debug, PartialEq, Reflect)]
#[reflect(Resource)]
pub struct SinewSettings {
    /// The fixed step, seconds: real-time pacing runs one step per `dt` of
    /// app time ([`crate::SimulationPacing`]). Default `1/60`.
    pub dt: f32,
    /// Iterations per substep (`N_it`). Default `10`.
    pub iterations: u32,
    /// Substeps per step. Default `1`.
    pub substeps: u32,
    /// Gravity, m/s² (real units; scaled by `length_unit`). Default zero.
    pub gravity: Vec3,
    /// Simulated seconds per second of app time: a step of `dt` simulates
    /// `dt × time_scale` (slow motion below 1; > 0, pause with
    /// [`SimulationState::Paused`]). Default `1`.
    pub time_scale: f32,
    /// Scene units per metre (`100` for centimetres): geometry is in scene
    /// units, every physical parameter SI, converted by it as in the core
    /// ([`SolverSettings::length_unit`]). Default `1`.
    pub length_unit: f32,
    /// Projection method. Default [`Method::Sequential`].
    pub method: Method,
    /// Worker threads of the plug-in's solver pool, which runs muscles and
    /// the chunks inside a large muscle (`1`: everything on the thread that
    /// runs the step; `0`: one per core). As in [`SolverSettings::threads`];
    /// the same bits for any count. Default `0` (every core).
    pub threads: u32,
    /// How coloured methods use the threads (as
    /// [`SolverSettings::schedule`]). Default [`SweepSchedule::Auto`].
    #[reflect(ignore)]
    pub schedule: SweepSchedule,
    /// Constraints (and particles) below which a step stays on one thread
    /// whatever `threads` says (as [`SolverSettings::parallel_threshold`]).
    /// Default `8192`.
    pub parallel_threshold: usize,
    /// The run-time guard's speed limit (as [`SolverSettings::max_speed`]):
    /// a muscle with a faster particle is put back to its last good frame
    /// and reported ([`crate::events::MuscleFaulted`]). Units: m/s.
    /// Default `100`.
    pub max_speed: f32,
    /// Frames between two full closest-point searches of a vertex. Default `16`.
    pub full_search_interval: u32,
    /// Frames between two choices of a vertex's closest target. Default `4`.
    pub choose_interval: u32,
    /// Iterations that do not walk project onto the feature the last walk
    /// found (as [`SolverSettings::feature_contacts`]). Default `false`.
    pub feature_contacts: bool,
    /// Iterations between two walks of Sliding's closest data over the
    /// targets (as [`SolverSettings::walk_interval`]; a substep's first
    /// always walks). Default `1` (every iteration).
    pub walk_interval: u32,
    /// Iterations between two bone-contact passes of a substep (as
    /// [`SolverSettings::bone_contact_interval`]; the first and each
    /// muscle's last always have one). Default `1` (every iteration).
    pub bone_contact_interval: u32,
    /// Iterations between two publications of the muscles' snapshots (as
    /// [`SolverSettings::snapshot_interval`]): [`crate::SinewIterationSchedule`]
    /// runs once per block of this many iterations, each muscle running the
    /// block back to back. Default `1` (every iteration).
    pub snapshot_interval: u32,
    /// Measure per-block time into [`SinewTimings`]. Default `true`.
    pub timers: bool,
    /// The order constraint types are projected in.
    #[reflect(ignore)]
    pub projection_order: Vec<ConstraintKind>,
}

impl Default for SinewSettings {
    fn default() -> Self {
        SolverSettings::default().into()
    }
}

impl From<SolverSettings> for SinewSettings {
    fn from(s: SolverSettings) -> Self {
        Self {
            dt: s.dt,
            iterations: s.iterations,
            substeps: s.substeps,
            gravity: s.gravity,
            time_scale: s.time_scale,
            length_unit: s.length_unit,
            method: s.method.into(),
            threads: s.threads,
            schedule: s.schedule,
            parallel_threshold: s.parallel_threshold,
            max_speed: s.max_speed,
            full_search_interval: s.full_search_interval,
            choose_interval: s.choose_interval,
            feature_contacts: s.feature_contacts,
            walk_interval: s.walk_interval,
            bone_contact_interval: s.bone_contact_interval,
            snapshot_interval: s.snapshot_interval,
            timers: s.timers,
            projection_order: s.projection_order,
        }
    }
}

impl SinewSettings {
    /// The core settings these stand for.
    pub fn to_core(&self) -> SolverSettings {
        SolverSettings {
            dt: self.dt,
            iterations: self.iterations,
            substeps: self.substeps,
            gravity: self.gravity,
            time_scale: self.time_scale,
            length_unit: self.length_unit,
            method: self.method.into(),
            projection_order: self.projection_order.clone(),
            timers: self.timers,
            full_search_interval: self.full_search_interval,
            choose_interval: self.choose_interval,
            feature_contacts: self.feature_contacts,
            walk_interval: self.walk_interval,
            bone_contact_interval: self.bone_contact_interval,
            snapshot_interval: self.snapshot_interval,
            threads: self.threads,
            schedule: self.schedule,
            parallel_threshold: self.parallel_threshold,
            max_speed: self.max_speed,
        }
    }
}

/// Play state of the simulation (the panel's play / pause / step / reset).
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Resource)]
pub enum SimulationState {
    /// Steps every frame.
    #[default]
    Playing,
    /// Holds still.
    Paused,
    /// Steps once, then pauses.
    StepOnce,
}

/// The simulation clock: time and frame count of the last step, and how
/// it keeps pace with the app ([`crate::SimulationPacing`]).
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Reflect)]
#[reflect(Resource)]
pub struct SinewClock {
    /// Simulated time at the end of the last step, seconds.
    pub time: f32,
    /// Steps taken.
    pub frame: u64,
    /// App time owed to the simulation: less than a step, carried to the
    /// next update (real-time pacing).
    pub owed: Duration,
    /// App time dropped because updates owed more than
    /// [`crate::SimulationPacing::max_steps_per_update`] steps (the
    /// simulation fell behind and slowed down), in total.
    pub dropped: Duration,
    /// Steps the last update ran.
    pub steps_last_update: u32,
}

/// Where a frame's time went, per block (SPEC §4, the core's
/// [`StepTimings`]: the same blocks the plain driver reports), with a history
/// for the panel's chart.
#[derive(Resource, Clone, Debug, Default, PartialEq, Reflect)]
#[reflect(Resource)]
pub struct SinewTimings {
    /// The blocks of the last step (of the step in progress while it runs).
    #[reflect(ignore)]
    pub step: StepTimings,
    /// Sum of the blocks of the last step.
    pub total: Duration,
    /// The blocks of the last `HISTORY` steps in ms, oldest first.
    #[reflect(ignore)]
    pub history: std::collections::VecDeque<[f32; 7]>,
}

impl SinewTimings {
    /// Frames kept in [`SinewTimings::history`].
    pub const HISTORY: usize = 240;

    /// The blocks of the last step as `(name, duration)`, in the order of
    /// [`StepTimings::NAMES`] (as in `history`).
    pub fn blocks(&self) -> impl Iterator<Item = (&'static str, Duration)> + use<> {
        StepTimings::NAMES.into_iter().zip(self.step.as_array())
    }

    /// The surface layers' (a skin's) own tasks in the last step, by phase
    /// ([`sinew_core::LayerTimings`]), and their share of the closest-data
    /// and project blocks they run in: near 1, the skin is what the frame
    /// waits for. `None` without a surface layer (or with the timers off).
    pub fn layers(&self) -> Option<(sinew_core::LayerTimings, f32)> {
        let layers = self.step.layers;
        let blocks = self.step.closest_data + self.step.project;
        (!layers.total().is_zero() && !blocks.is_zero())
            .then(|| (layers, layers.total().as_secs_f32() / blocks.as_secs_f32()))
    }

    /// The median of the steps' totals over [`SinewTimings::history`], in
    /// ms (`None` before the first step): the steady figure the panel shows
    /// beside the last step, which one slow step (a link, an OS hitch)
    /// would otherwise make flicker.
    pub fn median_total_ms(&self) -> Option<f32> {
        let totals = self.sorted_totals_ms();
        if totals.is_empty() {
            return None;
        }
        let mid = totals.len() / 2;
        Some(if totals.len() % 2 == 1 {
            totals[mid]
        } else {
            0.5 * (totals[mid - 1] + totals[mid])
        })
    }

    /// The steps' totals over [`SinewTimings::history`] in ms, smallest
    /// first (the panel's median and its chart's scale).
    pub fn sorted_totals_ms(&self) -> Vec<f32> {
        let mut totals: Vec<f32> = self.history.iter().map(|b| b.iter().sum()).collect();
        totals.sort_by(f32::total_cmp);
        totals
    }

    /// Starts the history again (the chart and the median then cover only
    /// the steps from here).
    pub fn restart_history(&mut self) {
        self.history.clear();
    }

    /// Closes a step: sums the blocks and pushes them to the history.
    pub(crate) fn finish_step(&mut self) {
        self.total = self.step.total();
        if self.history.len() == Self::HISTORY {
            self.history.pop_front();
        }
        self.history
            .push_back(self.step.as_array().map(|d| d.as_secs_f32() * 1e3));
    }

    /// Zeroes the blocks for a new step (history is kept).
    pub(crate) fn start_step(&mut self) {
        self.step = StepTimings::default();
        self.total = Duration::ZERO;
    }
}

/// A muscle built restarts the timing history, as a scene spawned does
/// (`scene::spawn_scenes`): the panel's median and chart then cover the
/// muscles as they run, not the near-empty steps taken before they were
/// there (the arm example read a median of 0.02 ms 30 steps after its
/// scene spawned, 40 of its 70 steps taken while the scene loaded).
pub(crate) fn restart_timing_history(
    _built: On<crate::events::MuscleBuilt>,
    mut timings: ResMut<SinewTimings>,
) {
    timings.restart_history();
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_median_step_is_the_middle_total_of_the_history() {
        let mut t = SinewTimings::default();
        assert_eq!(t.median_total_ms(), None);
        // Totals 3, 1, 100 (one slow step) and 2 ms: blocks of each step
        // add up to its total.
        for total in [[1.0, 2.0], [0.5, 0.5], [90.0, 10.0], [2.0, 0.0]] {
            let mut b = [0.0f32; 7];
            b[..2].copy_from_slice(&total);
            t.history.push_back(b);
        }
        assert_eq!(t.median_total_ms(), Some(2.5));
        t.history.pop_back();
        assert_eq!(t.median_total_ms(), Some(3.0));
    }

    /// The skin's own task's share is of closest data and project
    /// together; nothing without one.
    #[test]
    fn a_skins_share_is_of_the_blocks_it_runs_in() {
        let mut t = SinewTimings::default();
        assert_eq!(t.layers(), None);
        t.step.closest_data = Duration::from_millis(3);
        t.step.project = Duration::from_millis(5);
        assert_eq!(t.layers(), None, "no skin");
        t.step.layers.closest_data = Duration::from_millis(2);
        t.step.layers.sweep = Duration::from_millis(3);
        t.step.layers.finish = Duration::from_millis(1);
        let (layers, share) = t.layers().unwrap();
        assert_eq!(layers.total(), Duration::from_millis(6));
        assert!((share - 0.75).abs() < 1e-6, "{share}");
    }

    #[test]
    fn a_muscle_built_restarts_the_timing_history() {
        let mut app = App::new();
        app.init_resource::<SinewTimings>()
            .add_observer(restart_timing_history);
        let mut timings = app.world_mut().resource_mut::<SinewTimings>();
        timings.history.push_back([0.02; 7]);
        let entity = app.world_mut().spawn_empty().id();
        app.world_mut()
            .trigger(crate::events::MuscleBuilt { entity });
        let timings = app.world().resource::<SinewTimings>();
        assert!(timings.history.is_empty());
        assert_eq!(timings.median_total_ms(), None);
    }
}
