//! Skinned characters: a skin mesh bound to a joint hierarchy by
//! linear-blend-skinning weights, with joint animation clips — what a glTF
//! skinned model holds. [`makehuman`] builds one from the MakeHuman base mesh
//! and its game-engine rig; [`glb`] writes one as a binary glTF that Bevy,
//! Blender and other DCCs read, and reads a skinned `.glb` back
//! ([`glb::read`]).
//!
//! Conventions (glTF's): metres, +Y up, the character faces +Z. Joints are
//! axis-aligned at the bind pose (a joint's frame is a translation of the
//! world frame to its origin), so a clip's rotations are rotations about
//! world axes at the bind pose.

mod clip;
mod error;
pub mod fit;
mod gait;
pub mod glb;
mod glb_read;
pub mod makehuman;
pub mod primitives;
mod skeleton;

pub use clip::{JointClip, RotationChannel};
pub use error::CharacterError;
pub use gait::WalkCycle;
pub use skeleton::ClipPlayback;

use glam::{Affine3A, Quat, Vec3};

/// Most joints influencing one skin vertex (glTF's `JOINTS_0`/`WEIGHTS_0`).
pub const MAX_INFLUENCES: usize = 4;

/// A joint of the skeleton.
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    /// Name (unique in the character), e.g. `upperarm_r`.
    pub name: String,
    /// Parent joint (an index before this one), `None` for a root.
    pub parent: Option<usize>,
    /// Origin at the bind pose, world frame (m).
    pub origin: Vec3,
}

/// A skin mesh bound to a skeleton, with its animation clips.
#[derive(Clone, Debug, PartialEq)]
pub struct SkinnedCharacter {
    /// Name of the character (the glTF scene's root node).
    pub name: String,
    /// Skin vertex positions at the bind pose (m).
    pub positions: Vec<Vec3>,
    /// Skin triangles, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// Joints, parents before children.
    pub joints: Vec<Joint>,
    /// Per skin vertex: up to [`MAX_INFLUENCES`] joints and their weights
    /// (summing to 1; unused slots have weight 0).
    pub influences: Vec<[(u16, f32); MAX_INFLUENCES]>,
    /// Animation clips on the joints.
    pub clips: Vec<JointClip>,
}

impl SkinnedCharacter {
    /// The joint called `name`.
    pub fn joint(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }

    /// The joint called `name`, or an error naming it and what needs it
    /// (`needed_by`, e.g. "the walk cycle").
    pub fn require_joint(&self, name: &str, needed_by: &str) -> Result<usize, CharacterError> {
        self.joint(name).ok_or_else(|| CharacterError::Invalid {
            character: self.name.clone(),
            element: format!("joint {name}"),
            reason: format!("no such joint (needed by {needed_by})"),
        })
    }

    /// A joint's translation relative to its parent at the bind pose (m).
    pub fn local_translation(&self, joint: usize) -> Vec3 {
        let j = &self.joints[joint];
        j.parent
            .map_or(j.origin, |p| j.origin - self.joints[p].origin)
    }

    /// World transforms of every joint for local rotations `rotations` (one
    /// per joint, identity at the bind pose).
    pub fn pose(&self, rotations: &[Quat]) -> Vec<Affine3A> {
        let mut world: Vec<Affine3A> = Vec::with_capacity(self.joints.len());
        for (k, joint) in self.joints.iter().enumerate() {
            let local =
                Affine3A::from_rotation_translation(rotations[k], self.local_translation(k));
            world.push(joint.parent.map_or(local, |p| world[p] * local));
        }
        world
    }

    /// Skin positions for joint world transforms `pose` (linear-blend
    /// skinning: each vertex moves with its joints' transforms from the bind
    /// pose, weighted).
    pub fn skin(&self, pose: &[Affine3A]) -> Vec<Vec3> {
        self.positions
            .iter()
            .zip(&self.influences)
            .map(|(&p, influences)| {
                influences
                    .iter()
                    .filter(|(_, w)| *w > 0.0)
                    .map(|&(j, w)| {
                        let joint = j as usize;
                        let from_bind = p - self.joints[joint].origin;
                        w * pose[joint].transform_point3(from_bind)
                    })
                    .sum()
            })
            .collect()
    }

    /// Checks what a glTF reader relies on: finite positions, triangle and
    /// joint indices in range, parents before children, unique joint names,
    /// weights non-negative and summing to 1, clips on existing joints.
    pub fn validate(&self) -> Result<(), CharacterError> {
        let invalid = |element: String, reason: String| CharacterError::Invalid {
            character: self.name.clone(),
            element,
            reason,
        };
        if let Some(v) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(invalid(format!("vertex {v}"), "non-finite position".into()));
        }
        let n = self.positions.len() as u32;
        if let Some(t) = self
            .triangles
            .iter()
            .position(|t| t.iter().any(|&i| i >= n))
        {
            return Err(invalid(
                format!("triangle {t}"),
                format!("a corner past the {n} vertices"),
            ));
        }
        if self.joints.len() > u16::MAX as usize {
            return Err(invalid("joints".into(), "more than 65 535".into()));
        }
        for (k, joint) in self.joints.iter().enumerate() {
            if joint.parent.is_some_and(|p| p >= k) {
                return Err(invalid(
                    format!("joint {}", joint.name),
                    "its parent comes after it".into(),
                ));
            }
            if !joint.origin.is_finite() {
                return Err(invalid(
                    format!("joint {}", joint.name),
                    "non-finite origin".into(),
                ));
            }
            if self.joints[..k].iter().any(|j| j.name == joint.name) {
                return Err(invalid(
                    format!("joint {}", joint.name),
                    "name used twice".into(),
                ));
            }
        }
        if self.influences.len() != self.positions.len() {
            return Err(invalid(
                "influences".into(),
                format!(
                    "{} for {} vertices",
                    self.influences.len(),
                    self.positions.len()
                ),
            ));
        }
        for (v, influences) in self.influences.iter().enumerate() {
            let sum: f32 = influences.iter().map(|(_, w)| w).sum();
            let bad_joint = influences
                .iter()
                .any(|&(j, w)| w > 0.0 && j as usize >= self.joints.len());
            if bad_joint
                || influences.iter().any(|(_, w)| !w.is_finite() || *w < 0.0)
                || (sum - 1.0).abs() > 1e-4
            {
                return Err(invalid(
                    format!("vertex {v}"),
                    format!("weights {influences:?} (joints in range, ≥ 0, summing to 1)"),
                ));
            }
        }
        for clip in &self.clips {
            clip.validate(self)?;
        }
        Ok(())
    }
}
