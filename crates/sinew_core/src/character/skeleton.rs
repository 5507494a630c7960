//! A character's joints as a scene [`Skeleton`]: one body per joint, a ball
//! joint on every joint a clip turns, the clip as keyframed rotation
//! vectors — so a scene's bones can follow the character's joints and a
//! scene plays its clip like any other joint motion.

use super::{JointClip, SkinnedCharacter};
use crate::animation::{Curve, Interpolation};
use crate::skeleton::{BodySpec, JointKind, JointMotion, JointSpec, Skeleton};
use glam::{Quat, Vec3};

/// How [`SkinnedCharacter::skeleton`] plays a clip.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClipPlayback {
    /// Time from the bind pose to the clip's first pose (the joints turn
    /// there linearly). Units: s. Default: 1.
    pub lead_in: f32,
    /// Play the clip over and over until this time. Units: s. Default: 10.
    pub until: f32,
}

impl Default for ClipPlayback {
    fn default() -> Self {
        Self {
            lead_in: 1.0,
            until: 10.0,
        }
    }
}

impl SkinnedCharacter {
    /// The skeleton of the character: a body per joint (named as the
    /// joint, at its bind-pose offset from its parent, axis-aligned like
    /// the joints) and, with `clip`, a ball joint (named as the body) on
    /// every body the clip turns, keyed with the clip's rotations (as
    /// rotation vectors) from `playback.lead_in` on, looped until
    /// `playback.until`, from the bind pose at time 0. A body `b`'s world
    /// frame is then the joint's world transform of [`Self::pose`] for the
    /// clip's rotations at that time.
    pub fn skeleton(&self, clip: Option<&JointClip>, playback: &ClipPlayback) -> Skeleton {
        let turned: Vec<bool> = (0..self.joints.len())
            .map(|j| clip.is_some_and(|c| c.channels.iter().any(|ch| ch.joint == j)))
            .collect();
        let bodies = self
            .joints
            .iter()
            .enumerate()
            .map(|(j, joint)| BodySpec {
                name: joint.name.clone(),
                parent: joint.parent.map(|p| self.joints[p].name.clone()),
                translation: self.local_translation(j),
                rotation: Quat::IDENTITY,
                joints: if turned[j] {
                    vec![JointSpec {
                        name: joint.name.clone(),
                        kind: JointKind::Ball,
                        anchor: Vec3::ZERO,
                        axis: Vec3::Z,
                        range: None,
                    }]
                } else {
                    Vec::new()
                },
            })
            .collect();
        let mut motion = Vec::new();
        let duration = clip.map_or(0.0, JointClip::duration);
        for channel in clip.iter().flat_map(|c| c.channels.iter()) {
            let first = *channel.times.first().unwrap_or(&0.0);
            let mut keys: Vec<(f32, Vec3)> = vec![(0.0, Vec3::ZERO)];
            let mut start = playback.lead_in.max(0.0);
            'passes: loop {
                for (&t, &q) in channel.times.iter().zip(&channel.rotations) {
                    let time = start + t - first;
                    if time > playback.until {
                        break 'passes;
                    }
                    // Same time as the last key (a loop's end and the next
                    // pass's start): keep the first.
                    if keys.last().is_some_and(|&(last, _)| time <= last + 1e-6) {
                        continue;
                    }
                    keys.push((time, rotation_vector(q)));
                }
                if duration <= 0.0 {
                    break;
                }
                start += duration;
            }
            for component in 0..3 {
                motion.push(JointMotion {
                    joint: self.joints[channel.joint].name.clone(),
                    component: component as u8,
                    curve: Curve {
                        keys: keys.iter().map(|&(t, v)| (t, v[component])).collect(),
                        interpolation: Interpolation::Linear,
                    },
                });
            }
        }
        Skeleton {
            bodies,
            motion,
            couplings: Vec::new(),
        }
    }
}

/// The rotation vector (axis × angle, angle ≤ π) of `q`.
fn rotation_vector(q: Quat) -> Vec3 {
    let q = if q.w < 0.0 { -q } else { q };
    q.normalize().to_scaled_axis()
}
