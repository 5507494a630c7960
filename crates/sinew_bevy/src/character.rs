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

use crate::components::SinewBone;
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
