//! glTF characters (feature `gltf`): a skinned glTF scene's joints, played
//! by `bevy_animation`, drive muscles through the same components as any
//! bone: a joint entity with a [`SinewBone`] is read after transform
//! propagation like any other. [`GltfCharacters`] finds a spawned scene's
//! joints by name, makes them bones, and plays a clip on the scene's
//! [`AnimationPlayer`] (the `character` example, in full:
//! `examples/character.rs`).
//!
//! ```no_run
//! # use bevy::prelude::*;
//! # use bevy::world_serialization::{WorldAssetRoot, WorldInstanceReady};
//! # use sinew_bevy::prelude::*;
//! fn on_ready(ready: On<WorldInstanceReady>, mut gltf: GltfCharacters) -> Result {
//!     let upper_arm = gltf.bone(ready.entity, "upperarm_r")?;
//!     gltf.play_looped(ready.entity, GltfAssetLabel::Animation(0).from_asset("characters/makehuman.glb"))?;
//!     Ok(())
//! }
//! ```

use crate::components::{SinewBone, SkeletonDriver, SkeletonFrames};
use bevy::animation::{AnimationPlayer, graph::AnimationNodeIndex};
use bevy::asset::AssetPath;
use bevy::ecs::system::SystemParam;
use bevy::prelude::*;
use thiserror::Error;

/// The entities of spawned glTF scenes (a scene's root: the entity with the
/// `WorldAssetRoot`), by their glTF node names, and what to do with them:
/// make joints bones, play clips.
#[derive(SystemParam)]
pub struct GltfCharacters<'w, 's> {
    commands: Commands<'w, 's>,
    children: Query<'w, 's, &'static Children>,
    names: Query<'w, 's, &'static Name>,
    players: Query<'w, 's, (), With<AnimationPlayer>>,
    assets: Res<'w, AssetServer>,
    graphs: ResMut<'w, Assets<AnimationGraph>>,
}

/// A glTF scene lacks what was asked of it.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CharacterJointError {
    /// No entity under the scene root has this name.
    #[error("glTF scene {root}: no node named '{joint}' ({count} named nodes under it)")]
    MissingJoint {
        /// The scene root.
        root: Entity,
        /// The name asked for.
        joint: String,
        /// How many named entities the scene has.
        count: usize,
    },
    /// The scene has no [`AnimationPlayer`] (its file has no animation).
    #[error("glTF scene {root} has no AnimationPlayer (its file has no animation)")]
    NoAnimationPlayer {
        /// The scene root.
        root: Entity,
    },
}

impl<'w, 's> GltfCharacters<'w, 's> {
    /// The entity named `name` under `root` (glTF node names are the
    /// entities' [`Name`]s).
    pub fn joint(&self, root: Entity, name: &str) -> Result<Entity, CharacterJointError> {
        let mut count = 0;
        for entity in self.children.iter_descendants(root) {
            if let Ok(n) = self.names.get(entity) {
                if n.as_str() == name {
                    return Ok(entity);
                }
                count += 1;
            }
        }
        Err(CharacterJointError::MissingJoint {
            root,
            joint: name.to_string(),
            count,
        })
    }

    /// The joint named `name` under `root`, made a [`SinewBone`] of that
    /// name (its pose then moves the muscles attached to it and the targets
    /// on it).
    pub fn bone(&mut self, root: Entity, name: &str) -> Result<Entity, CharacterJointError> {
        let joint = self.joint(root, name)?;
        self.commands.entity(joint).insert(SinewBone::new(name));
        Ok(joint)
    }

    /// The entity under `root` whose [`AnimationPlayer`] plays the scene's
    /// clips (the glTF loader puts one on the root of each animated node tree).
    pub fn animation_player(&self, root: Entity) -> Result<Entity, CharacterJointError> {
        std::iter::once(root)
            .chain(self.children.iter_descendants(root))
            .find(|&e| self.players.contains(e))
            .ok_or(CharacterJointError::NoAnimationPlayer { root })
    }

    /// Plays the clip at `clip` (e.g. `GltfAssetLabel::Animation(0)
    /// .from_asset(file)`) on repeat on the scene's animation player, through
    /// a one-clip [`AnimationGraph`]; returns the clip's node.
    pub fn play_looped<'a>(
        &mut self,
        root: Entity,
        clip: impl Into<AssetPath<'a>>,
    ) -> Result<AnimationNodeIndex, CharacterJointError> {
        let player_entity = self.animation_player(root)?;
        let (graph, node) = AnimationGraph::from_clip(self.assets.load(clip.into()));
        let mut player = AnimationPlayer::default();
        player.play(node).repeat();
        let graph = AnimationGraphHandle(self.graphs.add(graph));
        self.commands.entity(player_entity).insert((player, graph));
        Ok(node)
    }

    /// The commands of the system this parameter belongs to.
    pub fn commands(&mut self) -> &mut Commands<'w, 's> {
        &mut self.commands
    }
}

/// Puts the [`SinewSceneRoot`](crate::scene::SinewSceneRoot) it is on onto
/// a spawned glTF character (this entity: the one with the glTF scene's
/// `WorldAssetRoot`): once both are spawned, every scene bone that follows a
/// skeleton body named like one of the character's nodes becomes a child of
/// that node at the identity, so the character's animation
/// (`bevy_animation`) moves it; bones whose body the character lacks stay
/// with the scene's own skeleton (a warning names them). Made for scenes
/// whose skeleton is the character's, as `sinew fit --out` writes them.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
pub struct OnCharacter(pub Entity);

/// Inserted once [`OnCharacter`] has put its scene's bones on the joints.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PlacedOnCharacter;

/// Places every spawned scene with an [`OnCharacter`] whose character has
/// spawned (see there).
pub(crate) fn place_scenes_on_characters(
    mut commands: Commands,
    mut roots: Query<
        (
            Entity,
            &OnCharacter,
            &crate::scene::SpawnedScene,
            Option<&mut SkeletonDriver>,
        ),
        Without<PlacedOnCharacter>,
    >,
    children: Query<&Children>,
    names: Query<&Name>,
) {
    for (root, on, spawned, driver) in &mut roots {
        if !spawned.done {
            continue;
        }
        let joints: std::collections::HashMap<&str, Entity> = children
            .iter_descendants(on.0)
            .filter_map(|e| names.get(e).ok().map(|n| (n.as_str(), e)))
            .collect();
        if joints.is_empty() {
            // The character has not spawned yet.
            continue;
        }
        if let Some(mut driver) = driver {
            let bodies = driver.rig.body_names().to_vec();
            let mut missing = Vec::new();
            driver
                .bones
                .retain(|&(bone, body)| match joints.get(bodies[body].as_str()) {
                    Some(&joint) => {
                        commands
                            .entity(bone)
                            .insert((ChildOf(joint), Transform::IDENTITY));
                        false
                    }
                    None => {
                        missing.push(bodies[body].clone());
                        true
                    }
                });
            if !missing.is_empty() {
                warn!(
                    "sinew: the character {} has no node named {}: those bones keep the scene's skeleton",
                    on.0,
                    missing.join(", ")
                );
            }
            if driver.bones.is_empty() {
                commands
                    .entity(root)
                    .remove::<(SkeletonDriver, SkeletonFrames)>();
            }
        }
        commands.entity(root).insert(PlacedOnCharacter);
    }
}

/// Registers every reflected type, as Bevy's `reflect_auto_register`
/// feature (on in Bevy's default features) does: a glTF scene is spawned by
/// reflection, and an app built without that feature — sinew's examples
/// use Bevy without its defaults — would panic on its first unregistered
/// component. Registering a type twice is harmless.
pub(crate) fn register_reflected_types(app: &mut App) {
    app.world()
        .resource::<AppTypeRegistry>()
        .write()
        .register_derived_types();
}
