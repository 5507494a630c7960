//! The RON scene format: bones (meshes + keyframed poses), muscles (mesh file
//! or generator, roots, attachments, targets, parameters, activation curve)
//! and solver settings. [`builtin`] makes the thesis' reference scenes.
//!
//! ```ron
//! Scene(
//!     name: "P1",
//!     frames: 120,
//!     settings: (iterations: 5, gravity: (0.0, -9.81, 0.0)),
//!     bones: [
//!         (name: "ground", shape: Some(Plane(center: (0.0, -0.04, 0.0), normal: (0.0, 1.0, 0.0), size: 0.4))),
//!     ],
//!     muscles: [
//!         (
//!             name: "oval",
//!             mesh: Generator(Ellipsoid(center: (0.0, 0.0, 0.0), radii: (0.06, 0.025, 0.025), segments: 10, stacks: 10)),
//!             roots: Vertices([0]),
//!             attachments: [(vertex: Some(0)), (vertex: Some(91))],
//!             targets: ["ground"],
//!         ),
//!     ],
//! )
//! ```
//! Paths of mesh files are relative to the scene file.

mod binding;
mod builtin;
mod crowd;
pub use crowd::MAX_CROWD;
mod meshes;
mod validate;

pub use binding::SkinBindingSpec;
pub use builtin::{BUILTIN_SCENES, builtin};

use crate::animation::{Curve, TransformTrack};
use crate::error::SceneError;
use crate::mesh::SurfaceMesh;
use crate::mesh::primitives::MeshGenerator;
use crate::muscle::{AttachmentDesc, MuscleDesc, MuscleParams, Roots, TargetRef, VertexMaps};
use crate::sensor::{ActivationLayer, ActivationRig, SensorSpec};
use crate::skeleton::Skeleton;
use crate::solver::{Solver, SolverSettings};
use glam::Vec3;
use meshes::{bone_mesh, muscle_mesh};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A whole scene.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Scene {
    /// Scene name.
    pub name: String,
    /// What the scene shows.
    pub description: String,
    /// Frames a bake or benchmark runs by default.
    pub frames: u32,
    /// Solver settings.
    pub settings: SolverSettings,
    /// Kinematic bones (and static colliders such as planes).
    pub bones: Vec<BoneSpec>,
    /// Muscles.
    pub muscles: Vec<MuscleSpec>,
    /// Joint hierarchy and its keyframed motion; bones with a `body` follow it.
    pub skeleton: Option<Skeleton>,
    /// Sensors reading bone frames, for muscles' activation layers.
    pub sensors: Vec<SensorSpec>,
}

/// A bone: its shape (optional; needed to be a target) and its animation.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BoneSpec {
    /// Unique name.
    pub name: String,
    /// Geometry in the bone's local frame.
    pub shape: Option<BoneShape>,
    /// Keyframed pose; empty = identity (static).
    pub track: TransformTrack,
    /// Skeleton body this bone follows (replaces `track`).
    pub body: Option<String>,
}

/// Geometry of a bone.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum BoneShape {
    /// An OBJ or STL file (relative to the scene), optionally scaled.
    Mesh {
        /// File path.
        file: String,
        /// Scale factor applied on load. Default: 1.
        #[serde(default = "one")]
        scale: f32,
        /// Reverse the faces of a closed mesh whose faces point inwards
        /// (negative volume) instead of refusing it. Default: false.
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        orient_outward: bool,
    },
    /// A square plane (two triangles) of side `size`, facing `normal`.
    Plane {
        /// Centre. Units: m.
        center: Vec3,
        /// Outward normal.
        normal: Vec3,
        /// Side length. Units: m.
        size: f32,
    },
    /// A generated mesh.
    Generated(MeshGenerator),
}

fn one() -> f32 {
    1.0
}

/// Where a muscle's mesh comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum MeshSource {
    /// OBJ or STL file relative to the scene.
    File {
        /// File path.
        path: String,
        /// Triangulate polygons (diagonals carry fibres too). Default: false.
        #[serde(default)]
        triangulate: bool,
        /// Scale applied on load. Default: 1.
        #[serde(default = "one")]
        scale: f32,
        /// Reverse the faces of a closed mesh whose faces point inwards
        /// (negative volume) instead of refusing it. Default: false.
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        orient_outward: bool,
        /// Moves the mesh, after the scale (a copy of a body placed beside
        /// it, see [`Scene::crowd`]). Units: scene units. Default: zero.
        #[serde(default, skip_serializing_if = "is_zero_vector")]
        translation: Vec3,
    },
    /// A built-in generator.
    Generator(MeshGenerator),
}

impl Default for MeshSource {
    fn default() -> Self {
        Self::Generator(crate::mesh::primitives::thesis_oval(Vec3::ZERO))
    }
}

/// An attachment in a scene.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AttachmentSpec {
    /// Bone name; `None` pins to the world.
    pub bone: Option<String>,
    /// Held vertex; `None` picks the vertex nearest `point`.
    pub vertex: Option<u32>,
    /// Rest-pose point used when `vertex` is `None`. Units: scene units.
    pub point: Option<Vec3>,
    /// With `point`: hold every vertex within this distance of it (a
    /// region), not only the nearest. Units: scene units. Default: `0`.
    #[serde(skip_serializing_if = "is_zero")]
    pub radius: f32,
}

fn is_zero(x: &f32) -> bool {
    *x == 0.0
}

fn is_zero_vector(v: &Vec3) -> bool {
    *v == Vec3::ZERO
}

/// A muscle in a scene.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MuscleSpec {
    /// Unique name.
    pub name: String,
    /// Mesh file or generator.
    pub mesh: MeshSource,
    /// Roots of the internal structure.
    pub roots: Roots,
    /// Attachments.
    pub attachments: Vec<AttachmentSpec>,
    /// Target names (bones with shapes, or muscles).
    pub targets: Vec<String>,
    /// Parameters.
    pub params: MuscleParams,
    /// Activation over time; `None` keeps `params.activation`.
    pub activation: Option<Curve>,
    /// Activation from sensors (replaces `activation` when not empty).
    pub drive: Vec<ActivationLayer>,
    /// Per-vertex maps.
    pub maps: VertexMaps,
    /// Skin binding: each surface vertex held softly to its linear-blend
    /// skinned position (a skin over the muscles); `None`: unbound.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub binding: Option<SkinBindingSpec>,
}

impl Scene {
    /// Reads a RON scene and [validates](Scene::validate) it. Syntax errors
    /// carry line and column; a misspelt field names the nearest valid one.
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            file: path.to_path_buf(),
            source,
        })?;
        let scene = Self::from_ron(&text, path)?;
        scene.validate().map_err(|e| e.in_file(path))?;
        Ok(scene)
    }

    /// Parses RON text; `path` is used in error messages. Unknown fields
    /// are errors; values are checked by [`Scene::validate`].
    pub fn from_ron(text: &str, path: &Path) -> Result<Self, SceneError> {
        crate::ron_text::parse(text, path)
    }

    /// RON text of the scene.
    pub fn to_ron(&self) -> Result<String, SceneError> {
        let config = ron::ser::PrettyConfig::new()
            .depth_limit(6)
            .struct_names(true);
        ron::ser::to_string_pretty(self, config).map_err(|e| SceneError::Serialize(e.to_string()))
    }

    /// Writes the scene as RON.
    pub fn save(&self, path: &Path) -> Result<(), SceneError> {
        let text = self.to_ron()?;
        crate::atomic_file::write(path, text).map_err(|source| SceneError::Io {
            file: path.to_path_buf(),
            source,
        })
    }

    /// Time of the scene's last motion key: bone tracks, joint motion and
    /// activation curves (sensors follow the bones). `0` for a still scene.
    /// Units: s.
    pub fn motion_end(&self) -> f32 {
        let tracks = self
            .bones
            .iter()
            .flat_map(|b| b.track.keys.iter().map(|k| k.time));
        let joints = self.skeleton.iter().flat_map(|s| {
            s.motion
                .iter()
                .flat_map(|m| m.curve.keys.iter().map(|k| k.0))
        });
        let curves = self
            .muscles
            .iter()
            .filter_map(|m| m.activation.as_ref())
            .flat_map(|c| c.keys.iter().map(|k| k.0));
        tracks.chain(joints).chain(curves).fold(0.0, f32::max)
    }

    /// Holds every bone track, joint motion and activation curve at its
    /// value at time 0: the scene at rest in its first pose (sensors then
    /// read still bones).
    pub fn hold_first_pose(&mut self) {
        for b in &mut self.bones {
            if !b.track.keys.is_empty() {
                let (rotation, translation) = b.track.sample_parts(0.0);
                b.track.keys = vec![crate::animation::TransformKey {
                    time: 0.0,
                    translation,
                    rotation,
                }];
            }
        }
        if let Some(skeleton) = &mut self.skeleton {
            for m in &mut skeleton.motion {
                m.curve = Curve::constant(m.curve.sample(0.0));
            }
        }
        for m in &mut self.muscles {
            if let Some(c) = &mut m.activation {
                *c = Curve::constant(c.sample(0.0));
            }
        }
    }

    /// Switches every muscle off: activation 0, no activation curve and no
    /// sensor drive (sensors still read the bones; nothing listens). The
    /// scene with no muscle active, e.g. to judge a skin at rest where
    /// nothing bulges.
    pub fn relax_muscles(&mut self) {
        for m in &mut self.muscles {
            m.params.activation = 0.0;
            m.activation = None;
            m.drive.clear();
        }
    }

    /// Loads every bone and muscle mesh (paths relative to `base_dir`).
    pub fn load_meshes(
        &self,
        base_dir: &Path,
    ) -> Result<(Vec<Option<SurfaceMesh>>, Vec<SurfaceMesh>), SceneError> {
        let bones = self
            .bones
            .iter()
            .map(|b| {
                b.shape
                    .as_ref()
                    .map(|s| bone_mesh(&b.name, s, base_dir))
                    .transpose()
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok((bones, self.load_muscle_meshes(base_dir)?))
    }

    /// Loads every muscle mesh (paths relative to `base_dir`).
    fn load_muscle_meshes(&self, base_dir: &Path) -> Result<Vec<SurfaceMesh>, SceneError> {
        (self.muscles.iter())
            .map(|m| muscle_mesh(&m.name, &m.mesh, base_dir))
            .collect()
    }

    /// Builds a [`Solver`] from the scene; mesh paths are relative to `base_dir`.
    pub fn instantiate(&self, base_dir: &Path) -> Result<Solver, SceneError> {
        self.validate()?;
        let muscle_meshes = self.load_muscle_meshes(base_dir)?;
        let mut solver = Solver::new(self.settings.clone())?;
        if let Some(skeleton) = &self.skeleton {
            solver.set_skeleton(skeleton.compile()?);
        }
        // The first bone of each shape, by the shape's text (exact: floats
        // print to the bit), so a crowd of any size finds them in one pass.
        let mut first_of_shape = std::collections::HashMap::new();
        for b in &self.bones {
            // A bone of an earlier bone's shape (its copy in a crowd) shares
            // that bone's geometry; any other is loaded, and dropped once
            // its target is built.
            let shape = b.shape.as_ref().map(|s| format!("{s:?}"));
            let like = shape.as_ref().and_then(|s| first_of_shape.get(s).copied());
            let index = match like {
                Some(j) => solver.add_bone_like(b.name.clone(), b.track.clone(), j),
                None => {
                    let mesh = (b.shape.as_ref())
                        .map(|s| bone_mesh(&b.name, s, base_dir))
                        .transpose()?;
                    solver.add_bone(b.name.clone(), b.track.clone(), mesh.as_ref())
                }
            };
            if let Some(shape) = shape {
                first_of_shape.entry(shape).or_insert(index);
            }
            if let Some(body) = &b.body {
                let found = solver.skeleton().and_then(|r| r.body_index(body));
                let body = found.ok_or_else(|| SceneError::UnknownReference {
                    context: format!("bone '{}'", b.name),
                    kind: "skeleton body",
                    name: body.clone(),
                })?;
                solver.bind_bone(index, body)?;
            }
        }
        let bone_index = |context: String, name: &str| {
            solver.bone_index(name).ok_or(SceneError::UnknownReference {
                context,
                kind: "bone",
                name: name.to_string(),
            })
        };
        // Muscles first without muscle targets, so muscles can target each other.
        let mut deferred = Vec::new();
        let mut descs = Vec::new();
        for (mi, (m, mesh)) in self.muscles.iter().zip(muscle_meshes).enumerate() {
            let mut attachments = Vec::new();
            for (i, a) in m.attachments.iter().enumerate() {
                let bone = a
                    .bone
                    .as_deref()
                    .map(|b| bone_index(format!("muscle '{}' attachment {i}", m.name), b))
                    .transpose()?;
                attachments.push(AttachmentDesc {
                    bone,
                    vertex: a.vertex,
                    point: a.point,
                    radius: a.radius,
                });
            }
            let mut targets = Vec::new();
            for (i, t) in m.targets.iter().enumerate() {
                if let Some(b) = solver.bone_index(t) {
                    targets.push(TargetRef::Bone(b));
                } else if let Some(o) = self.muscles.iter().position(|o| &o.name == t) {
                    deferred.push((mi, o));
                } else {
                    return Err(SceneError::UnknownReference {
                        context: format!("muscle '{}' target {i}", m.name),
                        kind: "target",
                        name: t.clone(),
                    });
                }
            }
            let binding = m
                .binding
                .as_ref()
                .map(|spec| {
                    spec.resolve(&m.name, |k, b| {
                        bone_index(format!("muscle '{}' binding bone {k}", m.name), b)
                    })
                })
                .transpose()?;
            descs.push(MuscleDesc {
                name: m.name.clone(),
                mesh,
                roots: m.roots.clone(),
                attachments,
                targets,
                params: m.params.clone(),
                maps: m.maps.clone(),
                binding,
            });
        }
        for (mi, desc) in descs.into_iter().enumerate() {
            let index = solver.add_muscle(desc)?;
            solver.set_activation_curve(index, self.muscles[mi].activation.clone());
        }
        for (m, o) in deferred {
            solver.add_target(m, TargetRef::Muscle(o))?;
        }
        if !self.sensors.is_empty() || self.muscles.iter().any(|m| !m.drive.is_empty()) {
            let mut rig = ActivationRig::new(&self.sensors, &|n| solver.bone_index(n))?;
            for (mi, m) in self.muscles.iter().enumerate() {
                if !m.drive.is_empty() {
                    rig.add_stack(mi, &m.name, &m.drive)?;
                }
            }
            solver.set_activation_rig(rig);
        }
        solver.prepare();
        Ok(solver)
    }
}

#[cfg(test)]
mod tests;
