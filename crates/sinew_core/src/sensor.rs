//! Sensors, triggers and activation layers (SPEC §8): muscle activation from
//! the skeleton's motion alone.
//!
//! A **sensor** reads bone frames every frame: the distance between two points,
//! the angle at a middle point of three (a joint angle), or one point's linear
//! motion. Each gives a value and its velocity and acceleration (backward
//! differences). A **trigger** remaps one of those outputs to `[0, 1]`
//! (input range → ramp → output range), gates it with a hysteresis threshold
//! and follows it with separate attack and release times. **Layers** combine
//! triggers, constants and curves into a muscle's activation in order (over,
//! add, sub, mult, div, clamp); the result is clamped to `[0, 1]`.

use crate::animation::Curve;
use crate::error::SceneError;
use glam::{Affine3A, Vec3};
use serde::{Deserialize, Serialize};

/// A point fixed in a bone's frame.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BonePoint {
    /// Bone name.
    pub bone: String,
    /// Position in the bone's frame. Units: m.
    pub point: Vec3,
}

/// What a sensor measures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum SensorKind {
    /// Distance between two points. Units: m.
    Distance {
        /// First point.
        a: BonePoint,
        /// Second point.
        b: BonePoint,
    },
    /// Angle at `middle` between the directions to `a` and `c`, in `[0, π]`
    /// (π when straight). Units: rad.
    Rotation {
        /// First end (e.g. the shoulder).
        a: BonePoint,
        /// The joint (e.g. the elbow).
        middle: BonePoint,
        /// Second end (e.g. the wrist).
        c: BonePoint,
    },
    /// One point's motion: value = distance from where it started, velocity
    /// and acceleration = magnitudes. Units: m, m/s, m/s².
    Linear {
        /// The point.
        point: BonePoint,
    },
}

/// A named sensor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SensorSpec {
    /// Unique name.
    pub name: String,
    /// What it measures.
    pub kind: SensorKind,
}

/// Which output of a sensor a trigger reads.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum SensorOutput {
    /// The measured value.
    #[default]
    Value,
    /// Its rate of change (signed for distance and rotation).
    Velocity,
    /// The rate of change of the velocity.
    Acceleration,
}

/// Maps a raw sensor output to `[output.0, output.1]`: normalise with `input`
/// (reversed ranges invert), shape with `ramp`, scale to `output`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Remap {
    /// Raw value giving 0 and raw value giving 1.
    pub input: (f32, f32),
    /// Shape on `[0, 1]`; `None` is the identity.
    pub ramp: Option<Curve>,
    /// Output range. Default `(0, 1)`.
    pub output: (f32, f32),
}

impl Default for Remap {
    fn default() -> Self {
        Self {
            input: (0.0, 1.0),
            ramp: None,
            output: (0.0, 1.0),
        }
    }
}

impl Remap {
    /// The remapped value.
    pub fn apply(&self, x: f32) -> f32 {
        let (lo, hi) = self.input;
        let t = if hi != lo {
            ((x - lo) / (hi - lo)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let shaped = self.ramp.as_ref().map_or(t, |c| c.sample(t));
        self.output.0 + (self.output.1 - self.output.0) * shaped
    }
}

/// Filters a remapped sensor value into an activation (SPEC §8.3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TriggerSpec {
    /// The gate opens at or above this value.
    pub threshold_on: f32,
    /// The gate closes at or below this value (≤ `threshold_on`).
    pub threshold_off: f32,
    /// Time constant while the activation rises. Units: s.
    pub attack: f32,
    /// Time constant while it falls. Units: s.
    pub release: f32,
    /// Gain applied above the threshold.
    pub gain: f32,
    /// Activation/relaxation shape on `[0, 1]`; `None` is the identity.
    pub curve: Option<Curve>,
}

impl Default for TriggerSpec {
    fn default() -> Self {
        Self {
            threshold_on: 0.0,
            threshold_off: 0.0,
            attack: 0.05,
            release: 0.15,
            gain: 1.0,
            curve: None,
        }
    }
}

/// One sensor output through a remap and a trigger.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SensorInput {
    /// Sensor name.
    pub sensor: String,
    /// Which output.
    pub output: SensorOutput,
    /// Raw → `[0, 1]`.
    pub remap: Remap,
    /// Filter.
    pub trigger: TriggerSpec,
}

/// What a layer reads.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum LayerInput {
    /// A triggered sensor output.
    Sensor(SensorInput),
    /// A constant.
    Constant(f32),
    /// A curve of time (s).
    Curve(Curve),
}

/// One step of a muscle's activation stack, applied in order to the running
/// value (which starts at 0).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ActivationLayer {
    /// Replace.
    Over(LayerInput),
    /// Add.
    Add(LayerInput),
    /// Subtract.
    Sub(LayerInput),
    /// Multiply.
    Mult(LayerInput),
    /// Divide (a zero divisor leaves the value unchanged).
    Div(LayerInput),
    /// Clamp to `[min, max]`.
    Clamp {
        /// Lower bound.
        min: f32,
        /// Upper bound.
        max: f32,
    },
}

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

/// A sensor's state between frames.
#[derive(Clone, Debug)]
struct SensorState {
    kind: CompiledKind,
    samples: u32,
    start: Vec3,
    last_point: Vec3,
    last_velocity_vector: Vec3,
    value: f32,
    velocity: f32,
    acceleration: f32,
}

impl SensorState {
    fn output(&self, which: SensorOutput) -> f32 {
        match which {
            SensorOutput::Value => self.value,
            SensorOutput::Velocity => self.velocity,
            SensorOutput::Acceleration => self.acceleration,
        }
    }

    fn update(&mut self, bones: &[Affine3A], dt: f32) {
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

#[derive(Clone, Debug)]
struct TriggerState {
    sensor: usize,
    input: SensorInput,
    gate: bool,
    activation: f32,
}

impl TriggerState {
    fn update(&mut self, sensors: &[SensorState], dt: f32) -> f32 {
        let spec = &self.input.trigger;
        let y = self
            .input
            .remap
            .apply(sensors[self.sensor].output(self.input.output));
        if y >= spec.threshold_on {
            self.gate = true;
        } else if y <= spec.threshold_off {
            self.gate = false;
        }
        let span = (1.0 - spec.threshold_off).max(1e-6);
        let target = if self.gate {
            (spec.gain * (y - spec.threshold_off) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let tau = if target > self.activation {
            spec.attack
        } else {
            spec.release
        };
        let k = if tau > 0.0 {
            1.0 - (-dt / tau).exp()
        } else {
            1.0
        };
        self.activation += k * (target - self.activation);
        spec.curve
            .as_ref()
            .map_or(self.activation, |c| c.sample(self.activation))
    }
}

#[derive(Clone, Debug)]
enum CompiledInput {
    Trigger(TriggerState),
    Constant(f32),
    Curve(Curve),
}

#[derive(Clone, Debug)]
enum CompiledLayer {
    Op(fn(f32, f32) -> f32, CompiledInput),
    Clamp(f32, f32),
}

/// Sensors plus the activation stacks of the muscles they drive, compiled to
/// bone and sensor indices. [`crate::Solver`] updates it once per frame.
#[derive(Clone, Debug, Default)]
pub struct ActivationRig {
    sensors: Vec<SensorState>,
    sensor_names: Vec<String>,
    /// `(muscle index, layers)`.
    stacks: Vec<(usize, Vec<CompiledLayer>)>,
}

impl ActivationRig {
    /// Compiles sensors against bone names (`bone_index`) and checks every layer.
    pub fn new(
        sensors: &[SensorSpec],
        bone_index: &dyn Fn(&str) -> Option<usize>,
    ) -> Result<Self, SceneError> {
        let mut states = Vec::with_capacity(sensors.len());
        let mut names: Vec<String> = Vec::with_capacity(sensors.len());
        for (i, s) in sensors.iter().enumerate() {
            if names.contains(&s.name) {
                return Err(SceneError::DuplicateName(s.name.clone()));
            }
            let point = |p: &BonePoint| -> Result<CompiledPoint, SceneError> {
                if !p.point.is_finite() {
                    return Err(SceneError::Invalid {
                        context: format!("sensor {i} '{}'", s.name),
                        reason: "non-finite point".into(),
                    });
                }
                Ok(CompiledPoint {
                    bone: bone_index(&p.bone).ok_or_else(|| SceneError::UnknownReference {
                        context: format!("sensor {i} '{}'", s.name),
                        kind: "bone",
                        name: p.bone.clone(),
                    })?,
                    point: p.point,
                })
            };
            let kind = match &s.kind {
                SensorKind::Distance { a, b } => CompiledKind::Distance(point(a)?, point(b)?),
                SensorKind::Rotation { a, middle, c } => {
                    CompiledKind::Rotation(point(a)?, point(middle)?, point(c)?)
                }
                SensorKind::Linear { point: p } => CompiledKind::Linear(point(p)?),
            };
            names.push(s.name.clone());
            states.push(SensorState {
                kind,
                samples: 0,
                start: Vec3::ZERO,
                last_point: Vec3::ZERO,
                last_velocity_vector: Vec3::ZERO,
                value: 0.0,
                velocity: 0.0,
                acceleration: 0.0,
            });
        }
        Ok(Self {
            sensors: states,
            sensor_names: names,
            stacks: Vec::new(),
        })
    }

    /// Adds the activation stack of muscle `muscle` (named `name` in errors).
    pub fn add_stack(
        &mut self,
        muscle: usize,
        name: &str,
        layers: &[ActivationLayer],
    ) -> Result<(), SceneError> {
        let mut compiled = Vec::with_capacity(layers.len());
        for (li, layer) in layers.iter().enumerate() {
            let context = || format!("muscle '{name}' activation layer {li}");
            let invalid = |reason: String| SceneError::Invalid {
                context: context(),
                reason,
            };
            let input = |input: &LayerInput| -> Result<CompiledInput, SceneError> {
                Ok(match input {
                    LayerInput::Constant(c) if c.is_finite() => CompiledInput::Constant(*c),
                    LayerInput::Constant(c) => return Err(invalid(format!("constant {c}"))),
                    LayerInput::Curve(c) => CompiledInput::Curve(c.clone()),
                    LayerInput::Sensor(s) => {
                        let sensor = self
                            .sensor_names
                            .iter()
                            .position(|n| n == &s.sensor)
                            .ok_or_else(|| SceneError::UnknownReference {
                                context: context(),
                                kind: "sensor",
                                name: s.sensor.clone(),
                            })?;
                        let t = &s.trigger;
                        let finite = [t.threshold_on, t.threshold_off, t.attack, t.release, t.gain]
                            .iter()
                            .chain([s.remap.input.0, s.remap.input.1].iter())
                            .chain([s.remap.output.0, s.remap.output.1].iter())
                            .all(|v| v.is_finite());
                        if !finite {
                            return Err(invalid("non-finite trigger or remap parameter".into()));
                        }
                        if t.threshold_off > t.threshold_on {
                            return Err(invalid(format!(
                                "threshold_off {} > threshold_on {}",
                                t.threshold_off, t.threshold_on
                            )));
                        }
                        if t.attack < 0.0 || t.release < 0.0 {
                            return Err(invalid("attack and release must be ≥ 0".into()));
                        }
                        CompiledInput::Trigger(TriggerState {
                            sensor,
                            input: s.clone(),
                            gate: false,
                            activation: 0.0,
                        })
                    }
                })
            };
            compiled.push(match layer {
                ActivationLayer::Over(i) => CompiledLayer::Op(|_, b| b, input(i)?),
                ActivationLayer::Add(i) => CompiledLayer::Op(|a, b| a + b, input(i)?),
                ActivationLayer::Sub(i) => CompiledLayer::Op(|a, b| a - b, input(i)?),
                ActivationLayer::Mult(i) => CompiledLayer::Op(|a, b| a * b, input(i)?),
                ActivationLayer::Div(i) => {
                    CompiledLayer::Op(|a, b| if b != 0.0 { a / b } else { a }, input(i)?)
                }
                ActivationLayer::Clamp { min, max } => {
                    if min.is_nan() || max.is_nan() || min > max {
                        return Err(invalid(format!("clamp [{min}, {max}] is empty")));
                    }
                    CompiledLayer::Clamp(*min, *max)
                }
            });
        }
        self.stacks.push((muscle, compiled));
        Ok(())
    }

    /// Whether any muscle is driven.
    pub fn is_empty(&self) -> bool {
        self.stacks.is_empty()
    }

    /// Reads the sensors from the bones' world transforms at the end of a
    /// frame of length `dt` (s) ending at `time`, and writes each driven
    /// muscle's activation through `set(muscle, activation)`.
    pub fn update(
        &mut self,
        bones: &[Affine3A],
        time: f32,
        dt: f32,
        mut set: impl FnMut(usize, f32),
    ) {
        let dt = dt.max(1e-9);
        for s in &mut self.sensors {
            s.update(bones, dt);
        }
        for (muscle, layers) in &mut self.stacks {
            let mut a = 0.0f32;
            for layer in layers.iter_mut() {
                a = match layer {
                    CompiledLayer::Clamp(lo, hi) => a.clamp(*lo, *hi),
                    CompiledLayer::Op(op, input) => {
                        let b = match input {
                            CompiledInput::Constant(c) => *c,
                            CompiledInput::Curve(c) => c.sample(time),
                            CompiledInput::Trigger(t) => t.update(&self.sensors, dt),
                        };
                        op(a, b)
                    }
                };
            }
            set(
                *muscle,
                if a.is_finite() {
                    a.clamp(0.0, 1.0)
                } else {
                    0.0
                },
            );
        }
    }

    /// Current value, velocity and acceleration of each sensor, by name.
    pub fn readings(&self) -> impl Iterator<Item = (&str, [f32; 3])> + '_ {
        self.sensor_names
            .iter()
            .zip(&self.sensors)
            .map(|(n, s)| (n.as_str(), [s.value, s.velocity, s.acceleration]))
    }
}

#[cfg(test)]
mod tests;
