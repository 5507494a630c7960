//! Components: bones and their target meshes, muscles with their parameters
//! and built state, activation drivers.

use crate::constraint_table::SetsSeen;
pub use crate::constraint_table::{Compliance, ConstraintSet, ConstraintSets};
use bevy::prelude::*;
use sinew_core::BuildError;
use sinew_core::MeshError;
use sinew_core::animation::{Curve, TransformTrack};
use sinew_core::closest::{TargetSource, TargetSurface};
use sinew_core::constraints::FiberMode as CoreFiberMode;
use sinew_core::glam::Affine3A;
use sinew_core::mesh::{LoadOptions, SurfaceMesh};
use sinew_core::muscle::{
    Compliances, ConnectionWeights as CoreWeights, Muscle as CoreMuscle, MuscleParams,
};
use sinew_core::skeleton::SkeletonRig;
use sinew_core::solver::MuscleWorkspace;
use std::path::Path;

/// A bone: a kinematic body muscles attach to and slide on. Its pose is its
/// [`GlobalTransform`], read after transform propagation in the same frame.
#[derive(Component, Clone, Debug, Default, PartialEq, Reflect)]
#[reflect(Component, Default)]
#[require(Transform, BonePose)]
pub struct SinewBone {
    /// Name (used by sensors and in messages).
    pub name: String,
}

impl SinewBone {
    /// A bone called `name`.
    pub fn new(name: impl Into<String>) -> Self {
        Self { name: name.into() }
    }
}

/// A bone's pose at the start and end of the current frame (world from
/// local); substeps interpolate between them. Maintained by the plug-in.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct BonePose {
    /// Pose at the start of the frame.
    pub previous: Affine3A,
    /// Pose at the end of the frame.
    pub current: Affine3A,
    /// Pose at the end of the current substep (interpolated once per bone,
    /// read by its target and by the attachments).
    pub substep: Affine3A,
    /// Whether `current` was read from the bone; a fresh bone starts at rest
    /// (no motion in its first frame).
    pub initialized: bool,
    /// Pose at the end of the last update's last step: where a bone moved by
    /// the app (not by a sinew track or skeleton) is interpolated from when
    /// one update runs several steps ([`crate::SimulationPacing`]).
    pub update_start: Affine3A,
}

impl BonePose {
    /// A bone already at `pose` (its first frame moves it from there).
    pub fn at(pose: Affine3A) -> Self {
        Self {
            previous: pose,
            current: pose,
            substep: pose,
            initialized: true,
            update_start: pose,
        }
    }
}

/// A bone's mesh as a collision/sliding target (local frame, with a BVH).
/// The plug-in moves it with the bone every substep. Cloning one shares its
/// geometry (the BVH, adjacency and side data are built once): load a bone
/// once and give each character's bone entity a clone.
#[derive(Component, Clone, Debug)]
pub struct BoneTarget(pub TargetSurface);

impl BoneTarget {
    /// A target from an OBJ or STL file, its vertices in the bone's frame
    /// (scene units; degenerate faces of scanned bones are dropped). For a
    /// bone whose mesh is also rendered, `TargetFromMesh` (feature `render`)
    /// makes one from its `Mesh3d`.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, MeshError> {
        let path = path.as_ref();
        let options = LoadOptions {
            drop_degenerate_faces: true,
            ..Default::default()
        };
        let mesh = SurfaceMesh::load(path, &options)?;
        let name = path.file_stem().map_or_else(
            || path.display().to_string(),
            |s| s.to_string_lossy().into(),
        );
        let mut target =
            TargetSurface::new(name, TargetSource::Bone(0), mesh.positions, mesh.triangles);
        target.set_transform(Affine3A::IDENTITY);
        Ok(Self(target))
    }
}

/// Keyframed animation of a bone (from a scene): the plug-in writes its
/// [`Transform`] for the end time of the coming step, before propagation.
#[derive(Component, Clone, Debug, Default, PartialEq)]
pub struct BoneTrack(pub TransformTrack);

impl BoneTrack {
    /// `base` posed by the track at time `t` (rotation and translation
    /// from the track, `base`'s scale kept), or `None` for a track with no
    /// keys (it leaves the bone where it is). What the plug-in writes to
    /// the bone's `Transform`, and what a step earlier in an update reads.
    pub fn transform_at(&self, t: f32, base: &Transform) -> Option<Transform> {
        if self.0.keys.is_empty() {
            return None;
        }
        let (rotation, translation) = self.0.sample_parts(t);
        Some(Transform {
            rotation,
            translation,
            ..*base
        })
    }
}

/// A skeleton (joint tree with keyframed joint values, from a scene) that
/// poses bones: each `(entity, body)` pair gets the body's world frame.
#[derive(Component, Clone, Debug)]
#[require(SkeletonFrames)]
pub struct SkeletonDriver {
    /// The compiled skeleton.
    pub rig: SkeletonRig,
    /// Bone entities and the skeleton body each follows.
    pub bones: Vec<(Entity, usize)>,
}

/// Every body frame of a [`SkeletonDriver`]'s skeleton at the end of the
/// coming step: posed once a frame when its bones are animated, and read
/// back as those bones' exact poses (a `Transform` round trip would round
/// them).
#[derive(Component, Clone, Debug, Default)]
pub struct SkeletonFrames(pub Vec<Affine3A>);

/// Fibre rest-length formula, as [`CoreFiberMode`] but reflectable.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
pub enum FiberMode {
    /// Eq. 2.12–2.15 as written (component-wise; not rotation-invariant).
    PaperExact,
    /// Only the edge component along the fibre shortens.
    #[default]
    RotationInvariant,
}

impl From<FiberMode> for CoreFiberMode {
    fn from(m: FiberMode) -> Self {
        match m {
            FiberMode::PaperExact => CoreFiberMode::PaperExact,
            FiberMode::RotationInvariant => CoreFiberMode::RotationInvariant,
        }
    }
}

impl From<CoreFiberMode> for FiberMode {
    fn from(m: CoreFiberMode) -> Self {
        match m {
            CoreFiberMode::PaperExact => FiberMode::PaperExact,
            CoreFiberMode::RotationInvariant => FiberMode::RotationInvariant,
        }
    }
}

/// Default weights of a muscle's three target connections (as the core's
/// [`CoreWeights`], reflectable): a vertex's Sliding, Soft and Hard
/// compliances are divided by them (0 switches one off), normalised per
/// vertex when `normalize` is set.
#[derive(Clone, Copy, Debug, PartialEq, Reflect)]
pub struct Weights {
    /// Sliding weight. Range `[0, ∞)`. Default: `1.0`.
    pub sliding: f32,
    /// Soft weight. Range `[0, ∞)`. Default: `0.5`.
    pub soft: f32,
    /// Hard weight. Range `[0, ∞)`. Default: `0.25`.
    pub hard: f32,
    /// Divide the three by their sum per vertex. Default: `true`.
    pub normalize: bool,
}

impl From<CoreWeights> for Weights {
    fn from(w: CoreWeights) -> Self {
        Self {
            sliding: w.sliding,
            soft: w.soft,
            hard: w.hard,
            normalize: w.normalize,
        }
    }
}

impl From<Weights> for CoreWeights {
    fn from(w: Weights) -> Self {
        Self {
            sliding: w.sliding,
            soft: w.soft,
            hard: w.hard,
            normalize: w.normalize,
        }
    }
}

/// A muscle and its live parameters: every parameter that needs no
/// rebuild. Edits take effect on the next step; a value the core refuses
/// ([`MuscleParams::validate`]) is reported once and the last valid
/// parameters are kept. The built particles and constraints are in
/// [`MuscleState`], which the plug-in inserts once the muscle is built.
#[derive(Component, Clone, Debug, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct Muscle {
    /// Activation `a ∈ [0, 1]` (values outside are clamped and reported once).
    pub activation: f32,
    /// Sensors or an [`ActivationCurve`] set `activation` every frame; when
    /// `false` the value here (a slider) rules.
    pub driven: bool,
    /// Compliance per constraint type.
    pub compliance: Compliance,
    /// Activation-independent volume gain `G` (1 keeps the rest volume).
    /// Range `(0, ∞)`. Default: `1`.
    pub volume_gain: f32,
    /// Volume gain at full activation `R` (the overpressure of a flexed
    /// muscle). Range `(0, ∞)`. Default: the core's.
    pub activation_volume_gain: f32,
    /// Iterations for this muscle; `None` uses [`crate::SinewSettings::iterations`].
    pub iterations: Option<u32>,
    /// Fibre rest-length formula.
    pub fiber_mode: FiberMode,
    /// Velocity damping rate: the velocity keeps `e^(−c h)` over `h`
    /// seconds. Units: 1/s. Range `[0, 1000]`. Default: `3.08`.
    pub damping: f32,
    /// Default Sliding / Soft / Hard weights (per-vertex maps override
    /// them).
    pub weights: Weights,
    /// Fraction of fibre length lost at full activation. Range `[0, 1]`.
    /// Default: `0.35`.
    pub max_contraction: f32,
    /// Activation of the modelled (rest) shape, clamped to ≤ 0.95. Range
    /// `[0, 1]`. Default: `0`.
    pub rest_activation: f32,
    /// What is left of a held shape's pull at full activation
    /// ([`MuscleParams::hold_release`]; only for a muscle built with
    /// `hold_shape`). Range `[0.01, 1]`. Default: `1`.
    pub hold_release: f32,
    /// How a held line bends at its ends, in chord lengths
    /// ([`MuscleParams::hold_bend`]; only for a muscle holding its shape
    /// along its line). Unitless, range `[0, 4]`. Default: `0`.
    pub hold_bend: f32,
    /// How far each end's held rings turn about their tendon's tip
    /// towards the line ([`MuscleParams::tendon_pivot`]). Unitless, range
    /// `[0, 1]`. Default: `0`.
    pub tendon_pivot: f32,
    /// Whether the rest lengths follow the held shape
    /// ([`MuscleParams::rest_follows_hold`]). Default: `false`.
    pub rest_follows_hold: bool,
}

impl Default for Muscle {
    fn default() -> Self {
        Self::from_params(&MuscleParams::default())
    }
}

impl Muscle {
    /// The live parameters of a muscle built with `p`.
    pub fn from_params(p: &MuscleParams) -> Self {
        Self {
            activation: p.activation,
            driven: false,
            compliance: p.compliance.into(),
            volume_gain: p.volume.gain,
            activation_volume_gain: p.volume.activation_gain,
            iterations: p.iterations,
            fiber_mode: p.fiber_mode.into(),
            damping: p.damping,
            weights: p.weights.into(),
            max_contraction: p.max_contraction,
            rest_activation: p.rest_activation,
            hold_release: p.hold_release,
            hold_bend: p.hold_bend,
            tendon_pivot: p.tendon_pivot,
            rest_follows_hold: p.rest_follows_hold,
        }
    }

    /// Writes these values into `p`; returns whether a compliance or a
    /// weight changed (the batches then need
    /// [`CoreMuscle::apply_compliances`]).
    pub fn write_to(&self, p: &mut MuscleParams) -> bool {
        p.activation = self.activation;
        p.volume.gain = self.volume_gain;
        p.volume.activation_gain = self.activation_volume_gain;
        p.iterations = self.iterations;
        p.fiber_mode = self.fiber_mode.into();
        p.damping = self.damping;
        p.max_contraction = self.max_contraction;
        p.rest_activation = self.rest_activation;
        p.hold_release = self.hold_release;
        p.hold_bend = self.hold_bend;
        p.tendon_pivot = self.tendon_pivot;
        p.rest_follows_hold = self.rest_follows_hold;
        let (compliance, weights): (Compliances, CoreWeights) =
            (self.compliance.into(), self.weights.into());
        let changed = compliance != p.compliance || weights != p.weights;
        p.compliance = compliance;
        p.weights = weights;
        changed
    }

    /// Whether the core accepts these values written over `p`
    /// ([`MuscleParams::validate`]; the activation is left to its clamp).
    /// `muscle` names the muscle in the error.
    pub fn validate(&self, p: &MuscleParams, muscle: &str) -> Result<(), BuildError> {
        let mut params = p.clone();
        self.write_to(&mut params);
        params.activation = 0.0;
        params.validate(muscle)
    }
}

/// A muscle's built state: particles, internal structure, constraint
/// batches, maps — the plain model the kernels (`sinew_core`'s) work on.
/// What the solver derives from it lives next to it in [`SolverWorkspace`].
#[derive(Component, Clone, Debug)]
#[require(SolverWorkspace, ConstraintSets, SetsSeen)]
pub struct MuscleState {
    /// The core muscle.
    pub muscle: CoreMuscle,
    /// Whether Sliding / Soft / Hard are linked to the current targets.
    pub(crate) linked: bool,
    /// Why the last parameters were refused (reported once).
    pub(crate) rejected: Option<String>,
    /// The attachment entities in place and their bones, in the order of
    /// [`crate::relations::Attachments`]: the core's bone index `k` is the
    /// `k`-th one's bone.
    pub(crate) attached: Vec<(Entity, Option<Entity>)>,
    /// The place the next attachment takes in the muscle's list.
    pub(crate) next_attachment: u64,
    /// Pose of each attachment's bone at the current substep (kept when a
    /// bone goes away within a step).
    pub(crate) bone_poses: Vec<Affine3A>,
    /// The targets Sliding / Soft / Hard are linked to, in order.
    pub(crate) connected: Vec<Entity>,
    /// A skin binding's bones: the core's binding bone index `k` is the
    /// `k`-th entity (a scene's bones, in scene order). Empty without a
    /// binding.
    pub(crate) bound_bones: Vec<Entity>,
    /// Pose of each bound bone at the current substep (kept when a bone
    /// goes away).
    pub(crate) bind_poses: Vec<Affine3A>,
}

impl MuscleState {
    /// Wraps a built muscle; its attachment entities and target links are
    /// read on the next step.
    pub fn new(muscle: CoreMuscle) -> Self {
        Self {
            next_attachment: muscle.attachments.len() as u64,
            muscle,
            linked: false,
            rejected: None,
            attached: Vec::new(),
            bone_poses: Vec::new(),
            connected: Vec::new(),
            bound_bones: Vec::new(),
            bind_poses: Vec::new(),
        }
    }

    /// Surface vertex positions (world).
    pub fn surface_positions(&self) -> &[Vec3] {
        self.muscle.surface_positions()
    }

    /// Asks for Sliding / Soft / Hard to be rebuilt from the current
    /// geometry on the next step.
    pub fn relink(&mut self) {
        self.linked = false;
    }
}

/// What the solver derives from a muscle's [`MuscleState`] and keeps
/// between steps: its colour plan or Jacobi incidence, closest-data caches,
/// the index of each of its targets in the step's target table. Maintained
/// by the plug-in (inserted with the state); read it for reports and debug
/// views ([`MuscleWorkspace::plan`]).
#[derive(Component, Clone, Debug, Default)]
pub struct SolverWorkspace(pub MuscleWorkspace);

/// A muscle as a target for other muscles: its surface as it was at the end
/// of the last iteration. Maintained by the plug-in.
#[derive(Component, Clone, Debug)]
pub struct MuscleSnapshot {
    /// The published surface.
    pub surface: TargetSurface,
    /// Some muscle targets it (only those are published).
    pub(crate) targeted: bool,
}

/// Drives [`Muscle::activation`] with a curve of simulated time (when
/// [`Muscle::driven`]).
#[derive(Component, Clone, Debug, PartialEq)]
pub struct ActivationCurve(pub Curve);
