//! A glTF character played by `bevy_animation`; its joints drive a biceps as any bone would.
use bevy::prelude::*;
use bevy::world_serialization::{WorldAssetRoot, WorldInstanceReady};
use sinew::bevy::prelude::*;

fn main() {
    App::new()
        .add_plugins((DefaultPlugins, SinewPlugin::default(), SinewUiPlugin))
        .add_systems(Startup, setup)
        .run();
}

fn setup(mut commands: Commands, assets: Res<AssetServer>) {
    let scene = assets.load(GltfAssetLabel::Scene(0).from_asset("characters/makehuman.glb"));
    commands.spawn(WorldAssetRoot(scene)).observe(add_biceps);
    let view = Transform::from_xyz(-0.9, 1.4, 1.3).looking_at(Vec3::new(-0.2, 1.15, 0.0), Vec3::Y);
    commands.spawn((Camera3d::default(), view));
    commands.spawn((DirectionalLight::default(), view));
}

fn add_biceps(ready: On<WorldInstanceReady>, mut gltf: GltfCharacters) -> Result {
    let upper_arm = gltf.bone(ready.entity, "upperarm_r")?;
    let forearm = gltf.bone(ready.entity, "lowerarm_r")?;
    // In the upper arm's frame: from the shoulder's front to below the elbow.
    let (origin, insertion) = (
        Vec3::new(-0.01, -0.03, 0.03),
        Vec3::new(-0.16, -0.19, 0.035),
    );
    gltf.commands().spawn(
        MuscleBuilder::new("biceps", MuscleSource::fusiform(origin, insertion, 0.02))
            .placed_on(upper_arm)
            .attach(MuscleAttachment::region(upper_arm, origin, 0.015))
            .attach(MuscleAttachment::region(forearm, insertion, 0.015)),
    );
    gltf.play_looped(
        ready.entity,
        GltfAssetLabel::Animation(0).from_asset("characters/makehuman.glb"),
    )?;
    Ok(())
}
