//! [`ActivationStack`]: one muscle's activation layers, compiled, with the
//! state of their triggers.

use super::{ActivationLayer, LayerInput, SensorInput, SensorOutput};
use crate::animation::Curve;
use crate::error::SceneError;

#[derive(Clone, Debug)]
struct TriggerState {
    sensor: usize,
    input: SensorInput,
    gate: bool,
    activation: f32,
}

impl TriggerState {
    fn update(&mut self, raw: f32, dt: f32) -> f32 {
        let spec = &self.input.trigger;
        let y = self.input.remap.apply(raw);
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

/// One muscle's activation layers (SPEC §8.3), compiled against sensor
/// indices, with the state of their triggers: applied in order to a
/// running value that starts at 0, the result clamped to `[0, 1]`.
#[derive(Clone, Debug)]
pub struct ActivationStack {
    layers: Vec<CompiledLayer>,
}

impl ActivationStack {
    /// Compiles `layers` of muscle `name` (in errors); `sensor_index`
    /// finds a sensor by name.
    pub fn new(
        name: &str,
        layers: &[ActivationLayer],
        sensor_index: &dyn Fn(&str) -> Option<usize>,
    ) -> Result<Self, SceneError> {
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
                    LayerInput::Curve(c) => {
                        c.validate(f32::MIN..=f32::MAX)
                            .map_err(|r| invalid(format!("curve: {r}")))?;
                        CompiledInput::Curve(c.clone())
                    }
                    LayerInput::Sensor(s) => {
                        let sensor = sensor_index(&s.sensor).ok_or_else(|| {
                            SceneError::UnknownReference {
                                context: context(),
                                kind: "sensor",
                                name: s.sensor.clone(),
                            }
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
                        if let Some(ramp) = &s.remap.ramp {
                            ramp.validate(f32::MIN..=f32::MAX)
                                .map_err(|r| invalid(format!("remap ramp: {r}")))?;
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
        Ok(Self { layers: compiled })
    }

    /// Renumbers the sensors the stack reads to `0..k`, in the order of
    /// their first use, and returns the old index of each: for a driver
    /// that gives each muscle its own list of sensors.
    pub fn localize_sensors(&mut self) -> Vec<usize> {
        let mut used: Vec<usize> = Vec::new();
        for layer in &mut self.layers {
            if let CompiledLayer::Op(_, CompiledInput::Trigger(t)) = layer {
                t.sensor = match used.iter().position(|&s| s == t.sensor) {
                    Some(slot) => slot,
                    None => {
                        used.push(t.sensor);
                        used.len() - 1
                    }
                };
            }
        }
        used
    }

    /// The trigger of layer `layer`, if it reads a sensor (tests tune it).
    #[cfg(test)]
    pub(super) fn trigger_mut(&mut self, layer: usize) -> Option<&mut super::TriggerSpec> {
        match self.layers.get_mut(layer) {
            Some(CompiledLayer::Op(_, CompiledInput::Trigger(t))) => Some(&mut t.input.trigger),
            _ => None,
        }
    }

    /// The activation at the end of a frame `dt` seconds long (at least
    /// 1 ns) ending at `time` (s), its triggers reading `output(sensor,
    /// which)`; in `[0, 1]` (0 when not finite). A layer whose sensor is
    /// missing (`None`) leaves the running value as it is.
    pub fn evaluate(
        &mut self,
        time: f32,
        dt: f32,
        output: impl Fn(usize, SensorOutput) -> Option<f32>,
    ) -> f32 {
        let dt = dt.max(1e-9);
        let mut a = 0.0f32;
        for layer in &mut self.layers {
            a = match layer {
                CompiledLayer::Clamp(lo, hi) => a.clamp(*lo, *hi),
                CompiledLayer::Op(op, input) => {
                    let b = match input {
                        CompiledInput::Constant(c) => *c,
                        CompiledInput::Curve(c) => c.sample(time),
                        CompiledInput::Trigger(t) => match output(t.sensor, t.input.output) {
                            Some(raw) => t.update(raw, dt),
                            None => continue,
                        },
                    };
                    op(a, b)
                }
            };
        }
        if a.is_finite() {
            a.clamp(0.0, 1.0)
        } else {
            0.0
        }
    }
}
