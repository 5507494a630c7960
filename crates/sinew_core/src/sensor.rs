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

mod stack;
mod tracker;

pub use stack::ActivationStack;
pub use tracker::SensorTracker;

use crate::animation::Curve;
use crate::error::SceneError;
use glam::{Affine3A, Vec3};
use serde::{Deserialize, Serialize};

/// A point fixed in a bone's frame.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BonePoint {
    /// Bone name.
    pub bone: String,
    /// Position in the bone's frame. Units: m.
    pub point: Vec3,
}

/// What a sensor measures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
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
#[serde(deny_unknown_fields)]
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
#[serde(deny_unknown_fields, default)]
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
#[serde(deny_unknown_fields, default)]
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
#[serde(deny_unknown_fields, default)]
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
#[serde(deny_unknown_fields)]
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

/// An [`ActivationRig`] taken apart ([`ActivationRig::into_parts`]).
#[derive(Clone, Debug)]
pub struct RigParts {
    /// Each sensor with its name, in scene order (the stacks' sensor
    /// indices).
    pub sensors: Vec<(String, SensorTracker)>,
    /// `(muscle index, stack)` of every driven muscle.
    pub stacks: Vec<(usize, ActivationStack)>,
}

/// Sensors plus the activation stacks of the muscles they drive, compiled to
/// bone and sensor indices. [`crate::Solver`] updates it once per frame:
/// every sensor ([`SensorTracker`]), then every stack
/// ([`ActivationStack`]) in order.
#[derive(Clone, Debug, Default)]
pub struct ActivationRig {
    sensors: Vec<SensorTracker>,
    sensor_names: Vec<String>,
    /// `(muscle index, stack)`.
    stacks: Vec<(usize, ActivationStack)>,
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
            states.push(SensorTracker::new(s, i, bone_index)?);
            names.push(s.name.clone());
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
        let names = &self.sensor_names;
        let stack = ActivationStack::new(name, layers, &|n| names.iter().position(|s| s == n))?;
        self.stacks.push((muscle, stack));
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
        for s in &mut self.sensors {
            s.update(bones, dt);
        }
        let sensors = &self.sensors;
        for (muscle, stack) in &mut self.stacks {
            set(
                *muscle,
                stack.evaluate(time, dt, |i, output| Some(sensors[i].output(output))),
            );
        }
    }

    /// Current value, velocity and acceleration of each sensor, by name.
    pub fn readings(&self) -> impl Iterator<Item = (&str, [f32; 3])> + '_ {
        self.sensor_names
            .iter()
            .zip(&self.sensors)
            .map(|(n, s)| (n.as_str(), s.reading()))
    }

    /// The named sensors and the stacks, for a driver that keeps them
    /// apart (the Bevy plug-in's sensor entities).
    pub fn into_parts(self) -> RigParts {
        RigParts {
            sensors: self.sensor_names.into_iter().zip(self.sensors).collect(),
            stacks: self.stacks,
        }
    }
}

#[cfg(test)]
mod tests;
