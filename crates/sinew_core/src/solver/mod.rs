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
mod momentum;
mod timings;

pub use timings::StepTimings;
use timings::Stopwatch;

use crate::animation::{Curve, TransformTrack, interpolate_rigid};
use crate::constraints::{ConstraintBatch, ConstraintKind};
use crate::error::BuildError;
use crate::mesh::SurfaceMesh;
use crate::muscle::{Muscle, MuscleDesc, SurfaceAnchor, TargetRef};
use crate::sensor::ActivationRig;
use crate::skeleton::SkeletonRig;
use crate::target::{TargetSource, TargetSurface};
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
}

/// What a colouring spans.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ColorScope {
    /// One colouring per muscle (the thesis).
    #[default]
    PerMuscle,
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
    /// (see [`crate::target`]). `1` = a full search every frame. Default: `16`.
    pub full_search_interval: u32,
    /// Walk over the targets in every iteration. When `false` (default), the
    /// walk runs in the first iteration of a frame and later iterations
    /// re-project onto the triangle it found (one triangle test): within a
    /// frame a contact point slides inside its triangle and reaches the
    /// neighbours at the next frame.
    pub walk_every_iteration: bool,
    /// Worker threads for closest data and projection, split by muscle
    /// (SPEC §9.1): `1` spawns none, `0` uses every core. Muscles read each
    /// other only through published snapshots, so the result is bit-identical
    /// for any count. Default: `1`.
    pub threads: u32,
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
            walk_every_iteration: false,
            threads: 1,
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
        if let SolverMethod::Jacobi { omega } = self.method
            && !(1.0..=2.0).contains(&omega)
        {
            return Err(bad("method.omega", omega, "must be in [1, 2]"));
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
        self.publish_muscles(true);
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
            link_muscle(m, &self.targets);
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
    fn publish_muscles(&mut self, first_iteration: bool) {
        for &ti in &self.published {
            let t = &mut self.targets[ti];
            if let TargetSource::Muscle(m) = t.source {
                let muscle = &self.muscles[m];
                t.publish(&muscle.p[..muscle.surface_count]);
                if first_iteration {
                    t.update_normals();
                    t.refit(false);
                }
            }
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
        for m in &mut self.muscles {
            if let Some(w) = m.update_activation() {
                self.warnings.push(w);
            }
        }
        self.prepare();
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
            for m in &mut self.muscles {
                update_attachment_goals(m, &pose);
            }
            clock.lap(&mut timings.update_targets);
            let damping_exp = 1.0 / substeps as f32;
            let mut free_momentum = Vec::new();
            for m in &mut self.muscles {
                integrate(m, gravity, h, damping_exp);
                m.place_pinned();
                m.constraints.clear_lambdas();
                free_momentum.push(momentum::is_free(m).then(|| momentum::measure(m)));
            }
            clock.lap(&mut timings.integrate);
            for it in 0..iterations {
                let full_searches = it == 0 && s == 0;
                self.publish_muscles(full_searches);
                clock.lap(&mut timings.update_targets);
                let search = ClosestSchedule {
                    frame: self.frame,
                    interval: self.settings.full_search_interval.max(1),
                    active: full_searches,
                    walk: full_searches || self.settings.walk_every_iteration,
                    substep_start: it == 0,
                };
                let targets = &self.targets;
                let order = &self.settings.projection_order;
                let method = self.settings.method;
                let parallel = self.pool.is_some();
                let active =
                    |m: &Muscle| it < m.params.iterations.unwrap_or(global_iterations) as usize;
                // Closest data, then projection, muscle by muscle: a muscle
                // reads the others only through the snapshots published above,
                // so splitting the work by muscle gives the same bits.
                for_each_muscle(self.pool.as_ref(), &mut self.muscles, |m| {
                    if active(m) {
                        closest_data(m, targets, search);
                    }
                });
                clock.lap(&mut timings.closest_data);
                for_each_muscle(self.pool.as_ref(), &mut self.muscles, |m| {
                    if active(m) {
                        project_iteration(m, method, order, targets, inv_h2, parallel);
                    }
                });
                clock.lap(&mut timings.project);
            }
            for (m, reference) in self.muscles.iter_mut().zip(free_momentum) {
                apply_predictions(m, h);
                if let Some(reference) = reference {
                    momentum::restore(m, reference, h);
                }
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

fn update_attachment_goals(m: &mut Muscle, pose: &impl Fn(Option<usize>) -> Affine3A) {
    let mut k = 0;
    for (i, a) in m.attachments.iter().enumerate() {
        let t = pose(a.bone);
        m.constraints.attach.goal[i] = t.transform_point3(a.vertex_local);
        if a.internal_particle.is_some() {
            m.constraints.branch_attach.goal[k] = t.transform_point3(a.internal_local);
            k += 1;
        }
    }
}

fn integrate(m: &mut Muscle, gravity: Vec3, h: f32, damping_exp: f32) {
    let keep = (1.0 - m.params.damping).powf(damping_exp);
    for i in 0..m.x.len() {
        let v = (m.v[i] + h * gravity) * keep;
        m.v[i] = v;
        m.p[i] = m.x[i] + h * v;
    }
}

fn apply_predictions(m: &mut Muscle, h: f32) {
    let inv_h = 1.0 / h;
    for i in 0..m.x.len() {
        m.v[i] = (m.p[i] - m.x[i]) * inv_h;
        m.x[i] = m.p[i];
    }
}

/// Which vertices run the full closest-point search in an iteration.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ClosestSchedule {
    /// Frame counter (staggers the vertices).
    pub frame: u64,
    /// Frames between two full searches of one vertex.
    pub interval: u32,
    /// The first iteration of a frame: full searches run, and every vertex
    /// re-chooses its closest target.
    pub active: bool,
    /// Walk from the last triangle (else re-project onto it).
    pub walk: bool,
    /// The first iteration of a substep: bones have just been posed.
    pub substep_start: bool,
}

impl ClosestSchedule {
    /// Every vertex, every target: the full search.
    #[cfg(test)]
    pub const ALWAYS: Self = Self {
        frame: 0,
        interval: 1,
        active: true,
        walk: true,
        substep_start: true,
    };

    fn wants(&self, vertex: usize) -> bool {
        self.active && (vertex as u64 + self.frame).is_multiple_of(self.interval as u64)
    }
}

/// Closest data (BE5): Sliding's closest point on the closest target per
/// vertex, and the current goals of Soft and Hard on their rest triangles.
pub(crate) fn closest_data(m: &mut Muscle, targets: &[TargetSurface], search: ClosestSchedule) {
    let nt = m.target_ids.len();
    if nt == 0 {
        return;
    }
    let c = &mut m.constraints;
    for i in 0..c.sliding.len() {
        let v = c.sliding.particle[i] as usize;
        let q = m.p[v];
        // (rank, distance, slot): the rank is the distance, except that a
        // vertex inside a rigid target (a bone) ranks it first, so Sliding
        // pushes it out of the bone even when a neighbouring muscle is nearer.
        let mut best: Option<(f32, f32, u32)> = None;
        // Last iteration's target first; every other search is bounded by the
        // best distance so far (Sliding only needs the closest target). The
        // closest target is re-chosen in the first iteration of a frame; later
        // iterations follow the chosen one only.
        let first = c.sliding.target[i] as usize;
        let choose = search.active || first >= nt;
        let order = (first < nt)
            .then_some(first)
            .into_iter()
            .chain((0..nt).filter(move |&s| choose && s != first));
        let full = search.wants(v);
        for slot in order {
            let cell = &mut m.closest[i * nt + slot];
            let warm = cell.map(|h| h.triangle);
            let target = &targets[m.target_ids[slot]];
            let lower = target.lower_bound(q);
            // Inside a bone's box the vertex may be inside the bone: search it
            // whatever the other targets' distances.
            let may_be_inside = lower == 0.0 && !target.is_deforming();
            let bound = match best {
                Some((rank, d, _)) if rank >= 0.0 && !may_be_inside => d,
                Some((rank, _, _)) if rank < 0.0 && !may_be_inside => continue,
                _ => f32::MAX,
            };
            if lower >= bound {
                continue;
            }
            let local = warm.filter(|_| !full).and_then(|t| {
                if search.walk {
                    target.walk(q, t)
                } else {
                    target.on_triangle(q, t)
                }
            });
            let hit = match local {
                Some(hit) => Some(hit),
                None => target.closest_within(q, warm, bound),
            };
            if hit.is_some() {
                *cell = hit;
            }
            if let Some(hit) = hit {
                let inside_bone = hit.signed_distance < 0.0 && !target.is_deforming();
                let rank = if inside_bone {
                    -hit.distance - 1.0
                } else {
                    hit.distance
                };
                if best.is_none_or(|(r, _, _)| rank < r) {
                    best = Some((rank, hit.distance, slot as u32));
                }
            }
        }
        match best {
            Some((_, _, slot)) => {
                let hit = m.closest[i * nt + slot as usize].expect("chosen hit");
                c.sliding.point[i] = hit.point;
                c.sliding.normal[i] = hit.normal;
                c.sliding.target[i] = slot;
            }
            None => c.sliding.target[i] = u32::MAX,
        }
    }
    // Soft and Hard goals on a rigid target only move with its bone, which
    // is posed once per substep; a muscle target moves every iteration.
    let moved = |t: &TargetSurface| search.substep_start || t.is_deforming();
    // Disabled instances (weight 0: infinite compliance) need no goal.
    for (i, a) in c.soft_anchor.iter().enumerate() {
        let t = &targets[m.target_ids[a.target as usize]];
        if c.soft.compliance[i].is_finite() && moved(t) {
            c.soft.goal[i] = t.point_at(a.triangle, a.barycentric);
        }
    }
    for (i, a) in c.hard_anchor.iter().enumerate() {
        let t = &targets[m.target_ids[a.target as usize]];
        if c.hard.compliance[i].is_finite() && moved(t) {
            c.hard.goal[i] = t.point_in_frame(a.triangle, a.barycentric, a.local);
        }
    }
}

/// Runs `f` on every muscle, on the pool's threads when there is one.
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
        _ => muscles.iter_mut().for_each(f),
    }
}

/// One iteration's projection of a muscle: every type in `order` but a
/// trailing Volume, then the bone contacts, then the Volume (which keeps the
/// volume exact while moving vertices far less than the contacts did).
fn project_iteration(
    m: &mut Muscle,
    method: SolverMethod,
    order: &[ConstraintKind],
    targets: &[TargetSurface],
    inv_h2: f32,
    parallel: bool,
) {
    let (body, volume_last) = match order.split_last() {
        Some((ConstraintKind::Volume, rest)) => (rest, true),
        _ => (order, false),
    };
    match method {
        SolverMethod::Sequential => project(m, body, inv_h2),
        SolverMethod::Colored { .. } => {
            let mut state = m
                .colors
                .take()
                .unwrap_or_else(|| coloring::ColoredState::new(m, order));
            coloring::project_colored(m, &mut state, inv_h2, parallel);
            m.colors = Some(state);
            if !volume_last && order.contains(&ConstraintKind::Volume) {
                project(m, &[ConstraintKind::Volume], inv_h2);
            }
        }
        SolverMethod::Jacobi { omega } => {
            let mut state = m
                .jacobi
                .take()
                .unwrap_or_else(|| jacobi::JacobiState::new(m, order));
            jacobi::project_jacobi(m, &mut state, inv_h2, omega, parallel);
            m.jacobi = Some(state);
            if !volume_last && order.contains(&ConstraintKind::Volume) {
                project(m, &[ConstraintKind::Volume], inv_h2);
            }
        }
    }
    bone_contacts(m, targets);
    if volume_last {
        project(m, &[ConstraintKind::Volume], inv_h2);
    }
}

/// In each iteration, after the projections (before a trailing Volume), puts
/// every surface vertex that ended up inside one of its muscle's bone targets (and was outside it at rest)
/// back on the bone's surface: bones do not give way, whatever the soft
/// constraints solved after Sliding did. Each bone is checked only for
/// vertices inside its bounding box, from the last closest triangle (a walk).
pub(crate) fn bone_contacts(m: &mut Muscle, targets: &[TargetSurface]) {
    let nt = m.target_ids.len();
    let c = &m.constraints.sliding;
    if nt == 0 || !c.rigid.iter().any(|&r| r) {
        return;
    }
    for i in 0..c.len() {
        let v = c.particle[i] as usize;
        if m.w[v] == 0.0 {
            continue;
        }
        for slot in (0..nt).filter(|&s| c.rigid[s]) {
            let target = &targets[m.target_ids[slot]];
            let q = m.p[v];
            if !c.rest_outside[i * nt + slot] || target.lower_bound(q) > 0.0 {
                continue;
            }
            let cell = &mut m.closest[i * nt + slot];
            let hit = match cell.map(|h| h.triangle) {
                Some(t) => target.walk(q, t),
                None => target.closest_within(q, None, f32::INFINITY),
            };
            if let Some(hit) = hit {
                *cell = Some(hit);
                if hit.signed_distance < 0.0 {
                    m.p[v] -= hit.normal * hit.signed_distance;
                }
            }
        }
    }
}

/// Projects every constraint of `m` once, type by type in `order` (BE6).
pub(crate) fn project(m: &mut Muscle, order: &[ConstraintKind], inv_h2: f32) {
    let (p, w, c) = (&mut m.p, &m.w, &mut m.constraints);
    for &kind in order {
        match kind {
            ConstraintKind::Attach => c.attach.solve(p, w, inv_h2),
            ConstraintKind::BranchAttach => c.branch_attach.solve(p, w, inv_h2),
            ConstraintKind::Hard => c.hard.solve(p, w, inv_h2),
            ConstraintKind::Soft => c.soft.solve(p, w, inv_h2),
            ConstraintKind::Sliding => c.sliding.solve(p, w, inv_h2),
            ConstraintKind::Branch => c.branch.solve(p, w, inv_h2),
            ConstraintKind::Internal => c.internal.solve(p, w, inv_h2),
            ConstraintKind::Fiber => c.fiber.solve(p, w, inv_h2),
            ConstraintKind::Volume => {
                if let Some(v) = &mut c.volume {
                    v.solve(p, w, inv_h2);
                }
            }
        }
    }
}

/// Creates one Sliding, Soft and Hard constraint per surface vertex against
/// the muscle's targets, from the current positions (SPEC §5.7–5.9).
fn link_muscle(m: &mut Muscle, targets: &[TargetSurface]) {
    let nt = m.target_ids.len();
    let n = m.surface_count;
    let c = &mut m.constraints;
    c.sliding = Default::default();
    c.soft = Default::default();
    c.hard = Default::default();
    c.soft_anchor.clear();
    c.hard_anchor.clear();
    m.colors = None;
    m.jacobi = None;
    m.closest = vec![None; n * nt];
    if nt == 0 {
        return;
    }
    c.sliding.targets = nt;
    c.sliding.mode = m.params.sliding_mode;
    c.sliding.rigid = m
        .target_ids
        .iter()
        .map(|&t| !targets[t].is_deforming() && matches!(targets[t].source, TargetSource::Bone(_)))
        .collect();
    for v in 0..n {
        let q = m.x[v];
        let mut best: Option<(f32, u32, crate::target::ClosestHit)> = None;
        for (slot, &tid) in m.target_ids.iter().enumerate() {
            let hit = targets[tid].closest(q, None);
            m.closest[v * nt + slot] = hit;
            match hit {
                Some(h) => {
                    c.sliding.rest_gap.push(h.distance);
                    c.sliding.rest_outside.push(!h.is_inside());
                    if best.is_none_or(|(d, _, _)| h.distance < d) {
                        best = Some((h.distance, slot as u32, h));
                    }
                }
                None => {
                    c.sliding.rest_gap.push(0.0);
                    c.sliding.rest_outside.push(true);
                }
            }
        }
        let Some((distance, slot, hit)) = best else {
            continue;
        };
        c.sliding.particle.push(v as u32);
        c.sliding.compliance.push(0.0);
        c.sliding.point.push(hit.point);
        c.sliding.normal.push(hit.normal);
        c.sliding.target.push(slot);
        c.sliding.lambda.push(0.0);
        let target = &targets[m.target_ids[slot as usize]];
        c.soft.push(v as u32, hit.point, distance, 0.0);
        c.soft_anchor.push(SurfaceAnchor {
            target: slot,
            triangle: hit.triangle,
            barycentric: hit.barycentric,
            local: Vec3::ZERO,
        });
        let frame = target.frame_at(hit.triangle, hit.barycentric);
        let local = Vec3::from(frame.basis.transpose() * glam::Vec3A::from(q - frame.origin));
        c.hard.push(v as u32, q, 0.0, 0.0);
        c.hard_anchor.push(SurfaceAnchor {
            target: slot,
            triangle: hit.triangle,
            barycentric: hit.barycentric,
            local,
        });
    }
    // rest_gap / rest_outside were pushed for every vertex; keep them aligned
    // with the constraints (vertices without any hit have no constraint).
    if c.sliding.len() != n {
        let keep: Vec<usize> = c.sliding.particle.iter().map(|&v| v as usize).collect();
        let gap = std::mem::take(&mut c.sliding.rest_gap);
        let out = std::mem::take(&mut c.sliding.rest_outside);
        for v in keep {
            c.sliding
                .rest_gap
                .extend_from_slice(&gap[v * nt..(v + 1) * nt]);
            c.sliding
                .rest_outside
                .extend_from_slice(&out[v * nt..(v + 1) * nt]);
        }
        let cl = std::mem::take(&mut m.closest);
        for &v in &c.sliding.particle {
            m.closest
                .extend_from_slice(&cl[v as usize * nt..(v as usize + 1) * nt]);
        }
    }
    m.relink_weights();
}

#[cfg(test)]
mod tests;
