//! What an import makes: [`ImportOptions`] and its parts.

use super::*;

/// Which bones get a mesh in the scene.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum BoneMeshes {
    /// Only bones that some muscle targets or is attached to.
    #[default]
    Used,
    /// Every body with a mesh geom.
    All,
}

/// A user mesh to use for a muscle instead of sweeping one.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct UserMuscleMesh {
    /// Muscle (actuator) name.
    pub muscle: String,
    /// OBJ or STL file (relative to the recipe or the working directory), in
    /// the model's world frame after the Y-up conversion. Units: m.
    pub file: String,
}

/// Per-muscle targets replacing the automatic choice.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TargetOverride {
    /// Muscle name.
    pub muscle: String,
    /// Bone and muscle names.
    pub targets: Vec<String>,
}

/// How a model is turned into a scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImportOptions {
    /// Actuators to make muscles of; empty = every tendon actuator.
    pub muscles: Vec<String>,
    /// Mesh resolution and thickness.
    pub sweep: SweepOptions,
    /// Per-muscle belly radius overrides `(muscle, radius m)`. A name that
    /// is not among the imported muscles is an error.
    pub radii: Vec<(String, f32)>,
    /// User meshes instead of swept ones.
    pub user_meshes: Vec<UserMuscleMesh>,
    /// Rings at each end held by the bone, besides the tip vertex.
    /// Default: 1.
    pub attach_rings: u32,
    /// Per-muscle overrides of `attach_rings`: `(muscle, rings held at its
    /// origin, rings held at its insertion)`, each besides the tip vertex
    /// (0: the tip alone). A longer tendon, or a broader attachment, holds
    /// more of the surface on its bone. A name that is not among the
    /// imported muscles is an error. Default: none.
    pub held_rings: Vec<(String, u32, u32)>,
    /// Most muscles a muscle targets (nearest first).
    pub muscle_targets: usize,
    /// Most bones a muscle targets (nearest first).
    pub bone_targets: usize,
    /// Neighbours farther than this are not targets. Units: m.
    pub neighbour_distance: f32,
    /// Targets chosen by hand.
    pub targets: Vec<TargetOverride>,
    /// Vertices inside a bone are pushed this far outside it. Units: m.
    pub push_out_margin: f32,
    /// Which bones get meshes.
    pub bone_meshes: BoneMeshes,
    /// Convert MuJoCo's Z-up to Y-up (Bevy). Default: true.
    pub y_up: bool,
    /// Run each tendon's path around its wrapping geoms (spheres and
    /// cylinders, on the side of their side sites) at the reference pose,
    /// as MuJoCo does, instead of straight through its sites. Default:
    /// false.
    pub wrap_paths: bool,
    /// Parameters of every muscle.
    pub params: MuscleParams,
}

impl Default for ImportOptions {
    fn default() -> Self {
        Self {
            muscles: Vec::new(),
            sweep: SweepOptions::default(),
            radii: Vec::new(),
            user_meshes: Vec::new(),
            attach_rings: 1,
            held_rings: Vec::new(),
            muscle_targets: 5,
            bone_targets: 3,
            neighbour_distance: 0.02,
            targets: Vec::new(),
            push_out_margin: 0.001,
            wrap_paths: false,
            bone_meshes: BoneMeshes::Used,
            y_up: true,
            params: MuscleParams::default(),
        }
    }
}

impl ImportOptions {
    /// Rings held at the origin and at the insertion of `muscle`, besides
    /// its tips: its [`Self::held_rings`] entry, or [`Self::attach_rings`]
    /// at both ends.
    pub fn rings_held_by(&self, muscle: &str) -> [u32; 2] {
        self.held_rings
            .iter()
            .find(|(m, ..)| m == muscle)
            .map_or([self.attach_rings; 2], |&(_, origin, insertion)| {
                [origin, insertion]
            })
    }
}
