//! The frame loop (SPEC §4) with the `Sequential` reference method.
//!
//! ```text
//! read inputs      activation → rest lengths and volume ratio; bone poses
//! for each substep (Small Steps; targets interpolated within the frame):
//!     update targets   bone poses at the substep, attachment goals
//!     integrate        v += Δt g;  v *= e^(−c Δt);  p = x + Δt v
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

mod bone_boxes;
mod bone_contacts;
mod closest_data;
pub mod coloring;
mod constraint_ref;
mod guard;
pub mod jacobi;
mod lane_groups;
mod link;
mod momentum;
mod muscle_ranges;
mod parallel;
mod params;
pub mod passes;
pub mod pipeline;
mod settings;
mod sliding_closest;
mod sliding_run;
mod step;
mod sweep;
mod timings;
mod workspace;

pub use constraint_ref::ConstraintRef;
pub use guard::{Fault, FaultKind, guard};
pub use momentum::RigidMomentum;
pub use parallel::{BorrowBuffer, MusclePair, WorkerPool, for_each_muscle};
pub use params::{
    ClosestSchedule, FrameParams, IterationParams, Parallelism, ProjectionOrder, SubstepParams,
};
pub use settings::{
    ColorScope, MAX_DT, MAX_GRAVITY, MAX_ITERATIONS, MAX_SUBSTEPS, MAX_THREADS, SolverMethod,
    SolverSettings, SweepSchedule,
};
pub use timings::{LayerTimings, StepTimings, Stopwatch, TaskSplit};
pub use workspace::MuscleWorkspace;

use crate::animation::{Curve, TransformTrack};
use crate::closest::{TargetSource, TargetSurface};
use crate::constraints::TargetId;
use crate::error::BuildError;
use crate::mesh::SurfaceMesh;
use crate::muscle::{Muscle, MuscleDesc, SkinBindingDesc, TargetRef};
use crate::sensor::ActivationRig;
use crate::skeleton::SkeletonRig;
use glam::Affine3A;

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
#[derive(Clone, Debug)]
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
///
/// A clone has the same state and gives the same bits from there on (its
/// worker pool is made on its first step).
#[derive(Clone, Debug)]
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
    faults: Vec<Fault>,
    /// Faults over the solver's life, and the first of them.
    fault_history: (u64, Option<Fault>),
    skeleton: Option<SkeletonState>,
    activation_rig: Option<ActivationRig>,
    /// Per muscle, what the solver derives from it (plans, caches).
    workspaces: Vec<MuscleWorkspace>,
    /// The settings of the last step that passed validation.
    valid: SolverSettings,
    /// The last settings that failed validation (reported once).
    rejected: Option<SolverSettings>,
    /// Worker threads for `settings.threads != 1`.
    pool: WorkerPool,
    /// The muscles and their workspaces, borrowed as pairs by each pass.
    pairs: BorrowBuffer<MusclePair<'static>>,
    /// The targeted muscles' snapshots and the muscles, borrowed to publish.
    snapshots: BorrowBuffer<(&'static mut TargetSurface, &'static Muscle)>,
    /// Bone poses at the current substep.
    substep_poses: Vec<Affine3A>,
}

impl Solver {
    /// An empty solver.
    pub fn new(settings: SolverSettings) -> Result<Self, BuildError> {
        settings.validate()?;
        Ok(Self {
            valid: settings.clone(),
            rejected: None,
            settings,
            workspaces: Vec::new(),
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
            faults: Vec::new(),
            fault_history: (0, None),
            skeleton: None,
            activation_rig: None,
            pool: WorkerPool::default(),
            pairs: BorrowBuffer::default(),
            snapshots: BorrowBuffer::default(),
            substep_poses: Vec::new(),
        })
    }

    /// Adds a bone posed by `track` (or by the host when the track is empty), with
    /// an optional mesh (local frame) that muscles can target. Returns its index.
    /// A mesh the same, to the bit, as an earlier bone's shares that bone's
    /// target geometry ([`TargetSurface::sharing_geometry`]): a crowd holds
    /// one copy of each bone however many bodies it has.
    pub fn add_bone(
        &mut self,
        name: impl Into<String>,
        track: TransformTrack,
        mesh: Option<&SurfaceMesh>,
    ) -> usize {
        let name = name.into();
        let source = TargetSource::Bone(self.bones.len());
        let target = mesh.map(|m| {
            let same = (self.targets.iter()).find(|t| t.is_rigid_of(&m.positions, &m.triangles));
            match same {
                Some(same) => same.sharing_geometry(name.clone(), source),
                None => TargetSurface::new(
                    name.clone(),
                    source,
                    m.positions.clone(),
                    m.triangles.clone(),
                ),
            }
        });
        self.push_bone(name, track, target)
    }

    /// Adds a bone of the same mesh as bone `like` (a copy of it in a
    /// crowd), sharing its target geometry without loading the mesh again.
    /// Returns its index. `like` must be a bone already added.
    pub(crate) fn add_bone_like(
        &mut self,
        name: String,
        track: TransformTrack,
        like: usize,
    ) -> usize {
        let source = TargetSource::Bone(self.bones.len());
        let target = (self.bones[like].target)
            .map(|t| self.targets[t].sharing_geometry(name.clone(), source));
        self.push_bone(name, track, target)
    }

    /// Adds a bone posed by `track`, with its target (if any) posed too.
    fn push_bone(
        &mut self,
        name: String,
        track: TransformTrack,
        target: Option<TargetSurface>,
    ) -> usize {
        let index = self.bones.len();
        let pose = track.sample(self.time);
        let target = target.map(|mut t| {
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
        if let Some(binding) = &desc.binding {
            for (v, influences) in binding.influences.iter().enumerate() {
                if let Some(&(b, _)) = influences.iter().find(|&&(b, _)| b >= self.bones.len()) {
                    return Err(BuildError::InvalidParameter {
                        muscle: desc.name.clone(),
                        parameter: format!("binding.influences[{v}]"),
                        value: b as f32,
                        reason: format!("there are only {} bones", self.bones.len()),
                    });
                }
            }
        }
        let mut desc = desc;
        if desc.params.hold_shape && desc.binding.is_none() {
            desc.binding = self.holding_shape(&desc)?;
        }
        let bones = &self.bones;
        let muscle = Muscle::build(desc, self.settings.length_unit, |b| bones[b].transform)?;
        let mut target = TargetSurface::new(
            muscle.name.clone(),
            TargetSource::Muscle(index),
            muscle.surface_positions().to_vec(),
            muscle.mesh.triangles.clone(),
        );
        target.set_transform(Affine3A::IDENTITY);
        self.targets.push(target);
        self.muscles.push(muscle);
        self.workspaces.push(MuscleWorkspace::default());
        self.curves.push(None);
        self.links_dirty = true;
        Ok(index)
    }

    /// The binding of a muscle that holds its shape
    /// ([`crate::muscle::MuscleParams::hold_shape`]): on its attachment bones
    /// and the bones it targets, by their surfaces
    /// ([`SkinBindingDesc::holding_shape`]).
    fn holding_shape(&self, desc: &MuscleDesc) -> Result<Option<SkinBindingDesc>, BuildError> {
        let positions = &desc.mesh.positions;
        let (_, held) = crate::muscle::held_by(&desc.attachments, positions, &desc.name)?;
        // A bone both targeted and attached to is measured once.
        let mut bones: Vec<usize> = desc
            .targets
            .iter()
            .filter_map(|t| match t {
                TargetRef::Bone(b) => Some(*b),
                TargetRef::Muscle(_) => None,
            })
            .chain(desc.attachments.iter().filter_map(|a| a.bone))
            .collect();
        bones.sort_unstable();
        bones.dedup();
        let surfaces: Vec<(usize, &TargetSurface)> = bones
            .into_iter()
            .filter_map(|b| self.bones[b].target.map(|t| (b, &self.targets[t])))
            .collect();
        Ok(SkinBindingDesc::holding_shape(positions, &held, &surfaces))
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
    /// compliances call [`Muscle::apply_compliances`]; after editing a
    /// batch's particle indices, [`Muscle::touch_topology`].
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

    /// Moves the clock to `time` (s): from the next step bone tracks, joint
    /// motion and activation curves are sampled from there — a host looping
    /// an animation sets it back to its start. Velocities and the frame
    /// count are kept.
    pub fn set_time(&mut self, time: f32) {
        self.time = time;
    }

    /// Frames stepped so far.
    pub fn frame(&self) -> u64 {
        self.frame
    }

    /// What the solver derived from each muscle (in muscle order).
    pub fn workspaces(&self) -> &[MuscleWorkspace] {
        &self.workspaces
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

    /// Muscles whose frame blew up since the last call (non-finite or
    /// faster than [`SolverSettings::max_speed`]): each was put back to its
    /// last good frame while the others ran on. The first fault of a
    /// muscle is also a warning ([`Solver::take_warnings`]).
    pub fn take_faults(&mut self) -> Vec<Fault> {
        std::mem::take(&mut self.faults)
    }

    /// How many muscle frames the guard has put back over the solver's
    /// life, and the first fault (kept when [`Solver::take_faults`] drains
    /// the recent ones).
    pub fn fault_history(&self) -> (u64, Option<&Fault>) {
        (self.fault_history.0, self.fault_history.1.as_ref())
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
        for t in &mut self.targets {
            if let TargetSource::Muscle(m) = t.source {
                pipeline::publish_at(t, &self.muscles[m], true);
            }
        }
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
        for (m, ws) in self.muscles.iter_mut().zip(&mut self.workspaces) {
            ws.target_ids = m
                .targets
                .iter()
                .map(|&t| match t {
                    TargetRef::Bone(b) => self.bones[b].target.expect("checked when added"),
                    TargetRef::Muscle(o) => muscle_target[o],
                })
                .map(TargetId::new)
                .collect();
            pipeline::link(m, ws, self.targets.as_slice());
        }
        // From now on only muscles somebody targets need a snapshot.
        let mut used: Vec<usize> = self
            .workspaces
            .iter()
            .flat_map(|ws| ws.target_ids.iter().map(|t| t.index()))
            .collect();
        used.sort_unstable();
        used.dedup();
        self.published = used
            .into_iter()
            .filter(|&t| matches!(self.targets[t].source, TargetSource::Muscle(_)))
            .collect();
        // A published muscle stages its snapshot in its own iterate task.
        for ws in &mut self.workspaces {
            ws.staged.target = None;
            ws.staged.ready = false;
        }
        for &t in &self.published {
            if let TargetSource::Muscle(m) = self.targets[t].source {
                self.workspaces[m].staged.target = Some(TargetId::new(t));
            }
        }
        self.links_dirty = false;
    }
}

#[cfg(test)]
mod determinism_tests;
#[cfg(test)]
mod parallelism_tests;
#[cfg(test)]
mod shared_geometry_tests;
#[cfg(test)]
mod snapshot_interval_tests;
#[cfg(test)]
mod spread_iterations_tests;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod walk_interval_tests;
