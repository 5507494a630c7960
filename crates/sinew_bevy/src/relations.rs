//! How muscles relate to the entities around them, as Bevy relationships.
//!
//! - **Attachments.** An attachment is an entity of its own: it belongs to
//!   a muscle ([`AttachmentOf`]; the muscle lists its [`Attachments`]),
//!   holds some of the muscle's surface vertices ([`AttachmentRegion`]) and
//!   is held by a bone ([`AttachedTo`]; the bone lists the attachments it
//!   holds in [`HeldAttachments`]) — or, without [`AttachedTo`], by the
//!   world. Spawning one attaches the muscle where it is now; despawning
//!   it detaches; inserting another [`AttachedTo`] re-targets it (the
//!   vertices stay where they are, held by the new bone from then on).
//! - **Connections.** What a muscle slides on (Sliding, Soft and Hard to
//!   bones with a [`crate::components::BoneTarget`], and muscle–muscle
//!   links) are entities too: [`ConnectionOf`] the muscle ([`Connections`]
//!   on it, in order) and [`ConnectsTo`] the target ([`ConnectedFrom`] on
//!   it). Adding, removing or re-targeting one relinks the muscle on the
//!   next step.
//!
//! Despawning a muscle despawns its attachments and connections;
//! despawning a bone or a target despawns the attachments it holds and the
//! connections to it (the muscles are detached, [`crate::events::MuscleDetached`]).
//!
//! ```
//! use bevy::prelude::*;
//! use sinew_bevy::prelude::*;
//!
//! fn attach_and_slide(mut commands: Commands, muscle: Entity, bone: Entity) {
//!     // Hold every vertex within 1 cm of the bone's tip to the bone…
//!     commands.spawn(AttachmentRegion::near(Vec3::new(0.0, 0.3, 0.0), 0.01).on(muscle, bone));
//!     // …and let the muscle slide on the bone's mesh.
//!     commands.spawn((ConnectionOf(muscle), ConnectsTo(bone)));
//! }
//! ```

use bevy::prelude::*;
use sinew_core::muscle::{Attachment as CoreAttachment, Muscle as CoreMuscle};

/// On an attachment entity: the muscle it belongs to. The entity also
/// needs an [`AttachmentRegion`] (which vertices it holds).
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, Reflect)]
#[reflect(Component)]
#[relationship(relationship_target = Attachments)]
#[require(HeldVertices)]
pub struct AttachmentOf(pub Entity);

/// On a muscle: its attachment entities, in the order they were added.
/// Despawning the muscle despawns them.
#[derive(Component, Clone, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Component)]
#[relationship_target(relationship = AttachmentOf, linked_spawn)]
pub struct Attachments(Vec<Entity>);

/// On an attachment entity: the bone ([`crate::components::SinewBone`])
/// that holds it. Without it the attachment holds its vertices to the
/// world.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, Reflect)]
#[reflect(Component)]
#[relationship(relationship_target = HeldAttachments)]
pub struct AttachedTo(pub Entity);

/// On a bone: the attachments it holds. Despawning the bone despawns them
/// (its muscles are detached from it).
#[derive(Component, Clone, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Component)]
#[relationship_target(relationship = AttachedTo, linked_spawn)]
pub struct HeldAttachments(Vec<Entity>);

/// On a connection entity: the muscle that slides on the target.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, Reflect)]
#[reflect(Component)]
#[relationship(relationship_target = Connections)]
pub struct ConnectionOf(pub Entity);

/// On a muscle: its connections, in order (the order of its targets).
/// Despawning the muscle despawns them.
#[derive(Component, Clone, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Component)]
#[relationship_target(relationship = ConnectionOf, linked_spawn)]
pub struct Connections(Vec<Entity>);

/// On a connection entity: what the muscle slides on — a bone with a
/// [`crate::components::BoneTarget`] or another muscle.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, Reflect)]
#[reflect(Component)]
#[relationship(relationship_target = ConnectedFrom)]
pub struct ConnectsTo(pub Entity);

/// On a target: the connections that reach it. Despawning the target
/// despawns them.
#[derive(Component, Clone, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Component)]
#[relationship_target(relationship = ConnectsTo, linked_spawn)]
pub struct ConnectedFrom(Vec<Entity>);

/// On an attachment entity: which of the muscle's surface vertices it
/// holds. Resolved against the muscle as it is when the attachment is
/// added (or the region or bone changes): the vertices are held where
/// they are then.
#[derive(Component, Clone, Debug, PartialEq, Reflect)]
#[reflect(Component)]
pub enum AttachmentRegion {
    /// These surface vertices.
    Vertices(Vec<u32>),
    /// The surface vertex nearest `point` (world, scene units) and every
    /// one within `radius` of it (scene units; `0`: the nearest only).
    Near {
        /// The point.
        point: Vec3,
        /// The region's radius. Units: scene units.
        radius: f32,
    },
}

impl AttachmentRegion {
    /// Whether `self` and `other` hold the same vertices: equal, comparing
    /// numbers by their bits (a NaN radius is the same region as itself,
    /// reported once).
    pub(crate) fn same_as(&self, other: &Self) -> bool {
        match (self, other) {
            (Self::Vertices(a), Self::Vertices(b)) => a == b,
            (
                Self::Near { point, radius },
                Self::Near {
                    point: other_point,
                    radius: other_radius,
                },
            ) => {
                point.to_array().map(f32::to_bits) == other_point.to_array().map(f32::to_bits)
                    && radius.to_bits() == other_radius.to_bits()
            }
            _ => false,
        }
    }

    /// The vertex nearest `point` and every vertex within `radius` of it.
    pub fn near(point: Vec3, radius: f32) -> Self {
        Self::Near { point, radius }
    }

    /// An attachment entity's components: this region of `muscle` held by
    /// `bone`.
    pub fn on(self, muscle: Entity, bone: Entity) -> impl Bundle {
        (AttachmentOf(muscle), AttachedTo(bone), self)
    }

    /// An attachment entity's components: this region of `muscle` held
    /// where it is in the world.
    pub fn in_world(self, muscle: Entity) -> impl Bundle {
        (AttachmentOf(muscle), self)
    }
}

/// Core attachments, each with its place in its muscle's list.
pub(crate) type PlacedAttachments = Vec<(u64, CoreAttachment)>;

/// What an attachment holds, as the plug-in resolved it: the vertices'
/// places in the bone's frame. Maintained by the plug-in.
#[derive(Component, Clone, Debug, Default)]
pub struct HeldVertices {
    /// The region and bone it was resolved for (`None`: not yet).
    pub(crate) resolved_for: Option<(Option<AttachmentRegion>, Option<Entity>)>,
    /// The core attachments, each with its place in the muscle's list
    /// (kept across detaching others, so a muscle's order never changes).
    pub(crate) attachments: PlacedAttachments,
}

impl HeldVertices {
    /// Whether it was resolved for `region` held by `bone` (regions
    /// compared by [`AttachmentRegion::same_as`]).
    pub(crate) fn is_resolved_for(
        &self,
        region: Option<&AttachmentRegion>,
        bone: Option<Entity>,
    ) -> bool {
        self.resolved_for.as_ref().is_some_and(|(r, b)| {
            *b == bone
                && match (r, region) {
                    (Some(r), Some(region)) => r.same_as(region),
                    (r, region) => r.is_none() && region.is_none(),
                }
        })
    }

    /// The held surface vertices.
    pub fn vertices(&self) -> impl Iterator<Item = u32> + '_ {
        self.attachments.iter().map(|(_, a)| a.vertex.raw())
    }
}

/// Spawns the attachment entities of a built muscle: one per bone (and
/// one for the world), holding its attachments as built, in order.
/// `bone_entity` names the bone behind a core bone index.
pub(crate) fn spawn_attachments(
    commands: &mut Commands,
    muscle: Entity,
    built: &CoreMuscle,
    bone_entity: impl Fn(usize) -> Entity,
) {
    let mut groups: Vec<(Option<usize>, PlacedAttachments)> = Vec::new();
    for (order, a) in built.attachments.iter().enumerate() {
        let entry = (order as u64, *a);
        match groups.iter_mut().find(|(bone, _)| *bone == a.bone) {
            Some((_, held)) => held.push(entry),
            None => groups.push((a.bone, vec![entry])),
        }
    }
    for (bone, attachments) in groups {
        let bone = bone.map(&bone_entity);
        let region =
            AttachmentRegion::Vertices(attachments.iter().map(|(_, a)| a.vertex.raw()).collect());
        let held = HeldVertices {
            resolved_for: Some((Some(region.clone()), bone)),
            attachments,
        };
        let mut e = commands.spawn((AttachmentOf(muscle), region, held));
        if let Some(bone) = bone {
            e.insert(AttachedTo(bone));
        }
    }
}

/// Spawns a muscle's connections to `targets`, in order.
pub(crate) fn spawn_connections(
    commands: &mut Commands,
    muscle: Entity,
    targets: impl IntoIterator<Item = Entity>,
) {
    for target in targets {
        commands.spawn((ConnectionOf(muscle), ConnectsTo(target)));
    }
}
