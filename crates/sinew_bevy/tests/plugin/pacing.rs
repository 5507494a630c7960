//! Real-time pacing: the simulation follows Bevy's `Time` with a fixed-step
//! accumulator. At a 144 Hz or a 30 Hz update rate one simulated second
//! takes one second of `Time` and gives the bits of 60 Hz stepping (and of
//! the plain driver); an app that falls behind runs at most the capped
//! steps and reports the time it dropped.

use crate::common;

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use sinew_bevy::prelude::*;
use sinew_core::scene::Scene;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

/// P2 with its ground moving and its muscle contracting: a scene whose
/// inputs move every step.
fn scene() -> Scene {
    let mut scene = common::p2_with_moving_ground();
    scene.muscles[0].params.activation = 0.4;
    scene
}

/// An app at `hz` updates per second of `Time`, real-time pacing.
fn app_at(hz: f64, pacing: SimulationPacing) -> (App, Entity) {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        bevy::transform::TransformPlugin,
        SinewPlugin::default().pacing(pacing),
    ))
    .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
        1.0 / hz,
    )));
    let built = SinewScene::build(scene(), Path::new(".")).unwrap();
    let root = app
        .world_mut()
        .spawn(SinewSceneRoot::Built(Arc::new(built)))
        .id();
    (app, root)
}

/// Every muscle's particle positions, as bits.
fn bits(app: &App, root: Entity) -> Vec<[u32; 3]> {
    let muscles = common::scene_muscles(app, root);
    muscles
        .iter()
        .flat_map(|&m| {
            let state = app.world().get::<MuscleState>(m).unwrap();
            state
                .muscle
                .x
                .iter()
                .map(|p| p.to_array().map(f32::to_bits))
                .collect::<Vec<_>>()
        })
        .collect()
}

#[test]
fn one_simulated_second_takes_one_second_of_time_at_any_update_rate() {
    let mut plain = scene().instantiate(Path::new(".")).unwrap();
    for _ in 0..60 {
        plain.step();
    }
    let reference: Vec<[u32; 3]> = plain
        .muscles()
        .iter()
        .flat_map(|m| m.x.iter().map(|p| p.to_array().map(f32::to_bits)))
        .collect();
    for hz in [60.0, 144.0, 30.0] {
        let (mut app, root) = app_at(hz, SimulationPacing::default());
        let mut updates = 0;
        while app.world().resource::<SinewClock>().frame < 60 {
            app.update();
            updates += 1;
            assert!(updates < 1000, "{hz} Hz: the simulation does not advance");
        }
        let clock = *app.world().resource::<SinewClock>();
        let elapsed = app.world().resource::<Time<Virtual>>().elapsed_secs_f64();
        println!(
            "{hz} Hz: 60 steps in {updates} updates, {elapsed:.4} s of Time, {:.4} s simulated",
            clock.time
        );
        // The first update has no elapsed time yet: 1 s is hz updates after it.
        assert_eq!(updates, hz as usize + 1, "{hz} Hz");
        assert!((elapsed - 1.0).abs() < 1e-6, "{hz} Hz: {elapsed} s of Time");
        assert_eq!(clock.frame, 60, "{hz} Hz ran past the second");
        assert_eq!(clock.dropped, Duration::ZERO);
        assert!(
            bits(&app, root) == reference,
            "{hz} Hz: the muscles differ from 60 Hz stepping"
        );
    }
}

#[test]
fn lockstep_advances_time_by_one_step_per_update_however_slow_the_updates() {
    // The app's own clock says 0.2 s per update (a slow machine); in
    // lockstep the plug-in makes it one step's time, so a clip played on
    // `Time` and the muscles stay in step: 60 updates, 60 steps, 1 s of
    // `Time` and 1 s simulated, nothing dropped.
    let lockstep = SimulationPacing {
        mode: PacingMode::Lockstep,
        ..default()
    };
    let (mut app, _) = app_at(5.0, lockstep);
    app.update(); // the plug-in takes the clock from the next update on
    let start = app.world().resource::<Time<Virtual>>().elapsed_secs_f64();
    for _ in 0..60 {
        app.update();
    }
    let clock = *app.world().resource::<SinewClock>();
    let elapsed = app.world().resource::<Time<Virtual>>().elapsed_secs_f64() - start;
    assert_eq!(clock.frame, 61);
    assert!((elapsed - 1.0).abs() < 1e-5, "{elapsed} s of Time");
    assert_eq!(clock.dropped, Duration::ZERO);
    // Back to real time: the app's clock is its own again.
    app.world_mut().resource_mut::<SimulationPacing>().mode = PacingMode::RealTime;
    app.update();
    assert!(matches!(
        *app.world().resource::<TimeUpdateStrategy>(),
        TimeUpdateStrategy::ManualDuration(d) if d == Duration::from_millis(200)
    ));
}

#[test]
fn an_app_that_falls_behind_runs_the_capped_steps_and_drops_the_rest() {
    // Two updates of 0.2 s each: 12 steps owed per update, 4 run. (Bevy's
    // `Time<Virtual>` itself clamps an update to `max_delta`, 0.25 s.)
    let pacing = SimulationPacing {
        max_steps_per_update: 4,
        ..default()
    };
    let (mut app, _) = app_at(5.0, pacing);
    app.update(); // no time has passed yet
    app.update();
    app.update();
    let clock = *app.world().resource::<SinewClock>();
    assert_eq!(clock.frame, 8);
    assert_eq!(clock.steps_last_update, 4);
    let dropped_steps = clock.dropped.as_secs_f64() * 60.0;
    assert!((dropped_steps - 16.0).abs() < 1e-3, "{dropped_steps}");
}

#[test]
fn a_bone_moved_by_the_app_is_interpolated_between_updates() {
    // At 30 Hz each update runs two steps; a bone the app moves at a
    // constant speed is, in the first, halfway between its poses.
    let (mut app, _) = app_at(30.0, SimulationPacing::default());
    let bone = app
        .world_mut()
        .spawn((SinewBone::new("mover"), Transform::default()))
        .id();
    for i in 0..4 {
        app.world_mut()
            .get_mut::<Transform>(bone)
            .unwrap()
            .translation
            .x = i as f32 * 0.1;
        app.update();
    }
    let pose = *app.world().get::<BonePose>(bone).unwrap();
    assert_eq!(app.world().resource::<SinewClock>().steps_last_update, 2);
    // The last step ends at x = 0.3, the one before it at 0.25.
    assert!((pose.current.translation.x - 0.3).abs() < 1e-6);
    assert!(
        (pose.previous.translation.x - 0.25).abs() < 1e-6,
        "{:?}",
        pose.previous
    );
}
