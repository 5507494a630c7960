//! Seeing through a character's skin (feature `render`): with
//! [`SkinView::xray`] on, every skinned mesh's material (a glTF character's
//! skin) is drawn blended at [`SkinView::opacity`] of its own opacity, so
//! the muscles under it show; off, each material gets its own alpha mode and
//! opacity back. The panel has the toggle when the scene has skinned meshes.

use bevy::mesh::skinning::SkinnedMesh;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;

/// How skinned meshes are drawn.
#[derive(Resource, Clone, Debug, PartialEq, Reflect)]
#[reflect(Resource)]
pub struct SkinView {
    /// Draw skinned meshes see-through. Default: `false`.
    pub xray: bool,
    /// Opacity multiplier while see-through, in `[0, 1]`. Default: 0.3.
    pub opacity: f32,
    /// How many skinned meshes the app has (maintained by the plug-in).
    pub skinned: usize,
}

impl Default for SkinView {
    fn default() -> Self {
        Self {
            xray: false,
            opacity: 0.3,
            skinned: 0,
        }
    }
}

/// Each touched material's own alpha mode and opacity.
#[derive(Default)]
pub(crate) struct OwnLook(HashMap<AssetId<StandardMaterial>, (AlphaMode, f32)>);

/// Applies [`SkinView`] to the skinned meshes' materials when it or the set
/// of skinned meshes changes.
pub(crate) fn apply_skin_view(
    mut view: ResMut<SkinView>,
    skins: Query<&MeshMaterial3d<StandardMaterial>, With<SkinnedMesh>>,
    added: Query<(), Added<SkinnedMesh>>,
    materials: Option<ResMut<Assets<StandardMaterial>>>,
    mut own: Local<OwnLook>,
) {
    let count = skins.iter().count();
    if view.skinned != count {
        view.skinned = count;
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
