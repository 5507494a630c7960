//! Bevy's own character path: a skinned glTF written by the test (the core's
//! two-bone arm), loaded by Bevy's glTF loader, its elbow flexed by
//! `bevy_animation`; its joints, made bones, drive a muscle placed on the
//! upper arm and held by the forearm.

#![cfg(feature = "gltf")]

use crate::common;

use bevy::animation::AnimationPlugin;
use bevy::gltf::GltfPlugin;
use bevy::mesh::MeshPlugin;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy::world_serialization::{WorldAssetRoot, WorldInstanceReady, WorldSerializationPlugin};
use sinew_bevy::prelude::*;
use sinew_core::character::{glb, primitives::two_bone_arm};
use std::time::Duration;

/// Elbow flexion of the test arm's clip at its peak (t = 1 s), rad.
pub(crate) const FLEX: f32 = 1.5;

#[derive(Resource, Clone, Copy)]
struct Joints {
    upper_arm: Entity,
    forearm: Entity,
}

/// A headless app that loads glTF scenes from `dir`, 60 updates per second
/// of `Time` (the animation's clock and the simulation's agree).
pub(crate) fn gltf_app(dir: &std::path::Path) -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin {
            file_path: dir.to_string_lossy().into_owned(),
            ..default()
        },
        TransformPlugin,
        MeshPlugin,
        AnimationPlugin,
        WorldSerializationPlugin,
        GltfPlugin::default(),
        SinewPlugin::default(),
    ));
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
        1.0 / 60.0,
    )));
    // The glTF loader is registered in `finish` (`App::run` calls it).
    app.finish();
    app.cleanup();
    app
}

/// A loaded glTF file: its scenes and clips, read once.
#[derive(Resource)]
pub(crate) struct LoadedGltf(pub Handle<Gltf>);

impl LoadedGltf {
    /// The file's first clip.
    pub(crate) fn first_clip(&self, gltfs: &Assets<Gltf>) -> Handle<AnimationClip> {
        gltfs.get(&self.0).expect("loaded").animations[0].clone()
    }
}

/// Loads `file` (once), waits for it, and spawns its first scene with
/// `extra`; the file stays loaded as [`LoadedGltf`]. Returns the scene root.
pub(crate) fn spawn_gltf(app: &mut App, file: &str, extra: impl Bundle) -> Entity {
    let handle: Handle<Gltf> = app.world().resource::<AssetServer>().load(file.to_string());
    common::update_for(app, common::WAIT_SECONDS, |app| {
        app.world().resource::<Assets<Gltf>>().contains(&handle)
    });
    let gltfs = app.world().resource::<Assets<Gltf>>();
    let scene = gltfs.get(&handle).expect("the glTF loads").scenes[0].clone();
    app.insert_resource(LoadedGltf(handle));
    app.world_mut().spawn((WorldAssetRoot(scene), extra)).id()
}

fn on_ready(
    ready: On<WorldInstanceReady>,
    loaded: Res<LoadedGltf>,
    gltfs: Res<Assets<Gltf>>,
    mut gltf: GltfCharacters,
) -> Result {
    let upper_arm = gltf.bone(ready.entity, "upper_arm")?;
    let forearm = gltf.bone(ready.entity, "forearm")?;
    // In the upper arm's frame (the shoulder at its origin, the elbow 30 cm
    // below): from 5 cm below the shoulder, in front, to 6 cm below the elbow.
    let (origin, insertion) = (Vec3::new(0.0, -0.05, 0.05), Vec3::new(0.0, -0.36, 0.045));
    gltf.commands().spawn(
        MuscleBuilder::new("biceps", MuscleSource::fusiform(origin, insertion, 0.02))
            .placed_on(upper_arm)
            .attach(MuscleAttachment::region(upper_arm, origin, 0.012))
            .attach(MuscleAttachment::region(forearm, insertion, 0.012)),
    );
    gltf.play_looped(ready.entity, loaded.first_clip(&gltfs))?;
    gltf.commands()
        .insert_resource(Joints { upper_arm, forearm });
    Ok(())
}

#[test]
fn gltf_joints_played_by_bevy_animation_drive_a_muscle() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("sinew_gltf_arm_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let arm = two_bone_arm(0.3, 0.04, FLEX);
    glb::write(&arm, &dir.join("arm.glb")).unwrap();

    let mut app = gltf_app(&dir);
    // The arm hangs from a shoulder 1.5 m up, moved away from the origin.
    let at = Transform::from_xyz(0.4, 1.5, -0.2);
    let character = spawn_gltf(&mut app, "arm.glb", at);
    app.world_mut().entity_mut(character).observe(on_ready);
    let built = common::update_for(&mut app, common::WAIT_SECONDS, |app| {
        let mut muscles = app
            .world_mut()
            .query_filtered::<Entity, With<MuscleState>>();
        muscles.iter(app.world()).next().is_some()
    });
    assert!(built, "the muscle was never built");
    let joints = *app.world().resource::<Joints>();
    let muscle = app
        .world_mut()
        .query_filtered::<Entity, With<MuscleState>>()
        .single(app.world())
        .unwrap();
    let global = |app: &App, e: Entity| *app.world().get::<GlobalTransform>(e).unwrap();

    // The muscle was built on the upper arm where the joint is, not at the
    // file's origin: its top within the shoulder's reach.
    let shoulder = global(&app, joints.upper_arm).translation();
    assert!(
        (shoulder - Vec3::new(0.4, 1.5, -0.2)).length() < 1e-4,
        "shoulder at {shoulder}"
    );
    let held_by = |app: &App, bone: Entity| -> Vec<u32> {
        let attachments = app.world().get::<Attachments>(muscle).unwrap();
        attachments
            .iter()
            .filter(|&a| app.world().get::<AttachedTo>(a).map(|t| t.0) == Some(bone))
            .flat_map(|a| {
                app.world()
                    .get::<HeldVertices>(a)
                    .unwrap()
                    .vertices()
                    .collect::<Vec<_>>()
            })
            .collect()
    };
    let (top, bottom) = (
        held_by(&app, joints.upper_arm),
        held_by(&app, joints.forearm),
    );
    assert!(
        !top.is_empty() && !bottom.is_empty(),
        "held by both bones: {top:?} {bottom:?}"
    );
    let positions = |app: &App| {
        app.world()
            .get::<MuscleState>(muscle)
            .unwrap()
            .surface_positions()
            .to_vec()
    };
    let start = positions(&app);
    for &v in &top {
        let d = (start[v as usize] - (shoulder + Vec3::new(0.0, -0.05, 0.05))).length();
        assert!(
            d < 0.02,
            "origin vertex {v} is {d} m from the origin on the bone"
        );
    }
    // Its whole surface where it was placed: within its belly radius of the
    // segment from its origin to its insertion on the posed arm.
    let (a, b) = (
        shoulder + Vec3::new(0.0, -0.05, 0.05),
        shoulder + Vec3::new(0.0, -0.36, 0.045),
    );
    for (v, p) in start.iter().enumerate() {
        let t = ((*p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
        let off = (*p - a.lerp(b, t)).length();
        assert!(
            off < 0.021,
            "vertex {v} at {p} is {off} m off the muscle's axis"
        );
    }
    // Each forearm-held vertex where the forearm's frame had it.
    let forearm_then = global(&app, joints.forearm).affine().inverse();
    let local: Vec<Vec3> = bottom
        .iter()
        .map(|&v| forearm_then.transform_point3(start[v as usize]))
        .collect();
    let length = |p: &[Vec3]| {
        let centre = |vs: &[u32]| vs.iter().map(|&v| p[v as usize]).sum::<Vec3>() / vs.len() as f32;
        (centre(&top) - centre(&bottom)).length()
    };
    let rest_length = length(&start);

    // Play on to the flexion's peak (t = 1 s of the clip) and a little past.
    let mut worst = 0.0f32;
    for _ in 0..60 {
        app.update();
        let now = positions(&app);
        let forearm_now = global(&app, joints.forearm).affine();
        for (&v, &l) in bottom.iter().zip(&local) {
            worst = worst.max((forearm_now.transform_point3(l) - now[v as usize]).length());
        }
    }
    let now = positions(&app);
    assert!(now.iter().all(|p| p.is_finite()));
    // bevy_animation turned the elbow: the forearm joint's rotation.
    let (_, rotation, _) = global(&app, joints.forearm).to_scale_rotation_translation();
    let turned = rotation.angle_between(Quat::IDENTITY);
    assert!(turned > 0.8 * FLEX, "the elbow flexed {turned} rad");
    assert!(
        worst < 1e-3,
        "held vertices followed the forearm within {worst} m"
    );
    let flexed_length = length(&now);
    assert!(
        flexed_length < 0.9 * rest_length,
        "the muscle shortened with the flexion: {rest_length} → {flexed_length} m"
    );
}

#[test]
fn skin_xray_blends_the_skinned_materials_and_gives_them_back() {
    let mut app = crate::common::app();
    app.add_plugins(AssetPlugin::default())
        .init_asset::<StandardMaterial>();
    let mut materials = app.world_mut().resource_mut::<Assets<StandardMaterial>>();
    let skin = materials.add(StandardMaterial {
        base_color: Color::srgba(0.8, 0.6, 0.5, 0.9),
        ..default()
    });
    let other = materials.add(StandardMaterial::default());
    app.world_mut().spawn((
        bevy::mesh::skinning::SkinnedMesh::default(),
        MeshMaterial3d(skin.clone()),
    ));
    app.world_mut().spawn(MeshMaterial3d(other.clone()));
    app.update();
    assert_eq!(app.world().resource::<SinewView>().skinned, 1);
    let look = |app: &App, h: &Handle<StandardMaterial>| {
        let m = app
            .world()
            .resource::<Assets<StandardMaterial>>()
            .get(h)
            .unwrap();
        (m.alpha_mode, m.base_color.alpha())
    };
    assert_eq!(look(&app, &skin), (AlphaMode::Opaque, 0.9));
    app.world_mut().resource_mut::<SinewView>().xray = true;
    app.update();
    let (mode, alpha) = look(&app, &skin);
    assert_eq!(mode, AlphaMode::Blend);
    assert!((alpha - 0.27).abs() < 1e-6, "0.3 of its own 0.9: {alpha}");
    assert_eq!(
        look(&app, &other),
        (AlphaMode::Opaque, 1.0),
        "not skinned: untouched"
    );
    app.world_mut().resource_mut::<SinewView>().xray = false;
    app.update();
    assert_eq!(
        look(&app, &skin),
        (AlphaMode::Opaque, 0.9),
        "its own look back"
    );
}

/// A scene whose skeleton is the character's (as `sinew fit --out` writes
/// them) put on the spawned glTF character: its bones become children of
/// the joints of their bodies' names, and `bevy_animation` moves them.
#[test]
fn a_scene_on_a_character_follows_its_animated_joints() {
    use sinew_bevy::scene::{SinewScene, SinewSceneRoot, SpawnedScene};
    use sinew_core::character::ClipPlayback;
    use sinew_core::scene::{BoneSpec, Scene};
    use std::sync::Arc;

    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("sinew_on_character_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let arm = two_bone_arm(0.3, 0.04, FLEX);
    glb::write(&arm, &dir.join("arm.glb")).unwrap();
    // The character's skeleton, still (the glTF animation moves it).
    let bone = |name: &str, body: &str| BoneSpec {
        name: name.into(),
        body: Some(body.into()),
        ..Default::default()
    };
    let scene = Scene {
        name: "arm bones".into(),
        skeleton: Some(arm.skeleton(None, &ClipPlayback::default())),
        bones: vec![
            bone("humerus", "upper_arm"),
            bone("ulna", "forearm"),
            bone("elsewhere", "shoulder"),
        ],
        ..Default::default()
    };
    let built = Arc::new(SinewScene::build(scene, &dir).unwrap());

    let mut app = gltf_app(&dir);
    let character = spawn_gltf(&mut app, "arm.glb", ());
    app.world_mut().entity_mut(character).observe(
        |ready: On<WorldInstanceReady>,
         loaded: Res<LoadedGltf>,
         gltfs: Res<Assets<Gltf>>,
         mut gltf: GltfCharacters|
         -> Result {
            gltf.play_looped(ready.entity, loaded.first_clip(&gltfs))?;
            Ok(())
        },
    );
    let root = app
        .world_mut()
        .spawn((SinewSceneRoot::Built(built), OnCharacter(character)))
        .id();
    let placed = common::update_for(&mut app, common::WAIT_SECONDS, |app| {
        app.world().get::<PlacedOnCharacter>(root).is_some()
    });
    assert!(placed, "the scene was never placed on the character");
    assert!(
        app.world().get::<SkeletonDriver>(root).is_none(),
        "every bone follows a joint: the scene's skeleton is dropped"
    );
    let bones = app.world().get::<SpawnedScene>(root).unwrap().bones.clone();
    let joint = |app: &mut App, name: &str| {
        app.world_mut()
            .query::<(Entity, &Name)>()
            .iter(app.world())
            .find(|(_, n)| n.as_str() == name)
            .map(|(e, _)| e)
            .unwrap()
    };
    let forearm = joint(&mut app, "forearm");
    let mut turned = 0.0f32;
    for _ in 0..70 {
        app.update();
        let at = |e: Entity| app.world().get::<GlobalTransform>(e).unwrap().affine();
        let pose = app.world().get::<BonePose>(bones[1]).unwrap().current;
        let (joint_at, bone_at) = (at(forearm), at(bones[1]));
        let off = (joint_at.matrix3 - pose.matrix3)
            .abs()
            .to_cols_array()
            .into_iter()
            .fold(0.0, f32::max)
            .max((joint_at.translation - pose.translation).length())
            .max((joint_at.translation - bone_at.translation).length());
        assert!(off < 1e-6, "the ulna is {off} off the forearm joint");
        let (_, rotation, _) = joint_at.to_scale_rotation_translation();
        turned = turned.max(rotation.angle_between(Quat::IDENTITY));
    }
    assert!(turned > 0.8 * FLEX, "the elbow flexed {turned} rad");
}
