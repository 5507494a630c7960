//! A walk cycle for game-engine (Unreal-style) rigs, from the sagittal
//! joint angles of a normal human gait: hip, knee and ankle flexion, the
//! pelvis turning with the swinging leg and the chest against it, the arms
//! hanging from an A-pose bind and swinging against the legs, elbows
//! flexing as the arm comes forward. It walks on the spot (the clips carry
//! rotations only).

use super::{CharacterError, JointClip, RotationChannel, SkinnedCharacter};
use glam::{Quat, Vec3};
use std::f32::consts::TAU;

/// The legs' angle out from vertical (hip to ankle) while walking. Units: rad.
const LEG_SPREAD: f32 = 0.03;

/// The shape of [`JointClip::walk`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WalkCycle {
    /// One stride (two steps). Units: s. Default: 1.1.
    pub period: f32,
    /// Scales every swing angle (hips, knees, ankles, arms, pelvis). Default: 1.
    pub amplitude: f32,
    /// The arms' angle out from hanging straight down. Units: rad. Default: 0.12.
    pub arm_spread: f32,
    /// Keys per stride (the first and last are the same pose). Default: 32.
    pub keys: usize,
}

impl Default for WalkCycle {
    fn default() -> Self {
        Self {
            period: 1.1,
            amplitude: 1.0,
            arm_spread: 0.12,
            keys: 32,
        }
    }
}

/// Joint angles of a walk at phase `s` ∈ [0, 1) of the left leg's stride
/// (0: left heel strike). Degrees; flexion positive.
struct GaitAngles {
    hip: f32,
    knee: f32,
    /// Dorsiflexion (toes up) positive.
    ankle: f32,
}

fn gait(s: f32) -> GaitAngles {
    // Periodic bump of height 1 at `centre`, width `width` (phase units).
    let bump = |centre: f32, width: f32| {
        let d = (s - centre + 0.5).rem_euclid(1.0) - 0.5;
        (-0.5 * (d / width).powi(2)).exp()
    };
    // Ankle: slight plantar flexion after heel strike, dorsiflexion in
    // stance, push-off, neutral in swing.
    let ankle_keys = [
        (0.0, 0.0),
        (0.08, -6.0),
        (0.45, 10.0),
        (0.62, -18.0),
        (0.75, 0.0),
        (1.0, 0.0),
    ];
    let ankle = ankle_keys
        .windows(2)
        .find(|w| s >= w[0].0 && s <= w[1].0)
        .map_or(0.0, |w| {
            let f = (s - w[0].0) / (w[1].0 - w[0].0);
            w[0].1 + f * (w[1].1 - w[0].1)
        });
    GaitAngles {
        hip: 10.0 + 18.0 * (TAU * (s - 0.92)).cos(),
        knee: 5.0 + 12.0 * bump(0.15, 0.06) + 55.0 * bump(0.72, 0.09),
        ankle,
    }
}

impl JointClip {
    /// A walk cycle named `name` for a game-engine (Unreal-style) rig:
    /// channels on `pelvis`, `spine_01`, `spine_03`, `thigh_*`, `calf_*`,
    /// `foot_*`, `upperarm_*` and `lowerarm_*` (`*`: `l`, `r`), one stride
    /// over `cycle.period`, the last key the first's pose (it loops). The
    /// arms hang from the bind pose (turned from the bind's upper-arm
    /// direction to `cycle.arm_spread` from straight down) and swing, the
    /// legs stand nearly straight under the hips (a bind's stance is often
    /// wide); the elbows bend about their bind-pose hinge axis from their
    /// bind-pose bend to 15–30°. Errors name a missing
    /// joint.
    pub fn walk(
        character: &SkinnedCharacter,
        name: &str,
        cycle: &WalkCycle,
    ) -> Result<Self, CharacterError> {
        let joint = |name: &str| character.require_joint(name, "the walk cycle");
        let origin = |j: usize| character.joints[j].origin;
        let keys = cycle.keys.max(2);
        let times: Vec<f32> = (0..=keys)
            .map(|k| cycle.period * k as f32 / keys as f32)
            .collect();
        let phases: Vec<f32> = (0..=keys)
            .map(|k| (k % keys) as f32 / keys as f32)
            .collect();
        let degrees = |d: f32| (cycle.amplitude * d).to_radians();
        // Flexion turns a limb forward (+Z): about −X for a limb hanging down.
        let flex = |d: f32| Quat::from_rotation_x(-degrees(d));
        let mut channels = Vec::new();
        let mut push = |joint: usize, rotation: &dyn Fn(f32) -> Quat| {
            channels.push(RotationChannel {
                joint,
                times: times.clone(),
                rotations: phases.iter().map(|&s| rotation(s)).collect(),
            });
        };
        // The pelvis turns forward on the side of the swinging leg; the
        // chest turns against it.
        let pelvis_turn = |s: f32| Quat::from_rotation_y(degrees(4.0) * (TAU * s).sin());
        push(joint("pelvis")?, &pelvis_turn);
        push(joint("spine_01")?, &|s| pelvis_turn(s).inverse());
        push(joint("spine_03")?, &|s| {
            Quat::from_rotation_y(-degrees(3.0) * (TAU * s).sin())
        });
        for (side, sign, offset) in [("l", 1.0f32, 0.0f32), ("r", -1.0, 0.5)] {
            let phase = move |s: f32| (s + offset).rem_euclid(1.0);
            // The legs stand from the bind's stance to `LEG_SPREAD` out of
            // vertical (hip to ankle), then swing.
            let (thigh, foot) = (
                joint(&format!("thigh_{side}"))?,
                joint(&format!("foot_{side}"))?,
            );
            let standing = Vec3::new(sign * LEG_SPREAD.sin(), -LEG_SPREAD.cos(), 0.0);
            let leg = (origin(foot) - origin(thigh)).normalize_or(Vec3::NEG_Y);
            let stand = Quat::from_rotation_arc(leg, standing);
            push(thigh, &|s| flex(gait(phase(s)).hip) * stand);
            push(joint(&format!("calf_{side}"))?, &|s| {
                flex(-gait(phase(s)).knee)
            });
            push(foot, &|s| {
                Quat::from_rotation_x(degrees(-gait(phase(s)).ankle))
            });
            let (upper, fore, hand) = (
                joint(&format!("upperarm_{side}"))?,
                joint(&format!("lowerarm_{side}"))?,
                joint(&format!("hand_{side}"))?,
            );
            let upper_arm = origin(fore) - origin(upper);
            let hanging = Vec3::new(sign * cycle.arm_spread.sin(), -cycle.arm_spread.cos(), 0.0);
            let down = Quat::from_rotation_arc(upper_arm.normalize_or(Vec3::NEG_Y), hanging);
            // The arm swings against its side's leg: forward as the leg goes back.
            let swing = move |s: f32| -0.6 * (gait(phase(s)).hip - 10.0);
            push(upper, &|s| flex(swing(s)) * down);
            let forearm = origin(hand) - origin(fore);
            let hinge = forearm
                .cross(-upper_arm)
                .try_normalize()
                .unwrap_or_else(|| upper_arm.cross(Vec3::Z).normalize_or(Vec3::X));
            // The elbow from its bind-pose bend to 15° (more as the arm
            // comes forward).
            let bind_bend = upper_arm.angle_between(forearm);
            push(fore, &|s| {
                let bend = (15.0 + 0.8 * cycle.amplitude * swing(s).max(0.0)).to_radians();
                Quat::from_axis_angle(hinge, bend - bind_bend)
            });
        }
        Ok(Self {
            name: name.to_string(),
            channels,
        })
    }
}
