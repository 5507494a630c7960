//! Small skinned characters built in code, for tests and examples.

use super::{Joint, JointClip, MAX_INFLUENCES, SkinnedCharacter};
use crate::mesh::primitives::{fan_triangles, oriented_outward, tube};
use glam::Vec3;
use std::f32::consts::TAU;

/// A straight arm hanging along −Y from a shoulder at the origin: joints
/// `shoulder` (root), `upper_arm` (at the shoulder), `forearm` (at the
/// elbow, `segment` below) and `hand` (`2 × segment` below); a capped tube of
/// `radius` (m) skinned to the upper arm and forearm, blended linearly over
/// `radius` on either side of the elbow. Its clip `elbow_flex` flexes the
/// elbow forward (towards +Z) by `flex_angle` (rad) and back over 2 s.
pub fn two_bone_arm(segment: f32, radius: f32, flex_angle: f32) -> SkinnedCharacter {
    const SIDES: usize = 12;
    const RINGS: usize = 16;
    let length = 2.0 * segment;
    let mut positions = Vec::new();
    let mut influences = Vec::new();
    let weigh = |y: f32| {
        // 1 on the upper arm, 0 on the forearm, linear across the elbow.
        let depth = -y;
        ((segment + radius - depth) / (2.0 * radius)).clamp(0.0, 1.0)
    };
    let slots = |upper: f32| {
        let mut s = [(0u16, 0.0f32); MAX_INFLUENCES];
        s[0] = (1, upper);
        s[1] = (2, 1.0 - upper);
        s
    };
    for ring in 0..=RINGS {
        let y = -length * ring as f32 / RINGS as f32;
        for side in 0..SIDES {
            let a = TAU * side as f32 / SIDES as f32;
            positions.push(Vec3::new(radius * a.cos(), y, radius * a.sin()));
            influences.push(slots(weigh(y)));
        }
    }
    let top = positions.len() as u32;
    positions.push(Vec3::ZERO);
    influences.push(slots(1.0));
    let bottom = positions.len() as u32;
    positions.push(Vec3::new(0.0, -length, 0.0));
    influences.push(slots(0.0));
    let rings: Vec<Vec<u32>> = (0..=RINGS)
        .map(|ring| {
            (0..SIDES)
                .map(|side| (ring * SIDES + side) as u32)
                .collect()
        })
        .collect();
    let surface = tube(&rings, Some(top), Some(bottom));
    let triangles = fan_triangles(&oriented_outward(&positions, surface));
    let joint = |name: &str, parent: Option<usize>, y: f32| Joint {
        name: name.into(),
        parent,
        origin: Vec3::new(0.0, y, 0.0),
    };
    let mut arm = SkinnedCharacter {
        name: "arm".into(),
        positions,
        triangles,
        joints: vec![
            joint("shoulder", None, 0.0),
            joint("upper_arm", Some(0), 0.0),
            joint("forearm", Some(1), -segment),
            joint("hand", Some(2), -length),
        ],
        influences,
        clips: Vec::new(),
    };
    if let Ok(clip) = JointClip::elbow_flexion(
        &arm,
        "elbow_flex",
        &[("upper_arm", "forearm", "hand")],
        flex_angle,
        2.0,
    ) {
        arm.clips.push(clip);
    }
    arm
}
