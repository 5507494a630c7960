//! The main example: the 17-muscle arm (scene T5, from myo-sim) flexing its
//! elbow, with an orbit camera (drag: orbit, scroll: zoom) and the tuning
//! panel open.
//!
//! `cargo run --release --example arm`
//!
//! Set `SINEW_SCREENSHOT=out.png` to save a screenshot at simulation frame
//! `SINEW_SCREENSHOT_FRAME` (default 90) and exit (the panel's
//! `SinewScreenshotPlugin`): CI does this under Xvfb.

use bevy::input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll};
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
        .add_systems(Update, (frame_the_muscles, orbit_camera))
        .run();
}

/// Orbit camera state: angles around the focus point and distance.
#[derive(Component)]
struct Orbit {
    focus: Vec3,
    yaw: f32,
    pitch: f32,
    distance: f32,
}

impl Orbit {
    fn transform(&self) -> Transform {
        let rotation = Quat::from_euler(EulerRot::YXZ, self.yaw, self.pitch, 0.0);
        Transform::from_translation(self.focus + rotation * Vec3::Z * self.distance)
            .looking_at(self.focus, Vec3::Y)
    }
}

fn setup(mut commands: Commands, assets: Res<AssetServer>) {
    commands.spawn(SinewSceneRoot::Asset(assets.load("scenes/t5.ron")));
    // Aimed at the muscles once they are built (`frame_the_muscles`).
    let orbit = Orbit {
        focus: Vec3::ZERO,
        yaw: -2.2,
        pitch: -0.1,
        distance: 1.0,
    };
    commands.spawn((Camera3d::default(), orbit.transform(), orbit));
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
    mut cameras: Query<&mut Orbit>,
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
        orbit.focus = (lo + hi) * 0.5;
        // The default 45° vertical field of view sees 0.83 × the distance;
        // leave a margin around the box's diagonal.
        orbit.distance = (hi - lo).length() * 1.25;
    }
    *framed = true;
}

fn orbit_camera(
    buttons: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    mut egui: sinew::bevy::ui::bevy_egui::EguiContexts,
    mut cameras: Query<(&mut Orbit, &mut Transform)>,
) {
    // The panel gets the mouse when the pointer is over it.
    if egui.ctx_mut().is_ok_and(|c| c.egui_wants_pointer_input()) {
        return;
    }
    for (mut orbit, mut transform) in &mut cameras {
        if buttons.pressed(MouseButton::Left) {
            orbit.yaw -= motion.delta.x * 0.005;
            orbit.pitch = (orbit.pitch - motion.delta.y * 0.005).clamp(-1.5, 1.5);
        }
        orbit.distance = (orbit.distance * (1.0 - scroll.delta.y * 0.1)).clamp(0.1, 5.0);
        *transform = orbit.transform();
    }
}
