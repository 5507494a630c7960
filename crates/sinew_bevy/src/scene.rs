//! Scenes: our RON scene files as Bevy assets, spawned as entities.
//!
//! `asset_server.load::<SinewScene>("scenes/p3.ron")` reads a scene (mesh
//! paths relative to the scene file, on the default file source) and builds
//! every muscle on the asset loader's thread. A [`SinewSceneRoot`] entity
//! then gets, as children, one entity per bone (with its keyframes, target
//! mesh and, with `render`, its mesh) and per muscle, plus the skeleton and
//! the sensors. The scene's solver settings replace [`SinewSettings`].
//! Keep the root at the identity: muscle vertices are world positions.

use crate::build::muscle_snapshot;
use crate::components::*;
use crate::relations::{spawn_attachments, spawn_connections};
use crate::sensors::{ActivationDrive, ReadsSensor, Sensor, SensorInputOf, SensorSlot};
use crate::settings::SinewSettings;
use bevy::asset::io::Reader;
use bevy::asset::io::file::FileAssetReader;
use bevy::asset::{AssetLoader, LoadContext};
use bevy::prelude::*;
use sinew_core::SolverParts;
use sinew_core::muscle::TargetRef;
use sinew_core::scene::Scene;
use sinew_core::sensor::ActivationRig;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A scene, parsed and built (every muscle's structure and constraints).
#[derive(Asset, TypePath, Clone, Debug)]
pub struct SinewScene {
    /// The scene as written.
    pub scene: Scene,
    /// The built bones, targets, muscles, skeleton and sensors.
    pub parts: SolverParts,
}

impl SinewScene {
    /// Builds `scene`, whose mesh paths are relative to `base_dir`.
    pub fn build(scene: Scene, base_dir: &Path) -> Result<Self, sinew_core::SceneError> {
        let parts = scene.instantiate(base_dir)?.into_parts();
        Ok(Self { scene, parts })
    }

    /// Reads and builds a scene file.
    pub fn load(path: &Path) -> Result<Self, sinew_core::SceneError> {
        let scene = Scene::load(path)?;
        Self::build(scene, path.parent().unwrap_or(Path::new("."))).map_err(|e| e.in_file(path))
    }
}

/// The entity a scene is spawned under.
#[derive(Component, Clone, Debug)]
#[require(Transform, SpawnedScene)]
pub enum SinewSceneRoot {
    /// A scene asset (spawned once loaded).
    Asset(Handle<SinewScene>),
    /// A scene already built (headless use, tests).
    Built(Arc<SinewScene>),
}

/// What a [`SinewSceneRoot`] spawned: bone and muscle entities by index in
/// the scene.
#[derive(Component, Clone, Debug, Default)]
pub struct SpawnedScene {
    /// Every entity spawned (despawned on reset).
    pub entities: Vec<Entity>,
    /// Bone entities, in scene order.
    pub bones: Vec<Entity>,
    /// Muscle entities, in scene order.
    pub muscles: Vec<Entity>,
    /// Spawned already.
    pub(crate) done: bool,
}

/// Loads `.ron` scenes (see the module docs).
#[derive(TypePath)]
pub struct SinewSceneLoader {
    /// Directory the default asset source reads from.
    root: PathBuf,
}

/// Why a scene asset could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneLoadError {
    /// The file could not be read.
    #[error("could not read scene '{path}': {source}")]
    Io {
        /// The asset path.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// The file is not UTF-8.
    #[error("scene '{0}' is not UTF-8 text")]
    NotText(String),
    /// The scene is invalid or could not be built.
    #[error(transparent)]
    Scene(#[from] sinew_core::SceneError),
}

impl AssetLoader for SinewSceneLoader {
    type Asset = SinewScene;
    type Settings = ();
    type Error = SceneLoadError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        load_context: &mut LoadContext<'_>,
    ) -> Result<SinewScene, SceneLoadError> {
        let asset_path = load_context.path().path().to_path_buf();
        let mut bytes = Vec::new();
        reader
            .read_to_end(&mut bytes)
            .await
            .map_err(|source| SceneLoadError::Io {
                path: asset_path.display().to_string(),
                source,
            })?;
        let text = String::from_utf8(bytes)
            .map_err(|_| SceneLoadError::NotText(asset_path.display().to_string()))?;
        let file = self.root.join(&asset_path);
        let scene = Scene::from_ron(&text, &file)?;
        let base = file.parent().map(Path::to_path_buf).unwrap_or_default();
        Ok(SinewScene::build(scene, &base).map_err(|e| e.in_file(&file))?)
    }

    fn extensions(&self) -> &[&str] {
        &["ron"]
    }
}

/// Registers the asset and its loader when the app has an asset server.
pub(crate) fn register(app: &mut App) {
    if app.is_plugin_added::<AssetPlugin>() {
        let folder = app
            .get_added_plugins::<AssetPlugin>()
            .first()
            .map_or_else(|| "assets".to_string(), |p| p.file_path.clone());
        let root = FileAssetReader::get_base_path().join(folder);
        app.init_asset::<SinewScene>()
            .insert_resource(crate::save::SceneFolder(root.clone()))
            .register_asset_loader(SinewSceneLoader { root })
            .add_systems(
                crate::SinewPrepareSchedule,
                crate::save::respawn_changed_scenes.before(spawn_scenes),
            );
    }
}

/// Spawns scenes whose asset is ready.
pub(crate) fn spawn_scenes(
    mut commands: Commands,
    mut roots: Query<(Entity, &SinewSceneRoot, &mut SpawnedScene)>,
    assets: Option<Res<Assets<SinewScene>>>,
    mut settings: ResMut<SinewSettings>,
    mut timings: Option<ResMut<crate::SinewTimings>>,
) {
    for (root, source, mut spawned) in &mut roots {
        if spawned.done {
            continue;
        }
        let scene = match source {
            SinewSceneRoot::Built(scene) => scene.as_ref(),
            SinewSceneRoot::Asset(handle) => match assets.as_ref().and_then(|a| a.get(handle)) {
                Some(scene) => scene,
                None => continue,
            },
        };
        *settings = scene.parts.settings.clone().into();
        // Children with meshes need a visible parent.
        #[cfg(feature = "render")]
        commands
            .entity(root)
            .insert_if_new((Visibility::default(), InheritedVisibility::default()));
        *spawned = spawn(&mut commands, root, scene);
        // The panel's chart and median cover the scene as it runs, not the
        // steps taken before it spawned.
        if let Some(timings) = timings.as_mut() {
            timings.restart_history();
        }
    }
}

/// Spawns a scene's sensors under `root` (one entity each, reading its own
/// list of bone entities) and, for every driven muscle, its
/// [`ActivationDrive`] and one input entity per sensor it reads. Returns
/// the sensor entities.
fn spawn_sensors(
    commands: &mut Commands,
    root: Entity,
    rig: ActivationRig,
    bones: &[Entity],
    muscles: &[Entity],
) -> Vec<Entity> {
    let parts = rig.into_parts();
    let sensors: Vec<Entity> = parts
        .sensors
        .into_iter()
        .map(|(name, mut tracker)| {
            let used = tracker.localize_bones();
            let sensor = Sensor {
                name: name.clone(),
                tracker,
                bones: used.iter().map(|&b| bones[b]).collect(),
            };
            commands
                .spawn((Name::new(name), sensor, ChildOf(root)))
                .id()
        })
        .collect();
    for (m, mut stack) in parts.stacks {
        let muscle = muscles[m];
        for (slot, global) in stack.localize_sensors().into_iter().enumerate() {
            commands.spawn((
                SensorInputOf(muscle),
                ReadsSensor(sensors[global]),
                SensorSlot(slot),
            ));
        }
        commands.entity(muscle).insert(ActivationDrive(stack));
    }
    sensors
}

/// Spawns the entities of `scene` under `root`.
fn spawn(commands: &mut Commands, root: Entity, scene: &SinewScene) -> SpawnedScene {
    let parts = &scene.parts;
    let bones: Vec<Entity> = parts
        .bones
        .iter()
        .map(|_| commands.spawn(ChildOf(root)).id())
        .collect();
    let muscles: Vec<Entity> = parts
        .muscles
        .iter()
        .map(|_| commands.spawn(ChildOf(root)).id())
        .collect();
    for (bone, &entity) in parts.bones.iter().zip(&bones) {
        let (_, rotation, translation) = bone.transform.to_scale_rotation_translation();
        let mut e = commands.entity(entity);
        e.insert((
            Name::new(bone.name.clone()),
            SinewBone::new(bone.name.clone()),
            Transform::from_translation(translation).with_rotation(rotation),
            BonePose::at(bone.transform),
        ));
        if !bone.track.keys.is_empty() {
            e.insert(BoneTrack(bone.track.clone()));
        }
        if let Some(t) = bone.target {
            e.insert(BoneTarget(parts.targets[t].clone()));
        }
    }
    for (i, (m, &entity)) in parts.muscles.iter().zip(&muscles).enumerate() {
        let spec = scene.scene.muscles.get(i);
        let curve = parts.curves.get(i).cloned().flatten();
        let driven = curve.is_some() || spec.is_some_and(|s| !s.drive.is_empty());
        let targets = m.targets.iter().map(|t| match *t {
            TargetRef::Bone(b) => bones[b],
            TargetRef::Muscle(o) => muscles[o],
        });
        let mut live = Muscle::from_params(&m.params);
        live.driven = driven;
        spawn_attachments(commands, entity, m, |b| bones[b]);
        spawn_connections(commands, entity, targets);
        let mut state = MuscleState::new(m.clone());
        if !m.binding.is_empty() {
            // The binding names bones by their index in the scene.
            state.bound_bones.clone_from(&bones);
        }
        let mut e = commands.entity(entity);
        e.insert((Name::new(m.name.clone()), live, muscle_snapshot(m), state));
        if let Some(curve) = curve {
            e.insert(ActivationCurve(curve));
        }
    }
    let mut root_entity = commands.entity(root);
    if let Some(rig) = &parts.skeleton {
        let bound = parts
            .bones
            .iter()
            .zip(&bones)
            .filter_map(|(b, &e)| b.body.map(|body| (e, body)))
            .collect();
        root_entity.insert(SkeletonDriver {
            rig: rig.clone(),
            bones: bound,
        });
    }
    let sensors = match &parts.activation_rig {
        Some(rig) => spawn_sensors(commands, root, rig.clone(), &bones, &muscles),
        None => Vec::new(),
    };
    let entities = bones
        .iter()
        .chain(&muscles)
        .chain(&sensors)
        .copied()
        .collect();
    SpawnedScene {
        entities,
        bones,
        muscles,
        done: true,
    }
}
