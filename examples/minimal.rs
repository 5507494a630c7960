//! One muscle from an OBJ file on a bone, held by its upper tendon and
//! sliding on the bone under gravity — without a vertex index.
//!
//! Run with `cargo run --release --example minimal`.

use bevy::prelude::*;
use sinew::bevy::prelude::*;
use sinew::core::muscle::Roots;
use std::f32::consts::FRAC_PI_2;

fn main() {
    App::new()
        .add_plugins(DefaultPlugins)
        .add_plugins(SinewPlugin::default().gravity(Vec3::new(0.0, -9.81, 0.0)))
        .add_plugins(SinewUiPlugin)
        .add_systems(Startup, setup)
        .run();
}

fn setup(mut commands: Commands) -> Result {
    // The humerus (its mesh in its own frame, placed as in the arm scene)
    // and the brachialis; the muscle is held by every vertex within 18 mm
    // of its upper tip and slides on the bone.
    let humerus = BoneTarget::load("assets/meshes/myoarm/humerus_r.obj")?;
    let at = Transform::from_xyz(-0.170, 0.474, -0.0995)
        .with_rotation(Quat::from_rotation_y(-FRAC_PI_2));
    let bone = commands
        .spawn((SinewBone::new("humerus"), humerus, at))
        .id();
    let tip = Vec3::new(-0.166, 0.300, -0.093);
    commands.spawn(
        MuscleBuilder::new(
            "brachialis",
            MuscleSource::file("assets/meshes/myoarm/BRA.obj"),
        )
        .roots(Roots::LongestAxisTips)
        .attach(MuscleAttachment::region(bone, tip, 0.018))
        .target(bone),
    );
    commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(0.15, 0.25, 0.45).looking_at(Vec3::new(-0.15, 0.2, -0.1), Vec3::Y),
    ));
    commands.spawn((
        DirectionalLight::default(),
        Transform::from_xyz(1.0, 2.0, 1.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    Ok(())
}
