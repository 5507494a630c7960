//! Copies of a scene's body side by side in one scene: a crowd, to measure
//! what many characters cost in one solver (`sinew bench --instances N`).
//!
//! Copy `k` (from 0) is the scene moved by `k × spacing` and started
//! `k × delay` later, so that the copies are in different phases of their
//! animation: every bone track, joint motion and activation curve of the
//! copy is delayed (it holds its first pose meanwhile, as it was built in).
//! Copy 0 keeps the scene's names; copy `k ≥ 1` renames every bone,
//! skeleton body, joint, muscle and sensor `name#k` and every reference to
//! them, so that each copy attaches to, slides on and senses only itself.

use super::{AttachmentSpec, BoneSpec, MeshSource, MuscleSpec, Scene};
use crate::animation::{Curve, TransformKey, TransformTrack};
use crate::error::SceneError;
use crate::sensor::{ActivationLayer, BonePoint, LayerInput, SensorKind, SensorSpec};
use crate::skeleton::Skeleton;
use glam::Vec3;

/// Most copies [`Scene::crowd`] makes.
pub const MAX_CROWD: u32 = 1024;

/// How copy `k ≥ 1` differs from the scene.
struct Placement {
    /// Name suffix, `#k`.
    suffix: String,
    /// Where it stands relative to the scene. Units: scene units.
    offset: Vec3,
    /// How much later it starts. Units: s.
    delay: f32,
}

impl Placement {
    fn name(&self, name: &str) -> String {
        format!("{name}{}", self.suffix)
    }

    fn curve(&self, curve: &Curve) -> Curve {
        let mut c = curve.clone();
        for key in &mut c.keys {
            key.0 += self.delay;
        }
        c
    }

    fn track(&self, track: &TransformTrack) -> TransformTrack {
        let mut t = track.clone();
        if t.keys.is_empty() {
            // A static bone: placed with the copy.
            t.keys.push(TransformKey {
                time: 0.0,
                translation: self.offset,
                rotation: glam::Quat::IDENTITY,
            });
        } else {
            for key in &mut t.keys {
                key.time += self.delay;
                key.translation += self.offset;
            }
        }
        t
    }

    fn bone(&self, bone: &BoneSpec) -> BoneSpec {
        BoneSpec {
            name: self.name(&bone.name),
            shape: bone.shape.clone(),
            // A bone on a skeleton body moves with the copy's root body.
            track: if bone.body.is_some() {
                bone.track.clone()
            } else {
                self.track(&bone.track)
            },
            body: bone.body.as_deref().map(|b| self.name(b)),
        }
    }

    fn point(&self, p: &BonePoint) -> BonePoint {
        BonePoint {
            bone: self.name(&p.bone),
            point: p.point,
        }
    }

    fn sensor(&self, sensor: &SensorSpec) -> SensorSpec {
        let kind = match &sensor.kind {
            SensorKind::Distance { a, b } => SensorKind::Distance {
                a: self.point(a),
                b: self.point(b),
            },
            SensorKind::Rotation { a, middle, c } => SensorKind::Rotation {
                a: self.point(a),
                middle: self.point(middle),
                c: self.point(c),
            },
            SensorKind::Linear { point } => SensorKind::Linear {
                point: self.point(point),
            },
        };
        SensorSpec {
            name: self.name(&sensor.name),
            kind,
        }
    }

    fn layer_input(&self, input: &LayerInput) -> LayerInput {
        match input {
            LayerInput::Sensor(s) => {
                let mut s = s.clone();
                s.sensor = self.name(&s.sensor);
                LayerInput::Sensor(s)
            }
            LayerInput::Constant(v) => LayerInput::Constant(*v),
            LayerInput::Curve(c) => LayerInput::Curve(self.curve(c)),
        }
    }

    fn layer(&self, layer: &ActivationLayer) -> ActivationLayer {
        match layer {
            ActivationLayer::Over(i) => ActivationLayer::Over(self.layer_input(i)),
            ActivationLayer::Add(i) => ActivationLayer::Add(self.layer_input(i)),
            ActivationLayer::Sub(i) => ActivationLayer::Sub(self.layer_input(i)),
            ActivationLayer::Mult(i) => ActivationLayer::Mult(self.layer_input(i)),
            ActivationLayer::Div(i) => ActivationLayer::Div(self.layer_input(i)),
            ActivationLayer::Clamp { min, max } => ActivationLayer::Clamp {
                min: *min,
                max: *max,
            },
        }
    }

    fn muscle(&self, muscle: &MuscleSpec) -> MuscleSpec {
        let mut m = muscle.clone();
        m.name = self.name(&m.name);
        match &mut m.mesh {
            MeshSource::File { translation, .. } => *translation += self.offset,
            MeshSource::Generator(g) => *g = g.translated(self.offset),
        }
        m.attachments = m
            .attachments
            .iter()
            .map(|a| AttachmentSpec {
                bone: a.bone.as_deref().map(|b| self.name(b)),
                vertex: a.vertex,
                point: a.point.map(|p| p + self.offset),
                radius: a.radius,
            })
            .collect();
        m.targets = m.targets.iter().map(|t| self.name(t)).collect();
        m.activation = m.activation.as_ref().map(|c| self.curve(c));
        m.drive = m.drive.iter().map(|l| self.layer(l)).collect();
        if let Some(binding) = &mut m.binding {
            binding.bones = binding.bones.iter().map(|b| self.name(b)).collect();
        }
        m
    }

    /// Appends this copy of `skeleton` to `into`.
    fn skeleton(&self, skeleton: &Skeleton, into: &mut Skeleton) {
        for body in &skeleton.bodies {
            let mut b = body.clone();
            b.name = self.name(&b.name);
            match &b.parent {
                Some(parent) => b.parent = Some(self.name(parent)),
                // A root stands in the world frame: it carries the copy.
                None => b.translation += self.offset,
            }
            for joint in &mut b.joints {
                joint.name = self.name(&joint.name);
            }
            into.bodies.push(b);
        }
        for motion in &skeleton.motion {
            let mut m = motion.clone();
            m.joint = self.name(&m.joint);
            m.curve = self.curve(&m.curve);
            into.motion.push(m);
        }
        for coupling in &skeleton.couplings {
            let mut c = coupling.clone();
            c.joint = self.name(&c.joint);
            c.driver = c.driver.as_deref().map(|d| self.name(d));
            into.couplings.push(c);
        }
    }
}

impl Scene {
    /// `copies` copies of the scene side by side in one scene: copy `k`
    /// (from 0) moved by `k × spacing` (scene units) and started `k × delay`
    /// seconds later — every bone track, joint motion and activation curve
    /// delayed, its first pose held meanwhile —, so that the copies are in
    /// different phases of their animation. Copy 0 keeps the scene's names;
    /// copy `k ≥ 1` renames every bone, skeleton body, joint, muscle and
    /// sensor `name#k` and every reference to them, so each copy attaches
    /// to, slides on and senses only itself. The frame count grows by the
    /// last copy's delay. Errors: `copies` outside `1..=`[`MAX_CROWD`], a
    /// spacing or delay that is not finite, a negative delay.
    pub fn crowd(&self, copies: u32, spacing: Vec3, delay: f32) -> Result<Scene, SceneError> {
        let invalid = |reason: String| SceneError::Invalid {
            context: format!("crowd of scene '{}'", self.name),
            reason,
        };
        if !(1..=MAX_CROWD).contains(&copies) {
            return Err(invalid(format!("{copies} copies (1 to {MAX_CROWD})")));
        }
        if !spacing.is_finite() {
            return Err(invalid(format!("spacing {spacing} is not finite")));
        }
        if !(delay.is_finite() && delay >= 0.0) {
            return Err(invalid(format!("delay {delay} s is not a finite time ≥ 0")));
        }
        // Copy 0 is the scene itself, unchanged.
        let mut crowd = Scene {
            name: format!("{} ×{copies}", self.name),
            description: format!(
                "{copies} copies of {}, {spacing} apart, each started {delay} s after the one before: {}",
                self.name, self.description
            ),
            frames: self.frames + (delay * (copies - 1) as f32 / self.settings.dt).ceil() as u32,
            ..self.clone()
        };
        for k in 1..copies {
            let copy = Placement {
                suffix: format!("#{k}"),
                offset: spacing * k as f32,
                delay: delay * k as f32,
            };
            crowd.bones.extend(self.bones.iter().map(|b| copy.bone(b)));
            crowd
                .muscles
                .extend(self.muscles.iter().map(|m| copy.muscle(m)));
            crowd
                .sensors
                .extend(self.sensors.iter().map(|s| copy.sensor(s)));
            if let (Some(s), Some(into)) = (&self.skeleton, &mut crowd.skeleton) {
                copy.skeleton(s, into);
            }
        }
        crowd.validate()?;
        Ok(crowd)
    }
}
