//! glTF characters (feature `gltf`): a skinned glTF scene's joints, played
//! by `bevy_animation`, drive muscles through the same components as any
//! bone: a joint entity with a [`SinewBone`] is read after transform
//! propagation like any other. [`GltfCharacters`] finds a spawned scene's
//! joints by name, makes them bones, and plays a clip on the scene's
//! [`AnimationPlayer`]; [`OnCharacter`] puts a fitted scene (bones,
//! muscles, a simulated skin) on a character (the `character` example:
//! `examples/character.rs`).
//!
//! Load a character's file once and take its scene and clips from the
//! loaded [`Gltf`] (`scenes`, `named_animations`): asking
//! for a file's assets one by one may read it several times, and asking
//! for one after the others were dropped reads it again — each new read
//! respawns the character, with everything parented to its joints.
//!
//! ```no_run
//! # use bevy::prelude::*;
//! # use bevy::world_serialization::{WorldAssetRoot, WorldInstanceReady};
//! # use sinew_bevy::prelude::*;
//! #[derive(Resource)]
//! struct Character(Handle<Gltf>);
//!
//! fn on_ready(
//!     ready: On<WorldInstanceReady>,
//!     character: Res<Character>,
//!     gltfs: Res<Assets<Gltf>>,
//!     mut gltf: GltfCharacters,
//! ) -> Result {
//!     let upper_arm = gltf.bone(ready.entity, "upperarm_r")?;
//!     let clip = gltfs.get(&character.0).ok_or("not loaded")?.animations[0].clone();
//!     gltf.play_looped(ready.entity, clip)?;
//!     Ok(())
//! }
//! ```

use crate::components::{SinewBone, SkeletonDriver, SkeletonFrames};
use bevy::animation::animated_field;
use bevy::animation::prelude::{AnimatableCurve, AnimatedField};
use bevy::animation::{
    AnimationClip, AnimationPlayer, AnimationTargetId, graph::AnimationNodeIndex,
};
use bevy::ecs::system::SystemParam;
use bevy::math::curve::{ConstantCurve, Interval};
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
    targets: Query<'w, 's, (&'static AnimationTargetId, &'static Transform)>,
    graphs: ResMut<'w, Assets<AnimationGraph>>,
    clips: ResMut<'w, Assets<AnimationClip>>,
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

    /// Plays `clip` (from the character's loaded `Gltf`: see the module
    /// docs) on repeat on the scene's animation player, through a one-clip
    /// [`AnimationGraph`]; returns the clip's node.
    pub fn play_looped(
        &mut self,
        root: Entity,
        clip: Handle<AnimationClip>,
    ) -> Result<AnimationNodeIndex, CharacterJointError> {
        let player_entity = self.animation_player(root)?;
        let (graph, node) = AnimationGraph::from_clip(clip);
        let mut player = AnimationPlayer::default();
        player.play(node).repeat();
        let graph = AnimationGraphHandle(self.graphs.add(graph));
        self.commands.entity(player_entity).insert((player, graph));
        Ok(node)
    }

    /// Plays `clip` on repeat, blended in from the pose the scene's joints
    /// have now (its bind pose, before any clip played) over `seconds`: a
    /// body simulated on the joints (muscles, a skin) then starts moving
    /// smoothly instead of jumping to the clip's first pose. Returns the
    /// clip's node. `seconds ≤ 0` plays it at once.
    pub fn play_looped_from_rest(
        &mut self,
        root: Entity,
        clip: Handle<AnimationClip>,
        seconds: f32,
    ) -> Result<AnimationNodeIndex, CharacterJointError> {
        // NaN or ≤ 0: no blend.
        if seconds.is_nan() || seconds <= 0.0 {
            return self.play_looped(root, clip);
        }
        let player_entity = self.animation_player(root)?;
        // The joints' pose now, held: one constant curve per channel.
        let mut rest = AnimationClip::default();
        let held = Interval::new(0.0, 1.0).expect("a unit interval");
        for entity in std::iter::once(root).chain(self.children.iter_descendants(root)) {
            let Ok((&target, t)) = self.targets.get(entity) else {
                continue;
            };
            rest.add_curve_to_target(
                target,
                AnimatableCurve::new(
                    animated_field!(Transform::translation),
                    ConstantCurve::new(held, t.translation),
                ),
            );
            rest.add_curve_to_target(
                target,
                AnimatableCurve::new(
                    animated_field!(Transform::rotation),
                    ConstantCurve::new(held, t.rotation),
                ),
            );
            rest.add_curve_to_target(
                target,
                AnimatableCurve::new(
                    animated_field!(Transform::scale),
                    ConstantCurve::new(held, t.scale),
                ),
            );
        }
        let mut graph = AnimationGraph::new();
        let from = graph.add_clip(self.clips.add(rest), 1.0, graph.root);
        let to = graph.add_clip(clip, 1.0, graph.root);
        let mut player = AnimationPlayer::default();
        player.play(from).repeat();
        player.play(to).repeat().set_weight(0.0);
        let blend = ClipBlendIn {
            from,
            to,
            seconds,
            elapsed: 0.0,
        };
        let graph = AnimationGraphHandle(self.graphs.add(graph));
        self.commands
            .entity(player_entity)
            .insert((player, graph, blend));
        Ok(to)
    }

    /// The commands of the system this parameter belongs to.
    pub fn commands(&mut self) -> &mut Commands<'w, 's> {
        &mut self.commands
    }
}

/// An [`AnimationPlayer`] blending from one playing clip to another
/// ([`GltfCharacters::play_looped_from_rest`]): the weight moves linearly
/// from `from` to `to` over `seconds` of virtual time, then `from` stops
/// and this component is removed.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct ClipBlendIn {
    /// The clip blended out.
    pub from: AnimationNodeIndex,
    /// The clip blended in.
    pub to: AnimationNodeIndex,
    /// How long the blend takes. Units: s.
    pub seconds: f32,
    /// How far it has gone. Units: s.
    pub elapsed: f32,
}

/// Advances every [`ClipBlendIn`].
pub(crate) fn blend_clips_in(
    mut commands: Commands,
    time: Res<Time>,
    mut players: Query<(Entity, &mut AnimationPlayer, &mut ClipBlendIn)>,
) {
    for (entity, mut player, mut blend) in &mut players {
        blend.elapsed += time.delta_secs();
        let s = (blend.elapsed / blend.seconds).clamp(0.0, 1.0);
        if let Some(to) = player.animation_mut(blend.to) {
            to.set_weight(s);
        }
        if s >= 1.0 {
            player.stop(blend.from);
            commands.entity(entity).remove::<ClipBlendIn>();
        } else if let Some(from) = player.animation_mut(blend.from) {
            from.set_weight(1.0 - s);
        }
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
/// When the scene brings a simulated skin (a surface layer bound to the
/// bones), the character's own skinned meshes are hidden
/// ([`SinewView::character_skin`](crate::view::SinewView::character_skin)
/// off): the simulated skin takes their place.
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
    states: Query<&crate::components::MuscleState>,
    mut view: Option<ResMut<crate::view::SinewView>>,
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
        let brings_skin = states
            .iter_many(&spawned.muscles)
            .any(|s| s.muscle.is_skin());
        if let Some(view) = view.as_deref_mut().filter(|_| brings_skin) {
            view.character_skin = false;
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
