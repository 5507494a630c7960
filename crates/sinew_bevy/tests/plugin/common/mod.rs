//! What several of the plug-in's test files build: a scene whose inputs
//! move every step, and a hand-built oval on a bone.

#![allow(dead_code)] // each test module uses a part

use bevy::prelude::*;
use sinew_bevy::prelude::*;
use sinew_core::animation::TransformKey;
use sinew_core::glam::Vec3 as CoreVec3;
use sinew_core::mesh::primitives::thesis_oval;
use sinew_core::muscle::Roots;
use sinew_core::scene::{Scene, builtin};

/// A headless app with the plug-in stepping once per update.
pub fn app() -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        bevy::transform::TransformPlugin,
        SinewPlugin::default().every_update(),
    ));
    app
}

/// P2 with its ground plane keyframed: rising 2 cm and tilting 0.2 rad over
/// a second.
pub fn p2_with_moving_ground() -> Scene {
    let mut scene = builtin("P2").unwrap();
    let ground = scene.bones.iter_mut().find(|b| b.name == "ground").unwrap();
    ground.track.keys = vec![
        TransformKey {
            time: 0.0,
            translation: CoreVec3::ZERO,
            rotation: Quat::IDENTITY,
        },
        TransformKey {
            time: 1.0,
            translation: CoreVec3::new(0.0, 0.02, 0.0),
            rotation: Quat::from_rotation_z(0.2),
        },
    ];
    scene
}

/// P1's oval (6 × 2.5 × 2.5 cm at the origin), its vertex 0 held by `bone`.
pub fn oval_on(bone: Entity) -> MuscleBuilder {
    let mesh = thesis_oval(CoreVec3::ZERO).build("oval").unwrap();
    MuscleBuilder::new("oval", MuscleSource::Mesh(mesh))
        .roots(Roots::LongestAxisTips)
        .attach(MuscleAttachment::vertex(bone, 0))
}

/// How long a test waits for work on Bevy's task pools (muscle builds,
/// asset loads, reloads) before it fails. Units: s. Far longer than that
/// work takes (milliseconds to a second here), so that a machine loaded by
/// other test binaries does not fail what a quiet one passes; a wait ends
/// as soon as the work is done.
pub const WAIT_SECONDS: f32 = 60.0;

/// Updates `app` (2 ms of wall time apart) until `done` holds or `seconds`
/// of wall time pass; whether `done` held.
pub fn update_for(app: &mut App, seconds: f32, mut done: impl FnMut(&mut App) -> bool) -> bool {
    let start = std::time::Instant::now();
    loop {
        app.update();
        if done(app) {
            return true;
        }
        if start.elapsed().as_secs_f32() >= seconds {
            return false;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
}

/// Updates until `done` holds (builds run on the async pool); fails the
/// test after [`WAIT_SECONDS`].
pub fn update_until(app: &mut App, done: impl Fn(&App) -> bool) {
    assert!(
        update_for(app, WAIT_SECONDS, |app| done(app)),
        "timed out after {WAIT_SECONDS} s"
    );
}

/// The muscle entities a scene root spawned, in scene order.
pub fn scene_muscles(app: &App, root: Entity) -> Vec<Entity> {
    app.world()
        .get::<SpawnedScene>(root)
        .expect("a spawned scene")
        .muscles
        .clone()
}
