//! The main example: the 17-muscle arm (scene T5, from myo-sim) flexing its
//! elbow, with an orbit camera (drag: orbit, scroll: zoom) and the tuning
//! panel open.
//!
//! `cargo run --release --example arm`
//!
//! Set `SINEW_SCREENSHOT=out.png` to save a screenshot at simulation frame
//! `SINEW_SCREENSHOT_FRAME` (default 90) and exit (the panel's
//! `SinewScreenshotPlugin`): CI does this under Xvfb.

use bevy::prelude::*;
use sinew::bevy::prelude::*;

fn main() {
    App::new()
        .add_plugins(DefaultPlugins.set(WindowPlugin {
            primary_window: Some(Window {
                title: "sinew — arm".into(),
                resolution: (1280, 720).into(),
                ..default()
            }),
            ..default()
        }))
        .add_plugins((SinewPlugin::default(), SinewUiPlugin, SinewDebugPlugin))
        .insert_resource(ClearColor(Color::srgb(0.11, 0.12, 0.14)))
        .insert_resource(GlobalAmbientLight {
            brightness: 300.0,
            ..default()
        })
        .add_systems(Startup, setup)
        .add_systems(Update, frame_the_muscles)
        .run();
}

fn setup(mut commands: Commands, assets: Res<AssetServer>) {
    commands.spawn(SinewSceneRoot::Asset(assets.load("scenes/t5.ron")));
    // Aimed at the muscles once they are built (`frame_the_muscles`).
    let orbit = OrbitCamera {
        yaw: -2.2,
        pitch: -0.1,
        distance: 1.0,
        ..default()
    };
    commands.spawn((Camera3d::default(), orbit));
    commands.spawn((
        DirectionalLight {
            illuminance: 8000.0,
            ..default()
        },
        Transform::from_xyz(-1.0, 2.0, -1.5).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.spawn((
        DirectionalLight {
            illuminance: 2500.0,
            ..default()
        },
        Transform::from_xyz(1.0, 0.5, 1.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
}

/// Once the muscles are built, points the camera at their bounding box and
/// backs off until the whole of it is in view.
fn frame_the_muscles(
    muscles: Query<&MuscleState>,
    mut cameras: Query<&mut OrbitCamera>,
    mut framed: Local<bool>,
) {
    if *framed || muscles.is_empty() {
        return;
    }
    let (lo, hi) = muscles.iter().flat_map(|m| m.muscle.x.iter()).fold(
        (Vec3::MAX, Vec3::MIN),
        |(lo, hi), &p| {
            let p = Vec3::from(p.to_array());
            (lo.min(p), hi.max(p))
        },
    );
    for mut orbit in &mut cameras {
        orbit.frame(lo, hi);
    }
    *framed = true;
}
