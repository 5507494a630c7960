//! The character's skin as a simulated layer of a fitted scene: a surface
//! layer held to its linear-blend-skinned position through the character's
//! joints, sliding on the muscles and bones below.

use super::FittedScene;
use crate::character::SkinnedCharacter;
use crate::constraints::{AreaMode, SlidingMode};
use crate::mesh::ObjObjects;
use crate::muscle::{MuscleParams, Roots};
use crate::scene::{BoneSpec, MeshSource, MuscleSpec, SkinBindingSpec};

/// The skin layer [`FittedScene::add_skin`] adds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkinLayer {
    /// Mass per area of skin and the fat it carries. Units: kg/m².
    /// Default: 1.1.
    pub area_density: f32,
    /// How far below the skin it looks for muscles and bones to slide on:
    /// at least the thickest fat. Units: m. Default: 0.02.
    pub reach: f32,
    /// Compliance of the skin's edges (how much it stretches). Units:
    /// m/N. Default: 0.005.
    pub stretch_compliance: f32,
    /// Compliance of each skin triangle's area (how much it gathers into
    /// folds or collapses). Units: m³/N. Default: 1e-7.
    pub area_compliance: f32,
    /// Whether the area is kept both ways or only against shrinking.
    /// Default: [`AreaMode::NoShrink`]: the skin stretches freely over a
    /// bulging muscle (its edges hold it). On MakeHuman's `elbow_flex` the
    /// skin over the biceps stands out of plain skinning by 5.0–6.2 mm;
    /// with [`AreaMode::Keep`] 2.8–6.4 mm (short head right 4.6, long 3.3),
    /// though over the walk `Keep` folds fewer triangles (118 against 169
    /// in the worst frame) and stretches the edges less (p99 ×1.35
    /// against ×1.45).
    pub area_mode: AreaMode,
    /// Compliance of the pull towards the skinned position (÷ a vertex's
    /// strength). Units: m/N. Default: 0.05.
    pub bind_compliance: f32,
    /// Solver iterations for the skin (its own count, below the muscles'):
    /// held by its binding and resting on the muscles, it converges in
    /// fewer. Over MakeHuman's walk 4 gave the figures of 10 (skin vertices
    /// inside 1.94 % against 1.90 %, 23 mm from the skinned position
    /// against 25) in 60 % less of the skin's time. They are spread over
    /// the substep's iterations ([`crate::solver::IterationParams::runs`]).
    /// Default: 4.
    pub iterations: u32,
}

impl Default for SkinLayer {
    fn default() -> Self {
        Self {
            area_density: 1.1,
            reach: 0.02,
            stretch_compliance: 0.005,
            area_compliance: 1e-7,
            area_mode: AreaMode::NoShrink,
            bind_compliance: 0.05,
            iterations: 4,
        }
    }
}

impl FittedScene {
    /// Adds `character`'s skin (its bind-pose mesh, `meshes/skin.obj`) as a
    /// surface layer ([`MuscleParams::surface_layer`], sliding in
    /// [`SlidingMode::Contact`]) named `skin`, bound
    /// by the character's weights to a mesh-less bone `joint:NAME` per
    /// joint (each following its skeleton body), sliding on every muscle
    /// and every bone with a mesh. The scene's skeleton must be the
    /// character's ([`SkinnedCharacter::skeleton`]).
    pub fn add_skin(&mut self, character: &SkinnedCharacter, layer: &SkinLayer) {
        let joint_bone = |name: &str| format!("joint:{name}");
        let targets: Vec<String> = self
            .scene
            .bones
            .iter()
            .filter(|b| b.shape.is_some())
            .map(|b| b.name.clone())
            .chain(self.scene.muscles.iter().map(|m| m.name.clone()))
            .collect();
        for joint in &character.joints {
            self.scene.bones.push(BoneSpec {
                name: joint_bone(&joint.name),
                shape: None,
                track: Default::default(),
                body: Some(joint.name.clone()),
            });
        }
        let file = "meshes/skin.obj".to_string();
        let mut obj = ObjObjects::default();
        obj.push(
            "skin",
            &character.positions,
            character.triangles.iter().map(|t| t.as_slice()),
            None,
        );
        self.meshes.push((file.clone(), obj.into_text()));
        let mut params = MuscleParams::surface_layer(layer.area_density, layer.reach);
        // Skin lifts off freely (held by its binding) but stays above what
        // it lies on.
        params.sliding_mode = SlidingMode::Contact;
        params.compliance.fiber = layer.stretch_compliance;
        params.compliance.area = layer.area_compliance;
        params.area_mode = layer.area_mode;
        params.compliance.bind = layer.bind_compliance;
        params.iterations = Some(layer.iterations.max(1));
        self.scene.muscles.push(MuscleSpec {
            name: "skin".into(),
            mesh: MeshSource::File {
                path: file,
                triangulate: false,
                scale: 1.0,
                orient_outward: false,
                translation: glam::Vec3::ZERO,
            },
            roots: Roots::Vertices(Vec::new()),
            targets,
            params,
            binding: Some(SkinBindingSpec {
                bones: character
                    .joints
                    .iter()
                    .map(|j| joint_bone(&j.name))
                    .collect(),
                influences: character
                    .influences
                    .iter()
                    .map(|list| list.iter().copied().filter(|&(_, w)| w > 0.0).collect())
                    .collect(),
                strength: Vec::new(),
            }),
            ..Default::default()
        });
    }
}
