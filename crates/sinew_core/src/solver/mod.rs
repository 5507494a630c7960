//! The frame loop (SPEC §4) with the `Sequential` reference method.
//!
//! ```text
//! read inputs      activation → rest lengths and volume ratio; bone poses
//! for each substep (Small Steps; targets interpolated within the frame):
//!     update targets   bone poses at the substep, attachment goals
//!     integrate        v += Δt g;  v *= damping;  p = x + Δt v
//!     λ = 0
//!     for it in 0..N_it:
//!         update targets   publish every muscle's p as its snapshot (BE4/BE7)
//!         for m in muscles with it < m.iterations:
//!             closest data (BE5), project m's constraints (BE6)
//!     apply            v = (p − x)/Δt, x = p
//! write back       output normals
//! ```
//!
//! A muscle reads its neighbours through snapshots published at the start of
//! the iteration, i.e. as they were at the end of the previous one (SPEC §4.2,
//! the thesis' Alg. 3). That makes the order of muscles irrelevant within an
//! iteration and the result deterministic.

pub mod coloring;
pub mod jacobi;
mod link;
mod momentum;
pub mod stage;
mod sweep;
mod timings;

pub use momentum::RigidMomentum;
pub use stage::ClosestSchedule;
use stage::{
    begin_substep, closest_data, end_substep, link_muscle, project_iteration,
    update_attachment_goals,
};

pub use timings::StepTimings;
use timings::{Stopwatch, TaskSplit};

use crate::animation::{Curve, TransformTrack, interpolate_rigid};
use crate::closest::{TargetSource, TargetSurface};
use crate::constraints::ConstraintKind;
use crate::error::BuildError;
use crate::mesh::SurfaceMesh;
use crate::muscle::{Muscle, MuscleDesc, TargetRef};
use crate::sensor::ActivationRig;
use crate::skeleton::SkeletonRig;
use glam::{Affine3A, Vec3};
use serde::{Deserialize, Serialize};

/// How constraints are projected.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub enum SolverMethod {
    /// Gauss–Seidel, one muscle after another, in the canonical order. The
    /// reference: bit-identical run to run.
    #[default]
    Sequential,
    /// Graph colouring (SPEC §9.3, the thesis' SMT-G): each muscle's
    /// constraints in greedy first-fit colour groups, the groups one after
    /// the other and each group's constraints in parallel. Volume and the
    /// bone contacts are solved after the groups, as in `Sequential`.
    Colored {
        /// Which constraints are coloured together.
        scope: ColorScope,
    },
    /// Jacobi (SPEC §9.2, the thesis' SMT-J): the attachments solved
    /// Gauss–Seidel first, every other constraint (but Volume) computed from
    /// the same positions, in parallel, and each particle moved by `omega`
    /// times the mean of its corrections. The per-particle sum is a gather in
    /// a fixed order (no float atomics), so any thread count gives the same
    /// bits. Volume and the bone contacts follow, as in `Sequential`.
    Jacobi {
        /// Over-relaxation ω ∈ [1, 2].
        omega: f32,
    },
    /// Hybrid (Fratarcangeli & Pellacini 2015): the per-muscle colour groups
    /// with at least `min_group` constraints are solved Gauss–Seidel, group by
    /// group; the small, high-degree tail (the internal points' links) is
    /// solved by one Jacobi pass after them, with over-relaxation `omega`.
    /// Volume and the bone contacts follow. Bit-identical for any thread count.
    Hybrid {
        /// Smallest colour group solved Gauss–Seidel (≥ 1).
        min_group: u32,
        /// Over-relaxation ω ∈ [1, 2] of the Jacobi tail.
        omega: f32,
    },
}

/// What a colouring spans.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ColorScope {
    /// One colouring per muscle, one constraint at a time (the thesis): the
    /// internal points make it long (24 groups per arm muscle).
    #[default]
    PerMuscle,
    /// Clustered colouring (see [`coloring::ColorPlan::clustered`]): the
    /// single-particle constraints of a vertex and the links of an internal
    /// point are units one thread solves in order, which cuts the colours to
    /// an edge colouring's. The solver runs colour `c` of every muscle in one
    /// parallel sweep, split into chunks, so a large muscle spreads over
    /// every thread.
    Global,
}

/// How the solver spreads a coloured method's sweeps over its threads. Both
/// give the same bits; only the speed differs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum SweepSchedule {
    /// Colour by colour across muscles when splitting by muscle would leave
    /// threads idle (one muscle much larger than its share), else by muscle.
    #[default]
    Auto,
    /// Each thread takes whole muscles: one synchronisation per iteration.
    ByMuscle,
    /// Colour `c` of every muscle in one parallel sweep of (muscle, chunk)
    /// tasks: balanced, one synchronisation per colour. Only for
    /// `Colored { scope: Global }` and `Hybrid`.
    ByColor,
}

/// Global solver settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SolverSettings {
    /// Frame time step. Units: s. Default: `1/60`.
    pub dt: f32,
    /// Global iterations per (sub)step; each muscle runs `min(own, N)`. Default: `10`.
    pub iterations: u32,
    /// Substeps per frame (Small Steps). Default: `1`.
    pub substeps: u32,
    /// Gravity as an acceleration, in real units. Units: m/s². Default: `(0, 0, 0)`.
    pub gravity: Vec3,
    /// Multiplies `dt` (slow motion < 1). Default: `1`.
    pub time_scale: f32,
    /// Scene units are `1/space_scale` of real size: gravity is divided by it.
    /// Default: `1` (scene in metres).
    pub space_scale: f32,
    /// Projection method. Default: [`SolverMethod::Sequential`].
    pub method: SolverMethod,
    /// Order in which constraint types are projected. Default: SPEC §4.3.
    pub projection_order: Vec<ConstraintKind>,
    /// Measure per-block time. Default: `true`.
    pub timers: bool,
    /// Every this many frames each vertex runs the full (BVH) closest-point
    /// search on each target, staggered over vertices; in between, the
    /// closest point walks over the target from last iteration's triangle
    /// (see [`crate::closest`]). `1` = a full search every frame. Default: `16`.
    pub full_search_interval: u32,
    /// Every this many frames each vertex re-chooses the target it slides
    /// on among the targets within its contact band (staggered over
    /// vertices, and always with a full search); in between it keeps its
    /// target and checks only the bones whose boxes it is in (it may have
    /// entered one). A vertex switches only to a target it has come nearer
    /// to *relative to its rest gap* by a tenth of the band (see
    /// `stage::closest_data`). `1` = every frame. Default: `4`.
    pub choose_interval: u32,
    /// When `walk_every_iteration` is off, later iterations of a frame
    /// project each vertex onto the face, edge or corner of the triangle the
    /// first iteration's walk found (a few loads) instead of re-projecting
    /// onto the triangle. Faster, exact while the vertex stays in that
    /// feature's region, but the contact point then jumps at the next
    /// frame's walk. Default: `false`.
    pub feature_contacts: bool,
    /// Walk over the targets in every iteration, so the contact point slides
    /// from triangle to triangle as the vertex does. With `false` the walk
    /// runs in the first iteration of a frame and later iterations re-project
    /// onto the triangle it found: the constraint then jumps from the
    /// triangle's plane to the next triangle at the next frame, a kick that
    /// kept T5 at rest moving at 1.2 mm/s (0.08 with walking). Default: `true`.
    pub walk_every_iteration: bool,
    /// Worker threads for closest data and projection, split by muscle
    /// (SPEC §9.1): `1` spawns none, `0` uses every core. Muscles read each
    /// other only through published snapshots, so the result is bit-identical
    /// for any count. Default: `1`.
    pub threads: u32,
    /// How coloured methods use the threads. Default: [`SweepSchedule::Auto`].
    pub schedule: SweepSchedule,
    /// Scenes with fewer constraints than this run their passes over
    /// muscles on the calling thread, and scenes with fewer particles their
    /// per-particle passes (integration, goals, publishing), whatever
    /// `threads` says: a fork and join (≈ 10 µs on the 2-core development
    /// machine) costs more than the split saves. The same bits either way.
    /// Default: `8192` (P2 ran 3× and P3 1.2× slower on two threads than on
    /// one without it; P4 and T7 split).
    pub parallel_threshold: usize,
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self {
            dt: 1.0 / 60.0,
            iterations: 10,
            substeps: 1,
            gravity: Vec3::ZERO,
            time_scale: 1.0,
            space_scale: 1.0,
            method: SolverMethod::Sequential,
            projection_order: ConstraintKind::CANONICAL_ORDER.to_vec(),
            timers: true,
            full_search_interval: 16,
            choose_interval: 4,
            feature_contacts: false,
            walk_every_iteration: true,
            threads: 1,
            schedule: SweepSchedule::Auto,
            parallel_threshold: 8192,
        }
    }
}

impl SolverSettings {
    /// Rejects NaN and out-of-range values.
    pub fn validate(&self) -> Result<(), BuildError> {
        let bad = |parameter: &str, value: f32, reason: &str| BuildError::InvalidParameter {
            muscle: "solver".into(),
            parameter: parameter.into(),
            value,
            reason: reason.into(),
        };
        if !(self.dt > 0.0 && self.dt.is_finite()) {
            return Err(bad("dt", self.dt, "must be finite and > 0"));
        }
        if let SolverMethod::Jacobi { omega } | SolverMethod::Hybrid { omega, .. } = self.method
            && !(1.0..=2.0).contains(&omega)
        {
            return Err(bad("method.omega", omega, "must be in [1, 2]"));
        }
        if let SolverMethod::Hybrid { min_group: 0, .. } = self.method {
            return Err(bad("method.min_group", 0.0, "must be ≥ 1"));
        }
        if !(self.time_scale > 0.0 && self.time_scale.is_finite()) {
            return Err(bad("time_scale", self.time_scale, "must be finite and > 0"));
        }
        if !(self.space_scale > 0.0 && self.space_scale.is_finite()) {
            return Err(bad(
                "space_scale",
                self.space_scale,
                "must be finite and > 0",
            ));
        }
        if self.full_search_interval == 0 {
            return Err(bad("full_search_interval", 0.0, "must be ≥ 1"));
        }
        if self.choose_interval == 0 {
            return Err(bad("choose_interval", 0.0, "must be ≥ 1"));
        }
        if self.iterations == 0 || self.substeps == 0 {
            return Err(bad("iterations/substeps", 0.0, "must be ≥ 1"));
        }
        if !self.gravity.is_finite() {
            return Err(bad("gravity", f32::NAN, "must be finite"));
        }
        Ok(())
    }
}

/// A kinematic bone: a pose per frame (from its track or the host) and an
/// optional target mesh.
#[derive(Clone, Debug)]
pub struct Bone {
    /// Unique name.
    pub name: String,
    /// Keyframes; when empty the host sets the pose with [`Solver::set_bone_transform`].
    pub track: TransformTrack,
    /// Pose at the end of the current frame.
    pub transform: Affine3A,
    /// Pose at the start of the current frame.
    pub previous: Affine3A,
    /// Target surface index, if the bone has a mesh.
    pub target: Option<usize>,
    /// Skeleton body whose world frame this bone follows (see [`Solver::set_skeleton`]).
    pub body: Option<usize>,
}

/// A [`Solver`] taken apart by [`Solver::into_parts`].
#[derive(Clone, Debug)]
pub struct SolverParts {
    /// The settings.
    pub settings: SolverSettings,
    /// Bones; [`Bone::target`] indexes `targets`.
    pub bones: Vec<Bone>,
    /// Every target: bone meshes (local frame) and muscle snapshots.
    pub targets: Vec<TargetSurface>,
    /// Built muscles; [`TargetRef`]s index `bones` and `muscles`.
    pub muscles: Vec<Muscle>,
    /// Per muscle, the activation curve that drives it, if any.
    pub curves: Vec<Option<Curve>>,
    /// The skeleton that poses bones bound to bodies, if any.
    pub skeleton: Option<SkeletonRig>,
    /// Sensors, triggers and layers, if any.
    pub activation_rig: Option<ActivationRig>,
    /// Simulated time, seconds.
    pub time: f32,
}

/// The solver's skeleton and its scratch buffers.
#[derive(Debug)]
struct SkeletonState {
    rig: SkeletonRig,
    values: Vec<f32>,
    world: Vec<Affine3A>,
}

impl SkeletonState {
    fn pose_at(&mut self, time: f32) {
        self.rig.pose_at(time, &mut self.values, &mut self.world);
    }
}

/// The MSXPBD solver: bones, muscles, targets and the frame loop.
#[derive(Debug)]
pub struct Solver {
    /// Settings; edits take effect on the next step.
    pub settings: SolverSettings,
    bones: Vec<Bone>,
    muscles: Vec<Muscle>,
    curves: Vec<Option<Curve>>,
    targets: Vec<TargetSurface>,
    /// Target indices of muscles that some muscle targets (published per iteration).
    published: Vec<usize>,
    links_dirty: bool,
    time: f32,
    frame: u64,
    timings: StepTimings,
    warnings: Vec<String>,
    skeleton: Option<SkeletonState>,
    activation_rig: Option<ActivationRig>,
    /// Worker pool for `settings.threads != 1`, with the count it was built for.
    pool: Option<(u32, rayon::ThreadPool)>,
    /// Bone poses at the current substep.
    substep_poses: Vec<Affine3A>,
    /// Per muscle, the momentum a free muscle restores at the substep's end.
    substep_momentum: Vec<Option<RigidMomentum>>,
}

impl Solver {
    /// An empty solver.
    pub fn new(settings: SolverSettings) -> Result<Self, BuildError> {
        settings.validate()?;
        Ok(Self {
            settings,
            bones: Vec::new(),
            muscles: Vec::new(),
            curves: Vec::new(),
            targets: Vec::new(),
            published: Vec::new(),
            links_dirty: false,
            time: 0.0,
            frame: 0,
            timings: StepTimings::default(),
            warnings: Vec::new(),
            skeleton: None,
            activation_rig: None,
            pool: None,
            substep_poses: Vec::new(),
            substep_momentum: Vec::new(),
        })
    }

    /// Adds a bone posed by `track` (or by the host when the track is empty), with
    /// an optional mesh (local frame) that muscles can target. Returns its index.
    pub fn add_bone(
        &mut self,
        name: impl Into<String>,
        track: TransformTrack,
        mesh: Option<&SurfaceMesh>,
    ) -> usize {
        let name = name.into();
        let index = self.bones.len();
        let pose = track.sample(self.time);
        let target = mesh.map(|m| {
            let mut t = TargetSurface::new(
                name.clone(),
                TargetSource::Bone(index),
                m.positions.clone(),
                m.triangles.clone(),
            );
            t.set_transform(pose);
            self.targets.push(t);
            self.targets.len() - 1
        });
        self.bones.push(Bone {
            name,
            track,
            transform: pose,
            previous: pose,
            target,
            body: None,
        });
        index
    }

    /// Poses bones from a skeleton from now on: bones bound with
    /// [`Solver::bind_bone`] follow their body's world frame, evaluated at the
    /// end of every frame and at every substep.
    pub fn set_skeleton(&mut self, rig: SkeletonRig) {
        let mut state = SkeletonState {
            rig,
            values: Vec::new(),
            world: Vec::new(),
        };
        state.pose_at(self.time);
        self.skeleton = Some(state);
    }

    /// The skeleton, if one was set.
    pub fn skeleton(&self) -> Option<&SkeletonRig> {
        self.skeleton.as_ref().map(|s| &s.rig)
    }

    /// Makes `bone` follow skeleton body `body` (its pose is taken now, so bind
    /// bones before adding the muscles attached to them).
    pub fn bind_bone(&mut self, bone: usize, body: usize) -> Result<(), BuildError> {
        let state = self
            .skeleton
            .as_ref()
            .ok_or_else(|| BuildError::InvalidParameter {
                muscle: self.bones[bone].name.clone(),
                parameter: "body".into(),
                value: body as f32,
                reason: "the solver has no skeleton".into(),
            })?;
        let pose = *state
            .world
            .get(body)
            .ok_or_else(|| BuildError::InvalidParameter {
                muscle: self.bones[bone].name.clone(),
                parameter: "body".into(),
                value: body as f32,
                reason: format!("the skeleton has {} bodies", state.world.len()),
            })?;
        let b = &mut self.bones[bone];
        b.body = Some(body);
        b.transform = pose;
        b.previous = pose;
        if let Some(t) = b.target {
            self.targets[t].set_transform(pose);
        }
        Ok(())
    }

    /// Drives muscle activations from sensors from now on (replacing
    /// curves and [`Solver::set_activation`] for the muscles it drives).
    pub fn set_activation_rig(&mut self, rig: ActivationRig) {
        self.activation_rig = Some(rig);
    }

    /// The sensor rig, if one was set.
    pub fn activation_rig(&self) -> Option<&ActivationRig> {
        self.activation_rig.as_ref()
    }

    /// Builds and adds a muscle. Bone targets must exist; muscle targets must
    /// have been added before (use [`Solver::add_target`] for mutual targets).
    pub fn add_muscle(&mut self, desc: MuscleDesc) -> Result<usize, BuildError> {
        let index = self.muscles.len();
        for (i, t) in desc.targets.iter().enumerate() {
            self.check_target(&desc.name, i, *t, index)?;
        }
        for (i, a) in desc.attachments.iter().enumerate() {
            if let Some(b) = a.bone.filter(|&b| b >= self.bones.len()) {
                return Err(BuildError::InvalidParameter {
                    muscle: desc.name.clone(),
                    parameter: format!("attachments[{i}].bone"),
                    value: b as f32,
                    reason: format!("there are only {} bones", self.bones.len()),
                });
            }
        }
        let bones = &self.bones;
        let muscle = Muscle::build(desc, |b| bones[b].transform)?;
        let mut target = TargetSurface::new(
            muscle.name.clone(),
            TargetSource::Muscle(index),
            muscle.surface_positions().to_vec(),
            muscle.mesh.triangles.clone(),
        );
        target.set_transform(Affine3A::IDENTITY);
        self.targets.push(target);
        self.muscles.push(muscle);
        self.curves.push(None);
        self.links_dirty = true;
        Ok(index)
    }

    fn check_target(
        &self,
        muscle: &str,
        slot: usize,
        t: TargetRef,
        self_index: usize,
    ) -> Result<(), BuildError> {
        let bad = |value: usize, reason: String| BuildError::InvalidParameter {
            muscle: muscle.to_string(),
            parameter: format!("targets[{slot}]"),
            value: value as f32,
            reason,
        };
        match t {
            TargetRef::Bone(b) if b >= self.bones.len() => {
                Err(bad(b, format!("there are only {} bones", self.bones.len())))
            }
            TargetRef::Bone(b) if self.bones[b].target.is_none() => Err(bad(
                b,
                format!("bone '{}' has no mesh to be a target", self.bones[b].name),
            )),
            TargetRef::Muscle(m) if m == self_index => {
                Err(bad(m, "a muscle cannot target itself".into()))
            }
            TargetRef::Muscle(m) if m >= self.muscles.len() => Err(bad(
                m,
                format!("there are only {} muscles", self.muscles.len()),
            )),
            _ => Ok(()),
        }
    }

    /// Adds a target to an existing muscle (e.g. a muscle added later).
    pub fn add_target(&mut self, muscle: usize, target: TargetRef) -> Result<(), BuildError> {
        let name = self.muscles[muscle].name.clone();
        let slot = self.muscles[muscle].targets.len();
        self.check_target(&name, slot, target, muscle)?;
        self.muscles[muscle].targets.push(target);
        self.links_dirty = true;
        Ok(())
    }

    /// Drives a muscle's activation with a curve of time (seconds).
    pub fn set_activation_curve(&mut self, muscle: usize, curve: Option<Curve>) {
        self.curves[muscle] = curve;
    }

    /// Sets a muscle's activation for the next step (clamped to [0, 1], reported once).
    pub fn set_activation(&mut self, muscle: usize, activation: f32) {
        self.muscles[muscle].params.activation = activation;
    }

    /// Sets the pose a host-driven bone reaches at the end of the next step.
    pub fn set_bone_transform(&mut self, bone: usize, transform: Affine3A) {
        self.bones[bone].transform = transform;
    }

    /// Bones.
    pub fn bones(&self) -> &[Bone] {
        &self.bones
    }

    /// Muscles.
    pub fn muscles(&self) -> &[Muscle] {
        &self.muscles
    }

    /// Mutable access to a muscle's parameters and state. After editing
    /// compliances call [`Muscle::apply_compliances`].
    pub fn muscle_mut(&mut self, index: usize) -> &mut Muscle {
        &mut self.muscles[index]
    }

    /// Target surfaces (bone meshes, then muscle snapshots, in creation order).
    pub fn targets(&self) -> &[TargetSurface] {
        &self.targets
    }

    /// Index of a bone by name.
    pub fn bone_index(&self, name: &str) -> Option<usize> {
        self.bones.iter().position(|b| b.name == name)
    }

    /// Index of a muscle by name.
    pub fn muscle_index(&self, name: &str) -> Option<usize> {
        self.muscles.iter().position(|m| m.name == name)
    }

    /// Simulated time. Units: s.
    pub fn time(&self) -> f32 {
        self.time
    }

    /// Frames stepped so far.
    pub fn frame(&self) -> u64 {
        self.frame
    }

    /// Per-block times of the last step.
    pub fn timings(&self) -> &StepTimings {
        &self.timings
    }

    /// Takes the solver apart for a driver that keeps the state elsewhere (the
    /// Bevy plug-in spawns an entity per bone and muscle). Target connections
    /// are not linked yet if no step ran: the new driver links them itself.
    pub fn into_parts(self) -> SolverParts {
        SolverParts {
            settings: self.settings,
            bones: self.bones,
            targets: self.targets,
            muscles: self.muscles,
            curves: self.curves,
            skeleton: self.skeleton.map(|s| s.rig),
            activation_rig: self.activation_rig,
            time: self.time,
        }
    }

    /// Warnings raised so far (clamped activations …), drained.
    pub fn take_warnings(&mut self) -> Vec<String> {
        std::mem::take(&mut self.warnings)
    }

    /// The iteration count each muscle runs and the global count `N_it`.
    fn iteration_counts(&self) -> usize {
        let global = self.settings.iterations;
        self.muscles
            .iter()
            .map(|m| m.params.iterations.unwrap_or(global))
            .max()
            .unwrap_or(global)
            .max(global) as usize
    }

    /// Links targets if muscles or targets were added since the last step (the
    /// first [`Solver::step`] does it anyway). Call it to see Sliding / Soft /
    /// Hard counts before stepping.
    pub fn prepare(&mut self) {
        if self.links_dirty {
            self.link_targets();
        }
    }

    /// Builds Sliding / Soft / Hard for every muscle from the current geometry
    /// (start frame, or when targets change).
    fn link_targets(&mut self) {
        // Link against every muscle's current geometry.
        self.published = (0..self.targets.len())
            .filter(|&t| matches!(self.targets[t].source, TargetSource::Muscle(_)))
            .collect();
        self.publish_muscles(true, false);
        // Muscle targets follow the bone targets that existed when each was added;
        // find them by source instead of assuming a layout.
        let muscle_target: Vec<usize> = (0..self.muscles.len())
            .map(|m| {
                self.targets
                    .iter()
                    .position(|t| t.source == TargetSource::Muscle(m))
                    .expect("every muscle has a target")
            })
            .collect();
        for mi in 0..self.muscles.len() {
            let m = &mut self.muscles[mi];
            m.target_ids = m
                .targets
                .iter()
                .map(|&t| match t {
                    TargetRef::Bone(b) => self.bones[b].target.expect("checked when added"),
                    TargetRef::Muscle(o) => muscle_target[o],
                })
                .collect();
            link_muscle(m, self.targets.as_slice());
        }
        // From now on only muscles somebody targets need a snapshot.
        let mut used: Vec<usize> = self
            .muscles
            .iter()
            .flat_map(|m| m.target_ids.clone())
            .collect();
        used.sort_unstable();
        used.dedup();
        self.published = used
            .into_iter()
            .filter(|&t| matches!(self.targets[t].source, TargetSource::Muscle(_)))
            .collect();
        self.links_dirty = false;
    }

    /// Copies the predictions of every targeted muscle into its snapshot.
    /// Publishes the targeted muscles' predictions; `first_iteration` also
    /// updates their normals and (when the slack asks for it) refits their
    /// BVHs: that iteration walks and runs the full searches.
    /// Targets are independent, so they are published in parallel on the
    /// pool.
    fn publish_muscles(&mut self, first_iteration: bool, parallel: bool) {
        use rayon::prelude::*;
        let (published, muscles) = (&self.published, &self.muscles);
        let publish = |(ti, t): (usize, &mut TargetSurface)| {
            if let TargetSource::Muscle(m) = t.source
                && published.binary_search(&ti).is_ok()
            {
                stage::publish(t, &muscles[m], first_iteration);
            }
        };
        match self.pool.as_ref().filter(|_| parallel) {
            Some((_, pool)) if published.len() > 1 => pool.install(|| {
                self.targets.par_iter_mut().enumerate().for_each(publish);
            }),
            _ => self.targets.iter_mut().enumerate().for_each(publish),
        }
    }

    /// Fills `substep_poses` with every bone's pose at fraction `alpha` of the
    /// frame (time `time`): skeleton bones from the skeleton itself, others
    /// interpolated rigidly between the frame's start and end poses.
    fn pose_bones_at(&mut self, alpha: f32, time: f32) {
        if alpha < 1.0
            && let Some(sk) = &mut self.skeleton
        {
            sk.pose_at(time);
        }
        let sk = self.skeleton.as_ref();
        self.substep_poses.clear();
        self.substep_poses
            .extend(self.bones.iter().map(|b| match (b.body, sk) {
                (Some(body), Some(sk)) if alpha < 1.0 => sk.world[body],
                _ => interpolate_rigid(b.previous, b.transform, alpha),
            }));
    }

    /// Builds (or drops) the worker pool to match `settings.threads`.
    fn sync_pool(&mut self) {
        let wanted = self.settings.threads;
        if wanted == 1 {
            self.pool = None;
            return;
        }
        if self.pool.as_ref().is_some_and(|(n, _)| *n == wanted) {
            return;
        }
        // A pool that cannot be built leaves the solver single-threaded.
        self.pool = rayon::ThreadPoolBuilder::new()
            .num_threads(wanted as usize)
            .thread_name(|i| format!("sinew-{i}"))
            .build()
            .ok()
            .map(|p| (wanted, p));
    }

    /// Advances one frame.
    pub fn step(&mut self) {
        self.sync_pool();
        let mut timings = StepTimings::default();
        let mut clock = Stopwatch::new(self.settings.timers);
        // Read inputs.
        let dt = self.settings.dt * self.settings.time_scale;
        let end_time = self.time + dt;
        if let Some(sk) = &mut self.skeleton {
            sk.pose_at(end_time);
        }
        for b in &mut self.bones {
            b.previous = b.transform;
            if let (Some(body), Some(sk)) = (b.body, &self.skeleton) {
                b.transform = sk.world[body];
            } else if !b.track.keys.is_empty() {
                b.transform = b.track.sample(end_time);
            }
        }
        for (m, curve) in self.muscles.iter_mut().zip(&self.curves) {
            if let Some(c) = curve {
                m.params.activation = c.sample(end_time);
            }
        }
        if let Some(rig) = &mut self.activation_rig {
            // The substep buffer holds the frame-end poses until the first substep.
            self.substep_poses.clear();
            self.substep_poses
                .extend(self.bones.iter().map(|b| b.transform));
            let muscles = &mut self.muscles;
            rig.update(&self.substep_poses, end_time, dt, |m, a| {
                if let Some(m) = muscles.get_mut(m) {
                    m.params.activation = a;
                }
            });
        }
        let many = self.muscles.len() > PARALLEL_MUSCLES || self.settings.parallel_threshold == 0;
        let warnings = map_muscles(
            self.pool.as_ref().filter(|_| many),
            &mut self.muscles,
            Muscle::update_activation,
        );
        self.warnings.extend(warnings.into_iter().flatten());
        self.prepare();
        // A fork and join costs about 10 µs here: a small scene runs on the
        // calling thread whatever `threads` says (the same bits either way).
        let (constraints, particles) = self
            .muscles
            .iter()
            .fold((0, 0), |(c, p), m| (c + m.counts().total(), p + m.x.len()));
        let split = constraints >= self.settings.parallel_threshold;
        let split_light = particles >= self.settings.parallel_threshold;
        clock.lap(&mut timings.read_inputs);
        let substeps = self.settings.substeps.max(1);
        let h = dt / substeps as f32;
        let inv_h2 = 1.0 / (h * h);
        let gravity = self.settings.gravity / self.settings.space_scale;
        let iterations = self.iteration_counts();
        let global_iterations = self.settings.iterations;
        for s in 0..substeps {
            // Bones and attachment goals at the substep's end time.
            let alpha = (s + 1) as f32 / substeps as f32;
            self.pose_bones_at(alpha, self.time + alpha * dt);
            for (b, pose) in self.bones.iter().zip(&self.substep_poses) {
                if let Some(t) = b.target {
                    self.targets[t].set_transform(*pose);
                }
            }
            let poses = &self.substep_poses;
            let pose = |b: Option<usize>| b.map_or(Affine3A::IDENTITY, |b| poses[b]);
            let light = self.pool.as_ref().filter(|_| split_light);
            for_each_muscle(light, &mut self.muscles, |m| {
                update_attachment_goals(m, &pose);
            });
            clock.lap(&mut timings.update_targets);
            let damping_exp = 1.0 / substeps as f32;
            self.substep_momentum = map_muscles(light, &mut self.muscles, |m| {
                begin_substep(m, gravity, h, damping_exp)
            });
            clock.lap(&mut timings.integrate);
            for it in 0..iterations {
                let full_searches = it == 0 && s == 0;
                self.publish_muscles(full_searches, split_light);
                clock.lap(&mut timings.update_targets);
                let parallel = split && self.pool.is_some();
                let search = ClosestSchedule {
                    frame: self.frame,
                    interval: self.settings.full_search_interval.max(1),
                    choose_interval: self.settings.choose_interval.max(1),
                    feature_contacts: self.settings.feature_contacts,
                    active: full_searches,
                    walk: full_searches || self.settings.walk_every_iteration,
                    substep_start: it == 0,
                    parallel,
                };
                let targets = self.targets.as_slice();
                let order = &self.settings.projection_order;
                let method = self.settings.method;
                let pool = self.pool.as_ref().filter(|_| split);
                let active =
                    |m: &Muscle| it < m.params.iterations.unwrap_or(global_iterations) as usize;
                match (stage::plan_kind(method), pool) {
                    // Global colouring and Hybrid on threads, when splitting
                    // by muscle would leave threads idle: closest data of
                    // every muscle, then colour c of every muscle in one
                    // parallel sweep (same bits as the muscle-by-muscle run
                    // below).
                    (Some((kind, omega)), Some((n, threads)))
                        if kind != coloring::PlanKind::PerConstraint
                            && match self.settings.schedule {
                                SweepSchedule::Auto => global_sweeps_pay(&self.muscles, *n),
                                SweepSchedule::ByMuscle => false,
                                SweepSchedule::ByColor => true,
                            } =>
                    {
                        for_each_muscle(pool, &mut self.muscles, |m| {
                            if active(m) {
                                closest_data(m, targets, search);
                            }
                        });
                        clock.lap(&mut timings.closest_data);
                        let muscles = &mut self.muscles;
                        let mut plans: Vec<Option<coloring::ColorPlan>> = muscles
                            .iter_mut()
                            .map(|m| {
                                active(m).then(|| coloring::take_plan(m, order, kind, it == 0))
                            })
                            .collect();
                        threads.install(|| {
                            use rayon::prelude::*;
                            let sweeps: Vec<_> = plans
                                .iter()
                                .map(|p| p.as_ref().map(coloring::ColorPlan::sweep))
                                .collect();
                            sweep::sweep_global(muscles, &sweeps, inv_h2);
                            muscles
                                .par_iter_mut()
                                .zip(&mut plans)
                                .for_each(|(m, plan)| {
                                    if let Some(mut plan) = plan.take() {
                                        coloring::project_tail(m, &mut plan, inv_h2, omega, true);
                                        m.colors = Some(plan);
                                        stage::volume_within(m, order, inv_h2, true);
                                        stage::finish_iteration(
                                            m,
                                            order,
                                            targets,
                                            inv_h2,
                                            true,
                                            it == 0,
                                        );
                                    }
                                });
                        });
                        clock.lap(&mut timings.project);
                    }
                    // Closest data and projection, muscle by muscle, in one
                    // task per muscle: a muscle reads the others only
                    // through the snapshots published above, so the split by
                    // muscle gives the same bits, and one task keeps the
                    // muscle in cache and saves a fork and join. The pass's
                    // time is split between the two blocks in proportion to
                    // the time the tasks spent in each.
                    _ => {
                        let task_time = TaskSplit::new(self.settings.timers);
                        for_each_muscle(pool, &mut self.muscles, |m| {
                            if active(m) {
                                let start = task_time.start();
                                closest_data(m, targets, search);
                                let middle = task_time.lap(start, 0);
                                project_iteration(
                                    m,
                                    method,
                                    order,
                                    targets,
                                    inv_h2,
                                    parallel,
                                    it == 0,
                                );
                                task_time.lap(middle, 1);
                            }
                        });
                        let [closest, project] = task_time.shares();
                        clock.lap_split(
                            [&mut timings.closest_data, &mut timings.project],
                            [closest, project],
                            task_time.reads(),
                        );
                    }
                }
            }
            let momenta = &self.substep_momentum;
            let end = |(m, &momentum): (&mut Muscle, &Option<RigidMomentum>)| {
                end_substep(m, h, momentum);
            };
            match self.pool.as_ref().filter(|_| split_light) {
                Some((_, pool)) => pool.install(|| {
                    use rayon::prelude::*;
                    self.muscles.par_iter_mut().zip(momenta).for_each(end);
                }),
                None => self.muscles.iter_mut().zip(momenta).for_each(end),
            }
            clock.lap(&mut timings.apply);
        }
        clock.lap(&mut timings.write_back);
        self.time = end_time;
        self.frame += 1;
        timings.clock_reads = clock.reads();
        self.timings = timings;
    }
}

/// Constraints one sweep's synchronisation costs as much as (about 10 µs of
/// fork and join on the 2-core development machine against about 50 ns per
/// constraint; `sinew suite` measures both).
const SWEEP_SYNC_CONSTRAINTS: usize = 200;

/// Whether colour-by-colour sweeps across muscles beat splitting by muscle
/// on `threads` threads: the split by muscle cannot finish before its largest
/// muscle, the sweeps pay a synchronisation per colour. The two give the
/// same bits, so this only picks the faster schedule.
fn global_sweeps_pay(muscles: &[Muscle], threads: u32) -> bool {
    let threads = if threads == 0 {
        rayon::current_num_threads()
    } else {
        threads as usize
    };
    let sizes = muscles.iter().map(|m| m.counts().total());
    let (total, largest) = sizes.fold((0, 0), |(t, l), n| (t + n, l.max(n)));
    let sweeps = muscles
        .iter()
        .filter_map(|m| m.colors.as_ref().map(coloring::ColorPlan::color_count))
        .max()
        .unwrap_or(16);
    largest > total / threads.max(1) + SWEEP_SYNC_CONSTRAINTS * sweeps
}

/// Muscles above which activations are updated in parallel (their rest
/// lengths: a few µs per muscle).
const PARALLEL_MUSCLES: usize = 16;

/// `f` of every muscle, in muscle order, computed on the pool's threads
/// when there is one.
fn map_muscles<R: Send>(
    pool: Option<&(u32, rayon::ThreadPool)>,
    muscles: &mut [Muscle],
    f: impl Fn(&mut Muscle) -> R + Sync + Send,
) -> Vec<R> {
    use rayon::prelude::*;
    match pool {
        Some((_, pool)) if muscles.len() > 1 => {
            pool.install(|| muscles.par_iter_mut().map(&f).collect())
        }
        _ => muscles.iter_mut().map(f).collect(),
    }
}

/// Runs `f` on every muscle, on the pool's threads when there is one (a
/// single muscle runs inside the pool too: its own parallel chunks use it).
fn for_each_muscle(
    pool: Option<&(u32, rayon::ThreadPool)>,
    muscles: &mut [Muscle],
    f: impl Fn(&mut Muscle) + Sync + Send,
) {
    use rayon::prelude::*;
    match pool {
        Some((_, pool)) if muscles.len() > 1 => {
            pool.install(|| muscles.par_iter_mut().for_each(&f));
        }
        Some((_, pool)) => pool.install(|| muscles.iter_mut().for_each(f)),
        None => muscles.iter_mut().for_each(f),
    }
}

#[cfg(test)]
mod tests;
