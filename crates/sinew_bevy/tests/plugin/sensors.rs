//! Sensors are entities: each reads its bones and shows its reading, is
//! related to the muscles it drives through input entities, can be
//! re-targeted, and can go away without harm.

use crate::common;

use bevy::prelude::*;
use sinew_bevy::prelude::*;
use std::path::Path;
use std::sync::Arc;

/// T3 (the biceps heads driven by an elbow sensor) spawned and stepped
/// `frames` times: the app, its sensors by name and its muscles.
fn t3(frames: usize) -> (App, Vec<(String, Entity)>, Vec<Entity>) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes/t3.ron");
    let mut app = common::app();
    let root = app
        .world_mut()
        .spawn(SinewSceneRoot::Built(Arc::new(
            SinewScene::load(&path).unwrap(),
        )))
        .id();
    for _ in 0..frames {
        app.update();
    }
    let mut sensors: Vec<(String, Entity)> = app
        .world_mut()
        .query::<(Entity, &Sensor)>()
        .iter(app.world())
        .map(|(e, s)| (s.name.clone(), e))
        .collect();
    sensors.sort();
    let muscles = common::scene_muscles(&app, root);
    (app, sensors, muscles)
}

/// The muscles a sensor drives: its readers' muscles.
fn driven_by(app: &App, sensor: Entity) -> Vec<Entity> {
    let world = app.world();
    world
        .get::<SensorReaders>(sensor)
        .map_or_else(Vec::new, |r| {
            r.iter()
                .map(|input| world.get::<SensorInputOf>(input).unwrap().0)
                .collect()
        })
}

fn activation(app: &App, muscle: Entity) -> f32 {
    app.world().get::<Muscle>(muscle).unwrap().activation
}

#[test]
fn sensors_are_entities_related_to_the_muscles_they_drive() {
    let (mut app, sensors, muscles) = t3(1);
    let names: Vec<&str> = sensors.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["elbow", "shoulder", "wrist"]);
    let (elbow, shoulder) = (sensors[0].1, sensors[1].1);
    let (mut driven, mut all) = (driven_by(&app, elbow), muscles.clone());
    driven.sort();
    all.sort();
    assert_eq!(driven, all, "the elbow drives both heads");

    assert!(driven_by(&app, shoulder).is_empty());
    // The elbow flexes 120° over 2 s: the reading falls from straight, and
    // the biceps activate.
    let straight = app.world().get::<SensorReading>(elbow).unwrap().value;
    for _ in 0..119 {
        app.update();
    }
    let flexed = app.world().get::<SensorReading>(elbow).unwrap().value;
    assert!(
        straight - flexed > 1.5,
        "elbow angle {straight} → {flexed} rad"
    );
    assert!(
        activation(&app, muscles[0]) > 0.5,
        "{}",
        activation(&app, muscles[0])
    );
}

#[test]
fn an_input_re_targeted_to_another_sensor_follows_it() {
    // A third of the way into the flexion, the elbow's remap gives the
    // heads a partial activation; the wrist's distance travelled, through
    // the same remap (made for an angle), saturates it.
    let (mut app, sensors, muscles) = t3(30);
    let wrist = sensors[2].1;
    let input = app.world().get::<SensorInputs>(muscles[0]).unwrap();
    let input = input.iter().next().unwrap();
    app.world_mut().entity_mut(input).insert(ReadsSensor(wrist));
    for _ in 0..15 {
        app.update();
    }
    assert_eq!(driven_by(&app, wrist), vec![muscles[0]]);
    let (a, b) = (activation(&app, muscles[0]), activation(&app, muscles[1]));
    assert!((a - b).abs() > 0.2, "the heads now differ: {a} vs {b}");
}

#[test]
fn a_despawned_sensor_leaves_its_layers_doing_nothing() {
    let (mut app, sensors, muscles) = t3(90);
    assert!(activation(&app, muscles[0]) > 0.2);
    app.world_mut().entity_mut(sensors[0].1).despawn();
    app.update();
    assert!(app.world().get::<SensorInputs>(muscles[0]).is_none());
    // Both of its layers read the elbow: the stack is now just its clamp.
    assert_eq!(activation(&app, muscles[0]), 0.0);
    let state = app.world().get::<MuscleState>(muscles[0]).unwrap();
    assert!(state.muscle.x.iter().all(|p| p.is_finite()));
}
