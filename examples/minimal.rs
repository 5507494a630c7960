//! One muscle from an OBJ file hanging from a bone under gravity.
//!
//! Run with `cargo run --release --example minimal`.

use bevy::prelude::*;
use sinew::bevy::prelude::*;
use sinew::core::mesh::LoadOptions;
use sinew::core::muscle::Roots;

fn main() {
    App::new()
        .add_plugins(DefaultPlugins)
        .add_plugins(SinewPlugin::default().gravity(Vec3::new(0.0, -9.81, 0.0)))
        .add_plugins(SinewUiPlugin)
        .add_systems(Startup, setup)
        .run();
}

fn setup(mut commands: Commands) {
    // The brachialis from the arm scene, held by its upper tendon: every
    // vertex within 18 mm of its tip.
    let tip = Vec3::new(-0.166, 0.300, -0.093);
    let bone = commands
        .spawn((SinewBone::new("hook"), Transform::from_translation(tip)))
        .id();
    let path = "assets/meshes/myoarm/BRA.obj";
    commands.spawn(
        MuscleBuilder::new(
            "brachialis",
            MuscleSource::File(path.into(), LoadOptions::default()),
        )
        .roots(Roots::LongestAxisTips)
        .attach(MuscleAttachment::region(bone, tip, 0.018)),
    );
    commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(0.15, 0.25, 0.45).looking_at(Vec3::new(-0.15, 0.2, -0.1), Vec3::Y),
    ));
    commands.spawn((
        DirectionalLight::default(),
        Transform::from_xyz(1.0, 2.0, 1.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
}
