//! Tuning that is kept: a spawned scene saved back to its RON file with
//! every muscle's live parameters ([`Muscle`]) and the solver settings
//! ([`SinewSettings`]), and a scene asset that changes (on disk, with
//! Bevy's `file_watcher`, or in [`Assets`]) spawned again.
//!
//! Saving writes the scene as it was loaded with only the tuned values
//! replaced, so loading the file gives the same scene and the same tuned
//! values, and saving again writes the same text. Mesh paths stay as
//! written (relative to the scene file): save next to the original.

use crate::components::Muscle;
use crate::events::SinewLog;
use crate::scene::{SinewScene, SinewSceneRoot, SpawnedScene};
use crate::settings::SinewSettings;
use bevy::ecs::system::SystemParam;
use bevy::prelude::*;
use sinew_core::scene::Scene;
use std::path::PathBuf;
use std::sync::Arc;

/// Sent to save the scene spawned under `root` (a [`SinewSceneRoot`]).
#[derive(Message, Clone, Debug, PartialEq)]
pub struct SaveScene {
    /// The scene's root entity.
    pub root: Entity,
    /// Where to write; `None`: the file the scene asset was loaded from.
    pub path: Option<PathBuf>,
}

/// A scene was saved.
#[derive(EntityEvent, Message, Clone, Debug, PartialEq)]
pub struct SceneSaved {
    /// The scene's root entity.
    pub entity: Entity,
    /// The file written.
    pub path: PathBuf,
}

/// A scene could not be saved.
#[derive(EntityEvent, Message, Clone, Debug)]
pub struct SceneSaveFailed {
    /// The scene's root entity.
    pub entity: Entity,
    /// Why.
    pub error: Arc<SceneSaveError>,
}

/// Why a scene could not be saved.
#[derive(Debug, thiserror::Error)]
pub enum SceneSaveError {
    /// The entity is not a spawned scene root.
    #[error("entity {0} is not a spawned scene root")]
    NotAScene(Entity),
    /// No path was given and the scene was not loaded from a file.
    #[error("scene '{0}' was not loaded from a file: give a path")]
    NoPath(String),
    /// Writing failed.
    #[error(transparent)]
    Scene(#[from] sinew_core::SceneError),
}

/// Scenes saved over their own asset file, by asset: when the file watcher
/// reloads that file (once or several times) and it holds exactly what was
/// saved, the running scene already has it and is not spawned again. An
/// entry goes at the first reload that holds something else.
#[derive(Resource, Default, Debug)]
pub(crate) struct SavedScenes(
    pub(crate) bevy::platform::collections::HashMap<AssetId<SinewScene>, Scene>,
);

/// Where the default asset source reads files from (set when the app has
/// an [`AssetPlugin`]).
#[derive(Resource, Clone, Debug)]
pub(crate) struct SceneFolder(pub(crate) PathBuf);

/// `scene` with the live parameters of its spawned muscles and `settings`
/// written in. A muscle driven by a curve or sensors keeps its written
/// activation (the drive sets it at run time).
pub fn tuned_scene(
    scene: &Scene,
    spawned: &SpawnedScene,
    muscle: impl Fn(Entity) -> Option<Muscle>,
    settings: &SinewSettings,
) -> Scene {
    let mut tuned = scene.clone();
    tuned.settings = settings.to_core();
    for (spec, &entity) in tuned.muscles.iter_mut().zip(&spawned.muscles) {
        if let Some(live) = muscle(entity) {
            let activation = spec.params.activation;
            live.write_to(&mut spec.params);
            if live.driven {
                spec.params.activation = activation;
            }
        }
    }
    tuned
}

/// Scene assets, the files they come from, and what was saved over them.
#[derive(SystemParam)]
pub(crate) struct SceneFiles<'w> {
    scenes: Option<Res<'w, Assets<SinewScene>>>,
    server: Option<Res<'w, AssetServer>>,
    folder: Option<Res<'w, SceneFolder>>,
    saved: ResMut<'w, SavedScenes>,
}

impl SceneFiles<'_> {
    /// The scene of `handle` and the file it was loaded from, if any.
    fn get(&self, handle: &Handle<SinewScene>) -> Option<(&Scene, Option<PathBuf>)> {
        let scene = &self.scenes.as_ref()?.get(handle)?.scene;
        let path = self.server.as_ref().and_then(|a| a.get_path(handle.id()));
        let file = path
            .zip(self.folder.as_ref())
            .map(|(p, f)| f.0.join(p.path()));
        Some((scene, file))
    }

    /// Remembers that `scene` was written over the file of `handle`.
    fn remember(&mut self, handle: &Handle<SinewScene>, scene: Scene) {
        self.saved.0.insert(handle.id(), scene);
    }
}

/// Handles [`SaveScene`].
pub(crate) fn save_scenes(
    mut requests: MessageReader<SaveScene>,
    roots: Query<(&SinewSceneRoot, &SpawnedScene)>,
    mut files: SceneFiles,
    muscles: Query<&Muscle>,
    settings: Res<SinewSettings>,
    mut log: ResMut<SinewLog>,
    mut commands: Commands,
) {
    for request in requests.read() {
        let root = request.root;
        let saved = (|| {
            let (source, spawned) = roots
                .get(root)
                .map_err(|_| SceneSaveError::NotAScene(root))?;
            let (scene, file) = match source {
                SinewSceneRoot::Built(scene) => (&scene.scene, None),
                SinewSceneRoot::Asset(handle) => {
                    files.get(handle).ok_or(SceneSaveError::NotAScene(root))?
                }
            };
            let own_file = request.path.is_none() || request.path == file;
            let path = request
                .path
                .clone()
                .or(file)
                .ok_or_else(|| SceneSaveError::NoPath(scene.name.clone()))?;
            let tuned = tuned_scene(scene, spawned, |e| muscles.get(e).ok().cloned(), &settings);
            tuned.save(&path)?;
            if let (SinewSceneRoot::Asset(handle), true) = (source, own_file) {
                files.remember(handle, tuned);
            }
            Ok(path)
        })();
        match saved {
            Ok(path) => {
                log.push(format!("saved {}", path.display()));
                let saved = SceneSaved { entity: root, path };
                commands.write_message(saved.clone());
                commands.trigger(saved);
            }
            Err(error) => {
                warn!("sinew: the scene could not be saved: {error}");
                log.push(format!("save failed: {error}"));
                let failed = SceneSaveFailed {
                    entity: root,
                    error: Arc::new(error),
                };
                commands.write_message(failed.clone());
                commands.trigger(failed);
            }
        }
    }
}

/// Spawns again every scene whose asset changed (reloaded from disk or
/// edited in [`Assets`]): its entities are despawned and the new scene is
/// spawned in their place this frame — unless the change is the reload of
/// what [`SaveScene`] just wrote over it (the running scene has that).
pub(crate) fn respawn_changed_scenes(
    mut changes: MessageReader<AssetEvent<SinewScene>>,
    mut roots: Query<(&SinewSceneRoot, &mut SpawnedScene)>,
    scenes: Res<Assets<SinewScene>>,
    mut saved_scenes: ResMut<SavedScenes>,
    mut log: ResMut<SinewLog>,
    mut commands: Commands,
) {
    for change in changes.read() {
        let AssetEvent::Modified { id } = change else {
            continue;
        };
        // One save can reach the watcher as more than one change (the
        // rename over the file and its metadata), so the saved scene is
        // kept for as long as reloads bring exactly it back, and forgotten
        // at the first that brings something else.
        if let Some(saved) = saved_scenes.0.get(id) {
            if scenes.get(*id).is_some_and(|s| s.scene == *saved) {
                log.push("saved scene reloaded from disk: already running".into());
                continue;
            }
            saved_scenes.0.remove(id);
        }
        for (source, mut spawned) in &mut roots {
            if let SinewSceneRoot::Asset(handle) = source
                && handle.id() == *id
                && spawned.done
            {
                for e in spawned.entities.drain(..) {
                    commands.entity(e).despawn();
                }
                spawned.done = false;
                log.push("scene changed on disk: spawned again".into());
            }
        }
    }
}
