//! Joint animation clips: keyed local rotations, linearly interpolated
//! (spherically for quaternions), as glTF's `LINEAR` rotation samplers.

use super::{CharacterError, SkinnedCharacter};
use glam::{Quat, Vec3};

/// Keyed local rotations of one joint.
#[derive(Clone, Debug, PartialEq)]
pub struct RotationChannel {
    /// The joint it turns.
    pub joint: usize,
    /// Key times (s), strictly increasing.
    pub times: Vec<f32>,
    /// The joint's local rotation at each key (identity: the bind pose).
    pub rotations: Vec<Quat>,
}

impl RotationChannel {
    /// The rotation at time `t` (s), held before the first and after the
    /// last key.
    pub fn sample(&self, t: f32) -> Quat {
        let k = self.times.partition_point(|&key| key <= t);
        if k == 0 {
            return self.rotations[0];
        }
        if k == self.times.len() {
            return self.rotations[k - 1];
        }
        let (t0, t1) = (self.times[k - 1], self.times[k]);
        self.rotations[k - 1].slerp(self.rotations[k], (t - t0) / (t1 - t0))
    }
}

/// A named animation of a character's joints.
#[derive(Clone, Debug, PartialEq)]
pub struct JointClip {
    /// Name (the glTF animation's).
    pub name: String,
    /// One channel per animated joint.
    pub channels: Vec<RotationChannel>,
}

impl JointClip {
    /// An elbow flexion and extension of every arm in `arms` (each
    /// `(upper arm, forearm, hand)` joint names): the forearm turns about
    /// the elbow's hinge axis (normal to the plane of upper arm and forearm
    /// at the bind pose) from the bind pose to `angle` (rad) and back,
    /// `1 − cos` eased, over `period` (s), keyed every `period / 16`.
    pub fn elbow_flexion(
        character: &SkinnedCharacter,
        name: &str,
        arms: &[(&str, &str, &str)],
        angle: f32,
        period: f32,
    ) -> Result<Self, CharacterError> {
        const KEYS: usize = 16;
        let joint = |name: &str| character.require_joint(name, "clip elbow flexion");
        let mut channels = Vec::with_capacity(arms.len());
        for &(upper, fore, hand) in arms {
            let (upper, fore, hand) = (joint(upper)?, joint(fore)?, joint(hand)?);
            let origin = |j: usize| character.joints[j].origin;
            let upper_arm = origin(fore) - origin(upper);
            let forearm = origin(hand) - origin(fore);
            // Turning the forearm about forearm × (−upper arm) brings the hand
            // towards the shoulder; a straight arm flexes forward (+Z).
            let axis = forearm
                .cross(-upper_arm)
                .try_normalize()
                .unwrap_or_else(|| upper_arm.cross(Vec3::Z).normalize_or(Vec3::X));
            let times: Vec<f32> = (0..=KEYS)
                .map(|k| period * k as f32 / KEYS as f32)
                .collect();
            let rotations = times
                .iter()
                .map(|&t| {
                    let eased = 0.5 * (1.0 - (std::f32::consts::TAU * t / period).cos());
                    Quat::from_axis_angle(axis, angle * eased)
                })
                .collect();
            channels.push(RotationChannel {
                joint: fore,
                times,
                rotations,
            });
        }
        Ok(Self {
            name: name.to_string(),
            channels,
        })
    }

    /// Length of the clip (s): its last key.
    pub fn duration(&self) -> f32 {
        self.channels
            .iter()
            .filter_map(|c| c.times.last().copied())
            .fold(0.0, f32::max)
    }

    /// Every joint's local rotation at time `t` (s): the keyed joints from
    /// their channels, the others at the bind pose.
    pub fn rotations_at(&self, joints: usize, t: f32) -> Vec<Quat> {
        let mut rotations = vec![Quat::IDENTITY; joints];
        for channel in &self.channels {
            rotations[channel.joint] = channel.sample(t);
        }
        rotations
    }

    pub(super) fn validate(&self, character: &SkinnedCharacter) -> Result<(), CharacterError> {
        for channel in &self.channels {
            let invalid = |reason: String| CharacterError::Invalid {
                character: character.name.clone(),
                element: format!("clip {} channel on joint {}", self.name, channel.joint),
                reason,
            };
            if channel.joint >= character.joints.len() {
                return Err(invalid("no such joint".into()));
            }
            if channel.times.is_empty() || channel.times.len() != channel.rotations.len() {
                return Err(invalid(format!(
                    "{} times for {} rotations",
                    channel.times.len(),
                    channel.rotations.len()
                )));
            }
            if !channel.times.windows(2).all(|w| w[0] < w[1])
                || !channel.times.iter().all(|t| t.is_finite() && *t >= 0.0)
            {
                return Err(invalid(
                    "key times must be finite, ≥ 0 and increasing".into(),
                ));
            }
            if !channel
                .rotations
                .iter()
                .all(|q| q.is_finite() && q.is_normalized())
            {
                return Err(invalid("rotations must be finite unit quaternions".into()));
            }
        }
        Ok(())
    }
}
