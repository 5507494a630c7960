//! Tuning that is kept: a tuned scene saved to RON loads back with the
//! same values and saves again to the same text; a scene without a file
//! needs a path (typed error); a scene asset that changes is spawned again,
//! and a scene file edited on disk too (the file watcher), but not on its own save.

use crate::common;

use bevy::prelude::*;
use sinew_bevy::prelude::*;
use sinew_core::scene::{Scene, builtin};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// A fresh file under the target directory's temporary folder.
fn temp_file(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("sinew_save");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// An app with `scene` spawned and stepped once; its root.
fn spawned_app(scene: Scene) -> (App, Entity) {
    let mut app = common::app();
    let scene = SinewScene::build(scene, Path::new(".")).unwrap();
    let root = app
        .world_mut()
        .spawn(SinewSceneRoot::Built(Arc::new(scene)))
        .id();
    app.update();
    (app, root)
}

/// Saves the scene under `root` to `path`; the `SceneSaved` path.
fn save(app: &mut App, root: Entity, path: &Path) -> PathBuf {
    let saved = Arc::new(Mutex::new(None));
    let sink = saved.clone();
    app.add_observer(move |s: On<SceneSaved>| *sink.lock().unwrap() = Some(s.path.clone()));
    app.world_mut().write_message(SaveScene {
        root,
        path: Some(path.to_path_buf()),
    });
    app.update();
    saved.lock().unwrap().clone().expect("saved")
}

#[test]
fn a_tuned_scene_saves_and_loads_back_exactly() {
    let (mut app, root) = spawned_app(builtin("P3").unwrap());
    let muscles = common::scene_muscles(&app, root);
    {
        let mut m = app.world_mut().get_mut::<Muscle>(muscles[0]).unwrap();
        m.compliance.fiber = 3.5e-5;
        m.weights.soft = 0.125;
        m.max_contraction = 0.42;
        m.rest_activation = 0.1;
        m.damping = 5.5;
        m.activation = 0.3;
    }
    app.world_mut()
        .get_mut::<Muscle>(muscles[1])
        .unwrap()
        .volume_gain = 1.05;
    app.world_mut().resource_mut::<SinewSettings>().iterations = 7;
    let tuned: Vec<Muscle> = muscles
        .iter()
        .map(|&e| app.world().get::<Muscle>(e).unwrap().clone())
        .collect();
    let first = temp_file("p3_tuned.ron");
    assert_eq!(save(&mut app, root, &first), first);

    // The file holds the tuned values…
    let loaded = Scene::load(&first).unwrap();
    assert_eq!(loaded.settings.iterations, 7);
    let p = &loaded.muscles[0].params;
    assert_eq!(p.compliance.fiber, 3.5e-5);
    assert_eq!(p.weights.soft, 0.125);
    assert_eq!((p.max_contraction, p.rest_activation), (0.42, 0.1));
    assert_eq!((p.damping, p.activation), (5.5, 0.3));
    assert_eq!(loaded.muscles[1].params.volume.gain, 1.05);
    // …and nothing else changed.
    let mut expected = builtin("P3").unwrap();
    expected.settings = loaded.settings.clone();
    for (spec, live) in expected.muscles.iter_mut().zip(&tuned) {
        live.write_to(&mut spec.params);
    }
    assert_eq!(loaded, expected);

    // Loaded back, the muscles have the tuned values; saved again, the
    // same text.
    let (mut again, root) = spawned_app(loaded);
    for (&e, live) in common::scene_muscles(&again, root).iter().zip(&tuned) {
        assert_eq!(again.world().get::<Muscle>(e).unwrap(), live);
    }
    let second = temp_file("p3_tuned_again.ron");
    save(&mut again, root, &second);
    assert_eq!(
        std::fs::read_to_string(&first).unwrap(),
        std::fs::read_to_string(&second).unwrap()
    );
}

#[test]
fn a_scene_not_loaded_from_a_file_needs_a_path() {
    let (mut app, root) = spawned_app(builtin("P1").unwrap());
    let failed = Arc::new(Mutex::new(Vec::new()));
    let sink = failed.clone();
    app.add_observer(move |f: On<SceneSaveFailed>| {
        sink.lock().unwrap().push(f.error.to_string());
    });
    app.world_mut()
        .write_message(SaveScene { root, path: None });
    let not_a_root = app.world_mut().spawn_empty().id();
    app.world_mut().write_message(SaveScene {
        root: not_a_root,
        path: Some(temp_file("never.ron")),
    });
    app.update();
    let failed = failed.lock().unwrap();
    assert_eq!(failed.len(), 2, "{failed:?}");
    assert!(failed[0].contains("give a path"), "{}", failed[0]);
    assert!(
        failed[1].contains("not a spawned scene root"),
        "{}",
        failed[1]
    );
    assert!(!temp_file("never.ron").exists());
}

#[test]
fn a_changed_scene_asset_is_spawned_again() {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        bevy::asset::AssetPlugin::default(),
        bevy::transform::TransformPlugin,
        SinewPlugin::default().every_update(),
    ));
    let build = |name| SinewScene::build(builtin(name).unwrap(), Path::new(".")).unwrap();
    let handle = app
        .world_mut()
        .resource_mut::<Assets<SinewScene>>()
        .add(build("P1"));
    let root = app
        .world_mut()
        .spawn(SinewSceneRoot::Asset(handle.clone()))
        .id();
    app.update();
    let before = common::scene_muscles(&app, root);
    assert_eq!(before.len(), 1);
    // The file changes (here: the asset is replaced, as a reload does).
    app.world_mut()
        .resource_mut::<Assets<SinewScene>>()
        .insert(handle.id(), build("P3"))
        .unwrap();
    app.update();
    app.update();
    let after = common::scene_muscles(&app, root);
    assert_eq!(after.len(), 2, "P3's two muscles");
    assert!(
        after
            .iter()
            .all(|e| app.world().get::<MuscleState>(*e).is_some())
    );
    assert!(
        app.world().get_entity(before[0]).is_err(),
        "the old muscle went"
    );
}

/// An app whose assets are read from a folder of their own, with P1
/// spawned from its `scene.ron` there.
struct SceneFileApp {
    /// The folder (`name`_<pid> under the target's temporary folder).
    dir: PathBuf,
    /// `scene.ron` in it.
    file: PathBuf,
    app: App,
    handle: Handle<SinewScene>,
    /// The scene's root, its P1 spawned.
    root: Entity,
}

impl SceneFileApp {
    /// The folder `name`_<pid> with P1 saved in it, read by an app (`watch`:
    /// with the file watcher) that has spawned it.
    fn new(name: &str, watch: bool) -> Self {
        let dir =
            Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("{name}_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("scene.ron");
        builtin("P1").unwrap().save(&file).unwrap();
        let mut app = App::new();
        app.add_plugins((
            MinimalPlugins,
            bevy::asset::AssetPlugin {
                file_path: dir.to_string_lossy().into_owned(),
                watch_for_changes_override: watch.then_some(true),
                ..default()
            },
            bevy::transform::TransformPlugin,
            SinewPlugin::default().every_update(),
        ));
        let handle: Handle<SinewScene> = app.world().resource::<AssetServer>().load("scene.ron");
        let root = app
            .world_mut()
            .spawn(SinewSceneRoot::Asset(handle.clone()))
            .id();
        let loaded = common::update_for(&mut app, common::WAIT_SECONDS, |app| {
            spawned_muscles(app, root).len() == 1
        });
        assert!(loaded, "P1 loaded");
        Self {
            dir,
            file,
            app,
            handle,
            root,
        }
    }
}

/// The muscles spawned under `root` so far (none before its scene loads).
fn spawned_muscles(app: &App, root: Entity) -> Vec<Entity> {
    app.world()
        .get::<SpawnedScene>(root)
        .map(|s| s.muscles.clone())
        .unwrap_or_default()
}

#[test]
fn an_own_save_reloaded_more_than_once_is_not_spawned_again() {
    let SceneFileApp {
        dir,
        file,
        mut app,
        handle,
        root,
    } = SceneFileApp::new("sinew_own", false);
    let spawned = |app: &App| spawned_muscles(app, root);
    let before = spawned(&app);
    app.world_mut()
        .write_message(SaveScene { root, path: None });
    app.update();

    // The watcher may bring one save back as several reloads of the same
    // text (here: the file read back and put in the asset, three times).
    let reload = |app: &mut App, scene: Scene| {
        let scene = SinewScene::build(scene, &dir).unwrap();
        app.world_mut()
            .resource_mut::<Assets<SinewScene>>()
            .insert(handle.id(), scene)
            .unwrap();
        app.update();
        app.update();
    };
    for _ in 0..3 {
        reload(&mut app, Scene::load(&file).unwrap());
        assert_eq!(
            spawned(&app),
            before,
            "its own save does not restart the scene"
        );
    }

    // Then the file brings something else: spawned again.
    reload(&mut app, builtin("P3").unwrap());
    assert_eq!(spawned(&app).len(), 2, "P3's two muscles");
    std::fs::remove_dir_all(&dir).ok();
}

#[cfg(feature = "hot_reload")]
#[test]
fn a_scene_file_edited_on_disk_is_spawned_again_but_not_its_own_save() {
    let SceneFileApp {
        dir,
        file,
        mut app,
        root,
        ..
    } = SceneFileApp::new("sinew_hot", true);
    let spawned = |app: &App| spawned_muscles(app, root);
    let before = spawned(&app);

    // Saved over its own file: the watcher reloads it, the scene keeps running.
    app.world_mut()
        .write_message(SaveScene { root, path: None });
    let respawned = common::update_for(&mut app, 2.0, |app| spawned(app) != before);
    assert!(!respawned, "its own save does not restart the scene");
    assert_eq!(spawned(&app), before);

    // Edited on disk (here: replaced by P3): spawned again, two muscles.
    builtin("P3").unwrap().save(&file).unwrap();
    assert!(
        common::update_for(&mut app, common::WAIT_SECONDS, |app| {
            spawned(app).len() == 2
        }),
        "the edited file was not spawned again"
    );
    std::fs::remove_dir_all(&dir).ok();
}
