//! Sensors as entities (SPEC §8): a [`Sensor`] reads its bones every step
//! and shows its [`SensorReading`]; a muscle's [`ActivationDrive`] turns
//! the readings of the sensors it is related to into its activation.
//!
//! A muscle reads a sensor through an input entity: [`SensorInputOf`] the
//! muscle ([`SensorInputs`] on it) and [`ReadsSensor`] the sensor
//! ([`SensorReaders`] on it), with its [`SensorSlot`] in the muscle's
//! stack. So the muscles a sensor drives are its readers' muscles, and
//! re-targeting an input (another [`ReadsSensor`]) makes the muscle follow
//! another sensor. Despawning a sensor despawns its inputs (the layers
//! that read it then do nothing); despawning a muscle despawns its inputs.

use crate::components::{BonePose, Muscle};
use bevy::prelude::*;
use sinew_core::glam::Affine3A;
use sinew_core::sensor::{ActivationStack, SensorTracker};

/// A sensor: what it measures, compiled to its own list of bones.
#[derive(Component, Clone, Debug)]
#[require(SensorReading)]
pub struct Sensor {
    /// Name (as in the scene).
    pub name: String,
    /// The compiled sensor and its state; its bone index `i` reads
    /// `bones[i]`.
    pub tracker: SensorTracker,
    /// The bone entities it reads.
    pub bones: Vec<Entity>,
}

/// A sensor's last reading. Maintained by the plug-in.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct SensorReading {
    /// The measured value (m or rad).
    pub value: f32,
    /// Its rate of change (per s).
    pub velocity: f32,
    /// The rate of change of the velocity (per s²).
    pub acceleration: f32,
}

/// On a sensor input entity: the muscle it feeds.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, Reflect)]
#[reflect(Component)]
#[relationship(relationship_target = SensorInputs)]
pub struct SensorInputOf(pub Entity);

/// On a muscle: its sensor inputs. Despawning the muscle despawns them.
#[derive(Component, Clone, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Component)]
#[relationship_target(relationship = SensorInputOf, linked_spawn)]
pub struct SensorInputs(Vec<Entity>);

/// On a sensor input entity: the sensor it reads.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, Reflect)]
#[reflect(Component)]
#[relationship(relationship_target = SensorReaders)]
pub struct ReadsSensor(pub Entity);

/// On a sensor: the inputs that read it (their [`SensorInputOf`] are the
/// muscles it drives). Despawning the sensor despawns them.
#[derive(Component, Clone, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Component)]
#[relationship_target(relationship = ReadsSensor, linked_spawn)]
pub struct SensorReaders(Vec<Entity>);

/// On a sensor input entity: which sensor of its muscle's
/// [`ActivationDrive`] it is.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, Reflect)]
#[reflect(Component)]
pub struct SensorSlot(pub usize);

/// On a muscle: its activation layers, reading its sensor inputs by
/// [`SensorSlot`]. Sets [`Muscle::activation`] every step when the muscle
/// is [`Muscle::driven`].
#[derive(Component, Clone, Debug)]
pub struct ActivationDrive(pub ActivationStack);

/// Every sensor reads its bones at the step's end, then every muscle's
/// drive turns the readings into its activation (the core's
/// `ActivationRig::update`, entity by entity).
pub(crate) fn drive_activation(
    ctx: Res<crate::systems::StepContext>,
    mut sensors: Query<(&mut Sensor, &mut SensorReading)>,
    bones: Query<&BonePose>,
    mut muscles: Query<(&mut Muscle, &mut ActivationDrive, Option<&SensorInputs>)>,
    inputs: Query<(&ReadsSensor, &SensorSlot)>,
    mut poses: Local<Vec<Affine3A>>,
) {
    let dt = ctx.settings.step_time();
    for (mut sensor, mut reading) in &mut sensors {
        let sensor = &mut *sensor;
        poses.clear();
        poses.extend(
            sensor
                .bones
                .iter()
                .map(|&b| bones.get(b).map_or(Affine3A::IDENTITY, |pose| pose.current)),
        );
        sensor.tracker.update(&poses, dt);
        let [value, velocity, acceleration] = sensor.tracker.reading();
        reading.set_if_neq(SensorReading {
            value,
            velocity,
            acceleration,
        });
    }
    let sensors = sensors.as_readonly();
    for (mut muscle, mut drive, links) in &mut muscles {
        let output = |slot: usize, which| {
            links
                .into_iter()
                .flat_map(|l| l.iter())
                .filter_map(|l| inputs.get(l).ok())
                .find(|(_, s)| s.0 == slot)
                .and_then(|(reads, _)| sensors.get(reads.0).ok())
                .map(|(sensor, _)| sensor.tracker.output(which))
        };
        let a = drive.0.evaluate(ctx.end_time, dt, output);
        if muscle.driven {
            muscle.activation = a;
        }
    }
}
