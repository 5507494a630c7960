//! What the viewport draws (feature `render`): the layers of a body —
//! simulated skin layers, a glTF character's own (linearly blended) skin,
//! the muscles, the bones — each shown or hidden, and the skin drawn
//! see-through ("x-ray") so the muscles under it show. [`SinewView`] is the
//! resource; the panel edits it.

use crate::render::{BoneMesh, MuscleMesh, SkinLayerMesh};
use bevy::mesh::skinning::SkinnedMesh;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;

/// Which layers are drawn, and how the skin is.
#[derive(Resource, Clone, Debug, PartialEq, Reflect)]
#[reflect(Resource)]
pub struct SinewView {
    /// Draw simulated skin layers (surface layers, e.g. the `skin` that
    /// `sinew fit` adds). Default: `true`.
    pub skin: bool,
    /// Draw skinned meshes (a glTF character's skin as its skeleton
    /// deforms it, without the simulation). Default: `true`;
    /// [`OnCharacter`](crate::character::OnCharacter) turns it off when its
    /// scene brings a simulated skin layer (which takes its place).
    pub character_skin: bool,
    /// Draw muscles. Default: `true`.
    pub muscles: bool,
    /// Draw the bones' meshes. Default: `true`.
    pub bones: bool,
    /// Draw the skin (skin layers and skinned meshes) see-through.
    /// Default: `false`.
    pub xray: bool,
    /// Opacity multiplier while see-through, in `[0, 1]`. Default: 0.3.
    pub opacity: f32,
    /// How many skinned meshes the app has (maintained by the plug-in).
    pub skinned: usize,
    /// How many simulated skin layers the app has (maintained by the
    /// plug-in).
    pub skin_layers: usize,
}

impl Default for SinewView {
    fn default() -> Self {
        Self {
            skin: true,
            character_skin: true,
            muscles: true,
            bones: true,
            xray: false,
            opacity: 0.3,
            skinned: 0,
            skin_layers: 0,
        }
    }
}

impl SinewView {
    /// Whether the app has any skin to show or see through.
    pub fn has_skin(&self) -> bool {
        self.skinned + self.skin_layers > 0
    }
}

/// Each touched material's own alpha mode and opacity.
#[derive(Default)]
pub(crate) struct OwnLook(HashMap<AssetId<StandardMaterial>, (AlphaMode, f32)>);

/// Skinned meshes and simulated skin layers: whose material x-ray blends.
type SkinMaterials<'w, 's> = Query<
    'w,
    's,
    &'static MeshMaterial3d<StandardMaterial>,
    Or<(With<SkinnedMesh>, With<SkinLayerMesh>)>,
>;

/// Skins that just appeared.
type NewSkins = Or<(Added<SkinnedMesh>, Added<SkinLayerMesh>)>;

/// Entities that just joined a layer.
type NewInLayer = Or<(Added<SkinnedMesh>, Added<MuscleMesh>, Added<BoneMesh>)>;

/// Counts the skins and applies [`SinewView::xray`] to their materials
/// when the view or the set of skins changes.
pub(crate) fn apply_xray(
    mut view: ResMut<SinewView>,
    skins: SkinMaterials,
    skinned: Query<(), With<SkinnedMesh>>,
    layers: Query<(), With<SkinLayerMesh>>,
    added: Query<(), NewSkins>,
    materials: Option<ResMut<Assets<StandardMaterial>>>,
    mut own: Local<OwnLook>,
) {
    let counts = (skinned.iter().count(), layers.iter().count());
    if (view.skinned, view.skin_layers) != counts {
        (view.skinned, view.skin_layers) = counts;
    }
    let Some(mut materials) = materials else {
        return;
    };
    if !view.is_changed() && added.is_empty() {
        return;
    }
    let opacity = view.opacity.clamp(0.0, 1.0);
    for handle in &skins {
        let id = handle.id();
        let Some(mut material) = materials.get_mut(id) else {
            continue;
        };
        let (mode, alpha) = *own
            .0
            .entry(id)
            .or_insert((material.alpha_mode, material.base_color.alpha()));
        if view.xray {
            material.alpha_mode = AlphaMode::Blend;
            material.base_color.set_alpha(alpha * opacity);
        } else {
            material.alpha_mode = mode;
            material.base_color.set_alpha(alpha);
        }
    }
}

/// Which layer a drawn entity belongs to.
type Layered = (
    Entity,
    Option<&'static mut Visibility>,
    Has<SkinLayerMesh>,
    Has<SkinnedMesh>,
    Has<MuscleMesh>,
);

/// Entities of a layer.
type AnyLayer = Or<(With<SkinnedMesh>, With<MuscleMesh>, With<BoneMesh>)>;

/// Shows or hides each layer's entities as [`SinewView`] says, when the
/// view changes and when an entity joins a layer (an app's own
/// [`Visibility`] on them stands until then).
pub(crate) fn apply_visibility(
    mut commands: Commands,
    view: Res<SinewView>,
    mut drawn: Query<Layered, AnyLayer>,
    added: Query<(), NewInLayer>,
) {
    if !view.is_changed() && added.is_empty() {
        return;
    }
    for (entity, visibility, layer, skinned, muscle) in &mut drawn {
        if !view.is_changed() && !added.contains(entity) {
            continue;
        }
        let shown = if layer {
            view.skin
        } else if skinned {
            view.character_skin
        } else if muscle {
            view.muscles
        } else {
            view.bones
        };
        let wanted = if shown {
            Visibility::Inherited
        } else {
            Visibility::Hidden
        };
        match visibility {
            Some(mut visibility) => {
                visibility.set_if_neq(wanted);
            }
            // A headless app's meshes may have none.
            None => {
                commands.entity(entity).insert(wanted);
            }
        }
    }
}
