//! A simulated skin on a glTF character: the scene `sinew fit` writes
//! (bones on the character's joints, a skin layer bound to them) replaces
//! the character's own skin, the view shows and hides each layer, and a
//! clip played from rest blends in from the bind pose.

#![cfg(feature = "gltf")]

use crate::character::{FLEX, LoadedGltf, gltf_app, spawn_gltf};
use crate::common;
use bevy::prelude::*;
use bevy::world_serialization::WorldInstanceReady;
use sinew_bevy::prelude::*;
use sinew_core::character::fit::{FittedScene, SkinLayer};
use sinew_core::character::{ClipPlayback, glb, primitives::two_bone_arm};
use sinew_core::scene::{BoneSpec, Scene};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

/// A folder with the test arm (`arm.glb`) for this test.
fn arm_folder(test: &str) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("sinew_{test}_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    glb::write(&two_bone_arm(0.3, 0.04, FLEX), &dir.join("arm.glb")).unwrap();
    dir
}

fn forearm(app: &mut App) -> Entity {
    app.world_mut()
        .query::<(Entity, &Name)>()
        .iter(app.world())
        .find(|(_, n)| n.as_str() == "forearm")
        .map(|(e, _)| e)
        .expect("the arm has a forearm joint")
}

/// The forearm joint's turn from its bind pose, rad.
fn elbow_angle(app: &mut App) -> f32 {
    let joint = forearm(app);
    let t = app.world().get::<Transform>(joint).unwrap();
    t.rotation.angle_between(Quat::IDENTITY)
}

#[test]
fn a_simulated_skin_replaces_the_characters_and_the_view_shows_each_layer() {
    let dir = arm_folder("skin_on_character");
    let arm = two_bone_arm(0.3, 0.04, FLEX);
    let bone = |name: &str, body: &str| BoneSpec {
        name: name.into(),
        body: Some(body.into()),
        ..Default::default()
    };
    let mut fitted = FittedScene {
        scene: Scene {
            name: "arm with skin".into(),
            skeleton: Some(arm.skeleton(None, &ClipPlayback::default())),
            bones: vec![bone("humerus", "upper_arm"), bone("ulna", "forearm")],
            ..Default::default()
        },
        meshes: Vec::new(),
    };
    fitted.add_skin(&arm, &SkinLayer::default());
    fitted.save(&dir.join("skin.ron")).unwrap();
    let built = Arc::new(SinewScene::load(&dir.join("skin.ron")).unwrap());

    let mut app = gltf_app(&dir);
    app.init_asset::<StandardMaterial>();
    let character = spawn_gltf(&mut app, "arm.glb", ());
    let root = app
        .world_mut()
        .spawn((SinewSceneRoot::Built(built), OnCharacter(character)))
        .id();
    common::update_for(&mut app, common::WAIT_SECONDS, |app| {
        app.world().get::<PlacedOnCharacter>(root).is_some()
    });
    assert!(app.world().get::<PlacedOnCharacter>(root).is_some());
    app.update();
    app.update();
    let view = app.world().resource::<SinewView>().clone();
    assert!(
        !view.character_skin,
        "a scene with a skin turns the character's skinned meshes off"
    );
    assert_eq!((view.skinned, view.skin_layers), (1, 1));
    let visibility = |app: &mut App, layer: fn(&EntityRef) -> bool| -> Vec<Visibility> {
        app.world_mut()
            .query::<EntityRef>()
            .iter(app.world())
            .filter(layer)
            .map(|e| *e.get::<Visibility>().unwrap())
            .collect()
    };
    let skinned = |e: &EntityRef| e.contains::<bevy::mesh::skinning::SkinnedMesh>();
    let layer = |e: &EntityRef| e.contains::<SkinLayerMesh>();
    assert_eq!(visibility(&mut app, skinned), [Visibility::Hidden]);
    assert_eq!(visibility(&mut app, layer), [Visibility::Inherited]);
    // The layer is drawn in skin colour, not tinted by activation.
    let skin = app
        .world_mut()
        .query_filtered::<&MeshMaterial3d<StandardMaterial>, With<SkinLayerMesh>>()
        .single(app.world())
        .unwrap()
        .0
        .clone();
    let color = app
        .world()
        .resource::<Assets<StandardMaterial>>()
        .get(&skin)
        .unwrap()
        .base_color;
    assert_eq!(color, SkinLayerMesh::COLOR);

    // Plain skinning only: the simulated skin hidden, the character's shown.
    {
        let mut view = app.world_mut().resource_mut::<SinewView>();
        view.skin = false;
        view.character_skin = true;
    }
    app.update();
    assert_eq!(visibility(&mut app, skinned), [Visibility::Inherited]);
    assert_eq!(visibility(&mut app, layer), [Visibility::Hidden]);
    // A muscle on the scene's bones (placed on the upper arm, in its
    // frame) stands for the muscles' layer.
    let bones = app.world().get::<SpawnedScene>(root).unwrap().bones.clone();
    let (origin, insertion) = (Vec3::new(0.0, -0.05, 0.05), Vec3::new(0.0, -0.36, 0.045));
    let muscle = app
        .world_mut()
        .spawn(
            MuscleBuilder::new("biceps", MuscleSource::fusiform(origin, insertion, 0.02))
                .placed_on(bones[0])
                .attach(MuscleAttachment::region(bones[0], origin, 0.012))
                .attach(MuscleAttachment::region(bones[1], insertion, 0.012)),
        )
        .id();
    common::update_for(&mut app, common::WAIT_SECONDS, |app| {
        app.world().get::<MuscleMesh>(muscle).is_some()
    });
    assert!(
        app.world().get::<MuscleMesh>(muscle).is_some(),
        "the muscle never got its mesh: {:?}",
        app.world().resource::<SinewLog>().lines
    );
    app.update();
    assert_eq!(
        app.world().get::<Visibility>(muscle),
        Some(&Visibility::Inherited)
    );
    app.world_mut().resource_mut::<SinewView>().muscles = false;
    app.update();
    assert_eq!(
        app.world().get::<Visibility>(muscle),
        Some(&Visibility::Hidden)
    );
    assert_eq!(
        visibility(&mut app, layer),
        [Visibility::Hidden],
        "a skin layer is not a muscle: the skin toggle rules it"
    );
}

#[test]
fn a_clip_played_from_rest_blends_in_from_the_bind_pose() {
    let dir = arm_folder("blend_in");
    let mut apps: Vec<App> = (0..2).map(|_| gltf_app(&dir)).collect();
    for (i, app) in apps.iter_mut().enumerate() {
        let character = spawn_gltf(app, "arm.glb", ());
        app.world_mut().entity_mut(character).observe(
            move |ready: On<WorldInstanceReady>,
                  loaded: Res<LoadedGltf>,
                  gltfs: Res<Assets<Gltf>>,
                  mut gltf: GltfCharacters|
                  -> Result {
                let clip = loaded.first_clip(&gltfs);
                if i == 0 {
                    gltf.play_looped(ready.entity, clip)?;
                } else {
                    gltf.play_looped_from_rest(ready.entity, clip, 1.0)?;
                }
                Ok(())
            },
        );
    }
    // Both load and start on the same update.
    let start = std::time::Instant::now();
    while start.elapsed().as_secs_f32() < common::WAIT_SECONDS {
        for app in &mut apps {
            app.update();
        }
        let playing = |app: &mut App| {
            app.world_mut()
                .query::<&bevy::animation::AnimationPlayer>()
                .iter(app.world())
                .any(|p| p.playing_animations().count() > 0)
        };
        if apps.iter_mut().all(playing) {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    // A quarter of a second in: a quarter of the way from rest to the clip.
    for _ in 0..15 {
        for app in &mut apps {
            app.update();
        }
    }
    let [plain, blended] = [0, 1].map(|i| elbow_angle(&mut apps[i]));
    assert!(plain > 0.2, "the clip flexes the elbow: {plain} rad");
    assert!(
        blended < 0.5 * plain && blended > 0.05 * plain,
        "blending in: {blended} rad against the clip's {plain}"
    );
    // After the blend: the clip alone.
    for _ in 0..60 {
        for app in &mut apps {
            app.update();
        }
    }
    let [plain, blended] = [0, 1].map(|i| elbow_angle(&mut apps[i]));
    assert!(
        (plain - blended).abs() < 1e-4,
        "blended in: {blended} rad against the clip's {plain}"
    );
    let blending = apps[1]
        .world_mut()
        .query::<&ClipBlendIn>()
        .iter(apps[1].world())
        .count();
    assert_eq!(blending, 0, "the blend is over");
}
