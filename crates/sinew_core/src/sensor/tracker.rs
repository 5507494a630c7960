//! [`SensorTracker`]: one sensor, compiled to bone indices, with its
//! value, velocity and acceleration between frames.

use super::{BonePoint, SensorKind, SensorOutput, SensorSpec};
use crate::error::SceneError;
use glam::{Affine3A, Vec3};

#[derive(Clone, Debug)]
struct CompiledPoint {
    bone: usize,
    point: Vec3,
}

impl CompiledPoint {
    fn world(&self, bones: &[Affine3A]) -> Vec3 {
        bones[self.bone].transform_point3(self.point)
    }
}

#[derive(Clone, Debug)]
enum CompiledKind {
    Distance(CompiledPoint, CompiledPoint),
    Rotation(CompiledPoint, CompiledPoint, CompiledPoint),
    Linear(CompiledPoint),
}

/// One sensor reading bone frames (SPEC §8.1): its points compiled to bone
/// indices, and its value, velocity and acceleration (backward
/// differences) between frames.
#[derive(Clone, Debug)]
pub struct SensorTracker {
    kind: CompiledKind,
    samples: u32,
    start: Vec3,
    last_point: Vec3,
    last_velocity_vector: Vec3,
    value: f32,
    velocity: f32,
    acceleration: f32,
}

impl SensorTracker {
    /// Compiles `spec` (sensor `index` of its scene, named in errors)
    /// against bone names.
    pub fn new(
        spec: &SensorSpec,
        index: usize,
        bone_index: &dyn Fn(&str) -> Option<usize>,
    ) -> Result<Self, SceneError> {
        let point = |p: &BonePoint| -> Result<CompiledPoint, SceneError> {
            if !p.point.is_finite() {
                return Err(SceneError::Invalid {
                    context: format!("sensor {index} '{}'", spec.name),
                    reason: "non-finite point".into(),
                });
            }
            Ok(CompiledPoint {
                bone: bone_index(&p.bone).ok_or_else(|| SceneError::UnknownReference {
                    context: format!("sensor {index} '{}'", spec.name),
                    kind: "bone",
                    name: p.bone.clone(),
                })?,
                point: p.point,
            })
        };
        let kind = match &spec.kind {
            SensorKind::Distance { a, b } => CompiledKind::Distance(point(a)?, point(b)?),
            SensorKind::Rotation { a, middle, c } => {
                CompiledKind::Rotation(point(a)?, point(middle)?, point(c)?)
            }
            SensorKind::Linear { point: p } => CompiledKind::Linear(point(p)?),
        };
        Ok(Self {
            kind,
            samples: 0,
            start: Vec3::ZERO,
            last_point: Vec3::ZERO,
            last_velocity_vector: Vec3::ZERO,
            value: 0.0,
            velocity: 0.0,
            acceleration: 0.0,
        })
    }

    /// Renumbers the bones its points read to `0..k`, in the order of
    /// their first use, and returns the old index of each: for a driver
    /// that gives each sensor its own list of bones (as
    /// [`super::ActivationStack::localize_sensors`] does for sensors).
    pub fn localize_bones(&mut self) -> Vec<usize> {
        let mut used: Vec<usize> = Vec::new();
        let mut localize = |p: &mut CompiledPoint| {
            p.bone = match used.iter().position(|&b| b == p.bone) {
                Some(slot) => slot,
                None => {
                    used.push(p.bone);
                    used.len() - 1
                }
            };
        };
        match &mut self.kind {
            CompiledKind::Distance(a, b) => [a, b].into_iter().for_each(&mut localize),
            CompiledKind::Rotation(a, m, c) => [a, m, c].into_iter().for_each(&mut localize),
            CompiledKind::Linear(p) => localize(p),
        }
        used
    }

    /// One output.
    pub fn output(&self, which: SensorOutput) -> f32 {
        match which {
            SensorOutput::Value => self.value,
            SensorOutput::Velocity => self.velocity,
            SensorOutput::Acceleration => self.acceleration,
        }
    }

    /// Value, velocity and acceleration.
    pub fn reading(&self) -> [f32; 3] {
        [self.value, self.velocity, self.acceleration]
    }

    /// Reads the bones' world frames (`bones`, by the compiled indices) at
    /// the end of a frame `dt` seconds long (at least 1 ns).
    pub fn update(&mut self, bones: &[Affine3A], dt: f32) {
        let dt = dt.max(1e-9);
        let n = self.samples;
        self.samples = n.saturating_add(1);
        match &self.kind {
            CompiledKind::Distance(a, b) => {
                let d = a.world(bones).distance(b.world(bones));
                self.scalar(d, n, dt);
            }
            CompiledKind::Rotation(a, m, c) => {
                let mid = m.world(bones);
                let (u, w) = (a.world(bones) - mid, c.world(bones) - mid);
                let theta = u.cross(w).length().atan2(u.dot(w));
                self.scalar(theta, n, dt);
            }
            CompiledKind::Linear(p) => {
                let x = p.world(bones);
                if n == 0 {
                    self.start = x;
                    self.last_point = x;
                }
                let v = if n == 0 {
                    Vec3::ZERO
                } else {
                    (x - self.last_point) / dt
                };
                let a = if n < 2 {
                    Vec3::ZERO
                } else {
                    (v - self.last_velocity_vector) / dt
                };
                self.value = x.distance(self.start);
                self.velocity = v.length();
                self.acceleration = a.length();
                self.last_point = x;
                self.last_velocity_vector = v;
            }
        }
    }

    fn scalar(&mut self, q: f32, n: u32, dt: f32) {
        let velocity = if n == 0 { 0.0 } else { (q - self.value) / dt };
        self.acceleration = if n < 2 {
            0.0
        } else {
            (velocity - self.velocity) / dt
        };
        self.velocity = velocity;
        self.value = q;
    }
}
